//! The weight function of a weighted basis (WEB): a smooth distance to the held regions that
//! vanishes on them, and the blends that carry each region's handle.
//!
//! With R held regions of signed distance `d_r(X)` (≤ 0 inside region r, m) and a transition
//! length δ (m):
//!
//! ```text
//! w(X)   = Π_r ω(d_r(X) / δ),   ω(s) = 1 − (1 − min(s, 1))²   (ω(0) = 0, ω'(0) = 2, ω = 1 for s ≥ 1)
//! g_r(X) = P_r / Σ_t P_t,       P_t = Π_{s ≠ t} max(d_s(X), 0)
//! ```
//!
//! `w` is 0 on every region and 1 farther than δ from all of them; `g_r` is 1 on region r, 0 on
//! the others, and the `g_r` sum to one. Inside a region w, ∇w and ∇g_r are 0 (the fields are
//! C⁰ across a region's boundary, like a clamped finite element). Höllig, Reif and Wipper's
//! WEB-splines; Rvachev's R-functions for the product over regions.
//!
//! With [`RegionWeight::with_held_material`], `d_r` in `w` (not in the blends) is the distance to
//! the material region r holds ([`HeldMaterial`]) rather than to its shape.

use nalgebra::Vector3;
use rkpm_core::IntegrationPoints;
use serde::{Deserialize, Serialize};

use crate::held_material::HeldMaterial;

/// A held region with an analytic signed distance (m): ≤ 0 inside, the distance to it outside.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum HeldRegionShape {
    /// `{X : n·X ≤ offset}`, n a unit vector; `d = n·X − offset`.
    #[serde(alias = "HalfSpace")]
    HalfSpace {
        /// Unit outward normal n of the region.
        normal: Vector3<f64>,
        /// Offset (m).
        offset: f64,
    },
    /// `{X : |X − c| ≤ radius}`; `d = |X − c| − radius`.
    #[serde(alias = "Ball")]
    Ball {
        /// Centre c (m).
        center: Vector3<f64>,
        /// Radius (m), positive.
        radius: f64,
    },
}

impl HeldRegionShape {
    /// `(d, ∇d)` at rest point `x`: the signed distance (m, ≤ 0 inside) and its gradient (unit).
    pub fn signed_distance(&self, x: &Vector3<f64>) -> (f64, Vector3<f64>) {
        match *self {
            HeldRegionShape::HalfSpace { normal, offset } => (normal.dot(x) - offset, normal),
            HeldRegionShape::Ball { center, radius } => {
                let r = x - center;
                let norm = r.norm();
                let grad = if norm > 0.0 {
                    r / norm
                } else {
                    Vector3::zeros()
                };
                (norm - radius, grad)
            }
        }
    }

    /// Why the shape is malformed (not finite, a normal that is not unit, a radius ≤ 0).
    fn defect(&self) -> Option<String> {
        match *self {
            HeldRegionShape::HalfSpace { normal, offset } => {
                if !(normal.iter().all(|v| v.is_finite()) && offset.is_finite()) {
                    Some("half-space not finite".into())
                } else if (normal.norm() - 1.0).abs() > 1e-9 {
                    Some(format!("half-space normal has length {}", normal.norm()))
                } else {
                    None
                }
            }
            HeldRegionShape::Ball { center, radius } => {
                if !(center.iter().all(|v| v.is_finite()) && radius.is_finite() && radius > 0.0) {
                    Some(format!(
                        "ball must be finite with a positive radius, got {radius}"
                    ))
                } else {
                    None
                }
            }
        }
    }
}

/// The weight `w` and blends `g_r` of R held regions (module docs).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RegionWeight {
    regions: Vec<HeldRegionShape>,
    transition: f64,
    /// With it, `d_r` outside region r is the distance to its held material
    /// ([`RegionWeight::with_held_material`]).
    #[serde(default)]
    material: Option<HeldMaterial>,
}

/// A [`RegionWeight`] that cannot be made.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RegionWeightError {
    /// No region was given.
    #[error("a weighted basis needs at least one held region")]
    NoRegions,
    /// A region is malformed.
    #[error("held region {region}: {problem}")]
    InvalidRegion {
        /// Its index.
        region: usize,
        /// What is wrong.
        problem: String,
    },
    /// δ is not a positive finite length.
    #[error("the transition length must be positive and finite, got {transition} m")]
    InvalidTransition {
        /// δ (m).
        transition: f64,
    },
    /// A region holds none of the points its held material is sampled from.
    #[error("held region {region} holds none of the {points} points sampling its material")]
    NoHeldMaterial {
        /// Its index.
        region: usize,
        /// How many points were given.
        points: usize,
    },
}

