//! The implicit corotated SPH solid of Kugelstadt et al. 2021 ("Fast Corotated Elastic SPH
//! Solids with Implicit Zero-Energy Mode Control"), as SPlisHSPlasH's
//! `Elasticity_Kugelstadt2021` runs it (design §3.10).
//!
//! One step of length Δt from time t (x, v the particles' positions and velocities):
//! 1. free particles: v ← v + Δt g; particles in a constrained region get the velocity that
//!    lands them on their target, v = (x̂(X, t + Δt) − x)/Δt;
//! 2. stretching (paper Eq. 29): x̃ = x + Δt v, R_i = polar(F_i(x̃)), and
//!    `A Δ = −Δt² ∇(E_s + E_h)(x̃)` with the constant matrix A = M + Δt² ∇²(E_s + E_h)
//!    ([`StretchingSystem`], factored once); v ← v + Δ/Δt. This minimizes
//!    ½‖x − x̃‖²_M + Δt² (E_s + E_h)(x) exactly for the frozen rotations;
//! 3. volume (paper Eq. 30): R_i = polar(F_i(x + Δt v)), then
//!    `(M + Δt² ∇²E_v) v' = M v − Δt ∇E_v(x)` by conjugate gradients (matrix-free, Jacobi
//!    preconditioned, warm-started from v plus the last step's correction, as SPlisHSPlasH does);
//! 4. x ← x + Δt v'; a floor half-space n·x ≥ o puts particles below it back on it and removes
//!    their inward normal velocity.
//!
//! The energies E_s, E_v, E_h are those of [`SphElasticity`]. Constrained particles are left
//! out of both solves (their velocities are known), as SPlisHSPlasH sorts its fixed particles
//! out of the factored system.

use std::time::Instant;

use hyperelastic::MaterialSample;
use nalgebra::{Matrix3, Vector3};
use rayon::prelude::*;
use reduced_sim::{PinnedRegion, Scene};
use rkpm_core::IntegrationPoints;
use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::particle_materials::ParticleMaterials;
use crate::sph::conjugate_gradients::conjugate_gradients;
use crate::sph::corrected_gradients::CorrectedGradients;
use crate::sph::cubic_spline::CubicSplineKernel;
use crate::sph::elasticity::SphElasticity;
use crate::sph::interpolation::ParticleInterpolation;
use crate::sph::rest_volume::RestVolume;
use crate::sph::stretching_system::StretchingSystem;

/// The SPH baseline's options.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct SphParams {
    /// Time step Δt (s). Default 0.01 (the paper's, on the beam).
    pub time_step: f64,
    /// Kernel support radius over the particle spacing (the cube root of the median particle
    /// volume). Default 2 (SPlisHSPlasH: support = 4 particle radii).
    pub support_over_spacing: f64,
    /// Zero-energy-mode coefficient α. Default 0.1 (SPlisHSPlasH's beam scene); 0 turns the
    /// term off.
    pub zero_energy_alpha: f64,
    /// Relative residual ‖b − A v‖ / ‖b‖ at which the volume solve stops. Default 1e-4
    /// (SPlisHSPlasH's). On the beam Bend at 0.1 m spacing, 1e-8 moves the tip at 0.5 s by
    /// 2e-5 m and takes 3× the iterations (`eval/examples/sph_beam.rs`).
    pub volume_tolerance: f64,
    /// Most conjugate-gradient iterations of one volume solve; more stops the run with
    /// [`SphError::VolumeSolveNotConverged`]. Default 1000.
    pub volume_max_iterations: usize,
    /// The volumes the energies are integrated with. Default [`RestVolume::Sampled`].
    #[serde(default)]
    pub rest_volume: RestVolume,
}

impl Default for SphParams {
    fn default() -> Self {
        SphParams {
            time_step: 0.01,
            support_over_spacing: 2.0,
            zero_energy_alpha: 0.1,
            volume_tolerance: 1e-4,
            volume_max_iterations: 1000,
            rest_volume: RestVolume::Sampled,
        }
    }
}

