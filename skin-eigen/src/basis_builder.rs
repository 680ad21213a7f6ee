//! The whole basis construction ("training"): kernels → shape functions → 𝓜, H_w → eigen
//! solve, timed per phase.

use std::time::Instant;

use hyperelastic::LameParameters;
use nalgebra::{DMatrix, Vector3};
use rkpm_core::{
    CoverageParams, CoverageReport, IntegrationPoints, KernelError, KernelParams, Kernels,
    ShapeFunctionError, ShapeFunctionParams, ShapeFunctions, cover_queries,
    evaluate_shape_functions, place_kernels, singular_queries,
};
use serde::{Deserialize, Serialize};

use crate::assembly::{AssemblyError, WeightSpaceMatrices, assemble_weight_space_matrices};
use crate::generalized_eigen::{
    EigenError, EigenParams, EigenSolution, solve_modes_keeping_first, solve_skinning_modes,
};
use crate::region_constraints::{RegionConstraintParams, RegionError, solve_constrained_modes};
use crate::skinning_basis::{BasisMetadata, SkinningBasis};
use crate::sparse_assembly::{SparseWeightSpaceMatrices, assemble_sparse_weight_space_matrices};
use crate::subspace_iteration::{SubspaceParams, solve_skinning_modes_iteratively};

/// Which eigen solver [`build_basis`] uses.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum EigenSolverChoice {
    /// Dense for K ≤ [`DENSE_SOLVER_MAX_KERNELS`], iterative above (default).
    #[default]
    #[serde(alias = "Auto")]
    Auto,
    /// Dense assembly and two dense eigendecompositions (O(K³)).
    #[serde(alias = "Dense")]
    Dense,
    /// Sparse assembly and shift-invert subspace iteration.
    #[serde(alias = "Iterative")]
    Iterative(SubspaceParams),
}

/// Largest K the `Auto` choice solves densely.
///
/// Measured on the beam with 30k integration points and m = 32 (2 cores): K = 4000 takes
/// 8.7 s dense assembly + 20.6 s dense eigen solve, but 34 s sparse assembly + 108 s
/// iterative solve — with the radius clamp (3× point spacing) each point sees ~500 kernels,
/// so the "sparse" matrices are nearly dense. The iterative path pays off only when kernels
/// stay local (K large with correspondingly more integration points); dense memory is
/// 2K² doubles plus one such pair per thread (≈ 1.2 GB at K = 5000 on 2 threads).
pub const DENSE_SOLVER_MAX_KERNELS: usize = 5000;

/// The assembled matrices, in the form the chosen solver used.
#[derive(Clone, Debug)]
pub enum AssembledMatrices {
    /// Dense K×K.
    Dense(WeightSpaceMatrices),
    /// Sparse K×K.
    Sparse(SparseWeightSpaceMatrices),
}

/// Options for [`build_basis`]; every default is the documented default of its part
/// (K = 1000 kernels, cutoff 4 r_k, m = 16, solver chosen by K).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct BasisParams {
    /// Kernel count and radius rule.
    pub kernels: KernelParams,
    /// Shape-function cutoff and conditioning threshold.
    pub shape_functions: ShapeFunctionParams,
    /// Number of modes and mass-rank tolerance.
    pub eigen: EigenParams,
    /// Dense or iterative eigen solve.
    pub solver: EigenSolverChoice,
    /// Widening of the kernels nearest an integration point where the shape functions do not
    /// exist ([`cover_queries`]; default 8 rounds of ×1.25, `max_rounds: 0` for the paper's
    /// kernels as placed). A basis buildable without it is not changed by it.
    #[serde(default)]
    pub coverage: CoverageParams,
}

impl BasisParams {
    /// The same options with `modes` skinning modes (m).
    pub fn with_modes(mut self, modes: usize) -> Self {
        self.eigen.modes = modes;
        self
    }

    /// The same options with `kernels` RKPM kernels (K).
    pub fn with_kernels(mut self, kernels: usize) -> Self {
        self.kernels.count = kernels;
        self
    }
}

/// Seconds spent in each phase of basis construction.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct PhaseTimings {
    /// Farthest point sampling and radii.
    pub kernel_placement: f64,
    /// Shape functions and gradients at the integration points (with any widening of the
    /// kernels, [`BasisParams::coverage`]).
    pub shape_functions: f64,
    /// 𝓜 and H_w.
    pub assembly: f64,
    /// Generalized eigen solve.
    pub eigen_solve: f64,
}

