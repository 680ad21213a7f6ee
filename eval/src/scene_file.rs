//! User scenes for `freeform simulate`: a TOML or JSON file naming the geometry, material, basis
//! settings, what acts on the object and how long to run; the run writes per-frame PLY and VTK
//! of the deformed surface.
//!
//! ```toml
//! [geometry]
//! mesh = "../data/meshes/bunny.obj"           # OBJ/STL/PLY, relative to this file; or
//! # box = { min = [0, 0, 0], max = [5, 1, 1] }
//! normalize = true                            # scale so the largest side is 1 m (default true)
//!
//! [material]                                  # SI units
//! youngs_modulus = 1e5
//! poisson_ratio = 0.45
//! density = 1000
//!
//! [basis]
//! modes = 16        # m
//! kernels = 1000    # K
//! points = 20000    # grid points the basis is built on
//!
//! [simulation]
//! time_step = 0.01  # s
//! steps = 100
//! points = 5000     # grid points the simulation integrates over
//! output_every = 5  # write every 5th frame (default 1)
//!
//! [scene]
//! gravity = [0, -9.8, 0]
//! [[scene.constraints]]
//! region = { below = { axis = 1, value = 0.05 } }
//! motion = "rest"
//! [[scene.constraints]]          # regions: below, above (a half-space), ball
//! region = { ball = { center = [0.5, 0.5, 0.4], radius = 0.1 } }
//! motion = { translate = { velocity = [0, 0.2, 0] } }
//! ```

use hyperelastic::MaterialSample;
use std::path::{Path, PathBuf};
use std::time::Instant;

use hyperelastic::StableNeoHookean;
use nalgebra::Vector3;
use reduced_sim::{DeformationMap, ReducedModel, SimulationParams, Simulator};
use rkpm_core::{GridSamplingParams, TriangleMesh, read_triangle_mesh, sample_grid};
use serde::{Deserialize, Serialize};
use skin_eigen::{BasisParams, build_basis};
use thiserror::Error;

use crate::EvalError;
use crate::output::{triangle_mesh_ply, unstructured_grid_vtk, write_atomically};
use crate::progress::Progress;
use crate::scene_spec::SceneSpec;

/// A scene file is unusable.
#[derive(Debug, Error)]
pub enum SceneFileError {
    /// The file could not be read.
    #[error("{path}: {source}")]
    Read {
        /// The file.
        path: String,
        /// Why.
        source: std::io::Error,
    },
    /// The text is not a valid scene (the message names the field and position).
    #[error("{path}: {message}")]
    Parse {
        /// The file.
        path: String,
        /// The parser's message.
        message: String,
    },
    /// A value is out of range.
    #[error("{path}: {field}: {problem}")]
    Invalid {
        /// The file.
        path: String,
        /// Dotted field name.
        field: String,
        /// What is wrong.
        problem: String,
    },
}

/// The object's shape.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GeometrySpec {
    /// A closed triangle mesh (path relative to the scene file).
    #[serde(default)]
    pub mesh: Option<PathBuf>,
    /// Or an axis-aligned box `{ min, max }` (m).
    #[serde(default, rename = "box")]
    pub cuboid: Option<BoxSpec>,
    /// Scale so the largest bounding-box side is 1 m (default true; ignored for a box).
    #[serde(default = "yes")]
    pub normalize: bool,
}

fn yes() -> bool {
    true
}

/// An axis-aligned box.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BoxSpec {
    /// Minimum corner (m).
    pub min: [f64; 3],
    /// Maximum corner (m).
    pub max: [f64; 3],
}

/// Basis settings.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BasisSpec {
    /// Modes m.
    pub modes: usize,
    /// Kernels K.
    pub kernels: usize,
    /// Grid points the basis is built on.
    pub points: usize,
}

/// Time stepping.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SimulationSpec {
    /// h (s).
    pub time_step: f64,
    /// Steps to run.
    pub steps: usize,
    /// Grid points the simulation integrates over.
    pub points: usize,
    /// Write every n-th frame (default 1).
    #[serde(default = "one")]
    pub output_every: usize,
}

fn one() -> usize {
    1
}

/// Material (SI units), uniform over the object.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MaterialSpec {
    /// Young's modulus E (Pa).
    pub youngs_modulus: f64,
    /// Poisson ratio ν, in (-1, 0.5).
    pub poisson_ratio: f64,
    /// Density ρ (kg/m³).
    pub density: f64,
}

