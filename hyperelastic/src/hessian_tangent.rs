//! Which material tangent the Newton Hessian of an implicit step uses, for every solver (the
//! reduced simulator and the FEM reference).
//!
//! Projected Newton clamps each point's negative tangent eigenvalues to zero
//! ([`Tangent::ProjectedPsd`]): every Hessian is positive semidefinite, but it is *stiffer*
//! than the true one wherever the material is compressed or buckling, so Newton converges only
//! linearly there. The exact tangent converges quadratically but can be indefinite far from
//! equilibrium. [`HessianTangent::ExactWhenDefinite`] takes the exact Hessian of the whole step
//! (inertia included, which usually makes it definite) and projects only when its Cholesky
//! factorization fails: the "projection on demand" of Longva et al., *Pitfalls of Projection*
//! (2023). [`HessianTangent::ExactElseAbsolute`] falls back to the absolute-eigenvalue tangent
//! instead ([`Tangent::AbsoluteEigenvalues`], Chen et al. 2024), which keeps the curvature the
//! projection drops. Measurements: `reduced_sim::hessian_tangent`, `fem_ref::FemParams::tangent`.

use serde::{Deserialize, Serialize};

use crate::material::Tangent;

/// The material tangent in the Hessian of each Newton iteration.
///
/// The converged state does not depend on it (the gradient is exact in every case); only the
/// path and the number of iterations do.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum HessianTangent {
    /// Every point's `∂P/∂F` projected onto the PSD cone (the paper's setting).
    #[serde(rename = "projected_psd", alias = "ProjectedPsd")]
    ProjectedPsd,
    /// The exact `∂P/∂F` (and the colliders' curvature): only safe while the Newton system
    /// stays positive definite; a failed factorization is reported.
    #[serde(rename = "exact", alias = "Exact")]
    Exact,
    /// The exact Hessian where it is positive definite (tested by a Cholesky factorization of
    /// the assembled Newton system: 12(m + 1) square in the reduced simulator, the free DOFs
    /// in the FEM), the projected one otherwise (the default of this enum and of the reduced
    /// simulator; the FEM's default is [`HessianTangent::ProjectedPsd`]).
    #[default]
    #[serde(rename = "exact_when_definite", alias = "ExactWhenDefinite")]
    ExactWhenDefinite,
    /// Every point's `∂P/∂F` with its eigenvalues replaced by their absolute values
    /// ([`Tangent::AbsoluteEigenvalues`], Chen et al. 2024): positive semidefinite like the
    /// projection, closer to the exact tangent where points are compressed.
    #[serde(rename = "absolute_eigenvalues", alias = "AbsoluteEigenvalues")]
    AbsoluteEigenvalues,
    /// As [`HessianTangent::ExactWhenDefinite`], but where the exact Hessian fails to factor
    /// the absolute-eigenvalue one is used instead of the projected one.
    #[serde(rename = "exact_else_absolute", alias = "ExactElseAbsolute")]
    ExactElseAbsolute,
}

impl HessianTangent {
    /// The tangent assembled first: exact unless always projected.
    pub fn first_try(self) -> Tangent {
        match self {
            HessianTangent::ProjectedPsd => Tangent::ProjectedPsd,
            HessianTangent::AbsoluteEigenvalues => Tangent::AbsoluteEigenvalues,
            HessianTangent::Exact
            | HessianTangent::ExactWhenDefinite
            | HessianTangent::ExactElseAbsolute => Tangent::Exact,
        }
    }

    /// The tangent assembled again when the first one's Newton system fails to factor: the
    /// projected one for [`HessianTangent::ExactWhenDefinite`], the absolute-eigenvalue one for
    /// [`HessianTangent::ExactElseAbsolute`], `None` where a failed factorization is an error
    /// (exact) or cannot happen (the positive semidefinite tangents, with inertia).
    pub fn fallback(self) -> Option<Tangent> {
        match self {
            HessianTangent::ExactWhenDefinite => Some(Tangent::ProjectedPsd),
            HessianTangent::ExactElseAbsolute => Some(Tangent::AbsoluteEigenvalues),
            HessianTangent::ProjectedPsd
            | HessianTangent::AbsoluteEigenvalues
            | HessianTangent::Exact => None,
        }
    }
}

impl From<Tangent> for HessianTangent {
    fn from(tangent: Tangent) -> Self {
        match tangent {
            Tangent::Exact => HessianTangent::Exact,
            Tangent::ProjectedPsd => HessianTangent::ProjectedPsd,
            Tangent::AbsoluteEigenvalues => HessianTangent::AbsoluteEigenvalues,
        }
    }
}
