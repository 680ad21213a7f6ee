//! `freeform.Simulation`: one object stepped from Python.

use std::path::PathBuf;
use std::sync::Arc;

use freeform::reduced_sim::{DeformationMap, PinTarget, PinnedRegion, ReducedState, Simulator};
use freeform::{PinHold, SceneSpec, Simulation, SimulationSpec, prepare_simulator};
use hyperelastic::{MaterialField, StableNeoHookean};
use nalgebra::{Matrix3, Vector3};
use numpy::ndarray::Array1;
use numpy::{IntoPyArray, PyArray1, PyArray2, PyArray3};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use skin_eigen::SkinningBasis;

use crate::arrays::{self, Points, points_array, points_of};
use crate::basis::PyBasis;
use crate::errors::{self, value_error};
use crate::material::PyMaterial;
use crate::outputs::{deform_splats, matrices_array, stress_arrays};
use crate::points::PyIntegrationPoints;
use crate::splats::PySplats;
use crate::threads::{on_pool, thread_pool};

/// The `[simulation]` settings of a run on a basis the caller built (JSON text): a basis built
/// without regions is held by the pin penalty and integrates the pointwise volumetric term, so
/// `pins` and `pressure` default to `"penalty"` and `"pointwise"` here, not to a scene file's
/// defaults (which build the basis for its regions and a pressure space).
///
/// # Errors
/// The JSON error of text that is not such settings.
pub(crate) fn settings_for_given_basis(json: &str) -> serde_json::Result<SimulationSpec> {
    let mut value: serde_json::Value = serde_json::from_str(json)?;
    if let Some(table) = value.as_object_mut() {
        table.entry("pins").or_insert_with(|| "penalty".into());
        table
            .entry("pressure")
            .or_insert_with(|| "pointwise".into());
    }
    serde_json::from_value(value)
}

/// A reduced simulation that Python steps: a basis, its integration points and material,
/// a scene and the simulation settings, both in the scene-file format (`docs/scene-files.md`,
/// the `[scene]` and `[simulation]` tables, as JSON text).
#[pyclass(module = "freeform._native", name = "Simulation")]
pub(crate) struct PySimulation {
    simulator: Simulator<StableNeoHookean>,
    basis: SkinningBasis,
    /// The material, for the stress.
    material: MaterialField,
    /// The integration points' rest positions (m).
    points: Vec<Vector3<f64>>,
    quadrature: String,
    /// Steps taken since it was built (the `StepError.step` of the next failure is one more).
    steps_taken: usize,
    /// The pool its setup and steps run on (`None`: the global pool).
    pool: Option<Arc<rayon::ThreadPool>>,
}

