//! Python bindings of FreeForm: the extension module `freeform._native`, re-exported by the
//! pure-Python package `freeform` (`python/freeform/__init__.py`).
//!
//! Conventions at the boundary: SI units, float64, points as `(n, 3)` arrays. Long calls
//! (a basis, a simulation) release the GIL. Errors are `FreeFormError` subclasses
//! (`errors`), `FileNotFoundError` for a missing file, `ValueError` for an argument of the
//! wrong shape, with the whole chain of causes in the message.

mod arrays;
mod errors;
mod material;
mod scene;

use std::path::PathBuf;

use arrays::{Points, matrix_array, points_array, points_of};
pub(crate) use material::PyMaterial;

use freeform::reduced_sim::{DeformationMap, PinTarget, PinnedRegion, ReducedState, Simulator};
use freeform::{
    FrameWriter, Geometry, ObjectsFile, PinHold, Progress, SceneFile, SceneSpec, Silent,
    Simulation, SimulationSpec, SplatTable, StressField, failure_chain, points_preview,
    prepare_simulator, simulate_objects, simulate_scene_file as run_scene_file,
};
use hyperelastic::{MaterialField, StableNeoHookean};
use nalgebra::{Matrix3, Vector3};
use numpy::ndarray::{Array1, Array2, Array3};
use numpy::{IntoPyArray, PyArray1, PyArray2, PyArray3};
use pyo3::exceptions::{PyFileNotFoundError, PyOSError, PyValueError};
use pyo3::prelude::*;
use rkpm_core::{IntegrationPoints, PointCloud, TriangleMesh};
use skin_eigen::{
    BasisParams, SkinningBasis, SkinningWeights, build_basis as build_skinning_basis,
};

/// `ValueError` with `error`'s chain of causes.
fn value_error(error: &dyn std::error::Error) -> PyErr {
    PyValueError::new_err(failure_chain(error))
}

/// Runs `work` on a rayon pool of `threads` threads (all cores when `None`).
fn with_threads<T: Send>(threads: Option<usize>, work: impl FnOnce() -> T + Send) -> PyResult<T> {
    match threads {
        None => Ok(work()),
        Some(0) => Err(PyValueError::new_err("threads must be at least 1")),
        Some(n) => rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build()
            .map(|pool| pool.install(work))
            .map_err(|e| value_error(&e)),
    }
}

/// Progress handed to a Python callable `progress(label, done, total)`: a stage's label with
/// the units done and its length, or a status line with `done` and `total` None. An exception
/// the callable raises is printed and the work goes on.
struct PythonProgress {
    callable: Py<PyAny>,
    /// The current stage's label, units done and length.
    stage: std::sync::Mutex<(String, usize, usize)>,
}

impl PythonProgress {
    fn call(&self, label: &str, done: Option<usize>, total: Option<usize>) {
        Python::attach(|py| {
            if let Err(e) = self.callable.call1(py, (label, done, total)) {
                e.print(py);
            }
        });
    }
}

impl Progress for PythonProgress {
    fn begin(&self, len: usize, label: &str) {
        if let Ok(mut stage) = self.stage.lock() {
            *stage = (label.to_string(), 0, len);
        }
        self.call(label, Some(0), Some(len));
    }

    fn advance(&self) {
        let Ok(mut stage) = self.stage.lock() else {
            return;
        };
        stage.1 += 1;
        let (label, done, len) = stage.clone();
        drop(stage);
        self.call(&label, Some(done), Some(len));
    }

    fn status(&self, line: &str) {
        self.call(line, None, None);
    }
}

/// A shape: a closed triangle surface or a point cloud (m).
#[pyclass(module = "freeform._native", name = "Geometry", frozen)]
pub(crate) struct PyGeometry {
    pub(crate) inner: Geometry,
}

#[pymethods]
impl PyGeometry {
    /// Reads a closed mesh (OBJ, STL, PLY with faces) or, from a PLY without faces, a point
    /// cloud (plain or 3DGS).
    #[staticmethod]
    fn read(path: PathBuf) -> PyResult<Self> {
        Geometry::read(&path)
            .map(|inner| PyGeometry { inner })
            .map_err(|e| errors::geometry_error(&e))
    }

