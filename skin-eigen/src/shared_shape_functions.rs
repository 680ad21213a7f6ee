//! Kernels and shape functions one build made, reused by a second build on the same points:
//! a weighted basis ([`crate::build_weighted_basis_sharing`]) evaluates the plain RKPM shape
//! functions of its kernels on the free part, and a plain basis
//! ([`build_basis_keeping_shape_functions`]) on all its points, which are exactly what a plain
//! basis of the same points with more or fewer modes ([`build_basis_sharing`]; the Neumann modes
//! of a pressure space) would place and evaluate again.

use hyperelastic::LameParameters;
use nalgebra::Vector3;
use rkpm_core::{
    CoverageReport, IntegrationPoints, KernelParams, Kernels, ShapeFunctionParams, ShapeFunctions,
};

use crate::basis_builder::{
    AssembledMatrices, BasisError, BasisParams, BasisReport, PhaseTimings, Placed, build_basis,
    build_on_placed, placed_kernels_and_shape_functions,
};
use crate::skinning_basis::SkinningBasis;

/// Kernels placed on a set of points by farthest point sampling, and their shape functions
/// (values and gradients) at those points, with the options that made them.
///
/// Memory: about `36 · N · k̄` bytes for N points reached by k̄ kernels each (200 MB at
/// N = 40 000, k̄ = 150): drop it once the second build is made.
#[derive(Clone, Debug)]
pub struct KernelShapeFunctions {
    points: Vec<Vector3<f64>>,
    kernels: Kernels,
    coverage: CoverageReport,
    shape: ShapeFunctions,
    kernel_params: KernelParams,
    shape_params: ShapeFunctionParams,
}

impl KernelShapeFunctions {
    /// The kernels `kernels`, placed with `kernel_params` on `points` (m) and widened as
    /// `coverage` says, and their shape functions `shape` at `points`, evaluated with
    /// `shape_params`.
    pub(crate) fn new(
        points: Vec<Vector3<f64>>,
        kernels: Kernels,
        coverage: CoverageReport,
        shape: ShapeFunctions,
        kernel_params: KernelParams,
        shape_params: ShapeFunctionParams,
    ) -> Self {
        KernelShapeFunctions {
            points,
            kernels,
            coverage,
            shape,
            kernel_params,
            shape_params,
        }
    }

    /// The points (m) the shape functions are evaluated at, in order.
    pub fn points(&self) -> &[Vector3<f64>] {
        &self.points
    }

    /// The kernels.
    pub fn kernels(&self) -> &Kernels {
        &self.kernels
    }

    /// Whether [`build_basis`] on `points` with `params` would place these kernels and evaluate
    /// these shape functions: the same points in the same order, the same kernel and
    /// shape-function options, and kernels as placed (none widened: a plain build widens only
    /// for its own points, the first build may have widened for others).
    pub fn fit(&self, points: &[Vector3<f64>], params: &BasisParams) -> bool {
        self.coverage.widened_kernels == 0
            && self.kernel_params == params.kernels
            && self.shape_params == params.shape_functions
            && self.points.as_slice() == points
    }
}

/// [`build_basis`] of `points`, on the kernels and shape functions of `shared` when they
/// [fit](KernelShapeFunctions::fit) (the same basis to the bit, without placing or evaluating
/// anything: its report's placement and shape-function times are 0), else built afresh.
///
/// # Errors
/// As [`build_basis`].
pub fn build_basis_sharing(
    points: &IntegrationPoints,
    materials: &[LameParameters],
    params: &BasisParams,
    shared: Option<&KernelShapeFunctions>,
) -> Result<(SkinningBasis, BasisReport, AssembledMatrices), BasisError> {
    match shared {
        Some(shared) if shared.fit(points.positions(), params) => build_on_placed(
            points,
            materials,
            params,
            None,
            &|_| {},
            Placed {
                timings: PhaseTimings::default(),
                kernels: shared.kernels.clone(),
                coverage: shared.coverage,
                shape: &shared.shape,
            },
        ),
        _ => build_basis(points, materials, params),
    }
}

/// [`build_basis`], also returning the kernels and shape functions it placed and evaluated at
/// `points`, for a second plain basis of the same points ([`build_basis_sharing`]).
///
/// # Errors
/// As [`build_basis`].
pub fn build_basis_keeping_shape_functions(
    points: &IntegrationPoints,
    materials: &[LameParameters],
    params: &BasisParams,
) -> Result<
    (
        SkinningBasis,
        BasisReport,
        AssembledMatrices,
        KernelShapeFunctions,
    ),
    BasisError,
> {
    let (timings, kernels, coverage, shape) =
        placed_kernels_and_shape_functions(points, &[], params)?;
    let (basis, report, matrices) = build_on_placed(
        points,
        materials,
        params,
        None,
        &|_| {},
        Placed {
            timings,
            kernels: kernels.clone(),
            coverage,
            shape: &shape,
        },
    )?;
    let shared = KernelShapeFunctions::new(
        points.positions().to_vec(),
        kernels,
        coverage,
        shape,
        params.kernels,
        params.shape_functions,
    );
    Ok((basis, report, matrices, shared))
}
