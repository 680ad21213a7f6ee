//! The distance to a held region's material: how far a rest point is from the part of the body
//! a region holds, not from the region's analytic shape.
//!
//! A region's analytic signed distance `d_R` (a half-space's plane, a ball's sphere) is the
//! distance to the held material only where the region's boundary runs through the body. A
//! slab that holds a flank and, across empty space, the tip of an ear has `d_R` small all
//! over the head beside the ear, so a weight `ω(d_R / δ)` damps a head the body does not hold
//! there. With the held samples `S_R` (rest points of the body inside the region, spacing h):
//!
//! ```text
//! s(X) = −τ ln Σ_i exp(−|X − S_i| / τ)     soft minimum (samples within 16τ of the nearest), τ = h/4
//! D(X) = max_k(d_R(X), s(X) − ρ)                          ρ = 2h, smooth maximum of width k = h/2
//! max_k(a, b) = max(a, b) for |a − b| ≥ k, else (a + b)/2 + (a − b)²/(4k) + k/4   (C¹)
//! ```
//!
//! Beside held material sampled on a grid of spacing h the nearest samples lie within
//! `d_R + 1.5 h`, so `D = d_R` exactly there (the weight and its gradient are the analytic ones across the interface); away from
//! it `D` grows with the distance to the held samples. `D ≥ d_R > 0` outside the region.

use std::sync::{Arc, OnceLock};

use nalgebra::Vector3;
use rkpm_core::{IntegrationPoints, SpatialIndex};
use serde::{Deserialize, Serialize};

/// The soft minimum sums over the samples within `CUTOFF · τ` of the nearest (the rest weigh
/// less than `e^{−CUTOFF}` each).
const CUTOFF: f64 = 16.0;
/// τ / h: the soft minimum's softness.
const SOFTNESS: f64 = 0.25;
/// ρ / h: how much farther than `d_R` the held samples may lie while `D = d_R`.
const MARGIN: f64 = 2.0;
/// k / h: the width of the smooth maximum.
const BLEND: f64 = 0.5;

/// The held samples of each region and their spacing (module docs).
#[derive(Clone, Serialize, Deserialize)]
pub struct HeldMaterial {
    /// Rest points (m) of the body in each region, in region order; none empty.
    samples: Vec<Vec<Vector3<f64>>>,
    /// h (m): the samples' spacing.
    spacing: f64,
    /// k-d trees over `samples`, built on first use.
    #[serde(skip)]
    indices: OnceLock<Arc<Vec<SpatialIndex>>>,
}

impl HeldMaterial {
    /// The held material of the regions whose membership `region_of` gives, sampled by
    /// `points` (the basis's integration points), with spacing `h = (Σ v / N)^{1/3}`.
    ///
    /// # Errors
    /// The index of the first region that holds none of the points.
    pub fn sample(
        points: &IntegrationPoints,
        regions: usize,
        region_of: impl Fn(&Vector3<f64>) -> Option<usize>,
    ) -> Result<HeldMaterial, usize> {
        let mut samples = vec![Vec::new(); regions];
        for x in points.positions() {
            if let Some(r) = region_of(x) {
                samples[r].push(*x);
            }
        }
        if let Some(empty) = samples.iter().position(Vec::is_empty) {
            return Err(empty);
        }
        // Volumes are positive and finite (`IntegrationPoints::new`), so h is.
        let volume: f64 = points.volumes().iter().sum();
        Ok(HeldMaterial {
            samples,
            spacing: (volume / points.len() as f64).cbrt(),
            indices: OnceLock::new(),
        })
    }

    /// `(D, ∇D)` (m, unit-bounded) at rest point `x` outside region `region`, given the
    /// region's analytic `(d_R, ∇d_R)` there (`d_R > 0`). `D ≥ d_R`.
    ///
    /// # Panics
    /// If `region` is out of range.
    pub fn distance(
        &self,
        region: usize,
        x: &Vector3<f64>,
        analytic: (f64, Vector3<f64>),
    ) -> (f64, Vector3<f64>) {
        let (s, grad_s) = self.soft_distance(region, x);
        let margin = MARGIN * self.spacing;
        smooth_max(analytic, (s - margin, grad_s), BLEND * self.spacing)
    }

    /// `(s, ∇s)`: the soft minimum of the distances from `x` to region `region`'s samples
    /// (module docs).
    fn soft_distance(&self, region: usize, x: &Vector3<f64>) -> (f64, Vector3<f64>) {
        let indices = self
            .indices
            .get_or_init(|| Arc::new(self.samples.iter().map(|s| SpatialIndex::new(s)).collect()));
        let index = &indices[region];
        let tau = SOFTNESS * self.spacing;
        let closest = index.nearest(x, 1)[0].1;
        let (mut sum, mut grad) = (0.0, Vector3::zeros());
        for (i, d) in index.within(x, closest + CUTOFF * tau) {
            let p = (-(d - closest) / tau).exp();
            sum += p;
            if d > 0.0 {
                grad += (x - self.samples[region][i]) * (p / d);
            }
        }
        (closest - tau * sum.ln(), grad / sum)
    }
}

