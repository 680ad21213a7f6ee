//! The convergence study's run: the references per ν, then per (K, m, treatment) the bases,
//! per volumetric term the pressure spaces, and per ν the static and dynamic rows; last the
//! coarse FEM points.

use freeform::metrics::trajectory_errors;
use freeform::scene::SceneSpec;
use freeform::terminal_progress::TerminalProgress;
use freeform::{
    PressureSpace, PressureSpaceParams, Simulation, failure_chain, pressure_inf_sup,
    static_equilibrium,
};
use hyperelastic::{MaterialField, MaterialSample, StableNeoHookean};
use nalgebra::Vector3;
use optimize::NewtonParams;
use reduced_sim::DeformationMap;
use skin_eigen::SkinningBasis;

use crate::EvalError;
use crate::beam_protocol::evaluation::region_drift;
use crate::beam_protocol::reduced::{
    beam_pressure_space, beam_simulation_points, build_beam_basis_for,
    run_reduced_beam_with_pressure,
};
use crate::beam_scenario::{BEAM_TIME_STEP, BeamTest, beam_length_scale, beam_material};
use crate::convergence::config::ConvergenceConfig;
use crate::convergence::nitsche_row::{
    NitscheBeam, free_part_basis, free_part_pressure_space, nitsche_dynamic_row, nitsche_static_row,
};
use crate::convergence::options::{BoundaryTreatment, ConvergenceTest, VolumetricTerm};
use crate::convergence::result::{
    CoarseFemRow, ConvergenceRow, ConvergenceStudy, StaticReferenceCheck,
};
use crate::convergence::static_reference::{
    StaticReference, field_errors, projections, reference_error, static_reference, static_scene,
};
use crate::fem_reference::{converged_fem_beam, run_fem_beam_with};
use crate::reduced_settings::ReducedSettings;
use freeform::fem_reference::FemRun;

/// The dynamic tests' references at one ν: (test, steps, the converged FEM run).
type DynamicReferences = Vec<(ConvergenceTest, usize, FemRun)>;

/// Runs the study.
///
/// # Errors
/// [`EvalError`] for a basis or reference that cannot be built; a reduced run that fails is
/// reported in its row.
pub fn run_convergence(
    config: &ConvergenceConfig,
    progress: &TerminalProgress,
) -> Result<ConvergenceStudy, EvalError> {
    let mut study = ConvergenceStudy::default();
    let materials: Vec<MaterialSample> = config
        .poisson_ratios
        .iter()
        .map(|&nu| MaterialSample {
            poisson_ratio: nu,
            ..beam_material()
        })
        .collect();
    let static_scene = static_scene(config.static_gravity_scale);
    let mut statics = Vec::new();
    let mut dynamics = Vec::new();
    for &material in &materials {
        let (reference, per_test) =
            references(config, material, &static_scene, &mut study, progress)?;
        statics.push(reference);
        dynamics.push(per_test);
    }
    let references = References {
        materials: &materials,
        statics: &statics,
        dynamics: &dynamics,
        static_scene: &static_scene,
    };
    for &kernels in &config.kernels {
        for &m in &config.modes {
            for &treatment in &config.treatments {
                let base = ReducedSettings {
                    modes: m,
                    kernels,
                    ..config.settings
                };
                let settings = treatment.settings(&base)?;
                let bases = TreatmentBases::build(config, &settings, treatment, progress)?;
                for &volumetric in &config.volumetric {
                    let spaces =
                        PressureSpaces::build(config, m, &settings, &bases, treatment, volumetric)?;
                    let run = RowRun {
                        config,
                        settings: &settings,
                        bases: &bases,
                        spaces: &spaces,
                        kernels,
                        m,
                        treatment,
                        volumetric,
                        progress,
                    };
                    run.rows(&references, &mut study)?;
                }
            }
        }
    }
    coarse_fem_rows(config, &materials, &dynamics, &mut study, progress)?;
    if config.pool_check {
        progress.status("checking the basis grid's integration pool (twice the points)");
        study.pool_checks = super::pool_check::pool_checks(config)?;
    }
    Ok(study)
}

