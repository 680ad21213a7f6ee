//! The greedy selection of cubature points with warm-started non-negative weights.

use faer::Mat;
use nalgebra::Vector3;
use optimize::{NnlsFactor, NnlsParams, NnlsWarmStart, nnls_normal_carried};
use rayon::prelude::*;

use crate::quadrature::cubature::gram::ForceGramFactors;

use super::candidates::CandidateForces;
use super::ranking::ResidualCorrelation;
use super::{CubatureError, CubatureParams, CubatureStop, norm};

/// The chosen candidates (indices into the pool), their weights (all positive) and the
/// residual `b − A_S w` they leave.
pub(super) struct Selection {
    pub(super) selected: Vec<usize>,
    pub(super) weights: Vec<f64>,
    pub(super) residual: Vec<f64>,
    pub(super) stop: CubatureStop,
}

/// Grows the set a batch at a time by the candidates most correlated with the residual
/// (`ranking`, f32 products of per-point factors, divided by the columns' norms; no two of a
/// batch nearer than [`CubatureParams::batch_spacing`] candidate spacings), re-solving the
/// weights by NNLS on the Gram matrix (from per-point factors, `cubature_gram`) after each
/// batch and dropping the candidates left at zero, until the relative residual against `b` is
/// within the tolerance, the set is full or no candidate left is positively correlated with the
/// residual. `omega` are the force weights and `pose_scales` `1/‖f_k‖`; `check_budget` is asked
/// with the support size before each batch.
///
/// # Errors
/// [`CubatureError::Nnls`] from the weight solve, or what `check_budget` returns.
#[allow(clippy::too_many_arguments)]
pub(super) fn select_greedily(
    candidates: &CandidateForces,
    ranking: &mut ResidualCorrelation,
    b: &[f64],
    omega: &[f64],
    pose_scales: &[f64],
    params: &CubatureParams,
    check_budget: &dyn Fn(usize) -> Result<(), CubatureError>,
) -> Result<Selection, CubatureError> {
    let pool = candidates.len();
    let b_norm = norm(b);
    let mut selected: Vec<usize> = Vec::new();
    let mut in_set = vec![false; pool];
    let mut gram = Mat::<f64>::zeros(0, 0);
    let mut gram_factors = ForceGramFactors::new(candidates.block_len(), candidates.pose_count());
    let mut atb: Vec<f64> = Vec::new();
    let mut weights: Vec<f64> = Vec::new();
    let mut residual = b.to_vec();
    let scaled_b = candidates.scaled(b);
    // Blocks of 16: the same KKT solution, far fewer factorizations at a thousand points.
    let nnls_params = NnlsParams {
        block: 16,
        ..NnlsParams::default()
    };
    // The support's factor, carried from batch to batch: each solve factors only what joined.
    let mut nnls_factor = NnlsFactor::new();
    let stop = loop {
        let error = norm(&residual) / b_norm;
        let support = weights.iter().filter(|&&w| w > 0.0).count();
        if error <= params.tolerance {
            break CubatureStop::Tolerance;
        }
        if support >= params.max_points {
            break CubatureStop::PointBudget;
        }
        if selected.len() >= pool {
            break CubatureStop::Candidates;
        }
        check_budget(support)?;
        ranking.retire(&in_set);
        let correlations = ranking.correlations(&residual);
        let column_norms = ranking.norms();
        let mut scores: Vec<(usize, f64)> = correlations
            .into_iter()
            .filter(|&(c, _)| !in_set[c] && column_norms[c] > 0.0)
            .map(|(c, correlation)| (c, correlation / column_norms[c]))
            .filter(|&(_, s)| s > 0.0)
            .collect();
        if scores.is_empty() {
            break CubatureStop::Candidates;
        }
        // Batches grow with the set (an eighth of it), so the weight solves stay few.
        let take = params
            .batch
            .max(support / 8)
            .min(params.max_points - support);
        scores.sort_by(|x, y| y.1.total_cmp(&x.1));
        let added = spread_out(
            &scores,
            take,
            params.batch_spacing * candidates.spacing(),
            |c| candidates.position(c),
        );
        let old = selected.len();
        selected.extend_from_slice(&added);
        for &c in &added {
            in_set[c] = true;
            gram_factors.push(
                candidates.gradient_block(c),
                omega,
                candidates.stresses(c),
                pose_scales,
            );
        }
        let k = selected.len();
        gram = grown_gram(&gram, &gram_factors.cross(old), old);
        atb.par_extend(added.par_iter().map(|&c| candidates.dot(c, &scaled_b)));
        weights.resize(k, 0.0);
        let free: Vec<bool> = (0..k).map(|i| i >= old).collect();
        let start = NnlsWarmStart {
            x: &weights,
            free: &free,
        };
        weights = nnls_normal_carried(
            gram.as_ref(),
            &atb,
            Some(start),
            &nnls_params,
            &mut nnls_factor,
        )?
        .x;
        // Candidates the weight solve left at zero leave the set for good (they stay marked, so
        // they are not chosen again): the Gram matrix and later solves only carry the support.
        let keep: Vec<usize> = (0..k).filter(|&i| weights[i] > 0.0).collect();
        if keep.len() < k {
            let mut new_index = vec![None; k];
            for (to, &from) in keep.iter().enumerate() {
                new_index[from] = Some(to);
            }
            nnls_factor.renumber(&new_index);
            gram = compacted(&gram, &keep);
            atb = keep.iter().map(|&i| atb[i]).collect();
            weights = keep.iter().map(|&i| weights[i]).collect();
            selected = keep.iter().map(|&i| selected[i]).collect();
            gram_factors.retain(&keep);
        }
        // r = b − A_S w, as one product of the members' factors.
        let fitted = candidates.combination(&selected, &weights);
        for ((r, b), f) in residual.iter_mut().zip(b).zip(&fitted) {
            *r = b - f;
        }
    };
    Ok(Selection {
        selected,
        weights,
        residual,
        stop,
    })
}

