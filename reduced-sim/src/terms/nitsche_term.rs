//! Symmetric Nitsche coupling of an interface of the body to prescribed positions: the held
//! part of an object left out of the body, and its boundary with the free part held weakly but
//! consistently, with a stabilization chosen from the reduced space instead of a user's factor.
//!
//! ```text
//! E_N(z, t) = Σ_s a_s [ −(x_s(z) − g_s(t)) · P(F_s(z)) N_s  +  β/2 |x_s(z) − g_s(t)|² ]
//! ```
//!
//! over interface samples s (rest positions X_s, areas a_s in m², unit normals N_s pointing out
//! of the simulated body), with targets g_s(t) ([`PinTarget`]), P the material's first
//! Piola-Kirchhoff stress (Pa) and β the stabilization (Pa/m). Added to the body's elastic
//! energy, the first term cancels the traction the body's own weak form leaves on the interface
//! (the method is consistent: a solution that meets its targets meets its equations, unlike a
//! penalty, which pulls with `β(x − g)` and no traction); the second makes the sum coercive when
//! `β ≥ 2C`, with C the largest ratio of the squared rest traction on the interface to the rest
//! elastic energy over the reduced space:
//!
//! ```text
//! C = λ_max( Σ_s a_s T_sᵀ T_s ,  K₀ )  on range(K₀),   β = 2 s C   (s: NitscheParams)
//! ```
//!
//! (T_s the 3 × 12(m+1) rest traction operator at sample s, K₀ the body's rest elastic Hessian).
//! On a body with a projected dilatation ([`NitscheInterface::on_model`]) P is the body's
//! projected stress at the samples (`nitsche_pressure.rs`), whose pressure depends on z through
//! the whole body.
//! Nitsche, 1971; as an energy for hyperelasticity and with β from a generalized eigenvalue
//! bound as in Griebel and Schweitzer's particle-partition of unity method; design notes in
//! `docs/design.md` §6.2.

use faer::{Mat, MatRef};
use hyperelastic::{HyperelasticMaterial, LameParameters, Matrix9, Tangent};
use nalgebra::DMatrix;
use nalgebra::{Matrix3, Vector3};
use rayon::prelude::*;
use skin_eigen::largest_eigenvalue_on_range;

use crate::model::deformation_map::DeformationMap;
use crate::model::reduced_model::ReducedModel;
use crate::model::skinning_field::SkinningField;
use crate::scene::PinTarget;
use crate::terms::nitsche_params::{NitscheError, NitscheParams, NitscheReport};
use crate::terms::nitsche_pressure::{InterfacePressure, PressureState};
use crate::terms::step_term::{StepTerm, TermPoint};

/// The term [`E_N`](self) of one interface: its samples' map, areas, normals, material and
/// targets, and β.
pub struct NitscheInterface<M> {
    map: DeformationMap,
    areas: Vec<f64>,
    normals: Vec<Vector3<f64>>,
    lame: LameParameters,
    material: M,
    target: PinTarget,
    stabilization: f64,
    /// The body's projected pressure, when it has one.
    pressure: Option<InterfacePressure>,
}

/// A sample's state at z: the gap `d = x − g` (m), F, the stress (the body's) and with a
/// projected pressure its shift `κ (p − (J − γ))` (Pa).
struct SampleState {
    gap: Vector3<f64>,
    f: Matrix3<f64>,
    stress: Matrix3<f64>,
    shift: f64,
}

