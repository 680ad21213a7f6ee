//! The body's projected pressure at a Nitsche interface's samples: on a model with a projected
//! dilatation the body's weak form leaves the traction of its projected stress on the
//! interface, `P̃ = P(F) + κ (p − (J − γ)) cof F` with `p = q(X)·p̂(z)`, `p̂ = G⁻¹ r(z)` over the
//! body's elastic points, so the interface's consistency term must use that stress, not the
//! material's pointwise one.
//!
//! ```text
//! r_a(z) = Σ_q w_q κ_q (J_q − γ_q) q_a(X_q),   ∂r/∂z = Σ_q w_q κ_q q(X_q) ⊗ v_q,
//! v_q[r·4(m+1) + k] = Σ_c cof(F_q)_rc G_q[k, c]
//! ```

use faer::{Accum, Mat, MatRef, Par};
use hyperelastic::{HyperelasticMaterial, LameParameters, VolumetricPart};
use nalgebra::{DMatrix, Matrix3};
use rayon::prelude::*;

use crate::model::deformation_map::DeformationMap;
use crate::model::projected_dilatation::ProjectedDilatation;
use crate::model::reduced_model::ReducedModel;
use crate::terms::nitsche_params::NitscheError;

/// The projection over the body's elastic points and the pressure functions at the samples.
pub(crate) struct InterfacePressure {
    dilatation: ProjectedDilatation,
    elastic_map: DeformationMap,
    /// q(X_s), row-major S × P.
    at_samples: Vec<f64>,
    /// κ (projected part) and γ at the samples' material.
    volumetric: VolumetricPart,
}

/// The projection at one z: the pressure coefficients p̂ and the elastic points' F.
pub(crate) struct PressureState {
    pub(crate) coefficients: Vec<f64>,
    gradients: Vec<Matrix3<f64>>,
}

impl InterfacePressure {
    /// The pressure of `model` (which must have a projected dilatation) at samples whose
    /// pressure functions are `values` (S × P) and whose material is `lame`.
    pub(crate) fn new<M: HyperelasticMaterial>(
        model: &ReducedModel<M>,
        values: &DMatrix<f64>,
        lame: &LameParameters,
    ) -> Result<Self, NitscheError> {
        let dilatation = model
            .dilatation()
            .ok_or(NitscheError::PressureValues {
                rows: values.nrows(),
                functions: values.ncols(),
                expected: 0,
            })?
            .clone();
        let functions = dilatation.functions();
        if values.ncols() != functions || values.iter().any(|v| !v.is_finite()) {
            return Err(NitscheError::PressureValues {
                rows: values.nrows(),
                functions: values.ncols(),
                expected: functions,
            });
        }
        let part = model
            .material()
            .volumetric_part(lame)
            .ok_or(NitscheError::PressureValues {
                rows: values.nrows(),
                functions: values.ncols(),
                expected: functions,
            })?;
        let retained = dilatation.params().retained_shear_multiple;
        Ok(InterfacePressure {
            elastic_map: model.elastic_map().clone(),
            at_samples: (0..values.nrows())
                .flat_map(|s| (0..functions).map(move |a| values[(s, a)]))
                .collect(),
            volumetric: VolumetricPart {
                modulus: (part.modulus - retained * lame.mu()).max(0.0),
                ..part
            },
            dilatation,
        })
    }

    /// The projection at `z`.
    pub(crate) fn state(&self, z: &[f64]) -> PressureState {
        let gradients = self.elastic_map.deformation_gradients(z);
        let coefficients = self.dilatation.state(&gradients).coefficients().to_vec();
        PressureState {
            coefficients,
            gradients,
        }
    }

    /// `q(X_s)` (P).
    pub(crate) fn sample_row(&self, s: usize) -> &[f64] {
        let p = self.dilatation.functions();
        &self.at_samples[s * p..(s + 1) * p]
    }

