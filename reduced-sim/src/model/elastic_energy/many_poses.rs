//! The elastic gradient at many poses at once, as matrix products over blocks of points
//! (what a cubature's training targets and its validation need: tens of poses on every point).
//!
//! With the poses side by side as `Z_all` (`4(m+1) × 3K`, pose k's z at columns 3k … 3k + 2)
//! and a block of points' gradient blocks side by side as `G_c` (`4(m+1) × 3c`),
//!
//! ```text
//! Z_allᵀ G_c   (3K × 3c):  entry (3k + r, 3i + s) = F_ik[r, s] − δ_rs,
//! G_c S_c      (4(m+1) × 3K):  S_c[3i + s, 3k + r] = w_i P_ik[r, s],
//! ```
//!
//! the second product is the block's share of every pose's gradient in z's layout. Two
//! products of inner dimension `4(m+1)` and `3c` per block instead of one small pass per
//! point and pose.

use faer::{Accum, Mat, MatMut, MatRef, Par};
use hyperelastic::HyperelasticMaterial;
use nalgebra::{DVector, Matrix3};
use rayon::prelude::*;

use crate::model::projected_dilatation::ProjectedDilatation;
use crate::model::reduced_model::ReducedModel;

/// Points per block: `Z_allᵀ G_c` is `3K × 3c` (1.1 MB for 60 poses).
const POINTS_PER_BLOCK: usize = 256;

/// The elastic gradients at several poses and, with a projected dilatation, its pressure
/// coefficients at each.
#[derive(Clone, Debug)]
pub(crate) struct ManyPoseGradients {
    /// `∂E_el/∂z` at each pose (12(m + 1) each).
    pub(crate) gradients: Vec<Vec<f64>>,
    /// `p̂` at each pose (P each); empty without a projected dilatation.
    pub(crate) pressure_coefficients: Vec<Vec<f64>>,
}

impl<M: HyperelasticMaterial> ReducedModel<M> {
    /// [`ReducedModel::elastic_gradient`] at each of `poses` (each of length 12(m + 1)): one
    /// `∂E_el/∂z` per pose (J per unit z, 12(m + 1), z's layout), formed as matrix products
    /// over blocks of points (module docs), over the elastic quadrature as the one-pose
    /// gradient is. Equal to the one-pose gradients up to the order of the sums (round-off),
    /// but for a projected dilatation's inversion barrier, which these leave out (it acts only
    /// where some point's J < [`crate::INVERSION_BARRIER_START`]; they are the forces a
    /// cubature is trained on).
    ///
    /// # Panics
    /// If a pose's length is not 12(m + 1).
    pub fn elastic_gradients(&self, poses: &[Vec<f64>]) -> Vec<Vec<f64>> {
        self.many_pose_gradients(poses).gradients
    }

    /// [`ReducedModel::elastic_gradients`] with the projected dilatation's pressure
    /// coefficients at each pose.
    pub(crate) fn many_pose_gradients(&self, poses: &[Vec<f64>]) -> ManyPoseGradients {
        let map = self.elastic_map();
        let layout = map.layout();
        assert!(
            poses.iter().all(|z| z.len() == layout.len()),
            "every pose has length 12(m + 1)"
        );
        let count = poses.len();
        if count == 0 {
            return ManyPoseGradients {
                gradients: Vec::new(),
                pressure_coefficients: Vec::new(),
            };
        }
        let all_poses: Vec<f64> = poses.iter().flat_map(|z| z.iter().copied()).collect();
        let strains = Strains {
            poses: MatRef::from_column_major_slice(&all_poses, layout.block_len(), 3 * count),
            gradients: map.gradient_matrix(),
            points: map.len(),
        };
        let (material, lame, weights) =
            (self.material(), self.elastic_lame(), self.elastic_weights());
        let (sum, pressure_coefficients) = match self.dilatation() {
            None => (
                strains.gradient_sum(|i, _, f| {
                    material.first_piola_kirchhoff(&lame[i], f) * weights[i]
                }),
                Vec::new(),
            ),
            Some(d) => {
                let coefficients = pressure_coefficients(d, &strains, count);
                let sum = strains.gradient_sum(|i, k, f| {
                    d.stress_at(
                        material.first_piola_kirchhoff(&lame[i], f),
                        f,
                        &coefficients[k],
                        i,
                    ) * weights[i]
                });
                (sum, coefficients)
            }
        };
        ManyPoseGradients {
            gradients: sum
                .chunks_exact(layout.len())
                .map(<[f64]>::to_vec)
                .collect(),
            pressure_coefficients,
        }
    }
}

