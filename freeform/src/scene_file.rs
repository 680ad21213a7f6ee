//! Scene files: a TOML or JSON file naming the geometry, material, basis settings, what acts on
//! the object and how long to run. [`crate::simulate::simulate_scene_file`] runs one and writes
//! per-frame PLY and VTK of the deformed surface (or cloud). `[basis]` and `[simulation]` and
//! every key in them are optional ([`BasisSpec::default`], [`SimulationSpec::default`]); every
//! key with its unit and default is listed in `docs/scene-files.md`.
//!
//! ```toml
//! [geometry]
//! mesh = "../data/meshes/bunny.obj"           # OBJ/STL/PLY, relative to this file; or
//! # box = { min = [0, 0, 0], max = [5, 1, 1] }
//! # points = "cloud.ply"                      # a point cloud or 3DGS PLY (no faces)
//! # splats = "object.ply"                     # a 3DGS PLY: frames are deformed 3DGS files
//! normalize = true                            # scale so the largest side is 1 m (default true;
//!                                             # a box or cloud keeps its units)
//! # fill_interior = true                      # points/splats: integration points inside too
//!
//! [material]                                  # SI units
//! youngs_modulus = 1e5
//! poisson_ratio = 0.45
//! density = 1000
//! [[material.regions]]                         # optional parts with their own material
//! region = { ball = { center = [0.5, 0.5, 0.5], radius = 0.2 } }   # the later region wins
//! youngs_modulus = 1e7
//! poisson_ratio = 0.45
//! density = 1000
//!
//! [basis]           # optional, as every key in it
//! modes = 16        # m (default 16)
//! kernels = 1000    # K (default 1000)
//! basis_points = 40000  # grid points the basis is built on (default 40 000)
//!
//! [simulation]      # optional, as every key in it
//! time_step = 0.01  # s (default 0.01)
//! steps = 100       # (default 100)
//! simulation_points = 40000  # grid points the simulation integrates over (default 40 000)
//! output_every = 5  # write every 5th frame (default 1)
//! quadrature = { kind = "automatic" } # a cubature if it pays for itself in the run, else every
//!                                     # point (default); { kind = "cubature" }: always one;
//!                                     # { kind = "full" }: every point, the paper's setting
//! newton_tolerance = 1e-6            # Newton stops below this RMS step / L (default)
//! floor_stiffness_factor = 1e4        # floor and colliders: κ = factor (λ + 2μ) / L² (default)
//! tangent = "exact_when_definite"     # Newton's material tangent (default); "projected_psd": the paper's
//! floor_contact = "penalty"           # floor and colliders (default); or an IPC barrier, no
//! # floor_contact = { barrier = { distance = 0.01 } }   # point ever reaching them
//! hessian_reuse = true                # carry the Hessian across steps (default; false or
//!                                     # "never": a fresh Hessian every iteration, the paper's)
//! pins = { weighted = { transition_fraction = 1.0 } }  # held exactly by a weighted basis
//!                                     # (default); "penalty": a pin penalty, the paper's; or
//! # pins = { exact = { inset = 0.05 } }  # exactly, on each region shrunk by 0.05 m
//! pressure = {}                       # the volumetric term projected onto a pressure space
//!                                     # (default); "pointwise": at every point, the paper's
//! stress = true                      # Cauchy, principal and von Mises stress in the VTK
//!                                     # frames and points_NNNNN.vtk (default false)
//!
//! [scene]
//! gravity = [0, -9.8, 0]
//! floor = { normal = [0, 1, 0], offset = -0.5, friction = 0.4 }  # optional; μ default 0
//! [[scene.colliders]]            # optional kinematic colliders: sphere, box, capsule
//! shape = { box = { half_extents = [0.05, 0.2, 0.2] } }
//! friction = 0.3                 # default 0
//! path = [{ time = 0, translation = [-0.2, 0.2, 0.5] },              # rotation = [i, j, k, w]
//!         { time = 2, translation = [0.6, 0.2, 0.5], rotation = [0, 0, 0, 1] }]
//! # parent = 0                   # attached to collider 0: the path is then in its frame (the
//!                                # links of a robot arm, examples/scenes/robot_arm.toml)
//! [[scene.constraints]]
//! region = { below = { axis = 1, value = 0.05 } }
//! motion = "rest"
//! [[scene.constraints]]          # regions: below, above (a half-space), ball
//! region = { ball = { center = [0.5, 0.5, 0.4], radius = 0.1 } }
//! motion = { translate = { velocity = [0, 0.2, 0] } }
//! ```

