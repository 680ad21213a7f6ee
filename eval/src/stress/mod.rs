//! The numerical stress suite (`freeform-paper stress`): the reduced simulator pushed to the edges a
//! user will hit — near-incompressible materials, stiffness contrast, large time steps, fast
//! twists that invert material, a 10 m/s impact, extreme m and K, degenerate sampling — with
//! per-case diagnostics that make a failure loud.
//!
//! Per case: finished or the named error it stopped with (a panic is caught and reported as a
//! bug), all values finite, Newton convergence per step, the largest energy growth
//! `max_t (H_t − H_0 − W_t) / S` and the smallest det F reached. Here
//! `H = kinetic + elastic + gravity potential + pin and floor penalty energy`, `W_t` the work
//! the moving pins did on the body up to step t (trapezoidal), and `S` the largest energy
//! exchanged (`max |W_t|`, `max |ΔU_gravity|`, the initial kinetic energy). Backward Euler only
//! dissipates, so a growth above the Newton tolerance's noise means energy was created.

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::time::Instant;

use serde::{Deserialize, Serialize};

/// The object and what happens to it.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum StressScene {
    /// The beam of design §4.1 (5 × 1 × 1 m, E = 5 MPa) under gravity, x ≤ 0.5 pinned.
    #[serde(alias = "BeamBend")]
    BeamBend,
    /// The beam with x ≤ 0.5 pinned and x ≥ 4.5 rotated about its axis at this rate up to 720°.
    #[serde(alias = "BeamTwist")]
    BeamTwist {
        /// Degrees per second (design §4.1: 2160).
        degrees_per_second: f64,
    },
    /// A 1 m cube (E = 0.1 MPa) starting 2 cm above a floor, moving down at this speed.
    #[serde(alias = "CubeImpact")]
    CubeImpact {
        /// m/s.
        speed: f64,
    },
    /// The paper's layered sphere (Sec. 9.2): radius 0.5 m, four concentric shells
    /// stiff-soft-stiff-soft (soft E = 0.1 MPa, stiff `contrast` times that), dropped from
    /// 0.1 m onto a floor (it lands after about 14 steps of 0.01 s).
    #[serde(alias = "LayeredSphereDrop")]
    LayeredSphereDrop {
        /// Stiff / soft Young's modulus.
        contrast: f64,
    },
    /// A 1 × 1 × `thickness` m plate (E = 0.1 MPa) under gravity, x ≤ 0.1 pinned, sampled by
    /// the given degenerate rule.
    #[serde(alias = "Plate")]
    Plate {
        /// Plate thickness (m).
        thickness: f64,
        /// How its points are placed.
        sampling: DegenerateSampling,
    },
}

/// Sampling rules a careless user might feed the basis builder.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DegenerateSampling {
    /// A grid whose spacing equals the thickness: one layer of coplanar points.
    #[serde(alias = "OneLayer")]
    OneLayer,
    /// A jittered grid of about this many points, each moved by up to 40% of the spacing.
    #[serde(alias = "SparseNoisy")]
    SparseNoisy {
        /// Number of points.
        points: usize,
    },
    /// A grid with every point given twice.
    #[serde(alias = "Duplicated")]
    Duplicated,
}

/// Which simulator a case runs.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum StressSolver {
    /// FreeForm's reduced simulator (default).
    #[default]
    #[serde(alias = "Reduced")]
    Reduced,
    /// The FEM reference, P2 tetrahedra at 2 cells per metre (beam scenes only; no energy
    /// balance: its Dirichlet handles' work is not tracked, so the growth column is NaN).
    #[serde(alias = "Fem")]
    Fem,
}

