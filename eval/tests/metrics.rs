//! The basis fitting residual on a real basis: zero for motions the basis spans, positive for
//! one it cannot.

use eval::beam_protocol::reduced::build_beam_basis;
use eval::beam_scenario::{BEAM_MAX, BEAM_MIN};
use eval::reduced_settings::ReducedSettings;
use freeform::metrics::basis_fitting_residual;
use nalgebra::{Matrix3, Vector3};
use reduced_sim::DeformationMap;

fn small_basis() -> skin_eigen::SkinningBasis {
    build_beam_basis(&ReducedSettings {
        modes: 4,
        kernels: 60,
        basis_points: 1500,
        ..ReducedSettings::default()
    })
    .unwrap()
    .basis
}

fn probe_points() -> Vec<Vector3<f64>> {
    let e = BEAM_MAX - BEAM_MIN;
    (0..200)
        .map(|i| {
            let f = |k: u32| ((i as f64 + 0.5) * (k as f64).sqrt()).fract();
            BEAM_MIN + Vector3::new(e.x * f(2), e.y * f(3), e.z * f(5))
        })
        .collect()
}

#[test]
fn affine_motions_fit_exactly_and_a_bend_leaves_a_positive_residual() {
    let basis = small_basis();
    let rest = probe_points();
    let map = DeformationMap::new(&basis, &rest).unwrap();
    let a = Matrix3::new(1.1, 0.2, 0.0, -0.1, 0.9, 0.3, 0.0, 0.1, 1.2);
    let t = Vector3::new(0.3, -0.2, 0.5);
    let affine: Vec<Vec<Vector3<f64>>> = (1..4)
        .map(|k| {
            rest.iter()
                .map(|x| x + (a * x + t - x) * k as f64 / 3.0)
                .collect()
        })
        .collect();
    let residual = basis_fitting_residual(&map, &affine, 5.0).unwrap();
    assert!(residual < 1e-10, "affine residual {residual}");

    // A twist with a non-smooth (absolute value) profile is outside any 5-handle LBS span.
    let kinked: Vec<Vec<Vector3<f64>>> = vec![
        rest.iter()
            .map(|x| x + Vector3::new(0.0, 0.3 * (x.x - 2.5).abs() * (x.z - 0.5), 0.0))
            .collect(),
    ];
    let residual = basis_fitting_residual(&map, &kinked, 5.0).unwrap();
    assert!(residual > 1e-4, "kinked residual {residual}");
}

/// Weights `[1, x², 0]`: the last handle's weight vanishes everywhere, as a mode living on a
/// part the reference mesh lacks vanishes on every reference vertex.
struct FieldWithADeadWeight;

impl reduced_sim::SkinningField for FieldWithADeadWeight {
    type Error = std::convert::Infallible;

    fn handles(&self) -> usize {
        3
    }

    fn evaluate(
        &self,
        points: &[Vector3<f64>],
    ) -> Result<skin_eigen::SkinningWeights, Self::Error> {
        let n = points.len();
        let mut w = nalgebra::DMatrix::zeros(n, 3);
        let mut gx = nalgebra::DMatrix::zeros(n, 3);
        for (i, p) in points.iter().enumerate() {
            w[(i, 0)] = 1.0;
            w[(i, 1)] = p.x * p.x;
            gx[(i, 1)] = 2.0 * p.x;
        }
        Ok(skin_eigen::SkinningWeights {
            weights: w,
            gradients: [
                gx,
                nalgebra::DMatrix::zeros(n, 3),
                nalgebra::DMatrix::zeros(n, 3),
            ],
        })
    }
}

#[test]
fn a_weight_that_vanishes_on_every_point_still_fits_affine_motions_exactly() {
    let rest = probe_points();
    let map = DeformationMap::new(&FieldWithADeadWeight, &rest).unwrap();
    let shifted: Vec<Vec<Vector3<f64>>> = vec![
        rest.iter()
            .map(|x| x + Vector3::new(0.1, -0.2, 0.05) + 0.1 * Vector3::new(x.y, 0.0, 0.0))
            .collect(),
    ];
    let residual = basis_fitting_residual(&map, &shifted, 5.0).unwrap();
    assert!(residual < 1e-8, "affine residual {residual}");
    // The x² handle is live: a quadratic stretch fits too, a kinked shear does not.
    let quadratic: Vec<Vec<Vector3<f64>>> = vec![
        rest.iter()
            .map(|x| x + Vector3::new(0.01 * x.x * x.x, 0.0, 0.0))
            .collect(),
    ];
    assert!(basis_fitting_residual(&map, &quadratic, 5.0).unwrap() < 1e-8);
    let kinked: Vec<Vec<Vector3<f64>>> = vec![
        rest.iter()
            .map(|x| x + Vector3::new(0.0, 0.3 * (x.x - 2.5).abs() * (x.z - 0.5), 0.0))
            .collect(),
    ];
    assert!(basis_fitting_residual(&map, &kinked, 5.0).unwrap() > 1e-4);
}