/// Why an SPH run cannot start or continue.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum SphError {
    /// A parameter out of its range.
    #[error("invalid SPH parameter: {0}")]
    InvalidParameter(String),
    /// Particles, materials or scene that cannot be simulated.
    #[error("invalid SPH input: {0}")]
    InvalidInput(String),
    /// A particle whose neighbours do not span three dimensions: its kernel-gradient
    /// correction is singular.
    #[error(
        "SPH particle {particle} has {neighbours} neighbours that do not span 3D (its gradient \
         correction is singular); the body is thinner than the kernel can resolve: use a finer \
         spacing or a larger support"
    )]
    IsolatedParticle {
        /// The particle.
        particle: usize,
        /// Its neighbours within the support.
        neighbours: usize,
    },
    /// The sparse Cholesky factorization of the stretching matrix failed.
    #[error("SPH stretching matrix could not be factored: {0}")]
    Factorization(String),
    /// The volume solve did not reach its tolerance.
    #[error(
        "SPH volume solve at t = {time:.5} s did not converge: relative residual {residual:.2e} \
         after {iterations} iterations"
    )]
    VolumeSolveNotConverged {
        /// Time at the end of the failing step (s).
        time: f64,
        /// Iterations taken.
        iterations: usize,
        /// Relative residual reached.
        residual: f64,
    },
    /// A static solve did not reach its tolerance.
    #[error(
        "SPH static solve did not converge: relative residual {residual:.2e} after {iterations} \
         iterations"
    )]
    StaticSolveNotConverged {
        /// Iterations taken.
        iterations: usize,
        /// Relative residual reached.
        residual: f64,
    },
    /// A position or velocity became NaN or infinite.
    #[error("SPH run went non-finite at t = {time:.5} s (particle {particle})")]
    NonFinite {
        /// Time at the end of the failing step (s).
        time: f64,
        /// The particle.
        particle: usize,
    },
    /// A probe point with too few particles around it (outside the body) or not finite.
    #[error("SPH probe {probe} has too few particles around it to interpolate (outside the body?)")]
    ProbeOutside {
        /// The probe.
        probe: usize,
    },
}

/// Seconds spent in each phase since the simulator was built.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct SphTimings {
    /// Neighbourhoods, corrections and the factorization (s).
    pub setup: f64,
    /// Stretching: rotations, right-hand side and the triangular solves (s).
    pub stretching: f64,
    /// Volume: rotations and the conjugate-gradient solve (s).
    pub volume: f64,
    /// Advection, floor, checks and probes (s).
    pub advection: f64,
    /// Steps taken.
    pub steps: usize,
    /// Conjugate-gradient iterations, all steps together.
    pub volume_iterations: usize,
}

impl SphTimings {
    /// Seconds of the steps (setup left out).
    pub fn stepping(&self) -> f64 {
        self.stretching + self.volume + self.advection
    }
}

/// Probe points moved with the particles (the FEM vertices, for the metrics).
struct Probes {
    interpolation: ParticleInterpolation,
    rest: Vec<Vector3<f64>>,
    regions: Vec<PinnedRegion>,
    positions: Vec<Vector3<f64>>,
}

/// An implicit corotated SPH simulation of one body.
pub struct SphSimulator {
    params: SphParams,
    scene: Scene,
    kernel: CubicSplineKernel,
    elasticity: SphElasticity,
    system: StretchingSystem,
    constrained: Vec<bool>,
    masses: Vec<f64>,
    positions: Vec<Vector3<f64>>,
    velocities: Vec<Vector3<f64>>,
    correction: Vec<Vector3<f64>>,
    probes: Option<Probes>,
    time: f64,
    timings: SphTimings,
}

