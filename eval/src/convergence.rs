//! The convergence study: does the beam error fall as m grows? For each boundary treatment,
//! Poisson ratio ν, kernel count K and mode count m, a linear static Bend against a static FEM
//! (with the best approximations the subspace allows beside it) and the dynamic Bend and Twist
//! of Table 1 against the cached FEM references.
//!
//! Static diagnostics, at the FEM nodes N with the LBS displacement `u_h = P z` of the basis:
//!
//! ```text
//! best_l2:      z = argmin |P z − u*|²                         (L2 projection onto V_m)
//! best_energy:  z = argmin (P z − u*)ᵀ K (P z − u*) + τ |P z − u*|²,  τ = 1e-8 tr(PᵀKP)/tr(PᵀP)
//! ```
//!
//! with K the FEM's stiffness at rest (no boundary condition: the L2 tie τ fixes the rigid
//! motions). For a conforming, exactly integrated model with exact held regions the Galerkin
//! solution is the energy projection restricted to the held subspace (Ritz), so the gap between
//! the two is what quadrature, penalty and locking cost.

use std::fmt::Write as _;
use std::path::PathBuf;

use fem_ref::{ElementOrder, TetMesh};
use freeform::fem_reference::FemProblem;
use freeform::metrics::trajectory_errors;
use freeform::scene::SceneSpec;
use freeform::terminal_progress::TerminalProgress;
use freeform::{
    PinHold, PressureSpace, PressureSpaceParams, Simulation, failure_chain, pressure_inf_sup,
    static_equilibrium,
};
use hyperelastic::{HessianTangent, MaterialField, MaterialSample, StableNeoHookean, Tangent};
use nalgebra::{DMatrix, DVector, Vector3};
use optimize::NewtonParams;
use reduced_sim::DeformationMap;
use serde::{Deserialize, Serialize};
use skin_eigen::SkinningBasis;

use crate::EvalError;
use crate::beam::reduced::{
    EXACT_INSET_KERNEL_RADII, ReducedSettings, beam_pressure_space, build_beam_basis_for,
    exact_pin_hold, run_reduced_beam_with_pressure,
};
use crate::beam::study::{beam_length_scale, region_drift};
use crate::beam::{BEAM_MAX, BEAM_MIN, BEAM_TIME_STEP, BeamTest, beam_material};
use crate::fem_reference::{FemResolution, run_fem_beam_with};

/// A test of the study.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ConvergenceTest {
    /// The Bend's clamp and gravity scaled by [`ConvergenceConfig::static_gravity_scale`],
    /// solved for static equilibrium: a linear problem whose Galerkin solution obeys the Ritz
    /// bounds.
    StaticBend,
    /// Table 1's dynamic Bend.
    Bend,
    /// Table 1's Twist.
    Twist,
}

impl ConvergenceTest {
    /// "static_bend", "bend" or "twist".
    pub fn name(self) -> &'static str {
        match self {
            ConvergenceTest::StaticBend => "static_bend",
            ConvergenceTest::Bend => "bend",
            ConvergenceTest::Twist => "twist",
        }
    }

    /// The beam test whose scene it runs.
    pub fn beam_test(self) -> BeamTest {
        match self {
            ConvergenceTest::StaticBend | ConvergenceTest::Bend => BeamTest::Bend,
            ConvergenceTest::Twist => BeamTest::Twist,
        }
    }
}

/// How the pinned and twisted ends are held.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum BoundaryTreatment {
    /// The penalty with the settings' factor ([`PinHold::Penalty`]; the paper's treatment).
    Penalty,
    /// Exact on the regions shrunk by [`EXACT_INSET_KERNEL_RADII`], penalty on the band
    /// ([`PinHold::Exact`]).
    ExactInset,
    /// The weighted basis ([`PinHold::WEIGHTED`]): exact on the whole regions, no parameter.
    Weighted,
}

