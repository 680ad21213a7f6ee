//! Explicit MPM with APIC transfers, as warp-mpm (PhysGaussian's solver) runs it (design §3.10).
//!
//! One substep of length Δt from time t:
//! 1. particles in a constrained region get the velocity that lands them on their target:
//!    v_p = (x̂(X_p, t + Δt) − x_p)/Δt (warp-mpm's particle velocity enforcement, with the
//!    target's position rather than its velocity so that held particles do not drift);
//! 2. Kirchhoff stress τ_p = τ(F_p) ([`MpmMaterial`]);
//! 3. P2G: m_i = Σ_p w_ip m_p, (m v)_i = Σ_p w_ip m_p (v_p + C_p (x_i − x_p)) − Δt Σ_p V⁰_p τ_p ∇w_ip
//!    (quadratic B-splines, [`QuadraticStencil`]);
//! 4. grid update: v_i = (m v)_i / m_i + Δt g; a floor half-space n·x ≥ o removes the inward
//!    normal velocity of nodes below it (frictionless, separating);
//! 5. G2P: v_p = Σ_i w_ip v_i, C_p = (4/Δx²) Σ_i w_ip v_i (x_i − x_p)ᵀ, ∇v_p = Σ_i v_i ∇w_ipᵀ,
//!    F_p ← (I + Δt ∇v_p) F_p, x_p ← x_p + Δt v_p.
//!
//! Tracers (massless points, e.g. the FEM vertices where the metrics are taken) move with the
//! mass-weighted grid velocity Σ w m_i v_i / Σ w m_i: inside the material (equal node masses)
//! the ordinary interpolation Σ w v_i, while a tracer on the surface is neither slowed by empty
//! nodes nor thrown by the fringe nodes whose tiny mass makes their velocity meaningless (a
//! plain normalization Σ' w v_i / Σ' w over nodes with mass did exactly that on the beam).

use std::time::Instant;

use hyperelastic::{LameParameters, MaterialSample};
use nalgebra::{Matrix3, Vector3};
use rayon::prelude::*;
use reduced_sim::{PinnedRegion, Scene};
use rkpm_core::IntegrationPoints;
use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::mpm::constitutive::MpmMaterial;
use crate::mpm::grid::{BackgroundGrid, GridLayout, Node};
use crate::mpm::quadratic_stencil::QuadraticStencil;
use crate::particle_materials::ParticleMaterials;

/// Nodes lighter than this fraction of the lightest particle carry no velocity (their momentum
/// is round-off).
const NODE_MASS_FRACTION: f64 = 1e-12;

/// The MPM baseline's options.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct MpmParams {
    /// Grid spacing Δx (m). Default 0.1.
    pub grid_spacing: f64,
    /// Substep Δt (s). Default 1e-4 (the paper's, on the beam).
    pub time_step: f64,
    /// Elastic model. Default fixed corotated (warp-mpm's).
    pub material: MpmMaterial,
    /// Largest accepted Courant number c Δt / Δx, c = √((λ + 2μ)/ρ) the fastest particle's
    /// P-wave speed. Default 0.5. A larger Δt is refused before the run
    /// ([`MpmError::TimeStepAboveCfl`]).
    pub cfl_number: f64,
}

impl Default for MpmParams {
    fn default() -> Self {
        MpmParams {
            grid_spacing: 0.1,
            time_step: 1e-4,
            material: MpmMaterial::FixedCorotated,
            cfl_number: 0.5,
        }
    }
}

