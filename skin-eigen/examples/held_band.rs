//! The band of a held region: on the 5 m × 1 m × 1 m beam with the end x ≤ 0.5 m
//! held, how far beyond x = 0.5 the modes stay near zero, for the Gaussian and the compact
//! B-spline kernel windows.
//!
//! ```sh
//! cargo run --release -p skin-eigen --example held_band
//! ```
//! Options: `--modes m` (default 16), `--kernels K` (default 1000), `--points N` (basis grid
//! points, default 20000).
//!
//! Output: the median kernel radius and, per window, the largest mode weight on slabs
//! x ∈ [a, a + 0.05) relative to its largest value along the beam, and the distance beyond
//! x = 0.5 m where that ratio first reaches 1% and 10%.

use hyperelastic::LameParameters;
use nalgebra::Vector3;
use rkpm_core::{KernelWindow, sample_box_grid};
use skin_eigen::{BasisParams, RegionConstraintParams, build_basis_with_regions};

/// Command-line options.
#[derive(clap::Parser)]
struct Args {
    /// Modes m.
    #[arg(long, default_value_t = 16)]
    modes: usize,
    /// Kernels K.
    #[arg(long, default_value_t = 1000)]
    kernels: usize,
    /// Basis grid points.
    #[arg(long = "points", default_value_t = 20_000)]
    points: usize,
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Args = clap::Parser::parse();
    let spacing = (5.0 / args.points as f64).cbrt();
    let grid = sample_box_grid(Vector3::zeros(), Vector3::new(5.0, 1.0, 1.0), spacing)?;
    let lame = vec![LameParameters::from_young_poisson(5e6, 0.45)?; grid.len()];
    let region: Vec<Vector3<f64>> = grid
        .positions()
        .iter()
        .filter(|x| x.x <= 0.5)
        .copied()
        .collect();
    // Probes along the beam: a 5 × 5 lattice across every 0.025 m.
    let probes: Vec<Vector3<f64>> = (0..200)
        .flat_map(|i| {
            (0..5).flat_map(move |j| {
                (0..5).map(move |k| {
                    Vector3::new(
                        0.0125 + 0.025 * i as f64,
                        0.1 + 0.2 * j as f64,
                        0.1 + 0.2 * k as f64,
                    )
                })
            })
        })
        .collect();
    for window in [KernelWindow::Gaussian, KernelWindow::CubicBSpline] {
        let mut params = BasisParams::default()
            .with_modes(args.modes)
            .with_kernels(args.kernels);
        params.shape_functions.window = window;
        let (basis, report, _) = build_basis_with_regions(
            &grid,
            &lame,
            &params,
            std::slice::from_ref(&region),
            &RegionConstraintParams::default(),
            &[],
        )?;
        let mut radii = basis.kernels().radii().to_vec();
        radii.sort_by(f64::total_cmp);
        let w = basis.evaluate(&probes)?.weights;
        // Largest |mode weight| per probe slab (modes: columns 1.. of a one-region basis).
        let slab = |i: usize| -> f64 {
            (25 * i..25 * (i + 1))
                .flat_map(|p| (1..w.ncols()).map(move |j| (p, j)))
                .map(|(p, j)| w[(p, j)].abs())
                .fold(0.0, f64::max)
        };
        let profile: Vec<f64> = (0..200).map(slab).collect();
        let peak = profile.iter().copied().fold(0.0, f64::max);
        let reach = |fraction: f64| -> f64 {
            (20..200)
                .find(|&i| profile[i] >= fraction * peak)
                .map_or(f64::NAN, |i| 0.025 * i as f64 - 0.5)
        };
        println!(
            "{window:?}: median kernel radius {:.3} m, {} region points, modes on the region ≤ {:.1e}; \
             the modes reach 1% of their peak {:.3} m and 10% {:.3} m beyond x = 0.5",
            radii[radii.len() / 2],
            region.len(),
            report
                .held_regions
                .map_or(f64::NAN, |h| h.max_mode_value_on_regions),
            reach(0.01),
            reach(0.1),
        );
        let line: Vec<String> = (16..48)
            .step_by(2)
            .map(|i| format!("{:.2}:{:.0e}", 0.025 * i as f64, profile[i] / peak))
            .collect();
        println!("  x:|W|/peak  {}", line.join(" "));
    }
    Ok(())
}