    /// The axis-aligned box from corner `lo` to corner `hi` (m).
    #[staticmethod]
    #[pyo3(name = "box")]
    fn cuboid(lo: [f64; 3], hi: [f64; 3]) -> PyResult<Self> {
        if !(0..3).all(|k| lo[k].is_finite() && hi[k].is_finite() && lo[k] < hi[k]) {
            return Err(PyValueError::new_err(format!(
                "a box needs finite corners with lo < hi on every axis, got lo {lo:?}, hi {hi:?}"
            )));
        }
        Ok(PyGeometry {
            inner: Geometry::cuboid(Vector3::from(lo), Vector3::from(hi)),
        })
    }

    /// A closed triangle surface from vertices `(n, 3)` (m) and triangles `(t, 3)` (vertex
    /// indices, counter-clockwise seen from outside).
    #[staticmethod]
    fn from_mesh(vertices: Points<'_>, triangles: Vec<[usize; 3]>) -> PyResult<Self> {
        let vertices = points_of(&vertices, "vertices")?;
        TriangleMesh::new(vertices, triangles)
            .map(|mesh| PyGeometry {
                inner: Geometry::Surface(mesh),
            })
            .map_err(|e| errors::raise::<errors::GeometryError>(&e))
    }

    /// A point cloud from an `(n, 3)` array of points (m).
    #[staticmethod]
    fn from_points(points: Points<'_>) -> PyResult<Self> {
        let points = points_of(&points, "points")?;
        if points.is_empty() {
            return Err(PyValueError::new_err(
                "a point cloud needs at least one point",
            ));
        }
        Ok(PyGeometry {
            inner: Geometry::Cloud(PointCloud::new(points, None)),
        })
    }

    /// About `n` integration points with their volumes: a grid inside a surface, or the
    /// cloud's points (down-sampled) with volumes from the voxels they fill.
    fn integration_points(&self, py: Python<'_>, n: usize) -> PyResult<PyIntegrationPoints> {
        let geometry = &self.inner;
        py.detach(|| geometry.integration_points(n))
            .map(|inner| PyIntegrationPoints { inner })
            .map_err(|e| errors::geometry_error(&e))
    }

    /// `(n, 3)` points that show the shape: the surface's vertices or the cloud's points (m).
    fn display_points<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        points_array(py, self.inner.display_points())
    }

    fn __repr__(&self) -> String {
        match &self.inner {
            Geometry::Surface(mesh) => format!(
                "Geometry(surface: {} vertices, {} triangles)",
                mesh.vertices().len(),
                mesh.triangles().len()
            ),
            Geometry::Cloud(cloud) => format!("Geometry(cloud: {} points)", cloud.len()),
        }
    }
}

/// Writes frames of a geometry's display points (its surface's vertices, or its cloud) as PLY
/// and VTK files (`frame_NNNNN.ply` / `.vtk`), for ParaView, Blender or MeshLab.
#[pyclass(module = "freeform._native", name = "FrameWriter", frozen)]
struct PyFrameWriter {
    inner: FrameWriter,
}

#[pymethods]
impl PyFrameWriter {
    /// A writer into folder `out_dir` for `geometry`.
    #[new]
    fn new(out_dir: PathBuf, geometry: &PyGeometry) -> Self {
        PyFrameWriter {
            inner: FrameWriter::new(out_dir, &geometry.inner),
        }
    }

    /// The rest positions `(n, 3)` (m) the frames deform: pass these to
    /// `Simulation.deformed_points` and write what it returns.
    #[getter]
    fn rest_positions<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        points_array(py, self.inner.rest_positions())
    }

    /// Writes frame `index` at `time` (s) with the display points at `positions` (`(n, 3)`, m,
    /// in the order of `rest_positions`); returns the PLY and VTK paths.
    fn write(
        &self,
        index: usize,
        positions: Points<'_>,
        time: f64,
    ) -> PyResult<(PathBuf, PathBuf)> {
        let positions = points_of(&positions, "positions")?;
        let expected = self.inner.rest_positions().len();
        if positions.len() != expected {
            return Err(PyValueError::new_err(format!(
                "{} positions for {expected} display points",
                positions.len()
            )));
        }
        let [ply, vtk] = self
            .inner
            .write(index, &positions, time)
            .map_err(|e| errors::raise::<PyOSError>(&e))?;
        Ok((ply, vtk))
    }
}