#[pymethods]
impl PySimulation {
    /// `scene` and `simulation` are JSON text of the scene file's `[scene]` and `[simulation]`
    /// tables (every key optional); `simulation.steps` is the run's planned length, which the
    /// automatic quadrature weighs. Held (exact, weighted) pins and a pressure space need a
    /// basis built for them: use `simulate_scene_file` for those.
    ///
    /// `pinned`: sets of integration-point indices held at rest by the same penalty as the
    /// scene's constraints (e.g. from a mask over the points). `threads`: the threads its
    /// setup and steps run on (all cores when None; a fixed count gives bit-identical runs).
    #[new]
    #[pyo3(signature = (basis, points, material, scene, simulation, cache_dir = None, pinned = Vec::new(), threads = None))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        basis: &PyBasis,
        points: &PyIntegrationPoints,
        material: &PyMaterial,
        scene: &str,
        simulation: &str,
        cache_dir: Option<PathBuf>,
        pinned: Vec<Vec<usize>>,
        threads: Option<usize>,
    ) -> PyResult<Self> {
        let pool = thread_pool(threads)?;
        let scene: SceneSpec = serde_json::from_str(scene)
            .map_err(|e| errors::SceneError::new_err(format!("scene: {e}")))?;
        scene
            .validate()
            .map_err(|e| errors::raise::<errors::SceneError>(&e))?;
        let spec = settings_for_given_basis(simulation)
            .map_err(|e| errors::SceneError::new_err(format!("simulation: {e}")))?;
        if let Some((field, problem)) = spec.defect() {
            return Err(errors::SceneError::new_err(format!("{field}: {problem}")));
        }
        if spec.pins != PinHold::Penalty || spec.pressure.is_some() {
            return Err(errors::SceneError::new_err(
                "simulation.pins other than \"penalty\" and simulation.pressure need a basis \
                 built for them: use simulate_scene_file",
            ));
        }
        let field = material.field();
        let simulation = Simulation::new(
            &basis.inner,
            &points.inner,
            &field,
            StableNeoHookean,
            &scene,
        )
        .with_params(spec.simulation_params())
        .with_quadrature(spec.quadrature)
        .with_cache_dir(cache_dir.as_deref())
        .with_pin_hold(spec.pins);
        let n = points.inner.len();
        if let Some(i) = pinned.iter().flatten().find(|&&i| i >= n) {
            return Err(PyValueError::new_err(format!(
                "pinned point {i} is not one of the {n} integration points"
            )));
        }
        let pins: Vec<PinnedRegion> = pinned
            .into_iter()
            .map(|points| PinnedRegion {
                points,
                target: PinTarget::Rest,
            })
            .collect();
        let (simulator, quadrature) = py
            .detach(|| {
                on_pool(pool.as_deref(), || {
                    prepare_simulator(&simulation, spec.steps, &pins)
                })
            })
            .map_err(|e| errors::raise::<errors::SceneError>(&e))?;
        let quadrature = serde_json::to_string(&quadrature).map_err(|e| value_error(&e))?;
        Ok(PySimulation {
            simulator,
            basis: basis.inner.clone(),
            material: field.clone(),
            points: points.inner.positions().to_vec(),
            quadrature,
            steps_taken: 0,
            pool,
        })
    }

    /// Advances one backward-Euler step; returns the Newton report as JSON text
    /// (`converged`, `iterations`, `hessian_assemblies`, `residual`, ...).
    fn step(&mut self, py: Python<'_>) -> PyResult<String> {
        let (simulator, pool) = (&mut self.simulator, self.pool.as_deref());
        let report = py
            .detach(|| on_pool(pool, || simulator.step()))
            .map_err(|e| errors::step_error(Some(self.steps_taken + 1), &e))?;
        self.steps_taken += 1;
        let json = serde_json::json!({
            "converged": report.converged(),
            "iterations": report.iterations,
            "hessian_assemblies": report.hessian_assemblies,
            "line_search_cuts": report.line_search_cuts,
            "residual": report.residual,
        });
        Ok(json.to_string())
    }

    /// Simulated time t (s).
    #[getter]
    fn time(&self) -> f64 {
        self.simulator.state().time
    }

    /// Replaces the state: coordinates z and their velocity ż (`(12(m + 1),)` each) and the
    /// time t (s).
    fn set_state(&mut self, coordinates: Vec<f64>, velocity: Vec<f64>, time: f64) -> PyResult<()> {
        self.simulator
            .set_state(ReducedState {
                z: coordinates,
                velocity,
                time,
            })
            .map_err(|e| value_error(&e))
    }

    /// Velocity ż of the reduced coordinates, `(12(m + 1),)`.
    #[getter]
    fn velocity<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        Array1::from(self.simulator.state().velocity.clone()).into_pyarray(py)
    }

    /// Reduced coordinates z, `(12(m + 1),)`: each handle's 3 × 4 affine transform minus the
    /// identity, row-major by transform row.
    #[getter]
    fn coordinates<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        Array1::from(self.simulator.state().z.clone()).into_pyarray(py)
    }

    /// Kinetic + elastic + gravitational + penalty energy at the current state (J).
    #[getter]
    fn mechanical_energy(&self) -> f64 {
        self.simulator.mechanical_energy()
    }

    /// The elastic quadrature used, as JSON text (`kind`, `points`, `cubature`, `choice`).
    #[getter]
    fn quadrature(&self) -> String {
        self.quadrature.clone()
    }

    /// Deformed positions `(n, 3)` (m) of rest `points` (`(n, 3)`, m; the integration points
    /// when omitted), written into `out` (a C-contiguous `(n, 3)` float64 array) and `out`
    /// returned when given.
    #[pyo3(signature = (points = None, out = None))]
    fn deformed_points<'py>(
        &self,
        py: Python<'py>,
        points: Option<Points<'py>>,
        out: Option<Bound<'py, PyArray2<f64>>>,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let z = &self.simulator.state().z;
        let deformed = match self.map_at(py, points)? {
            None => self.simulator.model().deformation_map().positions(z),
            Some(map) => map.positions(z),
        };
        match out {
            Some(out) => arrays::write_points_into(out, &deformed),
            None => Ok(points_array(py, &deformed)),
        }
    }

    /// Deformation gradients F = ∂x/∂X `(n, 3, 3)` (row i, column j: ∂x_i/∂X_j) at rest
    /// `points` (`(n, 3)`, m; the integration points when omitted).
    #[pyo3(signature = (points = None))]
    fn deformation_gradients<'py>(
        &self,
        py: Python<'py>,
        points: Option<Points<'py>>,
    ) -> PyResult<Bound<'py, PyArray3<f64>>> {
        let f = self.gradients_at(py, points)?;
        Ok(matrices_array(py, &f))
    }

    /// `splats` (rest centres in m) deformed by the current state: each centre moved, its
    /// covariance mapped to `F Σ Fᵀ` and its higher spherical harmonics rotated by F's
    /// rotation, F taken at its rest centre; and the number of splats with det F ≤ 0.
    fn deformed_splats(&self, py: Python<'_>, splats: &PySplats) -> PyResult<(PySplats, usize)> {
        deform_splats(py, &self.basis, &self.simulator.state().z, splats)
    }

    /// The stress at rest `points` (the integration points when omitted) of the simulation's
    /// material: Cauchy σ `(n, 3, 3)`, principal stresses σ₁ ≥ σ₂ ≥ σ₃ `(n, 3)` and von
    /// Mises `(n,)` (Pa), and the indices of inverted points (det F ≤ 0), whose stress is 0.
    #[pyo3(signature = (points = None))]
    #[allow(clippy::type_complexity)]
    fn stress<'py>(
        &self,
        py: Python<'py>,
        points: Option<Points<'py>>,
    ) -> PyResult<(
        Bound<'py, PyArray3<f64>>,
        Bound<'py, PyArray2<f64>>,
        Bound<'py, PyArray1<f64>>,
        Vec<usize>,
    )> {
        let rest = match &points {
            Some(p) => points_of(p, "points")?,
            None => self.points.clone(),
        };
        let f = self.gradients_at(py, points)?;
        stress_arrays(py, &self.material, &rest, &f)
    }
}

impl PySimulation {
    /// The deformation map at `points`, or `None` for the integration points.
    fn map_at(
        &self,
        py: Python<'_>,
        points: Option<Points<'_>>,
    ) -> PyResult<Option<DeformationMap>> {
        let Some(points) = points else {
            return Ok(None);
        };
        let points = points_of(&points, "points")?;
        let basis = &self.basis;
        py.detach(|| DeformationMap::new(basis, &points))
            .map(Some)
            .map_err(|e| errors::raise::<errors::BasisError>(&e))
    }

    /// F at `points` (the integration points when `None`).
    fn gradients_at(
        &self,
        py: Python<'_>,
        points: Option<Points<'_>>,
    ) -> PyResult<Vec<Matrix3<f64>>> {
        let z = &self.simulator.state().z;
        Ok(match self.map_at(py, points)? {
            None => self
                .simulator
                .model()
                .deformation_map()
                .deformation_gradients(z),
            Some(map) => map.deformation_gradients(z),
        })
    }
}