    /// The projected stress's shift at sample s, `κ (p_s − (J − γ))` (Pa), at F `f`.
    pub(crate) fn shift(&self, state: &PressureState, s: usize, f: &Matrix3<f64>) -> f64 {
        let p: f64 = self
            .sample_row(s)
            .iter()
            .zip(&state.coefficients)
            .map(|(a, b)| a * b)
            .sum();
        self.volumetric.modulus * (p - (f.determinant() - self.volumetric.rest_ratio))
    }

    /// κ of the projected part (Pa).
    pub(crate) fn modulus(&self) -> f64 {
        self.volumetric.modulus
    }

    /// Adds `(∂p̂/∂z)ᵀ c = (∂r/∂z)ᵀ G⁻¹ c` to `gradient` (c of length P).
    pub(crate) fn add_pullback(&self, state: &PressureState, c: &[f64], gradient: &mut [f64]) {
        let y = self.dilatation.gram_inverse() * nalgebra::DVector::from_column_slice(c);
        let n4 = self.elastic_map.layout().block_len();
        let sums: Vec<f64> = (0..state.gradients.len())
            .into_par_iter()
            .fold(
                || vec![0.0; 3 * n4],
                |mut sum, q| {
                    let factor = self.dilatation.weighted_modulus(q)
                        * self
                            .dilatation
                            .pressure_row(q)
                            .iter()
                            .zip(y.iter())
                            .map(|(a, b)| a * b)
                            .sum::<f64>();
                    add_cofactor_row(
                        &mut sum,
                        &state.gradients[q],
                        self.elastic_map.gradient_block(q),
                        n4,
                        factor,
                    );
                    sum
                },
            )
            .reduce(
                || vec![0.0; 3 * n4],
                |mut a, b| {
                    a.iter_mut().zip(&b).for_each(|(x, y)| *x += y);
                    a
                },
            );
        gradient.iter_mut().zip(&sums).for_each(|(g, s)| *g += s);
    }

    /// `∂p̂/∂z = G⁻¹ ∂r/∂z` (P × 12(m+1)).
    pub(crate) fn coefficient_jacobian(&self, state: &PressureState) -> Mat<f64> {
        let n4 = self.elastic_map.layout().block_len();
        let points = state.gradients.len();
        let p = self.dilatation.functions();
        // V (N_e × dof, row-major), row q = v_q; Q_w (N_e × P), row q = w κ q(X_q).
        let mut v = vec![0.0; points * 3 * n4];
        v.par_chunks_mut(3 * n4).enumerate().for_each(|(q, row)| {
            add_cofactor_row(
                row,
                &state.gradients[q],
                self.elastic_map.gradient_block(q),
                n4,
                1.0,
            )
        });
        let v = MatRef::from_row_major_slice(&v, points, 3 * n4);
        let weighted = Mat::<f64>::from_fn(points, p, |q, a| {
            self.dilatation.weighted_modulus(q) * self.dilatation.pressure_row(q)[a]
        });
        let mut r = Mat::<f64>::zeros(p, 3 * n4);
        faer::linalg::matmul::matmul(
            r.as_mut(),
            Accum::Replace,
            weighted.transpose(),
            v,
            1.0,
            Par::rayon(0),
        );
        let g_inverse = self.dilatation.gram_inverse();
        let g_inverse = MatRef::from_column_major_slice(g_inverse.as_slice(), p, p);
        g_inverse * &r
    }
}

/// Adds `factor · v` to `row` (length 12(m+1)), `v[r·n4 + k] = Σ_c cof(F)_rc G[k, c]` with G
/// column-major `n4 × 3`.
fn add_cofactor_row(row: &mut [f64], f: &Matrix3<f64>, g: &[f64], n4: usize, factor: f64) {
    if factor == 0.0 {
        return;
    }
    let cof = hyperelastic::cofactor(f);
    for r in 0..3 {
        for k in 0..n4 {
            row[r * n4 + k] += factor * (0..3).map(|c| cof[(r, c)] * g[c * n4 + k]).sum::<f64>();
        }
    }
}
