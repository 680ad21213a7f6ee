//! The bench's runs: every configuration against the ground truth, each method's run with its
//! step cost, scored at the ground truth's vertices.

use nalgebra::Vector3;
use optimize::{HessianReuse, NewtonParams};

use baselines::SimplicitsParams;
use reduced_sim::QuadratureRule;

use crate::EvalError;
use crate::beam_protocol::evaluation::region_drift;
use crate::beam_protocol::reduced::{
    build_beam_basis_for, exact_pin_hold, run_reduced_beam, run_reduced_beam_with,
};
use crate::beam_scenario::{BeamTest, beam_length_scale, beam_material};
use crate::bench::config::{BenchConfig, BenchMethod};
use crate::bench::report::{BenchResult, pareto_front};
use crate::fem_reference::{FemResolution, beam_seconds_per_step_here, run_fem_beam};
use crate::particle_baselines::mpm::MpmStudyConfig;
use crate::particle_baselines::particle_baseline::ParticleBeamRun;
use crate::particle_baselines::particle_config::ParticleConfig;
use crate::particle_baselines::sph::SphStudyConfig;
use crate::reduced_settings::ReducedSettings;
use crate::simplicits_cache::train_beam_simplicits;
use freeform::fem_reference::FemRun;
use freeform::metrics::trajectory_errors;
use freeform::terminal_progress::TerminalProgress;
use freeform::{PinHold, RunReport};

/// Runs every configuration against the ground truth.
///
/// # Errors
/// [`EvalError`] from any run.
pub fn run_bench(
    config: &BenchConfig,
    progress: &TerminalProgress,
) -> Result<Vec<BenchResult>, EvalError> {
    let truth = run_fem_beam(
        BeamTest::Bend,
        config.ground_truth,
        NewtonParams::default(),
        config.steps,
        &config.cache_dir,
        progress,
    )?;
    truth.check_converged(NewtonParams::default().max_iterations)?;
    let truth_frames = truth.vertex_frames();
    let vertices = truth.vertices().to_vec();
    let length = beam_length_scale();
    let bench = Bench {
        config,
        progress,
        truth: &truth,
        vertices: &vertices,
        default_mpm: MpmStudyConfig::default(),
        default_sph: SphStudyConfig::default(),
    };
    let mut results = Vec::new();
    for (knob, method) in &config.runs {
        let exact;
        let method = match method {
            BenchMethod::FreeFormExact(s, radii) => {
                exact = BenchMethod::FreeForm(ReducedSettings {
                    pins: exact_pin_hold(s, *radii)?,
                    ..*s
                });
                &exact
            }
            method => method,
        };
        let Some(run) = bench.run(method)? else {
            continue;
        };
        let errors = trajectory_errors(&run.frames[1..], &truth_frames[1..], length)?;
        progress.status(format!(
            "{} {}: {:.2} ms/step, MSE {:.2e}",
            run.name, run.label, run.timing.ms_per_step, errors.normalized_mse
        ));
        results.push(BenchResult {
            method: run.name.into(),
            knob: knob.clone(),
            label: run.label,
            ms_per_step: run.timing.ms_per_step,
            ms_split: run.timing.split,
            hessians_per_step: run.timing.hessians_per_step,
            quadrature_points: run.timing.quadrature_points,
            setup_seconds: run.setup_seconds,
            normalized_mse: errors.normalized_mse,
            normalized_max: errors.normalized_max,
            region_drift: run.drift,
            pareto: false,
        });
    }
    let points: Vec<(f64, f64)> = results
        .iter()
        .map(|r| (r.ms_per_step, r.normalized_mse))
        .collect();
    for i in pareto_front(&points) {
        results[i].pareto = true;
    }
    Ok(results)
}

/// What every run of the bench shares.
struct Bench<'a> {
    config: &'a BenchConfig,
    progress: &'a TerminalProgress,
    truth: &'a FemRun,
    vertices: &'a [Vector3<f64>],
    default_mpm: MpmStudyConfig,
    default_sph: SphStudyConfig,
}

/// One method's run before it is scored.
struct MethodRun {
    /// "freeform", "simplicits", "mpm", "sph" or "fem".
    name: &'static str,
    label: String,
    timing: Timing,
    setup_seconds: f64,
    /// Positions at the ground truth's vertices, frame by frame (m).
    frames: Vec<Vec<Vector3<f64>>>,
    /// Largest drift of the clamped end (m).
    drift: f64,
}

