//! A scene of several objects stepped from Python (`freeform.Scene`): objects added one by one
//! (a basis, its integration points, a material, where it starts, its held regions), the shared
//! gravity, floor and colliders, contact between the objects, and the same multibody simulator
//! a scene file with `[[objects]]` runs.

use freeform::reduced_sim::ReducedLayout;
use freeform::reduced_sim::{
    Body, BodyContactParams, DeformationMap, MultiBodySimulator, PinTarget, PinnedRegion,
    PlannedRun, ReducedState,
};
use freeform::{
    Constraint, PinHold, Placement, SceneSpec, Simulation, SimulationSpec, failure_chain,
    prepare_simulator_for,
};
use hyperelastic::{MaterialField, StableNeoHookean};
use nalgebra::{UnitQuaternion, Vector3};
use numpy::ndarray::Array3;
use numpy::{IntoPyArray, PyArray2, PyArray3};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use rkpm_core::IntegrationPoints;
use skin_eigen::SkinningBasis;

use crate::arrays::{self, Points, points_array, points_of};
use crate::basis::PyBasis;
use crate::errors::{self, SceneError};
use crate::geometry::PyGeometry;
use crate::material::PyMaterial;
use crate::outputs::matrices_array;
use crate::points::PyIntegrationPoints;
use crate::simulation::settings_for_given_basis;
use crate::splats::PySplats;
use crate::threads::{on_pool, thread_pool};
use std::sync::Arc;

/// One object as added, before the simulator is built.
struct ObjectInputs {
    basis: SkinningBasis,
    points: IntegrationPoints,
    material: MaterialField,
    placement: Placement,
    constraints: Vec<Constraint>,
    pinned: Vec<Vec<usize>>,
    /// Where it touches the others (rest frame, m).
    contact_samples: Vec<Vector3<f64>>,
}

/// Objects stepped together: added until the first step, then simulated.
#[pyclass(module = "freeform._native", name = "Scene")]
pub(crate) struct PyScene {
    shared: SceneSpec,
    spec: SimulationSpec,
    contact: BodyContactParams,
    cache_dir: Option<std::path::PathBuf>,
    objects: Vec<ObjectInputs>,
    simulator: Option<MultiBodySimulator<StableNeoHookean>>,
    steps_taken: usize,
    /// The pool its setup and steps run on (`None`: the global pool).
    pool: Option<Arc<rayon::ThreadPool>>,
}

#[pymethods]
impl PyScene {
    /// `scene`, `simulation` and `contact`: JSON text of a scene file's `[scene]` (gravity,
    /// floor, colliders; constraints go with each object), `[simulation]` and `[contact]`.
    /// `threads`: the threads its setup and steps run on (all cores when None; a fixed count
    /// gives bit-identical runs).
    #[new]
    #[pyo3(signature = (scene, simulation, contact, cache_dir = None, threads = None))]
    fn new(
        scene: &str,
        simulation: &str,
        contact: &str,
        cache_dir: Option<std::path::PathBuf>,
        threads: Option<usize>,
    ) -> PyResult<Self> {
        let pool = thread_pool(threads)?;
        let shared: SceneSpec =
            serde_json::from_str(scene).map_err(|e| SceneError::new_err(format!("scene: {e}")))?;
        if !shared.constraints.is_empty() {
            return Err(SceneError::new_err(
                "scene: constraints belong to an object (add_object(..., constraints=[...]))",
            ));
        }
        shared
            .validate()
            .map_err(|e| errors::raise::<SceneError>(&e))?;
        let spec = settings_for_given_basis(simulation)
            .map_err(|e| SceneError::new_err(format!("simulation: {e}")))?;
        if let Some((field, problem)) = spec.defect() {
            return Err(SceneError::new_err(format!(
                "simulation.{field}: {problem}"
            )));
        }
        if spec.pins != PinHold::Penalty || spec.pressure.is_some() {
            return Err(SceneError::new_err(
                "simulation.pins other than \"penalty\" and simulation.pressure need a basis \
                 built for them: use simulate_scene_file",
            ));
        }
        let contact: BodyContactParams = serde_json::from_str(contact)
            .map_err(|e| SceneError::new_err(format!("contact: {e}")))?;
        if let Some(problem) = contact.defect() {
            return Err(SceneError::new_err(format!("contact: {problem}")));
        }
        Ok(PyScene {
            shared,
            spec,
            contact,
            cache_dir,
            objects: Vec::new(),
            simulator: None,
            steps_taken: 0,
            pool,
        })
    }

