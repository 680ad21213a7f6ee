//! A volumetric term that does not lock: the material's `½ κ (J − γ)²` replaced by its
//! projection onto a small pressure space Q (J-bar / mixed u–p with the pressure eliminated).
//!
//! With pressure functions `q_1 … q_P` given at the elastic quadrature points (weights w_q),
//! `κ_q`, `γ_q` the material's [`VolumetricPart`] there and `J_q = det F_q(z)`:
//!
//! ```text
//! G  = Σ_q w_q κ_q q(X_q) q(X_q)ᵀ                      (P × P, the κ-weighted Gram matrix)
//! r  = Σ_q w_q κ_q q(X_q) (J_q − γ_q)                  (P)
//! p̂  = G⁻¹ r,   p(X) = p̂ · q(X)                        (the projected dilatation Π(J − γ))
//! E  = Σ_q w_q [Ψ(F_q) − ½ κ_q (J_q − γ_q)²]  +  ½ rᵀ G⁻¹ r
//! ∂E/∂z = Σ_q w_q Gᵢᵀ… [P(F_q) + κ_q (p_q − (J_q − γ_q)) cof F_q]          (the stress with p)
//! ∂²E/∂z² = Σ_q (∂F_q/∂z)ᵀ w_q [∂P/∂F − κ_q cof⊗cof + κ_q (p_q − (J_q − γ_q)) ∂²J/∂F²] (∂F_q/∂z)
//!         + (∂r/∂z)ᵀ G⁻¹ (∂r/∂z),    ∂r_b/∂z = Σ_q w_q κ_q q_b(X_q) cof F_q : ∂F_q/∂z
//! ```
//!
//! κ here is the projected part `κ_p = max(0, κ − c μ)` of the material's modulus
//! ([`ProjectedDilatationParams::retained_shear_multiple`]); the rest stays in the pointwise
//! energy. With Q = every function (one per point) this is the pointwise energy again; with a small Q
//! containing the constants the subspace no longer has to keep J ≈ γ pointwise, which is what
//! locks a poor displacement space at ν → 0.5. A point whose pressure values are all 0 (a held
//! region) carries no volumetric energy. The per-point curvature term can be indefinite; the
//! projected tangents project the whole per-point 9 × 9 matrix.
//!
//! An inversion guard: pointwise J can invert while ΠJ stays positive, so each point also
//! carries the barrier `κ_q β(J_q)`, `β(J) = −(J − Ĵ)² ln(J / Ĵ)` for `0 < J < Ĵ` and 0 above
//! ([`INVERSION_BARRIER_START`] = Ĵ; C² at Ĵ, IPC's barrier in J), and any `J_q ≤ 0` makes the
//! energy +∞. The barrier's force grows without bound as a point nears inversion, so Newton
//! is pushed back before the energy jumps (a bare +∞ left steps of colliding objects with
//! nothing but line-search cuts); points with `J ≥ Ĵ` never feel it. Its terms enter as the
//! rest: `κ_q β'(J_q)` in the factor of `cof F` ([`ProjectedDilatation::pressure_shift`]),
//! `κ_q β''(J_q)` in that of `cof⊗cof`.

use faer::linalg::matmul::matmul;
use faer::{Accum, Mat, MatRef, Par};
use hyperelastic::{
    HyperelasticMaterial, LameParameters, Matrix9, Tangent, VolumetricPart, cofactor,
    determinant_hessian,
};
use nalgebra::{DMatrix, DVector, Matrix3, SMatrix};
use rayon::prelude::*;
use thiserror::Error;

use crate::model::deformation_map::POINTS_PER_PART;

/// Ĵ: the volume ratio J below which a point of the projected dilatation feels the inversion
/// barrier `κ β(J)` (module docs): a tenth of its rest volume.
pub const INVERSION_BARRIER_START: f64 = 0.1;

/// `(β(J), β'(J), β''(J))` of the inversion barrier `β(J) = −(J − Ĵ)² ln(J / Ĵ)` for
/// `0 < J < Ĵ`, zeros for `J ≥ Ĵ` (Ĵ = [`INVERSION_BARRIER_START`]). At `J ≤ 0` the energy is
/// +∞ and the derivatives are those at `J = 10⁻⁹ Ĵ`: finite, and the force still points
/// towards larger J (no NaN where a pose inverts a point).
#[allow(non_snake_case)]
pub(crate) fn inversion_barrier(J: f64) -> (f64, f64, f64) {
    let start = INVERSION_BARRIER_START;
    if J >= start {
        return (0.0, 0.0, 0.0);
    }
    if J <= 0.0 {
        let (_, slope, curvature) = inversion_barrier(1e-9 * start);
        return (f64::INFINITY, slope, curvature);
    }
    let (d, log) = (J - start, (J / start).ln());
    (
        -d * d * log,
        -2.0 * d * log - d * d / J,
        -2.0 * log - 4.0 * d / J + d * d / (J * J),
    )
}

