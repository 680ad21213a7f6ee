//! FreeForm on the beam: build the skinning basis on a grid of the beam, simulate a beam test
//! on a (coarser) grid of integration points, record positions at given output points.

use std::path::Path;
use std::time::Instant;

use freeform::{PinHold, PressureSpace, PressureSpaceParams, Simulation};
use hyperelastic::{MaterialField, MaterialSample, StableNeoHookean};
use nalgebra::Vector3;
use optimize::{HessianReuse, NewtonParams};
use reduced_sim::{
    HessianTangent, PenaltyParams, PinModulus, QuadratureRule, SimulationParams, SkinningField,
};
use rkpm_core::{
    IntegrationPoints, Kernels, RandomSamplingParams, TriangleMesh, place_kernels, sample_box_grid,
    sample_random,
};
use serde::{Deserialize, Serialize};
use skin_eigen::{BasisError, BasisParams, BasisReport, SkinningBasis, build_basis};

use crate::EvalError;
use crate::beam::{BEAM_MAX, BEAM_MIN, BEAM_TIME_STEP, BeamTest, beam_grid_spacing, beam_material};
use crate::beam_scenario::beam_basis_grid;
use crate::reduced_run::{ReducedProblem, ReducedRun, run_reduced};
use freeform::terminal_progress::TerminalProgress;

/// The knobs of a reduced beam run.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct ReducedSettings {
    /// Skinning modes m (default 16).
    pub modes: usize,
    /// RKPM kernels K (default 1000).
    pub kernels: usize,
    /// Grid points the basis is built on (default 20 000).
    pub basis_points: usize,
    /// Grid points the simulation integrates over (default 5000).
    pub simulation_points: usize,
    /// Newton tolerance (default 1e-6, see `reduced_sim::NewtonParams`).
    pub tolerance: f64,
    /// Pin penalty factor (default the library's, [`PenaltyParams::default`]: 3e3 with
    /// [`PinModulus::Young`], κ = factor · max E / L², chosen by `freeform-paper pins` against the
    /// FEM; the first tables used 1e3 with [`PinModulus::PWave`]).
    pub pin_factor: f64,
    /// Where the simulation integrates (default the grid; random points are Table 4's
    /// ablation).
    #[serde(default)]
    pub simulation_sampling: SimulationSampling,
    /// Whether Newton carries its Hessian factorization across steps (default
    /// [`HessianReuse::Never`], the paper's setting; the bench's "Hessian reuse" series runs
    /// [`reduced_sim::SimulationParams::HESSIAN_REUSE`]).
    #[serde(default)]
    pub hessian_reuse: HessianReuse,
    /// Where the elastic energy is integrated (default [`QuadratureRule::PAPER`], every
    /// simulation point: the paper's setting; the bench's cubature series and
    /// [`ReducedSettings::library_default`] run [`QuadratureRule::Cubature`]).
    #[serde(default = "paper_quadrature")]
    pub quadrature: QuadratureRule,
    /// The modulus the pin penalty scales with (default the library's, [`PinModulus::Young`]:
    /// the same factor means the same drift at every ν).
    #[serde(default)]
    pub pin_modulus: PinModulus,
    /// How the pinned and twisted ends are held (default [`PinHold::Penalty`], the paper's
    /// treatment; [`exact_pin_hold`] gives the exact holding the tables run beside it).
    #[serde(default)]
    pub pins: PinHold,
    /// The material tangent of Newton's Hessians (default [`HessianTangent::ProjectedPsd`],
    /// the paper's setting; [`ReducedSettings::library_default`] runs the library's,
    /// [`HessianTangent::ExactWhenDefinite`]).
    #[serde(default = "paper_tangent")]
    pub tangent: HessianTangent,
}

fn paper_tangent() -> HessianTangent {
    HessianTangent::ProjectedPsd
}

/// The inset of exactly held regions, in kernel radii (the median radius of the basis's
/// kernels): [`exact_pin_hold`]'s rule.
///
/// Chosen against the converged FEM on the beam Bend (`results/RESULTS.md`, "The exact pins'
/// inset").
pub const EXACT_INSET_KERNEL_RADII: f64 = 1.5;

/// How the simulation's integration points are placed.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum SimulationSampling {
    /// A uniform grid of about `simulation_points` cells, `v_i = h³` (default).
    #[default]
    Grid,
    /// As many uniform random points in the beam as the grid has, `v_i = V / N`, seeded
    /// (design §3.1, Table 4).
    Random {
        /// The random seed.
        seed: u64,
    },
}

