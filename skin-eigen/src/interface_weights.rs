//! Skinning weights that vanish weakly on an interface: the weight eigenproblem (Eq. 15) with a
//! symmetric Nitsche-Dirichlet condition, for a body whose held part is left out and held
//! through that interface by a Nitsche term in the simulation
//! (`reduced_sim::NitscheInterface`). Modes free on the interface (the Neumann modes of
//! [`crate::build_basis`]) must represent the clamp's zero displacement through the constant
//! handle alone; these modes do not.
//!
//! ```text
//! (H_N)_kl = (H_w)_kl − Σ_s a_s κ [ ∂_N ϕ_k(X_s) ϕ_l(X_s) + ϕ_k(X_s) ∂_N ϕ_l(X_s) ]
//!            + β_w Σ_s a_s ϕ_k(X_s) ϕ_l(X_s),
//! β_w = 2 s C_w,   C_w = λ_max( Σ_s a_s κ² ∂_N ϕ ∂_N ϕᵀ , H_w )  on range(H_w)
//! ```
//!
//! with κ = λ + 4μ (H_w's coefficient, Prop. 1), samples X_s with areas a_s (m²) and outward
//! unit normals N_s of the body, over the samples of every interface; then `H_N c = λ 𝓜 c`
//! for the m smallest pairs, none dropped (no constant mode is left to drop). The basis's
//! handle 0 is still the constant. With R interfaces, R − 1 region handles follow it, as in
//! [`crate::build_basis_with_regions`]: `a_r = Σ ϕ_k c_kr` with `H_N c_r = b_r`, the weights
//! that are 1 on interface r and 0 on the others in the same weak sense,
//! `b_r = Σ_{s ∈ Γ_r} a_s (−κ ∂_N ϕ(X_s) + β_w ϕ(X_s))`; so interfaces that move relative to
//! each other (a twisted end against a clamp) are each followed by a handle of their own.

use faer::Mat;
use faer::linalg::solvers::Solve;
use hyperelastic::LameParameters;
use nalgebra::{DMatrix, Vector3};
use rkpm_core::{IntegrationPoints, ShapeFunctions, evaluate_shape_functions};

use crate::assembly::WeightSpaceMatrices;
use crate::basis_builder::{
    AssembledMatrices, BasisError, BasisParams, BasisReport, InterfaceTerms, Placed,
    build_on_placed_with, placed_kernels_and_shape_functions,
};
use crate::generalized_eigen::largest_eigenvalue_on_range;
use crate::skinning_basis::SkinningBasis;

/// One interface where the weights vanish weakly (one held region's boundary with the body).
#[derive(Clone, Debug, PartialEq)]
pub struct WeightInterface {
    /// Sample positions X_s (m), on the body's boundary.
    pub samples: Vec<Vector3<f64>>,
    /// Their areas a_s (m²), positive.
    pub areas: Vec<f64>,
    /// The body's outward unit normals N_s there.
    pub normals: Vec<Vector3<f64>>,
    /// The material there (κ = λ + 4μ).
    pub material: LameParameters,
    /// s in `β_w = 2 s C_w` (dimensionless; default of the simulation's interface, 2).
    pub stabilization_factor: f64,
}

/// Builds the basis of [`crate::build_basis`] on `points` with weights that vanish weakly on
/// every one of `interfaces` and, for R interfaces, R − 1 region handles (module docs):
/// kernels placed to reach the samples too. The stabilization factor and material of the
/// bound are the first interface's.
///
/// # Errors
/// [`BasisError`] as [`crate::build_basis`], and [`BasisError::Interface`] for no interface,
/// mismatched or invalid samples, a factor that is not positive, a weight Hessian with no
/// positive eigenvalue, or an interface system that is not positive definite;
/// [`BasisError::RegionsNeedDenseSolver`] for more kernels than the dense solver takes.
pub fn build_basis_with_interfaces(
    points: &IntegrationPoints,
    materials: &[LameParameters],
    params: &BasisParams,
    interfaces: &[WeightInterface],
) -> Result<(SkinningBasis, BasisReport, AssembledMatrices), BasisError> {
    let Some(first) = interfaces.first() else {
        return Err(BasisError::Interface("no interface".into()));
    };
    interfaces.iter().try_for_each(check)?;
    let samples: Vec<Vector3<f64>> = interfaces
        .iter()
        .flat_map(|i| i.samples.iter().copied())
        .collect();
    let (timings, kernels, coverage, shape) =
        placed_kernels_and_shape_functions(points, &[&samples], params)?;
    let at_samples = evaluate_shape_functions(&kernels, &samples, &params.shape_functions)
        .map_err(BasisError::from)?;
    let union = WeightInterface {
        samples,
        areas: interfaces
            .iter()
            .flat_map(|i| i.areas.iter().copied())
            .collect(),
        normals: interfaces
            .iter()
            .flat_map(|i| i.normals.iter().copied())
            .collect(),
        ..first.clone()
    };
    let beta = std::cell::Cell::new(0.0);
    let terms = InterfaceTerms {
        add: &|matrices: &mut WeightSpaceMatrices| {
            beta.set(add_interface_terms(matrices, &at_samples, &union)?);
            Ok(())
        },
    };
    let (basis, report, matrices) = build_on_placed_with(
        points,
        materials,
        params,
        &terms,
        Placed {
            timings,
            kernels,
            coverage,
            shape: &shape,
        },
    )?;
    if interfaces.len() == 1 {
        return Ok((basis, report, matrices));
    }
    let AssembledMatrices::Dense(dense) = &matrices else {
        return Err(BasisError::RegionsNeedDenseSolver {
            kernels: basis.kernels().len(),
        });
    };
    let regions = region_coefficients(&dense.hessian, &at_samples, interfaces, beta.get())?;
    let mut basis = basis.with_held_regions(regions);
    basis.keep_weights_at_build_points(points.positions(), points.positions(), &shape, None)?;
    Ok((basis, report, matrices))
}