/// One case of the suite.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct StressCase {
    /// The simulator.
    pub solver: StressSolver,
    /// Group ("ν", "dt", "twist", …) and short name.
    pub group: String,
    /// What varies, e.g. "ν = 0.499".
    pub name: String,
    /// The object and its scene.
    pub scene: StressScene,
    /// Poisson ratio ν.
    pub poisson_ratio: f64,
    /// Time step h (s).
    pub time_step: f64,
    /// Steps to run.
    pub steps: usize,
    /// Modes m.
    pub modes: usize,
    /// Kernels K.
    pub kernels: usize,
    /// Grid points for the basis (grid scenes).
    pub basis_points: usize,
    /// Grid points for the simulation (grid scenes).
    pub simulation_points: usize,
}

impl StressCase {
    fn beam(group: &str, name: String, scene: StressScene, steps: usize) -> Self {
        StressCase {
            solver: StressSolver::Reduced,
            group: group.into(),
            name,
            scene,
            poisson_ratio: 0.45,
            time_step: 0.01,
            steps,
            modes: 16,
            kernels: 500,
            basis_points: 10_000,
            simulation_points: 5000,
        }
    }
}

/// How a case ended.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CaseStatus {
    /// Every step ran.
    #[serde(alias = "Finished")]
    Finished,
    /// Stopped with a named error (setup or a step): a safe failure.
    #[serde(alias = "Error")]
    Error(String),
    /// A panic: a bug, whatever the input.
    #[serde(alias = "Panicked")]
    Panicked(String),
}

/// One case's diagnostics.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct StressOutcome {
    /// The case.
    pub case: StressCase,
    /// How it ended.
    pub status: CaseStatus,
    /// Steps completed.
    pub steps_run: usize,
    /// Steps whose Newton solve stopped before its tolerance.
    pub unconverged_steps: usize,
    /// Every coordinate, velocity and point position stayed finite.
    pub all_finite: bool,
    /// `max(0, max_t (H_t − H_0 − W_t)) / S` (see the module docs); positive means energy was
    /// created.
    pub max_energy_growth: f64,
    /// Smallest det F over the simulation points and steps.
    pub min_det_f: f64,
    /// Wall time including the basis (s).
    pub seconds: f64,
}

impl StressOutcome {
    /// The outcome of `case` before it runs: finished, nothing run, nothing measured.
    fn not_run(case: &StressCase) -> Self {
        StressOutcome {
            case: case.clone(),
            status: CaseStatus::Finished,
            steps_run: 0,
            unconverged_steps: 0,
            all_finite: true,
            max_energy_growth: f64::NAN,
            min_det_f: f64::NAN,
            seconds: 0.0,
        }
    }

    /// Acceptable: finished or stopped with a named error, and never a non-finite value.
    pub fn acceptable(&self) -> bool {
        self.all_finite && !matches!(self.status, CaseStatus::Panicked(_))
    }
}

/// The cases to run.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct StressConfig {
    /// The cases, in order.
    pub cases: Vec<StressCase>,
}

/// The full matrix's FEM reference cases (ν = 0.3 and 0.499, dt = 0.1, the fast twist) and its
/// degenerate samplings (a one-layer plate, a sparse noisy cloud, duplicated points).
fn fem_and_sampling_cases() -> Vec<StressCase> {
    let mut cases = Vec::new();
    for (name, nu, dt, scene, steps) in [
        ("FEM Bend ν = 0.3", 0.3, 0.01, StressScene::BeamBend, 300),
        (
            "FEM Bend ν = 0.499",
            0.499,
            0.01,
            StressScene::BeamBend,
            300,
        ),
        ("FEM Bend dt = 0.1", 0.45, 0.1, StressScene::BeamBend, 30),
        (
            "FEM Twist 4× faster (8640°/s)",
            0.45,
            0.01,
            StressScene::BeamTwist {
                degrees_per_second: 8640.0,
            },
            34,
        ),
    ] {
        cases.push(StressCase {
            solver: StressSolver::Fem,
            poisson_ratio: nu,
            time_step: dt,
            ..StressCase::beam("FEM", name.into(), scene, steps)
        });
    }
    for (name, thickness, sampling) in [
        ("plate one point thick", 0.05, DegenerateSampling::OneLayer),
        (
            "sparse noisy cloud (300 points)",
            0.3,
            DegenerateSampling::SparseNoisy { points: 300 },
        ),
        (
            "every point duplicated",
            0.3,
            DegenerateSampling::Duplicated,
        ),
    ] {
        cases.push(StressCase {
            modes: 8,
            kernels: 64,
            basis_points: 2000,
            simulation_points: 2000,
            ..StressCase::beam(
                "sampling",
                name.into(),
                StressScene::Plate {
                    thickness,
                    sampling,
                },
                30,
            )
        });
    }
    cases
}