    /// Adds an object; returns its index. `placement`: JSON text `{"position": [x, y, z],
    /// "rotation": [i, j, k, w], "velocity": [vx, vy, vz]}` (every key optional);
    /// `constraints`: JSON text of its `[[objects.constraints]]` (rest frame); `pinned`: sets
    /// of its integration-point indices held at rest; `geometry`: its shape, whose surface
    /// samples touch the other objects (its integration points when None).
    #[pyo3(signature = (basis, points, material, placement, constraints, pinned, geometry = None))]
    #[allow(clippy::too_many_arguments)]
    fn add_object(
        &mut self,
        basis: &PyBasis,
        points: &PyIntegrationPoints,
        material: &PyMaterial,
        placement: &str,
        constraints: &str,
        pinned: Vec<Vec<usize>>,
        geometry: Option<&PyGeometry>,
    ) -> PyResult<usize> {
        if self.simulator.is_some() {
            return Err(SceneError::new_err(
                "objects are added before the first step; this scene has started",
            ));
        }
        let placement: PlacementInput = serde_json::from_str(placement)
            .map_err(|e| SceneError::new_err(format!("placement: {e}")))?;
        let placement = placement.placement()?;
        let constraints: Vec<Constraint> = serde_json::from_str(constraints)
            .map_err(|e| SceneError::new_err(format!("constraints: {e}")))?;
        let n = points.inner.len();
        if let Some(i) = pinned.iter().flatten().find(|&&i| i >= n) {
            return Err(PyValueError::new_err(format!(
                "pinned point {i} is not one of the {n} integration points"
            )));
        }
        let contact_samples = match geometry {
            Some(g) => g.inner.contact_samples(self.contact.radius),
            None => points.inner.positions().to_vec(),
        };
        if basis.inner.handles() == 0 {
            return Err(errors::BasisError::new_err("the basis has no handle"));
        }
        self.objects.push(ObjectInputs {
            basis: basis.inner.clone(),
            points: points.inner.clone(),
            material: material.field(),
            placement,
            constraints,
            pinned,
            contact_samples,
        });
        Ok(self.objects.len() - 1)
    }

    /// Objects added.
    fn __len__(&self) -> usize {
        self.objects.len()
    }

    /// Advances every object one backward-Euler step (building the simulator first, with each
    /// object's quadrature, at the first step); returns the Newton reports as JSON text
    /// (`converged`, and per object `iterations`, `residual`, ...).
    fn step(&mut self, py: Python<'_>) -> PyResult<String> {
        let pool = self.pool.as_deref();
        if self.simulator.is_none() {
            let built = py.detach(|| on_pool(pool, || self.build()))?;
            self.simulator = Some(built);
        }
        let Some(simulator) = self.simulator.as_mut() else {
            return Err(SceneError::new_err(
                "the scene's simulator could not be built",
            ));
        };
        let report = py
            .detach(|| on_pool(pool, || simulator.step()))
            .map_err(|e| errors::step_error(Some(self.steps_taken + 1), &e))?;
        self.steps_taken += 1;
        let bodies: Vec<serde_json::Value> = report
            .bodies
            .iter()
            .map(|r| {
                serde_json::json!({
                    "converged": r.converged(),
                    "iterations": r.iterations,
                    "hessian_assemblies": r.hessian_assemblies,
                    "line_search_cuts": r.line_search_cuts,
                    "residual": r.residual,
                })
            })
            .collect();
        Ok(serde_json::json!({
            "converged": report.converged(),
            "objects": bodies,
            "joint_groups": report.joint_groups,
            "active_pairs": report.active_pairs,
        })
        .to_string())
    }

    /// Simulated time t (s).
    #[getter]
    fn time(&self) -> f64 {
        self.simulator
            .as_ref()
            .and_then(|s| s.bodies().first())
            .map_or(0.0, |b| b.simulator().state().time)
    }

    /// Kinetic, elastic, gravitational, penalty and contact energy of every object (J).
    #[getter]
    fn mechanical_energy(&self) -> PyResult<f64> {
        Ok(self.started()?.mechanical_energy())
    }