impl BoundaryTreatment {
    /// "penalty", "exact_inset" or "weighted".
    pub fn name(self) -> &'static str {
        match self {
            BoundaryTreatment::Penalty => "penalty",
            BoundaryTreatment::ExactInset => "exact_inset",
            BoundaryTreatment::Weighted => "weighted",
        }
    }

    /// `base` with this treatment's hold.
    ///
    /// # Errors
    /// [`EvalError`] when the exact inset's kernels cannot be placed.
    pub fn settings(self, base: &ReducedSettings) -> Result<ReducedSettings, EvalError> {
        let pins = match self {
            BoundaryTreatment::Penalty => PinHold::Penalty,
            BoundaryTreatment::ExactInset => exact_pin_hold(base, EXACT_INSET_KERNEL_RADII)?,
            BoundaryTreatment::Weighted => PinHold::WEIGHTED,
        };
        Ok(ReducedSettings { pins, ..*base })
    }

    /// Whether this is the library's default hold ([`PinHold::default`]).
    pub fn is_library_default(self) -> bool {
        matches!(
            (self, PinHold::default()),
            (BoundaryTreatment::Penalty, PinHold::Penalty)
                | (BoundaryTreatment::Weighted, PinHold::Weighted { .. })
                | (BoundaryTreatment::ExactInset, PinHold::Exact { .. })
        )
    }
}

/// How the volumetric term of the material is integrated.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum VolumetricTerm {
    /// At every quadrature point, as the material defines it (the paper's setting).
    Pointwise,
    /// Projected onto a pressure space ([`freeform::PressureSpace`],
    /// [`ConvergenceConfig::pressure`]): the locking-free term.
    Projected,
}

impl VolumetricTerm {
    /// "pointwise" or "projected".
    pub fn name(self) -> &'static str {
        match self {
            VolumetricTerm::Pointwise => "pointwise",
            VolumetricTerm::Projected => "projected",
        }
    }
}

/// What the study runs.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ConvergenceConfig {
    /// Tests.
    pub tests: Vec<ConvergenceTest>,
    /// Poisson ratios of the beam (E and ρ stay the beam's).
    pub poisson_ratios: Vec<f64>,
    /// Modes m.
    pub modes: Vec<usize>,
    /// Kernel counts K.
    pub kernels: Vec<usize>,
    /// Boundary treatments.
    pub treatments: Vec<BoundaryTreatment>,
    /// Volumetric terms.
    pub volumetric: Vec<VolumetricTerm>,
    /// The pressure space of [`VolumetricTerm::Projected`].
    pub pressure: PressureSpaceParams,
    /// Neumann-mode fractions whose inf-sup constants the static projected rows report.
    pub inf_sup_fractions: Vec<f64>,
    /// Everything else of the reduced runs (`modes`, `kernels` and `pins` are set per run).
    pub settings: ReducedSettings,
    /// Gravity of the static Bend as a fraction of the Bend's 9.8 m/s² (small: linear).
    pub static_gravity_scale: f64,
    /// Steps of the dynamic tests; `None` for Table 1's (300 Bend, 30 Twist).
    pub steps: Option<usize>,
    /// The FEM reference (static and dynamic).
    pub fem: FemResolution,
    /// Coarse FEM runs of the dynamic Bend at ν = 0.45 placed beside FreeForm in the plot.
    pub coarse_fem: Vec<FemResolution>,
    /// Cache folder (FEM trajectories, cubatures).
    pub cache_dir: PathBuf,
}