impl RegionWeight {
    /// The weight of `regions` with transition length `transition` (δ, m).
    ///
    /// # Errors
    /// [`RegionWeightError`] for no region, a malformed region or a δ that is not positive.
    pub fn new(
        regions: Vec<HeldRegionShape>,
        transition: f64,
    ) -> Result<RegionWeight, RegionWeightError> {
        if regions.is_empty() {
            return Err(RegionWeightError::NoRegions);
        }
        if let Some((region, problem)) = regions
            .iter()
            .enumerate()
            .find_map(|(i, r)| r.defect().map(|p| (i, p)))
        {
            return Err(RegionWeightError::InvalidRegion { region, problem });
        }
        if !(transition > 0.0 && transition.is_finite()) {
            return Err(RegionWeightError::InvalidTransition { transition });
        }
        Ok(RegionWeight {
            regions,
            transition,
            material: None,
        })
    }

    /// The weight with each region's distance `d_r` outside it measured to the part of the body
    /// it holds, sampled by `points` (the basis's integration points), rather than to its shape:
    /// `D_r` of [`HeldMaterial`], equal to `d_r` beside the held material and larger away from
    /// it. A slab that holds a flank and an ear's tip then damps the modes beside those, not
    /// over everything near its plane.
    ///
    /// # Errors
    /// [`RegionWeightError::NoHeldMaterial`] when a region holds none of `points`.
    pub fn with_held_material(
        self,
        points: &IntegrationPoints,
    ) -> Result<RegionWeight, RegionWeightError> {
        let material = HeldMaterial::sample(points, self.regions.len(), |x| self.region_of(x))
            .map_err(|region| RegionWeightError::NoHeldMaterial {
                region,
                points: points.len(),
            })?;
        Ok(RegionWeight {
            material: Some(material),
            ..self
        })
    }

    /// The held material the distances are measured to, if any
    /// ([`RegionWeight::with_held_material`]).
    pub fn held_material(&self) -> Option<&HeldMaterial> {
        self.material.as_ref()
    }

    /// The regions, in handle order.
    pub fn regions(&self) -> &[HeldRegionShape] {
        &self.regions
    }

    /// δ (m).
    pub fn transition(&self) -> f64 {
        self.transition
    }

    /// The first region containing rest point `x` (signed distance ≤ 0), if any.
    pub fn region_of(&self, x: &Vector3<f64>) -> Option<usize> {
        self.regions
            .iter()
            .position(|r| r.signed_distance(x).0 <= 0.0)
    }

    /// `(w, ∇w)` at rest point `x` (dimensionless, 1/m): 0 and 0 inside any region.
    pub fn weight(&self, x: &Vector3<f64>) -> (f64, Vector3<f64>) {
        let mut factors = Vec::with_capacity(self.regions.len());
        for (r, region) in self.regions.iter().enumerate() {
            let (d, grad) = region.signed_distance(x);
            if d <= 0.0 {
                return (0.0, Vector3::zeros());
            }
            // D ≥ d_r: past the transition the factor is 1 either way.
            let (d, grad) = match &self.material {
                Some(material) if d < self.transition => material.distance(r, x, (d, grad)),
                _ => (d, grad),
            };
            let s = d / self.transition;
            if s >= 1.0 {
                factors.push((1.0, Vector3::zeros()));
            } else {
                let value = 1.0 - (1.0 - s) * (1.0 - s);
                factors.push((value, grad * (2.0 * (1.0 - s) / self.transition)));
            }
        }
        product_with_gradient(&factors)
    }