/// Why an MPM run cannot start or continue.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum MpmError {
    /// Δt above the stability limit of the material and grid.
    #[error(
        "MPM time step {time_step:e} s is above the CFL limit {limit:.3e} s = {cfl_number} · Δx \
         ({grid_spacing} m) / P-wave speed ({wave_speed:.1} m/s); use a smaller time step or a \
         coarser grid"
    )]
    TimeStepAboveCfl {
        /// The requested Δt (s).
        time_step: f64,
        /// The largest accepted Δt (s).
        limit: f64,
        /// The accepted Courant number.
        cfl_number: f64,
        /// Δx (m).
        grid_spacing: f64,
        /// Fastest P-wave speed √((λ + 2μ)/ρ) over the particles (m/s).
        wave_speed: f64,
    },
    /// A parameter that is not positive and finite.
    #[error("invalid MPM parameter: {0}")]
    InvalidParameter(String),
    /// Particles, materials, scene or tracers that cannot be simulated.
    #[error("invalid MPM input: {0}")]
    InvalidInput(String),
    /// A particle moved more than a grid cell in one substep: the run has become unstable.
    #[error(
        "MPM run unstable at t = {time:.5} s: particle {particle} moves {speed:.3e} m/s, more \
         than a cell per substep ({limit:.3e} m/s)"
    )]
    Unstable {
        /// Time at the end of the failing substep (s).
        time: f64,
        /// The particle.
        particle: usize,
        /// Its speed (m/s).
        speed: f64,
        /// Δx / Δt (m/s).
        limit: f64,
    },
    /// A position, velocity or deformation gradient became NaN or infinite.
    #[error("MPM run went non-finite at t = {time:.5} s ({what} {index})")]
    NonFinite {
        /// Time at the end of the failing substep (s).
        time: f64,
        /// "particle" or "tracer".
        what: &'static str,
        /// Its index.
        index: usize,
    },
    /// A tracer has no node with mass around it (it left the material).
    #[error("tracer {tracer} at t = {time:.5} s has no grid node with mass around it")]
    TracerLost {
        /// The tracer.
        tracer: usize,
        /// Time (s).
        time: f64,
    },
}

/// Seconds spent in each phase since the simulator was built.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct MpmTimings {
    /// Prescribed velocities and stresses (s).
    pub stress: f64,
    /// Grid fit, bucketing and particle-to-grid scatter (s).
    pub particle_to_grid: f64,
    /// Grid velocities, gravity, floor (s).
    pub grid_update: f64,
    /// Grid-to-particle gather and tracer advection (s).
    pub grid_to_particle: f64,
    /// Substeps taken.
    pub substeps: usize,
}

impl MpmTimings {
    /// Total seconds.
    pub fn total(&self) -> f64 {
        self.stress + self.particle_to_grid + self.grid_update + self.grid_to_particle
    }
}

/// P-wave speed √((λ + 2μ)/ρ) (m/s) of one material sample.
///
/// # Errors
/// [`MpmError::InvalidInput`] for invalid elastic parameters.
pub fn p_wave_speed(material: &MaterialSample) -> Result<f64, MpmError> {
    let lame = material
        .lame_parameters()
        .map_err(|e| MpmError::InvalidInput(e.to_string()))?;
    Ok((lame.p_wave_modulus() / material.density).sqrt())
}

/// The largest P-wave speed (m/s) of `materials`.
///
/// # Errors
/// [`MpmError::InvalidInput`] for invalid elastic parameters or no material.
fn fastest_p_wave_speed(materials: &[MaterialSample]) -> Result<f64, MpmError> {
    let mut fastest: f64 = 0.0;
    for m in materials {
        fastest = fastest.max(p_wave_speed(m)?);
    }
    if !(fastest > 0.0) {
        return Err(MpmError::InvalidInput(
            "no material to take a wave speed of".into(),
        ));
    }
    Ok(fastest)
}

/// The largest Δt (s) `params.cfl_number` accepts on grid spacing `params.grid_spacing` for
/// the fastest of `materials`: `cfl · Δx / max c`.
///
/// # Errors
/// [`MpmError::InvalidInput`] for invalid elastic parameters or no material.
pub fn stable_time_step(params: &MpmParams, materials: &[MaterialSample]) -> Result<f64, MpmError> {
    Ok(params.cfl_number * params.grid_spacing / fastest_p_wave_speed(materials)?)
}

