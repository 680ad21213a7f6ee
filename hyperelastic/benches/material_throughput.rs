//! Nanoseconds per point for Ψ, P, ∂P/∂F and the PSD projections, beside a 9×9 matrix
//! product as a yardstick. Plain harness (no criterion): `cargo bench -p hyperelastic`.
//!
//! Each kernel runs over the same 100 000 deformation gradients (a quarter of them inverted),
//! best of 5 passes.

use std::hint::black_box;
use std::time::Instant;

use hyperelastic::{
    HyperelasticMaterial, LameParameters, Matrix9, StableNeoHookean, project_to_psd,
};
use nalgebra::Matrix3;

const N: usize = 100_000;

fn inputs() -> Vec<Matrix3<f64>> {
    let mut state = 0x9E3779B97F4A7C15u64;
    let mut next = || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    };
    (0..N)
        .map(|_| Matrix3::identity() + Matrix3::from_fn(|_, _| 0.7 * next()))
        .collect()
}

fn time_per_point(
    label: &str,
    f: &[Matrix3<f64>],
    mut kernel: impl FnMut(&Matrix3<f64>) -> f64,
) -> f64 {
    let mut best = f64::INFINITY;
    for _ in 0..5 {
        let start = Instant::now();
        let mut acc = 0.0;
        for x in f {
            acc += kernel(black_box(x));
        }
        black_box(acc);
        best = best.min(start.elapsed().as_secs_f64() / f.len() as f64 * 1e9);
    }
    println!("{label:44} {best:8.1} ns/point");
    best
}

fn main() {
    let f = inputs();
    let inverted = f.iter().filter(|x| x.determinant() < 0.0).count();
    println!("{N} deformation gradients, {inverted} inverted\n");
    let p = LameParameters::from_young_poisson(5e6, 0.45).expect("valid");
    let nh = StableNeoHookean;
    let gemm = time_per_point("9x9 matrix product (yardstick)", &f, |x| {
        let a = Matrix9::from_fn(|i, j| x[(i % 3, j % 3)]);
        (a * a)[(4, 4)]
    });
    let psi = time_per_point("stable NH energy density", &f, |x| nh.energy_density(&p, x));
    let stress = time_per_point("stable NH first Piola-Kirchhoff", &f, |x| {
        nh.first_piola_kirchhoff(&p, x)[(0, 1)]
    });
    let tangent = time_per_point("stable NH dP/dF (exact)", &f, |x| {
        nh.stress_derivative(&p, x)[(0, 1)]
    });
    let analytic = time_per_point("stable NH dP/dF projected (analytic eigen)", &f, |x| {
        nh.projected_stress_derivative(&p, x)[(0, 1)]
    });
    let numeric = time_per_point("stable NH dP/dF projected (numeric 9x9 eigen)", &f, |x| {
        project_to_psd(&nh.stress_derivative(&p, x))[(0, 1)]
    });
    println!(
        "\nrelative to one 9x9 product: Ψ {:.2}, P {:.2}, dP/dF {:.2}, analytic projection {:.1}, numeric projection {:.1}",
        psi / gemm,
        stress / gemm,
        tangent / gemm,
        analytic / gemm,
        numeric / gemm
    );
}
