//! The linear-blend-skinning deformation map at a fixed set of rest points, precomputed once
//! (design §3.7, paper Eq. 1).

use std::ops::Range;

use faer::{Accum, MatRef, Par};
use nalgebra::{Matrix3, Vector3};
use rayon::prelude::*;
use thiserror::Error;

use crate::model::reduced_coordinates::ReducedLayout;
use crate::model::skinning_field::SkinningField;

/// The weights could not be turned into a deformation map.
#[derive(Debug, Error)]
pub enum DeformationMapError {
    /// The basis failed to evaluate at the points.
    #[error("the skinning basis could not be evaluated at the points: {0}")]
    Basis(#[source] Box<dyn std::error::Error + Send + Sync>),
    /// A rest point has a NaN or infinite coordinate.
    #[error("rest point {point} is not finite: {position:?}")]
    NonFinitePoint {
        /// Index of the point.
        point: usize,
        /// Its coordinates.
        position: [f64; 3],
    },
    /// The basis returned a NaN or infinite weight or weight gradient.
    #[error("the basis returned a non-finite weight or gradient at point {point}")]
    NonFiniteWeight {
        /// Index of the point.
        point: usize,
    },
    /// Column 0 of the weights is not the constant handle 1 (the [`SkinningField`] contract).
    #[error("handle 0 must be the constant weight 1, but W⁰ = {value} at point {point}")]
    ConstantHandleMissing {
        /// Index of the first offending point.
        point: usize,
        /// The weight found there.
        value: f64,
    },
    /// The basis returned matrices of the wrong shape.
    #[error("the basis returned weights of shape {rows}×{cols}, expected {points}×{handles}")]
    WrongShape {
        /// Rows returned.
        rows: usize,
        /// Columns returned.
        cols: usize,
        /// Points asked for.
        points: usize,
        /// Handles the basis declared.
        handles: usize,
    },
}

/// `x_i(z)` and `F_i(z)` at N rest points, both linear in z:
///
/// ```text
/// x_i = X_i + Σ_r e_r b_iᵀ z_r,          b_i[4j + c] = W^j(X_i) X̄_i[c]            (4(m+1))
/// F_i = I + Zᵀ G_i,  Z = [z_0 z_1 z_2],  G_i[4j + c, s] = ∂_s W^j(X_i) X̄_i[c] + W^j(X_i) δ_cs
/// ```
///
/// (G_i is `4(m+1) × 3`, the paper's `G_ij = X̄ ∇W^jᵀ + W^j [I₃; 0]` stacked over handles.)
/// Stored as two dense column-major matrices, `B = [b_1 … b_N]` (`4(m+1) × N`) and
/// `G = [G_1 … G_N]` (`4(m+1) × 3N`), so positions and deformation gradients of all points are
/// one matrix product each, and per-frame output never re-evaluates the basis.
#[derive(Clone, Debug)]
pub struct DeformationMap {
    layout: ReducedLayout,
    rest: Vec<Vector3<f64>>,
    /// B, column-major, `block_len × N`.
    b: Vec<f64>,
    /// G, column-major, `block_len × 3N`.
    g: Vec<f64>,
}

impl DeformationMap {
    /// Evaluates the basis at `rest` (m) and precomputes B and G.
    ///
    /// # Errors
    /// [`DeformationMapError`]: non-finite points or weights, a basis error, or a basis whose
    /// handle 0 is not the constant 1.
    pub fn new<B: SkinningField + ?Sized>(
        basis: &B,
        rest: &[Vector3<f64>],
    ) -> Result<Self, DeformationMapError> {
        if let Some(point) = rest.iter().position(|p| !p.iter().all(|v| v.is_finite())) {
            return Err(DeformationMapError::NonFinitePoint {
                point,
                position: rest[point].into(),
            });
        }
        let handles = basis.handles();
        let layout = ReducedLayout::new(handles);
        let weights = basis
            .evaluate(rest)
            .map_err(|e| DeformationMapError::Basis(Box::new(e)))?;
        let w = &weights.weights;
        let shapes_ok = std::iter::once(w)
            .chain(weights.gradients.iter())
            .all(|m| m.nrows() == rest.len() && m.ncols() == handles);
        if !shapes_ok {
            return Err(DeformationMapError::WrongShape {
                rows: w.nrows(),
                cols: w.ncols(),
                points: rest.len(),
                handles,
            });
        }
        for i in 0..rest.len() {
            let finite = (0..handles).all(|j| {
                w[(i, j)].is_finite() && weights.gradients.iter().all(|g| g[(i, j)].is_finite())
            });
            if !finite {
                return Err(DeformationMapError::NonFiniteWeight { point: i });
            }
            let gradient_zero = weights.gradients.iter().all(|g| g[(i, 0)].abs() <= 1e-12);
            if (w[(i, 0)] - 1.0).abs() > 1e-12 || !gradient_zero {
                return Err(DeformationMapError::ConstantHandleMissing {
                    point: i,
                    value: w[(i, 0)],
                });
            }
        }
        let n4 = layout.block_len();
        let n = rest.len();
        let mut b = vec![0.0; n4 * n];
        let mut g = vec![0.0; n4 * 3 * n];
        b.par_chunks_mut(n4)
            .zip(g.par_chunks_mut(3 * n4))
            .enumerate()
            .for_each(|(i, (bi, gi))| {
                let xbar = [rest[i].x, rest[i].y, rest[i].z, 1.0];
                for j in 0..handles {
                    let wj = w[(i, j)];
                    for c in 0..4 {
                        bi[4 * j + c] = wj * xbar[c];
                        for s in 0..3 {
                            let kronecker = if c == s { wj } else { 0.0 };
                            gi[s * n4 + 4 * j + c] =
                                weights.gradients[s][(i, j)] * xbar[c] + kronecker;
                        }
                    }
                }
            });
        Ok(DeformationMap {
            layout,
            rest: rest.to_vec(),
            b,
            g,
        })
    }