/// At one material: the static reference (when the static Bend runs) and the dynamic tests'
/// converged references; a reference that did not converge is named in
/// `study.refused_references` and its test left out.
fn references(
    config: &ConvergenceConfig,
    material: MaterialSample,
    static_scene: &SceneSpec,
    study: &mut ConvergenceStudy,
    progress: &TerminalProgress,
) -> Result<(Option<StaticReference>, DynamicReferences), EvalError> {
    let nu = material.poisson_ratio;
    let statics = if config.tests.contains(&ConvergenceTest::StaticBend) {
        let resolution = config.static_reference_resolution();
        progress.status(format!("static FEM ν = {nu} ({})", resolution.label()));
        let reference = static_reference(static_scene, resolution, material)?;
        if let Some(finer) = config.static_reference_check {
            progress.status(format!(
                "static FEM ν = {nu}: the reference against {}",
                finer.label()
            ));
            let error = reference_error(&reference, static_scene, finer, material)?;
            progress.status(format!(
                "static FEM ν = {nu}: {} against {}: MSE {:.3e}, tip {:+.2}%",
                resolution.label(),
                finer.label(),
                error.mse,
                100.0 * error.tip_change
            ));
            study.static_reference_checks.push(StaticReferenceCheck {
                nu,
                resolution: resolution.label(),
                finer: finer.label(),
                mse: error.mse,
                tip_change: error.tip_change,
            });
        }
        Some(reference)
    } else {
        None
    };
    let mut per_test = Vec::new();
    for &test in &config.tests {
        if test == ConvergenceTest::StaticBend {
            continue;
        }
        let beam = test.beam_test();
        let steps = config.steps.unwrap_or(beam.steps());
        match converged_fem_beam(
            beam,
            config.fem,
            material,
            steps,
            &config.cache_dir,
            progress,
        )? {
            Ok(fem) => per_test.push((test, steps, fem)),
            Err(why) => study.refused_references.push(why),
        }
    }
    Ok((statics, per_test))
}

/// Every material's references.
struct References<'a> {
    materials: &'a [MaterialSample],
    statics: &'a [Option<StaticReference>],
    dynamics: &'a [DynamicReferences],
    static_scene: &'a SceneSpec,
}

/// One treatment's bases: one per beam test (the penalty's one basis serves both).
struct TreatmentBases(Vec<(BeamTest, SkinningBasis)>);

impl TreatmentBases {
    fn build(
        config: &ConvergenceConfig,
        settings: &ReducedSettings,
        treatment: BoundaryTreatment,
        progress: &TerminalProgress,
    ) -> Result<Self, EvalError> {
        let mut bases: Vec<(BeamTest, SkinningBasis)> = Vec::new();
        for &test in &config.tests {
            let beam = test.beam_test();
            if treatment == BoundaryTreatment::Penalty && !bases.is_empty()
                || bases.iter().any(|(b, _)| *b == beam)
            {
                continue;
            }
            progress.status(format!(
                "basis K = {}, m = {}, {} ({})",
                settings.kernels,
                settings.modes,
                treatment.name(),
                beam.name()
            ));
            let basis = if treatment == BoundaryTreatment::Nitsche {
                free_part_basis(beam, settings, config.nitsche_stabilization_factor)?
            } else {
                build_beam_basis_for(beam, settings)?.basis
            };
            bases.push((beam, basis));
        }
        Ok(TreatmentBases(bases))
    }

    /// The basis `beam` runs on.
    fn basis_for(&self, beam: BeamTest) -> &SkinningBasis {
        &self
            .0
            .iter()
            .find(|(b, _)| *b == beam)
            .unwrap_or(&self.0[0])
            .1
    }
}

