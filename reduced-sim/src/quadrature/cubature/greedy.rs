//! The greedy selection of cubature points with warm-started non-negative weights.

use faer::{Accum, Mat, MatRef, Par};
use hyperelastic::HyperelasticMaterial;
use optimize::{NnlsParams, NnlsWarmStart, nnls_normal};
use rayon::prelude::*;

use crate::quadrature::cubature::gram::ForceGramFactors;

use super::candidates::CandidateForces;
use super::{CubatureError, CubatureParams, dot, norm};

/// The chosen candidates (indices into the pool), their weights (all positive) and the
/// residual `b − A_S w` they leave.
pub(super) struct Selection {
    pub(super) selected: Vec<usize>,
    pub(super) weights: Vec<f64>,
    pub(super) residual: Vec<f64>,
}

/// Grows the set a batch at a time by the candidates most correlated with the residual
/// (ranked on the f32 `columns` with norms `column_norms`), re-solving the weights by NNLS on
/// the Gram matrix (from per-point factors, `cubature_gram`) after each batch and dropping the
/// candidates left at zero, until the relative residual against `b` is within the tolerance or
/// the set is full. `omega` are the force weights and `pose_scales` `1/‖f_k‖`; `check_budget`
/// is asked with the support size before each batch.
///
/// # Errors
/// [`CubatureError::Nnls`] from the weight solve, or what `check_budget` returns.
#[allow(clippy::too_many_arguments)]
pub(super) fn select_greedily<M: HyperelasticMaterial>(
    candidates: &CandidateForces<'_, M>,
    columns: &[f32],
    column_norms: &[f64],
    b: &[f64],
    omega: &[f64],
    pose_scales: &[f64],
    params: &CubatureParams,
    check_budget: &dyn Fn(usize) -> Result<(), CubatureError>,
) -> Result<Selection, CubatureError> {
    let (rows, pool) = (candidates.rows(), candidates.len());
    let a = MatRef::from_column_major_slice(columns, rows, pool);
    let b_norm = norm(b);
    let mut selected: Vec<usize> = Vec::new();
    let mut in_set = vec![false; pool];
    let mut gram = Mat::<f64>::zeros(0, 0);
    let mut gram_factors = ForceGramFactors::new(candidates.block_len(), candidates.pose_count());
    let mut atb: Vec<f64> = Vec::new();
    let mut weights: Vec<f64> = Vec::new();
    let mut residual = b.to_vec();
    let mut selected_columns: Vec<f64> = Vec::new();
    // Blocks of 16: the same KKT solution, far fewer factorizations at a thousand points.
    let nnls_params = NnlsParams {
        block: 16,
        ..NnlsParams::default()
    };
    loop {
        let error = norm(&residual) / b_norm;
        let support = weights.iter().filter(|&&w| w > 0.0).count();
        if error <= params.tolerance || support >= params.max_points || selected.len() >= pool {
            break;
        }
        check_budget(weights.iter().filter(|&&w| w > 0.0).count())?;
        // Correlations Aᵀr of every candidate with the residual, as one product.
        let residual32: Vec<f32> = residual.iter().map(|&r| r as f32).collect();
        let mut correlation = Mat::<f32>::zeros(pool, 1);
        faer::linalg::matmul::matmul(
            correlation.as_mut(),
            Accum::Replace,
            a.transpose(),
            MatRef::from_column_major_slice(&residual32, rows, 1),
            1.0,
            Par::rayon(0),
        );
        let mut scores: Vec<(usize, f64)> = (0..pool)
            .filter(|&c| !in_set[c] && column_norms[c] > 0.0)
            .map(|c| (c, f64::from(correlation[(c, 0)]) / column_norms[c]))
            .filter(|&(_, s)| s > 0.0)
            .collect();
        if scores.is_empty() {
            break;
        }
        // Batches grow with the set (an eighth of it), so the weight solves stay few.
        let take = params
            .batch
            .max(support / 8)
            .min(params.max_points - support);
        scores.sort_by(|x, y| y.1.total_cmp(&x.1));
        let added: Vec<usize> = scores.iter().take(take).map(|&(c, _)| c).collect();
        let old = selected.len();
        selected.extend_from_slice(&added);
        for &c in &added {
            in_set[c] = true;
        }
        add_columns(
            candidates,
            &added,
            omega,
            pose_scales,
            &mut selected_columns,
            &mut gram_factors,
        );
        let k = selected.len();
        gram = grown_gram(&gram, &gram_factors.cross(old), old);
        for j in old..k {
            atb.push(dot(&selected_columns[j * rows..(j + 1) * rows], b));
        }
        weights.resize(k, 0.0);
        let free: Vec<bool> = (0..k).map(|i| i >= old).collect();
        let start = NnlsWarmStart {
            x: &weights,
            free: &free,
        };
        weights = nnls_normal(gram.as_ref(), &atb, Some(start), &nnls_params)?.x;
        // Candidates the weight solve left at zero leave the set for good (they stay marked, so
        // they are not chosen again): the Gram matrix and later solves only carry the support.
        let keep: Vec<usize> = (0..k).filter(|&i| weights[i] > 0.0).collect();
        if keep.len() < k {
            gram = Mat::from_fn(keep.len(), keep.len(), |i, j| gram[(keep[i], keep[j])]);
            atb = keep.iter().map(|&i| atb[i]).collect();
            weights = keep.iter().map(|&i| weights[i]).collect();
            selected = keep.iter().map(|&i| selected[i]).collect();
            // In place: mostly the newest columns leave, so little moves.
            for (to, &from) in keep.iter().enumerate() {
                if to != from {
                    selected_columns.copy_within(from * rows..(from + 1) * rows, to * rows);
                }
            }
            selected_columns.truncate(keep.len() * rows);
            gram_factors.retain(&keep);
        }
        // r = b − A_S w, as one product.
        residual.copy_from_slice(b);
        faer::linalg::matmul::matmul(
            faer::MatMut::from_column_major_slice_mut(&mut residual, rows, 1),
            Accum::Add,
            MatRef::from_column_major_slice(&selected_columns, rows, weights.len()),
            MatRef::from_column_major_slice(&weights, weights.len(), 1),
            -1.0,
            Par::rayon(0),
        );
    }
    Ok(Selection {
        selected,
        weights,
        residual,
    })
}

