//! RKPM kernel centres and radii (design §3.2).
//!
//! Centres: farthest point sampling over the integration points. Radius of kernel k:
//! `r_k = max(radius_scale · d₂(p_k), min_radius_factor · s̄)`, with d₂ the distance from p_k to
//! its second-nearest other centre (the paper's "minimal distance to reach two other centers")
//! and s̄ the mean nearest-neighbour spacing of the integration points (the authors' clamp).
//! The raw kernel is a window of `|X - p_k| / r_k` ([`KernelWindow`]): the paper's Gaussian
//! `φ_k(X) = exp(-|X - p_k|² / r_k²)` by default, or a compactly supported cubic B-spline.

use nalgebra::Vector3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::integration_points::mean_nearest_neighbor_distance;
use crate::spatial_index::SpatialIndex;

/// Options for [`place_kernels`].
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct KernelParams {
    /// Number of kernels K (default 1000).
    pub count: usize,
    /// Multiplier on the second-nearest-centre distance (default 1.0).
    pub radius_scale: f64,
    /// Lower clamp of the radius in units of the mean integration-point spacing (default 3.0).
    pub min_radius_factor: f64,
    /// Seed choosing the first farthest-point-sampling centre (default 0).
    pub seed: u64,
}

impl Default for KernelParams {
    fn default() -> Self {
        KernelParams {
            count: 1000,
            radius_scale: 1.0,
            min_radius_factor: 3.0,
            seed: 0,
        }
    }
}

/// The window `φ(X) = w(|X − p| / r)` of one RKPM kernel of centre p and radius r (m).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum KernelWindow {
    /// `w(q) = exp(−q²)` (the Gaussian RBF of the paper, Sec. 4): infinite support, truncated by
    /// [`crate::ShapeFunctionParams::cutoff`].
    #[default]
    Gaussian,
    /// The cubic B-spline `w(q) = 2/3 − q² + q³/2` for q < 1, `(2 − q)³/6` for 1 ≤ q < 2, 0
    /// beyond: C², exactly zero outside 2r, so no tail is truncated.
    CubicBSpline,
}

impl KernelWindow {
    /// Support radius in units of r (`∞` for the Gaussian).
    pub fn support(&self) -> f64 {
        match self {
            KernelWindow::Gaussian => f64::INFINITY,
            KernelWindow::CubicBSpline => 2.0,
        }
    }

    /// `φ(X)` and `∇φ(X)` (1/m) at offset `d = X − p` (m) from a kernel of radius `r` (m).
    pub fn value_and_gradient(&self, d: &Vector3<f64>, r: f64) -> (f64, Vector3<f64>) {
        match self {
            KernelWindow::Gaussian => {
                let f = (-d.norm_squared() / (r * r)).exp();
                (f, d * (-2.0 * f / (r * r)))
            }
            KernelWindow::CubicBSpline => {
                let distance = d.norm();
                let q = distance / r;
                // w'(q)/q keeps the gradient finite at the centre: w'(q) = −2q + 3q²/2 on [0, 1).
                let (w, dw_over_q) = if q < 1.0 {
                    (2.0 / 3.0 - q * q + 0.5 * q * q * q, -2.0 + 1.5 * q)
                } else if q < 2.0 {
                    let t = 2.0 - q;
                    (t * t * t / 6.0, -0.5 * t * t / q)
                } else {
                    (0.0, 0.0)
                };
                // ∇φ = w'(q) ∇q = w'(q) d / (r |d|) = (w'(q)/q) d / r².
                (w, d * (dw_over_q / (r * r)))
            }
        }
    }

    /// `φ(X)` at offset `d = X − p` (m) from a kernel of radius `r` (m).
    pub fn value(&self, d: &Vector3<f64>, r: f64) -> f64 {
        match self {
            KernelWindow::Gaussian => (-d.norm_squared() / (r * r)).exp(),
            KernelWindow::CubicBSpline => self.value_and_gradient(d, r).0,
        }
    }
}