/// The points' deformation gradients at every pose, a block of points at a time.
struct Strains<'a> {
    /// `Z_all` (`4(m+1) × 3K`).
    poses: MatRef<'a, f64>,
    /// Every point's G side by side (`4(m+1) × 3N`).
    gradients: MatRef<'a, f64>,
    /// N.
    points: usize,
}

impl Strains<'_> {
    /// The blocks of points, in order.
    fn blocks(&self) -> impl IndexedParallelIterator<Item = std::ops::Range<usize>> + use<> {
        let n = self.points;
        (0..n.div_ceil(POINTS_PER_BLOCK))
            .into_par_iter()
            .map(move |b| b * POINTS_PER_BLOCK..((b + 1) * POINTS_PER_BLOCK).min(n))
    }

    /// `visit(i, k, F_ik)` for every point i of `block` and pose k, points outermost.
    fn for_each(
        &self,
        block: std::ops::Range<usize>,
        mut visit: impl FnMut(usize, usize, &Matrix3<f64>),
    ) {
        let poses = self.poses.ncols() / 3;
        let mut strain = Mat::<f64>::zeros(3 * poses, 3 * block.len());
        faer::linalg::matmul::matmul(
            strain.as_mut(),
            Accum::Replace,
            self.poses.transpose(),
            self.gradients.subcols(3 * block.start, 3 * block.len()),
            1.0,
            Par::Seq,
        );
        for (local, i) in block.enumerate() {
            for k in 0..poses {
                let f = Matrix3::from_fn(|r, s| {
                    strain[(3 * k + r, 3 * local + s)] + f64::from(u8::from(r == s))
                });
                visit(i, k, &f);
            }
        }
    }

    /// `Σ_i G_i S_ikᵀ` for every pose k, `S_ik = stress(i, k, F_ik)`: the poses' gradients
    /// one after the other (`12(m+1) · K`), the blocks' shares added in block order.
    fn gradient_sum(
        &self,
        stress: impl Fn(usize, usize, &Matrix3<f64>) -> Matrix3<f64> + Sync,
    ) -> Vec<f64> {
        let (n4, columns) = (self.poses.nrows(), self.poses.ncols());
        let shares: Vec<Vec<f64>> = self
            .blocks()
            .map(|block| {
                let (first, len) = (block.start, block.len());
                let mut stacked = Mat::<f64>::zeros(3 * len, columns);
                self.for_each(block, |i, k, f| {
                    let p = stress(i, k, f);
                    for r in 0..3 {
                        for s in 0..3 {
                            stacked[(3 * (i - first) + s, 3 * k + r)] = p[(r, s)];
                        }
                    }
                });
                let mut share = vec![0.0; n4 * columns];
                faer::linalg::matmul::matmul(
                    MatMut::from_column_major_slice_mut(&mut share, n4, columns),
                    Accum::Replace,
                    self.gradients.subcols(3 * first, 3 * len),
                    stacked.as_ref(),
                    1.0,
                    Par::Seq,
                );
                share
            })
            .collect();
        let mut sum = vec![0.0; n4 * columns];
        for share in &shares {
            for (a, b) in sum.iter_mut().zip(share) {
                *a += b;
            }
        }
        sum
    }
}

