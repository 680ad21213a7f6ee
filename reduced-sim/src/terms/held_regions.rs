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
//! The fit is made about the region's centroid c_r (`D_r = [A | t − A c_r]` from the fit of
//! `A (X − c_r) + t`). A flat region (one layer of points, unit normal n = t₁ × t₂) leaves
//! `F n` undetermined (`F = I + A`); it is completed as `F n = F t₁ × F t₂ / |F t₁ × F t₂|`,
//! so that a rigid motion of the region (a placed or turning object) is fitted by that rigid
//! motion, not a shear.
//!
//! and every region point sits on its target whenever the targets are an affine motion of the
//! region (rest, rigid motions, the Twist's rotating end); otherwise the residual of the fit is
//! the drift [`crate::Simulator::max_held_deviation`] reports.

use nalgebra::{Matrix3, Matrix3x4, Matrix4, SymmetricEigen, Vector3, Vector4};

use crate::model::reduced_coordinates::ReducedLayout;
use crate::scene_error::SceneError;

/// How far (absolute, dimensionless) the basis's weights on a region may be from 1/0 for the
/// region to count as held by it. The weights of [`skin_eigen::build_basis_with_regions`] are
/// exact to about 1e-7.
pub(crate) const HELD_WEIGHT_TOLERANCE: f64 = 1e-5;

/// One region's least-squares fit of an affine displacement to its targets.
struct RegionFit {
    /// `g_p = v_p G⁺ X̃_p` per point.
    fit: Vec<Vector4<f64>>,
    /// `Σ_p X_p g_pᵀ`.
    rest_term: Matrix3x4<f64>,
    /// `U = [[I, −c], [0, 1]]`: from the centred fit to `D` on `X̄`.
    uncentre: Matrix4<f64>,
    /// For a flat region, two orthonormal directions (t₁, t₂) in its plane.
    plane: Option<(Vector3<f64>, Vector3<f64>)>,
}

impl RegionFit {
    /// The centred fit `[A | t]` with, for a flat region, `F n` completed from its plane.
    fn completed(&self, mut fit: Matrix3x4<f64>) -> Matrix3x4<f64> {
        let Some((t1, t2)) = self.plane else {
            return fit;
        };
        let f = Matrix3::identity() + fit.fixed_view::<3, 3>(0, 0);
        let normal = t1.cross(&t2);
        let across = (f * t1).cross(&(f * t2));
        let length = across.norm();
        if !(length > 0.0 && length.is_finite()) {
            return fit;
        }
        // F ← F + (F_n − F n) nᵀ: only the normal column changes.
        let f = f + (across / length - f * normal) * normal.transpose();
        fit.fixed_view_mut::<3, 3>(0, 0)
            .copy_from(&(f - Matrix3::identity()));
        fit
    }
}

