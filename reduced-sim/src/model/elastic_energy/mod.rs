//! The reduced elastic energy `Σ_i v_i Ψ(F_i(z))`, its gradient and its Hessian, built from
//! dense matrix products over the per-point G_i (design §3.7, paper Eq. 2).

use faer::linalg::matmul::triangular::{self, BlockStructure};
use faer::{Accum, Mat, MatRef, Par};
use hyperelastic::{HyperelasticMaterial, LameParameters, Matrix9, Tangent};
use nalgebra::Matrix3;
use rayon::prelude::*;

use crate::model::deformation_map::{DeformationMap, deformation_gradient_of_block};
use crate::model::elastic_deformation::ElasticDeformation;
use crate::model::projected_dilatation::{DilatationState, InversionBarrier, ProjectedDilatation};
use crate::model::reduced_model::ReducedModel;

/// The three diagonal and three upper row-block pairs (r, q) of the reduced Hessian.
const BLOCK_PAIRS: [(usize, usize); 6] = [(0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2)];

/// Integration points per chunk of the Hessian assembly: `T^{rq}` of a chunk is
/// `4(m+1) × 3·POINTS_PER_CHUNK` (about 200 KB at m = 32), so it stays in cache between its
/// forming and its product.
const POINTS_PER_CHUNK: usize = 64;

impl<M: HyperelasticMaterial> ReducedModel<M> {
    /// Elastic energy `E_el(z) = Σ_i v_i Ψ(F_i(z))` (J), the sum over the elastic quadrature
    /// (`Σ_q w_q Ψ(F_q(z))` when one is set; the same for the gradient and Hessian below).
    ///
    /// # Panics
    /// If `z.len() != 12(m + 1)`.
    pub fn elastic_energy(&self, z: &[f64]) -> f64 {
        if self.dilatation().is_some() {
            // The projected term needs every J before any point's share: F formed once.
            return self.elastic_energy_at(&self.elastic_deformation(z));
        }
        let map = self.elastic_map();
        let z = map.z_columns(z);
        let (lame, weights, material) =
            (self.elastic_lame(), self.elastic_weights(), self.material());
        // Parts of fixed size in parallel, summed in part order: the sum does not depend on
        // the number of threads or on scheduling.
        let parts: Vec<f64> = map
            .point_parts()
            .map(|range| {
                pulp::Arch::new().dispatch(EnergyPart {
                    map,
                    z,
                    energy: &|i: usize, f: &Matrix3<f64>| {
                        weights[i] * material.energy_density(&lame[i], f)
                    },
                    range,
                })
            })
            .collect();
        parts.iter().sum()
    }

    /// [`ReducedModel::elastic_energy`] at a deformation already formed: at
    /// `self.elastic_deformation(z)` the same bits as `self.elastic_energy(z)` (the same
    /// parts, summed in the same order), without reading the points' `G_i` again.
    pub(crate) fn elastic_energy_at(&self, deformation: &ElasticDeformation) -> f64 {
        let f = &deformation.gradients;
        let (lame, weights, material) =
            (self.elastic_lame(), self.elastic_weights(), self.material());
        let parts: Vec<f64> = self
            .elastic_map()
            .point_parts()
            .map(|range| {
                let mut sum = 0.0;
                for i in range {
                    sum += weights[i] * material.energy_density(&lame[i], &f[i]);
                }
                sum
            })
            .collect();
        let pointwise: f64 = parts.iter().sum();
        match &deformation.dilatation {
            Some(state) => pointwise + state.energy,
            None => pointwise,
        }
    }

    /// Gradient `∂E_el/∂z` (J per unit z, length 12(m + 1), z's layout):
    /// `∂E_el/∂z_r = Σ_i v_i G_i P_i[r, :]ᵀ`, in one pass over the points that forms each
    /// `F_i = I + Zᵀ G_i` and adds the point's term while its `G_i` is in cache.
    ///
    /// # Panics
    /// If `z.len() != 12(m + 1)`.
    pub fn elastic_gradient(&self, z: &[f64]) -> Vec<f64> {
        if self.dilatation().is_some() {
            return self.elastic_gradient_at(&self.elastic_deformation(z));
        }
        weighted_elastic_gradient_at_z(
            self.material(),
            self.elastic_map(),
            self.elastic_lame(),
            self.elastic_weights(),
            z,
        )
    }