impl StressConfig {
    /// The matrix: ν ∈ {0.3, 0.45, 0.49, 0.499}; contrast 10² and 10⁴; dt ∈ {0.01,
    /// 0.05, 0.1}; the 720° Twist, held past 720°, and 4× faster; a 10 m/s impact; m from 1 to
    /// 64 and K from 64 to 4000; the FEM reference at ν = 0.3 and 0.499, dt = 0.1 and the fast
    /// twist; a one-layer plate, a sparse noisy cloud, duplicated points.
    pub fn full() -> Self {
        let mut cases = Vec::new();
        for nu in [0.3, 0.45, 0.49, 0.499] {
            cases.push(StressCase {
                poisson_ratio: nu,
                ..StressCase::beam("ν", format!("Bend ν = {nu}"), StressScene::BeamBend, 300)
            });
        }
        for contrast in [1e2, 1e4] {
            cases.push(StressCase {
                kernels: 400,
                basis_points: 8000,
                simulation_points: 4000,
                ..StressCase::beam(
                    "contrast",
                    format!("layered sphere, contrast {contrast:.0e}"),
                    StressScene::LayeredSphereDrop { contrast },
                    100,
                )
            });
        }
        for dt in [0.01, 0.05, 0.1] {
            cases.push(StressCase {
                time_step: dt,
                ..StressCase::beam(
                    "dt",
                    format!("Bend dt = {dt}"),
                    StressScene::BeamBend,
                    (3.0 / dt).round() as usize,
                )
            });
        }
        for (name, rate, steps) in [
            ("Twist 720° (34 steps)", 2160.0, 34),
            ("Twist held at 720° to 1 s", 2160.0, 100),
            ("Twist 4× faster (8640°/s)", 8640.0, 34),
        ] {
            cases.push(StressCase::beam(
                "twist",
                name.into(),
                StressScene::BeamTwist {
                    degrees_per_second: rate,
                },
                steps,
            ));
        }
        cases.push(StressCase {
            kernels: 400,
            basis_points: 8000,
            simulation_points: 4000,
            ..StressCase::beam(
                "impact",
                "cube at 10 m/s onto a floor".into(),
                StressScene::CubeImpact { speed: 10.0 },
                60,
            )
        });
        for m in [1, 4, 16, 64] {
            cases.push(StressCase {
                modes: m,
                kernels: 1000,
                basis_points: 20_000,
                ..StressCase::beam("m", format!("Bend m = {m}"), StressScene::BeamBend, 100)
            });
        }
        for k in [64, 250, 1000, 4000] {
            cases.push(StressCase {
                kernels: k,
                basis_points: 20_000,
                ..StressCase::beam("K", format!("Bend K = {k}"), StressScene::BeamBend, 100)
            });
        }
        cases.extend(fem_and_sampling_cases());
        StressConfig { cases }
    }