    /// `(g_r, ∇g_r)` at rest point `x`: 1 on region r, 0 on the other regions (gradient 0
    /// inside any region), the distance blend of the module docs between them.
    ///
    /// # Panics
    /// If `region` is not below the number of regions.
    pub fn blend(&self, region: usize, x: &Vector3<f64>) -> (f64, Vector3<f64>) {
        assert!(region < self.regions.len(), "region index in range");
        if let Some(inside) = self.region_of(x) {
            return (f64::from(u8::from(inside == region)), Vector3::zeros());
        }
        let distances: Vec<(f64, Vector3<f64>)> =
            self.regions.iter().map(|r| r.signed_distance(x)).collect();
        // P_t = Π_{s≠t} d_s and its gradient.
        let others = |t: usize| {
            let factors: Vec<(f64, Vector3<f64>)> = distances
                .iter()
                .enumerate()
                .filter(|&(s, _)| s != t)
                .map(|(_, &f)| f)
                .collect();
            product_with_gradient(&factors)
        };
        let terms: Vec<(f64, Vector3<f64>)> = (0..self.regions.len()).map(others).collect();
        let (sum, grad_sum) = terms
            .iter()
            .fold((0.0, Vector3::zeros()), |(s, g), &(p, gp)| (s + p, g + gp));
        let (p, grad_p) = terms[region];
        (p / sum, (grad_p * sum - grad_sum * p) / (sum * sum))
    }
}