/// An explicit APIC MPM simulation of one body, with optional tracer points.
pub struct MpmSimulator {
    params: MpmParams,
    scene: Scene,
    rest: Vec<Vector3<f64>>,
    positions: Vec<Vector3<f64>>,
    velocities: Vec<Vector3<f64>>,
    affine: Vec<Matrix3<f64>>,
    deformation: Vec<Matrix3<f64>>,
    stress: Vec<Matrix3<f64>>,
    masses: Vec<f64>,
    volumes: Vec<f64>,
    lame: Vec<LameParameters>,
    tracers: Vec<Vector3<f64>>,
    tracer_rest: Vec<Vector3<f64>>,
    tracer_regions: Vec<PinnedRegion>,
    grid: BackgroundGrid,
    buckets: Vec<Vec<usize>>,
    time: f64,
    timings: MpmTimings,
    node_mass_floor: f64,
}

impl MpmSimulator {
    /// Particles at `points` (rest positions and volumes) of `materials` (one per particle, or
    /// one for all) at rest with F = I, under `scene` (gravity, pinned or moving particle
    /// regions, a floor; held regions are not supported).
    ///
    /// # Errors
    /// [`MpmError::InvalidParameter`] for a non-positive Δx, Δt or Courant number,
    /// [`MpmError::TimeStepAboveCfl`] for a Δt above the stability limit,
    /// [`MpmError::InvalidInput`] for mismatched lengths, invalid materials, a region naming a
    /// missing particle, or held regions.
    pub fn new(
        points: &IntegrationPoints,
        materials: &[MaterialSample],
        scene: &Scene,
        params: MpmParams,
    ) -> Result<Self, MpmError> {
        for (name, value) in [
            ("grid_spacing", params.grid_spacing),
            ("time_step", params.time_step),
            ("cfl_number", params.cfl_number),
        ] {
            if !(value > 0.0 && value.is_finite()) {
                return Err(MpmError::InvalidParameter(format!(
                    "{name} = {value} must be positive and finite"
                )));
            }
        }
        let n = points.len();
        let wave_speed = fastest_p_wave_speed(materials)?;
        let limit = params.cfl_number * params.grid_spacing / wave_speed;
        if params.time_step > limit {
            return Err(MpmError::TimeStepAboveCfl {
                time_step: params.time_step,
                limit,
                cfl_number: params.cfl_number,
                grid_spacing: params.grid_spacing,
                wave_speed,
            });
        }
        if !scene.held.is_empty() {
            return Err(MpmError::InvalidInput(
                "held regions are a reduced-simulator concept; give MPM pinned regions".into(),
            ));
        }
        for (r, region) in scene.pins.iter().enumerate() {
            if let Some(&p) = region.points.iter().find(|&&p| p >= n) {
                return Err(MpmError::InvalidInput(format!(
                    "pinned region {r} names particle {p} of {n}"
                )));
            }
        }
        let ParticleMaterials { lame, masses } =
            ParticleMaterials::new(points.volumes(), materials).map_err(MpmError::InvalidInput)?;
        let lightest = masses.iter().copied().fold(f64::INFINITY, f64::min);
        Ok(MpmSimulator {
            params,
            scene: scene.clone(),
            rest: points.positions().to_vec(),
            positions: points.positions().to_vec(),
            velocities: vec![Vector3::zeros(); n],
            affine: vec![Matrix3::zeros(); n],
            deformation: vec![Matrix3::identity(); n],
            stress: vec![Matrix3::zeros(); n],
            masses,
            volumes: points.volumes().to_vec(),
            lame,
            tracers: Vec::new(),
            tracer_rest: Vec::new(),
            tracer_regions: Vec::new(),
            grid: BackgroundGrid::default(),
            buckets: Vec::new(),
            time: 0.0,
            timings: MpmTimings::default(),
            node_mass_floor: NODE_MASS_FRACTION * lightest,
        })
    }