    /// A subset that runs in well under a minute on 2 cores: ν = 0.499, dt = 0.1, the fast
    /// twist, the impact, contrast 10⁴, m = 1, the FEM at ν = 0.499, and the three degenerate
    /// samplings, all short and coarse.
    pub fn quick() -> Self {
        let full = StressConfig::full();
        let pick = |name: &str| {
            full.cases
                .iter()
                .find(|c| c.name == name)
                .cloned()
                .expect("a case of the full matrix")
        };
        let coarse = |c: StressCase, steps: usize| StressCase {
            steps,
            kernels: c.kernels.min(150),
            basis_points: c.basis_points.min(3000),
            simulation_points: c.simulation_points.min(1500),
            ..c
        };
        let cases = vec![
            coarse(pick("Bend ν = 0.499"), 20),
            coarse(pick("Bend dt = 0.1"), 10),
            coarse(pick("Twist 4× faster (8640°/s)"), 12),
            coarse(pick("cube at 10 m/s onto a floor"), 15),
            coarse(pick("layered sphere, contrast 1e4"), 25),
            coarse(pick("Bend m = 1"), 10),
            coarse(pick("FEM Bend ν = 0.499"), 10),
            pick("plate one point thick"),
            coarse(pick("sparse noisy cloud (300 points)"), 10),
            coarse(pick("every point duplicated"), 10),
        ];
        StressConfig { cases }
    }
}

/// Runs every case (a panic inside a case is caught and reported), calling `on_case` after each.
pub fn run_stress(
    config: &StressConfig,
    mut on_case: impl FnMut(&StressOutcome),
) -> Vec<StressOutcome> {
    config
        .cases
        .iter()
        .map(|case| {
            let start = Instant::now();
            let outcome = match catch_unwind(AssertUnwindSafe(|| run_case(case))) {
                Ok(outcome) => outcome,
                Err(panic) => {
                    let message = panic
                        .downcast_ref::<String>()
                        .cloned()
                        .or_else(|| panic.downcast_ref::<&str>().map(|s| s.to_string()))
                        .unwrap_or_else(|| "unknown panic".into());
                    StressOutcome {
                        status: CaseStatus::Panicked(message),
                        ..StressOutcome::not_run(case)
                    }
                }
            };
            let outcome = StressOutcome {
                seconds: start.elapsed().as_secs_f64(),
                ..outcome
            };
            on_case(&outcome);
            outcome
        })
        .collect()
}

/// The outcomes as a Markdown table, with what each column means.
pub fn stress_markdown(outcomes: &[StressOutcome]) -> String {
    use std::fmt::Write as _;
    let mut md = String::from(
        "## Stress suite (reduced simulator)\n\n\
         growth = max_t (H_t − H_0 − W_t) / S: energy created, relative to the largest energy \
         exchanged (H = kinetic + elastic + gravity + penalty energies, W = work of moving pins); \
         0 means the energy never rose above its start (backward Euler only dissipates). min det F over all points and steps (< 0: inverted \
         material). ok = finished or stopped with a named error, all values finite, no panic.\n\n\
         | group | case | ν | dt | m | K | status | steps | unconverged | finite | growth | min det F | s | ok |\n\
         |---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for o in outcomes {
        let c = &o.case;
        let reduced_only = |v: usize| match c.solver {
            StressSolver::Reduced => v.to_string(),
            StressSolver::Fem => "—".into(),
        };
        let status = match &o.status {
            CaseStatus::Finished => "finished".to_string(),
            CaseStatus::Error(e) => format!("error: {}", e.replace('|', "/")),
            CaseStatus::Panicked(e) => format!("PANIC: {}", e.replace('|', "/")),
        };
        let _ = writeln!(
            md,
            "| {} | {} | {} | {} | {} | {} | {} | {}/{} | {} | {} | {:.1e} | {:.3} | {:.1} | {} |",
            c.group,
            c.name,
            c.poisson_ratio,
            c.time_step,
            reduced_only(c.modes),
            reduced_only(c.kernels),
            status,
            o.steps_run,
            c.steps,
            o.unconverged_steps,
            if o.all_finite { "yes" } else { "NO" },
            o.max_energy_growth,
            o.min_det_f,
            o.seconds,
            if o.acceptable() { "yes" } else { "NO" }
        );
    }
    md
}

mod fem_case;
mod reduced_case;

use reduced_case::run_case;