impl SimulationSampling {
    /// "grid" or "random".
    pub fn name(&self) -> &'static str {
        match self {
            SimulationSampling::Grid => "grid",
            SimulationSampling::Random { .. } => "random",
        }
    }

    /// The beam's integration points for about `points` points.
    ///
    /// # Errors
    /// [`EvalError::Sampling`] for a count the samplers reject.
    pub fn beam_points(&self, points: usize) -> Result<IntegrationPoints, EvalError> {
        let grid =
            sample_box_grid(BEAM_MIN, BEAM_MAX, beam_grid_spacing(points)).map_err(|source| {
                EvalError::Sampling {
                    what: "simulation points",
                    source,
                }
            })?;
        match *self {
            SimulationSampling::Grid => Ok(grid),
            SimulationSampling::Random { seed } => sample_random(
                &TriangleMesh::cuboid(BEAM_MIN, BEAM_MAX),
                &RandomSamplingParams {
                    points: grid.len(),
                    seed,
                },
            )
            .map_err(|source| EvalError::Sampling {
                what: "simulation points",
                source,
            }),
        }
    }
}

fn paper_quadrature() -> QuadratureRule {
    QuadratureRule::PAPER
}

/// A quadrature rule in words, for table preambles: "every simulation point (the paper's
/// setting)", a random subset, or an optimized cubature.
pub fn quadrature_rule_label(rule: QuadratureRule) -> String {
    match rule {
        QuadratureRule::Full => "every simulation point (the paper's setting)".to_string(),
        QuadratureRule::RandomSubset { points, seed } => {
            format!("{points} random simulation points (seed {seed}), volumes rescaled")
        }
        QuadratureRule::Cubature(p) => format!(
            "optimized cubature (An et al. 2008) to relative force error {} on the basis's \
             training poses, at most {} points",
            p.tolerance, p.max_points
        ),
        QuadratureRule::Automatic(p) => format!(
            "optimized cubature (An et al. 2008) to relative force error {}, at most {} points, \
             when it pays for itself over the run, otherwise every simulation point",
            p.tolerance, p.max_points
        ),
    }
}

impl ReducedSettings {
    /// The elastic quadrature in words, for table preambles: "every simulation point (the
    /// paper's setting)", a random subset, or an optimized cubature.
    pub fn quadrature_label(&self) -> String {
        quadrature_rule_label(self.quadrature)
    }

    /// When the Newton Hessian is rebuilt, in words, for table preambles.
    pub fn hessian_reuse_label(&self) -> String {
        match self.hessian_reuse {
            HessianReuse::Never => "fresh every Newton iteration (the paper's setting)".to_string(),
            HessianReuse::WhileContracting { contraction } => {
                format!("reused across steps while chord steps contract by {contraction}")
            }
        }
    }

    /// The pin penalty in words, for table preambles: "κ_pin = 3e3 · max E / L² (the library
    /// default, chosen against the FEM by `freeform-paper pins`)".
    pub fn pin_rule_label(&self) -> String {
        let modulus = match self.pin_modulus {
            PinModulus::Young => "max E",
            PinModulus::PWave => "max (λ + 2μ)",
        };
        let default = PenaltyParams::default();
        let origin =
            if self.pin_factor == default.pin_factor && self.pin_modulus == default.pin_modulus {
                " (the library default, chosen against the FEM by `freeform-paper pins`)"
            } else {
                ""
            };
        match self.pins {
            PinHold::Penalty => {
                format!("κ_pin = {:e} · {modulus} / L²{origin}", self.pin_factor)
            }
            PinHold::Exact { inset } => {
                format!("exact (held regions shrunk by {inset:.3} m, compact kernels)")
            }
            PinHold::Weighted {
                transition_fraction,
            } => format!(
                "exact (weighted basis, transition {transition_fraction} × the beam's thickness)"
            ),
        }
    }

    /// The defaults with the library's fast step instead of the paper's setting: the elastic
    /// energy on an optimized cubature ([`QuadratureRule::default`]), the Hessian carried
    /// across steps ([`reduced_sim::SimulationParams::HESSIAN_REUSE`]) and the exact tangent
    /// wherever the step's system factors ([`HessianTangent::ExactWhenDefinite`]).
    pub fn library_default() -> Self {
        ReducedSettings {
            quadrature: QuadratureRule::default(),
            hessian_reuse: SimulationParams::HESSIAN_REUSE,
            tangent: HessianTangent::default(),
            ..ReducedSettings::default()
        }
    }