impl ConvergenceConfig {
    /// The whole study: the three tests at ν = 0.3 / 0.45 / 0.49, m = 8 … 64, K = 1000 and
    /// 2000, every treatment, every simulation point with Hessian reuse, the P2 res 6 reference
    /// and P1 / P2 res 2–4 beside it.
    pub fn full(cache_dir: PathBuf) -> Self {
        let coarse = |order, cells_per_metre| FemResolution {
            order,
            cells_per_metre,
        };
        ConvergenceConfig {
            tests: vec![
                ConvergenceTest::StaticBend,
                ConvergenceTest::Bend,
                ConvergenceTest::Twist,
            ],
            poisson_ratios: vec![0.3, 0.45, 0.49],
            modes: vec![8, 12, 16, 24, 32, 48, 64],
            kernels: vec![1000, 2000],
            treatments: vec![
                BoundaryTreatment::Penalty,
                BoundaryTreatment::ExactInset,
                BoundaryTreatment::Weighted,
            ],
            volumetric: vec![VolumetricTerm::Pointwise, VolumetricTerm::Projected],
            pressure: PressureSpaceParams::default(),
            inf_sup_fractions: vec![0.5, 1.0, 2.0, 3.0, 5.0],
            settings: ReducedSettings {
                hessian_reuse: reduced_sim::SimulationParams::HESSIAN_REUSE,
                ..ReducedSettings::default()
            },
            static_gravity_scale: 1e-3,
            steps: None,
            fem: FemResolution::GROUND_TRUTH,
            coarse_fem: vec![
                coarse(ElementOrder::Linear, 2),
                coarse(ElementOrder::Linear, 3),
                coarse(ElementOrder::Linear, 4),
                coarse(ElementOrder::Quadratic, 2),
                coarse(ElementOrder::Quadratic, 3),
                coarse(ElementOrder::Quadratic, 4),
            ],
            cache_dir,
        }
    }

    /// A minutes-long version: the static Bend at ν = 0.45, m = 8 / 16 / 32, K = 1000, every
    /// treatment and volumetric term, against P2 res 4.
    pub fn quick(cache_dir: PathBuf) -> Self {
        ConvergenceConfig {
            tests: vec![ConvergenceTest::StaticBend],
            poisson_ratios: vec![0.45],
            modes: vec![8, 16, 32],
            kernels: vec![1000],
            steps: Some(100),
            fem: FemResolution {
                order: ElementOrder::Quadratic,
                cells_per_metre: 4,
            },
            coarse_fem: Vec::new(),
            ..ConvergenceConfig::full(cache_dir)
        }
    }
}

/// One (test, ν, K, m, treatment) result.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ConvergenceRow {
    /// The test.
    pub test: ConvergenceTest,
    /// Poisson ratio.
    pub nu: f64,
    /// Modes m.
    pub m: usize,
    /// Kernels K.
    pub kernels: usize,
    /// Boundary treatment.
    pub treatment: BoundaryTreatment,
    /// Volumetric term.
    pub volumetric: VolumetricTerm,
    /// Pressure functions P of the projected term (0 for the pointwise one).
    pub pressure_functions: usize,
    /// Whether this is the library's default treatment.
    pub default: bool,
    /// Normalized MSE against the FEM, `mean |x − x*|² / L²` over the output points (and frames).
    pub mse: f64,
    /// Relative L2 error of the displacements, `sqrt(Σ|u − u*|² / Σ|u*|²)` over points (and
    /// frames).
    pub relative_error: f64,
    /// Tip error: `max_t |x_tip − x*_tip| / max_t |u*_tip|` at the node nearest the tip corner
    /// (5, 1, 1).
    pub tip_error: f64,
    /// Static Bend: `u_tip,y / u*_tip,y − 1` (+ too soft, − too stiff); NaN for dynamic tests.
    pub tip_ratio: f64,
    /// Largest distance of an FEM node in a constrained region from its target (m).
    pub held_drift: f64,
    /// Milliseconds per step (the static solve's for the static test).
    pub ms_per_step: f64,
    /// Normalized MSE of the L2 projection of the FEM field onto the subspace (static only).
    pub best_l2: Option<f64>,
    /// Normalized MSE of the energy projection of the FEM field onto the subspace (static only).
    pub best_energy: Option<f64>,
    /// Static projected rows: the discrete inf-sup constant β of the pressure space with each
    /// candidate count of Neumann modes ([`ConvergenceConfig::inf_sup_fractions`]).
    pub inf_sup: Vec<(usize, f64)>,
    /// Why the run stopped, when it did (then the errors are NaN).
    pub failure: Option<String>,
}

