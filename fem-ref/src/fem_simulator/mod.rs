//! Backward Euler with Newton on the full FEM model, exact Dirichlet conditions, per-step
//! reports (design §3.8).

use std::path::PathBuf;

use hyperelastic::{HyperelasticMaterial, Tangent};
use nalgebra::Vector3;
use optimize::{
    CarriedFactor, HessianReuse, NewtonError, NewtonParams, NewtonReport, minimize,
    minimize_reusing,
};
use rayon::prelude::*;
use thiserror::Error;

use crate::fem_model::FemModel;
use crate::scene::{FemFloor, FemScene};
use crate::sparse_system::{NumericFactor, SparseSystem, SystemSetupError};
use crate::trajectory_cache::{Trajectory, TrajectoryCacheError};

pub use crate::fem_params::{DEFAULT_CHECKPOINT_INTERVAL, FemParams};
pub use crate::fem_setup_error::FemSetupError;

mod run_management;
mod step_objective;

pub use run_management::{CachedRun, RunProgress};
use step_objective::StepObjective;

/// A cached run failed.
#[derive(Debug, Error)]
pub enum FemRunError {
    /// A step failed.
    #[error("FEM step {step} failed: {source}")]
    Step {
        /// 1-based step.
        step: usize,
        /// Why.
        #[source]
        source: NewtonError,
    },
    /// The cache could not be read, or a checkpoint asked for by a stop could not be written.
    #[error(transparent)]
    Cache(TrajectoryCacheError),
    /// The caller's progress callback stopped the run; what was computed is saved and the
    /// next [`FemSimulator::run_cached`] of the same run resumes from it.
    #[error("FEM run stopped after step {step} of {steps}; saved to {}", .checkpoint.display())]
    Stopped {
        /// Steps done.
        step: usize,
        /// Steps asked for.
        steps: usize,
        /// The checkpoint file.
        checkpoint: PathBuf,
    },
    /// A checkpoint under the run's key does not fit the run (a damaged or foreign file);
    /// delete it to start over.
    #[error("FEM checkpoint {} does not fit this run: {reason}", .path.display())]
    CheckpointMismatch {
        /// The file.
        path: PathBuf,
        /// Why.
        reason: String,
    },
    /// The trajectory was computed but could not be stored; it is returned here.
    #[error("the trajectory was computed but not cached: {error}")]
    CacheWrite {
        /// Why.
        error: TrajectoryCacheError,
        /// The computed trajectory.
        trajectory: Box<Trajectory>,
    },
}

/// Newton for a reference with the factorization carried across steps: chord steps while each
/// is at most half the last, tolerance 1e-8 (a hundred times tighter than the default, since a
/// chord iteration's last step bounds its error less sharply than Newton's). On the beam Bend
/// (P2, 8.7k / 27k / 62k DOFs, 2 cores) it takes 21 / 166 / 403 ms a step instead of 49 / 398
/// / 1615 ms with the default fresh factorizations at 1e-6, and at 8.7k DOFs its tip is closer
/// to the 1e-9 solution (1.3e-7 relative instead of 1.0e-5; `examples/beam_bend.rs --reuse`).
pub fn reusing_reference_newton() -> NewtonParams {
    NewtonParams {
        tolerance: 1e-8,
        hessian_reuse: HessianReuse::WhileContracting { contraction: 0.5 },
        ..NewtonParams::default()
    }
}

/// The most steps one factorization of the FEM is carried across with Hessian reuse.
pub const FEM_FACTOR_MAX_AGE: usize = 50;

/// Backward-Euler FEM simulation.
pub struct FemSimulator<M: HyperelasticMaterial> {
    model: FemModel<M>,
    scene: FemScene,
    floor: Option<(FemFloor, f64)>,
    params: FemParams,
    system: SparseSystem,
    /// Flat node positions (m) and velocities (m/s).
    x: Vec<f64>,
    v: Vec<f64>,
    time: f64,
    length_scale: f64,
    /// With Hessian reuse: the last factorization and the steps since it was made.
    carried: Option<CarriedFactor<NumericFactor>>,
    /// Steps taken as halves since construction ([`FemParams::failed_step_halvings`]).
    split_steps: usize,
}

/// The largest side of the mesh's bounding box (m): the length the floor penalty scales by.
fn length_scale<M: HyperelasticMaterial>(model: &FemModel<M>) -> f64 {
    rkpm_core::Aabb::from_points(model.mesh().nodes())
        .expect("non-empty mesh")
        .largest_side()
}