use std::path::{Path, PathBuf};

use reduced_sim::{ColliderShape, PenaltyParams, QuadratureRule, SimulationParams};
use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::geometry::{Geometry, GeometryError};
use crate::scene::SceneSpec;

pub use crate::material_spec::{MaterialRegion, MaterialSpec};

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
    /// Or a point cloud: a PLY without faces, plain or 3DGS (path relative to the scene file).
    #[serde(default)]
    pub points: Option<PathBuf>,
    /// Or a 3D Gaussian Splatting PLY, simulated on its splat centres; every written frame is
    /// the deformed 3DGS file (centres moved, covariances `F Σ Fᵀ`; see [`crate::splats`]).
    #[serde(default)]
    pub splats: Option<PathBuf>,
    /// Scale a mesh so its largest bounding-box side is 1 m (default true; a box or a cloud
    /// keeps its units).
    #[serde(default = "yes")]
    pub normalize: bool,
    /// For `points` and `splats`: add integration points inside the cloud (default false; a
    /// 3DGS file samples only its surface, so without them mass and elastic energy sit on that
    /// shell, see [`rkpm_core::PointCloudSamplingParams::fill_interior`]).
    #[serde(default)]
    pub fill_interior: bool,
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

/// Basis settings; every field is optional in a file and defaults to [`BasisSpec::default`].
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct BasisSpec {
    /// Modes m (default 16, [`skin_eigen::EigenParams`]).
    pub modes: usize,
    /// Kernels K (default 1000, [`rkpm_core::KernelParams`]).
    pub kernels: usize,
    /// Grid points the basis is built on (default [`BasisSpec::DEFAULT_POINTS`]; `points` is
    /// accepted for it).
    #[serde(alias = "points")]
    pub basis_points: usize,
}

impl BasisSpec {
    /// Integration points the basis is built on when a file does not say: 40 000 (an
    /// integration pool converged for the weighted basis at K ≤ 2000, `docs/defaults.md`).
    pub const DEFAULT_POINTS: usize = 40_000;
}

impl Default for BasisSpec {
    /// The library's basis: m = 16, K = 1000 on 40 000 points.
    fn default() -> Self {
        let params = skin_eigen::BasisParams::default();
        BasisSpec {
            modes: params.eigen.modes,
            kernels: params.kernels.count,
            basis_points: Self::DEFAULT_POINTS,
        }
    }
}