/// The Gram matrix of the set grown from `old` to `old + cross.ncols()` members: `gram` (the
/// old members') and the new columns `cross` = `[A_S]ᵀ A_new` from the points' factors
/// (`cubature_gram`), mirrored.
fn grown_gram(gram: &Mat<f64>, cross: &Mat<f64>, old: usize) -> Mat<f64> {
    let k = cross.nrows();
    let mut grown = Mat::<f64>::zeros(k, k);
    for j in 0..old {
        for i in 0..old {
            grown[(i, j)] = gram[(i, j)];
        }
    }
    for j in old..k {
        for i in 0..k {
            grown[(i, j)] = cross[(i, j - old)];
            grown[(j, i)] = cross[(i, j - old)];
        }
    }
    grown
}

/// Appends the f64 columns of the candidates `added` to `selected_columns` (`rows` each) and
/// their factors to `gram_factors`.
fn add_columns<M: HyperelasticMaterial>(
    candidates: &CandidateForces<'_, M>,
    added: &[usize],
    omega: &[f64],
    pose_scales: &[f64],
    selected_columns: &mut Vec<f64>,
    gram_factors: &mut ForceGramFactors,
) {
    let rows = candidates.rows();
    let old = selected_columns.len() / rows;
    selected_columns.resize((old + added.len()) * rows, 0.0);
    let added_stresses: Vec<Mat<f64>> = added.par_iter().map(|&c| candidates.stresses(c)).collect();
    selected_columns[old * rows..]
        .par_chunks_mut(rows)
        .zip(added)
        .zip(&added_stresses)
        .for_each(|((column, &c), stresses)| {
            candidates.column(c, stresses.as_ref(), column);
        });
    for (&c, stresses) in added.iter().zip(&added_stresses) {
        gram_factors.push(
            candidates.gradient_block(c),
            omega,
            stresses.as_ref(),
            pose_scales,
        );
    }
}