/// The scene's floor with a unit normal and its penalty stiffness
/// `κ = floor_factor · (λ + 2μ)_max / L²` (Pa/m², L = [`length_scale`] of the model).
fn penalized_floor<M: HyperelasticMaterial>(
    model: &FemModel<M>,
    scene: &FemScene,
    length_scale: f64,
) -> Result<Option<(FemFloor, f64)>, FemSetupError> {
    let Some(f) = scene.floor else {
        return Ok(None);
    };
    let norm = f.normal.norm();
    if !(norm > 0.0 && norm.is_finite() && f.offset.is_finite() && f.floor_factor > 0.0) {
        return Err(FemSetupError::InvalidScene(format!("invalid floor {f:?}")));
    }
    let kappa = f.floor_factor * model.max_p_wave_modulus() / length_scale.powi(2);
    let floor = FemFloor {
        normal: f.normal / norm,
        offset: f.offset / norm,
        ..f
    };
    Ok(Some((floor, kappa)))
}

struct StepProblem<'a> {
    predicted: Option<&'a [f64]>,
    inverse_step_squared: f64,
}

impl<M: HyperelasticMaterial> FemSimulator<M> {
    /// A simulator at rest at t = 0.
    ///
    /// # Errors
    /// [`FemSetupError`].
    pub fn new(
        model: FemModel<M>,
        scene: FemScene,
        params: FemParams,
    ) -> Result<Self, FemSetupError> {
        if !(params.time_step > 0.0 && params.time_step.is_finite()) {
            return Err(FemSetupError::InvalidTimeStep(params.time_step));
        }
        let fixed = scene.held_nodes(model.mesh().nodes().len())?;
        if let Some(g) = scene.gravity
            && !g.iter().all(|c| c.is_finite())
        {
            return Err(FemSetupError::InvalidScene(format!(
                "gravity {g:?} is not finite"
            )));
        }
        let length_scale = length_scale(&model);
        let floor = penalized_floor(&model, &scene, length_scale)?;
        let system = SparseSystem::new(&model, &fixed, params.ordering, params.factor_memory)
            .map_err(|e| match e {
                SystemSetupError::FactorTooLarge {
                    dofs,
                    factor_nonzeros,
                    bytes,
                    limit,
                } => FemSetupError::FactorTooLarge {
                    dofs,
                    factor_nonzeros,
                    bytes,
                    limit,
                },
                e => FemSetupError::Symbolic(e.to_string()),
            })?;
        let x: Vec<f64> = model
            .mesh()
            .nodes()
            .iter()
            .flat_map(|p| [p.x, p.y, p.z])
            .collect();
        let v = vec![0.0; x.len()];
        Ok(FemSimulator {
            model,
            scene,
            floor,
            params,
            system,
            x,
            v,
            time: 0.0,
            length_scale,
            carried: None,
            split_steps: 0,
        })
    }

    /// The model.
    pub fn model(&self) -> &FemModel<M> {
        &self.model
    }

    /// Current time (s).
    pub fn time(&self) -> f64 {
        self.time
    }

    /// Current node positions (m).
    pub fn positions(&self) -> Vec<Vector3<f64>> {
        self.x
            .chunks_exact(3)
            .map(|c| Vector3::new(c[0], c[1], c[2]))
            .collect()
    }

    /// Current node velocities (m/s).
    pub fn velocities(&self) -> Vec<Vector3<f64>> {
        self.v
            .chunks_exact(3)
            .map(|c| Vector3::new(c[0], c[1], c[2]))
            .collect()
    }

    /// Steps of h that did not converge whole and were taken as halves
    /// ([`FemParams::failed_step_halvings`]) since the simulator was built.
    pub fn split_steps(&self) -> usize {
        self.split_steps
    }

    /// Unknowns of the Newton system: the free DOFs, [`FemScene::free_dofs`] of its scene.
    pub fn free_dofs(&self) -> usize {
        self.system.free_count
    }

    /// Stored entries of the lower triangle of the Newton matrix.
    pub fn matrix_nonzeros(&self) -> usize {
        self.system.nonzeros()
    }

    /// Stored entries of its Cholesky factor L (the fill left by [`FemParams::ordering`]).
    pub fn factor_nonzeros(&self) -> usize {
        self.system.factor_nonzeros()
    }

    /// Bytes its factors need, known from the symbolic analysis before any numeric work: two
    /// factors of [`Self::factor_nonzeros`] `f64` entries (a carried or previous one and the
    /// fresh one) and the factorization's workspace; what [`FemParams::factor_memory`] is
    /// checked against.
    pub fn factor_memory_bytes(&self) -> u64 {
        self.system.factor_bytes()
    }

    /// Sets Dirichlet nodes to their targets at `t`.
    fn apply_targets(&self, x: &mut [f64], t: f64) {
        let rest = self.model.mesh().nodes();
        for d in &self.scene.dirichlet {
            for &node in &d.nodes {
                let p = d.target.at(&rest[node], t);
                x[3 * node..3 * node + 3].copy_from_slice(p.as_slice());
            }
        }
    }

