//! Exactly held regions ([`crate::Scene::held`]): each held region moves
//! by an affine transform carried by its own handles, prescribed from the region's targets and
//! eliminated from Newton.
//!
//! The basis must hold the regions ([`skin_eigen::build_basis_with_regions`]): on region 0 the
//! weights are `[1, 0 … 0 | 0 …]` and on region r ≥ 1 `[1, e_r | 0 …]` (constant handle, the
//! R − 1 region weights, then modes that vanish there). A point of region r then moves by
//! `x = X + (Z_0 + Z_r) X̄` (`Z_r` absent for r = 0), so with `D_r` the affine displacement
//! fitted to the region's targets at time t,
//!
//! ```text
//! D_r = argmin_D Σ_{p ∈ Ω_r} v_p |D X̄_p − (target_p(t) − X_p)|²      (3 × 4)
//! Z_0 = D_0,   Z_r = D_r − D_0  (1 ≤ r < R)
//! ```
//!
//! and every region point sits on its target whenever the targets are an affine motion of the
//! region (rest, rigid motions, the Twist's rotating end); otherwise the residual of the fit is
//! the drift [`crate::Simulator::max_held_deviation`] reports.

use nalgebra::{Matrix3x4, Matrix4, Vector3, Vector4};

use crate::reduced_coordinates::ReducedLayout;
use crate::scene_error::SceneError;

/// How far (absolute, dimensionless) the basis's weights on a region may be from 1/0 for the
/// region to count as held by it. The weights of [`skin_eigen::build_basis_with_regions`] are
/// exact to about 1e-7.
pub(crate) const HELD_WEIGHT_TOLERANCE: f64 = 1e-5;

/// The regions' transforms, prepared once.
pub(crate) struct HeldRegions {
    layout: ReducedLayout,
    /// Per region: per point `g_p = v_p G_r⁺ X̄_p` with `G_r = Σ v X̄ X̄ᵀ`, and the rest term
    /// `Σ_p X_p g_pᵀ`, so that `D_r = Σ_p t_p g_pᵀ − Σ_p X_p g_pᵀ` for targets `t_p`.
    fits: Vec<(Vec<Vector4<f64>>, Matrix3x4<f64>)>,
    /// Indices of z not prescribed (ascending).
    free: Vec<usize>,
}

impl HeldRegions {
    /// Checks that the weights (`weight(point, handle)`, `handles` of them) hold the regions as
    /// described in the module docs, and prepares the fits.
    ///
    /// # Errors
    /// [`SceneError::TooFewHandles`] for fewer handles than regions, [`SceneError::RegionNotHeld`] naming the first region point whose
    /// weights are not those of a held region.
    pub(crate) fn new(
        layout: ReducedLayout,
        regions: &[Vec<usize>],
        rest: &[Vector3<f64>],
        volumes: &[f64],
        weight: impl Fn(usize, usize) -> f64,
    ) -> Result<Self, SceneError> {
        let count = regions.len();
        let handles = layout.handles();
        if handles < count {
            return Err(SceneError::TooFewHandles {
                regions: count,
                handles,
            });
        }
        for (region, points) in regions.iter().enumerate() {
            for &point in points {
                for handle in 0..handles {
                    let expected = if handle == 0 || handle == region {
                        1.0
                    } else {
                        0.0
                    };
                    let found = weight(point, handle);
                    if !((found - expected).abs() <= HELD_WEIGHT_TOLERANCE) {
                        return Err(SceneError::RegionNotHeld {
                            region,
                            point,
                            handle,
                            weight: found,
                            expected,
                        });
                    }
                }
            }
        }
        let fits = regions
            .iter()
            .map(|points| {
                let moment: Matrix4<f64> = points
                    .iter()
                    .map(|&p| {
                        let x = rest[p].push(1.0);
                        volumes[p] * x * x.transpose()
                    })
                    .sum();
                // A flat region (one layer of points) leaves the transform along its normal
                // undetermined; the pseudo-inverse then keeps it at the identity.
                let inverse = moment
                    .pseudo_inverse(1e-12 * moment.norm())
                    .unwrap_or_else(|_| Matrix4::zeros());
                let fit: Vec<Vector4<f64>> = points
                    .iter()
                    .map(|&p| volumes[p] * (inverse * rest[p].push(1.0)))
                    .collect();
                let rest_term = points
                    .iter()
                    .zip(&fit)
                    .map(|(&p, g)| rest[p] * g.transpose())
                    .sum();
                (fit, rest_term)
            })
            .collect();
        let mut is_held = vec![false; layout.len()];
        for j in 0..count {
            for r in 0..3 {
                for c in 0..4 {
                    is_held[layout.index(j, r, c)] = true;
                }
            }
        }
        let free = (0..layout.len()).filter(|&i| !is_held[i]).collect();
        Ok(HeldRegions { layout, fits, free })
    }

    /// Indices of z that Newton solves for (all but the R held handles' 12 entries each).
    pub(crate) fn free_coordinates(&self) -> &[usize] {
        &self.free
    }

    /// Writes the held handles' entries of z for the targets `targets[r][p]` (m) of every region
    /// point, in the order the regions' points were given to [`HeldRegions::new`].
    pub(crate) fn prescribe(&self, z: &mut [f64], targets: &[Vec<Vector3<f64>>]) {
        let displacement = |r: usize| -> Matrix3x4<f64> {
            let (fit, rest_term) = &self.fits[r];
            fit.iter()
                .zip(&targets[r])
                .map(|(g, t)| t * g.transpose())
                .sum::<Matrix3x4<f64>>()
                - rest_term
        };
        let base = displacement(0);
        for region in 0..self.fits.len() {
            let transform = if region == 0 {
                base
            } else {
                displacement(region) - base
            };
            for r in 0..3 {
                for c in 0..4 {
                    z[self.layout.index(region, r, c)] = transform[(r, c)];
                }
            }
        }
    }
}