    /// Adds massless tracers at rest positions `points` (m), moved each substep with the
    /// mass-weighted grid velocity (module documentation); they must lie in or next to the
    /// material (a tracer with no node of mass around it stops the run). Tracers named by
    /// `regions` (indices into `points`) belong to a constrained region and are moved like its
    /// particles: onto their target at the end of each substep.
    ///
    /// # Errors
    /// [`MpmError::InvalidInput`] for a non-finite point, a region naming a missing tracer, or
    /// a simulator that already ran or already has tracers.
    pub fn with_tracers(
        mut self,
        points: &[Vector3<f64>],
        regions: &[PinnedRegion],
    ) -> Result<Self, MpmError> {
        if self.time > 0.0 || !self.tracers.is_empty() {
            return Err(MpmError::InvalidInput(
                "tracers must be added once, before the first substep".into(),
            ));
        }
        if let Some(i) = points.iter().position(|p| !p.iter().all(|c| c.is_finite())) {
            return Err(MpmError::InvalidInput(format!("tracer {i} is not finite")));
        }
        for (r, region) in regions.iter().enumerate() {
            if let Some(&t) = region.points.iter().find(|&&t| t >= points.len()) {
                return Err(MpmError::InvalidInput(format!(
                    "tracer region {r} names tracer {t} of {}",
                    points.len()
                )));
            }
        }
        self.tracers = points.to_vec();
        self.tracer_rest = points.to_vec();
        self.tracer_regions = regions.to_vec();
        Ok(self)
    }

    /// Sets every particle's velocity (m/s) and affine velocity C (1/s), e.g. for an initial
    /// spin; call before the first substep.
    ///
    /// # Errors
    /// [`MpmError::InvalidInput`] for a wrong length or non-finite values.
    pub fn set_velocities(
        &mut self,
        velocities: &[Vector3<f64>],
        affine: &[Matrix3<f64>],
    ) -> Result<(), MpmError> {
        let n = self.positions.len();
        if velocities.len() != n || affine.len() != n {
            return Err(MpmError::InvalidInput(format!(
                "{} velocities and {} affine matrices for {n} particles",
                velocities.len(),
                affine.len()
            )));
        }
        if !velocities.iter().all(|v| v.iter().all(|c| c.is_finite()))
            || !affine.iter().all(|c| c.iter().all(|x| x.is_finite()))
        {
            return Err(MpmError::InvalidInput("non-finite initial velocity".into()));
        }
        self.velocities.copy_from_slice(velocities);
        self.affine.copy_from_slice(affine);
        Ok(())
    }

    /// Advances by `duration` (s) in `⌈duration / Δt⌉` equal substeps (none of them longer than
    /// Δt); returns the number of substeps.
    ///
    /// # Errors
    /// [`MpmError::InvalidParameter`] for a negative or non-finite duration; the run's own
    /// errors ([`MpmError::Unstable`], [`MpmError::NonFinite`], [`MpmError::TracerLost`]), after
    /// which the state is that of the failing substep.
    pub fn advance(&mut self, duration: f64) -> Result<usize, MpmError> {
        if !(duration >= 0.0 && duration.is_finite()) {
            return Err(MpmError::InvalidParameter(format!(
                "duration {duration} must be non-negative and finite"
            )));
        }
        let substeps = (duration / self.params.time_step - 1e-9).ceil().max(0.0) as usize;
        if substeps == 0 {
            return Ok(0);
        }
        let dt = duration / substeps as f64;
        for _ in 0..substeps {
            self.substep(dt)?;
        }
        Ok(substeps)
    }