/// The regions' transforms, prepared once.
pub(crate) struct HeldRegions {
    layout: ReducedLayout,
    /// Per region: per point `g_p = v_p G_r⁺ X̃_p` with `X̃_p = [X_p − c_r; 1]` and
    /// `G_r = Σ v X̃ X̃ᵀ`, the rest term `Σ_p X_p g_pᵀ`, and `U_r = [[I, −c_r], [0, 1]]`, so that
    /// `D_r = (Σ_p t_p g_pᵀ − Σ_p X_p g_pᵀ) U_r` for targets `t_p`.
    fits: Vec<RegionFit>,
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
                let volume: f64 = points.iter().map(|&p| volumes[p]).sum();
                let centroid: Vector3<f64> = points
                    .iter()
                    .map(|&p| rest[p] * volumes[p])
                    .sum::<Vector3<f64>>()
                    / volume;
                let centred = |p: usize| (rest[p] - centroid).push(1.0);
                // Centred, the moment Σ v X̃ X̃ᵀ is block diagonal: the spread S = Σ v (X − c)(X − c)ᵀ
                // and the volume. S is inverted on its range (a flat region leaves its normal
                // out; a point or a line more), so the fit keeps the identity there.
                let spread_matrix: Matrix3<f64> = points
                    .iter()
                    .map(|&p| volumes[p] * (rest[p] - centroid) * (rest[p] - centroid).transpose())
                    .sum();
                let spread = SymmetricEigen::new(spread_matrix);
                let largest = spread.eigenvalues.max();
                let mut spread_inverse = Matrix3::zeros();
                for (i, &lambda) in spread.eigenvalues.iter().enumerate() {
                    if lambda > 1e-12 * largest {
                        let e = spread.eigenvectors.column(i);
                        spread_inverse += e * e.transpose() / lambda;
                    }
                }
                let mut inverse = Matrix4::zeros();
                inverse
                    .fixed_view_mut::<3, 3>(0, 0)
                    .copy_from(&spread_inverse);
                inverse[(3, 3)] = 1.0 / volume;
                let fit: Vec<Vector4<f64>> = points
                    .iter()
                    .map(|&p| volumes[p] * (inverse * centred(p)))
                    .collect();
                let rest_term = points
                    .iter()
                    .zip(&fit)
                    .map(|(&p, g)| rest[p] * g.transpose())
                    .sum();
                let mut uncentre = Matrix4::identity();
                for r in 0..3 {
                    uncentre[(r, 3)] = -centroid[r];
                }
                let order = {
                    let mut order = [0, 1, 2];
                    order.sort_by(|&a, &b| spread.eigenvalues[a].total_cmp(&spread.eigenvalues[b]));
                    order
                };
                let flat = spread.eigenvalues[order[0]] <= 1e-12 * spread.eigenvalues[order[2]]
                    && spread.eigenvalues[order[1]] > 1e-12 * spread.eigenvalues[order[2]];
                let plane = flat.then(|| {
                    let t1: Vector3<f64> = spread.eigenvectors.column(order[1]).into_owned();
                    let t2: Vector3<f64> = spread.eigenvectors.column(order[2]).into_owned();
                    (t1, t2)
                });
                RegionFit {
                    fit,
                    rest_term,
                    uncentre,
                    plane,
                }
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
            let region = &self.fits[r];
            region.completed(
                region
                    .fit
                    .iter()
                    .zip(&targets[r])
                    .map(|(g, t)| t * g.transpose())
                    .sum::<Matrix3x4<f64>>()
                    - region.rest_term,
            ) * region.uncentre
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

#[cfg(test)]
mod tests {
    use nalgebra::{Rotation3, UnitQuaternion};

    use super::*;

    /// The affine map `x = X + Z_0 X̄` the constant handle gives a region point.
    fn moved(layout: &ReducedLayout, z: &[f64], x: &Vector3<f64>) -> (Vector3<f64>, Matrix3<f64>) {
        let d = Matrix3x4::from_fn(|r, c| z[layout.index(0, r, c)]);
        (
            x + d * x.push(1.0),
            Matrix3::identity() + d.fixed_view::<3, 3>(0, 0),
        )
    }

    /// A flat region (one layer of points) far from the origin, carried by a rotation and a
    /// translation, or a thick one: the fitted transform is that rigid motion, with no shear
    /// along the flat region's normal.
    #[test]
    fn a_rigid_motion_of_a_flat_or_thick_region_away_from_the_origin_is_fitted_exactly() {
        let layout = ReducedLayout::new(2);
        let rotation = UnitQuaternion::from_euler_angles(0.4, -0.3, 0.7);
        let shift = Vector3::new(-0.15, 1.45, 0.3);
        for layers in [1, 3] {
            let rest: Vec<Vector3<f64>> = (0..6)
                .flat_map(|i| (0..5).map(move |k| (i, k)))
                .flat_map(|(i, k)| {
                    (0..layers).map(move |l| {
                        Vector3::new(
                            2.0 + 0.1 * i as f64,
                            1.3 + 0.05 * l as f64,
                            -0.7 + 0.1 * k as f64,
                        )
                    })
                })
                .collect();
            let points: Vec<usize> = (0..rest.len()).collect();
            let volumes = vec![1e-3; rest.len()];
            let held = HeldRegions::new(layout, &[points], &rest, &volumes, |_, handle| {
                f64::from(u8::from(handle == 0))
            })
            .unwrap();
            let targets: Vec<Vector3<f64>> = rest.iter().map(|x| rotation * x + shift).collect();
            let mut z = layout.rest();
            held.prescribe(&mut z, std::slice::from_ref(&targets));
            for (x, target) in rest.iter().zip(&targets) {
                let (x, f) = moved(&layout, &z, x);
                assert!(
                    (x - target).norm() < 1e-11,
                    "{layers} layers: {x} vs {target}"
                );
                let expected = Rotation3::from(rotation).into_inner();
                assert!((f - expected).norm() < 1e-10, "{layers} layers: F = {f}");
            }
        }
    }
}