/// Integration points x_i (m) with their volumes v_i (m³).
#[pyclass(module = "freeform._native", name = "IntegrationPoints", frozen)]
pub(crate) struct PyIntegrationPoints {
    pub(crate) inner: IntegrationPoints,
}

#[pymethods]
impl PyIntegrationPoints {
    /// Integration points from an `(n, 3)` array of positions (m) and `n` volumes (m³).
    #[new]
    fn new(positions: Points<'_>, volumes: Vec<f64>) -> PyResult<Self> {
        let positions = points_of(&positions, "positions")?;
        IntegrationPoints::new(positions, volumes)
            .map(|inner| PyIntegrationPoints { inner })
            .map_err(|e| errors::raise::<errors::GeometryError>(&e))
    }

    /// `(n, 3)` positions (m).
    #[getter]
    fn positions<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        points_array(py, self.inner.positions())
    }

    /// `(n,)` volumes (m³).
    #[getter]
    fn volumes<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        Array1::from(self.inner.volumes().to_vec()).into_pyarray(py)
    }

    fn __len__(&self) -> usize {
        self.inner.len()
    }

    fn __repr__(&self) -> String {
        let volume: f64 = self.inner.volumes().iter().sum();
        format!(
            "IntegrationPoints({} points, volume {volume:.6} m³)",
            self.inner.len()
        )
    }
}

/// A skinning basis: m eigenmode weights plus the constant handle, evaluated anywhere in the
/// shape.
#[pyclass(module = "freeform._native", name = "Basis", frozen)]
pub(crate) struct PyBasis {
    pub(crate) inner: SkinningBasis,
}

impl PyBasis {
    /// W and ∇W at `points`, evaluated without the GIL.
    fn evaluate(&self, py: Python<'_>, points: &Points<'_>) -> PyResult<SkinningWeights> {
        let points = points_of(points, "points")?;
        let basis = &self.inner;
        py.detach(|| basis.evaluate(&points))
            .map_err(|e| errors::raise::<errors::BasisError>(&e))
    }
}

#[pymethods]
impl PyBasis {
    /// Modes m (the handles are m + 1 with the constant one).
    #[getter]
    fn modes(&self) -> usize {
        self.inner.modes()
    }

    /// Handles m + 1 (the constant handle first).
    #[getter]
    fn handles(&self) -> usize {
        self.inner.handles()
    }

    /// The m generalized eigenvalues of the modes, ascending.
    #[getter]
    fn eigenvalues(&self) -> Vec<f64> {
        self.inner.eigenvalues().to_vec()
    }

    /// Weights W at `points` (`(n, 3)`, m): `(n, m + 1)`, column 0 the constant handle (1).
    fn weights<'py>(
        &self,
        py: Python<'py>,
        points: Points<'py>,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let evaluated = self.evaluate(py, &points)?;
        Ok(matrix_array(py, &evaluated.weights))
    }

    /// Weight gradients ∇W at `points` (`(n, 3)`, m): `(n, m + 1, 3)` (1/m).
    fn weight_gradients<'py>(
        &self,
        py: Python<'py>,
        points: Points<'py>,
    ) -> PyResult<Bound<'py, PyArray3<f64>>> {
        let evaluated = self.evaluate(py, &points)?;
        let g = &evaluated.gradients;
        let shape = (g[0].nrows(), self.inner.handles(), 3);
        Ok(Array3::from_shape_fn(shape, |(i, j, k)| g[k][(i, j)]).into_pyarray(py))
    }

    /// Writes the basis to `path` (the library's versioned binary format).
    fn save(&self, path: PathBuf) -> PyResult<()> {
        self.inner
            .save(&path)
            .map_err(|e| errors::raise::<PyOSError>(&e))
    }

    /// Reads a basis written by `save`.
    #[staticmethod]
    fn load(path: PathBuf) -> PyResult<Self> {
        if !path.is_file() {
            return Err(PyFileNotFoundError::new_err(format!(
                "{}: no such file",
                path.display()
            )));
        }
        SkinningBasis::load(&path)
            .map(|inner| PyBasis { inner })
            .map_err(|e| errors::raise::<errors::FileFormatError>(&e))
    }

    fn __repr__(&self) -> String {
        format!(
            "Basis({} modes, {} kernels)",
            self.inner.modes(),
            self.inner.kernels().len()
        )
    }
}