/// `p̂_k = G⁻¹ r_k` at every pose k, `r_k = Σ_q w_q κ_q (J_qk − γ_q) q(X_q)` summed a block
/// of points at a time, the blocks' shares added in block order.
fn pressure_coefficients(
    d: &ProjectedDilatation,
    strains: &Strains<'_>,
    poses: usize,
) -> Vec<Vec<f64>> {
    let size = d.functions();
    let shares: Vec<Vec<f64>> = strains
        .blocks()
        .map(|block| {
            let mut share = vec![0.0; size * poses];
            strains.for_each(block, |q, k, f| {
                let wd = d.weighted_modulus(q) * (f.determinant() - d.rest_ratio(q));
                for (r, v) in share[k * size..(k + 1) * size]
                    .iter_mut()
                    .zip(d.pressure_row(q))
                {
                    *r += wd * v;
                }
            });
            share
        })
        .collect();
    let mut r = vec![0.0; size * poses];
    for share in &shares {
        for (a, b) in r.iter_mut().zip(share) {
            *a += b;
        }
    }
    r.chunks_exact(size)
        .map(|r| {
            (d.gram_inverse() * DVector::from_column_slice(r))
                .iter()
                .copied()
                .collect()
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use crate::ProjectedDilatationParams;
    use crate::model::analytic_field::{affine_pressure, analytic_model_with_spacing, probe_z};

    /// Largest relative difference of `many` from `single`, pose by pose.
    fn largest_relative_difference(many: &[Vec<f64>], single: &[Vec<f64>]) -> f64 {
        assert_eq!(many.len(), single.len());
        many.iter()
            .zip(single)
            .map(|(a, b)| {
                let scale = b.iter().map(|x| x * x).sum::<f64>().sqrt();
                assert!(scale > 0.0, "a pose with force");
                let difference: f64 = a.iter().zip(b).map(|(a, b)| (a - b) * (a - b)).sum();
                difference.sqrt() / scale
            })
            .fold(0.0, f64::max)
    }

    /// Poses of several amplitudes (the first at rest, where only a volumetric shift acts).
    fn poses(len: usize) -> Vec<Vec<f64>> {
        [0.005, 0.01, 0.02, 0.03]
            .iter()
            .map(|&amplitude| probe_z(len, amplitude))
            .collect()
    }

    /// 2000 points: eight blocks, the last one partial.
    #[test]
    fn gradients_at_many_poses_equal_the_one_pose_gradients() {
        let (model, _) = analytic_model_with_spacing(0.1);
        let poses = poses(model.deformation_map().layout().len());
        let single: Vec<Vec<f64>> = poses.iter().map(|z| model.elastic_gradient(z)).collect();
        let difference = largest_relative_difference(&model.elastic_gradients(&poses), &single);
        assert!(difference < 1e-12, "relative difference {difference:e}");
    }

    #[test]
    fn gradients_and_pressures_at_many_poses_equal_those_of_one_pose_with_a_projected_dilatation() {
        let (model, points) = analytic_model_with_spacing(0.1);
        let pressure = affine_pressure(&points);
        let model = model
            .with_projected_dilatation(pressure, ProjectedDilatationParams::default())
            .expect("independent functions");
        let poses = poses(model.deformation_map().layout().len());
        let many = model.many_pose_gradients(&poses);
        let single: Vec<Vec<f64>> = poses.iter().map(|z| model.elastic_gradient(z)).collect();
        let difference = largest_relative_difference(&many.gradients, &single);
        assert!(
            difference < 1e-12,
            "relative gradient difference {difference:e}"
        );
        let single_pressures: Vec<Vec<f64>> = poses
            .iter()
            .map(|z| {
                let deformation = model.elastic_deformation(z);
                let state = deformation.dilatation.expect("a dilatation");
                state.coefficients().to_vec()
            })
            .collect();
        let difference =
            largest_relative_difference(&many.pressure_coefficients, &single_pressures);
        assert!(
            difference < 1e-12,
            "relative pressure difference {difference:e}"
        );
    }
}
