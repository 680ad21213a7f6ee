//! Sparse assembly of 𝓜 and H_w for large K, where dense K×K matrices no longer fit.

use faer::sparse::{SparseColMat, Triplet};
use hyperelastic::LameParameters;
use rayon::prelude::*;
use rkpm_core::{Kernels, ShapeFunctions, SpatialIndex};

use crate::assembly::{AssemblyError, accumulate_kernel_pairs};

/// 𝓜 and H_w (same formulas as [`crate::WeightSpaceMatrices`]) as sparse symmetric matrices
/// with both triangles stored.
#[derive(Clone, Debug)]
pub struct SparseWeightSpaceMatrices {
    /// 𝓜 (K × K).
    pub mass: SparseColMat<usize, f64>,
    /// H_w (K × K).
    pub hessian: SparseColMat<usize, f64>,
}

/// Assembles 𝓜 and H_w sparsely. The pattern holds the kernel pairs whose supports can overlap
/// (`|p_a - p_b| < cutoff (r_a + r_b)`, a superset of the pairs any point couples), upper
/// triangle, rows sorted; each point adds its pairs by binary search in its rows. Parallel over
/// rows, bit-identical for any thread count.
///
/// # Errors
/// [`AssemblyError::LengthMismatch`] as for the dense assembly.
pub fn assemble_sparse_weight_space_matrices(
    shape: &ShapeFunctions,
    kernels: &Kernels,
    cutoff: f64,
    volumes: &[f64],
    materials: &[LameParameters],
) -> Result<SparseWeightSpaceMatrices, AssemblyError> {
    let k = kernels.len();
    let (centers, radii) = (kernels.centers(), kernels.radii());
    let r_max = radii.iter().copied().fold(0.0, f64::max);
    let index = SpatialIndex::new(centers);
    let rows: Vec<Vec<u32>> = (0..k)
        .into_par_iter()
        .map(|a| {
            let mut row: Vec<u32> = index
                .within(&centers[a], cutoff * (radii[a] + r_max))
                .into_iter()
                .filter(|&(b, d)| b >= a && d < cutoff * (radii[a] + radii[b]))
                .map(|(b, _)| b as u32)
                .collect();
            row.sort_unstable();
            row
        })
        .collect();
    let mut offsets = Vec::with_capacity(k + 1);
    offsets.push(0usize);
    for row in &rows {
        offsets.push(offsets.last().expect("non-empty") + row.len());
    }
    let columns: Vec<u32> = rows.into_iter().flatten().collect();
    let nnz = columns.len();
    let (mass, hessian) = accumulate_kernel_pairs(shape, volumes, materials, &offsets, |a, b| {
        let (start, end) = (offsets[a as usize], offsets[a as usize + 1]);
        columns[start..end]
            .binary_search(&b)
            .expect("pattern holds every overlapping pair")
    })?;
    let symmetric = |values: &[f64]| {
        let mut triplets = Vec::with_capacity(2 * nnz);
        for a in 0..k {
            for slot in offsets[a]..offsets[a + 1] {
                let b = columns[slot] as usize;
                triplets.push(Triplet::new(a, b, values[slot]));
                if a != b {
                    triplets.push(Triplet::new(b, a, values[slot]));
                }
            }
        }
        SparseColMat::try_new_from_triplets(k, k, &triplets).expect("indices are in range")
    };
    Ok(SparseWeightSpaceMatrices {
        mass: symmetric(&mass),
        hessian: symmetric(&hessian),
    })
}
