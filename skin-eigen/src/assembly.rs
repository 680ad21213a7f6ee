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
/// (m³) and Lamé parameters, in parallel over points; each point touches only the kernels in
/// its cutoff. Only the upper triangle is accumulated and then mirrored, so both matrices are
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
    let (mass, hessian) = accumulate_kernel_pairs(shape, volumes, materials, k * k, |a, b| {
        a as usize * k + b as usize
    })?;
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
/// `v_i ϕ_a ϕ_b` and `v_i (λ_i + 4μ_i) ∇ϕ_a·∇ϕ_b` at `slot(a, b)` of two `len`-long arrays.
/// Parallel over points, one pair of arrays per thread (summed at the end).
///
/// # Errors
/// [`AssemblyError::LengthMismatch`] unless `volumes` and `materials` have one entry per point.
pub(crate) fn accumulate_kernel_pairs(
    shape: &ShapeFunctions,
    volumes: &[f64],
    materials: &[LameParameters],
    len: usize,
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
    // One accumulator pair per thread: 2 · len doubles each (512 MB at K = 4000 dense).
    let chunk = n.div_ceil(rayon::current_num_threads()).max(1);
    Ok((0..n)
        .into_par_iter()
        .chunks(chunk)
        .map(|points| {
            let (mut mass, mut hessian) = (vec![0.0; len], vec![0.0; len]);
            for i in points {
                let (kernels, values, gradients) =
                    (shape.kernels(i), shape.values(i), shape.gradients(i));
                let v = volumes[i];
                let modulus = v * materials[i].weight_space_hessian_modulus();
                for (a, &ka) in kernels.iter().enumerate() {
                    let (va, ga) = (v * values[a], modulus * gradients[a]);
                    // Kernels are sorted, so kb ≥ ka for b ≥ a: the upper triangle.
                    for (b, &kb) in kernels.iter().enumerate().skip(a) {
                        let s = slot(ka, kb);
                        mass[s] += va * values[b];
                        hessian[s] += ga.dot(&gradients[b]);
                    }
                }
            }
            (mass, hessian)
        })
        .reduce(
            || (vec![0.0; len], vec![0.0; len]),
            |(mut m1, mut h1), (m2, h2)| {
                m1.iter_mut().zip(&m2).for_each(|(a, b)| *a += b);
                h1.iter_mut().zip(&h2).for_each(|(a, b)| *a += b);
                (m1, h1)
            },
        ))
}