/// One volumetric term's pressure spaces per basis (none for the pointwise term): the space the
/// runs use and the largest of the inf-sup candidates, which share it.
struct PressureSpaces {
    spaces: Vec<(BeamTest, PressureSpace)>,
    full_spaces: Vec<(BeamTest, PressureSpace)>,
    /// The candidates' sizes (Neumann modes) of the inf-sup report.
    candidates: Vec<usize>,
}

impl PressureSpaces {
    fn build(
        config: &ConvergenceConfig,
        m: usize,
        settings: &ReducedSettings,
        bases: &TreatmentBases,
        treatment: BoundaryTreatment,
        volumetric: VolumetricTerm,
    ) -> Result<Self, EvalError> {
        let mut spaces: Vec<(BeamTest, PressureSpace)> = Vec::new();
        // The candidates of the inf-sup report share one space built for the largest.
        let candidates: Vec<usize> = config
            .inf_sup_fractions
            .iter()
            .map(|&f| {
                PressureSpaceParams {
                    mode_fraction: f,
                    ..config.pressure
                }
                .neumann_modes(m)
            })
            .collect();
        let chosen = config.pressure.neumann_modes(m);
        let largest = PressureSpaceParams {
            mode_fraction: config
                .inf_sup_fractions
                .iter()
                .copied()
                .fold(config.pressure.mode_fraction, f64::max),
            ..config.pressure
        };
        let mut full_spaces: Vec<(BeamTest, PressureSpace)> = Vec::new();
        if volumetric == VolumetricTerm::Projected && treatment == BoundaryTreatment::Nitsche {
            // The free part's own spaces; no inf-sup report (its candidates are the held body's).
            for (beam, _) in &bases.0 {
                spaces.push((
                    *beam,
                    free_part_pressure_space(*beam, settings, &config.pressure)?,
                ));
            }
        } else if volumetric == VolumetricTerm::Projected {
            for (beam, _) in &bases.0 {
                let full = beam_pressure_space(*beam, settings, &largest)?;
                spaces.push((*beam, full.truncated(chosen)));
                full_spaces.push((*beam, full));
            }
        }
        Ok(PressureSpaces {
            spaces,
            full_spaces,
            candidates,
        })
    }

    /// The space `beam` runs with, if any.
    fn space_for(&self, beam: BeamTest) -> Option<&PressureSpace> {
        self.spaces
            .iter()
            .find(|(b, _)| *b == beam)
            .or(self.spaces.first())
            .map(|(_, s)| s)
    }

    /// The Bend's largest space with the candidates, for the inf-sup report.
    fn inf_sup_for_bend(&self) -> Option<(&PressureSpace, &[usize])> {
        self.full_spaces
            .iter()
            .find(|(b, _)| *b == BeamTest::Bend)
            .map(|(_, s)| (s, self.candidates.as_slice()))
    }
}

/// One (K, m, treatment, volumetric term): its rows at every material.
struct RowRun<'a> {
    config: &'a ConvergenceConfig,
    settings: &'a ReducedSettings,
    bases: &'a TreatmentBases,
    spaces: &'a PressureSpaces,
    kernels: usize,
    m: usize,
    treatment: BoundaryTreatment,
    volumetric: VolumetricTerm,
    progress: &'a TerminalProgress,
}