impl<M: HyperelasticMaterial> NitscheInterface<M> {
    /// The interface at rest positions `samples` (m) with areas `areas` (m²) and outward unit
    /// normals `normals` of the simulated body, on `basis`, of a body of `material` with
    /// `lame`, held at `target`; β from `rest_stiffness`, the body's rest elastic Hessian K₀
    /// (12(m+1) square, J; e.g. [`crate::ReducedModel::elastic_hessian`] at z = 0).
    ///
    /// # Errors
    /// [`NitscheError`] for empty or mismatched samples, a bad area or normal, a bad factor, a
    /// stiffness of the wrong size or with no positive eigenvalue, or a basis that cannot be
    /// evaluated at the samples.
    #[allow(clippy::too_many_arguments)]
    pub fn new<B: SkinningField + ?Sized>(
        basis: &B,
        samples: &[Vector3<f64>],
        areas: &[f64],
        normals: &[Vector3<f64>],
        material: M,
        lame: LameParameters,
        target: PinTarget,
        rest_stiffness: MatRef<'_, f64>,
        params: &NitscheParams,
    ) -> Result<(Self, NitscheReport), NitscheError> {
        let map = checked_map(basis, samples, areas, normals, params)?;
        NitscheInterface::build(
            map,
            areas,
            normals,
            material,
            lame,
            target,
            None,
            rest_stiffness,
            params.stabilization_factor,
        )
    }

    /// The interface of [`NitscheInterface::new`] on a body `model` (its material, and K₀ its
    /// rest elastic Hessian), with the traction of the body's projected stress when the model
    /// has a projected dilatation: `pressure_values` are then the pressure functions at the
    /// samples (S × P, the same space the model was given, e.g. `PressureSpace::values`).
    ///
    /// # Errors
    /// As [`NitscheInterface::new`], and [`NitscheError::PressureValues`] for values missing on
    /// a model with a projected dilatation, given to one without, or of the wrong shape.
    #[allow(clippy::too_many_arguments)]
    pub fn on_model<B: SkinningField + ?Sized>(
        basis: &B,
        model: &ReducedModel<M>,
        samples: &[Vector3<f64>],
        areas: &[f64],
        normals: &[Vector3<f64>],
        lame: LameParameters,
        target: PinTarget,
        pressure_values: Option<&DMatrix<f64>>,
        params: &NitscheParams,
    ) -> Result<(Self, NitscheReport), NitscheError>
    where
        M: Clone,
    {
        let pressure = match (model.dilatation(), pressure_values) {
            (None, None) => None,
            (Some(_), Some(values)) if values.nrows() == samples.len() => {
                Some(InterfacePressure::new(model, values, &lame)?)
            }
            (dilatation, values) => {
                return Err(NitscheError::PressureValues {
                    rows: values.map_or(0, |v| v.nrows()),
                    functions: values.map_or(0, |v| v.ncols()),
                    expected: dilatation.map_or(0, |d| d.functions()),
                });
            }
        };
        let rest = model.elastic_hessian(
            &vec![0.0; model.deformation_map().layout().len()],
            Tangent::Exact,
        );
        let map = checked_map(basis, samples, areas, normals, params)?;
        NitscheInterface::build(
            map,
            areas,
            normals,
            model.material().clone(),
            lame,
            target,
            pressure,
            rest.as_ref(),
            params.stabilization_factor,
        )
    }

    /// The interface with β from K₀ = `rest_stiffness` (validated inputs).
    #[allow(clippy::too_many_arguments)]
    fn build(
        map: DeformationMap,
        areas: &[f64],
        normals: &[Vector3<f64>],
        material: M,
        lame: LameParameters,
        target: PinTarget,
        pressure: Option<InterfacePressure>,
        rest_stiffness: MatRef<'_, f64>,
        s: f64,
    ) -> Result<(Self, NitscheReport), NitscheError> {
        let len = map.layout().len();
        if rest_stiffness.nrows() != len || rest_stiffness.ncols() != len {
            return Err(NitscheError::StiffnessShape {
                rows: rest_stiffness.nrows(),
                cols: rest_stiffness.ncols(),
                expected: len,
            });
        }
        let mut interface = NitscheInterface {
            map,
            areas: areas.to_vec(),
            normals: normals.to_vec(),
            lame,
            material,
            target,
            stabilization: 0.0,
            pressure,
        };
        let bound = interface.trace_bound(rest_stiffness)?;
        interface.stabilization = 2.0 * s * bound;
        let report = NitscheReport {
            samples: areas.len(),
            area: areas.iter().sum(),
            bound,
            stabilization: interface.stabilization,
        };
        Ok((interface, report))
    }

