//! Kernels widened where linear RKPM is undefined.
//!
//! The shape functions at X exist only where the moment matrix `M(X) = Σ_k φ_k(X) b_k bₖᵀ`
//! (Eq. 10) is invertible, that is where the kernels reaching X have centres spread in all three
//! directions. In a part one or two integration points thick, the few kernels that reach a point
//! can all lie in one plane, so `M(X)` is singular; a compact window ([`KernelWindow::CubicBSpline`],
//! zero beyond 2 r_k) meets this far sooner than the Gaussian truncated at 4 r_k, because fewer
//! kernels reach each point. [`cover_queries`] widens the kernels nearest each such point until
//! every point is covered (a wider kernel only adds positive terms to `M(X)`; every point is
//! checked again after each round all the same). Linear fields are still reproduced exactly at
//! every point, since the correction of Eq. 9 is computed with whatever kernels reach it. A
//! point whose `M(X)` passes the condition estimate but whose functions reproduce linear fields
//! only approximately (nearly singular, [`ShapeFunctionError::InaccurateReproduction`]) counts
//! as uncovered and is widened around too.
//! Where nothing is singular the kernels are returned as placed, so a basis that could be built
//! before does not change.
//!
//! [`KernelWindow::CubicBSpline`]: crate::KernelWindow::CubicBSpline

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

use crate::kernels::Kernels;
use crate::shape_functions::{ShapeFunctionError, ShapeFunctionParams, singular_queries};
use crate::spatial_index::SpatialIndex;

/// Options of [`cover_queries`].
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct CoverageParams {
    /// Rounds of widening before a point still singular is an error (default 8). 0 leaves the
    /// kernels as placed (the paper's setting): the first singular point is an error.
    pub max_rounds: usize,
    /// Factor by which one round multiplies a widened kernel's radius (default 1.25; > 1).
    pub growth: f64,
    /// Kernels widened around each singular point in one round: its nearest centres (default 8).
    pub nearest_kernels: usize,
}

impl Default for CoverageParams {
    fn default() -> Self {
        CoverageParams {
            max_rounds: 8,
            growth: 1.25,
            nearest_kernels: 8,
        }
    }
}

/// What [`cover_queries`] did.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct CoverageReport {
    /// Query points whose moment matrix was singular (or whose functions were inaccurate) with
    /// the kernels as placed.
    pub singular_points: usize,
    /// Rounds of widening run (0 when every point was covered).
    pub rounds: usize,
    /// Kernels whose radius was enlarged.
    pub widened_kernels: usize,
    /// Largest ratio of a kernel's final radius to its placed one (1 when none was widened).
    pub max_radius_growth: f64,
}

impl Default for CoverageReport {
    fn default() -> Self {
        CoverageReport {
            singular_points: 0,
            rounds: 0,
            widened_kernels: 0,
            max_radius_growth: 1.0,
        }
    }
}