impl SphSimulator {
    /// Particles at `points` (rest positions and volumes) of `materials` (one per particle, or
    /// one for all) at rest, under `scene` (gravity, pinned or moving particle regions, a
    /// floor; held regions are not supported). Builds the neighbourhoods and factors the
    /// stretching matrix.
    ///
    /// # Errors
    /// [`SphError::InvalidParameter`] for a non-positive Δt, support or tolerance or a
    /// negative α; [`SphError::InvalidInput`] for no particles, mismatched lengths, invalid
    /// materials, non-finite points, a region naming a missing particle, or held regions;
    /// [`SphError::IsolatedParticle`]; [`SphError::Factorization`].
    pub fn new(
        points: &IntegrationPoints,
        materials: &[MaterialSample],
        scene: &Scene,
        params: SphParams,
    ) -> Result<Self, SphError> {
        let start = Instant::now();
        check_params(&params)?;
        let n = points.len();
        if n == 0 {
            return Err(SphError::InvalidInput("no particles".into()));
        }
        if !scene.held.is_empty() {
            return Err(SphError::InvalidInput(
                "held regions are a reduced-simulator concept; give SPH pinned regions".into(),
            ));
        }
        let mut constrained = vec![false; n];
        for (r, region) in scene.pins.iter().enumerate() {
            for &p in &region.points {
                if p >= n {
                    return Err(SphError::InvalidInput(format!(
                        "pinned region {r} names particle {p} of {n}"
                    )));
                }
                constrained[p] = true;
            }
        }
        let rest = points.positions();
        if let Some(i) = rest.iter().position(|x| !x.iter().all(|c| c.is_finite())) {
            return Err(SphError::InvalidInput(format!(
                "particle {i} is not finite"
            )));
        }
        let ParticleMaterials { lame, masses } =
            ParticleMaterials::new(points.volumes(), materials).map_err(SphError::InvalidInput)?;
        let kernel = CubicSplineKernel::new(
            params.support_over_spacing * particle_spacing(points.volumes()),
        );
        let volumes = params
            .rest_volume
            .volumes(rest, &masses, points.volumes(), &kernel);
        let gradients = CorrectedGradients::new(rest, &volumes, &kernel)?;
        let elasticity = SphElasticity::new(
            gradients,
            rest,
            &volumes,
            &lame,
            &kernel,
            params.zero_energy_alpha,
        );
        let system = StretchingSystem::new(&elasticity, &masses, &constrained, params.time_step)?;
        let timings = SphTimings {
            setup: start.elapsed().as_secs_f64(),
            ..SphTimings::default()
        };
        Ok(SphSimulator {
            params,
            scene: scene.clone(),
            kernel,
            elasticity,
            system,
            constrained,
            masses,
            positions: rest.to_vec(),
            velocities: vec![Vector3::zeros(); n],
            correction: vec![Vector3::zeros(); n],
            probes: None,
            time: 0.0,
            timings,
        })
    }

    /// Adds probe points at rest positions `points` (m), moved with the particles by the
    /// linear interpolant of [`ParticleInterpolation`]; probes named by `regions` (indices into
    /// `points`) belong to a constrained region and are put on its target instead.
    ///
    /// # Errors
    /// [`SphError::ProbeOutside`] for a probe outside the body; [`SphError::InvalidInput`] for
    /// a region naming a missing probe or a simulator that already ran or has probes.
    pub fn with_probes(
        mut self,
        points: &[Vector3<f64>],
        regions: &[PinnedRegion],
    ) -> Result<Self, SphError> {
        if self.time > 0.0 || self.probes.is_some() {
            return Err(SphError::InvalidInput(
                "probes must be added once, before the first step".into(),
            ));
        }
        for (r, region) in regions.iter().enumerate() {
            if let Some(&t) = region.points.iter().find(|&&t| t >= points.len()) {
                return Err(SphError::InvalidInput(format!(
                    "probe region {r} names probe {t} of {}",
                    points.len()
                )));
            }
        }
        let interpolation = ParticleInterpolation::new(
            self.elasticity.rest_positions(),
            self.elasticity.volumes(),
            &self.kernel,
            points,
        )?;
        self.probes = Some(Probes {
            interpolation,
            rest: points.to_vec(),
            regions: regions.to_vec(),
            positions: points.to_vec(),
        });
        Ok(self)
    }

    /// Sets every particle's velocity (m/s), e.g. for an initial spin; call before the first
    /// step.
    ///
    /// # Errors
    /// [`SphError::InvalidInput`] for a wrong length or non-finite values.
    pub fn set_velocities(&mut self, velocities: &[Vector3<f64>]) -> Result<(), SphError> {
        if velocities.len() != self.velocities.len() {
            return Err(SphError::InvalidInput(format!(
                "{} velocities for {} particles",
                velocities.len(),
                self.velocities.len()
            )));
        }
        if !velocities.iter().all(|v| v.iter().all(|c| c.is_finite())) {
            return Err(SphError::InvalidInput("non-finite initial velocity".into()));
        }
        self.velocities.copy_from_slice(velocities);
        Ok(())
    }