/// Whether a force of the projected dilatation includes its inversion barrier.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum InversionBarrier {
    /// The simulated model's force (its energy's gradient).
    Included,
    /// The force a cubature is trained and validated on (module docs).
    LeftOut,
}

/// Options of the projected volumetric term.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ProjectedDilatationParams {
    /// c: the part `min(κ, c μ)` of the volumetric modulus stays pointwise and only
    /// `κ_p = max(0, κ − c μ)` is projected (default 0: all of it). A bounded pointwise part
    /// cannot lock (it is at most c shear moduli), and at a compressible material with
    /// κ ≤ c μ the term is the pointwise one again, with no projection softening it.
    pub retained_shear_multiple: f64,
}

impl Default for ProjectedDilatationParams {
    fn default() -> Self {
        ProjectedDilatationParams {
            retained_shear_multiple: 0.0,
        }
    }
}

/// The projected dilatation could not be set up.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum ProjectedDilatationError {
    /// The material has no volumetric term of the form `½ κ (J − γ)²`.
    #[error("the material `{material}` has no volumetric term to project")]
    NoVolumetricPart {
        /// Its name.
        material: &'static str,
    },
    /// The retained multiple c is negative or not finite.
    #[error("the retained shear multiple must be finite and non-negative, got {value}")]
    RetainedMultiple {
        /// The value given.
        value: f64,
    },
    /// The pressure values do not have one row per integration point.
    #[error("pressure values have {rows} rows for {points} integration points")]
    RowCount {
        /// Rows given.
        rows: usize,
        /// Points of the model.
        points: usize,
    },
    /// No pressure function, or a value that is not finite.
    #[error("the pressure space needs at least one function with finite values")]
    Empty,
    /// The pressure functions are linearly dependent at the elastic points.
    #[error(
        "the pressure functions are linearly dependent at the elastic points (Gram matrix {size}×{size} not positive definite)"
    )]
    DependentFunctions {
        /// P.
        size: usize,
    },
}

/// The pressure space at every integration point of a model, and what the energy needs at its
/// elastic quadrature points.
#[derive(Clone, Debug)]
pub(crate) struct ProjectedDilatation {
    /// q at every model point, N × P.
    pressure: DMatrix<f64>,
    /// The options it was made with.
    params: ProjectedDilatationParams,
    /// q at the elastic points, row-major N_e × P: point q's values at `[q P, (q + 1) P)`.
    elastic_pressure: Vec<f64>,
    /// κ_q, γ_q at the elastic points.
    volumetric: Vec<VolumetricPart>,
    /// w_q κ_q at the elastic points.
    weighted_modulus: Vec<f64>,
    /// G (P × P).
    gram: DMatrix<f64>,
    /// G⁻¹ (P × P).
    gram_inverse: DMatrix<f64>,
}

/// The term at some deformation gradients: its energy, each point's dilatation and the
/// pressure coefficients p̂, from which [`ProjectedDilatation::pressure_shift`] gives each
/// point's factor of `cof F`.
#[derive(Debug)]
pub(crate) struct DilatationState {
    /// `½ rᵀ G⁻¹ r − Σ_q w_q ½ κ_q (J_q − γ_q)² + Σ_q w_q κ_q β(J_q)` (J); +∞ when some
    /// `J_q ≤ 0`.
    pub energy: f64,
    /// `J_q − γ_q` per elastic point.
    dilatations: Vec<f64>,
    /// `p̂ = G⁻¹ r` (P).
    coefficients: Vec<f64>,
}

impl DilatationState {
    /// `p̂ = G⁻¹ r` (P): the pressure coefficients.
    pub(crate) fn coefficients(&self) -> &[f64] {
        &self.coefficients
    }
}