/// Kernel placement failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum KernelError {
    /// More kernels than points to place them on, or fewer than the 4 a linear basis needs.
    #[error(
        "cannot place {requested} kernels on {available} points (need 4 ≤ K ≤ number of points)"
    )]
    InvalidCount {
        /// K requested.
        requested: usize,
        /// Points available.
        available: usize,
    },
    /// A radius parameter is not positive and finite.
    #[error("invalid kernel parameter `{name}` = {value}: must be positive and finite")]
    InvalidParameter {
        /// Parameter name.
        name: &'static str,
        /// The value given.
        value: f64,
    },
    /// The chosen centres coincide (duplicated input points), so radii would be zero.
    #[error("kernel {kernel} has radius {radius}: the input points coincide")]
    DegenerateRadius {
        /// Kernel index.
        kernel: usize,
        /// Its radius.
        radius: f64,
    },
}

/// Gaussian kernels: centres `p_k` (m) and radii `r_k` (m), K of each.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Kernels {
    centers: Vec<Vector3<f64>>,
    radii: Vec<f64>,
}

impl Kernels {
    /// Kernels from explicit centres and radii.
    ///
    /// # Errors
    /// [`KernelError::InvalidCount`] for fewer than 4 kernels or mismatched lengths;
    /// [`KernelError::DegenerateRadius`] for a radius that is not positive and finite.
    pub fn new(centers: Vec<Vector3<f64>>, radii: Vec<f64>) -> Result<Self, KernelError> {
        if centers.len() < 4 || centers.len() != radii.len() {
            return Err(KernelError::InvalidCount {
                requested: radii.len(),
                available: centers.len(),
            });
        }
        if let Some(k) = radii.iter().position(|r| !(r.is_finite() && *r > 0.0)) {
            return Err(KernelError::DegenerateRadius {
                kernel: k,
                radius: radii[k],
            });
        }
        Ok(Kernels { centers, radii })
    }

    /// Centres `p_k` (K).
    pub fn centers(&self) -> &[Vector3<f64>] {
        &self.centers
    }

    /// Radii `r_k` (K).
    pub fn radii(&self) -> &[f64] {
        &self.radii
    }

    /// Number of kernels K.
    pub fn len(&self) -> usize {
        self.centers.len()
    }

    /// Whether there are no kernels (never true for a constructed value).
    pub fn is_empty(&self) -> bool {
        self.centers.is_empty()
    }
}

/// Farthest point sampling: `count` indices into `points`, the first drawn from `seed`, each
/// next one the point farthest from all chosen so far. Deterministic; O(count · N), the
/// distance update parallel over points.
///
/// # Panics
/// If `count > points.len()`.
pub fn farthest_point_sampling(points: &[Vector3<f64>], count: usize, seed: u64) -> Vec<usize> {
    assert!(
        count <= points.len(),
        "cannot choose {count} of {} points",
        points.len()
    );
    if count == 0 {
        return Vec::new();
    }
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut chosen = Vec::with_capacity(count);
    let mut current = rng.random_range(0..points.len());
    let mut dist2 = vec![f64::INFINITY; points.len()];
    for _ in 0..count {
        chosen.push(current);
        let c = points[current];
        // Update and find the new farthest point in one parallel pass; ties go to the lowest
        // index so the result does not depend on the thread count.
        let (far, _) = dist2
            .par_iter_mut()
            .zip(points.par_iter())
            .enumerate()
            .map(|(i, (d, p))| {
                *d = d.min((p - c).norm_squared());
                (i, *d)
            })
            .reduce(
                || (usize::MAX, f64::NEG_INFINITY),
                |a, b| {
                    if b.1 > a.1 || (b.1 == a.1 && b.0 < a.0) {
                        b
                    } else {
                        a
                    }
                },
            );
        current = far;
    }
    chosen
}