    /// One step of length Δt (the sequence of the module documentation).
    ///
    /// # Errors
    /// [`SphError::VolumeSolveNotConverged`], [`SphError::NonFinite`]; the state is then that
    /// of the failing step.
    pub fn step(&mut self) -> Result<(), SphError> {
        let dt = self.params.time_step;
        let t_next = self.time + dt;
        let start = Instant::now();
        // 1. Gravity and prescribed velocities.
        let gravity = self.scene.gravity.unwrap_or_else(Vector3::zeros);
        for (v, &c) in self.velocities.iter_mut().zip(&self.constrained) {
            if !c {
                *v += dt * gravity;
            }
        }
        for region in &self.scene.pins {
            for &p in &region.points {
                let target = region
                    .target
                    .at(&self.elasticity.rest_positions()[p], t_next);
                self.velocities[p] = (target - self.positions[p]) / dt;
            }
        }
        // 2. Stretching and zero-energy modes, against the factored matrix.
        let predicted = self.advected(dt);
        let rotations = self.elasticity.rotations(&predicted);
        let stretch = self.elasticity.stretching_gradient(&predicted, &rotations);
        let hourglass = self.elasticity.hourglass_gradient(&predicted);
        let rhs: Vec<Vector3<f64>> = stretch
            .iter()
            .zip(&hourglass)
            .map(|(s, h)| -(dt * dt) * (s + h))
            .collect();
        let delta = self.system.solve(&rhs);
        for (v, d) in self.velocities.iter_mut().zip(&delta) {
            *v += d / dt;
        }
        let stretched = Instant::now();
        // 3. Volume, by conjugate gradients.
        let iterations = self.solve_volume(dt, t_next)?;
        let volumed = Instant::now();
        // 4. Advection and floor.
        self.positions = self.advected(dt);
        if let Some(floor) = &self.scene.floor {
            for (x, v) in self.positions.iter_mut().zip(&mut self.velocities) {
                let depth = floor.offset - floor.normal.dot(x);
                if depth > 0.0 {
                    *x += depth * floor.normal;
                    let vn = floor.normal.dot(v);
                    if vn < 0.0 {
                        *v -= vn * floor.normal;
                    }
                }
            }
        }
        self.time = t_next;
        if let Some(particle) = self
            .positions
            .iter()
            .zip(&self.velocities)
            .position(|(x, v)| !x.iter().chain(v.iter()).all(|c| c.is_finite()))
        {
            return Err(SphError::NonFinite {
                time: self.time,
                particle,
            });
        }
        if let Some(probes) = &mut self.probes {
            probes.positions = probes
                .interpolation
                .positions(self.elasticity.rest_positions(), &self.positions);
            for region in &probes.regions {
                for &t in &region.points {
                    probes.positions[t] = region.target.at(&probes.rest[t], self.time);
                }
            }
        }
        let end = Instant::now();
        let t = &mut self.timings;
        t.stretching += (stretched - start).as_secs_f64();
        t.volume += (volumed - stretched).as_secs_f64();
        t.advection += (end - volumed).as_secs_f64();
        t.steps += 1;
        t.volume_iterations += iterations;
        Ok(())
    }

    /// x + Δt v for every particle.
    fn advected(&self, dt: f64) -> Vec<Vector3<f64>> {
        self.positions
            .par_iter()
            .zip(&self.velocities)
            .map(|(x, v)| x + dt * v)
            .collect()
    }

    /// Step 3: `(M + Δt² ∇²E_v) v' = M v − Δt ∇E_v(x)` over the free particles by
    /// Jacobi-preconditioned conjugate gradients; returns the iterations.
    fn solve_volume(&mut self, dt: f64, t_next: f64) -> Result<usize, SphError> {
        let el = &self.elasticity;
        let n = self.positions.len();
        let rotations = el.rotations(&self.advected(dt));
        let strains = el.volume_strains(&self.positions, &rotations, 3.0);
        let force = el.volume_divergence(&strains, &rotations);
        let hessian = el.volume_hessian(&rotations);
        let apply = |u: &[Vector3<f64>]| -> Vec<Vector3<f64>> {
            let k = hessian.apply(u);
            (0..n)
                .into_par_iter()
                .map(|i| self.masses[i] * u[i] + (dt * dt) * k[i])
                .collect()
        };
        let b: Vec<Vector3<f64>> = (0..n)
            .map(|i| self.masses[i] * self.velocities[i] - dt * force[i])
            .collect();
        let diagonal: Vec<Vector3<f64>> = hessian
            .diagonal()
            .iter()
            .zip(&self.masses)
            .map(|(d, m)| Vector3::repeat(*m) + (dt * dt) * d)
            .collect();
        let free: Vec<bool> = self.constrained.iter().map(|c| !c).collect();
        // Warm start: this step's velocity plus the last volume correction.
        let start: Vec<Vector3<f64>> = (0..n)
            .map(|i| {
                if free[i] {
                    self.velocities[i] + self.correction[i]
                } else {
                    self.velocities[i]
                }
            })
            .collect();
        let (v, iterations) = conjugate_gradients(
            apply,
            &b,
            start,
            Some(&diagonal),
            &free,
            self.params.volume_tolerance,
            self.params.volume_max_iterations,
        )
        .map_err(|e| SphError::VolumeSolveNotConverged {
            time: t_next,
            iterations: e.iterations,
            residual: e.residual,
        })?;
        for i in 0..n {
            if free[i] {
                self.correction[i] = v[i] - self.velocities[i];
            }
        }
        self.velocities = v;
        Ok(iterations)
    }