impl ProjectedDilatation {
    /// The term for pressure values `pressure` (N × P, at every model point) on the elastic
    /// points `elastic_points` (indices into the model's points) with weights `weights` and
    /// Lamé parameters `lame`.
    pub(crate) fn new<M: HyperelasticMaterial>(
        material: &M,
        pressure: DMatrix<f64>,
        params: ProjectedDilatationParams,
        elastic_points: Option<&[usize]>,
        weights: &[f64],
        lame: &[LameParameters],
    ) -> Result<Self, ProjectedDilatationError> {
        let retained = params.retained_shear_multiple;
        if !(retained >= 0.0 && retained.is_finite()) {
            return Err(ProjectedDilatationError::RetainedMultiple { value: retained });
        }
        if pressure.ncols() == 0 || pressure.iter().any(|v| !v.is_finite()) {
            return Err(ProjectedDilatationError::Empty);
        }
        let rows: Vec<usize> = match elastic_points {
            None => (0..pressure.nrows()).collect(),
            Some(points) => points.to_vec(),
        };
        let values = &pressure;
        let elastic_pressure: Vec<f64> = rows
            .iter()
            .flat_map(|&q| (0..values.ncols()).map(move |b| values[(q, b)]))
            .collect();
        let volumetric = lame
            .iter()
            .map(|l| {
                material
                    .volumetric_part(l)
                    .map(|v| VolumetricPart {
                        modulus: (v.modulus - retained * l.mu()).max(0.0),
                        ..v
                    })
                    .ok_or(ProjectedDilatationError::NoVolumetricPart {
                        material: material.name(),
                    })
            })
            .collect::<Result<Vec<_>, _>>()?;
        let weighted_modulus: Vec<f64> = weights
            .iter()
            .zip(&volumetric)
            .map(|(w, v)| w * v.modulus)
            .collect();
        let size = pressure.ncols();
        // G = Qᵀ diag(w κ) Q, one product.
        let q = MatRef::from_row_major_slice(&elastic_pressure, rows.len(), size);
        let weighted_pressure =
            Mat::from_fn(rows.len(), size, |i, b| weighted_modulus[i] * q[(i, b)]);
        let mut product = Mat::<f64>::zeros(size, size);
        matmul(
            product.as_mut(),
            Accum::Replace,
            q.transpose(),
            weighted_pressure.as_ref(),
            1.0,
            Par::Seq,
        );
        let gram = DMatrix::from_fn(size, size, |a, b| product[(a, b)]);
        // All of the modulus kept pointwise: nothing is projected (and G is 0).
        let gram_inverse = if weighted_modulus.iter().all(|&w| w == 0.0) {
            DMatrix::zeros(size, size)
        } else {
            let factor = gram
                .clone()
                .cholesky()
                .ok_or(ProjectedDilatationError::DependentFunctions { size })?;
            // A pivot lost to rounding against its diagonal entry: dependent functions (the
            // product forming G may leave a dependent pair a rounding error from singular).
            let l = factor.l_dirty();
            if (0..size).any(|i| !(l[(i, i)] * l[(i, i)] > 1e-12 * gram[(i, i)])) {
                return Err(ProjectedDilatationError::DependentFunctions { size });
            }
            factor.inverse()
        };
        Ok(ProjectedDilatation {
            pressure,
            params,
            elastic_pressure,
            volumetric,
            weighted_modulus,
            gram,
            gram_inverse,
        })
    }

    /// The options it was made with.
    pub(crate) fn params(&self) -> ProjectedDilatationParams {
        self.params
    }

    /// The pressure values at every model point (N × P).
    pub(crate) fn pressure(&self) -> &DMatrix<f64> {
        &self.pressure
    }

    /// Number P of pressure functions.
    pub(crate) fn functions(&self) -> usize {
        self.pressure.ncols()
    }