impl PhaseTimings {
    /// Sum of all phases (s).
    pub fn total(&self) -> f64 {
        self.kernel_placement + self.shape_functions + self.assembly + self.eigen_solve
    }
}

/// What [`build_basis`] measured, returned to the caller (the library prints nothing).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BasisReport {
    /// Per-phase wall time.
    pub timings: PhaseTimings,
    /// Number of kernels K.
    pub kernels: usize,
    /// Number of integration points N.
    pub integration_points: usize,
    /// Mean kernels reaching an integration point.
    pub mean_kernels_per_point: f64,
    /// Kernels widened where the shape functions did not exist, or missed the reproducing
    /// conditions ([`BasisParams::coverage`]).
    #[serde(default)]
    pub coverage: CoverageReport,
    /// `λ_max(𝓜)/λ_min(𝓜)` (NaN for the iterative solver, which does not compute it).
    pub mass_condition_number: f64,
    /// Near-null mass directions discarded (dense solver).
    pub discarded_mass_directions: usize,
    /// `max_j |H_w c_j - λ_j 𝓜 c_j| / (|H_w|_F |c_j|)`.
    pub eigen_relative_residual: f64,
    /// `max |cᵀ𝓜c - I|`.
    pub orthonormality_error: f64,
    /// For a basis with held regions ([`build_basis_with_regions`]): how exactly its weights
    /// hold them.
    #[serde(default)]
    pub held_regions: Option<HeldRegionsReport>,
}

/// How exactly the weights of a basis with held regions hold them.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct HeldRegionsReport {
    /// Number of regions R.
    pub regions: usize,
    /// Points the regions are held at.
    pub points: usize,
    /// `max |W_r − δ_r|` of the region weights on the region points.
    pub max_region_weight_error: f64,
    /// `max |W_j|` of the modes on the region points.
    pub max_mode_value_on_regions: f64,
    /// Dimension of the space of kernel weights that vanish on the regions (of K).
    pub null_space_dimension: usize,
}