/// Up to `take` of the `ranked` candidates (best first), in that order, each at least
/// `min_distance` (m) from those taken before it: the best candidate is always taken, a
/// candidate nearer than `min_distance` to one already taken is passed over.
fn spread_out(
    ranked: &[(usize, f64)],
    take: usize,
    min_distance: f64,
    position: impl Fn(usize) -> Vector3<f64>,
) -> Vec<usize> {
    let mut taken: Vec<(usize, Vector3<f64>)> = Vec::with_capacity(take);
    for &(c, _) in ranked {
        if taken.len() >= take {
            break;
        }
        let x = position(c);
        if taken.iter().all(|(_, y)| (x - y).norm() >= min_distance) {
            taken.push((c, x));
        }
    }
    taken.into_iter().map(|(c, _)| c).collect()
}

/// The Gram matrix of the set grown from `old` to `old + cross.ncols()` members: `gram` (the
/// old members') and the new columns `cross` = `[A_S]ᵀ A_new` from the points' factors
/// (`cubature_gram`), mirrored.
fn grown_gram(gram: &Mat<f64>, cross: &Mat<f64>, old: usize) -> Mat<f64> {
    let k = cross.nrows();
    let mut grown = Mat::<f64>::zeros(k, k);
    for j in 0..old {
        let column = grown.col_as_slice_mut(j);
        column[..old].copy_from_slice(gram.col_as_slice(j));
        for (i, x) in column.iter_mut().enumerate().skip(old) {
            *x = cross[(j, i - old)];
        }
    }
    for j in old..k {
        grown
            .col_as_slice_mut(j)
            .copy_from_slice(cross.col_as_slice(j - old));
    }
    grown
}

/// The rows and columns `keep` (ascending) of the symmetric `gram`.
fn compacted(gram: &Mat<f64>, keep: &[usize]) -> Mat<f64> {
    let mut kept = Mat::<f64>::zeros(keep.len(), keep.len());
    for (to, &from) in keep.iter().enumerate() {
        let source = gram.col_as_slice(from);
        for (x, &i) in kept.col_as_slice_mut(to).iter_mut().zip(keep) {
            *x = source[i];
        }
    }
    kept
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Candidates on a line, 0.1 m apart, ranked by the given order.
    fn on_a_line(order: &[usize]) -> (Vec<(usize, f64)>, impl Fn(usize) -> Vector3<f64>) {
        let ranked = order
            .iter()
            .enumerate()
            .map(|(rank, &c)| (c, 1.0 / (1.0 + rank as f64)))
            .collect();
        (ranked, |c: usize| Vector3::new(0.1 * c as f64, 0.0, 0.0))
    }

    #[test]
    fn spread_out_without_a_distance_takes_the_best_in_order() {
        let (ranked, position) = on_a_line(&[3, 4, 2, 9, 0]);
        assert_eq!(spread_out(&ranked, 3, 0.0, position), vec![3, 4, 2]);
    }

    #[test]
    fn spread_out_passes_over_neighbours_of_the_taken_and_keeps_rank_order() {
        // 0.25 m apart at least: 4 and 2 are within 0.2 m of 3, 5 within 0.2 m of 3.
        let (ranked, position) = on_a_line(&[3, 4, 2, 5, 9, 0, 6, 7]);
        let taken = spread_out(&ranked, 4, 0.25, &position);
        assert_eq!(taken, vec![3, 9, 0, 6]);
        for (i, &a) in taken.iter().enumerate() {
            for &b in &taken[i + 1..] {
                assert!((position(a) - position(b)).norm() >= 0.25);
            }
        }
    }

    #[test]
    fn spread_out_takes_fewer_when_every_other_candidate_is_too_near() {
        let (ranked, position) = on_a_line(&[5, 4, 6]);
        assert_eq!(spread_out(&ranked, 3, 0.5, position), vec![5]);
    }
}