    /// The term's state at the elastic points' deformation gradients `f`: r summed over
    /// fixed parts of the points in parallel (one read of each point's pressure values; the
    /// parts of the elastic passes, summed in order, so r does not depend on the number of
    /// threads), then `p̂ = G⁻¹ r`.
    #[allow(non_snake_case)]
    pub(crate) fn state(&self, f: &[Matrix3<f64>]) -> DilatationState {
        let size = self.functions();
        let mut inverted = false;
        let dilatations: Vec<f64> = f
            .iter()
            .zip(&self.volumetric)
            .map(|(f, v)| {
                let J = f.determinant();
                inverted |= J <= 0.0;
                J - v.rest_ratio
            })
            .collect();
        // Per part: r = Σ w κ d q(X) and Σ w κ (d² − 2 β(J)).
        let parts: Vec<(Vec<f64>, f64)> = dilatations
            .par_chunks(POINTS_PER_PART)
            .enumerate()
            .map(|(part, chunk)| {
                let first = part * POINTS_PER_PART;
                let mut r = vec![0.0; size];
                let mut pointwise = 0.0;
                for (k, &d) in chunk.iter().enumerate() {
                    let q = first + k;
                    let wd = self.weighted_modulus[q] * d;
                    let (barrier, _, _) = inversion_barrier(d + self.volumetric[q].rest_ratio);
                    pointwise += wd * d;
                    if barrier > 0.0 {
                        pointwise -= 2.0 * self.weighted_modulus[q] * barrier;
                    }
                    for (r, v) in r.iter_mut().zip(self.pressure_row(q)) {
                        *r += wd * v;
                    }
                }
                (r, pointwise)
            })
            .collect();
        let mut r = DVector::zeros(size);
        let mut pointwise = 0.0;
        for (part, sum) in &parts {
            for (a, b) in r.iter_mut().zip(part) {
                *a += b;
            }
            pointwise += sum;
        }
        let p_hat = &self.gram_inverse * &r;
        let energy = if inverted {
            f64::INFINITY
        } else {
            0.5 * r.dot(&p_hat) - 0.5 * pointwise
        };
        DilatationState {
            energy,
            dilatations,
            coefficients: p_hat.iter().copied().collect(),
        }
    }

    /// `κ_q (p_q − (J_q − γ_q) + β'(J_q))` (Pa) of elastic point q in `state`, with `p_q = p̂ ·
    /// q(X_q)` and β the inversion barrier (0 when `barrier` leaves it out): the factor of
    /// `cof F` in its stress and of `∂²J/∂F²` in its tangent.
    pub(crate) fn pressure_shift(
        &self,
        state: &DilatationState,
        q: usize,
        barrier: InversionBarrier,
    ) -> f64 {
        let dilatation = state.dilatations[q];
        let shift = self.pressure_shift_at(&state.coefficients, q, dilatation);
        match barrier {
            InversionBarrier::LeftOut => shift,
            InversionBarrier::Included => {
                let (_, slope, _) = inversion_barrier(dilatation + self.rest_ratio(q));
                shift + self.volumetric[q].modulus * slope
            }
        }
    }

    /// `κ_q (p_q − (J_q − γ_q))`, [`Self::pressure_shift`] without the inversion barrier, for
    /// given pressure coefficients p̂ (P, e.g. a state of another quadrature of the same
    /// points) and dilatation `J_q − γ_q` of elastic point q: the forces a cubature is trained
    /// on, which leave out the barrier (a guard that acts only near inversion, finite there
    /// only where J > 0).
    pub(crate) fn pressure_shift_at(&self, coefficients: &[f64], q: usize, dilatation: f64) -> f64 {
        let p: f64 = self
            .pressure_row(q)
            .iter()
            .zip(coefficients)
            .map(|(a, b)| a * b)
            .sum();
        self.volumetric[q].modulus * (p - dilatation)
    }

    /// `γ_q`: the rest volume ratio of elastic point q's volumetric term.
    pub(crate) fn rest_ratio(&self, q: usize) -> f64 {
        self.volumetric[q].rest_ratio
    }

    /// `q(X_q)` of elastic point q (P).
    pub(crate) fn pressure_row(&self, q: usize) -> &[f64] {
        let size = self.functions();
        &self.elastic_pressure[q * size..(q + 1) * size]
    }