/// `(Π f_i, ∇Π f_i)` of factors `(f_i, ∇f_i)` (1 and 0 for none).
fn product_with_gradient(factors: &[(f64, Vector3<f64>)]) -> (f64, Vector3<f64>) {
    let value: f64 = factors.iter().map(|f| f.0).product();
    let gradient = (0..factors.len())
        .map(|i| {
            let rest: f64 = factors
                .iter()
                .enumerate()
                .filter(|&(j, _)| j != i)
                .map(|(_, f)| f.0)
                .product();
            factors[i].1 * rest
        })
        .fold(Vector3::zeros(), |a, b| a + b);
    (value, gradient)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn beam_ends() -> RegionWeight {
        RegionWeight::new(
            vec![
                HeldRegionShape::HalfSpace {
                    normal: Vector3::x(),
                    offset: 0.5,
                },
                HeldRegionShape::HalfSpace {
                    normal: -Vector3::x(),
                    offset: -4.5,
                },
            ],
            1.0,
        )
        .unwrap()
    }

    fn central_difference(
        f: impl Fn(&Vector3<f64>) -> f64,
        x: &Vector3<f64>,
        h: f64,
    ) -> Vector3<f64> {
        Vector3::from_fn(|d, _| {
            let mut e = Vector3::zeros();
            e[d] = h;
            (f(&(x + e)) - f(&(x - e))) / (2.0 * h)
        })
    }

    #[test]
    fn weight_vanishes_on_regions_and_is_one_past_the_transition() {
        let w = beam_ends();
        for x in [0.0, 0.3, 0.5, 4.5, 4.9] {
            assert_eq!(
                w.weight(&Vector3::new(x, 0.4, 0.4)),
                (0.0, Vector3::zeros())
            );
        }
        assert_eq!(w.weight(&Vector3::new(2.5, 0.4, 0.4)).0, 1.0);
        let near = w.weight(&Vector3::new(0.5 + 1e-6, 0.4, 0.4));
        assert!((near.0 - 2e-6).abs() < 1e-11, "ω'(0) = 2/δ: {}", near.0);
    }

    #[test]
    fn weight_and_blend_gradients_match_finite_differences() {
        let w = RegionWeight::new(
            vec![
                HeldRegionShape::HalfSpace {
                    normal: Vector3::x(),
                    offset: 0.5,
                },
                HeldRegionShape::Ball {
                    center: Vector3::new(3.0, 0.5, 0.5),
                    radius: 0.3,
                },
                HeldRegionShape::HalfSpace {
                    normal: -Vector3::x(),
                    offset: -4.5,
                },
            ],
            0.8,
        )
        .unwrap();
        for x in [
            Vector3::new(0.9, 0.2, 0.7),
            Vector3::new(2.4, 0.9, 0.1),
            Vector3::new(3.5, 0.5, 0.6),
            Vector3::new(4.1, 0.3, 0.3),
        ] {
            let (_, grad) = w.weight(&x);
            let fd = central_difference(|y| w.weight(y).0, &x, 1e-6);
            assert!((grad - fd).norm() < 1e-7, "∇w {grad} vs {fd}");
            for r in 0..3 {
                let (_, grad) = w.blend(r, &x);
                let fd = central_difference(|y| w.blend(r, y).0, &x, 1e-6);
                assert!((grad - fd).norm() < 1e-7, "∇g_{r} {grad} vs {fd}");
            }
        }
    }

    #[test]
    fn blends_are_one_on_their_region_zero_on_others_and_sum_to_one() {
        let w = beam_ends();
        assert_eq!(w.blend(0, &Vector3::new(0.2, 0.5, 0.5)).0, 1.0);
        assert_eq!(w.blend(1, &Vector3::new(0.2, 0.5, 0.5)).0, 0.0);
        assert_eq!(w.blend(1, &Vector3::new(4.7, 0.5, 0.5)).0, 1.0);
        for x in [0.6, 1.7, 3.2, 4.4] {
            let p = Vector3::new(x, 0.5, 0.5);
            let sum = w.blend(0, &p).0 + w.blend(1, &p).0;
            assert!((sum - 1.0).abs() < 1e-15);
            // Two parallel planes: the blend is linear between them.
            assert!((w.blend(1, &p).0 - (x - 0.5) / 4.0).abs() < 1e-15);
        }
    }

    /// The region x ≤ 0.1 (grown by nothing) on grid points of `boxes` (min, max corners),
    /// spacing 0.05 m.
    fn slab_on(boxes: &[(Vector3<f64>, Vector3<f64>)]) -> (RegionWeight, IntegrationPoints) {
        let mut positions = Vec::new();
        for &(min, max) in boxes {
            let grid = rkpm_core::sample_box_grid(min, max, 0.05).unwrap();
            positions.extend_from_slice(grid.positions());
        }
        let volumes = vec![0.05f64.powi(3); positions.len()];
        let slab = HeldRegionShape::HalfSpace {
            normal: Vector3::x(),
            offset: 0.1,
        };
        (
            RegionWeight::new(vec![slab], 0.5).unwrap(),
            IntegrationPoints::new(positions, volumes).unwrap(),
        )
    }

    #[test]
    fn a_region_held_across_the_whole_body_weighs_the_same_with_held_material() {
        let (shape, points) = slab_on(&[(Vector3::zeros(), Vector3::new(1.0, 0.3, 0.2))]);
        let material = shape.clone().with_held_material(&points).unwrap();
        for x in points.positions() {
            assert_eq!(shape.weight(x), material.weight(x), "at {x}");
        }
    }

    #[test]
    fn held_material_lifts_the_weight_beside_the_region_away_from_what_it_holds() {
        // An L: a bar that crosses the plane x = 0.1 and an arm beside the plane that does not.
        let (shape, points) = slab_on(&[
            (Vector3::zeros(), Vector3::new(1.0, 0.3, 0.2)),
            (Vector3::new(0.15, 0.3, 0.0), Vector3::new(1.0, 1.0, 0.2)),
        ]);
        let material = shape.clone().with_held_material(&points).unwrap();
        let arm = Vector3::new(0.2, 0.9, 0.1);
        let (lifted, grad) = material.weight(&arm);
        assert!(shape.weight(&arm).0 < 0.4 && lifted == 1.0, "{lifted}");
        assert_eq!(grad, Vector3::zeros());
        for x in [Vector3::new(0.2, 0.45, 0.1), Vector3::new(0.3, 0.6, 0.05)] {
            let (value, grad) = material.weight(&x);
            assert!(value > shape.weight(&x).0 && value < 1.0, "{value} at {x}");
            let fd = central_difference(|y| material.weight(y).0, &x, 1e-6);
            assert!((grad - fd).norm() < 1e-6, "∇w {grad} vs {fd}");
        }
        let empty = RegionWeight::new(
            vec![HeldRegionShape::HalfSpace {
                normal: Vector3::x(),
                offset: -1.0,
            }],
            0.5,
        )
        .unwrap();
        assert_eq!(
            empty.with_held_material(&points),
            Err(RegionWeightError::NoHeldMaterial {
                region: 0,
                points: points.len()
            })
        );
    }

    #[test]
    fn malformed_regions_and_transitions_are_named() {
        assert_eq!(
            RegionWeight::new(vec![], 1.0),
            Err(RegionWeightError::NoRegions)
        );
        let ball = HeldRegionShape::Ball {
            center: Vector3::zeros(),
            radius: -1.0,
        };
        assert!(matches!(
            RegionWeight::new(vec![ball], 1.0),
            Err(RegionWeightError::InvalidRegion { region: 0, .. })
        ));
        let plane = HeldRegionShape::HalfSpace {
            normal: Vector3::x(),
            offset: 0.0,
        };
        assert!(matches!(
            RegionWeight::new(vec![plane], f64::NAN),
            Err(RegionWeightError::InvalidTransition { .. })
        ));
    }
}
