//! Held regions by a weighted basis (WEB): modes that vanish on the regions by construction,
//! with no penalty and no band.
//!
//! With the weight w and blends g_r of [`RegionWeight`], kernels placed on the free part
//! Ω_f (the points outside every region) only, and ψ_k = w ϕ_k:
//!
//! ```text
//! 𝓜ʷ_kl  = Σ_{i ∈ Ω_f} v_i ψ_k ψ_l                                  (Eq. 14 on ψ)
//! Hʷ_kl  = Σ_{i ∈ Ω_f} v_i (λ_i + 4μ_i) ∇ψ_k · ∇ψ_l,  ∇ψ = w∇ϕ + ϕ∇w    (Prop. 1 on ψ)
//! modes           Hʷ c = λ 𝓜ʷ c,  cᵀ𝓜ʷc = I,  W^j = w Σ_k ϕ_k c_kj       (Eq. 15; no constant mode)
//! region handles  a_r = g_r + w Σ_k ϕ_k b_kr,  Hʷ b_r = −Σ_i v_i (λ_i + 4μ_i) ∇ψ · ∇g_r
//! ```
//!
//! The modes are 0 and each region handle is exactly 1 on its region and 0 on the others, so
//! region points follow the affine transform of their handles exactly for any coordinates. The
//! region handle `a_r` is the material-aware harmonic extension of its trace (the minimizer of
//! the Hʷ energy among `g_r + span ψ`). Kernels centred in a region, whose support would barely
//! enter Ω_f, are never placed: coarsely integrated they make spurious soft modes. See the
//! convergence study in `results/RESULTS.md` for why this treatment converges in m where a
//! penalty does not.

use std::time::Instant;

use faer::Mat;
use hyperelastic::LameParameters;
use nalgebra::{DMatrix, Vector3};
use rkpm_core::IntegrationPoints;

use crate::assembly::{WeightSpaceMatrices, assemble_weight_space_matrices};
use crate::basis_builder::{
    BasisError, BasisParams, BasisReport, DENSE_SOLVER_MAX_KERNELS, EigenSolverChoice,
    HeldRegionsReport, placed_kernels_and_shape_functions,
};
use crate::generalized_eigen::{EigenError, EigenSolution, smallest_generalized_eigenpairs};
use crate::region_constraints::RegionError;
use crate::region_weight::RegionWeight;
use crate::shared_shape_functions::KernelShapeFunctions;
use crate::skinning_basis::{BasisMetadata, SkinningBasis};

/// Builds a weighted basis (module docs) on `points` with Lamé parameters `materials`: m modes
/// (`params.eigen.modes`) and R − 1 region handles for the R regions of `weight`, handles
/// `[1, a_1 … a_{R-1}, W^1 … W^m]` as for [`crate::build_basis_with_regions`]. The K kernels
/// are placed among the points outside every region and widened
/// ([`BasisParams::coverage`]) where they leave a free point of `points` or of `evaluated_at`
/// without shape functions. Solved densely. When `evaluated_at` holds `points` itself, the basis
/// keeps its weights there ([`SkinningBasis::evaluate`] returns them without evaluating).
///
/// Postconditions: `cᵀ𝓜ʷc = I`; every mode is exactly 0 and every region handle exactly 1 or
/// 0 on the regions ([`BasisReport::held_regions`] measures both on the region points).
///
/// # Errors
/// [`BasisError::Regions`] when no point lies outside the regions, or no point lies in some
/// region; [`BasisError::RegionsNeedDenseSolver`] when the options ask for the iterative
/// solver or K > [`DENSE_SOLVER_MAX_KERNELS`]; otherwise as [`crate::build_basis`] (m ≥ K, a
/// singular moment matrix).
pub fn build_weighted_basis(
    points: &IntegrationPoints,
    materials: &[LameParameters],
    params: &BasisParams,
    weight: &RegionWeight,
    evaluated_at: &[&[Vector3<f64>]],
) -> Result<(SkinningBasis, BasisReport, WeightSpaceMatrices), BasisError> {
    build_weighted_basis_sharing(points, materials, params, weight, evaluated_at)
        .map(|(basis, report, matrices, _)| (basis, report, matrices))
}