    /// The basis builder's options for these settings: `modes` and `kernels`, the rest default.
    pub fn basis_params(&self) -> BasisParams {
        BasisParams::default()
            .with_modes(self.modes)
            .with_kernels(self.kernels)
    }

    /// The simulator's options for these settings at time step `time_step` (s): Newton
    /// tolerance and pin penalty from here, everything else default.
    pub fn simulation_params(&self, time_step: f64) -> SimulationParams {
        SimulationParams {
            time_step,
            newton: NewtonParams {
                tolerance: self.tolerance,
                hessian_reuse: self.hessian_reuse,
                ..Default::default()
            },
            penalty: PenaltyParams {
                pin_factor: self.pin_factor,
                pin_modulus: self.pin_modulus,
                ..Default::default()
            },
            tangent: self.tangent,
            ..SimulationParams::default()
        }
    }
}

impl Default for ReducedSettings {
    fn default() -> Self {
        ReducedSettings {
            modes: 16,
            kernels: 1000,
            basis_points: 20_000,
            simulation_points: 5000,
            tolerance: NewtonParams::default().tolerance,
            pin_factor: PenaltyParams::default().pin_factor,
            simulation_sampling: SimulationSampling::Grid,
            hessian_reuse: HessianReuse::Never,
            quadrature: QuadratureRule::PAPER,
            pin_modulus: PenaltyParams::default().pin_modulus,
            pins: PinHold::Penalty,
            tangent: paper_tangent(),
        }
    }
}

/// A beam basis and what building it cost.
pub struct BeamBasis {
    /// The basis.
    pub basis: SkinningBasis,
    /// Its build report (per-phase seconds).
    pub report: BasisReport,
    /// Wall time including grid sampling (s).
    pub seconds: f64,
}

/// Builds the beam's skinning basis for `settings` (modes, kernels, basis points).
///
/// # Errors
/// [`EvalError::Basis`] from the builder (e.g. m ≥ K).
pub fn build_beam_basis(settings: &ReducedSettings) -> Result<BeamBasis, EvalError> {
    let start = Instant::now();
    let (grid, lame) = beam_basis_grid(settings.basis_points)?;
    let (basis, report, _) =
        build_basis(&grid, &lame, &settings.basis_params()).map_err(EvalError::Basis)?;
    Ok(BeamBasis {
        basis,
        report,
        seconds: start.elapsed().as_secs_f64(),
    })
}

/// Exact holding for `settings`' beam basis: each region shrunk by `inset_radii` (default
/// [`EXACT_INSET_KERNEL_RADII`]) times the median radius of the kernels placed on the basis
/// grid.
///
/// # Errors
/// [`EvalError::Sampling`] / [`EvalError::Basis`] when the grid or the kernels cannot be made.
pub fn exact_pin_hold(settings: &ReducedSettings, inset_radii: f64) -> Result<PinHold, EvalError> {
    let (grid, _) = beam_basis_grid(settings.basis_points)?;
    let kernels = place_kernels(grid.positions(), &settings.basis_params().kernels)
        .map_err(|e| EvalError::Basis(BasisError::Kernels(e)))?;
    Ok(PinHold::Exact {
        inset: inset_radii * median_kernel_radius(&kernels),
    })
}

/// The beam's basis for `test` under `settings`: [`build_beam_basis`] for the penalty; for
/// exact holding, built for the test's held regions at the basis grid's and the simulation's
/// points ([`PinHold::build_basis`]; no output points are passed: the box's kernels as placed
/// reach its FEM vertices, and a vertex they did not reach would fail the run by name).
///
/// # Errors
/// [`EvalError::Basis`] from the builder, [`EvalError::Scene`] for a held region that holds no
/// point.
pub fn build_beam_basis_for(
    test: BeamTest,
    settings: &ReducedSettings,
) -> Result<BeamBasis, EvalError> {
    if settings.pins == PinHold::Penalty {
        return build_beam_basis(settings);
    }
    let start = Instant::now();
    let (grid, lame) = beam_basis_grid(settings.basis_points)?;
    let points = settings
        .simulation_sampling
        .beam_points(settings.simulation_points)?;
    let (basis, report) = settings.pins.build_basis(
        &test.scene(),
        &grid,
        &lame,
        points.positions(),
        &[],
        settings.basis_params(),
    )?;
    Ok(BeamBasis {
        basis,
        report,
        seconds: start.elapsed().as_secs_f64(),
    })
}

