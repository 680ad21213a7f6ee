//! Reduced Hessian assembly on the 5 × 1 × 1 m beam with 5000 simulation points, for
//! m = 6, 9, 16, 32, beside a plain faer GEMM of the same shape as a yardstick, and the
//! one-pass elastic energy and gradient beside the deformation gradients alone
//! (`DeformationMap::deformation_gradients`, the passes' own SIMD kernel for `F = I + Zᵀ G_i`,
//! one read of G: the floor for a pass over the points).
//! Plain harness: `cargo bench -p reduced-sim`.
//!
//! Useful work per assembly: three diagonal blocks computed as lower triangles and three
//! off-diagonal blocks, each a product `T^{rq} Gᵀ` of `n4 × 3N` by `3N × n4`
//! (n4 = 4(m + 1)): `(3 · ½ + 3) · 2 · n4² · 3N` flops. The yardstick is one full
//! `n4 × 3N × n4` GEMM timed alone, so the ratio shows what the per-point tangents, the
//! `T^{rq}` construction and the scatter into the 12(m+1) matrix cost on top of the products.

use hyperelastic::MaterialSample;
use std::hint::black_box;
use std::time::Instant;

use faer::{Accum, Mat, Par};
use hyperelastic::{LameParameters, StableNeoHookean, Tangent};
use nalgebra::Vector3;
use reduced_sim::ReducedModel;
use rkpm_core::{KernelParams, sample_box_grid};
use skin_eigen::{BasisParams, EigenParams, build_basis};

fn best_of<T>(runs: usize, mut f: impl FnMut() -> T) -> f64 {
    (0..runs)
        .map(|_| {
            let t = Instant::now();
            black_box(f());
            t.elapsed().as_secs_f64()
        })
        .fold(f64::INFINITY, f64::min)
}

fn main() {
    let material = MaterialSample {
        youngs_modulus: 5e6,
        poisson_ratio: 0.45,
        density: 1000.0,
    };
    let lame = LameParameters::from_young_poisson(5e6, 0.45).unwrap();
    let points = sample_box_grid(Vector3::zeros(), Vector3::new(5.0, 1.0, 1.0), 0.1).unwrap();
    let n = points.len();
    println!("beam, {n} simulation points, best of 5");
    println!(
        "| m | assembly (ms) | GFLOP/s (assembly) | GEMM n4×3N×n4 (ms) | GFLOP/s (GEMM) | ratio | \
         energy (ms) | gradient (ms) | F alone (ms) |"
    );
    println!("|---|---|---|---|---|---|---|---|---|");
    for m in [6, 9, 16, 32] {
        let params = BasisParams {
            kernels: KernelParams {
                count: 1000,
                ..Default::default()
            },
            eigen: EigenParams {
                modes: m,
                ..Default::default()
            },
            ..Default::default()
        };
        let (basis, _, _) = build_basis(&points, &vec![lame; n], &params).unwrap();
        let model =
            ReducedModel::new(&basis, &points, &vec![material; n], StableNeoHookean).unwrap();
        let len = model.deformation_map().layout().len();
        let z: Vec<f64> = (0..len).map(|i| 0.01 * (i as f64).sin()).collect();
        let assembly = best_of(5, || model.elastic_hessian(&z, Tangent::ProjectedPsd));
        let energy = best_of(20, || model.elastic_energy(&z));
        let gradient = best_of(20, || model.elastic_gradient(&z));
        let deformation_gradients =
            best_of(20, || model.deformation_map().deformation_gradients(&z));

        let n4 = 4 * (m + 1);
        let a = Mat::<f64>::from_fn(n4, 3 * n, |i, j| ((i * 7 + j) % 13) as f64);
        let b = Mat::<f64>::from_fn(3 * n, n4, |i, j| ((i + 3 * j) % 11) as f64);
        let mut c = Mat::<f64>::zeros(n4, n4);
        let gemm = best_of(5, || {
            faer::linalg::matmul::matmul(
                c.as_mut(),
                Accum::Replace,
                a.as_ref(),
                b.as_ref(),
                1.0,
                Par::rayon(0),
            )
        });
        let gemm_flops = 2.0 * (n4 * n4 * 3 * n) as f64;
        let assembly_flops = 4.5 * gemm_flops;
        println!(
            "| {m} | {:.2} | {:.1} | {:.3} | {:.1} | {:.2} | {:.3} | {:.3} | {:.3} |",
            1e3 * assembly,
            assembly_flops / assembly * 1e-9,
            1e3 * gemm,
            gemm_flops / gemm * 1e-9,
            (assembly_flops / assembly) / (gemm_flops / gemm),
            1e3 * energy,
            1e3 * gradient,
            1e3 * deformation_gradients,
        );
    }
}
