//! A closed-form skinning field for unit tests: the simulator must not depend on how a basis
//! was made, and exact derivatives make finite-difference checks sharp.

use hyperelastic::MaterialSample;
use std::convert::Infallible;

use hyperelastic::StableNeoHookean;
use nalgebra::{DMatrix, Vector3};
use rkpm_core::{IntegrationPoints, sample_box_grid};
use skin_eigen::SkinningWeights;

use crate::model::reduced_model::ReducedModel;
use crate::model::skinning_field::SkinningField;

/// Weights `[1, x², y z, sin(x + z)]` (m = 3) on any points. (A weight linear in X would make
/// `W^j X̄` linearly dependent on the constant handle's affine terms and the mass singular.)
pub(crate) struct AnalyticField;

impl SkinningField for AnalyticField {
    type Error = Infallible;

    fn handles(&self) -> usize {
        4
    }

    fn evaluate(&self, points: &[Vector3<f64>]) -> Result<SkinningWeights, Infallible> {
        let n = points.len();
        let mut w = DMatrix::zeros(n, 4);
        let mut g = [
            DMatrix::zeros(n, 4),
            DMatrix::zeros(n, 4),
            DMatrix::zeros(n, 4),
        ];
        for (i, p) in points.iter().enumerate() {
            let s = (p.x + p.z).sin();
            let c = (p.x + p.z).cos();
            w[(i, 0)] = 1.0;
            w[(i, 1)] = p.x * p.x;
            w[(i, 2)] = p.y * p.z;
            w[(i, 3)] = s;
            g[0][(i, 1)] = 2.0 * p.x;
            g[1][(i, 2)] = p.z;
            g[2][(i, 2)] = p.y;
            g[0][(i, 3)] = c;
            g[2][(i, 3)] = c;
        }
        Ok(SkinningWeights {
            weights: w,
            gradients: g,
        })
    }
}

/// A 2 × 1 × 1 m block of about 250 grid points, E = 1 MPa, ν = 0.4, ρ = 1000.
pub(crate) fn analytic_model() -> (ReducedModel<StableNeoHookean>, IntegrationPoints) {
    analytic_model_with_spacing(0.2)
}

/// [`analytic_model`] on a grid of `spacing` (m).
pub(crate) fn analytic_model_with_spacing(
    spacing: f64,
) -> (ReducedModel<StableNeoHookean>, IntegrationPoints) {
    let points =
        sample_box_grid(Vector3::zeros(), Vector3::new(2.0, 1.0, 1.0), spacing).expect("valid box");
    let material = MaterialSample {
        youngs_modulus: 1e6,
        poisson_ratio: 0.4,
        density: 1000.0,
    };
    let model = ReducedModel::new(
        &AnalyticField,
        &points,
        &vec![material; points.len()],
        StableNeoHookean,
    )
    .expect("valid model");
    (model, points)
}

/// The constant and the three linear functions at `points` (N × 4): a pressure space for a
/// projected dilatation in tests.
pub(crate) fn affine_pressure(points: &IntegrationPoints) -> DMatrix<f64> {
    DMatrix::from_fn(points.len(), 4, |i, b| match b {
        0 => 1.0,
        _ => points.positions()[i][b - 1],
    })
}

/// A deterministic z of length `len` and moderate amplitude (|F − I| about 0.1 at 0.02).
pub(crate) fn probe_z(len: usize, amplitude: f64) -> Vec<f64> {
    (0..len)
        .map(|i| amplitude * ((i as f64 * 1.37).sin() + 0.3 * (i as f64 * 0.71).cos()))
        .collect()
}