/// Places K kernels on the integration points by farthest point sampling and sets their radii
/// by the rule in the module docs.
///
/// # Errors
/// [`KernelError`] for K < 4 or K > N, non-positive radius parameters, or coinciding points.
pub fn place_kernels(
    points: &[Vector3<f64>],
    params: &KernelParams,
) -> Result<Kernels, KernelError> {
    if params.count < 4 || params.count > points.len() {
        return Err(KernelError::InvalidCount {
            requested: params.count,
            available: points.len(),
        });
    }
    for (name, value) in [
        ("radius_scale", params.radius_scale),
        ("min_radius_factor", params.min_radius_factor),
    ] {
        if !(value.is_finite() && value > 0.0) {
            return Err(KernelError::InvalidParameter { name, value });
        }
    }
    let centers: Vec<Vector3<f64>> = farthest_point_sampling(points, params.count, params.seed)
        .into_iter()
        .map(|i| points[i])
        .collect();
    let min_radius = params.min_radius_factor * mean_nearest_neighbor_distance(points);
    let index = SpatialIndex::new(&centers);
    let radii: Vec<f64> = centers
        .par_iter()
        .map(|c| {
            // The nearest hit is the centre itself; the third is the second-nearest other.
            let second = index.nearest(c, 3).last().map_or(0.0, |&(_, d)| d);
            (params.radius_scale * second).max(min_radius)
        })
        .collect();
    if let Some(k) = radii.iter().position(|r| !(*r > 0.0)) {
        return Err(KernelError::DegenerateRadius {
            kernel: k,
            radius: radii[k],
        });
    }
    Ok(Kernels { centers, radii })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lattice(n: usize) -> Vec<Vector3<f64>> {
        (0..n * n * n)
            .map(|i| Vector3::new((i / (n * n)) as f64, ((i / n) % n) as f64, (i % n) as f64))
            .collect()
    }

    #[test]
    fn fps_is_deterministic_distinct_and_spread() {
        let pts = lattice(10);
        let a = farthest_point_sampling(&pts, 50, 7);
        assert_eq!(a, farthest_point_sampling(&pts, 50, 7));
        let mut s = a.clone();
        s.sort_unstable();
        s.dedup();
        assert_eq!(s.len(), 50);
        // The second pick is a corner farthest from the first.
        let d01 = (pts[a[0]] - pts[a[1]]).norm();
        assert!(pts.iter().all(|p| (p - pts[a[0]]).norm() <= d01 + 1e-12));
    }

    #[test]
    fn radius_rule_uses_second_nearest_center_and_clamp() {
        let pts = lattice(6);
        let k = place_kernels(
            &pts,
            &KernelParams {
                count: pts.len(),
                min_radius_factor: 0.5,
                ..Default::default()
            },
        )
        .unwrap();
        // All lattice points are centres: second-nearest other centre is at distance 1.
        assert!(k.radii().iter().all(|&r| (r - 1.0).abs() < 1e-12));
        let k = place_kernels(
            &pts,
            &KernelParams {
                count: pts.len(),
                min_radius_factor: 3.0,
                ..Default::default()
            },
        )
        .unwrap();
        assert!(k.radii().iter().all(|&r| (r - 3.0).abs() < 1e-12));
    }

    #[test]
    fn too_many_kernels_is_an_error() {
        let pts = lattice(2);
        let err = place_kernels(
            &pts,
            &KernelParams {
                count: 9,
                ..Default::default()
            },
        );
        assert_eq!(
            err,
            Err(KernelError::InvalidCount {
                requested: 9,
                available: 8
            })
        );
    }
}

#[cfg(test)]
mod window_tests {
    use super::*;

    #[test]
    fn window_gradients_match_central_differences_and_the_spline_is_c1_at_its_knots() {
        let h = 1e-6;
        let r = 0.7;
        for window in [KernelWindow::Gaussian, KernelWindow::CubicBSpline] {
            // Offsets at q = 0.3, 0.999, 1.001, 1.6 and 2.2 along a skew direction.
            let dir = Vector3::new(0.3, -0.5, 0.8).normalize();
            for q in [0.3, 0.999, 1.001, 1.6, 2.2] {
                let d = dir * q * r;
                let (_, g) = window.value_and_gradient(&d, r);
                let fd = Vector3::from_fn(|i, _| {
                    let e = Vector3::ith(i, h);
                    (window.value(&(d + e), r) - window.value(&(d - e), r)) / (2.0 * h)
                });
                assert!(
                    (g - fd).norm() < 1e-7,
                    "{window:?} at q = {q}: {g:?} vs {fd:?}"
                );
            }
            let (f0, g0) = window.value_and_gradient(&Vector3::zeros(), r);
            assert!(f0 > 0.0 && g0.norm() == 0.0);
        }
        let spline = KernelWindow::CubicBSpline;
        let at = |q: f64| spline.value(&Vector3::new(q * r, 0.0, 0.0), r);
        assert!((at(1.0 - 1e-12) - at(1.0 + 1e-12)).abs() < 1e-11);
        assert_eq!(at(2.0), 0.0);
        assert!((at(0.0) - 2.0 / 3.0).abs() < 1e-15);
    }
}