/// A coarse FEM's dynamic Bend at ν = 0.45.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CoarseFemRow {
    /// "P2 res 4".
    pub resolution: String,
    /// Normalized MSE against the reference.
    pub mse: f64,
    /// Seconds per step as run (or as cached).
    pub ms_per_step: f64,
}

/// The study's results.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ConvergenceStudy {
    /// One row per run.
    pub rows: Vec<ConvergenceRow>,
    /// The coarse FEM points.
    pub coarse_fem: Vec<CoarseFemRow>,
    /// References that failed their own check, and so scored nothing.
    pub refused_references: Vec<String>,
}

/// A static FEM solution with what the projections need.
struct StaticReference {
    nodes: Vec<Vector3<f64>>,
    displacements: Vec<Vector3<f64>>,
    /// Per element: its nodes and its rest stiffness (row-major, node-major DOFs).
    elements: Vec<(Vec<usize>, Vec<f64>)>,
    tip: usize,
}

/// Index of the point nearest the beam's tip corner (5, 1, 1): off the Twist's axis, so that
/// the Twist moves it too.
fn tip_index(points: &[Vector3<f64>]) -> usize {
    let tip = BEAM_MAX;
    (0..points.len())
        .min_by(|&a, &b| {
            (points[a] - tip)
                .norm()
                .total_cmp(&(points[b] - tip).norm())
        })
        .unwrap_or(0)
}

/// The static Bend's scene: the Bend with gravity scaled by `scale`.
fn static_scene(scale: f64) -> SceneSpec {
    let mut scene = BeamTest::Bend.scene();
    scene.gravity = scene.gravity.map(|g| g * scale);
    scene
}

/// Solves the static FEM reference at `resolution` for `material`.
fn static_reference(
    scene: &SceneSpec,
    resolution: FemResolution,
    material: MaterialSample,
) -> Result<StaticReference, EvalError> {
    let r = resolution.cells_per_metre;
    let tets = TetMesh::cuboid(BEAM_MIN, BEAM_MAX, [5 * r, r, r]).map_err(EvalError::FemBox)?;
    let problem = FemProblem {
        tets,
        order: resolution.order,
        material,
        scene,
        time_step: BEAM_TIME_STEP,
        newton: NewtonParams::default(),
        tangent: HessianTangent::ProjectedPsd,
        ordering: Default::default(),
        failed_step_halvings: 0,
        steps: 0,
    };
    let (mut sim, _) = problem.simulator()?;
    let report = sim
        .solve_static(0.0)
        .map_err(|source| EvalError::Fem(fem_ref::FemRunError::Step { step: 0, source }))?;
    if !report.converged() {
        return Err(EvalError::StaticReferenceNotConverged {
            iterations: report.iterations,
        });
    }
    let model = sim.model();
    let nodes = model.mesh().nodes().to_vec();
    let displacements: Vec<Vector3<f64>> = sim
        .positions()
        .iter()
        .zip(&nodes)
        .map(|(x, rest)| x - rest)
        .collect();
    let rest: Vec<f64> = nodes.iter().flat_map(|x| x.iter().copied()).collect();
    let elements = (0..model.mesh().element_count())
        .map(|e| {
            (
                model.mesh().element(e).to_vec(),
                model.element_hessian(e, &rest, Tangent::Exact, 0.0),
            )
        })
        .collect();
    let tip = tip_index(&nodes);
    Ok(StaticReference {
        nodes,
        displacements,
        elements,
        tip,
    })
}

/// Normalized MSE (over L²) and relative L2 error of `ours` against `reference`.
fn field_errors(ours: &[Vector3<f64>], reference: &[Vector3<f64>]) -> (f64, f64) {
    let (mut error, mut size) = (0.0, 0.0);
    for (a, b) in ours.iter().zip(reference) {
        error += (a - b).norm_squared();
        size += b.norm_squared();
    }
    let length = beam_length_scale();
    (
        error / ours.len().max(1) as f64 / (length * length),
        (error / size).sqrt(),
    )
}