    /// The largest distance (m) of a particle in a constrained region from its target now.
    pub fn max_pin_deviation(&self) -> f64 {
        let mut worst: f64 = 0.0;
        for region in &self.scene.pins {
            for &p in &region.points {
                let target = region
                    .target
                    .at(&self.elasticity.rest_positions()[p], self.time);
                worst = worst.max((self.positions[p] - target).norm());
            }
        }
        worst
    }

    /// Simulated time (s).
    pub fn time(&self) -> f64 {
        self.time
    }

    /// The options.
    pub fn params(&self) -> &SphParams {
        &self.params
    }

    /// The kernel (its support radius h, m).
    pub fn kernel(&self) -> &CubicSplineKernel {
        &self.kernel
    }

    /// The elastic energies, neighbourhoods and corrected gradients.
    pub fn elasticity(&self) -> &SphElasticity {
        &self.elasticity
    }

    /// Stored entries of the factored matrix's lower triangle.
    pub fn system_nonzeros(&self) -> usize {
        self.system.nonzeros()
    }

    /// Particle positions (m).
    pub fn positions(&self) -> &[Vector3<f64>] {
        &self.positions
    }

    /// Particle rest positions (m).
    pub fn rest_positions(&self) -> &[Vector3<f64>] {
        self.elasticity.rest_positions()
    }

    /// Particle velocities (m/s).
    pub fn velocities(&self) -> &[Vector3<f64>] {
        &self.velocities
    }

    /// Particle masses (kg).
    pub fn masses(&self) -> &[f64] {
        &self.masses
    }

    /// Probe positions (m), in the order given to [`SphSimulator::with_probes`] (empty
    /// without probes).
    pub fn probe_positions(&self) -> &[Vector3<f64>] {
        self.probes.as_ref().map_or(&[], |p| &p.positions)
    }

    /// Seconds per phase and steps so far.
    pub fn timings(&self) -> &SphTimings {
        &self.timings
    }

    /// Total linear momentum Σ m_i v_i (kg·m/s).
    pub fn linear_momentum(&self) -> Vector3<f64> {
        self.masses
            .iter()
            .zip(&self.velocities)
            .map(|(m, v)| *m * v)
            .sum()
    }

    /// The deformation gradients F_i now.
    pub fn deformation_gradients(&self) -> Vec<Matrix3<f64>> {
        self.elasticity.deformation_gradients(&self.positions)
    }
}

/// The particle spacing (m) of volumes `volumes`: the cube root of their median.
pub fn particle_spacing(volumes: &[f64]) -> f64 {
    let mut sorted = volumes.to_vec();
    sorted.sort_by(f64::total_cmp);
    sorted.get(sorted.len() / 2).map_or(0.0, |v| v.cbrt())
}

fn check_params(params: &SphParams) -> Result<(), SphError> {
    for (name, value) in [
        ("time_step", params.time_step),
        ("support_over_spacing", params.support_over_spacing),
        ("volume_tolerance", params.volume_tolerance),
    ] {
        if !(value > 0.0 && value.is_finite()) {
            return Err(SphError::InvalidParameter(format!(
                "{name} = {value} must be positive and finite"
            )));
        }
    }
    if !(params.zero_energy_alpha >= 0.0 && params.zero_energy_alpha.is_finite()) {
        return Err(SphError::InvalidParameter(format!(
            "zero_energy_alpha = {} must be non-negative and finite",
            params.zero_energy_alpha
        )));
    }
    if params.support_over_spacing < 1.0 {
        return Err(SphError::InvalidParameter(format!(
            "support_over_spacing = {} leaves particles without neighbours (use ≥ 1, default 2)",
            params.support_over_spacing
        )));
    }
    Ok(())
}