/// `kernels` with radii enlarged until the shape functions exist at every query point.
///
/// Each round finds the points where `M(X)` is singular or the functions inaccurate
/// ([`singular_queries`]) and multiplies by
/// `growth` the radius of the `nearest_kernels` kernels nearest each one; centres and K do not
/// change. Postcondition: [`crate::evaluate_shape_functions`] succeeds on `queries` with the
/// returned kernels and `shape`.
///
/// # Errors
/// [`ShapeFunctionError::SingularMomentMatrix`] (or
/// [`ShapeFunctionError::InaccurateReproduction`]) for the first point still uncovered after
/// `max_rounds` rounds (e.g. a flat cloud, whose kernels all lie in one plane whatever their
/// radius); [`ShapeFunctionError::InvalidParameter`] for `growth` ≤ 1 or not finite, or
/// `nearest_kernels` = 0 while `max_rounds` > 0; [`ShapeFunctionError::NonFiniteQuery`].
pub fn cover_queries(
    kernels: &Kernels,
    queries: &[Vector3<f64>],
    shape: &ShapeFunctionParams,
    params: &CoverageParams,
) -> Result<(Kernels, CoverageReport), ShapeFunctionError> {
    if params.max_rounds > 0 {
        if !(params.growth.is_finite() && params.growth > 1.0) {
            return Err(ShapeFunctionError::InvalidParameter {
                name: "growth",
                value: params.growth,
            });
        }
        if params.nearest_kernels == 0 {
            return Err(ShapeFunctionError::InvalidParameter {
                name: "nearest_kernels",
                value: 0.0,
            });
        }
    }
    let mut singular = singular_queries(kernels, queries, shape)?;
    let mut report = CoverageReport {
        singular_points: singular.len(),
        ..CoverageReport::default()
    };
    let index = SpatialIndex::new(kernels.centers());
    let mut radii = kernels.radii().to_vec();
    let mut covered = kernels.clone();
    while let Some(first) = singular.first() {
        if report.rounds == params.max_rounds {
            return Err(first.clone());
        }
        let mut grow = vec![false; radii.len()];
        for point in singular
            .iter()
            .filter_map(ShapeFunctionError::uncovered_point)
        {
            for (k, _) in index.nearest(&queries[point], params.nearest_kernels) {
                grow[k] = true;
            }
        }
        for (r, _) in radii.iter_mut().zip(&grow).filter(|(_, g)| **g) {
            *r *= params.growth;
        }
        covered = Kernels::new(kernels.centers().to_vec(), radii.clone())
            .expect("enlarged radii of valid kernels are valid");
        report.rounds += 1;
        singular = singular_queries(&covered, queries, shape)?;
    }
    let growth = radii
        .iter()
        .zip(kernels.radii())
        .map(|(new, old)| new / old);
    report.widened_kernels = growth.clone().filter(|&g| g > 1.0).count();
    report.max_radius_growth = growth.fold(1.0, f64::max);
    Ok((covered, report))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kernels::KernelWindow;
    use crate::shape_functions::evaluate_shape_functions;

    /// A slab `nx × ny × nz` of points at spacing `h` (m), and compact kernels of radius
    /// `radius` on every `stride`-th point in x and y of its lowest layer and of its top layer.
    fn slab(nz: usize, radius: f64) -> (Vec<Vector3<f64>>, Kernels) {
        let h = 0.1;
        let mut points = Vec::new();
        for i in 0..12 {
            for j in 0..12 {
                for k in 0..nz {
                    points.push(Vector3::new(i as f64, j as f64, k as f64) * h);
                }
            }
        }
        let centers: Vec<_> = points
            .iter()
            .filter(|p| {
                let (i, j) = ((p.x / h).round() as usize, (p.y / h).round() as usize);
                i % 3 == 0 && j % 3 == 0
            })
            .copied()
            .collect();
        let radii = vec![radius; centers.len()];
        (points, Kernels::new(centers, radii).unwrap())
    }

    fn compact() -> ShapeFunctionParams {
        ShapeFunctionParams {
            window: KernelWindow::CubicBSpline,
            ..ShapeFunctionParams::default()
        }
    }

    #[test]
    fn widened_kernels_cover_a_two_layer_slab_and_reproduce_linear_fields_exactly() {
        // Two layers 0.1 m apart, kernels every 0.3 m in x and y: with support 2 r = 0.3 m
        // a point between four columns sees too few of them.
        let (points, kernels) = slab(2, 0.15);
        let shape = compact();
        let before = singular_queries(&kernels, &points, &shape).unwrap();
        assert!(!before.is_empty(), "the slab must start uncovered");

        let (covered, report) =
            cover_queries(&kernels, &points, &shape, &CoverageParams::default()).unwrap();
        assert_eq!(report.singular_points, before.len());
        assert!(report.rounds >= 1 && report.widened_kernels > 0);
        assert!(report.max_radius_growth > 1.0);
        assert_eq!(covered.centers(), kernels.centers());
        assert!(
            covered
                .radii()
                .iter()
                .zip(kernels.radii())
                .all(|(a, b)| a >= b)
        );

        let functions = evaluate_shape_functions(&covered, &points, &shape).unwrap();
        let errors = functions.reproducing_errors(&covered, &points, 1.1);
        assert!(errors.max() < 1e-10, "{errors:?}");
    }

    #[test]
    fn covered_kernels_are_returned_as_placed() {
        let (points, kernels) = slab(4, 0.4);
        let (covered, report) =
            cover_queries(&kernels, &points, &compact(), &CoverageParams::default()).unwrap();
        assert_eq!(covered, kernels);
        assert_eq!(report, CoverageReport::default());
    }

    #[test]
    fn a_flat_cloud_stays_singular_and_names_its_first_point() {
        // One layer: every centre lies in the plane z = 0 whatever the radii.
        let (points, kernels) = slab(1, 0.4);
        let error =
            cover_queries(&kernels, &points, &compact(), &CoverageParams::default()).unwrap_err();
        assert!(
            matches!(
                error,
                ShapeFunctionError::SingularMomentMatrix { point: 0, .. }
            ),
            "{error}"
        );
    }

    #[test]
    fn zero_rounds_keep_the_papers_behaviour_of_failing_at_the_first_singular_point() {
        let (points, kernels) = slab(2, 0.15);
        let shape = compact();
        let placed = evaluate_shape_functions(&kernels, &points, &shape).unwrap_err();
        let params = CoverageParams {
            max_rounds: 0,
            ..CoverageParams::default()
        };
        assert_eq!(
            cover_queries(&kernels, &points, &shape, &params).unwrap_err(),
            placed
        );
    }

    #[test]
    fn a_growth_that_does_not_widen_is_rejected() {
        let (points, kernels) = slab(2, 0.15);
        let params = CoverageParams {
            growth: 1.0,
            ..CoverageParams::default()
        };
        assert!(matches!(
            cover_queries(&kernels, &points, &compact(), &params),
            Err(ShapeFunctionError::InvalidParameter { name: "growth", .. })
        ));
    }
}