impl From<MaterialSpec> for MaterialSample {
    fn from(m: MaterialSpec) -> Self {
        MaterialSample {
            youngs_modulus: m.youngs_modulus,
            poisson_ratio: m.poisson_ratio,
            density: m.density,
        }
    }
}

/// A whole scene file.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneFile {
    /// Shape.
    pub geometry: GeometrySpec,
    /// Material (SI).
    pub material: MaterialSpec,
    /// Basis settings.
    pub basis: BasisSpec,
    /// Time stepping.
    pub simulation: SimulationSpec,
    /// What acts on the object.
    #[serde(default)]
    pub scene: SceneSpec,
}

impl SceneFile {
    /// Reads and validates a `.toml` or `.json` scene file; a relative mesh path becomes
    /// relative to the file's folder.
    ///
    /// # Errors
    /// [`SceneFileError`] naming the file and the field.
    pub fn load(path: &Path) -> Result<Self, SceneFileError> {
        let display = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|source| SceneFileError::Read {
            path: display.clone(),
            source,
        })?;
        let is_json = path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("json"));
        let mut file: SceneFile = if is_json {
            serde_json::from_str(&text).map_err(|e| SceneFileError::Parse {
                path: display.clone(),
                message: e.to_string(),
            })?
        } else {
            toml::from_str(&text).map_err(|e| SceneFileError::Parse {
                path: display.clone(),
                message: e.to_string().trim().replace('\n', " "),
            })?
        };
        if let Some(mesh) = &file.geometry.mesh
            && mesh.is_relative()
            && let Some(dir) = path.parent()
        {
            file.geometry.mesh = Some(dir.join(mesh));
        }
        file.validate(&display)?;
        Ok(file)
    }

    fn validate(&self, path: &str) -> Result<(), SceneFileError> {
        let bad = |field: &str, problem: String| {
            Err(SceneFileError::Invalid {
                path: path.into(),
                field: field.into(),
                problem,
            })
        };
        match (&self.geometry.mesh, &self.geometry.cuboid) {
            (Some(_), Some(_)) | (None, None) => {
                return bad("geometry", "give exactly one of `mesh` and `box`".into());
            }
            (None, Some(b)) if !(0..3).all(|d| b.max[d] > b.min[d]) => {
                return bad(
                    "geometry.box",
                    format!("max {:?} must exceed min {:?}", b.max, b.min),
                );
            }
            _ => {}
        }
        let m = &self.material;
        if let Err(e) = MaterialSample::from(*m).lame_parameters() {
            return bad("material", e.to_string());
        }
        if !(m.density > 0.0 && m.density.is_finite()) {
            return bad(
                "material.density",
                format!("{} must be positive", m.density),
            );
        }
        if self.basis.modes == 0 || self.basis.modes >= self.basis.kernels {
            return bad(
                "basis.modes",
                format!(
                    "{} must be at least 1 and below basis.kernels = {}",
                    self.basis.modes, self.basis.kernels
                ),
            );
        }
        if self.basis.points == 0 || self.simulation.points == 0 {
            return bad(
                "basis.points / simulation.points",
                "must be positive".into(),
            );
        }
        let s = &self.simulation;
        if !(s.time_step > 0.0 && s.time_step.is_finite()) {
            return bad(
                "simulation.time_step",
                format!("{} must be positive", s.time_step),
            );
        }
        if s.steps == 0 {
            return bad("simulation.steps", "must be at least 1".into());
        }
        if s.output_every == 0 {
            return bad("simulation.output_every", "must be at least 1".into());
        }
        if let Err(e) = self.scene.validate() {
            return bad("scene", e.to_string());
        }
        Ok(())
    }

    /// The surface of the object, normalized if asked.
    ///
    /// # Errors
    /// [`EvalError::Setup`] if the mesh cannot be read or is invalid.
    pub fn surface(&self) -> Result<TriangleMesh, EvalError> {
        match (&self.geometry.mesh, &self.geometry.cuboid) {
            (Some(path), _) => {
                let mesh = read_triangle_mesh(path).map_err(|e| EvalError::Setup(e.to_string()))?;
                Ok(if self.geometry.normalize {
                    mesh.normalized().0
                } else {
                    mesh
                })
            }
            (None, Some(b)) => Ok(TriangleMesh::cuboid(b.min.into(), b.max.into())),
            (None, None) => Err(EvalError::Setup("no geometry".into())),
        }
    }
}