impl Bench<'_> {
    /// `method`'s run, or `None` for a particle run that failed (reported and left out).
    fn run(&self, method: &BenchMethod) -> Result<Option<MethodRun>, EvalError> {
        match method {
            BenchMethod::FreeForm(s) => self.freeform(s).map(Some),
            BenchMethod::Simplicits(s, params) => self.simplicits(s, params).map(Some),
            BenchMethod::Mpm(spacing) => {
                self.particle(ParticleConfig::Mpm(&self.default_mpm), *spacing)
            }
            BenchMethod::Sph(spacing) => {
                self.particle(ParticleConfig::Sph(&self.default_sph), *spacing)
            }
            BenchMethod::FreeFormExact(..) => unreachable!("resolved to FreeForm by run_bench"),
            BenchMethod::Fem(r) => self.fem(*r).map(Some),
        }
    }

    fn freeform(&self, s: &ReducedSettings) -> Result<MethodRun, EvalError> {
        let basis = build_beam_basis_for(BeamTest::Bend, s)?;
        let run = run_reduced_beam_with(
            BeamTest::Bend,
            &basis.basis,
            s,
            beam_material(),
            Some(&self.config.cache_dir),
            self.vertices,
            self.config.steps,
            self.progress,
        )?;
        Ok(MethodRun {
            name: "freeform",
            label: format!(
                "m={} K={} pts={} tol={:e} pin={}{}{}{}",
                s.modes,
                s.kernels,
                run.report.simulation_points,
                s.newton_tolerance,
                match s.pins {
                    PinHold::Penalty => format!("{:e}", s.pin_factor),
                    PinHold::Exact { inset } => format!("exact(inset {inset:.3} m)"),
                    PinHold::Weighted { .. } => "weighted".to_string(),
                },
                match s.hessian_reuse {
                    HessianReuse::Never => String::new(),
                    HessianReuse::WhileContracting { contraction } => {
                        format!(" reuse={contraction}")
                    }
                },
                quadrature_label(&s.quadrature, run.report.quadrature.points),
                if s.pressure.is_some() {
                    " pressure"
                } else {
                    ""
                },
            ),
            timing: Timing::of(&run.report),
            setup_seconds: basis.seconds + run.report.setup_seconds,
            drift: region_drift(BeamTest::Bend, self.vertices, &run.frames),
            frames: run.frames,
        })
    }

    fn simplicits(
        &self,
        s: &ReducedSettings,
        params: &SimplicitsParams,
    ) -> Result<MethodRun, EvalError> {
        let net = train_beam_simplicits(
            params,
            s.basis_points,
            &self.config.cache_dir,
            self.progress,
        )?;
        let run = run_reduced_beam(
            BeamTest::Bend,
            &net.trained.field,
            s,
            self.vertices,
            self.config.steps,
            self.progress,
        )?;
        Ok(MethodRun {
            name: "simplicits",
            label: format!(
                "m={} pts={} ({} training steps)",
                s.modes, run.report.simulation_points, params.steps
            ),
            timing: Timing::of(&run.report),
            setup_seconds: net.trained.report.seconds,
            drift: region_drift(BeamTest::Bend, self.vertices, &run.frames),
            frames: run.frames,
        })
    }

    fn particle(
        &self,
        particle: ParticleConfig<'_>,
        spacing: f64,
    ) -> Result<Option<MethodRun>, EvalError> {
        let method = particle.method();
        let ParticleBeamRun { row, frames } = particle.run(
            BeamTest::Bend,
            spacing,
            self.config.steps,
            self.truth,
            &self.config.cache_dir,
            self.progress,
        )?;
        if let Some(why) = &row.failure {
            self.progress.status(format!(
                "{} {} = {spacing} m left out: {why}",
                method.label(),
                method.spacing_name()
            ));
            return Ok(None);
        }
        Ok(Some(MethodRun {
            name: method.key(),
            label: format!(
                "{}={} m ({} particles, {} steps per 0.01 s)",
                method.spacing_name(),
                row.spacing,
                row.particles,
                row.substeps_per_step
            ),
            timing: Timing {
                ms_per_step: row.ms_per_step,
                split: [0.0; 3],
                hessians_per_step: 0.0,
                quadrature_points: 0,
            },
            setup_seconds: row.setup_seconds,
            frames,
            drift: row.max_pin_deviation,
        }))
    }

    fn fem(&self, r: FemResolution) -> Result<MethodRun, EvalError> {
        let run = run_fem_beam(
            BeamTest::Bend,
            r,
            NewtonParams::default(),
            self.config.steps,
            &self.config.cache_dir,
            self.progress,
        )?;
        let frames = run.frames_at(self.vertices)?;
        let (seconds_per_step, _) = beam_seconds_per_step_here(
            &run,
            BeamTest::Bend,
            r,
            NewtonParams::default(),
            self.config.steps,
        )?;
        Ok(MethodRun {
            name: "fem",
            label: format!("{} ({} DOFs)", r.label(), run.dofs),
            timing: Timing {
                ms_per_step: 1e3 * seconds_per_step,
                split: [0.0; 3],
                hessians_per_step: 1.0,
                quadrature_points: 0,
            },
            setup_seconds: 0.0,
            frames,
            drift: 0.0,
        })
    }
}

/// A run's step cost as the bench reports it.
struct Timing {
    ms_per_step: f64,
    split: [f64; 3],
    hessians_per_step: f64,
    quadrature_points: usize,
}

impl Timing {
    fn of(report: &RunReport) -> Timing {
        Timing {
            ms_per_step: report.ms_per_step,
            split: [
                report.ms_assembly_per_step,
                report.ms_solve_per_step,
                report.ms_line_search_per_step,
            ],
            hessians_per_step: report.hessians_per_step,
            quadrature_points: report.quadrature.points,
        }
    }
}

/// " cubature(tol=0.02, 142 pts)", " random(500 pts)", or "" for every point.
pub fn quadrature_label(rule: &QuadratureRule, points: usize) -> String {
    match rule {
        QuadratureRule::Full => String::new(),
        QuadratureRule::RandomSubset { .. } => format!(" random({points} pts)"),
        QuadratureRule::Cubature(p) => format!(" cubature(tol={}, {points} pts)", p.tolerance),
        QuadratureRule::Automatic(p) => {
            format!(" automatic(tol={}, {points} pts)", p.tolerance)
        }
    }
}