/// Builds the skinning basis of `points` (Sec. 4–5): `kernels` RKPM kernels, the `modes`
/// lowest generalized eigenmodes of the elastic Hessian at rest against the mass.
/// `threads`: the threads it may use (all cores when None).
#[pyfunction]
#[pyo3(signature = (points, material, modes = 16, kernels = 1000, threads = None))]
fn build_basis(
    py: Python<'_>,
    points: &PyIntegrationPoints,
    material: &PyMaterial,
    modes: usize,
    kernels: usize,
    threads: Option<usize>,
) -> PyResult<PyBasis> {
    let lame = material.lame_at(points.inner.positions())?;
    let params = BasisParams::default()
        .with_modes(modes)
        .with_kernels(kernels);
    let points = &points.inner;
    py.detach(|| with_threads(threads, || build_skinning_basis(points, &lame, &params)))?
        .map(|(inner, _, _)| PyBasis { inner })
        .map_err(|e| errors::raise::<errors::BasisError>(&e))
}

/// Runs a scene file (TOML or JSON, one object or several) and writes its frames and
/// `summary.json` under `out_dir`; returns the summary as JSON text. Cubatures are cached
/// under `cache_dir` when given. `threads`: the threads it may use (all cores when None);
/// `progress`: a callable `progress(label, done, total)` (see [`PythonProgress`]).
#[pyfunction]
#[pyo3(signature = (path, out_dir, cache_dir = None, threads = None, progress = None))]
fn simulate_scene_file(
    py: Python<'_>,
    path: PathBuf,
    out_dir: PathBuf,
    cache_dir: Option<PathBuf>,
    threads: Option<usize>,
    progress: Option<Py<PyAny>>,
) -> PyResult<String> {
    let cache = cache_dir.as_deref();
    let progress: Box<dyn Progress> = match progress {
        None => Box::new(Silent),
        Some(callable) => Box::new(PythonProgress {
            callable,
            stage: Default::default(),
        }),
    };
    let progress = progress.as_ref();
    let summary = py.detach(|| {
        with_threads(threads, || -> PyResult<String> {
            let json = if ObjectsFile::describes(&path) {
                let file = ObjectsFile::load(&path).map_err(|e| errors::scene_file_error(&e))?;
                let report = simulate_objects(&file, &out_dir, cache, progress)
                    .map_err(|e| errors::simulate_error(&e))?;
                serde_json::to_string(&report)
            } else {
                let file = SceneFile::load(&path).map_err(|e| errors::scene_file_error(&e))?;
                let report = run_scene_file(&file, &out_dir, cache, progress)
                    .map_err(|e| errors::simulate_error(&e))?;
                serde_json::to_string(&report)
            };
            json.map_err(|e| value_error(&e))
        })
    })??;
    Ok(summary)
}

/// The vertex table of a 3DGS PLY file (binary little-endian), kept byte for byte: what a
/// deformation rewrites (centres, scales, rotations, higher SH) is typed, the rest is carried.
#[pyclass(module = "freeform._native", name = "Splats", frozen)]
pub(crate) struct PySplats {
    inner: SplatTable,
}

#[pymethods]
impl PySplats {
    /// Reads a 3DGS PLY file.
    #[staticmethod]
    fn read(path: PathBuf) -> PyResult<Self> {
        SplatTable::read(&path)
            .map(|inner| PySplats { inner })
            .map_err(|e| errors::splat_error(&e))
    }

    /// Writes the table (atomically).
    fn write(&self, path: PathBuf) -> PyResult<()> {
        self.inner.write(&path).map_err(|e| errors::splat_error(&e))
    }