    /// One substep of length `dt` (s), the sequence of the module documentation.
    fn substep(&mut self, dt: f64) -> Result<(), MpmError> {
        let start = Instant::now();
        self.prescribe_velocities(dt);
        let material = self.params.material;
        self.stress
            .par_iter_mut()
            .zip(&self.deformation)
            .zip(&self.lame)
            .for_each(|((tau, f), lame)| *tau = material.kirchhoff_stress(lame, f));
        let stress_done = Instant::now();
        self.particle_to_grid(dt);
        let p2g_done = Instant::now();
        self.update_grid(dt);
        let grid_done = Instant::now();
        let result = self.grid_to_particle(dt);
        let end = Instant::now();
        self.time += dt;
        let t = &mut self.timings;
        t.stress += (stress_done - start).as_secs_f64();
        t.particle_to_grid += (p2g_done - stress_done).as_secs_f64();
        t.grid_update += (grid_done - p2g_done).as_secs_f64();
        t.grid_to_particle += (end - grid_done).as_secs_f64();
        t.substeps += 1;
        result
    }

    /// Step 1: constrained particles aim at their targets at the end of the substep.
    fn prescribe_velocities(&mut self, dt: f64) {
        let t_next = self.time + dt;
        for region in &self.scene.pins {
            for &p in &region.points {
                let target = region.target.at(&self.rest[p], t_next);
                self.velocities[p] = (target - self.positions[p]) / dt;
            }
        }
    }

    /// Step 3: fit the grid, bucket particles by slab, scatter slab colour by colour.
    fn particle_to_grid(&mut self, dt: f64) {
        let spacing = self.params.grid_spacing;
        let inverse = 1.0 / spacing;
        let origin = Vector3::zeros();
        self.grid
            .fit(spacing, self.positions.iter().chain(self.tracers.iter()));
        let slabs = self.grid.layout.slabs();
        self.buckets.resize_with(slabs, Vec::new);
        self.buckets.truncate(slabs);
        for b in &mut self.buckets {
            b.clear();
        }
        for (p, x) in self.positions.iter().enumerate() {
            let stencil = QuadraticStencil::new(x, &origin, inverse);
            self.buckets[self.grid.layout.slab(&stencil)].push(p);
        }
        let particles = ParticleView {
            positions: &self.positions,
            velocities: &self.velocities,
            affine: &self.affine,
            stress: &self.stress,
            masses: &self.masses,
            volumes: &self.volumes,
        };
        for colour in 0..2 {
            let layout = self.grid.layout;
            let buckets = &self.buckets;
            self.grid.slabs_of_colour(colour).into_par_iter().for_each(
                |(slab, first_row, nodes)| {
                    for &p in &buckets[slab] {
                        particles.scatter(p, &layout, first_row, nodes, spacing, dt);
                    }
                },
            );
        }
    }

    /// Step 4: momentum to velocity, gravity, floor.
    fn update_grid(&mut self, dt: f64) {
        let gravity = self.scene.gravity.unwrap_or_else(Vector3::zeros);
        let floor = self.scene.floor;
        let floor_mass = self.node_mass_floor;
        let layout = self.grid.layout;
        self.grid
            .nodes
            .par_iter_mut()
            .enumerate()
            .for_each(|(i, node)| {
                let mass = node[3];
                if mass <= floor_mass {
                    *node = [0.0; 4];
                    return;
                }
                let mut v = Vector3::new(node[0], node[1], node[2]) / mass + dt * gravity;
                if let Some(floor) = &floor {
                    let x = layout.node_position(i);
                    if floor.normal.dot(&x) < floor.offset {
                        let vn = floor.normal.dot(&v);
                        if vn < 0.0 {
                            v -= vn * floor.normal;
                        }
                    }
                }
                *node = [v.x, v.y, v.z, mass];
            });
    }