/// Basis construction failed; the variant says in which phase.
#[derive(Debug, thiserror::Error)]
pub enum BasisError {
    /// Kernel placement.
    #[error("kernel placement: {0}")]
    Kernels(#[from] KernelError),
    /// Shape-function evaluation.
    #[error("shape functions: {0}")]
    ShapeFunctions(#[from] ShapeFunctionError),
    /// Assembly.
    #[error("assembly: {0}")]
    Assembly(#[from] AssemblyError),
    /// Eigen solve.
    #[error("eigen solve: {0}")]
    Eigen(#[from] EigenError),
    /// Held regions ([`build_basis_with_regions`]).
    #[error("held regions: {0}")]
    Regions(#[from] RegionError),
    /// Held regions need the dense solver.
    #[error(
        "held regions are solved densely, but the options ask for the iterative solver (K = {kernels}); use EigenSolverChoice::Dense or at most {DENSE_SOLVER_MAX_KERNELS} kernels"
    )]
    RegionsNeedDenseSolver {
        /// K.
        kernels: usize,
    },
    /// An interface of [`crate::build_basis_with_interface`] is invalid, or its terms cannot
    /// be formed.
    #[error("weight interface: {0}")]
    Interface(String),
}

/// Builds the skinning basis of an object given by integration points and per-point Lamé
/// parameters (the rest Hessian of the stable Neo-Hookean energy, Prop. 1).
///
/// Returns the basis, its report, and the assembled matrices (for checks and ablations).
///
/// # Errors
/// [`BasisError`] naming the phase and the problem (e.g. m ≥ K, a singular moment matrix).
pub fn build_basis(
    points: &IntegrationPoints,
    materials: &[LameParameters],
    params: &BasisParams,
) -> Result<(SkinningBasis, BasisReport, AssembledMatrices), BasisError> {
    build(points, materials, params, None, &[], &|_| {})
}

/// A stage of building a basis, in the order [`build_basis_observed`] reports them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BasisStage {
    /// Placing the K kernels and evaluating the RKPM shape functions at the points.
    ShapeFunctions,
    /// Assembling the weight-space stiffness and mass matrices (Eq. 12).
    Assembly,
    /// Solving the generalized eigenproblem for the m modes.
    EigenSolve,
}

impl BasisStage {
    /// The stages in order.
    pub const ALL: [BasisStage; 3] = [
        BasisStage::ShapeFunctions,
        BasisStage::Assembly,
        BasisStage::EigenSolve,
    ];

    /// "shape functions", "assembly" or "eigen solve".
    pub fn name(self) -> &'static str {
        match self {
            BasisStage::ShapeFunctions => "shape functions",
            BasisStage::Assembly => "assembly",
            BasisStage::EigenSolve => "eigen solve",
        }
    }
}

/// [`build_basis`], calling `on_stage` as each stage begins (for a progress display; the
/// result is the same).
///
/// # Errors
/// As [`build_basis`].
pub fn build_basis_observed(
    points: &IntegrationPoints,
    materials: &[LameParameters],
    params: &BasisParams,
    on_stage: &dyn Fn(BasisStage),
) -> Result<(SkinningBasis, BasisReport, AssembledMatrices), BasisError> {
    build(points, materials, params, None, &[], on_stage)
}

/// [`build_basis`] for an object with R exactly held regions: the basis carries one
/// weight per region beyond the first (1 on its region, 0 on the others, the material-aware
/// harmonic extension of H_w elsewhere) and m modes computed among the weights that vanish on
/// every region ([`crate::solve_constrained_modes`]), so each region moves by the affine
/// transform of its handles alone. `regions` holds, per region, the rest points (m) it must be
/// held at: at least the simulation's integration points in the region (those the simulator
/// checks), ideally also this assembly's points there. `evaluated_at` lists the other point
/// sets the basis will be evaluated at (simulation points, output vertices): the kernels are
/// widened ([`BasisParams::coverage`]) so that the shape functions exist at them and at
/// `points` alike (region points drawn from these sets are then covered too; one outside the
/// kernels' reach is [`RegionError::ShapeFunctions`]).
///
/// # Errors
/// [`BasisError`] as for [`build_basis`] (a point where the shape functions do not exist even
/// after widening is numbered through `points` and then `evaluated_at`, and named by its
/// position); [`BasisError::Regions`] for empty regions, region
/// points out of the kernels' reach and regions the kernels cannot separate;
/// [`BasisError::RegionsNeedDenseSolver`] when the options select the iterative solver.
pub fn build_basis_with_regions(
    points: &IntegrationPoints,
    materials: &[LameParameters],
    params: &BasisParams,
    regions: &[Vec<Vector3<f64>>],
    region_params: &RegionConstraintParams,
    evaluated_at: &[&[Vector3<f64>]],
) -> Result<(SkinningBasis, BasisReport, AssembledMatrices), BasisError> {
    build(
        points,
        materials,
        params,
        Some((regions, region_params)),
        evaluated_at,
        &|_| {},
    )
}

fn build(
    points: &IntegrationPoints,
    materials: &[LameParameters],
    params: &BasisParams,
    regions: Option<(&[Vec<Vector3<f64>>], &RegionConstraintParams)>,
    evaluated_at: &[&[Vector3<f64>]],
    on_stage: &dyn Fn(BasisStage),
) -> Result<(SkinningBasis, BasisReport, AssembledMatrices), BasisError> {
    on_stage(BasisStage::ShapeFunctions);
    let (timings, kernels, coverage, shape) =
        placed_kernels_and_shape_functions(points, evaluated_at, params)?;
    build_on_placed(
        points,
        materials,
        params,
        regions,
        on_stage,
        Placed {
            timings,
            kernels,
            coverage,
            shape: &shape,
        },
    )
}

/// Kernels placed for a build, what widening did, their shape functions at the build's points
/// and what placing and evaluating them took.
pub(crate) struct Placed<'a> {
    pub(crate) timings: PhaseTimings,
    pub(crate) kernels: Kernels,
    pub(crate) coverage: CoverageReport,
    pub(crate) shape: &'a ShapeFunctions,
}

/// Terms added to the dense weight matrices before the eigen solve, which then keeps its
/// smallest pair (no constant mode is left to drop): [`crate::build_basis_with_interface`].
pub(crate) struct InterfaceTerms<'a> {
    pub(crate) add: &'a dyn Fn(&mut WeightSpaceMatrices) -> Result<(), BasisError>,
}