    /// β (Pa/m).
    pub fn stabilization(&self) -> f64 {
        self.stabilization
    }

    /// The largest distance (m) of an interface sample from its target at `z` and `time`.
    pub fn max_gap(&self, z: &[f64], time: f64) -> f64 {
        let rest = self.map.rest_positions();
        self.map
            .positions(z)
            .iter()
            .zip(rest)
            .map(|(x, x0)| (x - self.target.at(x0, time)).norm())
            .fold(0.0, f64::max)
    }

    /// C of the module docs: the rest traction operators' Gram over K₀ on K₀'s range.
    fn trace_bound(&self, rest_stiffness: MatRef<'_, f64>) -> Result<f64, NitscheError> {
        let len = self.map.layout().len();
        let rest = vec![0.0; len];
        let pressure = self.pressure.as_ref().map(|p| {
            let state = p.state(&rest);
            (p, p.coefficient_jacobian(&state))
        });
        let identity = Matrix3::identity();
        let tangent = self.stress_tangent(&identity, 0.0, Tangent::Exact);
        let mut traction_gram = Mat::<f64>::zeros(len, len);
        for s in 0..self.areas.len() {
            let mut t = self.traction_operator(s, &tangent);
            if let Some((p, jacobian)) = &pressure {
                // + κ N q_sᵀ ∂p̂/∂z (cof I = I).
                let q = p.sample_row(s);
                let n = self.normals[s];
                for col in 0..len {
                    let dp: f64 = q
                        .iter()
                        .enumerate()
                        .map(|(a, v)| v * jacobian[(a, col)])
                        .sum();
                    for i in 0..3 {
                        t[(i, col)] += p.modulus() * n[i] * dp;
                    }
                }
            }
            faer::linalg::matmul::matmul(
                traction_gram.as_mut(),
                faer::Accum::Add,
                t.transpose(),
                t.as_ref(),
                self.areas[s],
                faer::Par::Seq,
            );
        }
        largest_eigenvalue_on_range(traction_gram.as_ref(), rest_stiffness)
            .ok_or(NitscheError::NoStiffness)
    }

    /// `T_s = ∂(P N_s)/∂z` at `tangent` = ∂P/∂F (3 × 12(m+1)).
    fn traction_operator(&self, s: usize, tangent: &Matrix9) -> Mat<f64> {
        let n4 = self.map.layout().block_len();
        let g = self.map.gradient_block(s);
        let w = self.traction_tangent(s, tangent);
        Mat::from_fn(3, 3 * n4, |i, col| {
            let (r, k) = (col / n4, col % n4);
            (0..3).map(|c| w[(i, r + 3 * c)] * g[c * n4 + k]).sum()
        })
    }

    /// `∂(P N_s)_i / ∂vec(F)_q = Σ_j N_j A[i + 3j, q]` (3 × 9).
    fn traction_tangent(&self, s: usize, tangent: &Matrix9) -> nalgebra::SMatrix<f64, 3, 9> {
        let n = self.normals[s];
        nalgebra::SMatrix::<f64, 3, 9>::from_fn(|i, q| {
            (0..3).map(|j| n[j] * tangent[(i + 3 * j, q)]).sum()
        })
    }

    /// `∂P̃/∂F` at F with the projected stress's `shift` (the material's tangent without a
    /// projected pressure), as `tangent` asks (only [`Tangent::Exact`] is used here).
    fn stress_tangent(&self, f: &Matrix3<f64>, shift: f64, tangent: Tangent) -> Matrix9 {
        let exact = self.material.stress_derivative(&self.lame, f);
        match &self.pressure {
            None => exact,
            Some(p) => crate::model::projected_dilatation::ProjectedDilatation::shifted_tangent(
                &exact,
                f,
                p.modulus(),
                shift,
                tangent,
            ),
        }
    }

