//! Determinism: the same inputs and seed give bit-identical outputs for the basis, the reduced
//! simulation and the FEM reference. Runs are repeated in a 3-thread rayon pool (more threads
//! than this machine's cores, so work stealing varies between runs) and compared bit for bit:
//! a parallel sum whose association depended on stealing would differ in the last bits.
//!
//! The FEM is even identical on 1 and 3 threads, and so is the weight-space assembly
//! (`skin-eigen/tests/eigenmodes.rs`); the basis is not across thread counts (≈1e-13 relative)
//! because faer's dense eigensolver blocks its work by the thread count.

use eval::beam_protocol::reduced::{build_beam_basis, run_reduced_beam};
use eval::beam_scenario::BeamTest;
use eval::fem_reference::{FemResolution, run_fem_beam};
use eval::reduced_settings::ReducedSettings;
use fem_ref::ElementOrder;
use freeform::terminal_progress::TerminalProgress;
use nalgebra::Vector3;
use optimize::NewtonParams;

fn in_pool<T: Send>(threads: usize, f: impl FnOnce() -> T + Send) -> T {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap()
        .install(f)
}

fn settings() -> ReducedSettings {
    ReducedSettings {
        modes: 6,
        kernels: 120,
        basis_points: 3000,
        simulation_points: 1500,
        ..ReducedSettings::default()
    }
}

#[test]
fn basis_and_reduced_simulation_are_bit_identical_across_runs() {
    let quiet = TerminalProgress {
        quiet: true,
        ..Default::default()
    };
    let outputs: Vec<Vector3<f64>> = (0..=20)
        .map(|i| Vector3::new(0.25 * i as f64, 0.5, 0.5))
        .collect();
    let run = |threads| {
        in_pool(threads, || {
            let basis = build_beam_basis(&settings()).unwrap();
            let frames = [BeamTest::Bend, BeamTest::Twist].map(|test| {
                run_reduced_beam(test, &basis.basis, &settings(), &outputs, 12, &quiet)
                    .unwrap()
                    .frames
            });
            (basis.basis, frames)
        })
    };
    let (first_basis, first_frames) = run(3);
    let (second_basis, second_frames) = run(3);
    assert_eq!(
        first_basis.kernels(),
        second_basis.kernels(),
        "kernel placement"
    );
    assert_eq!(
        first_basis.coefficients(),
        second_basis.coefficients(),
        "eigen-weights"
    );
    assert_eq!(first_basis.eigenvalues(), second_basis.eigenvalues());
    assert_eq!(first_frames, second_frames, "reduced trajectories");
    // The runs moved (a frozen simulation would be trivially deterministic).
    assert!((first_frames[0][12][20] - outputs[20]).norm() > 1e-3);
}

#[test]
fn fem_reference_is_bit_identical_on_one_and_three_threads() {
    let quiet = TerminalProgress {
        quiet: true,
        ..Default::default()
    };
    let dir = std::env::temp_dir().join(format!("freeform-determinism-{}", std::process::id()));
    let resolution = FemResolution {
        order: ElementOrder::Quadratic,
        cells_per_metre: 2,
    };
    let run = |threads: usize| {
        in_pool(threads, || {
            // A separate cache per run, so both are computed.
            run_fem_beam(
                BeamTest::Twist,
                resolution,
                NewtonParams::default(),
                6,
                &dir.join(format!("cache{threads}")),
                &quiet,
            )
            .unwrap()
        })
    };
    let (one, three) = (run(1), run(3));
    assert!(!one.cached && !three.cached);
    assert_eq!(one.frames, three.frames, "FEM trajectories");
    assert!((one.frames[6][0] - one.frames[0][0]).norm() >= 0.0);
    let moved = one.frames[6]
        .iter()
        .zip(&one.frames[0])
        .map(|(a, b)| (a - b).norm())
        .fold(0.0, f64::max);
    assert!(moved > 0.1, "the twisted end moved {moved} m");
    let _ = std::fs::remove_dir_all(&dir);
}
