//! The reduced elastic energy `Σ_i v_i Ψ(F_i(z))`, its gradient and its Hessian, built from
//! dense matrix products over the per-point G_i (DESIGN 3.7, paper Eq. 2).

use faer::linalg::matmul::triangular::{self, BlockStructure};
use faer::{Accum, Mat, MatRef, Par};
use hyperelastic::{HyperelasticMaterial, LameParameters, Matrix9, Tangent};
use nalgebra::Matrix3;
use rayon::prelude::*;

use crate::deformation_map::DeformationMap;
use crate::reduced_model::ReducedModel;

/// The three diagonal and three upper row-block pairs (r, q) of the reduced Hessian.
const BLOCK_PAIRS: [(usize, usize); 6] = [(0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2)];

/// Integration points per parallel task when forming `T^{rq}`.
const POINTS_PER_TASK: usize = 32;

impl<M: HyperelasticMaterial> ReducedModel<M> {
    /// Elastic energy `E_el(z) = Σ_i v_i Ψ(F_i(z))` (J), the sum over the elastic quadrature
    /// (`Σ_q w_q Ψ(F_q(z))` when one is set; the same for the gradient and Hessian below).
    ///
    /// # Panics
    /// If `z.len() != 12(m + 1)`.
    pub fn elastic_energy(&self, z: &[f64]) -> f64 {
        let f = self.elastic_map().deformation_gradients(z);
        self.elastic_energy_at(&f)
    }

    /// Elastic energy from precomputed deformation gradients (J).
    pub(crate) fn elastic_energy_at(&self, f: &[Matrix3<f64>]) -> f64 {
        let lame = self.elastic_lame();
        let material = self.material();
        // Per-point terms in parallel, summed in index order: a parallel `sum` would associate
        // differently from run to run and make trajectories differ in the last bits.
        let terms: Vec<f64> = f
            .par_iter()
            .zip(lame.par_iter())
            .zip(self.elastic_weights().par_iter())
            .map(|((f, p), v)| v * material.energy_density(p, f))
            .collect();
        terms.iter().sum()
    }

    /// Gradient `∂E_el/∂z` (J per unit z, length 12(m + 1), z's layout):
    /// `∂E_el/∂z_r = Σ_i v_i G_i P_i[r, :]ᵀ`, computed as the product `G · P̃` with
    /// `P̃[3i + s, r] = v_i P_i[r, s]` (`4(m+1) × 3N` times `3N × 3`).
    ///
    /// # Panics
    /// If `z.len() != 12(m + 1)`.
    pub fn elastic_gradient(&self, z: &[f64]) -> Vec<f64> {
        let f = self.elastic_map().deformation_gradients(z);
        self.elastic_gradient_at(&f)
    }

    pub(crate) fn elastic_gradient_at(&self, f: &[Matrix3<f64>]) -> Vec<f64> {
        weighted_elastic_gradient(
            self.material(),
            self.elastic_map(),
            self.elastic_lame(),
            self.elastic_weights(),
            f,
        )
    }

    /// Hessian `∂²E_el/∂z²` (`12(m+1) × 12(m+1)`, symmetric), exact or with PSD-projected
    /// material tangents (then PSD itself).
    ///
    /// Block (r, q) of size `4(m+1)` is `Σ_i G_i A_i^{rq} G_iᵀ` with
    /// `A_i^{rq}[s, t] = v_i ∂²Ψ/∂F_rs∂F_qt`: each is formed as `T^{rq} Gᵀ`, one GEMM of inner
    /// dimension 3N, where `T^{rq}[:, 3i + t] = Σ_s G_i[:, s] A_i^{rq}[s, t]`. Six blocks are
    /// computed, the other three are their transposes.
    ///
    /// # Panics
    /// If `z.len() != 12(m + 1)`.
    pub fn elastic_hessian(&self, z: &[f64], tangent: Tangent) -> Mat<f64> {
        let f = self.elastic_map().deformation_gradients(z);
        let mut h = Mat::zeros(z.len(), z.len());
        self.add_elastic_hessian_at(&f, tangent, &mut h);
        h
    }