/// Time stepping; every field is optional in a file and defaults to
/// [`SimulationSpec::default`].
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SimulationSpec {
    /// h (s) (default 0.01).
    pub time_step: f64,
    /// Steps to run (default 100).
    pub steps: usize,
    /// Grid points the simulation integrates over (default
    /// [`SimulationSpec::DEFAULT_POINTS`]; `points` is accepted for it).
    #[serde(alias = "points")]
    pub simulation_points: usize,
    /// Write every n-th frame (default 1).
    pub output_every: usize,
    /// Where the elastic energy is integrated (default `{ kind = "automatic" }`: a cubature
    /// when its training pays for itself over the run's steps, otherwise every point,
    /// [`QuadratureRule::Automatic`]; `{ kind = "cubature" }`: always a cubature, optimized
    /// first; both take [`reduced_sim::CubatureParams`]' fields as optional overrides;
    /// `{ kind = "full" }`: every point, the paper's setting).
    pub quadrature: QuadratureRule,
    /// When Newton may keep an older Hessian factorization (default `{ while_contracting = {
    /// contraction = 0.7 } }`, [`reduced_sim::SimulationParams::HESSIAN_REUSE`]: carried across
    /// steps while chord steps contract; `"never"`: a fresh Hessian every Newton iteration, the
    /// paper's setting). `true` and `false` are read as these two.
    #[serde(deserialize_with = "crate::settings_vocabulary::hessian_reuse_or_bool")]
    pub hessian_reuse: optimize::HessianReuse,
    /// How the constraints are held (default `{ weighted = { transition_fraction = 1.0 } }`,
    /// [`crate::PinHold::WEIGHTED`]: exactly, by a weighted basis; `"penalty"`: the paper's pin
    /// penalty; `{ exact = { inset = d } }` builds the basis for the regions shrunk by d m, see
    /// [`crate::PinHold`]).
    pub pins: crate::PinHold,
    /// Write the stress (Sec. 9.3) into every VTK frame at the surface vertices or cloud
    /// points, and `points_NNNNN.vtk` of the integration points with theirs (default false:
    /// not computed). See [`crate::StressField`] for the arrays.
    pub stress: bool,
    /// Slip speed ε_v (m/s) at which friction reaches its Coulomb limit (default 1e-3,
    /// [`reduced_sim::PenaltyParams::friction_slip_speed`]): larger values let sticking
    /// contacts creep faster (about 0.6 ε_v under 80% of the limit) but cost far fewer Newton
    /// iterations.
    pub friction_slip_speed: f64,
    /// Newton's tolerance (default 1e-6, [`optimize::NewtonParams::tolerance`]): a step is
    /// solved when a Newton step moves the mass by less than this times the object's largest
    /// rest side, root mean square. A looser tolerance (e.g. 3e-5) speeds up contact scenes that
    /// converge slowly near the end (`results/RESULTS.md`, "Newton's tolerance in contact scenes").
    pub newton_tolerance: f64,
    /// The floor's and colliders' penalty factor (default 1e4,
    /// [`reduced_sim::PenaltyParams::floor_factor`]: κ = factor · (λ + 2μ) / L²). Penetration
    /// falls about as 1/factor.
    pub floor_stiffness_factor: f64,
    /// The material tangent in Newton's Hessians (default `"exact_when_definite"`: projected
    /// only when the exact system does not factor, see [`reduced_sim::HessianTangent`]; the
    /// container example's armadillo converges in half the Hessians; `"projected_psd"` at every
    /// point is the paper's; `"exact"`).
    pub tangent: reduced_sim::HessianTangent,
    /// How the floor and the colliders push back (default `"penalty"`; `{ barrier = {
    /// distance = d } }`: IPC's log barrier within d m, so no integration point ever reaches
    /// them, see [`reduced_sim::FloorContact`]). A mesh collider's band must exceed d.
    pub floor_contact: reduced_sim::FloorContact,
    /// The volumetric term (default `Some(PressureSpaceParams::default())`, written `{}`:
    /// projected onto a pressure space, locking-free, [`crate::PressureSpace`]; `None`, written
    /// `"pointwise"`: the material's own volumetric term at every point, the paper's setting).
    #[serde(
        deserialize_with = "crate::settings_vocabulary::pressure_or_pointwise",
        serialize_with = "crate::settings_vocabulary::serialize_pressure"
    )]
    pub pressure: Option<crate::PressureSpaceParams>,
}

impl SimulationSpec {
    /// Integration points the simulation uses when a file does not say: 40 000, the basis's
    /// pool, which the cubature is trained on (the paper's 5000 under-integrate the weighted
    /// basis, `docs/defaults.md`).
    pub const DEFAULT_POINTS: usize = 40_000;
}

impl SimulationSpec {
    /// The paper's setting of the step with the library's other defaults: 5000 points, every
    /// one integrated (`{ kind = "full" }`), a fresh Hessian every Newton iteration, the
    /// PSD-projected tangent, the pin penalty and the pointwise volumetric term.
    pub fn paper() -> Self {
        let step = SimulationParams::paper_setting();
        SimulationSpec {
            simulation_points: 5000,
            quadrature: QuadratureRule::PAPER,
            hessian_reuse: step.newton.hessian_reuse,
            tangent: step.tangent,
            pins: crate::PinHold::Penalty,
            pressure: None,
            ..SimulationSpec::default()
        }
    }
}