    /// Step 5: gather velocities, affine velocities and velocity gradients; move particles and
    /// tracers. Checks every particle and tracer afterwards.
    fn grid_to_particle(&mut self, dt: f64) -> Result<(), MpmError> {
        let spacing = self.params.grid_spacing;
        let inverse = 1.0 / spacing;
        let origin = Vector3::zeros();
        let grid = &self.grid;
        self.positions
            .par_iter_mut()
            .zip(&mut self.velocities)
            .zip(&mut self.affine)
            .zip(&mut self.deformation)
            .for_each(|(((x, v), c), f)| {
                let stencil = QuadraticStencil::new(x, &origin, inverse);
                let mut new_v = Vector3::zeros();
                let mut new_c = Matrix3::zeros();
                let mut grad_v = Matrix3::zeros();
                for i in 0..3 {
                    for j in 0..3 {
                        for k in 0..3 {
                            let node = &grid.nodes[grid.layout.index(&stencil, [i, j, k])];
                            let vi = Vector3::new(node[0], node[1], node[2]);
                            let w = stencil.weight(i, j, k);
                            new_v += w * vi;
                            new_c += (w * vi) * stencil.node_offset(i, j, k).transpose();
                            grad_v += vi * stencil.weight_gradient(i, j, k).transpose();
                        }
                    }
                }
                *v = new_v;
                *c = new_c * (4.0 * inverse);
                *f = (Matrix3::identity() + dt * grad_v) * *f;
                *x += dt * new_v;
            });
        let floor_mass = self.node_mass_floor;
        let lost: Vec<Option<usize>> = self
            .tracers
            .par_iter_mut()
            .enumerate()
            .map(|(t, x)| {
                let stencil = QuadraticStencil::new(x, &origin, inverse);
                let mut sum = Vector3::zeros();
                let mut weight = 0.0;
                for i in 0..3 {
                    for j in 0..3 {
                        for k in 0..3 {
                            let node = &grid.nodes[grid.layout.index(&stencil, [i, j, k])];
                            let wm = stencil.weight(i, j, k) * node[3];
                            sum += wm * Vector3::new(node[0], node[1], node[2]);
                            weight += wm;
                        }
                    }
                }
                if weight > floor_mass {
                    *x += dt * sum / weight;
                    None
                } else {
                    Some(t)
                }
            })
            .collect();
        let time = self.time + dt;
        for region in &self.tracer_regions {
            for &t in &region.points {
                self.tracers[t] = region.target.at(&self.tracer_rest[t], time);
            }
        }
        let held = |t: usize| self.tracer_regions.iter().any(|r| r.points.contains(&t));
        if let Some(tracer) = lost.into_iter().flatten().find(|&t| !held(t)) {
            return Err(MpmError::TracerLost { tracer, time });
        }
        let limit = spacing / dt;
        for (p, (x, v)) in self.positions.iter().zip(&self.velocities).enumerate() {
            let finite = x.iter().chain(v.iter()).all(|c| c.is_finite())
                && self.deformation[p].iter().all(|c| c.is_finite());
            if !finite {
                return Err(MpmError::NonFinite {
                    time,
                    what: "particle",
                    index: p,
                });
            }
            let speed = v.norm();
            if speed > limit {
                return Err(MpmError::Unstable {
                    time,
                    particle: p,
                    speed,
                    limit,
                });
            }
        }
        if let Some(index) = self
            .tracers
            .iter()
            .position(|x| !x.iter().all(|c| c.is_finite()))
        {
            return Err(MpmError::NonFinite {
                time,
                what: "tracer",
                index,
            });
        }
        Ok(())
    }