/// The build after its shape functions: assembly, eigen solve and the basis.
pub(crate) fn build_on_placed(
    points: &IntegrationPoints,
    materials: &[LameParameters],
    params: &BasisParams,
    regions: Option<(&[Vec<Vector3<f64>>], &RegionConstraintParams)>,
    on_stage: &dyn Fn(BasisStage),
    placed: Placed<'_>,
) -> Result<(SkinningBasis, BasisReport, AssembledMatrices), BasisError> {
    build_on_placed_inner(points, materials, params, regions, None, on_stage, placed)
}

/// [`build_on_placed`] with `terms` added to the weight matrices (dense solver only).
pub(crate) fn build_on_placed_with(
    points: &IntegrationPoints,
    materials: &[LameParameters],
    params: &BasisParams,
    terms: &InterfaceTerms<'_>,
    placed: Placed<'_>,
) -> Result<(SkinningBasis, BasisReport, AssembledMatrices), BasisError> {
    build_on_placed_inner(
        points,
        materials,
        params,
        None,
        Some(terms),
        &|_| {},
        placed,
    )
}

fn build_on_placed_inner(
    points: &IntegrationPoints,
    materials: &[LameParameters],
    params: &BasisParams,
    regions: Option<(&[Vec<Vector3<f64>>], &RegionConstraintParams)>,
    terms: Option<&InterfaceTerms<'_>>,
    on_stage: &dyn Fn(BasisStage),
    placed: Placed<'_>,
) -> Result<(SkinningBasis, BasisReport, AssembledMatrices), BasisError> {
    let Placed {
        mut timings,
        kernels,
        coverage,
        shape,
    } = placed;
    let iterative = match params.solver {
        EigenSolverChoice::Auto if kernels.len() > DENSE_SOLVER_MAX_KERNELS => {
            Some(SubspaceParams::default())
        }
        EigenSolverChoice::Auto | EigenSolverChoice::Dense => None,
        EigenSolverChoice::Iterative(subspace) => Some(subspace),
    };
    if (regions.is_some() || terms.is_some()) && iterative.is_some() {
        return Err(BasisError::RegionsNeedDenseSolver {
            kernels: kernels.len(),
        });
    }
    on_stage(BasisStage::Assembly);
    let t = Instant::now();
    let mut held = None;
    let (matrices, solution) = match iterative {
        None => {
            let mut matrices = assemble_weight_space_matrices(shape, points.volumes(), materials)?;
            if let Some(terms) = terms {
                (terms.add)(&mut matrices)?;
            }
            timings.assembly = t.elapsed().as_secs_f64();
            on_stage(BasisStage::EigenSolve);
            let t = Instant::now();
            let solution = match regions {
                None if terms.is_some() => solve_modes_keeping_first(&matrices, &params.eigen)?,
                None => solve_skinning_modes(&matrices, &params.eigen)?,
                Some((regions, region_params)) => {
                    let constrained = solve_constrained_modes(
                        &matrices,
                        &kernels,
                        &params.shape_functions,
                        regions,
                        &params.eigen,
                        region_params,
                    )?;
                    let a = &constrained.region_coefficients;
                    let report = HeldRegionsReport {
                        regions: regions.len(),
                        points: regions.iter().map(Vec::len).sum(),
                        max_region_weight_error: constrained.max_region_weight_error,
                        max_mode_value_on_regions: constrained.max_mode_value_on_regions,
                        null_space_dimension: constrained.null_space_dimension,
                    };
                    held = Some((
                        DMatrix::from_fn(a.nrows(), a.ncols() - 1, |i, j| a[(i, j + 1)]),
                        report,
                    ));
                    EigenSolution::from_constrained(constrained)
                }
            };
            timings.eigen_solve = t.elapsed().as_secs_f64();
            (AssembledMatrices::Dense(matrices), solution)
        }
        Some(subspace) => {
            let matrices = assemble_sparse_weight_space_matrices(
                shape,
                &kernels,
                params.shape_functions.cutoff,
                points.volumes(),
                materials,
            )?;
            timings.assembly = t.elapsed().as_secs_f64();
            on_stage(BasisStage::EigenSolve);
            let t = Instant::now();
            let solution = solve_skinning_modes_iteratively(&matrices, &params.eigen, &subspace)?;
            timings.eigen_solve = t.elapsed().as_secs_f64();
            (AssembledMatrices::Sparse(matrices), solution)
        }
    };

    let c = &solution.coefficients;
    let coefficients = DMatrix::from_fn(c.nrows(), c.ncols(), |i, j| c[(i, j)]);
    let metadata = BasisMetadata {
        material: "stable Neo-Hookean (rest Hessian, λ + 4μ)".into(),
        integration_points: points.len(),
        mass_condition_number: solution.mass_condition_number,
        discarded_mass_directions: solution.discarded_mass_directions,
        constant_eigenvalue: solution.constant_eigenvalue,
    };
    let report = BasisReport {
        timings,
        kernels: kernels.len(),
        integration_points: points.len(),
        mean_kernels_per_point: shape.mean_kernels_per_point(),
        coverage,
        mass_condition_number: solution.mass_condition_number,
        discarded_mass_directions: solution.discarded_mass_directions,
        eigen_relative_residual: solution.max_relative_residual,
        orthonormality_error: solution.orthonormality_error,
        held_regions: held.as_ref().map(|(_, report)| *report),
    };
    let mut basis = SkinningBasis::new(
        kernels,
        params.shape_functions,
        coefficients,
        solution.eigenvalues,
        metadata,
    );
    if let Some((region_coefficients, _)) = held {
        basis = basis.with_held_regions(region_coefficients);
    }
    basis.keep_weights_at_build_points(points.positions(), points.positions(), shape, None)?;
    Ok((basis, report, matrices))
}