    /// Object `k`'s reduced coordinates z, `(12(m + 1),)`.
    fn coordinates<'py>(
        &self,
        py: Python<'py>,
        k: usize,
    ) -> PyResult<Bound<'py, numpy::PyArray1<f64>>> {
        Ok(numpy::ndarray::Array1::from(self.state(k)?.z.clone()).into_pyarray(py))
    }

    /// Deformed positions `(n, 3)` (m, world) of object `k`'s rest `points` (its integration
    /// points when omitted), written into `out` and `out` returned when given.
    #[pyo3(signature = (k, points = None, out = None))]
    fn deformed_points<'py>(
        &self,
        py: Python<'py>,
        k: usize,
        points: Option<Points<'py>>,
        out: Option<Bound<'py, PyArray2<f64>>>,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let z = &self.state(k)?.z;
        let deformed = self.map(py, k, points)?.positions(z);
        match out {
            Some(out) => arrays::write_points_into(out, &deformed),
            None => Ok(points_array(py, &deformed)),
        }
    }

    /// Deformation gradients F `(n, 3, 3)` of object `k` at its rest `points`.
    #[pyo3(signature = (k, points = None))]
    fn deformation_gradients<'py>(
        &self,
        py: Python<'py>,
        k: usize,
        points: Option<Points<'py>>,
    ) -> PyResult<Bound<'py, PyArray3<f64>>> {
        let z = &self.state(k)?.z;
        let f = self.map(py, k, points)?.deformation_gradients(z);
        Ok(matrices_array(py, &f))
    }

    /// The stress of object `k` at its rest `points` (its integration points when omitted):
    /// Cauchy σ `(n, 3, 3)`, principal stresses `(n, 3)` (σ₁ ≥ σ₂ ≥ σ₃), von Mises `(n,)`
    /// (Pa), and the indices of inverted points (det F ≤ 0), whose stress is 0.
    #[pyo3(signature = (k, points = None))]
    #[allow(clippy::type_complexity)]
    fn stress<'py>(
        &self,
        py: Python<'py>,
        k: usize,
        points: Option<Points<'py>>,
    ) -> PyResult<(
        Bound<'py, PyArray3<f64>>,
        Bound<'py, PyArray2<f64>>,
        Bound<'py, numpy::PyArray1<f64>>,
        Vec<usize>,
    )> {
        let rest = self.rest_points(k, points.as_ref())?;
        let z = &self.state(k)?.z;
        let f = self.map(py, k, points)?.deformation_gradients(z);
        crate::outputs::stress_arrays(py, &self.object(k)?.material, &rest, &f)
    }

    /// `splats` (rest centres in object `k`'s rest frame, m) deformed with object `k`: centres
    /// moved, covariances mapped to `F Σ Fᵀ`, higher spherical harmonics rotated; and the
    /// number of splats with det F ≤ 0.
    fn deformed_splats(
        &self,
        py: Python<'_>,
        k: usize,
        splats: &PySplats,
    ) -> PyResult<(PySplats, usize)> {
        let z = self.state(k)?.z;
        crate::outputs::deform_splats(py, &self.object(k)?.basis, &z, splats)
    }

    /// Per-point affine transforms `(n, 4, 4)` of object `k` at its rest `points`: `[F t; 0 1]`
    /// with `x = F X + t` to first order about each point (the blended handle transform).
    #[pyo3(signature = (k, points = None))]
    fn point_transforms<'py>(
        &self,
        py: Python<'py>,
        k: usize,
        points: Option<Points<'py>>,
    ) -> PyResult<Bound<'py, PyArray3<f64>>> {
        let rest = self.rest_points(k, points.as_ref())?;
        let z = &self.state(k)?.z;
        let map = self.map(py, k, points)?;
        let (x, f) = (map.positions(z), map.deformation_gradients(z));
        let transforms = Array3::from_shape_fn((x.len(), 4, 4), |(i, r, c)| match (r, c) {
            (3, 3) => 1.0,
            (3, _) => 0.0,
            (_, 3) => x[i][r] - (f[i] * rest[i])[r],
            _ => f[i][(r, c)],
        });
        Ok(transforms.into_pyarray(py))
    }
}

impl PyScene {
    /// The simulator, or a `SceneError` before the first step.
    fn started(&self) -> PyResult<&MultiBodySimulator<StableNeoHookean>> {
        self.simulator
            .as_ref()
            .ok_or_else(|| SceneError::new_err("the scene has not been stepped yet"))
    }

    /// Object `k` as added.
    fn object(&self, k: usize) -> PyResult<&ObjectInputs> {
        self.objects.get(k).ok_or_else(|| {
            PyValueError::new_err(format!(
                "no object {k}: the scene has {}",
                self.objects.len()
            ))
        })
    }