    /// The map at a subset of its points (`indices` into this map's points, in that order):
    /// the columns of B and G copied, no basis evaluation.
    ///
    /// # Panics
    /// If an index is out of range.
    pub fn subset(&self, indices: &[usize]) -> DeformationMap {
        let n4 = self.layout.block_len();
        let mut b = Vec::with_capacity(n4 * indices.len());
        let mut g = Vec::with_capacity(3 * n4 * indices.len());
        for &i in indices {
            b.extend_from_slice(self.position_row(i));
            g.extend_from_slice(self.gradient_block(i));
        }
        DeformationMap {
            layout: self.layout,
            rest: indices.iter().map(|&i| self.rest[i]).collect(),
            b,
            g,
        }
    }

    /// The layout of z.
    pub fn layout(&self) -> ReducedLayout {
        self.layout
    }

    /// Number of points N.
    pub fn len(&self) -> usize {
        self.rest.len()
    }

    /// True when the map has no points.
    pub fn is_empty(&self) -> bool {
        self.rest.is_empty()
    }

    /// Rest positions X_i (m).
    pub fn rest_positions(&self) -> &[Vector3<f64>] {
        &self.rest
    }

    /// B (`4(m+1) × N`, column i is b_i).
    pub fn position_matrix(&self) -> MatRef<'_, f64> {
        MatRef::from_column_major_slice(&self.b, self.layout.block_len(), self.len())
    }