/// [`build_weighted_basis`], also returning the plain (unweighted) shape functions of its
/// kernels at the points outside every region: a plain basis of that free part with the same
/// kernel options (the Neumann modes of a pressure space) can be built on them
/// ([`crate::build_basis_sharing`]) instead of placing and evaluating them again.
///
/// # Errors
/// As [`build_weighted_basis`].
pub fn build_weighted_basis_sharing(
    points: &IntegrationPoints,
    materials: &[LameParameters],
    params: &BasisParams,
    weight: &RegionWeight,
    evaluated_at: &[&[Vector3<f64>]],
) -> Result<
    (
        SkinningBasis,
        BasisReport,
        WeightSpaceMatrices,
        KernelShapeFunctions,
    ),
    BasisError,
> {
    if matches!(params.solver, EigenSolverChoice::Iterative(_))
        || params.kernels.count > DENSE_SOLVER_MAX_KERNELS
    {
        return Err(BasisError::RegionsNeedDenseSolver {
            kernels: params.kernels.count,
        });
    }
    if materials.len() != points.len() {
        return Err(crate::AssemblyError::LengthMismatch {
            what: "materials",
            got: materials.len(),
            expected: points.len(),
        }
        .into());
    }
    let regions = weight.regions().len();
    let mut region_points = vec![0usize; regions];
    let mut free = Vec::new();
    for (i, x) in points.positions().iter().enumerate() {
        match weight.region_of(x) {
            Some(r) => region_points[r] += 1,
            None => free.push(i),
        }
    }
    if let Some(region) = region_points.iter().position(|&count| count == 0) {
        return Err(RegionError::EmptyRegion { region }.into());
    }
    if free.is_empty() {
        return Err(RegionError::NoFreePoints.into());
    }
    let free_points = IntegrationPoints::new(
        free.iter().map(|&i| points.positions()[i]).collect(),
        free.iter().map(|&i| points.volumes()[i]).collect(),
    )
    .map_err(|_| RegionError::NoFreePoints)?;
    let free_materials: Vec<LameParameters> = free.iter().map(|&i| materials[i]).collect();
    let free_evaluated: Vec<Vec<Vector3<f64>>> = evaluated_at
        .iter()
        .map(|set| {
            set.iter()
                .filter(|x| weight.region_of(x).is_none())
                .copied()
                .collect()
        })
        .collect();
    let free_evaluated: Vec<&[Vector3<f64>]> = free_evaluated.iter().map(Vec::as_slice).collect();

    let (mut timings, kernels, coverage, shape) =
        placed_kernels_and_shape_functions(&free_points, &free_evaluated, params)?;
    let t = Instant::now();
    // Kept only when the basis will be evaluated at its own points: the weight's distances at
    // every point are not free. Keeping needs the weight at every point, the build only at the
    // free ones: computed once either way.
    let keep = evaluated_at.contains(&points.positions());
    let every_factor: Option<Vec<(f64, Vector3<f64>)>> = keep.then(|| {
        points
            .positions()
            .iter()
            .map(|x| weight.weight(x))
            .collect()
    });
    let factors: Vec<(f64, Vector3<f64>)> = match &every_factor {
        Some(every) => free.iter().map(|&i| every[i]).collect(),
        None => free_points
            .positions()
            .iter()
            .map(|x| weight.weight(x))
            .collect(),
    };
    let weighted = shape.multiplied(&factors);
    timings.shape_functions += t.elapsed().as_secs_f64();

    let t = Instant::now();
    let matrices =
        assemble_weight_space_matrices(&weighted, free_points.volumes(), &free_materials)?;
    timings.assembly = t.elapsed().as_secs_f64();

    let t = Instant::now();
    let modes = params.eigen.modes;
    if modes == 0 {
        return Err(EigenError::NoModes.into());
    }
    // Every pair: the modes are the first m, and the region handles solve with Hʷ on the
    // mass-rank-reduced space, Hʷ⁻¹ = C Λ⁻¹ Cᵀ (Hʷ is definite there: w removes the constants).
    let pencil = smallest_generalized_eigenpairs(
        matrices.mass.as_ref(),
        matrices.hessian.as_ref(),
        usize::MAX,
        modes + 1,
        params.eigen.mass_rank_tolerance,
    )?;
    let all = &pencil.vectors;
    let all_values = &pencil.values[..all.ncols()];
    let mut rhs = Mat::<f64>::zeros(kernels.len(), regions.saturating_sub(1));
    for (q, x) in free_points.positions().iter().enumerate() {
        let v = free_points.volumes()[q] * free_materials[q].weight_space_hessian_modulus();
        for r in 1..regions {
            let (_, grad_g) = weight.blend(r, x);
            for (&k, grad_psi) in weighted.kernels(q).iter().zip(weighted.gradients(q)) {
                rhs[(k as usize, r - 1)] -= v * grad_psi.dot(&grad_g);
            }
        }
    }
    let projected = all.transpose() * &rhs;
    let scaled = Mat::from_fn(projected.nrows(), projected.ncols(), |j, r| {
        projected[(j, r)] / all_values[j]
    });
    let region_coefficients = all * scaled;
    let truncated = crate::generalized_eigen::Pencil {
        vectors: pencil.vectors.subcols(0, modes).to_owned(),
        values: pencil.values,
        mass_condition_number: pencil.mass_condition_number,
        discarded_mass_directions: pencil.discarded_mass_directions,
    };
    let hc = &matrices.hessian * &truncated.vectors;
    let mc = &matrices.mass * &truncated.vectors;
    let h_norm = matrices.hessian.norm_l2();
    let solution = EigenSolution::from_pencil(truncated, 0, &hc, &mc, h_norm);
    timings.eigen_solve = t.elapsed().as_secs_f64();

    let c = &solution.coefficients;
    let metadata = BasisMetadata {
        material: "stable Neo-Hookean (rest Hessian, λ + 4μ), weighted by the held regions".into(),
        integration_points: free_points.len(),
        mass_condition_number: solution.mass_condition_number,
        discarded_mass_directions: solution.discarded_mass_directions,
        constant_eigenvalue: 0.0,
    };
    let mut basis = SkinningBasis::new(
        kernels,
        params.shape_functions,
        DMatrix::from_fn(c.nrows(), c.ncols(), |i, j| c[(i, j)]),
        solution.eigenvalues.clone(),
        metadata,
    )
    .with_held_regions(DMatrix::from_fn(
        region_coefficients.nrows(),
        region_coefficients.ncols(),
        |i, j| region_coefficients[(i, j)],
    ))
    .with_region_weight(weight.clone());
    if let Some(every_factor) = &every_factor {
        basis.keep_weights_at_build_points(
            points.positions(),
            free_points.positions(),
            &shape,
            Some(every_factor),
        )?;
    }

    let held_points: Vec<Vector3<f64>> = points
        .positions()
        .iter()
        .filter(|x| weight.region_of(x).is_some())
        .copied()
        .collect();
    let on_regions = basis.evaluate(&held_points)?;
    let (mut weight_error, mut mode_value) = (0.0f64, 0.0f64);
    for (p, x) in held_points.iter().enumerate() {
        let inside = weight.region_of(x).unwrap_or(0);
        for r in 1..regions {
            let target = f64::from(u8::from(r == inside));
            weight_error = weight_error.max((on_regions.weights[(p, r)] - target).abs());
        }
        for j in regions..basis.handles() {
            mode_value = mode_value.max(on_regions.weights[(p, j)].abs());
        }
    }
    let report = BasisReport {
        timings,
        kernels: basis.kernels().len(),
        integration_points: free_points.len(),
        mean_kernels_per_point: shape.mean_kernels_per_point(),
        coverage,
        mass_condition_number: solution.mass_condition_number,
        discarded_mass_directions: solution.discarded_mass_directions,
        eigen_relative_residual: solution.max_relative_residual,
        orthonormality_error: solution.orthonormality_error,
        held_regions: Some(HeldRegionsReport {
            regions,
            points: held_points.len(),
            max_region_weight_error: weight_error,
            max_mode_value_on_regions: mode_value,
            null_space_dimension: basis.kernels().len(),
        }),
    };
    let shared = KernelShapeFunctions::new(
        free_points.positions().to_vec(),
        basis.kernels().clone(),
        coverage,
        shape,
        params.kernels,
        params.shape_functions,
    );
    Ok((basis, report, matrices, shared))
}