/// `max_k(a, b)` and its gradient (module docs), for `(value, gradient)` pairs.
fn smooth_max(a: (f64, Vector3<f64>), b: (f64, Vector3<f64>), width: f64) -> (f64, Vector3<f64>) {
    let gap = a.0 - b.0;
    if gap >= width {
        a
    } else if gap <= -width {
        b
    } else {
        (
            0.5 * (a.0 + b.0) + gap * gap / (4.0 * width) + 0.25 * width,
            (a.1 + b.1) * 0.5 + (a.1 - b.1) * (gap / (2.0 * width)),
        )
    }
}

impl PartialEq for HeldMaterial {
    fn eq(&self, other: &Self) -> bool {
        self.samples == other.samples && self.spacing == other.spacing
    }
}

impl std::fmt::Debug for HeldMaterial {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let counts: Vec<usize> = self.samples.iter().map(Vec::len).collect();
        f.debug_struct("HeldMaterial")
            .field("samples_per_region", &counts)
            .field("spacing", &self.spacing)
            .finish()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Held samples in two pieces on a 0.05 m grid in x ∈ [0, 0.1], z ∈ [0, 0.2]: a column
    /// over y ∈ [0, 1] and, across a gap, a small cluster over y ∈ [2.9, 3] (the "ear").
    fn material() -> HeldMaterial {
        let h = 0.05;
        let mut samples = Vec::new();
        for i in 0..=2 {
            for j in 0..=60 {
                for k in 0..=4 {
                    let y = j as f64 * h;
                    if y <= 1.0 || y >= 2.9 {
                        samples.push(Vector3::new(i as f64 * h, y, k as f64 * h));
                    }
                }
            }
        }
        HeldMaterial {
            samples: vec![samples],
            spacing: h,
            indices: OnceLock::new(),
        }
    }

    /// The plane x = 0.1 bounding the region x ≤ 0.1.
    fn plane(x: &Vector3<f64>) -> (f64, Vector3<f64>) {
        (x.x - 0.1, Vector3::x())
    }

    #[test]
    fn beside_held_material_the_distance_is_the_regions_own() {
        let m = material();
        for x in [
            Vector3::new(0.1 + 1e-6, 0.5, 0.1),
            Vector3::new(0.3, 0.2, 0.05),
            Vector3::new(0.6, 2.95, 0.1),
        ] {
            assert_eq!(m.distance(0, &x, plane(&x)), plane(&x), "at {x}");
        }
    }

    #[test]
    fn away_from_held_material_the_distance_grows_with_the_gap() {
        let m = material();
        // Beside the region's plane but 1 m from any held sample.
        let x = Vector3::new(0.15, 2.0, 0.1);
        let (d, _) = m.distance(0, &x, plane(&x));
        assert!(d > 0.7 && d < 0.9, "D = {d} (d_R = 0.05)");
    }

    #[test]
    fn the_distance_gradient_matches_central_differences() {
        let m = material();
        // Points in the soft minimum's and the smooth maximum's ranges.
        for x in [
            Vector3::new(0.15, 2.0, 0.1),
            Vector3::new(0.2, 1.17, 0.1),
            Vector3::new(0.2, 1.19, 0.07),
            Vector3::new(0.25, 1.2, 0.3),
            Vector3::new(0.4, 2.6, 0.1),
        ] {
            let (_, grad) = m.distance(0, &x, plane(&x));
            let h = 1e-6;
            let fd = Vector3::from_fn(|d, _| {
                let mut e = Vector3::zeros();
                e[d] = h;
                let (p, q) = (x + e, x - e);
                (m.distance(0, &p, plane(&p)).0 - m.distance(0, &q, plane(&q)).0) / (2.0 * h)
            });
            assert!((grad - fd).norm() < 1e-6, "∇D {grad} vs {fd} at {x}");
        }
    }

    #[test]
    fn the_smooth_maximum_is_continuous_with_its_gradient_at_the_blend_edges() {
        let (ga, gb) = (Vector3::x(), Vector3::y());
        let width = 0.5;
        for edge in [width, -width] {
            let below = smooth_max((1.0 + edge - 1e-9, ga), (1.0, gb), width);
            let above = smooth_max((1.0 + edge + 1e-9, ga), (1.0, gb), width);
            assert!((below.0 - above.0).abs() < 1e-8, "{below:?} vs {above:?}");
            assert!((below.1 - above.1).norm() < 1e-8, "{below:?} vs {above:?}");
        }
    }
}