    /// G (`4(m+1) × 3N`, columns 3i..3i+3 are G_i).
    pub fn gradient_matrix(&self) -> MatRef<'_, f64> {
        MatRef::from_column_major_slice(&self.g, self.layout.block_len(), 3 * self.len())
    }

    /// G's storage, column-major (`4(m+1) · 3N` values; e.g. for content hashes).
    pub fn gradient_matrix_slice(&self) -> &[f64] {
        &self.g
    }

    /// b_i (length `4(m+1)`).
    pub fn position_row(&self, i: usize) -> &[f64] {
        let n4 = self.layout.block_len();
        &self.b[i * n4..(i + 1) * n4]
    }

    /// G_i, column-major `4(m+1) × 3`.
    pub fn gradient_block(&self, i: usize) -> &[f64] {
        let n4 = self.layout.block_len();
        &self.g[3 * i * n4..3 * (i + 1) * n4]
    }

    /// Deformed positions `x_i(z)` (m).
    ///
    /// # Panics
    /// If `z.len() != 12(m + 1)`.
    pub fn positions(&self, z: &[f64]) -> Vec<Vector3<f64>> {
        self.rest
            .iter()
            .zip(self.displacements(z))
            .map(|(x, u)| x + u)
            .collect()
    }

    /// Displacements `x_i(z) - X_i` (m); applied to ż, the point velocities (m/s).
    ///
    /// # Panics
    /// If `z.len() != 12(m + 1)`.
    pub fn displacements(&self, z: &[f64]) -> Vec<Vector3<f64>> {
        let n = self.len();
        let mut u = vec![0.0; 3 * n];
        faer::linalg::matmul::matmul(
            faer::MatMut::from_column_major_slice_mut(&mut u, 3, n),
            Accum::Replace,
            self.z_matrix(z).transpose(),
            self.position_matrix(),
            1.0,
            self.parallelism(),
        );
        u.chunks_exact(3)
            .map(|u| Vector3::new(u[0], u[1], u[2]))
            .collect()
    }

    /// Deformation gradients `F_i(z) = I + Zᵀ G_i` (dimensionless), each formed by
    /// `deformation_gradient_of_block`: the same bits as the `F_i` the one-pass elastic
    /// energy and gradient form, so a gradient taken at these F equals
    /// [`crate::ReducedModel::elastic_gradient`] at z to the bit.
    ///
    /// # Panics
    /// If `z.len() != 12(m + 1)`.
    pub fn deformation_gradients(&self, z: &[f64]) -> Vec<Matrix3<f64>> {
        let z = self.z_columns(z);
        let mut out = vec![Matrix3::zeros(); self.len()];
        out.par_chunks_mut(POINTS_PER_PART)
            .enumerate()
            .for_each(|(part, out)| {
                pulp::Arch::new().dispatch(DeformationGradientPart {
                    map: self,
                    z,
                    first: part * POINTS_PER_PART,
                    out,
                })
            });
        out
    }

    /// The position `x_i(z) = X_i + B_i z` (m) of point i alone.
    ///
    /// # Panics
    /// If i is out of range or `z.len() != 12(m + 1)`.
    pub fn position(&self, i: usize, z: &[f64]) -> Vector3<f64> {
        let n4 = self.layout.block_len();
        let b = self.position_row(i);
        self.rest[i]
            + Vector3::from_fn(|r, _| {
                b.iter()
                    .zip(&z[r * n4..(r + 1) * n4])
                    .map(|(b, z)| b * z)
                    .sum()
            })
    }

    /// Adds `Σ_k B_kᵀ f_k` to `gradient` (length 12(m + 1)): the z-gradient of a term whose
    /// x-gradient at point `points[k]` is `forces[k]` (x_i = X_i + B_i z).
    pub fn add_point_gradients(
        &self,
        points: &[usize],
        forces: &[Vector3<f64>],
        gradient: &mut [f64],
    ) {
        let n4 = self.layout.block_len();
        for (&i, f) in points.iter().zip(forces) {
            let b = self.position_row(i);
            for r in 0..3 {
                for (g, bk) in gradient[r * n4..(r + 1) * n4].iter_mut().zip(b) {
                    *g += f[r] * bk;
                }
            }
        }
    }

    /// Adds `Σ_k B_kᵀ H_k B_k` to `hessian` (12(m + 1) square): the z-Hessian of a term whose
    /// x-Hessian at point `points[k]` is `hessians[k]` (symmetric).
    pub fn add_point_hessians(
        &self,
        points: &[usize],
        hessians: &[Matrix3<f64>],
        hessian: &mut faer::Mat<f64>,
    ) {
        if points.is_empty() {
            return;
        }
        let n4 = self.layout.block_len();
        let rows: Vec<f64> = points
            .iter()
            .flat_map(|&i| self.position_row(i).iter().copied())
            .collect();
        let b = MatRef::from_column_major_slice(&rows, n4, points.len());
        let mut weighted = vec![0.0; rows.len()];
        let mut block = faer::Mat::<f64>::zeros(n4, n4);
        // Σ_k H_k[r, q] b_k b_kᵀ for each pair r ≤ q, one product each.
        for r in 0..3 {
            for q in r..3 {
                for ((column, b_k), h) in weighted.chunks_mut(n4).zip(rows.chunks(n4)).zip(hessians)
                {
                    for (c, b) in column.iter_mut().zip(b_k) {
                        *c = h[(r, q)] * b;
                    }
                }
                faer::linalg::matmul::matmul(
                    block.as_mut(),
                    Accum::Replace,
                    MatRef::from_column_major_slice(&weighted, n4, points.len()),
                    b.transpose(),
                    1.0,
                    Par::Seq,
                );
                for c in 0..n4 {
                    for a in 0..n4 {
                        hessian[(r * n4 + a, q * n4 + c)] += block[(a, c)];
                        if q != r {
                            hessian[(q * n4 + c, r * n4 + a)] += block[(a, c)];
                        }
                    }
                }
            }
        }
    }

    /// Threads for a product over all points: one for small maps (a few thousand multiply-adds
    /// cost less than waking the pool), all otherwise.
    fn parallelism(&self) -> Par {
        if self.b.len() < 1 << 16 {
            Par::Seq
        } else {
            Par::rayon(0)
        }
    }

    /// The three columns `z_r` of Z (each `4(m+1)`; z's layout).
    ///
    /// # Panics
    /// If `z.len() != 12(m + 1)`.
    pub(crate) fn z_columns<'a>(&self, z: &'a [f64]) -> [&'a [f64]; 3] {
        let n4 = self.layout.block_len();
        assert_eq!(z.len(), 3 * n4, "z has the wrong length");
        [&z[..n4], &z[n4..2 * n4], &z[2 * n4..]]
    }

    /// The points in consecutive ranges of [`POINTS_PER_PART`], in parallel; collected, the
    /// parts come back in order.
    pub(crate) fn point_parts(&self) -> impl IndexedParallelIterator<Item = Range<usize>> {
        let n = self.len();
        (0..n.div_ceil(POINTS_PER_PART))
            .into_par_iter()
            .map(move |part| part * POINTS_PER_PART..((part + 1) * POINTS_PER_PART).min(n))
    }

    /// z viewed as the `4(m+1) × 3` matrix Z = [z_0 z_1 z_2].
    pub(crate) fn z_matrix<'a>(&self, z: &'a [f64]) -> MatRef<'a, f64> {
        assert_eq!(z.len(), self.layout.len(), "z has the wrong length");
        MatRef::from_column_major_slice(z, self.layout.block_len(), 3)
    }
}