    /// Adds the elastic Hessian at the deformation gradients `f` to `h`.
    pub(crate) fn add_elastic_hessian_at(
        &self,
        f: &[Matrix3<f64>],
        tangent: Tangent,
        h: &mut Mat<f64>,
    ) {
        let n = f.len();
        let material = self.material();
        let lame = self.elastic_lame();
        let volumes = self.elastic_weights();
        let mut tangents = vec![Matrix9::zeros(); n];
        tangents.par_iter_mut().enumerate().for_each(|(i, d)| {
            let raw = match tangent {
                Tangent::Exact => material.stress_derivative(&lame[i], &f[i]),
                Tangent::ProjectedPsd => material.projected_stress_derivative(&lame[i], &f[i]),
            };
            *d = raw * volumes[i];
        });
        let map = self.elastic_map();
        let n4 = map.layout().block_len();
        let g = map.gradient_matrix();
        let mut t_buffer = vec![0.0; n4 * 3 * n];
        let mut block = Mat::<f64>::zeros(n4, n4);
        // The loops below are compiled for the widest SIMD the CPU has (AVX2 / AVX-512 via
        // pulp's runtime dispatch): 1.4× faster assembly at m = 16 than baseline x86-64.
        let arch = pulp::Arch::new();
        for (r, q) in BLOCK_PAIRS {
            t_buffer
                .par_chunks_mut(3 * n4 * POINTS_PER_TASK)
                .enumerate()
                .for_each(|(chunk, t_chunk)| {
                    arch.dispatch(|| {
                        for (k, ti) in t_chunk.chunks_exact_mut(3 * n4).enumerate() {
                            let i = chunk * POINTS_PER_TASK + k;
                            let gi = map.gradient_block(i);
                            let d = &tangents[i];
                            for t in 0..3 {
                                let col = &mut ti[t * n4..(t + 1) * n4];
                                let [a0, a1, a2] = [0, 1, 2].map(|s| d[(3 * s + r, 3 * t + q)]);
                                let (g0, rest) = gi.split_at(n4);
                                let (g1, g2) = rest.split_at(n4);
                                for (((c, x), y), w) in col.iter_mut().zip(g0).zip(g1).zip(g2) {
                                    *c = a0 * x + a1 * y + a2 * w;
                                }
                            }
                        }
                    })
                });
            let t_mat = MatRef::from_column_major_slice(&t_buffer, n4, 3 * n);
            if r == q {
                // A^{rr} is symmetric, so is the block: compute its lower triangle only.
                triangular::matmul(
                    block.as_mut(),
                    BlockStructure::TriangularLower,
                    Accum::Replace,
                    t_mat,
                    BlockStructure::Rectangular,
                    g.transpose(),
                    BlockStructure::Rectangular,
                    1.0,
                    Par::rayon(0),
                );
                for b in 0..n4 {
                    for a in b..n4 {
                        let v = block[(a, b)];
                        h[(r * n4 + a, r * n4 + b)] += v;
                        if a != b {
                            h[(r * n4 + b, r * n4 + a)] += v;
                        }
                    }
                }
            } else {
                faer::linalg::matmul::matmul(
                    block.as_mut(),
                    Accum::Replace,
                    t_mat,
                    g.transpose(),
                    1.0,
                    Par::rayon(0),
                );
                for b in 0..n4 {
                    for a in 0..n4 {
                        let v = block[(a, b)];
                        h[(r * n4 + a, q * n4 + b)] += v;
                        h[(q * n4 + b, r * n4 + a)] += v;
                    }
                }
            }
        }
    }
}

/// `Σ_i w_i G_i P_i(F_i)ᵀ` over the points of `map` (length 12(m + 1), z's layout), with
/// Lamé parameters `lame`, weights `weights` (volumes or quadrature weights, m³) and
/// deformation gradients `f`: the elastic gradient of [`ReducedModel::elastic_gradient`],
/// computed as the product `G · P̃` with `P̃[3i + s, r] = w_i P_i[r, s]` (`4(m+1) × 3N` times
/// `3N × 3`).
pub(crate) fn weighted_elastic_gradient<M: HyperelasticMaterial>(
    material: &M,
    map: &DeformationMap,
    lame: &[LameParameters],
    weights: &[f64],
    f: &[Matrix3<f64>],
) -> Vec<f64> {
    let n = f.len();
    // Per point, the column-major storage of w_i P_i: entry 3s + r is w_i P_i[r, s], so the
    // whole buffer is P̃ᵀ as a column-major 3 × 3N matrix.
    let mut stresses_t = vec![0.0; 9 * n];
    stresses_t
        .par_chunks_mut(9)
        .enumerate()
        .for_each(|(i, out)| {
            let p = material.first_piola_kirchhoff(&lame[i], &f[i]) * weights[i];
            out.copy_from_slice(p.as_slice());
        });
    let n4 = map.layout().block_len();
    let mut gradient = vec![0.0; 3 * n4];
    faer::linalg::matmul::matmul(
        faer::MatMut::from_column_major_slice_mut(&mut gradient, n4, 3),
        Accum::Replace,
        map.gradient_matrix(),
        MatRef::from_column_major_slice(&stresses_t, 3, 3 * n).transpose(),
        1.0,
        Par::rayon(0),
    );
    gradient
}
