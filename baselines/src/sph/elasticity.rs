//! The corotated elastic energy of the SPH solid, split as Kugelstadt et al. 2021 split it
//! (Sec. 4–5): a stretching part and a volume part for given rotations R_i, and the
//! zero-energy-mode (hourglass) term. Each energy comes with its exact gradient, which the
//! step's right-hand sides use.

use hyperelastic::{LameParameters, polar_rotation};
use nalgebra::{Matrix3, Vector3};
use rayon::prelude::*;

use crate::sph::conjugate_gradients::conjugate_gradients;
use crate::sph::corrected_gradients::CorrectedGradients;
use crate::sph::cubic_spline::CubicSplineKernel;
use crate::sph::simulator::SphError;

/// Particle volumes, Lamé parameters, corrected gradients and hourglass stiffnesses of one
/// SPH solid.
///
/// With F_i = Σ_j (x_j − x_i) ỹ_ijᵀ ([`CorrectedGradients`]):
///
/// ```text
/// E_s(x; R) = Σ_i V_i μ_i ‖F_i − R_i‖²                          (stretching)
/// E_v(x; R) = Σ_i V_i λ_i/2 (tr(R_iᵀ F_i) − 3)²                 (volume, linearized)
/// E_h(x)    = ½ Σ_i Σ_{j ∈ N(i)} c_ij ‖(x_j − x_i) − F_i (X_j − X_i)‖²,
///             c_ij = α μ_i V_i V_j W(X_i − X_j) / ‖X_i − X_j‖²   (zero-energy modes)
/// ```
///
/// With R_i the polar rotation of F_i, E_s + E_v is the corotated energy linearized in the
/// volume term (the paper's model); E_h penalizes the part of the motion within a
/// neighbourhood that F_i does not see (hourglass modes), and is zero for every affine motion.
#[derive(Clone, Debug)]
pub struct SphElasticity {
    gradients: CorrectedGradients,
    rest: Vec<Vector3<f64>>,
    volumes: Vec<f64>,
    lame: Vec<LameParameters>,
    hourglass: Vec<f64>,
}

impl SphElasticity {
    /// The solid of particles at `rest` (m) with `volumes` (m³) and one Lamé pair per
    /// particle, with corrected gradients `gradients` (of `kernel`) and zero-energy-mode
    /// coefficient `alpha` (dimensionless; 0 turns the term off).
    pub fn new(
        gradients: CorrectedGradients,
        rest: &[Vector3<f64>],
        volumes: &[f64],
        lame: &[LameParameters],
        kernel: &CubicSplineKernel,
        alpha: f64,
    ) -> Self {
        let hourglass: Vec<f64> = (0..rest.len())
            .into_par_iter()
            .flat_map_iter(|i| {
                let gradients = &gradients;
                gradients.entries(i).map(move |e| {
                    let j = gradients.neighbour(e);
                    let r = rest[i] - rest[j];
                    alpha * lame[i].mu() * volumes[i] * volumes[j] * kernel.value(&r)
                        / r.norm_squared()
                })
            })
            .collect();
        SphElasticity {
            gradients,
            rest: rest.to_vec(),
            volumes: volumes.to_vec(),
            lame: lame.to_vec(),
            hourglass,
        }
    }

    /// The neighbourhoods and corrected gradients.
    pub fn gradients(&self) -> &CorrectedGradients {
        &self.gradients
    }

    /// Rest positions (m).
    pub fn rest_positions(&self) -> &[Vector3<f64>] {
        &self.rest
    }

    /// Particle volumes V_i (m³).
    pub fn volumes(&self) -> &[f64] {
        &self.volumes
    }

    /// Lamé parameters per particle.
    pub fn lame(&self) -> &[LameParameters] {
        &self.lame
    }

    /// c_ij of entry e (J/m²... N/m: the stiffness of the pair's hourglass error).
    pub fn hourglass_stiffness(&self, e: usize) -> f64 {
        self.hourglass[e]
    }

    /// F_i at positions `x` (m), every particle.
    pub fn deformation_gradients(&self, x: &[Vector3<f64>]) -> Vec<Matrix3<f64>> {
        self.gradients.field_gradients(x)
    }

