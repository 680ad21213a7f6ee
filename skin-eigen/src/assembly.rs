//! Assembly of the RKPM mass matrix 𝓜 (Eq. 14) and the weight-space Hessian H_w (Prop. 1).

use faer::Mat;
use hyperelastic::LameParameters;
use rayon::prelude::*;
use rkpm_core::ShapeFunctions;

/// Assembly input does not fit together.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum AssemblyError {
    /// Per-point arrays differ in length from the shape functions' point count.
    #[error("{what}: {got} entries for {expected} integration points")]
    LengthMismatch {
        /// Which array.
        what: &'static str,
        /// Its length.
        got: usize,
        /// The number of points.
        expected: usize,
    },
}

/// The two K×K weight-space matrices, dense and symmetric by construction.
///
/// ```text
/// 𝓜_kl    = Σ_i v_i ϕ_k(X_i) ϕ_l(X_i)                         (Eq. 14, m³)
/// (H_w)_kl = Σ_i v_i (λ_i + 4μ_i) ∇ϕ_k(X_i) · ∇ϕ_l(X_i)       (Prop. 1, Pa·m)
/// ```
#[derive(Clone, Debug)]
pub struct WeightSpaceMatrices {
    /// 𝓜 (K × K).
    pub mass: Mat<f64>,
    /// H_w (K × K).
    pub hessian: Mat<f64>,
}

/// Assembles 𝓜 and H_w from shape functions at the integration points, their volumes `v_i`
/// (m³) and Lamé parameters, in parallel over kernel rows (bit-identical for any thread
/// count); each point touches only the kernels in its cutoff. Only the upper triangle is accumulated and then mirrored, so both matrices are
/// exactly symmetric.
///
/// # Errors
/// [`AssemblyError::LengthMismatch`] when `volumes` or `materials` do not have one entry per
/// point of `shape`.
pub fn assemble_weight_space_matrices(
    shape: &ShapeFunctions,
    volumes: &[f64],
    materials: &[LameParameters],
) -> Result<WeightSpaceMatrices, AssemblyError> {
    let k = shape.kernel_count();
    let row_offsets: Vec<usize> = (0..=k).map(|a| a * k).collect();
    let (mass, hessian) =
        accumulate_kernel_pairs(shape, volumes, materials, &row_offsets, |_, b| b as usize)?;
    // Row-major upper triangle → symmetric faer matrices.
    let symmetric = |upper: &[f64]| {
        Mat::from_fn(k, k, |r, c| {
            if r <= c {
                upper[r * k + c]
            } else {
                upper[c * k + r]
            }
        })
    };
    Ok(WeightSpaceMatrices {
        mass: symmetric(&mass),
        hessian: symmetric(&hessian),
    })
}

/// The shared assembly loop: for every point i and kernel pair (a, b ≥ a) reaching it, adds
/// `v_i ϕ_a ϕ_b` and `v_i (λ_i + 4μ_i) ∇ϕ_a·∇ϕ_b` into row a of two row-major arrays, row a
/// being `row_offsets[a]..row_offsets[a + 1]` and entry (a, b) at `row_offsets[a] + slot(a, b)`.
///
/// Parallel over rows: row a visits the points kernel a reaches in index order, so every entry
/// is summed in the same order whatever the number of threads (bit-identical results on 1 or
/// 64 threads), and no thread needs its own K × K buffer.
///
/// # Errors
/// [`AssemblyError::LengthMismatch`] unless `volumes` and `materials` have one entry per point.
pub(crate) fn accumulate_kernel_pairs(
    shape: &ShapeFunctions,
    volumes: &[f64],
    materials: &[LameParameters],
    row_offsets: &[usize],
    slot: impl Fn(u32, u32) -> usize + Sync,
) -> Result<(Vec<f64>, Vec<f64>), AssemblyError> {
    let n = shape.point_count();
    for (what, got) in [("volumes", volumes.len()), ("materials", materials.len())] {
        if got != n {
            return Err(AssemblyError::LengthMismatch {
                what,
                got,
                expected: n,
            });
        }
    }
    let k = shape.kernel_count();
    // Transpose of the shape-function table: for kernel a, the (point, position in the point's
    // kernel list) pairs, points ascending.
    let mut starts = vec![0usize; k + 1];
    for i in 0..n {
        for &a in shape.kernels(i) {
            starts[a as usize + 1] += 1;
        }
    }
    for a in 0..k {
        starts[a + 1] += starts[a];
    }
    let mut fill = starts.clone();
    let mut support = vec![(0u32, 0u32); starts[k]];
    for i in 0..n {
        for (p, &a) in shape.kernels(i).iter().enumerate() {
            support[fill[a as usize]] = (i as u32, p as u32);
            fill[a as usize] += 1;
        }
    }

    let len = row_offsets[k];
    let (mut mass, mut hessian) = (vec![0.0; len], vec![0.0; len]);
    split_rows(&mut mass, row_offsets)
        .into_par_iter()
        .zip(split_rows(&mut hessian, row_offsets))
        .enumerate()
        .for_each(|(a, (mass_row, hessian_row))| {
            for &(i, p) in &support[starts[a]..starts[a + 1]] {
                let (i, p) = (i as usize, p as usize);
                let (kernels, values, gradients) =
                    (shape.kernels(i), shape.values(i), shape.gradients(i));
                let v = volumes[i];
                let (va, ga) = (
                    v * values[p],
                    v * materials[i].weight_space_hessian_modulus() * gradients[p],
                );
                // Kernels are sorted, so kb ≥ ka for positions ≥ p: the upper triangle.
                for b in p..kernels.len() {
                    let s = slot(a as u32, kernels[b]);
                    mass_row[s] += va * values[b];
                    hessian_row[s] += ga.dot(&gradients[b]);
                }
            }
        });
    Ok((mass, hessian))
}

/// `values` cut into the rows `row_offsets[a]..row_offsets[a + 1]`.
fn split_rows<'a>(values: &'a mut [f64], row_offsets: &[usize]) -> Vec<&'a mut [f64]> {
    let mut rest = values;
    row_offsets
        .windows(2)
        .map(|w| {
            let (row, tail) = std::mem::take(&mut rest).split_at_mut(w[1] - w[0]);
            rest = tail;
            row
        })
        .collect()
}