    /// The largest distance (m) of a particle in a constrained region from its target now:
    /// how well particle velocity enforcement holds the regions.
    pub fn max_pin_deviation(&self) -> f64 {
        let mut worst: f64 = 0.0;
        for region in &self.scene.pins {
            for &p in &region.points {
                let target = region.target.at(&self.rest[p], self.time);
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
    pub fn params(&self) -> &MpmParams {
        &self.params
    }

    /// Particle positions (m).
    pub fn positions(&self) -> &[Vector3<f64>] {
        &self.positions
    }

    /// Particle rest positions (m).
    pub fn rest_positions(&self) -> &[Vector3<f64>] {
        &self.rest
    }

    /// Particle velocities (m/s).
    pub fn velocities(&self) -> &[Vector3<f64>] {
        &self.velocities
    }

    /// Particle affine velocities C (1/s).
    pub fn affine_velocities(&self) -> &[Matrix3<f64>] {
        &self.affine
    }

    /// Particle deformation gradients F.
    pub fn deformation_gradients(&self) -> &[Matrix3<f64>] {
        &self.deformation
    }

    /// Particle masses (kg).
    pub fn masses(&self) -> &[f64] {
        &self.masses
    }

    /// Tracer positions (m), in the order given to [`MpmSimulator::with_tracers`].
    pub fn tracer_positions(&self) -> &[Vector3<f64>] {
        &self.tracers
    }

    /// Seconds per phase and substeps so far.
    pub fn timings(&self) -> &MpmTimings {
        &self.timings
    }

    /// Total linear momentum Σ m_p v_p (kg·m/s).
    pub fn linear_momentum(&self) -> Vector3<f64> {
        self.masses
            .iter()
            .zip(&self.velocities)
            .map(|(m, v)| *m * v)
            .sum()
    }

    /// Total angular momentum about the origin, with APIC's affine part (Jiang et al. 2015,
    /// Sec. 5.3): Σ_p m_p x_p × v_p + m_p Δx²/4 · ε : C_pᵀ, i.e. the angular momentum the
    /// particles put on the grid (kg·m²/s).
    pub fn angular_momentum(&self) -> Vector3<f64> {
        let d = 0.25 * self.params.grid_spacing.powi(2);
        let mut total = Vector3::zeros();
        for p in 0..self.positions.len() {
            let m = self.masses[p];
            let c = &self.affine[p];
            total += m * self.positions[p].cross(&self.velocities[p]);
            total += m
                * d
                * Vector3::new(
                    c[(2, 1)] - c[(1, 2)],
                    c[(0, 2)] - c[(2, 0)],
                    c[(1, 0)] - c[(0, 1)],
                );
        }
        total
    }
}

/// Read-only particle arrays for the scatter.
struct ParticleView<'a> {
    positions: &'a [Vector3<f64>],
    velocities: &'a [Vector3<f64>],
    affine: &'a [Matrix3<f64>],
    stress: &'a [Matrix3<f64>],
    masses: &'a [f64],
    volumes: &'a [f64],
}

impl ParticleView<'_> {
    /// Adds particle `p`'s mass and momentum (with its stress impulse) to the rows of `nodes`
    /// starting at row `first_row`.
    fn scatter(
        &self,
        p: usize,
        layout: &GridLayout,
        first_row: usize,
        nodes: &mut [Node],
        spacing: f64,
        dt: f64,
    ) {
        let stencil = QuadraticStencil::new(&self.positions[p], &Vector3::zeros(), 1.0 / spacing);
        let m = self.masses[p];
        let momentum = m * self.velocities[p];
        // C (x_i − x_p) = C · offset Δx; the stress impulse −Δt V⁰ τ ∇w.
        let affine = self.affine[p] * (m * spacing);
        let impulse = self.stress[p] * (-dt * self.volumes[p]);
        for i in 0..3 {
            for j in 0..3 {
                for k in 0..3 {
                    let w = stencil.weight(i, j, k);
                    let add = w * (momentum + affine * stencil.node_offset(i, j, k))
                        + impulse * stencil.weight_gradient(i, j, k);
                    let node = &mut nodes[layout.local_index(&stencil, [i, j, k], first_row)];
                    node[0] += add.x;
                    node[1] += add.y;
                    node[2] += add.z;
                    node[3] += w * m;
                }
            }
        }
    }
}