impl RowRun<'_> {
    /// The static and dynamic rows at every material of `references`, into `study`.
    fn rows(
        &self,
        references: &References<'_>,
        study: &mut ConvergenceStudy,
    ) -> Result<(), EvalError> {
        for (v, &material) in references.materials.iter().enumerate() {
            if let Some(reference) = &references.statics[v] {
                study
                    .rows
                    .push(self.static_bend(material, references.static_scene, reference));
            }
            for (test, steps, fem) in &references.dynamics[v] {
                study.rows.push(self.dynamic(*test, *steps, fem, material)?);
            }
        }
        Ok(())
    }

    /// What a Nitsche row of `beam` at `material` runs with.
    fn nitsche(&self, beam: BeamTest, material: MaterialSample) -> NitscheBeam<'_> {
        NitscheBeam {
            basis: self.bases.basis_for(beam),
            pressure: self.spaces.space_for(beam),
            settings: self.settings,
            material,
            factor: self.config.nitsche_stabilization_factor,
            cache_dir: &self.config.cache_dir,
        }
    }

    /// A row of `test` at `nu` before it is measured (NaN scores, no failure).
    fn row(&self, test: ConvergenceTest, nu: f64) -> ConvergenceRow {
        ConvergenceRow {
            m: self.m,
            kernels: self.kernels,
            pressure_functions: self.spaces.spaces.first().map_or(0, |(_, s)| s.functions()),
            default: self.treatment.is_library_default() && self.volumetric.is_library_default(),
            ..ConvergenceRow::unmeasured(test, nu, self.treatment, self.volumetric)
        }
    }

    /// The static Bend's row at `material`.
    fn static_bend(
        &self,
        material: MaterialSample,
        scene: &SceneSpec,
        reference: &StaticReference,
    ) -> ConvergenceRow {
        let nu = material.poisson_ratio;
        let mut r = self.row(ConvergenceTest::StaticBend, nu);
        let outcome = if self.treatment == BoundaryTreatment::Nitsche {
            nitsche_static_row(
                &mut r,
                &self.nitsche(BeamTest::Bend, material),
                scene,
                reference,
            )
        } else {
            static_row(
                &mut r,
                self.bases.basis_for(BeamTest::Bend),
                self.spaces.space_for(BeamTest::Bend),
                self.spaces.inf_sup_for_bend(),
                self.settings,
                material,
                scene,
                reference,
                self.config,
            )
        };
        if let Err(e) = outcome {
            r.failure = Some(failure_chain(&e));
        }
        self.progress.status(format!(
            "static ν = {nu} K = {} m = {} {} {}: MSE {:.3e}, tip {:+.2}%, best L2 {:.3e}, best \
             energy {:.3e}, inf-sup {:?}",
            self.kernels,
            self.m,
            self.treatment.name(),
            self.volumetric.name(),
            r.mse,
            100.0 * r.tip_ratio,
            r.best_l2.unwrap_or(f64::NAN),
            r.best_energy.unwrap_or(f64::NAN),
            r.inf_sup
        ));
        r
    }

    /// A dynamic test's row at `material` against its reference `fem` over `steps`.
    fn dynamic(
        &self,
        test: ConvergenceTest,
        steps: usize,
        fem: &FemRun,
        material: MaterialSample,
    ) -> Result<ConvergenceRow, EvalError> {
        let nu = material.poisson_ratio;
        let beam = test.beam_test();
        let mut r = self.row(test, nu);
        let vertices = fem.vertices();
        let reference = fem.vertex_frames();
        let outcome = if self.treatment == BoundaryTreatment::Nitsche {
            let held = self.nitsche(beam, material);
            nitsche_dynamic_row(&mut r, &held, beam, vertices, &reference, steps)
        } else {
            run_reduced_beam_with_pressure(
                beam,
                self.bases.basis_for(beam),
                self.settings,
                material,
                self.spaces.space_for(beam),
                Some(&self.config.cache_dir),
                vertices,
                steps,
                self.progress,
            )
            .and_then(|run| {
                r.score_frames(&run.frames, &reference, vertices)?;
                r.held_drift = region_drift(beam, vertices, &run.frames);
                r.ms_per_step = run.report.ms_per_step;
                Ok(())
            })
        };
        if let Err(e) = outcome {
            r.failure = Some(failure_chain(&e));
        }
        self.progress.status(format!(
            "{} ν = {nu} K = {} m = {} {} {}: MSE {:.3e}, drift {:.1e} m",
            test.name(),
            self.kernels,
            self.m,
            self.treatment.name(),
            self.volumetric.name(),
            r.mse,
            r.held_drift
        ));
        Ok(r)
    }
}

