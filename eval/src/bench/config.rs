//! What the bench sweeps ([`BenchConfig`]): one [`BenchMethod`] per run, labelled by the knob it
//! varies.

use optimize::HessianReuse;
use std::path::PathBuf;

use baselines::SimplicitsParams;
use fem_ref::ElementOrder;
use reduced_sim::{CubatureParams, QuadratureRule, SimulationParams};
use serde::{Deserialize, Serialize};

use crate::beam_scenario::BeamTest;
use crate::fem_reference::FemResolution;
use crate::reduced_settings::{EXACT_INSET_KERNEL_RADII, ReducedSettings};

/// The cubature of the bench's cubature series: [`CubatureParams::default`] (relative force
/// error 0.02 on the training poses, at most 400 points).
pub const CUBATURE: QuadratureRule = QuadratureRule::Cubature(CubatureParams::DEFAULT);

/// The fast-step series at modes `modes` on `base`: Hessian reuse on every point,
/// then the cubature with fresh and with reused Hessians.
fn fast_step_runs(base: ReducedSettings, modes: &[usize]) -> Vec<(String, BenchMethod)> {
    let mut runs = Vec::new();
    for (knob, quadrature, hessian_reuse) in [
        (
            "Hessian reuse",
            QuadratureRule::Full,
            SimulationParams::HESSIAN_REUSE,
        ),
        ("cubature", CUBATURE, HessianReuse::Never),
        (
            "cubature + reuse",
            CUBATURE,
            SimulationParams::HESSIAN_REUSE,
        ),
    ] {
        for &m in modes {
            runs.push((
                knob.into(),
                BenchMethod::FreeForm(ReducedSettings {
                    modes: m,
                    quadrature,
                    hessian_reuse,
                    ..base
                }),
            ));
        }
    }
    runs
}

/// One configuration to time.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum BenchMethod {
    /// FreeForm with these settings.
    #[serde(rename = "freeform", alias = "FreeForm")]
    FreeForm(ReducedSettings),
    /// FreeForm with these settings and the clamped end held exactly, on the end shrunk by this
    /// many median kernel radii ([`crate::beam_protocol::reduced::exact_pin_hold`]).
    #[serde(rename = "freeform_exact", alias = "FreeFormExact")]
    FreeFormExact(ReducedSettings, f64),
    /// The FEM at a coarser resolution than the ground truth.
    #[serde(alias = "Fem")]
    Fem(FemResolution),
    /// The Simplicits baseline (network trained on the basis grid of the settings, cached),
    /// simulated with these settings.
    #[serde(alias = "Simplicits")]
    Simplicits(ReducedSettings, SimplicitsParams),
    /// The MPM baseline at this grid spacing (m), otherwise [`crate::particle_baselines::mpm::MpmStudyConfig::default`]
    /// (trajectories cached, shared with Table 1).
    #[serde(alias = "Mpm")]
    Mpm(f64),
    /// The SPH baseline at this particle spacing (m), otherwise [`crate::particle_baselines::sph::SphStudyConfig::default`]
    /// (trajectories cached, shared with Table 1).
    #[serde(alias = "Sph")]
    Sph(f64),
}

/// What to sweep.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BenchConfig {
    /// Bend steps (300 = design §4.1).
    pub steps: usize,
    /// The ground truth.
    pub ground_truth: FemResolution,
    /// (knob being varied, configuration).
    pub runs: Vec<(String, BenchMethod)>,
    /// Cache folder.
    pub cache_dir: PathBuf,
}

impl BenchConfig {
    /// The full sweep around the default (m = 16, K = 1000, 5000 points, tolerance 1e-6), the
    /// Simplicits baseline at the four m of Table 1 (trained once, about 10 min per m on 2
    /// cores, then cached), and five coarser FEM levels.
    pub fn full(cache_dir: PathBuf) -> Self {
        let base = ReducedSettings::default();
        let mut runs = Vec::new();
        for m in [6, 9, 16, 32] {
            runs.push((
                "m".into(),
                BenchMethod::FreeForm(ReducedSettings { modes: m, ..base }),
            ));
        }
        runs.extend(freeform_sweeps(base));
        runs.extend(baseline_runs(base));
        BenchConfig {
            steps: BeamTest::Bend.steps(),
            ground_truth: FemResolution::GROUND_TRUTH,
            runs,
            cache_dir,
        }
    }

    /// A one-minute sweep: 100 steps, ground truth P2 res 4, m ∈ {6, 16} at K = 500, two FEM
    /// levels.
    pub fn quick(cache_dir: PathBuf) -> Self {
        let base = ReducedSettings {
            kernels: 500,
            basis_points: 10_000,
            ..ReducedSettings::default()
        };
        let mut runs: Vec<(String, BenchMethod)> = [6, 16]
            .into_iter()
            .map(|m| {
                (
                    "m".into(),
                    BenchMethod::FreeForm(ReducedSettings { modes: m, ..base }),
                )
            })
            .collect();
        runs.push((
            "points".into(),
            BenchMethod::FreeForm(ReducedSettings {
                simulation_points: 2000,
                ..base
            }),
        ));
        runs.extend(fast_step_runs(base, &[6, 16]));
        for order in [ElementOrder::Linear, ElementOrder::Quadratic] {
            runs.push((
                "FEM".into(),
                BenchMethod::Fem(FemResolution {
                    order,
                    cells_per_metre: 2,
                }),
            ));
        }
        BenchConfig {
            steps: 100,
            ground_truth: FemResolution {
                cells_per_metre: 4,
                ..FemResolution::GROUND_TRUTH
            },
            runs,
            cache_dir,
        }
    }
}