impl Default for SimulationSpec {
    /// The library's defaults: 100 steps of 0.01 s on 40 000 points, every frame written, the
    /// automatic quadrature, Hessian reuse, the regions held by the weighted basis, the
    /// projected volumetric term, no stress, and [`reduced_sim::PenaltyParams`]' and
    /// [`optimize::NewtonParams`]' contact and solver settings.
    fn default() -> Self {
        let penalty = reduced_sim::PenaltyParams::default();
        SimulationSpec {
            time_step: 0.01,
            steps: 100,
            simulation_points: Self::DEFAULT_POINTS,
            output_every: 1,
            quadrature: QuadratureRule::Automatic(reduced_sim::CubatureParams::DEFAULT),
            hessian_reuse: SimulationParams::HESSIAN_REUSE,
            pins: crate::PinHold::default(),
            stress: false,
            friction_slip_speed: penalty.friction_slip_speed,
            newton_tolerance: optimize::NewtonParams::default().tolerance,
            floor_stiffness_factor: penalty.floor_factor,
            tangent: reduced_sim::HessianTangent::default(),
            floor_contact: reduced_sim::FloorContact::default(),
            pressure: Some(crate::PressureSpaceParams::default()),
        }
    }
}

fn yes() -> bool {
    true
}

/// A whole scene file.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneFile {
    /// Shape.
    pub geometry: GeometrySpec,
    /// Material (SI).
    pub material: MaterialSpec,
    /// Basis settings (default [`BasisSpec::default`]).
    #[serde(default)]
    pub basis: BasisSpec,
    /// Time stepping (default [`SimulationSpec::default`]).
    #[serde(default)]
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
        let mut file: SceneFile = read_document(path)?;
        let dir = path.parent().unwrap_or(Path::new(""));
        file.geometry.resolve_paths(dir);
        load_collider_meshes(&mut file.scene, dir, &display)?;
        file.validate(&display)?;
        Ok(file)
    }

    fn validate(&self, path: &str) -> Result<(), SceneFileError> {
        let defect = self
            .geometry
            .defect()
            .or_else(|| self.material.defect())
            .or_else(|| self.basis.defect())
            .or_else(|| self.simulation.defect())
            .or_else(|| {
                let e = self.scene.validate().err()?;
                Some(("scene".into(), e.to_string()))
            });
        match defect {
            Some((field, problem)) => Err(SceneFileError::Invalid {
                path: path.into(),
                field,
                problem,
            }),
            None => Ok(()),
        }
    }

    /// The object's shape: the mesh (normalized if asked), the box, or the cloud.
    ///
    /// # Errors
    /// [`GeometryError`] if the file cannot be read, is not closed, or (for `points`) has no
    /// points.
    pub fn geometry(&self) -> Result<Geometry, GeometryError> {
        self.geometry.read()
    }
}

/// Parses a `.json` file as JSON and anything else as TOML.
///
/// # Errors
/// [`SceneFileError::Read`] or [`SceneFileError::Parse`] naming the file.
pub(crate) fn read_document<T: serde::de::DeserializeOwned>(
    path: &Path,
) -> Result<T, SceneFileError> {
    let display = path.display().to_string();
    let text = std::fs::read_to_string(path).map_err(|source| SceneFileError::Read {
        path: display.clone(),
        source,
    })?;
    let is_json = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("json"));
    if is_json {
        serde_json::from_str(&text).map_err(|e| SceneFileError::Parse {
            path: display,
            message: e.to_string(),
        })
    } else {
        toml::from_str(&text).map_err(|e| SceneFileError::Parse {
            path: display,
            message: e.to_string().trim().replace('\n', " "),
        })
    }
}

/// Reads the closed meshes of the scene's mesh colliders (paths relative to `dir`).
///
/// # Errors
/// [`SceneFileError::Invalid`] naming the collider and why its mesh cannot be read.
pub(crate) fn load_collider_meshes(
    scene: &mut SceneSpec,
    dir: &Path,
    path: &str,
) -> Result<(), SceneFileError> {
    for (i, collider) in scene.colliders.iter_mut().enumerate() {
        if let ColliderShape::Mesh(mesh) = &mut collider.shape {
            mesh.load(dir).map_err(|e| SceneFileError::Invalid {
                path: path.into(),
                field: format!("scene.colliders[{i}].shape.mesh"),
                problem: e.to_string(),
            })?;
        }
    }
    Ok(())
}

impl GeometrySpec {
    /// Makes the relative file paths relative to `dir` (the scene file's folder).
    pub(crate) fn resolve_paths(&mut self, dir: &Path) {
        for file_path in [&mut self.mesh, &mut self.points, &mut self.splats]
            .into_iter()
            .flatten()
        {
            if file_path.is_relative() {
                *file_path = dir.join(&*file_path);
            }
        }
    }