    /// `q_b(X_q)` at the elastic points (N_e × P).
    pub(crate) fn elastic_pressure(&self) -> MatRef<'_, f64> {
        MatRef::from_row_major_slice(
            &self.elastic_pressure,
            self.weighted_modulus.len(),
            self.functions(),
        )
    }

    /// `w_q κ_q` of elastic point q (N·m⁻² · m³): its weight in `r` and `∂r/∂z`.
    pub(crate) fn weighted_modulus(&self, q: usize) -> f64 {
        self.weighted_modulus[q]
    }

    /// G.
    pub(crate) fn gram(&self) -> &DMatrix<f64> {
        &self.gram
    }

    /// G⁻¹.
    pub(crate) fn gram_inverse(&self) -> &DMatrix<f64> {
        &self.gram_inverse
    }

    /// The stress `P(F) + shift · cof F` of an elastic point whose material stress is `stress`.
    pub(crate) fn shifted_stress(
        stress: Matrix3<f64>,
        f: &Matrix3<f64>,
        shift: f64,
    ) -> Matrix3<f64> {
        stress + cofactor(f) * shift
    }

    /// The stress `P(F) + κ_q (p̂ · q(X_q) − (J − γ_q)) cof F` (no inversion barrier, as
    /// [`Self::pressure_shift_at`]) of elastic point q at
    /// deformation `f` for the pressure coefficients p̂ (P, e.g. a pose's of
    /// [`ReducedModel::elastic_gradients`]), its material stress being `stress`.
    ///
    /// [`ReducedModel::elastic_gradients`]: crate::ReducedModel::elastic_gradients
    pub(crate) fn stress_at(
        &self,
        stress: Matrix3<f64>,
        f: &Matrix3<f64>,
        coefficients: &[f64],
        q: usize,
    ) -> Matrix3<f64> {
        let dilatation = f.determinant() - self.rest_ratio(q);
        Self::shifted_stress(
            stress,
            f,
            self.pressure_shift_at(coefficients, q, dilatation),
        )
    }

    /// The tangent of an elastic point: `∂P/∂F − κ cof⊗cof + shift · ∂²J/∂F²` from the exact
    /// material tangent `exact`, then treated as `tangent` asks (projected or mirrored as a
    /// whole).
    pub(crate) fn shifted_tangent(
        exact: &Matrix9,
        f: &Matrix3<f64>,
        modulus: f64,
        shift: f64,
        tangent: Tangent,
    ) -> Matrix9 {
        let c = cofactor(f);
        let c: SMatrix<f64, 9, 1> = SMatrix::from_column_slice(c.as_slice());
        let d = exact - c * c.transpose() * modulus + determinant_hessian(f) * shift;
        match tangent {
            Tangent::Exact => d,
            Tangent::ProjectedPsd => hyperelastic::psd_projection::project_to_psd(&d),
            Tangent::AbsoluteEigenvalues => hyperelastic::psd_projection::absolute_eigenvalues(&d),
        }
    }

    /// `κ_q (1 − β''(J))` of elastic point q at volume ratio `J`: minus the factor of
    /// `cof⊗cof` in its tangent (the pointwise volumetric curvature taken out, the inversion
    /// barrier's put in).
    #[allow(non_snake_case)]
    pub(crate) fn cofactor_modulus(&self, q: usize, J: f64) -> f64 {
        let (_, _, curvature) = inversion_barrier(J);
        self.volumetric[q].modulus * (1.0 - curvature)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_inversion_barriers_derivatives_match_central_differences_and_vanish_at_its_start() {
        let h = 1e-7;
        for j in [0.003, 0.02, 0.05, 0.08, 0.099] {
            let (b, slope, curvature) = inversion_barrier(j);
            assert!(b > 0.0 && slope < 0.0 && curvature > 0.0, "J = {j}");
            let fd_slope = (inversion_barrier(j + h).0 - inversion_barrier(j - h).0) / (2.0 * h);
            let fd_curvature =
                (inversion_barrier(j + h).1 - inversion_barrier(j - h).1) / (2.0 * h);
            assert!((slope - fd_slope).abs() <= 1e-6 * slope.abs(), "β' at {j}");
            assert!(
                (curvature - fd_curvature).abs() <= 1e-6 * curvature.abs(),
                "β'' at {j}"
            );
        }
        // C² at Ĵ: all three tend to 0 from below, and are 0 above.
        let below = inversion_barrier(INVERSION_BARRIER_START * (1.0 - 1e-6));
        assert!(below.0.abs() < 1e-16 && below.1.abs() < 1e-10 && below.2.abs() < 1e-4);
        assert_eq!(inversion_barrier(INVERSION_BARRIER_START), (0.0, 0.0, 0.0));
        assert_eq!(inversion_barrier(1.0), (0.0, 0.0, 0.0));
        // Unbounded towards inversion, infinite past it.
        assert!(inversion_barrier(1e-12).1 < -1e9);
        let (energy, slope, curvature) = inversion_barrier(-0.5);
        assert_eq!(inversion_barrier(0.0).0, f64::INFINITY);
        assert_eq!(energy, f64::INFINITY);
        assert!(slope.is_finite() && slope < 0.0 && curvature.is_finite());
    }
}