    /// [`ReducedModel::elastic_gradient`] at a deformation already formed: at
    /// `self.elastic_deformation(z)` the same bits as `self.elastic_gradient(z)`, without
    /// forming F again.
    pub(crate) fn elastic_gradient_at(&self, deformation: &ElasticDeformation) -> Vec<f64> {
        projected_elastic_gradient(
            self.material(),
            self.elastic_map(),
            self.elastic_lame(),
            self.elastic_weights(),
            self.dilatation().zip(deformation.dilatation.as_ref()),
            InversionBarrier::Included,
            &deformation.gradients,
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
        let mut h = Mat::zeros(z.len(), z.len());
        self.add_elastic_hessian_at(&self.elastic_deformation(z), tangent, &mut h);
        h
    }

    /// Adds the elastic Hessian at `deformation` to `h`.
    ///
    /// The points are split into one contiguous part per thread. Each part walks its points
    /// [`POINTS_PER_CHUNK`] at a time: the chunk's material tangents, then for each block pair
    /// (r, q) the chunk's `T^{rq}` (small enough to stay in cache) and one product
    /// `T^{rq} G_chunkᵀ` added to the part's own six blocks. The parts' blocks are then summed
    /// in part order, so the result does not depend on scheduling.
    pub(crate) fn add_elastic_hessian_at(
        &self,
        deformation: &ElasticDeformation,
        tangent: Tangent,
        h: &mut Mat<f64>,
    ) {
        let f = &deformation.gradients;
        let n = f.len();
        if n == 0 {
            return;
        }
        let map = self.elastic_map();
        let n4 = map.layout().block_len();
        let parts = rayon::current_num_threads().clamp(1, n.div_ceil(POINTS_PER_CHUNK));
        let part_len = n.div_ceil(parts);
        let shift = self.pressure_shifts(deformation);
        let blocks: Vec<[Mat<f64>; 6]> = (0..parts)
            .into_par_iter()
            .map(|part| {
                let range = part * part_len..((part + 1) * part_len).min(n);
                self.elastic_hessian_blocks(f, range, tangent, shift.as_deref())
            })
            .collect();
        for part in &blocks {
            for ((r, q), block) in BLOCK_PAIRS.into_iter().zip(part) {
                if r == q {
                    // Only the lower triangle of a diagonal block was computed.
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
        if let Some(d) = self.dilatation() {
            self.add_dilatation_rank_update(d, f, h);
        }
    }

    /// The discrete inf-sup constants (Brezzi–Bathe test) of the leading `sizes[k]` functions
    /// of the projected dilatation's pressure space, at rest, on the coordinates `free` (those
    /// Newton solves for):
    ///
    /// ```text
    /// β_n² = λ_min( B_n K₀⁻¹ B_nᵀ, G_n ),   B_n = ∂r_{1..n}/∂z at rest,   K₀ = rest Hessian less Bᵀ G⁻¹ B
    /// ```
    ///
    /// (K₀: the pointwise part, the shear stiffness; a relative ridge of 1e-10 keeps its rigid
    /// directions, in which B vanishes, invertible.) A space whose β_n falls as n grows is
    /// heading for locking. `None` without a projected dilatation or for sizes out of range.
    pub fn inf_sup_constants(&self, free: &[usize], sizes: &[usize]) -> Option<Vec<f64>> {
        let d = self.dilatation()?;
        let functions = d.functions();
        if sizes.iter().any(|&n| n == 0 || n > functions) || free.is_empty() {
            return None;
        }
        let rest_z = self.elastic_map().layout().rest();
        let f = vec![Matrix3::identity(); self.elastic_map().len()];
        let full = self.elastic_hessian(&rest_z, Tangent::Exact);
        let jacobian_t = self.dilatation_jacobian_transpose(d, &f);
        let nf = free.len();
        let b = nalgebra::DMatrix::from_fn(functions, nf, |a, k| jacobian_t[(free[k], a)]);
        let h = nalgebra::DMatrix::from_fn(nf, nf, |i, j| full[(free[i], free[j])]);
        let shear = h - b.transpose() * d.gram_inverse() * &b;
        let ridge = 1e-10 * shear.trace() / nf as f64;
        let shear =
            (&shear + shear.transpose()) * 0.5 + nalgebra::DMatrix::identity(nf, nf) * ridge;
        let factor = shear.cholesky()?;
        let solved = factor.solve(&b.transpose());
        let s = &b * solved;
        sizes
            .iter()
            .map(|&n| {
                let g = d.gram().view((0, 0), (n, n)).into_owned();
                let l = g.cholesky()?.l();
                let l_inv = l.try_inverse()?;
                let m = &l_inv * s.view((0, 0), (n, n)) * l_inv.transpose();
                let m = (&m + m.transpose()) * 0.5;
                Some(m.symmetric_eigenvalues().min().max(0.0).sqrt())
            })
            .collect()
    }

    /// Each elastic point's `κ_q (p_q − (J_q − γ_q))` in `deformation`
    /// ([`ProjectedDilatation::pressure_shift`]); `None` without a projected dilatation.
    fn pressure_shifts(&self, deformation: &ElasticDeformation) -> Option<Vec<f64>> {
        let n = deformation.gradients.len();
        deformation
            .dilatation
            .as_ref()
            .zip(self.dilatation())
            .map(|(state, d)| {
                (0..n)
                    .map(|q| d.pressure_shift(state, q, InversionBarrier::Included))
                    .collect()
            })
    }

    /// The weighted tangents `w_i ∂P/∂F(F_i)` of the elastic points `range` into `out` (one
    /// per point), shifted by the projected dilatation (`pressure_shift`, one per elastic
    /// point, when given) and treated as `tangent` asks.
    fn weighted_tangents(
        &self,
        f: &[Matrix3<f64>],
        range: std::ops::Range<usize>,
        tangent: Tangent,
        pressure_shift: Option<&[f64]>,
        out: &mut [Matrix9],
    ) {
        let (material, lame) = (self.material(), self.elastic_lame());
        let (start, end) = (range.start, range.end);
        match (pressure_shift, self.dilatation()) {
            (Some(shift), Some(d)) => {
                material.stress_derivatives(&lame[start..end], &f[start..end], Tangent::Exact, out);
                for (k, t) in out.iter_mut().enumerate() {
                    let i = start + k;
                    *t = ProjectedDilatation::shifted_tangent(
                        t,
                        &f[i],
                        d.cofactor_modulus(i, f[i].determinant()),
                        shift[i],
                        tangent,
                    );
                }
            }
            _ => material.stress_derivatives(&lame[start..end], &f[start..end], tangent, out),
        }
        for (d, w) in out.iter_mut().zip(&self.elastic_weights()[start..end]) {
            *d *= *w;
        }
    }

    /// The six blocks `Σ_i G_i A_i^{rq} G_iᵀ` (r, q in [`BLOCK_PAIRS`] order, each
    /// `4(m+1) × 4(m+1)`, the diagonal ones lower triangle only) over the points in `range`,
    /// on this thread.
    fn elastic_hessian_blocks(
        &self,
        f: &[Matrix3<f64>],
        range: std::ops::Range<usize>,
        tangent: Tangent,
        pressure_shift: Option<&[f64]>,
    ) -> [Mat<f64>; 6] {
        let map = self.elastic_map();
        let n4 = map.layout().block_len();
        let g = map.gradient_matrix();
        let mut blocks: [Mat<f64>; 6] = std::array::from_fn(|_| Mat::zeros(n4, n4));
        let mut t_buffer = vec![0.0; n4 * 3 * POINTS_PER_CHUNK];
        let mut tangents = [Matrix9::zeros(); POINTS_PER_CHUNK];
        // The loops below are compiled for the widest SIMD the CPU has (AVX2 / AVX-512 via
        // pulp's runtime dispatch): 1.4× faster assembly at m = 16 than baseline x86-64.
        let arch = pulp::Arch::new();
        for start in range.clone().step_by(POINTS_PER_CHUNK) {
            let end = (start + POINTS_PER_CHUNK).min(range.end);
            let len = end - start;
            self.weighted_tangents(f, start..end, tangent, pressure_shift, &mut tangents[..len]);
            let g_chunk = g.subcols(3 * start, 3 * len);
            for ((r, q), block) in BLOCK_PAIRS.into_iter().zip(blocks.iter_mut()) {
                let t_chunk = &mut t_buffer[..3 * n4 * len];
                arch.dispatch(|| {
                    for (k, ti) in t_chunk.chunks_exact_mut(3 * n4).enumerate() {
                        let gi = map.gradient_block(start + k);
                        let d = &tangents[k];
                        let (g0, rest) = gi.split_at(n4);
                        let (g1, g2) = rest.split_at(n4);
                        for t in 0..3 {
                            let col = &mut ti[t * n4..(t + 1) * n4];
                            let [a0, a1, a2] = [0, 1, 2].map(|s| d[(3 * s + r, 3 * t + q)]);
                            for (((c, x), y), w) in col.iter_mut().zip(g0).zip(g1).zip(g2) {
                                *c = a0 * x + a1 * y + a2 * w;
                            }
                        }
                    }
                });
                let t_mat = MatRef::from_column_major_slice(t_chunk, n4, 3 * len);
                if r == q {
                    // A^{rr} is symmetric, so is the block: its lower triangle only.
                    triangular::matmul(
                        block.as_mut(),
                        BlockStructure::TriangularLower,
                        Accum::Add,
                        t_mat,
                        BlockStructure::Rectangular,
                        g_chunk.transpose(),
                        BlockStructure::Rectangular,
                        1.0,
                        Par::Seq,
                    );
                } else {
                    faer::linalg::matmul::matmul(
                        block.as_mut(),
                        Accum::Add,
                        t_mat,
                        g_chunk.transpose(),
                        1.0,
                        Par::Seq,
                    );
                }
            }
        }
        blocks
    }
}

/// `Σ_i w_i G_i P_i(F_i)ᵀ` over the points of `map` (length 12(m + 1), z's layout), with
/// Lamé parameters `lame`, weights `weights` (volumes or quadrature weights, m³) and
/// deformation gradients `f`: the elastic gradient of [`ReducedModel::elastic_gradient`].
pub(crate) fn weighted_elastic_gradient<M: HyperelasticMaterial>(
    material: &M,
    map: &DeformationMap,
    lame: &[LameParameters],
    weights: &[f64],
    f: &[Matrix3<f64>],
) -> Vec<f64> {
    accumulate_point_gradients(map, PointDeformation::Given(f), |i, f| {
        material.first_piola_kirchhoff(&lame[i], f) * weights[i]
    })
}

/// [`weighted_elastic_gradient`] with the projected volumetric term `dilatation` in its
/// `state` at `f`, when given: each point's stress is `P(F_i) + κ_i (p_i − (J_i − γ_i) +
/// β'(J_i)) cof F_i` ([`ProjectedDilatation::shifted_stress`]), the inversion barrier's β'
/// as `barrier` says. With the barrier, the elastic gradient of
/// [`ReducedModel::elastic_gradient`] on a model with a projected dilatation.
pub(crate) fn projected_elastic_gradient<M: HyperelasticMaterial>(
    material: &M,
    map: &DeformationMap,
    lame: &[LameParameters],
    weights: &[f64],
    dilatation: Option<(&ProjectedDilatation, &DilatationState)>,
    barrier: InversionBarrier,
    f: &[Matrix3<f64>],
) -> Vec<f64> {
    let Some((d, state)) = dilatation else {
        return weighted_elastic_gradient(material, map, lame, weights, f);
    };
    accumulate_point_gradients(map, PointDeformation::Given(f), |i, f| {
        ProjectedDilatation::shifted_stress(
            material.first_piola_kirchhoff(&lame[i], f),
            f,
            d.pressure_shift(state, i, barrier),
        ) * weights[i]
    })
}

/// [`weighted_elastic_gradient`] at the reduced coordinates `z` (length 12(m + 1)), each
/// point's `F_i = I + Zᵀ G_i` formed from its `G_i` while that is in cache for the point's
/// gradient term: one pass over G instead of two (`F` for every point, then `G · P̃`).
///
/// # Panics
/// If `z.len() != 12(m + 1)`.
pub(crate) fn weighted_elastic_gradient_at_z<M: HyperelasticMaterial>(
    material: &M,
    map: &DeformationMap,
    lame: &[LameParameters],
    weights: &[f64],
    z: &[f64],
) -> Vec<f64> {
    accumulate_point_gradients(map, PointDeformation::FromZ(map.z_columns(z)), |i, f| {
        material.first_piola_kirchhoff(&lame[i], f) * weights[i]
    })
}

/// Where [`accumulate_point_gradients`] takes each point's deformation gradient from.
#[derive(Clone, Copy)]
enum PointDeformation<'a> {
    /// `F_i` already formed.
    Given(&'a [Matrix3<f64>]),
    /// `F_i = I + Zᵀ G_i` from Z's three columns (each `4(m+1)`).
    FromZ([&'a [f64]; 3]),
}

/// `Σ_i G_i S_iᵀ` (length 12(m + 1), z's layout: entry `r·4(m+1) + a` is
/// `Σ_i Σ_s G_i[a, s] S_i[r, s]`) for the 3 × 3 `S_i = stress(i, F_i)`, G_i column-major
/// `4(m+1) × 3`. The points are taken
/// [`POINTS_PER_PART`](crate::model::deformation_map::POINTS_PER_PART) at a time in parallel, each G_i
/// read once; the parts' sums are added in part order.
fn accumulate_point_gradients(
    map: &DeformationMap,
    deformation: PointDeformation<'_>,
    stress: impl Fn(usize, &Matrix3<f64>) -> Matrix3<f64> + Sync,
) -> Vec<f64> {
    let n4 = map.layout().block_len();
    let parts: Vec<Vec<f64>> = map
        .point_parts()
        .map(|range| {
            let mut sum = vec![0.0; 3 * n4];
            // Compiled for the widest SIMD the CPU has (pulp's runtime dispatch).
            pulp::Arch::new().dispatch(GradientPart {
                map,
                deformation,
                stress: &stress,
                range,
                sum: &mut sum,
            });
            sum
        })
        .collect();
    let mut gradient = vec![0.0; 3 * n4];
    for part in &parts {
        for (g, p) in gradient.iter_mut().zip(part) {
            *g += p;
        }
    }
    gradient
}

/// One part of [`accumulate_point_gradients`]: the points in `range`, added to `sum`. A
/// [`pulp::WithSimd`] whose body is `inline(always)`, so that all of it is compiled inside the
/// dispatched, SIMD-enabled function (a closure's body is not inlined there).
struct GradientPart<'a, S> {
    map: &'a DeformationMap,
    deformation: PointDeformation<'a>,
    stress: &'a S,
    range: std::ops::Range<usize>,
    sum: &'a mut [f64],
}

impl<S: Fn(usize, &Matrix3<f64>) -> Matrix3<f64>> pulp::WithSimd for GradientPart<'_, S> {
    type Output = ();

    #[inline(always)]
    fn with_simd<Simd: pulp::Simd>(self, simd: Simd) {
        let GradientPart {
            map,
            deformation,
            stress,
            range,
            sum,
        } = self;
        let n4 = map.layout().block_len();
        let (s0, rest) = sum.split_at_mut(n4);
        let (s1, s2) = rest.split_at_mut(n4);
        for i in range {
            let gi = map.gradient_block(i);
            let p = match deformation {
                PointDeformation::Given(f) => stress(i, &f[i]),
                PointDeformation::FromZ(z) => {
                    stress(i, &deformation_gradient_of_block(simd, z, gi))
                }
            };
            let (g0, rest) = gi.split_at(n4);
            let (g1, g2) = rest.split_at(n4);
            for (r, out) in [&mut *s0, &mut *s1, &mut *s2].into_iter().enumerate() {
                let [p0, p1, p2] = [p[(r, 0)], p[(r, 1)], p[(r, 2)]];
                for (((o, x), y), w) in out.iter_mut().zip(g0).zip(g1).zip(g2) {
                    *o += x * p0 + y * p1 + w * p2;
                }
            }
        }
    }
}

/// One part of [`ReducedModel::elastic_energy`]: `Σ_i energy(i, F_i)` over the points in
/// `range`, `F_i = I + Zᵀ G_i`, in index order ([`pulp::WithSimd`] as [`GradientPart`]).
struct EnergyPart<'a, E> {
    map: &'a DeformationMap,
    z: [&'a [f64]; 3],
    energy: &'a E,
    range: std::ops::Range<usize>,
}

impl<E: Fn(usize, &Matrix3<f64>) -> f64> pulp::WithSimd for EnergyPart<'_, E> {
    type Output = f64;

    #[inline(always)]
    fn with_simd<Simd: pulp::Simd>(self, simd: Simd) -> f64 {
        let mut sum = 0.0;
        for i in self.range {
            let f = deformation_gradient_of_block(simd, self.z, self.map.gradient_block(i));
            sum += (self.energy)(i, &f);
        }
        sum
    }
}

mod dilatation_jacobian;
mod hessian_diagonal;
mod many_poses;
#[cfg(test)]
mod tests;