    /// One backward-Euler step of h, split into halves where it does not converge whole
    /// ([`FemParams::failed_step_halvings`]). The report sums the iterations of every try
    /// (the failed whole step's included) and is converged only when every piece is.
    ///
    /// # Errors
    /// [`NewtonError`] of the deepest try; the state is then that of the last piece that
    /// succeeded (unchanged when none did, as without splitting).
    pub fn step(&mut self) -> Result<NewtonReport, NewtonError> {
        let (report, split) =
            self.step_split(self.params.time_step, self.params.failed_step_halvings)?;
        self.split_steps += usize::from(split);
        Ok(report)
    }

    /// A step of `h` that may split `halvings` levels deep, and whether it split.
    fn step_split(&mut self, h: f64, halvings: usize) -> Result<(NewtonReport, bool), NewtonError> {
        if halvings == 0 {
            return Ok((self.backward_euler_step(h)?, false));
        }
        let (x, v, time) = (self.x.clone(), self.v.clone(), self.time);
        let whole = match self.backward_euler_step(h) {
            Ok(report) if report.converged() => return Ok((report, false)),
            Ok(report) => Some(report),
            Err(_) => None,
        };
        // Again from the step's start in two halves; a carried factor belongs to h's system.
        (self.x, self.v, self.time) = (x, v, time);
        self.carried = None;
        let (first, _) = self.step_split(0.5 * h, halvings - 1)?;
        let (second, _) = self.step_split(0.5 * h, halvings - 1)?;
        self.time = time + h;
        let halves = if first.converged() {
            first.followed_by(&second)
        } else {
            NewtonReport {
                stop: first.stop,
                residual: first.residual,
                ..first.followed_by(&second)
            }
        };
        let report = match whole {
            Some(whole) => whole.followed_by(&halves),
            None => halves,
        };
        Ok((report, true))
    }

    /// One backward-Euler step of `h` (s).
    fn backward_euler_step(&mut self, h: f64) -> Result<NewtonReport, NewtonError> {
        let mut predicted: Vec<f64> = self.x.iter().zip(&self.v).map(|(x, v)| x + h * v).collect();
        self.apply_targets(&mut predicted, self.time + h);
        let mut x = predicted.clone();
        let problem = StepProblem {
            predicted: Some(&predicted),
            inverse_step_squared: 1.0 / (h * h),
        };
        let newton = self.params.newton;
        let (carried, age) = CarriedFactor::usable(self.carried.take(), FEM_FACTOR_MAX_AGE);
        let objective = StepObjective::new(self, problem);
        let (report, factor) = if newton.hessian_reuse == HessianReuse::Never {
            (minimize(&objective, &mut x, &newton)?, None)
        } else {
            let mut factor = carried;
            let first = minimize_reusing(&objective, &mut x, &newton, &mut factor)?;
            if first.converged() {
                (first, factor)
            } else {
                // Chord steps spent the iterations: again from the prediction, fresh Hessians.
                x.clone_from(&predicted);
                let fresh = NewtonParams {
                    hessian_reuse: HessianReuse::Never,
                    ..newton
                };
                let mut factor = None;
                let second = minimize_reusing(&objective, &mut x, &fresh, &mut factor)?;
                (first.followed_by(&second), factor)
            }
        };
        self.carried = CarriedFactor::after(factor, age, &report);
        self.v = x.iter().zip(&self.x).map(|(a, b)| (a - b) / h).collect();
        self.x = x;
        self.time += h;
        Ok(report)
    }

    /// Static equilibrium with the Dirichlet targets at `time`; sets velocities to zero.
    ///
    /// # Errors
    /// [`NewtonError`]; the state is then unchanged.
    pub fn solve_static(&mut self, time: f64) -> Result<NewtonReport, NewtonError> {
        let mut x = self.x.clone();
        self.apply_targets(&mut x, time);
        let problem = StepProblem {
            predicted: None,
            inverse_step_squared: 0.0,
        };
        let report = minimize(
            &StepObjective::new(self, problem),
            &mut x,
            &self.params.newton,
        )?;
        self.x = x;
        self.v.fill(0.0);
        self.time = time;
        Ok(report)
    }