/// The median radius (m) of `kernels`: the length exact holding's inset is measured in.
pub(crate) fn median_kernel_radius(kernels: &Kernels) -> f64 {
    let mut radii = kernels.radii().to_vec();
    radii.sort_by(f64::total_cmp);
    radii[radii.len() / 2]
}

/// Simulates `steps` steps of `test` with `basis` (ours, or any other skinning field) on about
/// `settings.simulation_points` points placed by `settings.simulation_sampling`, recording
/// positions at `output_points` (rest positions, m) every step.
///
/// # Errors
/// [`EvalError`] for a failed setup or step.
pub fn run_reduced_beam<B: SkinningField + ?Sized>(
    test: BeamTest,
    basis: &B,
    settings: &ReducedSettings,
    output_points: &[Vector3<f64>],
    steps: usize,
    progress: &TerminalProgress,
) -> Result<ReducedRun, EvalError> {
    run_reduced_beam_with(
        test,
        basis,
        settings,
        beam_material(),
        None,
        output_points,
        steps,
        progress,
    )
}

/// [`run_reduced_beam`] with a material (the beam's is [`beam_material`]; the pin sweep varies
/// its Poisson ratio) and a cache folder for the cubature (`None`: optimized every run).
///
/// # Errors
/// As [`run_reduced_beam`].
#[allow(clippy::too_many_arguments)]
pub fn run_reduced_beam_with<B: SkinningField + ?Sized>(
    test: BeamTest,
    basis: &B,
    settings: &ReducedSettings,
    material: MaterialSample,
    cache_dir: Option<&Path>,
    output_points: &[Vector3<f64>],
    steps: usize,
    progress: &TerminalProgress,
) -> Result<ReducedRun, EvalError> {
    run_reduced_beam_with_pressure(
        test,
        basis,
        settings,
        material,
        None,
        cache_dir,
        output_points,
        steps,
        progress,
    )
}

/// [`run_reduced_beam_with`] with the locking-free volumetric term over `pressure`
/// ([`freeform::Simulation::pressure`]; `None` is [`run_reduced_beam_with`]).
///
/// # Errors
/// As [`run_reduced_beam`].
#[allow(clippy::too_many_arguments)]
pub fn run_reduced_beam_with_pressure<B: SkinningField + ?Sized>(
    test: BeamTest,
    basis: &B,
    settings: &ReducedSettings,
    material: MaterialSample,
    pressure: Option<&PressureSpace>,
    cache_dir: Option<&Path>,
    output_points: &[Vector3<f64>],
    steps: usize,
    progress: &TerminalProgress,
) -> Result<ReducedRun, EvalError> {
    let points = settings
        .simulation_sampling
        .beam_points(settings.simulation_points)?;
    run_reduced(
        &ReducedProblem {
            simulation: Simulation::new(
                basis,
                &points,
                &MaterialField::Uniform(material),
                StableNeoHookean,
                &test.scene(),
            )
            .with_params(settings.simulation_params(BEAM_TIME_STEP))
            .with_quadrature(settings.quadrature)
            .with_cache_dir(cache_dir)
            .with_pin_hold(settings.pins)
            .with_pressure(pressure),
            output_points,
            steps,
        },
        &format!("FreeForm {} m={}", test.name(), settings.modes),
        progress,
    )
}

/// The pressure space of `test`'s beam under `settings` (its hold, kernels and modes) on the
/// basis grid ([`PressureSpace::build`]).
///
/// # Errors
/// [`EvalError::Sampling`] / [`EvalError::Basis`] when the grid or the Neumann basis cannot be
/// made.
pub fn beam_pressure_space(
    test: BeamTest,
    settings: &ReducedSettings,
    params: &PressureSpaceParams,
) -> Result<PressureSpace, EvalError> {
    let (grid, lame) = beam_basis_grid(settings.basis_points)?;
    PressureSpace::build(
        &test.scene(),
        settings.pins,
        &grid,
        &lame,
        settings.basis_params(),
        settings.modes,
        params,
    )
    .map_err(EvalError::Basis)
}