    /// Object `k`'s state: its placement before the first step.
    fn state(&self, k: usize) -> PyResult<ReducedState> {
        let object = self.object(k)?;
        Ok(match &self.simulator {
            Some(sim) => sim.bodies()[k].simulator().state().clone(),
            None => object
                .placement
                .state(&ReducedLayout::new(object.basis.handles())),
        })
    }

    /// Object `k`'s rest `points` (m), its integration points when `None`.
    fn rest_points(&self, k: usize, points: Option<&Points<'_>>) -> PyResult<Vec<Vector3<f64>>> {
        match points {
            Some(p) => points_of(p, "points"),
            None => Ok(self.object(k)?.points.positions().to_vec()),
        }
    }

    /// Object `k`'s deformation map at `points` (its integration points when `None`).
    fn map(
        &self,
        py: Python<'_>,
        k: usize,
        points: Option<Points<'_>>,
    ) -> PyResult<DeformationMap> {
        let points = self.rest_points(k, points.as_ref())?;
        let basis = &self.object(k)?.basis;
        py.detach(|| DeformationMap::new(basis, &points))
            .map_err(|e| errors::raise::<errors::BasisError>(&e))
    }

    /// The multibody simulator of the objects added, each prepared as a scene file's object is.
    fn build(&self) -> PyResult<MultiBodySimulator<StableNeoHookean>> {
        if self.objects.is_empty() {
            return Err(SceneError::new_err(
                "the scene has no object: add_object first",
            ));
        }
        let planned = match self.objects.len() {
            1 => PlannedRun::single_body(self.spec.steps),
            _ => PlannedRun::multibody(self.spec.steps),
        };
        let mut bodies = Vec::with_capacity(self.objects.len());
        for (k, object) in self.objects.iter().enumerate() {
            let scene = SceneSpec {
                constraints: object.constraints.clone(),
                ..self.shared.clone()
            };
            scene
                .validate()
                .map_err(|e| errors::raise::<SceneError>(&e))?;
            let simulation = Simulation::new(
                &object.basis,
                &object.points,
                &object.material,
                StableNeoHookean,
                &scene,
            )
            .with_params(self.spec.simulation_params())
            .with_quadrature(self.spec.quadrature)
            .with_cache_dir(self.cache_dir.as_deref())
            .with_pin_hold(self.spec.pins)
            .with_placement(Some(object.placement));
            let pins: Vec<PinnedRegion> = object
                .pinned
                .iter()
                .map(|points| PinnedRegion {
                    points: points.clone(),
                    target: PinTarget::Rest,
                })
                .collect();
            let (simulator, _) = prepare_simulator_for(&simulation, planned, &pins)
                .map_err(|e| SceneError::new_err(format!("object {k}: {}", failure_chain(&e))))?;
            let samples = DeformationMap::new(&object.basis, &object.contact_samples)
                .map_err(|e| errors::raise::<errors::BasisError>(&e))?;
            bodies
                .push(Body::new(simulator, samples).map_err(|e| errors::raise::<SceneError>(&e))?);
        }
        MultiBodySimulator::new(bodies, self.contact).map_err(|e| errors::raise::<SceneError>(&e))
    }
}

/// Where an object starts, as Python gives it.
#[derive(serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct PlacementInput {
    #[serde(default)]
    position: Option<[f64; 3]>,
    /// `[i, j, k, w]`.
    #[serde(default)]
    rotation: Option<[f64; 4]>,
    #[serde(default)]
    velocity: Option<[f64; 3]>,
}

impl PlacementInput {
    fn placement(&self) -> PyResult<Placement> {
        let mut placement = Placement::default();
        if let Some(p) = self.position {
            placement.position = Vector3::from(p);
        }
        if let Some(v) = self.velocity {
            placement.velocity = Vector3::from(v);
        }
        if let Some([i, j, k, w]) = self.rotation {
            let q = nalgebra::Quaternion::new(w, i, j, k);
            if !(q.norm() > 0.0) {
                return Err(SceneError::new_err(
                    "placement.rotation: a quaternion [i, j, k, w] that is not zero",
                ));
            }
            placement.rotation = UnitQuaternion::from_quaternion(q);
        }
        if !placement.is_finite() {
            return Err(SceneError::new_err("placement: every value must be finite"));
        }
        Ok(placement)
    }
}