/// What `simulate` did.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SimulateReport {
    /// Basis build time (s).
    pub basis_seconds: f64,
    /// Mean wall time per step (ms).
    pub ms_per_step: f64,
    /// Steps that did not converge.
    pub unconverged_steps: usize,
    /// Frames written.
    pub frames_written: usize,
    /// Integration points simulated.
    pub simulation_points: usize,
    /// Largest displacement of a surface vertex at the last frame (m).
    pub final_max_displacement: f64,
}

/// Runs a scene file and writes `frame_NNNNN.ply` / `.vtk` (deformed surface) and
/// `summary.json` under `out_dir`.
///
/// # Errors
/// [`EvalError`] from any stage; frames already written stay valid files.
pub fn run_scene_file(
    file: &SceneFile,
    out_dir: &Path,
    progress: &Progress,
) -> Result<SimulateReport, EvalError> {
    let surface = file.surface()?;
    let lame = MaterialSample::from(file.material)
        .lame_parameters()
        .map_err(|e| EvalError::Setup(e.to_string()))?;
    let start = Instant::now();
    progress.status(format!(
        "basis: m = {}, K = {}, ≈{} grid points",
        file.basis.modes, file.basis.kernels, file.basis.points
    ));
    let basis_points = sample_grid(
        &surface,
        &GridSamplingParams {
            target_points: file.basis.points,
        },
    )
    .map_err(|e| EvalError::Basis(e.to_string()))?;
    let params = BasisParams::default()
        .with_modes(file.basis.modes)
        .with_kernels(file.basis.kernels);
    let (basis, _, _) = build_basis(&basis_points, &vec![lame; basis_points.len()], &params)
        .map_err(|e| EvalError::Basis(e.to_string()))?;
    let basis_seconds = start.elapsed().as_secs_f64();

    let points = sample_grid(
        &surface,
        &GridSamplingParams {
            target_points: file.simulation.points,
        },
    )
    .map_err(|e| EvalError::Setup(e.to_string()))?;
    let model = ReducedModel::new(
        &basis,
        &points,
        &vec![MaterialSample::from(file.material); points.len()],
        StableNeoHookean,
    )
    .map_err(|e| EvalError::Setup(e.to_string()))?;
    let scene = file.scene.reduced_scene(model.rest_positions())?;
    let mut sim = Simulator::new(
        model,
        &scene,
        SimulationParams {
            time_step: file.simulation.time_step,
            ..Default::default()
        },
    )
    .map_err(|e| EvalError::Setup(e.to_string()))?;
    let rest: Vec<Vector3<f64>> = surface.vertices().to_vec();
    let output = DeformationMap::new(&basis, &rest).map_err(|e| EvalError::Setup(e.to_string()))?;
    let write_frame = |frame: usize, z: &[f64], time: f64| -> Result<(), EvalError> {
        let x = output.positions(z);
        let name = out_dir.join(format!("frame_{frame:05}"));
        write_atomically(
            &name.with_extension("ply"),
            triangle_mesh_ply(&x, surface.triangles()).as_bytes(),
        )?;
        write_atomically(
            &name.with_extension("vtk"),
            unstructured_grid_vtk(&x, &rest, surface.triangles(), time).as_bytes(),
        )
    };
    write_frame(0, &sim.state().z, 0.0)?;
    let mut frames_written = 1;
    let bar = progress.bar(file.simulation.steps, "simulate");
    let (mut unconverged, mut stepping) = (0usize, 0.0);
    for step in 1..=file.simulation.steps {
        let t = Instant::now();
        let report = sim
            .step()
            .map_err(|e| EvalError::Reduced(format!("step {step}: {e}")))?;
        stepping += t.elapsed().as_secs_f64();
        unconverged += usize::from(!report.converged());
        if step % file.simulation.output_every == 0 || step == file.simulation.steps {
            write_frame(step, &sim.state().z, sim.state().time)?;
            frames_written += 1;
        }
        bar.inc(1);
    }
    bar.finish_and_clear();
    let last = output.displacements(&sim.state().z);
    let report = SimulateReport {
        basis_seconds,
        ms_per_step: 1e3 * stepping / file.simulation.steps as f64,
        unconverged_steps: unconverged,
        frames_written,
        simulation_points: points.len(),
        final_max_displacement: last.iter().map(|d| d.norm()).fold(0.0, f64::max),
    };
    write_atomically(
        &out_dir.join("summary.json"),
        serde_json::to_string_pretty(&report)
            .unwrap_or_default()
            .as_bytes(),
    )?;
    Ok(report)
}
