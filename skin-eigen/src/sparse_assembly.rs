//! Sparse assembly of 𝓜 and H_w for large K, where dense K×K matrices no longer fit.

use faer::sparse::{SparseColMat, Triplet};
use hyperelastic::LameParameters;
use rayon::prelude::*;
use rkpm_core::{Kernels, ShapeFunctions, SpatialIndex};

use crate::assembly::AssemblyError;

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
/// points with one value array per thread.
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
    let chunk = n.div_ceil(rayon::current_num_threads()).max(1);
    let (mass, hessian) = (0..n)
        .into_par_iter()
        .chunks(chunk)
        .map(|points| {
            let (mut mass, mut hessian) = (vec![0.0; nnz], vec![0.0; nnz]);
            for i in points {
                let (ks, values, gradients) =
                    (shape.kernels(i), shape.values(i), shape.gradients(i));
                let v = volumes[i];
                let modulus = v * materials[i].weight_space_hessian_modulus();
                for (a, &ka) in ks.iter().enumerate() {
                    let (start, end) = (offsets[ka as usize], offsets[ka as usize + 1]);
                    let row = &columns[start..end];
                    let (va, ga) = (v * values[a], modulus * gradients[a]);
                    for (b, &kb) in ks.iter().enumerate().skip(a) {
                        let slot = start
                            + row
                                .binary_search(&kb)
                                .expect("pattern holds every overlapping pair");
                        mass[slot] += va * values[b];
                        hessian[slot] += ga.dot(&gradients[b]);
                    }
                }
            }
            (mass, hessian)
        })
        .reduce(
            || (vec![0.0; nnz], vec![0.0; nnz]),
            |(mut m1, mut h1), (m2, h2)| {
                m1.iter_mut().zip(&m2).for_each(|(a, b)| *a += b);
                h1.iter_mut().zip(&h2).for_each(|(a, b)| *a += b);
                (m1, h1)
            },
        );
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