    /// Splat centres `(n, 3)` (file units, m for a simulated scene).
    #[getter]
    fn positions<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        points_array(py, &self.inner.positions())
    }

    /// Covariances `Σ = R diag(exp(2 s)) Rᵀ` `(n, 3, 3)` (file units²).
    #[getter]
    fn covariances<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray3<f64>> {
        let c = self.inner.covariances();
        Array3::from_shape_fn((c.len(), 3, 3), |(i, r, k)| c[i][(r, k)]).into_pyarray(py)
    }

    /// Covariances packed `(n, 6)` as `(xx, xy, xz, yy, yz, zz)`, the upper triangle that 3DGS
    /// rasterizers take (file units²).
    #[getter]
    fn packed_covariances<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        const UPPER: [(usize, usize); 6] = [(0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)];
        let c = self.inner.covariances();
        Array2::from_shape_fn((c.len(), 6), |(i, k)| c[i][UPPER[k]]).into_pyarray(py)
    }

    /// The property names of a splat, in file order.
    #[getter]
    fn properties(&self) -> Vec<String> {
        self.inner
            .property_names()
            .into_iter()
            .map(str::to_string)
            .collect()
    }

    /// The values `(n,)` of property `name` (e.g. `opacity`, `f_dc_0`).
    fn column<'py>(&self, py: Python<'py>, name: &str) -> PyResult<Bound<'py, PyArray1<f64>>> {
        self.inner
            .column(name)
            .map(|c| Array1::from(c).into_pyarray(py))
            .ok_or_else(|| PyValueError::new_err(format!("the splats have no property {name:?}")))
    }

    fn __len__(&self) -> usize {
        self.inner.len()
    }

    fn __repr__(&self) -> String {
        format!("Splats({} splats)", self.inner.len())
    }
}

/// A reduced simulation that Python steps: a basis, its integration points and material,
/// a scene and the simulation settings, both in the scene-file format (`docs/scene-files.md`,
/// the `[scene]` and `[simulation]` tables, as JSON text).
#[pyclass(module = "freeform._native", name = "Simulation")]
struct PySimulation {
    simulator: Simulator<StableNeoHookean>,
    basis: SkinningBasis,
    /// The material, for the stress.
    material: MaterialField,
    /// The integration points' rest positions (m).
    points: Vec<Vector3<f64>>,
    quadrature: String,
    /// Steps taken since it was built (the `StepError.step` of the next failure is one more).
    steps_taken: usize,
}