/// The L2 and the energy projection of a field, as displacement fields at the same points.
type Projections = (Vec<Vector3<f64>>, Vec<Vector3<f64>>);

/// The L2 and energy projections of the reference onto the LBS span of `basis` at the nodes
/// (module docs), as displacement fields.
fn projections(
    basis: &SkinningBasis,
    reference: &StaticReference,
) -> Result<Projections, EvalError> {
    let map = DeformationMap::new(basis, &reference.nodes).map_err(EvalError::OutputMap)?;
    let positions = map.position_matrix();
    let (width, n) = (positions.nrows(), positions.ncols());
    // B: N × 4h, row i = b_iᵀ.
    let b = DMatrix::from_fn(n, width, |i, k| positions[(k, i)]);
    let gram = b.transpose() * &b;
    let cholesky = gram.clone().cholesky().ok_or_else(|| {
        EvalError::Projection("the basis's LBS Gram matrix at the FEM nodes is singular")
    })?;
    let u =
        |axis: usize| DVector::from_iterator(n, reference.displacements.iter().map(|d| d[axis]));
    let coefficients: Vec<DVector<f64>> = (0..3)
        .map(|axis| cholesky.solve(&(b.transpose() * u(axis))))
        .collect();
    let field = |c: &[DVector<f64>]| -> Vec<Vector3<f64>> {
        let per_axis: Vec<DVector<f64>> = c.iter().map(|c| &b * c).collect();
        (0..n)
            .map(|i| Vector3::new(per_axis[0][i], per_axis[1][i], per_axis[2][i]))
            .collect()
    };
    let best_l2 = field(&coefficients);

    // KP: 3N × 3w, column block r for axis r.
    let d = 3 * width;
    let mut kp = DMatrix::<f64>::zeros(3 * n, d);
    for (nodes, hessian) in &reference.elements {
        let size = 3 * nodes.len();
        for (a, &node_a) in nodes.iter().enumerate() {
            for i in 0..3 {
                let row = 3 * node_a + i;
                for (bi, &node_b) in nodes.iter().enumerate() {
                    for r in 0..3 {
                        let h = hessian[(3 * a + i) * size + 3 * bi + r];
                        if h == 0.0 {
                            continue;
                        }
                        for k in 0..width {
                            kp[(row, r * width + k)] += h * b[(node_b, k)];
                        }
                    }
                }
            }
        }
    }
    let mut system = DMatrix::<f64>::zeros(d, d);
    let mut rhs = DVector::<f64>::zeros(d);
    let flat_u = DVector::from_iterator(
        3 * n,
        reference
            .displacements
            .iter()
            .flat_map(|v| v.iter().copied()),
    );
    let kp_u = kp.transpose() * &flat_u;
    for r in 0..3 {
        let rows = DMatrix::from_fn(n, d, |i, c| kp[(3 * i + r, c)]);
        let block = b.transpose() * rows;
        system.rows_mut(r * width, width).copy_from(&block);
    }
    rhs += &kp_u;
    let trace_k = system.trace();
    let tie = 1e-8 * trace_k / (3.0 * gram.trace());
    for r in 0..3 {
        let mut diagonal = system.view_mut((r * width, r * width), (width, width));
        diagonal += &gram * tie;
        let mut part = rhs.rows_mut(r * width, width);
        part += b.transpose() * u(r) * tie;
    }
    let system = (&system + system.transpose()) * 0.5;
    let solution = system
        .cholesky()
        .ok_or_else(|| EvalError::Projection("the energy projection's system is not definite"))?
        .solve(&rhs);
    let energy: Vec<DVector<f64>> = (0..3)
        .map(|r| solution.rows(r * width, width).into_owned())
        .collect();
    Ok((best_l2, field(&energy)))
}

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
        let nu = material.poisson_ratio;
        if config.tests.contains(&ConvergenceTest::StaticBend) {
            progress.status(format!("static FEM ν = {nu} ({})", config.fem.label()));
            statics.push(Some(static_reference(&static_scene, config.fem, material)?));
        } else {
            statics.push(None);
        }
        let mut per_test = Vec::new();
        for &test in &config.tests {
            if test == ConvergenceTest::StaticBend {
                continue;
            }
            let beam = test.beam_test();
            let steps = config.steps.unwrap_or(beam.steps());
            let fem = run_fem_beam_with(
                beam,
                config.fem,
                material,
                NewtonParams::default(),
                steps,
                &config.cache_dir,
                progress,
            )?;
            if let Err(why) = fem.check_converged(NewtonParams::default().max_iterations) {
                study
                    .refused_references
                    .push(format!("ν = {nu}, {}: {why}", beam.name()));
                continue;
            }
            per_test.push((test, steps, fem));
        }
        dynamics.push(per_test);
    }
    for &kernels in &config.kernels {
        for &m in &config.modes {
            for &treatment in &config.treatments {
                let base = ReducedSettings {
                    modes: m,
                    kernels,
                    ..config.settings
                };
                let settings = treatment.settings(&base)?;
                let mut bases: Vec<(BeamTest, SkinningBasis)> = Vec::new();
                for &test in &config.tests {
                    let beam = test.beam_test();
                    if treatment == BoundaryTreatment::Penalty && !bases.is_empty()
                        || bases.iter().any(|(b, _)| *b == beam)
                    {
                        continue;
                    }
                    progress.status(format!(
                        "basis K = {kernels}, m = {m}, {} ({})",
                        treatment.name(),
                        beam.name()
                    ));
                    bases.push((beam, build_beam_basis_for(beam, &settings)?.basis));
                }
                let basis_for = |beam: BeamTest| {
                    &bases
                        .iter()
                        .find(|(b, _)| *b == beam)
                        .unwrap_or(&bases[0])
                        .1
                };
                for &volumetric in &config.volumetric {
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
                    if volumetric == VolumetricTerm::Projected {
                        for (beam, _) in &bases {
                            let full = beam_pressure_space(*beam, &settings, &largest)?;
                            spaces.push((*beam, full.truncated(chosen)));
                            full_spaces.push((*beam, full));
                        }
                    }
                    let space_for = |beam: BeamTest| {
                        spaces
                            .iter()
                            .find(|(b, _)| *b == beam)
                            .or(spaces.first())
                            .map(|(_, s)| s)
                    };
                    let pressure_functions = spaces.first().map_or(0, |(_, s)| s.functions());
                    for (v, &material) in materials.iter().enumerate() {
                        let nu = material.poisson_ratio;
                        let row = |test| ConvergenceRow {
                            test,
                            nu,
                            m,
                            kernels,
                            treatment,
                            volumetric,
                            pressure_functions,
                            default: treatment.is_library_default(),
                            mse: f64::NAN,
                            relative_error: f64::NAN,
                            tip_error: f64::NAN,
                            tip_ratio: f64::NAN,
                            held_drift: f64::NAN,
                            ms_per_step: f64::NAN,
                            best_l2: None,
                            best_energy: None,
                            inf_sup: Vec::new(),
                            failure: None,
                        };
                        if let Some(reference) = &statics[v] {
                            let mut r = row(ConvergenceTest::StaticBend);
                            let basis = basis_for(BeamTest::Bend);
                            let full_space = full_spaces
                                .iter()
                                .find(|(b, _)| *b == BeamTest::Bend)
                                .map(|(_, s)| (s, candidates.as_slice()));
                            match static_row(
                                &mut r,
                                basis,
                                space_for(BeamTest::Bend),
                                full_space,
                                &settings,
                                material,
                                &static_scene,
                                reference,
                                config,
                            ) {
                                Ok(()) => {}
                                Err(e) => r.failure = Some(failure_chain(&e)),
                            }
                            progress.status(format!(
                            "static ν = {nu} K = {kernels} m = {m} {} {}: MSE {:.3e}, tip {:+.2}%, \
                             best L2 {:.3e}, best energy {:.3e}, inf-sup {:?}",
                            treatment.name(),
                            volumetric.name(),
                            r.mse,
                            100.0 * r.tip_ratio,
                            r.best_l2.unwrap_or(f64::NAN),
                            r.best_energy.unwrap_or(f64::NAN),
                            r.inf_sup
                        ));
                            study.rows.push(r);
                        }
                        for (test, steps, fem) in &dynamics[v] {
                            let beam = test.beam_test();
                            let mut r = row(*test);
                            let vertices = fem.vertices();
                            let reference = fem.vertex_frames();
                            match run_reduced_beam_with_pressure(
                                beam,
                                basis_for(beam),
                                &settings,
                                material,
                                space_for(beam),
                                Some(&config.cache_dir),
                                vertices,
                                *steps,
                                progress,
                            ) {
                                Ok(run) => {
                                    let errors = trajectory_errors(
                                        &run.frames[1..],
                                        &reference[1..],
                                        beam_length_scale(),
                                    )?;
                                    r.mse = errors.normalized_mse;
                                    let (mut error, mut size) = (0.0, 0.0);
                                    let tip = tip_index(vertices);
                                    let (mut tip_error, mut tip_size): (f64, f64) = (0.0, 0.0);
                                    for (ours, theirs) in run.frames.iter().zip(&reference) {
                                        for ((a, b), rest) in ours.iter().zip(theirs).zip(vertices)
                                        {
                                            error += (a - b).norm_squared();
                                            size += (b - rest).norm_squared();
                                        }
                                        tip_error = tip_error.max((ours[tip] - theirs[tip]).norm());
                                        tip_size =
                                            tip_size.max((theirs[tip] - vertices[tip]).norm());
                                    }
                                    r.relative_error = (error / size).sqrt();
                                    r.tip_error = tip_error / tip_size;
                                    r.held_drift = region_drift(beam, vertices, &run.frames);
                                    r.ms_per_step = run.report.ms_per_step;
                                }
                                Err(e) => r.failure = Some(failure_chain(&e)),
                            }
                            progress.status(format!(
                            "{} ν = {nu} K = {kernels} m = {m} {} {}: MSE {:.3e}, drift {:.1e} m",
                            test.name(),
                            treatment.name(),
                            volumetric.name(),
                            r.mse,
                            r.held_drift
                        ));
                            study.rows.push(r);
                        }
                    }
                }
            }
        }
    }
    if let Some(reference_bend) = dynamics
        .iter()
        .zip(&materials)
        .find(|(_, m)| m.poisson_ratio == beam_material().poisson_ratio)
        .and_then(|(d, _)| d.iter().find(|(t, _, _)| *t == ConvergenceTest::Bend))
    {
        let (_, steps, reference) = reference_bend;
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
    }
    Ok(study)
}