/// The full sweep's FreeForm runs past the plain m series: the fast step, the basis grid, the
/// exact pins, the converging setting ([`ReducedSettings::converging`]) at m = 16 … 64, fewer
/// quadrature points, and K, points, tolerance and pin factor about `base`.
fn freeform_sweeps(base: ReducedSettings) -> Vec<(String, BenchMethod)> {
    let mut runs = Vec::new();
    runs.extend(fast_step_runs(base, &[6, 9, 16, 32]));
    // The simulation on the basis's own grid (20 000 points instead of 5000): the cubature
    // keeps the step's cost, and the Bend MSE at m = 32 drops about 4×.
    for m in [6, 9, 16, 32] {
        runs.push((
            "basis grid".into(),
            BenchMethod::FreeForm(ReducedSettings {
                modes: m,
                simulation_points: base.basis_points,
                quadrature: CUBATURE,
                hessian_reuse: SimulationParams::HESSIAN_REUSE,
                ..base
            }),
        ));
    }
    for m in [6, 9, 16, 32] {
        runs.push((
            "exact pins".into(),
            BenchMethod::FreeFormExact(
                ReducedSettings {
                    modes: m,
                    ..ReducedSettings::library_step()
                },
                EXACT_INSET_KERNEL_RADII,
            ),
        ));
    }
    // The setting whose error falls monotonically in m, on to m = 64.
    for m in [16, 32, 48, 64] {
        runs.push((
            "converging".into(),
            BenchMethod::FreeForm(ReducedSettings {
                modes: m,
                ..base.converging()
            }),
        ));
    }
    for tolerance in [0.05, 0.005] {
        runs.push((
            "quadrature points".into(),
            BenchMethod::FreeForm(ReducedSettings {
                quadrature: QuadratureRule::Cubature(CubatureParams {
                    tolerance,
                    ..CubatureParams::DEFAULT
                }),
                ..base
            }),
        ));
    }
    for points in [150, 500] {
        runs.push((
            "quadrature points".into(),
            BenchMethod::FreeForm(ReducedSettings {
                quadrature: QuadratureRule::RandomSubset { points, seed: 0 },
                ..base
            }),
        ));
    }
    for k in [250, 500, 2000] {
        runs.push((
            "K".into(),
            BenchMethod::FreeForm(ReducedSettings { kernels: k, ..base }),
        ));
    }
    for n in [1000, 2000, 10_000] {
        runs.push((
            "points".into(),
            BenchMethod::FreeForm(ReducedSettings {
                simulation_points: n,
                ..base
            }),
        ));
    }
    for tol in [1e-2, 1e-4] {
        runs.push((
            "tolerance".into(),
            BenchMethod::FreeForm(ReducedSettings {
                newton_tolerance: tol,
                ..base
            }),
        ));
    }
    for pin_factor in [1e2, 1e4] {
        runs.push((
            "pin factor".into(),
            BenchMethod::FreeForm(ReducedSettings { pin_factor, ..base }),
        ));
    }
    runs
}

/// The full sweep's other methods: Simplicits at Table 1's m, MPM and SPH at two spacings,
/// five coarser FEM levels.
fn baseline_runs(base: ReducedSettings) -> Vec<(String, BenchMethod)> {
    let mut runs = Vec::new();
    for m in [6, 9, 16, 32] {
        runs.push((
            "m".into(),
            BenchMethod::Simplicits(
                ReducedSettings { modes: m, ..base },
                SimplicitsParams {
                    modes: m,
                    ..SimplicitsParams::default()
                },
            ),
        ));
    }
    // Δx = 0.05 m would add more than an hour (Table 1 runs it).
    for spacing in [0.2, 0.1] {
        runs.push(("MPM Δx".into(), BenchMethod::Mpm(spacing)));
    }
    // 0.05 m (40 000 particles) takes about 3 min for the 300 steps; Table 1 runs it.
    for spacing in [0.2, 0.1] {
        runs.push(("SPH spacing".into(), BenchMethod::Sph(spacing)));
    }
    for (order, r) in [
        (ElementOrder::Linear, 2),
        (ElementOrder::Linear, 4),
        (ElementOrder::Linear, 8),
        (ElementOrder::Quadratic, 2),
        (ElementOrder::Quadratic, 4),
    ] {
        runs.push((
            "FEM".into(),
            BenchMethod::Fem(FemResolution {
                order,
                cells_per_metre: r,
            }),
        ));
    }
    runs
}