    /// The polar rotations R_i of the deformation gradients at `x`.
    pub fn rotations(&self, x: &[Vector3<f64>]) -> Vec<Matrix3<f64>> {
        self.deformation_gradients(x)
            .par_iter()
            .map(polar_rotation)
            .collect()
    }

    /// E_s(x; R) (J).
    pub fn stretching_energy(&self, x: &[Vector3<f64>], rotations: &[Matrix3<f64>]) -> f64 {
        (0..x.len())
            .into_par_iter()
            .map(|i| {
                let f = self.gradients.field_gradient(i, x);
                self.volumes[i] * self.lame[i].mu() * (f - rotations[i]).norm_squared()
            })
            .sum()
    }

    /// ∇E_s(x; R), per particle (N): the scatter of 2 μ_i V_i (F_i − R_i).
    pub fn stretching_gradient(
        &self,
        x: &[Vector3<f64>],
        rotations: &[Matrix3<f64>],
    ) -> Vec<Vector3<f64>> {
        let p: Vec<Matrix3<f64>> = (0..x.len())
            .into_par_iter()
            .map(|i| {
                let f = self.gradients.field_gradient(i, x);
                (f - rotations[i]) * (2.0 * self.lame[i].mu() * self.volumes[i])
            })
            .collect();
        self.gradients.stress_divergence(&p)
    }

    /// The volume strains tr(R_iᵀ G_i) − `offset` of the particle field `u` (G_i its gradient):
    /// with u = x and offset 3 the strains s_i of E_v; with u = v and offset 0 their rate.
    pub fn volume_strains(
        &self,
        u: &[Vector3<f64>],
        rotations: &[Matrix3<f64>],
        offset: f64,
    ) -> Vec<f64> {
        (0..u.len())
            .into_par_iter()
            .map(|i| {
                let g = self.gradients.field_gradient(i, u);
                rotations[i].component_mul(&g).sum() - offset
            })
            .collect()
    }

    /// E_v(x; R) (J).
    pub fn volume_energy(&self, x: &[Vector3<f64>], rotations: &[Matrix3<f64>]) -> f64 {
        let s = self.volume_strains(x, rotations, 3.0);
        (0..x.len())
            .map(|i| 0.5 * self.volumes[i] * self.lame[i].lambda() * s[i] * s[i])
            .sum()
    }

    /// The scatter of the volume stresses λ_i V_i s_i R_i for per-particle strains `s`:
    /// ∇E_v(x; R) when s are the strains at x.
    pub fn volume_divergence(&self, s: &[f64], rotations: &[Matrix3<f64>]) -> Vec<Vector3<f64>> {
        let p: Vec<Matrix3<f64>> = (0..s.len())
            .into_par_iter()
            .map(|i| rotations[i] * (self.lame[i].lambda() * self.volumes[i] * s[i]))
            .collect();
        self.gradients.stress_divergence(&p)
    }