/// The first two phases of a basis build, timed: kernels placed on `points` by farthest point
/// sampling, widened where needed ([`shape_functions_covering`]), and their shape functions at
/// `points`.
pub(crate) fn placed_kernels_and_shape_functions(
    points: &IntegrationPoints,
    evaluated_at: &[&[Vector3<f64>]],
    params: &BasisParams,
) -> Result<(PhaseTimings, Kernels, CoverageReport, ShapeFunctions), BasisError> {
    let mut timings = PhaseTimings::default();
    let t = Instant::now();
    let placed = place_kernels(points.positions(), &params.kernels)?;
    timings.kernel_placement = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let (kernels, coverage, shape) =
        shape_functions_covering(points, evaluated_at, placed, params)?;
    timings.shape_functions = t.elapsed().as_secs_f64();
    Ok((timings, kernels, coverage, shape))
}

/// The kernels (`placed`, widened where needed, [`cover_queries`]), what widening did, and the
/// shape functions at `points`. Kernels as placed that reach every point of `points` and of
/// `evaluated_at` are kept after one evaluation at `points` and a check of the other sets.
fn shape_functions_covering(
    points: &IntegrationPoints,
    evaluated_at: &[&[Vector3<f64>]],
    placed: Kernels,
    params: &BasisParams,
) -> Result<(Kernels, CoverageReport, ShapeFunctions), BasisError> {
    let shape_params = &params.shape_functions;
    match evaluate_shape_functions(&placed, points.positions(), shape_params) {
        Ok(shape)
            if reaches_every_point(&placed, evaluated_at, points.positions(), shape_params) =>
        {
            return Ok((placed, CoverageReport::default(), shape));
        }
        Ok(_) => {}
        Err(e) if e.uncovered_point().is_some() => {}
        Err(e) => return Err(e.into()),
    }
    let covered: Vec<Vector3<f64>> = std::iter::once(points.positions())
        .chain(evaluated_at.iter().copied())
        .flatten()
        .copied()
        .collect();
    let (kernels, coverage) = cover_queries(&placed, &covered, shape_params, &params.coverage)?;
    let shape = evaluate_shape_functions(&kernels, points.positions(), shape_params)?;
    Ok((kernels, coverage, shape))
}

/// Whether the shape functions of `kernels` exist at every point of `sets` (any failure, a
/// non-finite point included, is left to [`cover_queries`] to report); a set equal to
/// `already_covered` (points where they were just evaluated) is not evaluated again.
fn reaches_every_point(
    kernels: &Kernels,
    sets: &[&[Vector3<f64>]],
    already_covered: &[Vector3<f64>],
    params: &ShapeFunctionParams,
) -> bool {
    sets.iter().all(|set| {
        *set == already_covered
            || singular_queries(kernels, set, params).is_ok_and(|singular| singular.is_empty())
    })
}