/// The coarse FEM points: each of `config.coarse_fem` on the dynamic Bend at the beam's ν,
/// scored at the reference's vertices inside it.
fn coarse_fem_rows(
    config: &ConvergenceConfig,
    materials: &[MaterialSample],
    dynamics: &[DynamicReferences],
    study: &mut ConvergenceStudy,
    progress: &TerminalProgress,
) -> Result<(), EvalError> {
    let Some((_, steps, reference)) = dynamics
        .iter()
        .zip(materials)
        .find(|(_, m)| m.poisson_ratio == beam_material().poisson_ratio)
        .and_then(|(d, _)| d.iter().find(|(t, _, _)| *t == ConvergenceTest::Bend))
    else {
        return Ok(());
    };
    let frames = reference.vertex_frames();
    for &resolution in &config.coarse_fem {
        let coarse = run_fem_beam_with(
            BeamTest::Bend,
            resolution,
            beam_material(),
            NewtonParams::default(),
            *steps,
            &config.cache_dir,
            progress,
        )?;
        let (inside, at) = coarse.frames_inside(reference.vertices());
        let theirs: Vec<Vec<Vector3<f64>>> = frames
            .iter()
            .map(|f| inside.iter().map(|&i| f[i]).collect())
            .collect();
        let errors = trajectory_errors(&at[1..], &theirs[1..], beam_length_scale())?;
        study.coarse_fem.push(CoarseFemRow {
            resolution: resolution.label(),
            mse: errors.normalized_mse,
            ms_per_step: 1e3 * coarse.seconds_per_step,
        });
    }
    Ok(())
}

/// Fills `row` with the static Bend of `basis` under `settings`.
#[allow(clippy::too_many_arguments)]
pub(super) fn static_row(
    row: &mut ConvergenceRow,
    basis: &SkinningBasis,
    pressure: Option<&PressureSpace>,
    inf_sup: Option<(&PressureSpace, &[usize])>,
    settings: &ReducedSettings,
    material: MaterialSample,
    scene: &SceneSpec,
    reference: &StaticReference,
    config: &ConvergenceConfig,
) -> Result<(), EvalError> {
    let points = beam_simulation_points(scene, settings)?;
    let material = MaterialField::Uniform(material);
    let simulation = Simulation::new(basis, &points, &material, StableNeoHookean, scene)
        .with_params(settings.simulation_params(BEAM_TIME_STEP))
        .with_quadrature(settings.quadrature)
        .with_cache_dir(Some(&config.cache_dir))
        .with_pin_hold(settings.pins)
        .with_pressure(pressure);
    let equilibrium = static_equilibrium(&simulation, 0.0)?;
    let map = DeformationMap::new(basis, &reference.nodes).map_err(EvalError::OutputMap)?;
    let ours = map.displacements(&equilibrium.z);
    row.score_static(&ours, reference);
    row.held_drift = scene
        .constraints
        .iter()
        .flat_map(|c| {
            reference
                .nodes
                .iter()
                .zip(&ours)
                .filter(|(x, _)| c.region.contains(x))
                .map(|(_, u)| u.norm())
        })
        .fold(0.0, f64::max);
    row.ms_per_step = 1e3 * equilibrium.solve_seconds;
    let (best_l2, best_energy) = projections(basis, reference)?;
    row.best_l2 = Some(field_errors(&best_l2, &reference.displacements).0);
    row.best_energy = Some(field_errors(&best_energy, &reference.displacements).0);
    if let Some((space, candidates)) = inf_sup {
        let candidates_space = simulation.with_pressure(Some(space));
        if let Some(betas) = pressure_inf_sup(&candidates_space, candidates)? {
            row.inf_sup = candidates.iter().copied().zip(betas).collect();
        }
    }
    Ok(())
}