/// [`build_basis_with_interfaces`] with one interface (no region handle).
///
/// # Errors
/// As [`build_basis_with_interfaces`].
pub fn build_basis_with_interface(
    points: &IntegrationPoints,
    materials: &[LameParameters],
    params: &BasisParams,
    interface: &WeightInterface,
) -> Result<(SkinningBasis, BasisReport, AssembledMatrices), BasisError> {
    build_basis_with_interfaces(points, materials, params, std::slice::from_ref(interface))
}

/// The coefficients of the region handles a_1 … a_{R−1} (K × (R − 1)): `H_N c_r = b_r`
/// (module docs) for every interface but the first; `at_samples` are the shape functions at
/// every interface's samples in order, `beta` is β_w.
fn region_coefficients(
    hessian: &Mat<f64>,
    at_samples: &ShapeFunctions,
    interfaces: &[WeightInterface],
    beta: f64,
) -> Result<DMatrix<f64>, BasisError> {
    let k = hessian.nrows();
    let cholesky = hessian.llt(faer::Side::Lower).map_err(|_| {
        BasisError::Interface(
            "the weight Hessian with its interfaces is not positive definite".into(),
        )
    })?;
    let mut loads = Mat::<f64>::zeros(k, interfaces.len() - 1);
    let mut first_sample = interfaces[0].samples.len();
    for (r, interface) in interfaces.iter().enumerate().skip(1) {
        let kappa = interface.material.lambda() + 4.0 * interface.material.mu();
        for (j, (a, n)) in interface.areas.iter().zip(&interface.normals).enumerate() {
            let s = first_sample + j;
            for ((&kernel, value), gradient) in at_samples
                .kernels(s)
                .iter()
                .zip(at_samples.values(s))
                .zip(at_samples.gradients(s))
            {
                loads[(kernel as usize, r - 1)] += a * (beta * value - kappa * gradient.dot(n));
            }
        }
        first_sample += interface.samples.len();
    }
    let solved = cholesky.solve(&loads);
    Ok(DMatrix::from_fn(k, interfaces.len() - 1, |i, j| {
        solved[(i, j)]
    }))
}

fn check(interface: &WeightInterface) -> Result<(), BasisError> {
    let n = interface.samples.len();
    let problem = if n == 0 {
        Some("no interface sample".to_string())
    } else if interface.areas.len() != n || interface.normals.len() != n {
        Some(format!(
            "{n} samples, {} areas and {} normals",
            interface.areas.len(),
            interface.normals.len()
        ))
    } else if let Some(s) = (0..n).find(|&s| {
        let (a, normal) = (interface.areas[s], interface.normals[s]);
        let valid = a.is_finite()
            && a > 0.0
            && interface.samples[s].iter().all(|v| v.is_finite())
            && (normal.norm() - 1.0).abs() <= 1e-9;
        !valid
    }) {
        Some(format!(
            "sample {s}: a positive area and a unit normal are needed"
        ))
    } else if !(interface.stabilization_factor.is_finite() && interface.stabilization_factor > 0.0)
    {
        Some(format!(
            "the stabilization factor must be positive, got {}",
            interface.stabilization_factor
        ))
    } else {
        None
    };
    problem.map_or(Ok(()), |p| Err(BasisError::Interface(p)))
}

/// Adds the Nitsche-Dirichlet terms of the module docs to `matrices.hessian`; returns β_w.
fn add_interface_terms(
    matrices: &mut WeightSpaceMatrices,
    at_samples: &ShapeFunctions,
    interface: &WeightInterface,
) -> Result<f64, BasisError> {
    let k = matrices.hessian.nrows();
    let kappa = interface.material.lambda() + 4.0 * interface.material.mu();
    let mut consistency = Mat::<f64>::zeros(k, k);
    let mut mass = Mat::<f64>::zeros(k, k);
    let mut flux = Mat::<f64>::zeros(k, k);
    for s in 0..interface.samples.len() {
        let a = interface.areas[s];
        let n = interface.normals[s];
        let kernels = at_samples.kernels(s);
        let values = at_samples.values(s);
        let normal_derivatives: Vec<f64> =
            at_samples.gradients(s).iter().map(|g| g.dot(&n)).collect();
        for (p, &kp) in kernels.iter().enumerate() {
            for (q, &kq) in kernels.iter().enumerate() {
                let (kp, kq) = (kp as usize, kq as usize);
                consistency[(kp, kq)] -= a
                    * kappa
                    * (normal_derivatives[p] * values[q] + values[p] * normal_derivatives[q]);
                mass[(kp, kq)] += a * values[p] * values[q];
                flux[(kp, kq)] += a * kappa * kappa * normal_derivatives[p] * normal_derivatives[q];
            }
        }
    }
    let bound =
        largest_eigenvalue_on_range(flux.as_ref(), matrices.hessian.as_ref()).ok_or_else(|| {
            BasisError::Interface("the weight Hessian has no positive eigenvalue".into())
        })?;
    let beta = 2.0 * interface.stabilization_factor * bound;
    matrices.hessian = &matrices.hessian + &consistency + &mass * beta;
    Ok(beta)
}
