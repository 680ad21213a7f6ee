//! Skinning eigenmodes of the 5 m × 1 m × 1 m beam against the analytic Neumann-Laplacian
//! eigenvalues π²(i²/a² + j²/b² + k²/c²) (design §3.5).
//!
//! ```sh
//! cargo run --release -p skin-eigen --example box_modes -- --json
//! ```
//! Options: `--json` (machine-readable output), `--points N` (integration points, default
//! 30000), `--kernels K` (default 1000).

use std::f64::consts::PI;
use std::time::Instant;

use hyperelastic::LameParameters;
use nalgebra::Vector3;
use rkpm_core::{GridSamplingParams, KernelParams, TriangleMesh, sample_grid};
use skin_eigen::{BasisParams, EigenParams, build_basis};

/// Command-line options.
#[derive(clap::Parser)]
struct Args {
    /// Machine-readable output.
    #[arg(long)]
    json: bool,
    /// Integration points.
    #[arg(long = "points", default_value_t = 30_000)]
    target_points: usize,
    /// Kernels K.
    #[arg(long = "kernels", default_value_t = 1000)]
    count: usize,
}

/// The smallest `count` nonzero Neumann eigenvalues of the box, ascending.
fn analytic(sides: [f64; 3], count: usize) -> Vec<f64> {
    let mut values = Vec::new();
    for i in 0..12 {
        for j in 0..6 {
            for k in 0..6 {
                let v = PI
                    * PI
                    * ((i * i) as f64 / sides[0].powi(2)
                        + (j * j) as f64 / sides[1].powi(2)
                        + (k * k) as f64 / sides[2].powi(2));
                if v > 0.0 {
                    values.push(v);
                }
            }
        }
    }
    values.sort_by(f64::total_cmp);
    values.truncate(count);
    values
}

fn list(values: &[f64]) -> String {
    values
        .iter()
        .map(|v| format!("{v:.6}"))
        .collect::<Vec<_>>()
        .join(", ")
}

fn run() -> Result<(), String> {
    let Args {
        json,
        target_points,
        count,
    } = clap::Parser::parse();
    let sides = [5.0, 1.0, 1.0];
    let beam = TriangleMesh::cuboid(Vector3::zeros(), Vector3::from(sides));

    let t = Instant::now();
    let points =
        sample_grid(&beam, &GridSamplingParams { target_points }).map_err(|e| e.to_string())?;
    let sampling = t.elapsed().as_secs_f64();
    let lame = LameParameters::from_young_poisson(5e6, 0.45).map_err(|e| e.to_string())?;
    let materials = vec![lame; points.len()];
    let params = BasisParams {
        kernels: KernelParams {
            count,
            ..Default::default()
        },
        eigen: EigenParams {
            modes: 16,
            ..Default::default()
        },
        ..Default::default()
    };
    let (basis, report, _) =
        build_basis(&points, &materials, &params).map_err(|e| e.to_string())?;
    let computed: Vec<f64> = basis
        .eigenvalues()
        .iter()
        .take(10)
        .map(|l| l / lame.weight_space_hessian_modulus())
        .collect();
    let expected = analytic(sides, computed.len());
    let errors: Vec<f64> = computed
        .iter()
        .zip(&expected)
        .map(|(c, a)| (c - a) / a)
        .collect();
    let t = report.timings;
    if json {
        println!("{{");
        println!("  \"computed\": [{}],", list(&computed));
        println!("  \"analytic\": [{}],", list(&expected));
        println!("  \"relative_error\": [{}],", list(&errors));
        println!("  \"kernels\": {},", report.kernels);
        println!("  \"points\": {},", report.integration_points);
        println!(
            "  \"mean_kernels_per_point\": {:.2},",
            report.mean_kernels_per_point
        );
        println!(
            "  \"mass_condition_number\": {:.3e},",
            report.mass_condition_number
        );
        println!(
            "  \"discarded_mass_directions\": {},",
            report.discarded_mass_directions
        );
        println!(
            "  \"eigen_relative_residual\": {:.3e},",
            report.eigen_relative_residual
        );
        println!(
            "  \"orthonormality_error\": {:.3e},",
            report.orthonormality_error
        );
        println!(
            "  \"timings\": {{\"sampling\": {sampling:.4}, \"fps\": {:.4}, \"shape_functions\": {:.4}, \"assembly\": {:.4}, \"eigen_solve\": {:.4}}}",
            t.kernel_placement, t.shape_functions, t.assembly, t.eigen_solve
        );
        println!("}}");
    } else {
        println!(
            "beam 5×1×1 m: {} integration points, {} kernels ({:.1} per point), cond(𝓜) = {:.2e}",
            report.integration_points,
            report.kernels,
            report.mean_kernels_per_point,
            report.mass_condition_number
        );
        println!(
            "eigen residual {:.2e}, |cᵀ𝓜c - I| {:.2e}",
            report.eigen_relative_residual, report.orthonormality_error
        );
        println!(
            "{:>4} {:>12} {:>12} {:>10}",
            "mode", "computed", "analytic", "rel.err"
        );
        for (i, ((c, a), e)) in computed.iter().zip(&expected).zip(&errors).enumerate() {
            println!("{:>4} {c:>12.6} {a:>12.6} {:>9.3}%", i + 1, 100.0 * e);
        }
        println!(
            "timings (s): sampling {sampling:.3}, FPS {:.3}, shape functions {:.3}, assembly {:.3}, eigen solve {:.3}",
            t.kernel_placement, t.shape_functions, t.assembly, t.eigen_solve
        );
    }
    Ok(())
}

fn main() {
    if let Err(message) = run() {
        eprintln!("error: {message}");
        std::process::exit(1);
    }
}