/// Points per part of the passes over all points (deformation gradients, elastic energy and
/// gradient, the projected dilatation's r). Parts are summed in part order, so sums do not
/// depend on the number of threads.
pub(crate) const POINTS_PER_PART: usize = 256;

/// `F = I + Zᵀ G_i` from the columns `z_r` of Z (each `4(m+1)`) and G_i (column-major
/// `4(m+1) × 3`): `F[r, s] = δ_rs + z_r · G_i[:, s]`, the nine dot products in SIMD lanes.
#[inline(always)]
pub(crate) fn deformation_gradient_of_block<S: pulp::Simd>(
    simd: S,
    z: [&[f64]; 3],
    gi: &[f64],
) -> Matrix3<f64> {
    let n4 = z[0].len();
    let zs = z.map(S::as_simd_f64s);
    let gs = [&gi[..n4], &gi[n4..2 * n4], &gi[2 * n4..3 * n4]].map(S::as_simd_f64s);
    let mut sums = [simd.splat_f64s(0.0); 9];
    for k in 0..zs[0].0.len() {
        for (r, zr) in zs.iter().enumerate() {
            for (s, gs) in gs.iter().enumerate() {
                sums[3 * s + r] = simd.mul_add_e_f64s(zr.0[k], gs.0[k], sums[3 * s + r]);
            }
        }
    }
    Matrix3::from_fn(|r, s| {
        let tail: f64 = zs[r].1.iter().zip(gs[s].1).map(|(a, b)| a * b).sum();
        f64::from(u8::from(r == s)) + simd.reduce_sum_f64s(sums[3 * s + r]) + tail
    })
}

/// One part of [`DeformationMap::deformation_gradients`]: `F_i` of the points `first..` into
/// `out`. A [`pulp::WithSimd`] with an `inline(always)` body, so that the kernel is compiled
/// inside the dispatched, SIMD-enabled function (a closure's body is not inlined there).
struct DeformationGradientPart<'a> {
    map: &'a DeformationMap,
    z: [&'a [f64]; 3],
    first: usize,
    out: &'a mut [Matrix3<f64>],
}

impl pulp::WithSimd for DeformationGradientPart<'_> {
    type Output = ();

    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, simd: S) {
        for (k, f) in self.out.iter_mut().enumerate() {
            *f = deformation_gradient_of_block(
                simd,
                self.z,
                self.map.gradient_block(self.first + k),
            );
        }
    }
}
