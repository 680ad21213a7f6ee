//! A basis built from the same material description the simulator takes.

use hyperelastic::{MaterialField, MaterialParameterError, lame_parameters_of};
use rkpm_core::IntegrationPoints;
use skin_eigen::{BasisError, BasisParams, BasisReport, SkinningBasis};
use thiserror::Error;

/// [`build_basis`] could not build the basis.
#[derive(Debug, Error)]
pub enum BasisBuildError {
    /// E or ν is out of range at a point.
    #[error("the material at basis point {point} is invalid")]
    Material {
        /// The point (index into the basis points).
        point: usize,
        /// Why.
        #[source]
        source: MaterialParameterError,
    },
    /// The basis builder failed (a singular moment matrix, m ≥ K, …).
    #[error("building the basis failed")]
    Basis(#[source] BasisError),
}

/// The skinning basis (paper Sec. 3-4: m eigenmodes of K RKPM kernels, `params`) of `points`
/// for `material`, the [`MaterialField`] a [`crate::Simulation`] takes: E and ν sampled at the
/// points give the Lamé parameters of the weight-space Hessian (Eq. 14;
/// [`skin_eigen::build_basis`]); ρ does not enter the basis.
///
/// # Errors
/// [`BasisBuildError::Material`] naming the first point whose E or ν is out of range,
/// [`BasisBuildError::Basis`] from the builder.
pub fn build_basis(
    points: &IntegrationPoints,
    material: &MaterialField,
    params: &BasisParams,
) -> Result<(SkinningBasis, BasisReport), BasisBuildError> {
    let lame = lame_parameters_of(&material.sample(points.positions()))
        .map_err(|(point, source)| BasisBuildError::Material { point, source })?;
    let (basis, report, _) =
        skin_eigen::build_basis(points, &lame, params).map_err(BasisBuildError::Basis)?;
    Ok((basis, report))
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use hyperelastic::MaterialSample;
    use nalgebra::Vector3;
    use rkpm_core::sample_box_grid;

    use super::*;

    fn rubber(poisson_ratio: f64) -> MaterialSample {
        MaterialSample {
            youngs_modulus: 1e6,
            poisson_ratio,
            density: 1000.0,
        }
    }

    #[test]
    fn a_basis_from_the_material_field_is_the_basis_from_its_lame_parameters() {
        let points = sample_box_grid(Vector3::zeros(), Vector3::new(1.0, 0.4, 0.4), 0.1).unwrap();
        let params = BasisParams::default().with_modes(4).with_kernels(40);
        let (basis, _) =
            build_basis(&points, &MaterialField::Uniform(rubber(0.4)), &params).unwrap();
        let lame = vec![rubber(0.4).lame_parameters().unwrap(); points.len()];
        let (direct, _, _) = skin_eigen::build_basis(&points, &lame, &params).unwrap();
        assert_eq!(basis.modes(), 4);
        assert_eq!(basis, direct);
    }

    #[test]
    fn an_invalid_material_somewhere_names_its_first_point() {
        let points = sample_box_grid(Vector3::zeros(), Vector3::new(1.0, 0.4, 0.4), 0.1).unwrap();
        let material = MaterialField::Function(Arc::new(|x: &Vector3<f64>| {
            rubber(if x.x > 0.5 { 0.6 } else { 0.3 })
        }));
        let params = BasisParams::default().with_modes(4).with_kernels(40);
        match build_basis(&points, &material, &params) {
            Err(BasisBuildError::Material { point, .. }) => {
                assert!(points.positions()[point].x > 0.5);
                assert!(points.positions()[..point].iter().all(|x| x.x <= 0.5));
            }
            other => panic!("expected the material error, got {:?}", other.map(|_| ())),
        }
    }
}