    /// Every sample's gap, F and stress at `at`, and the body's projection there if any.
    fn states(&self, at: &TermPoint<'_>) -> (Vec<SampleState>, Option<PressureState>) {
        let positions = self.map.positions(at.z);
        let gradients = self.map.deformation_gradients(at.z);
        let rest = self.map.rest_positions();
        let time = at.time;
        let pressure = self.pressure.as_ref().map(|p| p.state(at.z));
        let states = positions
            .par_iter()
            .zip(&gradients)
            .zip(rest)
            .enumerate()
            .map(|(s, ((x, f), x0))| {
                let material = self.material.first_piola_kirchhoff(&self.lame, f);
                let shift = match (&self.pressure, &pressure) {
                    (Some(p), Some(state)) => p.shift(state, s, f),
                    _ => 0.0,
                };
                SampleState {
                    gap: x - self.target.at(x0, time),
                    f: *f,
                    stress: material + hyperelastic::cofactor(f) * shift,
                    shift,
                }
            })
            .collect();
        (states, pressure)
    }
}

impl<M: HyperelasticMaterial> StepTerm for NitscheInterface<M> {
    fn name(&self) -> &str {
        "Nitsche interface"
    }

    fn add_energy(&self, at: &TermPoint<'_>, energy: &mut f64) {
        let beta = self.stabilization;
        *energy += self
            .states(at)
            .0
            .iter()
            .zip(&self.areas)
            .zip(&self.normals)
            .map(|((state, a), n)| {
                a * (-state.gap.dot(&(state.stress * n)) + 0.5 * beta * state.gap.norm_squared())
            })
            .sum::<f64>();
    }

    /// The Hessian's terms proportional to the gap d (they vanish where the targets are met)
    /// are added with [`Tangent::Exact`] only: without a projected pressure the term
    /// `−a J_Fᵀ (∂A/∂F[d Nᵀ]) J_F`, by a central difference of the tangent along `d Nᵀ`; with
    /// one, the whole Hessian is then central differences of the gradient (step 1e-6 in z). The
    /// other tangents leave them out.
    fn add_derivatives(
        &self,
        at: &TermPoint<'_>,
        tangent: Tangent,
        gradient: &mut [f64],
        hessian: Option<&mut Mat<f64>>,
    ) {
        match hessian {
            Some(h) if tangent == Tangent::Exact && self.pressure.is_some() => {
                self.add_differenced_hessian(at, h);
                self.add_gradient_and_tangent(at, gradient, None, false);
            }
            hessian => {
                self.add_gradient_and_tangent(at, gradient, hessian, tangent == Tangent::Exact)
            }
        }
    }
}