    /// The Hessian ∇²E_v for `rotations`, as an operator.
    pub fn volume_hessian(&self, rotations: &[Matrix3<f64>]) -> VolumeHessian<'_> {
        VolumeHessian::new(self, rotations)
    }

    /// ∇E_v(x; R), per particle (N).
    pub fn volume_gradient(
        &self,
        x: &[Vector3<f64>],
        rotations: &[Matrix3<f64>],
    ) -> Vec<Vector3<f64>> {
        self.volume_divergence(&self.volume_strains(x, rotations, 3.0), rotations)
    }

    /// The hourglass errors e_ij = (x_j − x_i) − F_i (X_j − X_i) of every entry (m).
    pub fn hourglass_errors(&self, x: &[Vector3<f64>]) -> Vec<Vector3<f64>> {
        let g = &self.gradients;
        (0..x.len())
            .into_par_iter()
            .flat_map_iter(|i| {
                let f = g.field_gradient(i, x);
                g.entries(i).map(move |e| {
                    let j = g.neighbour(e);
                    (x[j] - x[i]) - f * (self.rest[j] - self.rest[i])
                })
            })
            .collect()
    }

    /// E_h(x) (J).
    pub fn hourglass_energy(&self, x: &[Vector3<f64>]) -> f64 {
        self.hourglass_errors(x)
            .iter()
            .zip(&self.hourglass)
            .map(|(e, c)| 0.5 * c * e.norm_squared())
            .sum()
    }

    /// ∇E_h(x), per particle (N): with w_ij = c_ij e_ij and Q_i = Σ_j w_ij (X_j − X_i)ᵀ, the
    /// pair scatter of w minus the stress scatter of Q.
    pub fn hourglass_gradient(&self, x: &[Vector3<f64>]) -> Vec<Vector3<f64>> {
        let g = &self.gradients;
        let w: Vec<Vector3<f64>> = self
            .hourglass_errors(x)
            .into_iter()
            .zip(&self.hourglass)
            .map(|(e, c)| *c * e)
            .collect();
        let q: Vec<Matrix3<f64>> = (0..x.len())
            .into_par_iter()
            .map(|i| {
                let mut q = Matrix3::zeros();
                for e in g.entries(i) {
                    q -= w[e] * (self.rest[g.neighbour(e)] - self.rest[i]).transpose();
                }
                q
            })
            .collect();
        let pairs = g.pair_divergence(&w);
        let stresses = g.stress_divergence(&q);
        pairs.iter().zip(&stresses).map(|(a, b)| a + b).collect()
    }

    /// The small-strain limit of the corotated energy (rotations R ≈ I + skew dropped):
    /// E_lin(x) = Σ_i V_i [μ_i ‖sym F_i − I‖² + λ_i/2 tr(F_i − I)²] + E_h(x) (J). The static
    /// solution of a small load on this energy is what the SPH discretization converges to,
    /// whatever the time stepping.
    pub fn small_strain_energy(&self, x: &[Vector3<f64>]) -> f64 {
        let elastic: f64 = (0..x.len())
            .into_par_iter()
            .map(|i| {
                let f = self.gradients.field_gradient(i, x);
                let strain = 0.5 * (f + f.transpose()) - Matrix3::identity();
                let l = &self.lame[i];
                self.volumes[i]
                    * (l.mu() * strain.norm_squared() + 0.5 * l.lambda() * strain.trace().powi(2))
            })
            .sum();
        elastic + self.hourglass_energy(x)
    }

    /// ∇E_lin(x), per particle (N): the scatter of V_i [2μ_i (sym F_i − I) + λ_i tr(F_i − I) I]
    /// plus ∇E_h.
    pub fn small_strain_gradient(&self, x: &[Vector3<f64>]) -> Vec<Vector3<f64>> {
        let p: Vec<Matrix3<f64>> = (0..x.len())
            .into_par_iter()
            .map(|i| {
                let f = self.gradients.field_gradient(i, x);
                let strain = 0.5 * (f + f.transpose()) - Matrix3::identity();
                let l = &self.lame[i];
                (2.0 * l.mu() * strain + l.lambda() * strain.trace() * Matrix3::identity())
                    * self.volumes[i]
            })
            .collect();
        let s = self.gradients.stress_divergence(&p);
        let h = self.hourglass_gradient(x);
        s.iter().zip(&h).map(|(a, b)| a + b).collect()
    }

    /// The static displacement u (m) of the small-strain energy under `forces` (N per
    /// particle) with the particles not flagged in `free` held at rest: K u = f on the free
    /// particles, K = ∇²E_lin applied through [`SphElasticity::small_strain_gradient`], by
    /// conjugate gradients until ‖f − K u‖ ≤ `tolerance` ‖f‖.
    ///
    /// # Errors
    /// [`SphError::StaticSolveNotConverged`] after `max_iterations` iterations.
    pub fn small_strain_static(
        &self,
        free: &[bool],
        forces: &[Vector3<f64>],
        tolerance: f64,
        max_iterations: usize,
    ) -> Result<Vec<Vector3<f64>>, SphError> {
        let rest = &self.rest;
        let apply = |u: &[Vector3<f64>]| {
            let x: Vec<Vector3<f64>> = rest.iter().zip(u).map(|(x, u)| x + u).collect();
            self.small_strain_gradient(&x)
        };
        let start = vec![Vector3::zeros(); rest.len()];
        conjugate_gradients(apply, forces, start, None, free, tolerance, max_iterations)
            .map(|(u, _)| u)
            .map_err(|e| SphError::StaticSolveNotConverged {
                iterations: e.iterations,
                residual: e.residual,
            })
    }

    /// The corotated elastic force −∇(E_s + E_v + E_h) at `x` with R_i the polar rotations of
    /// F_i(x) (N per particle): zero for every rigid motion.
    pub fn elastic_forces(&self, x: &[Vector3<f64>]) -> Vec<Vector3<f64>> {
        let rotations = self.rotations(x);
        let s = self.stretching_gradient(x, &rotations);
        let v = self.volume_gradient(x, &rotations);
        let h = self.hourglass_gradient(x);
        (0..x.len()).map(|i| -(s[i] + v[i] + h[i])).collect()
    }

    /// Root-mean-square hourglass error over all entries (m): how far particles within a
    /// neighbourhood are from the neighbourhood's affine motion.
    pub fn hourglass_measure(&self, x: &[Vector3<f64>]) -> f64 {
        let errors = self.hourglass_errors(x);
        let total: f64 = errors.iter().map(|e| e.norm_squared()).sum();
        (total / errors.len().max(1) as f64).sqrt()
    }
}