#[pymethods]
impl PySimulation {
    /// `scene` and `simulation` are JSON text of the scene file's `[scene]` and `[simulation]`
    /// tables (every key optional); `simulation.steps` is the run's planned length, which the
    /// automatic quadrature weighs. Held (exact, weighted) pins and a pressure space need a
    /// basis built for them: use `simulate_scene_file` for those.
    ///
    /// `pinned`: sets of integration-point indices held at rest by the same penalty as the
    /// scene's constraints (e.g. from a mask over the points).
    #[new]
    #[pyo3(signature = (basis, points, material, scene, simulation, cache_dir = None, pinned = Vec::new()))]
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
    ) -> PyResult<Self> {
        let scene: SceneSpec = serde_json::from_str(scene)
            .map_err(|e| errors::SceneError::new_err(format!("scene: {e}")))?;
        scene
            .validate()
            .map_err(|e| errors::raise::<errors::SceneError>(&e))?;
        let spec: SimulationSpec = serde_json::from_str(simulation)
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
            .detach(|| prepare_simulator(&simulation, spec.steps, &pins))
            .map_err(|e| errors::raise::<errors::SceneError>(&e))?;
        let quadrature = serde_json::to_string(&quadrature).map_err(|e| value_error(&e))?;
        Ok(PySimulation {
            simulator,
            basis: basis.inner.clone(),
            material: field.clone(),
            points: points.inner.positions().to_vec(),
            quadrature,
            steps_taken: 0,
        })
    }

    /// Advances one backward-Euler step; returns the Newton report as JSON text
    /// (`converged`, `iterations`, `hessian_assemblies`, `residual`, ...).
    fn step(&mut self, py: Python<'_>) -> PyResult<String> {
        let simulator = &mut self.simulator;
        let report = py
            .detach(|| simulator.step())
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
        Ok(Array3::from_shape_fn((f.len(), 3, 3), |(i, r, c)| f[i][(r, c)]).into_pyarray(py))
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

/// `splats` (rest centres, m) deformed by `basis` at coordinates `z`, and the number of splats
/// with det F ≤ 0.
fn deform_splats(
    py: Python<'_>,
    basis: &SkinningBasis,
    z: &[f64],
    splats: &PySplats,
) -> PyResult<(PySplats, usize)> {
    let table = &splats.inner;
    let (deformed, inverted) = py
        .detach(|| -> Result<_, Box<dyn std::error::Error + Send + Sync>> {
            let map = DeformationMap::new(basis, &table.positions())?;
            Ok(table.deformed(&map.positions(z), &map.deformation_gradients(z))?)
        })
        .map_err(|e| errors::raise::<errors::BasisError>(e.as_ref()))?;
    Ok((PySplats { inner: deformed }, inverted))
}

/// The stress of `material` with deformation gradients `f` at rest positions `rest`: Cauchy σ
/// `(n, 3, 3)`, principal stresses `(n, 3)`, von Mises `(n,)` (Pa), inverted points.
#[allow(clippy::type_complexity)]
fn stress_arrays<'py>(
    py: Python<'py>,
    material: &MaterialField,
    rest: &[Vector3<f64>],
    f: &[Matrix3<f64>],
) -> PyResult<(
    Bound<'py, PyArray3<f64>>,
    Bound<'py, PyArray2<f64>>,
    Bound<'py, PyArray1<f64>>,
    Vec<usize>,
)> {
    let lame = material
        .sample(rest)
        .iter()
        .map(|m| m.lame_parameters())
        .collect::<Result<Vec<_>, _>>()
        .map_err(|e| errors::raise::<errors::SceneError>(&e))?;
    let field = StressField::new(&StableNeoHookean, &lame, f).map_err(|e| value_error(&e))?;
    let samples = &field.samples;
    let n = samples.len();
    let cauchy = Array3::from_shape_fn((n, 3, 3), |(i, r, c)| samples[i].cauchy[(r, c)]);
    let principal = Array2::from_shape_fn((n, 3), |(i, k)| samples[i].principal[k]);
    let von_mises = Array1::from_iter(samples.iter().map(|s| s.von_mises));
    Ok((
        cauchy.into_pyarray(py),
        principal.into_pyarray(py),
        von_mises.into_pyarray(py),
        field.inverted,
    ))
}

/// A `(height, width, 3)` uint8 RGB preview of `points` (`(n, 3)`, m) seen from 30° about and
/// 20° above `up`, each point a round splat, coloured by `values` (`(n,)`, e.g. von Mises
/// stress; grey without) with `opacity` (`(n,)` in [0, 1]; opaque without), on white.
#[pyfunction]
#[pyo3(signature = (points, values = None, opacity = None, up = [0.0, 1.0, 0.0], width = 512, height = 512))]
fn render_preview<'py>(
    py: Python<'py>,
    points: Points<'py>,
    values: Option<Vec<f64>>,
    opacity: Option<Vec<f64>>,
    up: [f64; 3],
    width: usize,
    height: usize,
) -> PyResult<Bound<'py, PyArray3<u8>>> {
    let points = points_of(&points, "points")?;
    let image = py
        .detach(|| {
            points_preview(
                &points,
                values.as_deref(),
                opacity.as_deref(),
                Vector3::from(up),
                width,
                height,
            )
        })
        .map_err(|e| value_error(&e))?;
    let shape = (image.height, image.width, 3);
    Ok(Array3::from_shape_fn(shape, |(y, x, c)| image.pixel(x, y)[c]).into_pyarray(py))
}

/// The extension module.
#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyGeometry>()?;
    m.add_class::<PyIntegrationPoints>()?;
    m.add_class::<PyMaterial>()?;
    m.add_class::<PyBasis>()?;
    m.add_class::<PySimulation>()?;
    m.add_class::<scene::PyScene>()?;
    m.add_class::<PySplats>()?;
    m.add_class::<PyFrameWriter>()?;
    m.add_function(wrap_pyfunction!(build_basis, m)?)?;
    m.add_function(wrap_pyfunction!(simulate_scene_file, m)?)?;
    m.add_function(wrap_pyfunction!(render_preview, m)?)?;
    errors::register(m)?;
    Ok(())
}