/// Fills `row` with the static Bend of `basis` under `settings`.
#[allow(clippy::too_many_arguments)]
fn static_row(
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
    let points = settings
        .simulation_sampling
        .beam_points(settings.simulation_points)?;
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
    let (mse, relative) = field_errors(&ours, &reference.displacements);
    row.mse = mse;
    row.relative_error = relative;
    let tip = reference.tip;
    let exact_tip = reference.displacements[tip];
    row.tip_error = (ours[tip] - exact_tip).norm() / exact_tip.norm();
    row.tip_ratio = ours[tip].y / exact_tip.y - 1.0;
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

/// The study as Markdown: per (test, ν, K), MSE against m for every treatment (and the static
/// projections), then the coarse FEM points.
pub fn convergence_table(config: &ConvergenceConfig, study: &ConvergenceStudy) -> String {
    let mut md = format!(
        "## Convergence in m: beam against the FEM ({})\n\n\
         E = 5 MPa, ρ = 1000 kg/m³, {} simulation points, {}; static Bend at {} g. Cells: \
         normalized MSE (static: tip error in %, + too soft; and the MSE of the energy \
         projection of the FEM field onto the same subspace).\n\n",
        config.fem.label(),
        config.settings.simulation_points,
        config.settings.quadrature_label(),
        config.static_gravity_scale
    );
    for why in &study.refused_references {
        let _ = writeln!(md, "Not scored: {why}.\n");
    }
    for &test in &config.tests {
        for &nu in &config.poisson_ratios {
            for &kernels in &config.kernels {
                let _ = write!(md, "### {} ν = {nu} K = {kernels}\n\n| m |", test.name());
                let columns: Vec<(BoundaryTreatment, VolumetricTerm)> = config
                    .treatments
                    .iter()
                    .flat_map(|&t| config.volumetric.iter().map(move |&v| (t, v)))
                    .collect();
                for (t, v) in &columns {
                    let _ = write!(md, " {} {} |", t.name(), v.name());
                }
                md += "\n|---|";
                for _ in &columns {
                    md += "---|";
                }
                md += "\n";
                for &m in &config.modes {
                    let _ = write!(md, "| {m} |");
                    for &(t, v) in &columns {
                        let row = study.rows.iter().find(|r| {
                            r.test == test
                                && r.nu == nu
                                && r.kernels == kernels
                                && r.m == m
                                && r.treatment == t
                                && r.volumetric == v
                        });
                        match row {
                            Some(r) if r.failure.is_none() => {
                                if test == ConvergenceTest::StaticBend {
                                    let _ = write!(
                                        md,
                                        " {:.3e} ({:+.2}%; best E {:.2e}) |",
                                        r.mse,
                                        100.0 * r.tip_ratio,
                                        r.best_energy.unwrap_or(f64::NAN)
                                    );
                                } else {
                                    let _ = write!(md, " {:.3e} |", r.mse);
                                }
                            }
                            Some(_) => md += " failed |",
                            None => md += " — |",
                        }
                    }
                    md += "\n";
                }
                md += "\n";
            }
        }
    }
    if !study.coarse_fem.is_empty() {
        md += "### Coarse FEM, dynamic Bend ν = 0.45\n\n| FEM | MSE | ms/step |\n|---|---|---|\n";
        for c in &study.coarse_fem {
            let _ = writeln!(
                md,
                "| {} | {:.3e} | {:.1} |",
                c.resolution, c.mse, c.ms_per_step
            );
        }
    }
    md
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::beam::reduced::build_beam_basis;

    fn small_basis() -> SkinningBasis {
        let settings = ReducedSettings {
            modes: 4,
            kernels: 120,
            basis_points: 3000,
            ..ReducedSettings::default()
        };
        build_beam_basis(&settings).unwrap().basis
    }

    fn coarse_reference() -> StaticReference {
        let resolution = FemResolution {
            order: ElementOrder::Linear,
            cells_per_metre: 2,
        };
        static_reference(&static_scene(1e-3), resolution, beam_material()).unwrap()
    }

    #[test]
    fn both_projections_reproduce_a_field_the_subspace_contains() {
        let basis = small_basis();
        let mut reference = coarse_reference();
        let map = DeformationMap::new(&basis, &reference.nodes).unwrap();
        let z: Vec<f64> = (0..map.layout().len())
            .map(|i| 1e-3 * ((i * 7919) % 13) as f64 / 13.0 - 5e-4)
            .collect();
        reference.displacements = map.displacements(&z);
        let (l2, energy) = projections(&basis, &reference).unwrap();
        for field in [l2, energy] {
            let (_, relative) = field_errors(&field, &reference.displacements);
            assert!(relative < 1e-7, "relative error {relative}");
        }
    }

    #[test]
    fn the_l2_projection_has_the_smallest_mse_in_the_subspace() {
        let basis = small_basis();
        let reference = coarse_reference();
        let (l2, energy) = projections(&basis, &reference).unwrap();
        let (best, _) = field_errors(&l2, &reference.displacements);
        let (other, _) = field_errors(&energy, &reference.displacements);
        assert!(best > 0.0, "the FEM field is not in a 4-mode subspace");
        assert!(best <= other, "L2 {best:e} above energy {other:e}");
    }
}