/// The Hessian of E_v for frozen rotations, ∇²E_v u = Gᵀ Λ G u with (G u)_i = Σ_j (u_j − u_i) ·
/// r_ij, r_ij = R_i ỹ_ij and Λ = diag(λ_i V_i): what [`SphElasticity::volume_divergence`] of
/// [`SphElasticity::volume_strains`] (offset 0) computes, with the r_ij formed once for many
/// products (the volume solve's conjugate gradients). Built by
/// [`SphElasticity::volume_hessian`].
pub struct VolumeHessian<'a> {
    gradients: &'a CorrectedGradients,
    rotated: Vec<Vector3<f64>>,
    own: Vec<Vector3<f64>>,
    stiffness: Vec<f64>,
}

impl<'a> VolumeHessian<'a> {
    fn new(elasticity: &'a SphElasticity, rotations: &[Matrix3<f64>]) -> Self {
        let g = elasticity.gradients();
        let n = g.len();
        let rotated: Vec<Vector3<f64>> = (0..n)
            .into_par_iter()
            .flat_map_iter(|i| g.weights(i).iter().map(move |w| rotations[i] * w))
            .collect();
        let own: Vec<Vector3<f64>> = (0..n)
            .into_par_iter()
            .map(|i| g.entries(i).map(|e| rotated[e]).sum())
            .collect();
        let stiffness = (0..n)
            .map(|i| elasticity.lame()[i].lambda() * elasticity.volumes()[i])
            .collect();
        VolumeHessian {
            gradients: g,
            rotated,
            own,
            stiffness,
        }
    }

    /// Gᵀ Λ G u (N per particle for u in m; N/s for u in m/s).
    pub fn apply(&self, u: &[Vector3<f64>]) -> Vec<Vector3<f64>> {
        let g = self.gradients;
        let stress: Vec<f64> = (0..u.len())
            .into_par_iter()
            .map(|i| {
                let rate: f64 = g
                    .entries(i)
                    .map(|e| u[g.neighbour(e)].dot(&self.rotated[e]))
                    .sum();
                self.stiffness[i] * (rate - u[i].dot(&self.own[i]))
            })
            .collect();
        (0..u.len())
            .into_par_iter()
            .map(|k| {
                let mut f = -stress[k] * self.own[k];
                for e in g.entries(k) {
                    f += stress[g.neighbour(e)] * self.rotated[g.reverse(e)];
                }
                f
            })
            .collect()
    }

    /// The diagonal of Gᵀ Λ G per coordinate (N/m).
    pub fn diagonal(&self) -> Vec<Vector3<f64>> {
        let g = self.gradients;
        (0..g.len())
            .into_par_iter()
            .map(|k| {
                let mut d = self.stiffness[k] * self.own[k].component_mul(&self.own[k]);
                for e in g.entries(k) {
                    let a = self.rotated[g.reverse(e)];
                    d += self.stiffness[g.neighbour(e)] * a.component_mul(&a);
                }
                d
            })
            .collect()
    }
}