    fn energy(&self, problem: &StepProblem<'_>, x: &[f64]) -> f64 {
        let mut e = self.model.elastic_energy(x);
        if let Some(g) = self.scene.gravity {
            e -= self
                .model
                .node_masses()
                .iter()
                .zip(x.chunks_exact(3))
                .map(|(m, xa)| m * (g.x * xa[0] + g.y * xa[1] + g.z * xa[2]))
                .sum::<f64>();
        }
        if let Some((floor, kappa)) = &self.floor {
            e += x
                .chunks_exact(3)
                .zip(self.model.node_volumes())
                .map(|(xa, v)| {
                    let depth = floor.offset - floor.normal.dot(&Vector3::new(xa[0], xa[1], xa[2]));
                    if depth > 0.0 {
                        0.5 * kappa * v * depth * depth
                    } else {
                        0.0
                    }
                })
                .sum::<f64>();
        }
        if let Some(pred) = problem.predicted {
            let d: Vec<f64> = x.iter().zip(pred).map(|(a, b)| a - b).collect();
            let md = self.model.apply_mass(&d);
            e += 0.5
                * problem.inverse_step_squared
                * d.iter().zip(&md).map(|(a, b)| a * b).sum::<f64>();
        }
        e
    }

    /// Full-length gradient (fixed DOFs included, ignored later).
    fn gradient(&self, problem: &StepProblem<'_>, x: &[f64]) -> Vec<f64> {
        let mut g = self.model.elastic_gradient(x);
        if let Some(grav) = self.scene.gravity {
            for (a, m) in self.model.node_masses().iter().enumerate() {
                for i in 0..3 {
                    g[3 * a + i] -= m * grav[i];
                }
            }
        }
        if let Some((floor, kappa)) = &self.floor {
            for (a, v) in self.model.node_volumes().iter().enumerate() {
                let xa = Vector3::new(x[3 * a], x[3 * a + 1], x[3 * a + 2]);
                let depth = floor.offset - floor.normal.dot(&xa);
                if depth > 0.0 {
                    for i in 0..3 {
                        g[3 * a + i] -= kappa * v * depth * floor.normal[i];
                    }
                }
            }
        }
        if let Some(pred) = problem.predicted {
            let d: Vec<f64> = x.iter().zip(pred).map(|(a, b)| a - b).collect();
            let md = self.model.apply_mass(&d);
            for (gi, m) in g.iter_mut().zip(md) {
                *gi += problem.inverse_step_squared * m;
            }
        }
        g
    }

    /// Sparse Hessian values on the free DOFs (lower triangle) with the element tangent
    /// `tangent`.
    fn hessian(&self, problem: &StepProblem<'_>, x: &[f64], tangent: Tangent) -> Vec<f64> {
        let mut values = vec![0.0; self.system.nonzeros()];
        // Element matrices in parallel a chunk at a time, scattered in order: a chunk's
        // matrices stay in cache, and the heap is not grown by every element's at once.
        const CHUNK: usize = 1024;
        let elements = self.model.mesh().element_count();
        for start in (0..elements).step_by(CHUNK) {
            let locals: Vec<Vec<f64>> = (start..(start + CHUNK).min(elements))
                .into_par_iter()
                .map(|e| {
                    self.model
                        .element_hessian(e, x, tangent, problem.inverse_step_squared)
                })
                .collect();
            for (e, local) in (start..).zip(&locals) {
                self.system.scatter_element(e, local, &mut values);
            }
        }
        if let Some((floor, kappa)) = &self.floor {
            for (a, v) in self.model.node_volumes().iter().enumerate() {
                let xa = Vector3::new(x[3 * a], x[3 * a + 1], x[3 * a + 2]);
                if floor.offset - floor.normal.dot(&xa) > 0.0 {
                    for i in 0..3 {
                        for j in 0..=i {
                            let (r, c) = (
                                self.system.free_index[3 * a + i],
                                self.system.free_index[3 * a + j],
                            );
                            if r != usize::MAX && c != usize::MAX {
                                let k = kappa * v * floor.normal[i] * floor.normal[j];
                                self.system.add(r, c, k, &mut values);
                            }
                        }
                    }
                }
            }
        }
        values
    }

    fn free_part(&self, full: &[f64]) -> Vec<f64> {
        let mut out = vec![0.0; self.system.free_count];
        for (dof, &k) in self.system.free_index.iter().enumerate() {
            if k != usize::MAX {
                out[k] = full[dof];
            }
        }
        out
    }

    fn scatter_step(&self, free: &[f64]) -> Vec<f64> {
        self.system
            .free_index
            .iter()
            .map(|&k| if k == usize::MAX { 0.0 } else { free[k] })
            .collect()
    }

    fn step_norm(&self, dx: &[f64]) -> f64 {
        let m = self.model.apply_mass(dx);
        let e: f64 = dx.iter().zip(&m).map(|(a, b)| a * b).sum();
        (e.max(0.0) / self.model.total_mass()).sqrt() / self.length_scale
    }

    fn solve(&self, factor: &NumericFactor, gradient_free: &[f64]) -> Vec<f64> {
        let mut step: Vec<f64> = gradient_free.iter().map(|g| -g).collect();
        self.system.solve_in_place(factor, &mut step);
        self.scatter_step(&step)
    }
}