impl<M: HyperelasticMaterial> NitscheInterface<M> {
    /// Adds the gradient and, when asked, the Hessian without the gap's terms (with the
    /// tangent's derivative along the gap when `third`; no projected pressure then).
    fn add_gradient_and_tangent(
        &self,
        at: &TermPoint<'_>,
        gradient: &mut [f64],
        mut hessian: Option<&mut Mat<f64>>,
        third: bool,
    ) {
        let n4 = self.map.layout().block_len();
        let beta = self.stabilization;
        let (states, projection) = self.states(at);
        let functions = projection.as_ref().map_or(0, |p| p.coefficients.len());
        // c = Σ_s a κ (cof F N · d) q_s, and U = Σ_s a κ J_xᵀ (cof F N) q_sᵀ (dof × P).
        let mut c = vec![0.0; functions];
        let mut u = Mat::<f64>::zeros(if hessian.is_some() { 3 * n4 } else { 0 }, functions);
        // Per sample, U_s = [b_s, G_s] (n4 × 4) and, per axis pair (r, r'), the 4 × 4 weights
        // W with H_{rr'} = Σ_s U_s W U_sᵀ.
        let mut weights: Vec<[[[f64; 4]; 4]; 9]> = Vec::new();
        for (s, state) in states.iter().enumerate() {
            let a = self.areas[s];
            let n = self.normals[s];
            let b = self.map.position_row(s);
            let g = self.map.gradient_block(s);
            let traction = state.stress * n;
            let a_tensor = self.stress_tangent(&state.f, state.shift, Tangent::Exact);
            // ∂/∂vec(F) of −d·(P̃ N) at fixed pressure is −Ã vec(d Nᵀ) (Ã symmetric).
            let dn = state.gap * n.transpose();
            let dn_vec = nalgebra::SVector::<f64, 9>::from_column_slice(dn.as_slice());
            let stress_like = -(a_tensor * dn_vec);
            let position_force = -traction + beta * state.gap;
            for r in 0..3 {
                let block = &mut gradient[r * n4..(r + 1) * n4];
                for k in 0..n4 {
                    let mut value = position_force[r] * b[k];
                    for c in 0..3 {
                        value += stress_like[r + 3 * c] * g[c * n4 + k];
                    }
                    block[k] += a * value;
                }
            }
            let pressure = self.pressure.as_ref().map(|p| {
                let cn = hyperelastic::cofactor(&state.f) * n;
                (p.sample_row(s), a * p.modulus() * cn)
            });
            if let Some((q, scaled)) = &pressure {
                let along = scaled.dot(&state.gap);
                c.iter_mut().zip(*q).for_each(|(c, q)| *c += along * q);
            }
            if hessian.is_none() {
                continue;
            }
            if let Some((q, scaled)) = &pressure {
                for r in 0..3 {
                    for k in 0..n4 {
                        for (col, q) in q.iter().enumerate() {
                            u[(r * n4 + k, col)] += scaled[r] * b[k] * q;
                        }
                    }
                }
            }
            let cross = self.traction_tangent(s, &a_tensor);
            let third = (third && dn.norm() > 0.0).then(|| self.tangent_derivative(&state.f, &dn));
            let mut sample_weights = [[[0.0; 4]; 4]; 9];
            for r in 0..3 {
                for rr in 0..3 {
                    let w = &mut sample_weights[3 * r + rr];
                    if r == rr {
                        w[0][0] = a * beta;
                    }
                    for c in 0..3 {
                        w[0][1 + c] -= a * cross[(r, rr + 3 * c)];
                        w[1 + c][0] -= a * cross[(rr, r + 3 * c)];
                        if let Some(third) = &third {
                            for cc in 0..3 {
                                w[1 + c][1 + cc] -= a * third[(r + 3 * c, rr + 3 * cc)];
                            }
                        }
                    }
                }
            }
            weights.push(sample_weights);
        }
        if let Some(h) = hessian.as_deref_mut() {
            add_sample_blocks(h, &self.map, &weights);
        }
        let (Some(p), Some(projection)) = (&self.pressure, &projection) else {
            return;
        };
        // −(∂p̂/∂z)ᵀ c, and −(U ∂p̂/∂z + its transpose).
        let minus_c: Vec<f64> = c.iter().map(|c| -c).collect();
        p.add_pullback(projection, &minus_c, gradient);
        if let Some(h) = hessian {
            let coupling = &u * p.coefficient_jacobian(projection);
            let len = coupling.nrows();
            for j in 0..len {
                for i in 0..len {
                    h[(i, j)] -= coupling[(i, j)] + coupling[(j, i)];
                }
            }
        }
    }

    /// Adds central differences of the gradient (step 1e-6 in every z), symmetrized.
    fn add_differenced_hessian(&self, at: &TermPoint<'_>, h: &mut Mat<f64>) {
        let len = at.z.len();
        let step = 1e-6;
        let columns: Vec<Vec<f64>> = (0..len)
            .map(|k| {
                let gradient_at = |delta: f64| {
                    let mut z = at.z.to_vec();
                    z[k] += delta;
                    let mut g = vec![0.0; len];
                    self.add_gradient_and_tangent(&at.at(&z), &mut g, None, false);
                    g
                };
                let (plus, minus) = (gradient_at(step), gradient_at(-step));
                plus.iter()
                    .zip(&minus)
                    .map(|(p, m)| (p - m) / (2.0 * step))
                    .collect()
            })
            .collect();
        for j in 0..len {
            for i in 0..len {
                h[(i, j)] += 0.5 * (columns[j][i] + columns[i][j]);
            }
        }
    }
}