    /// The first problem as (field, what is wrong): not exactly one shape, an empty box.
    pub(crate) fn defect(&self) -> Option<(String, String)> {
        let given = [
            self.mesh.is_some(),
            self.cuboid.is_some(),
            self.points.is_some(),
            self.splats.is_some(),
        ];
        if given.iter().filter(|&&given| given).count() != 1 {
            return Some((
                "geometry".into(),
                "give exactly one of `mesh`, `box`, `points` and `splats`".into(),
            ));
        }
        if let Some(b) = &self.cuboid
            && !(0..3).all(|d| b.max[d] > b.min[d])
        {
            return Some((
                "geometry.box".into(),
                format!("max {:?} must exceed min {:?}", b.max, b.min),
            ));
        }
        None
    }

    /// The shape: the mesh (normalized if asked), the box, or the cloud.
    ///
    /// # Errors
    /// [`GeometryError`] if the file cannot be read, is not closed, or (for `points`) has no
    /// points.
    pub fn read(&self) -> Result<Geometry, GeometryError> {
        let g = self;
        if let Some(b) = &g.cuboid {
            return Ok(Geometry::cuboid(b.min.into(), b.max.into()));
        }
        if let Some(path) = g.points.as_ref().or(g.splats.as_ref()) {
            return Ok(Geometry::Cloud(rkpm_core::read_point_cloud(path)?));
        }
        let path = g.mesh.as_deref().unwrap_or(Path::new(""));
        let mesh = rkpm_core::read_triangle_mesh(path)?;
        Ok(if g.normalize {
            Geometry::Surface(mesh).normalized()
        } else {
            Geometry::Surface(mesh)
        })
    }
}

impl BasisSpec {
    /// The first problem as (field, what is wrong): m not in [1, K), no grid points.
    pub(crate) fn defect(&self) -> Option<(String, String)> {
        if self.modes == 0 || self.modes >= self.kernels {
            return Some((
                "basis.modes".into(),
                format!(
                    "{} must be at least 1 and below basis.kernels = {}",
                    self.modes, self.kernels
                ),
            ));
        }
        (self.basis_points == 0).then(|| ("basis.basis_points".into(), "must be positive".into()))
    }
}

impl SimulationSpec {
    /// The simulator's options these settings ask for: the time step, the friction slip speed,
    /// and the library defaults with Hessian reuse or the paper's setting without.
    pub fn simulation_params(&self) -> SimulationParams {
        let base = if self.hessian_reuse == optimize::HessianReuse::Never {
            SimulationParams::paper_setting()
        } else {
            SimulationParams::default()
        };
        SimulationParams {
            time_step: self.time_step,
            newton: optimize::NewtonParams {
                tolerance: self.newton_tolerance,
                hessian_reuse: self.hessian_reuse,
                ..base.newton
            },
            penalty: PenaltyParams {
                friction_slip_speed: self.friction_slip_speed,
                floor_factor: self.floor_stiffness_factor,
                floor_contact: self.floor_contact,
                ..PenaltyParams::default()
            },
            tangent: self.tangent,
            ..base
        }
    }

    /// The first problem as (field, what is wrong): a time step, floor stiffness factor or
    /// Newton tolerance that is not finite and positive, no steps, points or output.
    pub fn defect(&self) -> Option<(String, String)> {
        let field = |name: &str| format!("simulation.{name}");
        let positive = |name: &str, value: f64| {
            (!(value > 0.0 && value.is_finite()))
                .then(|| (field(name), format!("{value} must be positive")))
        };
        if self.simulation_points == 0 {
            return Some((field("simulation_points"), "must be positive".into()));
        }
        if let Some(defect) = positive("time_step", self.time_step) {
            return Some(defect);
        }
        if self.steps == 0 {
            return Some((field("steps"), "must be at least 1".into()));
        }
        let barrier_distance = match self.floor_contact {
            reduced_sim::FloorContact::Penalty => 1.0,
            reduced_sim::FloorContact::Barrier { distance } => distance,
        };
        if let Some(defect) = positive("floor_stiffness_factor", self.floor_stiffness_factor)
            .or_else(|| positive("newton_tolerance", self.newton_tolerance))
            .or_else(|| positive("floor_contact.barrier.distance", barrier_distance))
        {
            return Some(defect);
        }
        if self.output_every == 0 {
            return Some((field("output_every"), "must be at least 1".into()));
        }
        None
    }
}