impl<M: HyperelasticMaterial> NitscheInterface<M> {
    /// `∂A/∂F[E]`, the tangent's derivative along E, by a central difference with `|ΔF| = 1e-5`.
    fn tangent_derivative(&self, f: &Matrix3<f64>, direction: &Matrix3<f64>) -> Matrix9 {
        let step = 1e-5 / direction.norm();
        let plus = self
            .material
            .stress_derivative(&self.lame, &(f + direction * step));
        let minus = self
            .material
            .stress_derivative(&self.lame, &(f - direction * step));
        (plus - minus) / (2.0 * step)
    }
}

/// Adds `Σ_s U_s W_s^{rr'} U_sᵀ` to every `n4` square block (r, r') of `h`, `U_s = [b_s, G_s]`
/// (`n4 × 4`) at the samples of `map` and `weights[s][3r + r']` the 4 × 4 W: per block one
/// product `Y Xᵀ`, X = [U_1 … U_S], Y = [U_1 W_1 … U_S W_S].
fn add_sample_blocks(h: &mut Mat<f64>, map: &DeformationMap, weights: &[[[[f64; 4]; 4]; 9]]) {
    let n4 = map.layout().block_len();
    let samples = weights.len();
    let u = |s: usize, k: usize, p: usize| {
        if p == 0 {
            map.position_row(s)[k]
        } else {
            map.gradient_block(s)[(p - 1) * n4 + k]
        }
    };
    let x = Mat::<f64>::from_fn(n4, 4 * samples, |k, col| u(col / 4, k, col % 4));
    for r in 0..3 {
        for rr in 0..3 {
            let y = Mat::<f64>::from_fn(n4, 4 * samples, |k, col| {
                let (s, q) = (col / 4, col % 4);
                let w = &weights[s][3 * r + rr];
                (0..4).map(|p| x[(k, 4 * s + p)] * w[p][q]).sum()
            });
            faer::linalg::matmul::matmul(
                h.submatrix_mut(r * n4, rr * n4, n4, n4),
                faer::Accum::Add,
                y.as_ref(),
                x.transpose(),
                1.0,
                faer::Par::rayon(0),
            );
        }
    }
}

/// The basis at `samples` once the samples, areas, normals and factor are checked.
fn checked_map<B: SkinningField + ?Sized>(
    basis: &B,
    samples: &[Vector3<f64>],
    areas: &[f64],
    normals: &[Vector3<f64>],
    params: &NitscheParams,
) -> Result<DeformationMap, NitscheError> {
    if samples.is_empty() {
        return Err(NitscheError::NoSamples);
    }
    if areas.len() != samples.len() || normals.len() != samples.len() {
        return Err(NitscheError::LengthMismatch {
            samples: samples.len(),
            areas: areas.len(),
            normals: normals.len(),
        });
    }
    let bad = areas.iter().zip(normals).position(|(a, n)| {
        !(a.is_finite() && *a > 0.0 && n.iter().all(|v| v.is_finite()))
            || (n.norm() - 1.0).abs() > 1e-9
    });
    if let Some(index) = bad {
        return Err(NitscheError::BadSample {
            index,
            area: areas[index],
            normal: normals[index].into(),
        });
    }
    let s = params.stabilization_factor;
    if !(s.is_finite() && s > 0.0) {
        return Err(NitscheError::Params(s));
    }
    Ok(DeformationMap::new(basis, samples)?)
}

#[cfg(test)]
#[path = "nitsche_term_tests.rs"]
mod tests;
