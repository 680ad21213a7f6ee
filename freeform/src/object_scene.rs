//! Scene files with several objects: each object its own shape, material, basis,
//! pose and velocity; contact between them ([`reduced_sim::MultiBodySimulator`]); gravity,
//! floor and colliders shared.
//!
//! ```toml
//! [simulation]                     # as for one object; `points` is per object
//! time_step = 0.01
//! steps = 200
//! points = 2000
//! output_every = 5
//!
//! [scene]                          # gravity, floor and colliders act on every object
//! gravity = [0, -9.8, 0]
//! floor = { normal = [0, 1, 0], offset = 0, friction = 0.3 }
//!
//! [contact]                        # between objects
//! radius = 0.02                    # m: contact distance d̂, and the spacing of the samples
//! model = "penalty"                # or "barrier" (default penalty)
//! friction = 0.3                   # default 0
//!
//! [[objects]]
//! name = "bunny"                   # frames go to <out>/bunny/
//! geometry = { mesh = "bunny.obj" }   # as [geometry] of a one-object file
//! scale = 0.3                      # after normalizing (default 1)
//! material = { youngs_modulus = 1e5, poisson_ratio = 0.45, density = 1000 }
//! basis = { modes = 16, kernels = 300, points = 10000 }
//! position = [0, 1, 0]             # x = R X + position (m); R from rotation = [i, j, k, w]
//! velocity = [0, 0, 0]             # m/s
//!
//! [[objects.constraints]]          # this object's held or moving regions, in its rest frame
//! region = { below = { axis = 1, value = 0.05 } }
//! motion = "rest"                  # held where it starts
//! ```
//!
//! Everything else of `[simulation]` applies to every object as to one (`stress`, `pins`,
//! `pressure`, `quadrature`); each object is prepared as a one-object scene file is
//! (`ObjectSetup`), then they step together.

use std::path::Path;
use std::time::Instant;

use hyperelastic::StableNeoHookean;
use nalgebra::{UnitQuaternion, Vector3};
use reduced_sim::{
    Body, BodyContactParams, DeformationMap, MultiBodySimulator, PlannedRun, QuadratureReport,
};
use serde::{Deserialize, Serialize};

use crate::object_setup::{ObjectDescription, ObjectOutput, ObjectSetup};
use crate::pin_hold::PinHold;
use crate::placement::Placement;
use crate::progress::Progress;
use crate::runner::prepare_simulator_for;
use crate::scene::{Constraint, SceneSpec};
use crate::scene_file::{
    BasisSpec, GeometrySpec, MaterialSpec, SceneFileError, SimulationSpec, load_collider_meshes,
    read_document,
};
use crate::simulate::write_summary;
use crate::simulate_error::SimulateError;
use crate::step_loop::{StepStatistics, run_steps};
use crate::stress_summary::StressSummary;

/// One object of a scene.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ObjectSpec {
    /// Its name: letters, digits, `-` and `_` (its frames go to `<out>/<name>/`).
    pub name: String,
    /// Its shape.
    pub geometry: GeometrySpec,
    /// Scale applied after reading (and normalizing) the shape (default 1; a splat file keeps
    /// its scale).
    #[serde(default = "unit_scale")]
    pub scale: f64,
    /// Its material.
    pub material: MaterialSpec,
    /// Its basis (default [`BasisSpec::default`]).
    #[serde(default)]
    pub basis: BasisSpec,
    /// Where its rest frame's origin starts (m): `x = R X + position`.
    #[serde(default)]
    pub position: Vector3<f64>,
    /// R (default identity; `[i, j, k, w]`).
    #[serde(default = "UnitQuaternion::identity")]
    pub rotation: UnitQuaternion<f64>,
    /// Its initial velocity (m/s, default 0).
    #[serde(default)]
    pub velocity: Vector3<f64>,
    /// Its held and moving regions (default none), in its rest frame (after `scale`, before
    /// `position` and `rotation`, which move the targets with it), as `[[scene.constraints]]`
    /// of a one-object file: `[[objects.constraints]]`.
    #[serde(default)]
    pub constraints: Vec<Constraint>,
}

impl ObjectSpec {
    /// Where it starts ([`Placement`]).
    pub fn placement(&self) -> Placement {
        Placement {
            rotation: self.rotation,
            position: self.position,
            velocity: self.velocity,
        }
    }

    /// The scene that acts on it: `shared`'s gravity, floor and colliders, and its own
    /// constraints.
    pub fn scene(&self, shared: &SceneSpec) -> SceneSpec {
        SceneSpec {
            constraints: self.constraints.clone(),
            ..shared.clone()
        }
    }
}

fn unit_scale() -> f64 {
    1.0
}

/// A scene file with `[[objects]]`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ObjectsFile {
    /// The objects (at least one).
    pub objects: Vec<ObjectSpec>,
    /// Time stepping, shared (`points` per object; default [`SimulationSpec::default`]).
    #[serde(default)]
    pub simulation: SimulationSpec,
    /// Gravity, floor and colliders, shared.
    #[serde(default)]
    pub scene: SceneSpec,
    /// Contact between the objects.
    pub contact: BodyContactParams,
}

impl ObjectsFile {
    /// Whether the `.toml` or `.json` file at `path` describes several objects (has
    /// `objects`); false when it cannot be read or parsed (the one-object reader then says
    /// why).
    pub fn describes(path: &Path) -> bool {
        read_document::<serde_json::Value>(path)
            .is_ok_and(|v| v.get("objects").is_some_and(|o| o.is_array()))
    }

    /// Reads and validates a scene file with `[[objects]]`; relative paths are relative to the
    /// file's folder.
    ///
    /// # Errors
    /// [`SceneFileError`] naming the file and the field.
    pub fn load(path: &Path) -> Result<Self, SceneFileError> {
        let display = path.display().to_string();
        let mut file: ObjectsFile = read_document(path)?;
        let dir = path.parent().unwrap_or(Path::new(""));
        for object in &mut file.objects {
            object.geometry.resolve_paths(dir);
        }
        load_collider_meshes(&mut file.scene, dir, &display)?;
        if let Some((field, problem)) = file.defect() {
            return Err(SceneFileError::Invalid {
                path: display,
                field,
                problem,
            });
        }
        Ok(file)
    }

    /// The first problem as (field, what is wrong).
    fn defect(&self) -> Option<(String, String)> {
        if self.objects.is_empty() {
            return Some(("objects".into(), "give at least one object".into()));
        }
        for (k, object) in self.objects.iter().enumerate() {
            let prefixed = |(field, problem): (String, String)| {
                Some((format!("objects[{k}].{field}"), problem))
            };
            let name_ok = !object.name.is_empty()
                && object
                    .name
                    .chars()
                    .all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_');
            if !name_ok {
                return prefixed((
                    "name".into(),
                    format!("{:?}: use letters, digits, - and _", object.name),
                ));
            }
            if self.objects[..k].iter().any(|o| o.name == object.name) {
                return prefixed(("name".into(), format!("{:?} is used twice", object.name)));
            }
            if let Some(defect) = object
                .geometry
                .defect()
                .or_else(|| object.material.defect())
                .or_else(|| object.basis.defect())
            {
                return prefixed(defect);
            }
            if !(object.scale > 0.0 && object.scale.is_finite()) {
                return prefixed(("scale".into(), format!("{} must be positive", object.scale)));
            }
            if object.geometry.splats.is_some() && object.scale != 1.0 {
                return prefixed((
                    "scale".into(),
                    "a splat file keeps its scale (the frames are the file's splats)".into(),
                ));
            }
            if !object.placement().is_finite() {
                return prefixed((
                    "position / rotation / velocity".into(),
                    "must be finite".into(),
                ));
            }
        }
        if let Some(defect) = self.simulation.defect() {
            return Some(defect);
        }
        if !self.scene.constraints.is_empty() {
            return Some((
                "scene.constraints".into(),
                "with several objects, give each object its own constraints ([[objects.constraints]])"
                    .into(),
            ));
        }
        for (k, object) in self.objects.iter().enumerate() {
            if let Err(e) = object.scene(&self.scene).validate() {
                return Some((format!("objects[{k}].constraints"), e.to_string()));
            }
        }
        if let Err(e) = self.scene.validate() {
            return Some(("scene".into(), e.to_string()));
        }
        self.contact
            .defect()
            .map(|why| ("contact".into(), format!("invalid {why}")))
    }
}

/// One object of an [`ObjectsReport`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ObjectSummary {
    /// Its name.
    pub name: String,
    /// Integration points simulated.
    pub simulation_points: usize,
    /// Its elastic quadrature (kind, points, cubature report).
    pub quadrature: QuadratureReport,
    /// Contact samples on its surface.
    pub contact_samples: usize,
    /// Basis build time (s).
    pub basis_seconds: f64,
    /// Its stress over the frames written (with `simulation.stress`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stress: Option<StressSummary>,
    /// The largest distance of its exactly held points from their targets over the run (m;
    /// with held regions).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_held_deviation: Option<f64>,
}

/// What [`simulate_objects`] did (`summary.json`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ObjectsReport {
    /// The objects.
    pub objects: Vec<ObjectSummary>,
    /// Steps taken.
    pub steps: usize,
    /// Mean wall time per step (ms), contact search included.
    pub ms_per_step: f64,
    /// Of which: assembly of gradients and Hessians (the objects' terms and the contact
    /// between them), factorization and solve, line search, contact search (ms), summed over
    /// the step's solves: objects alone are solved on several threads at once, so the parts
    /// can add up to more than `ms_per_step`.
    pub ms_split_per_step: [f64; 4],
    /// Mean Newton iterations per step, summed over the step's solves.
    pub iterations_per_step: f64,
    /// Mean Hessians assembled and factored per step, summed over the step's solves.
    #[serde(default)]
    pub hessians_per_step: f64,
    /// Mean line-search step halvings per step, summed over the step's solves.
    #[serde(default)]
    pub line_search_cuts_per_step: f64,
    /// Mean groups of objects in contact solved together per step.
    pub joint_solves_per_step: f64,
    /// Steps with a solve that did not converge.
    pub unconverged_steps: usize,
    /// The deepest penetration over the run (m): into the floor or a collider, and with
    /// penalty contact the overlap `d̂ − d` of samples of different objects.
    pub max_penetration: f64,
    /// The largest overlap of a contact pair between objects over the run (m): how far a sample
    /// got into another object's contact shell along the pair's normal (`d̂ − n·p`; see
    /// [`reduced_sim::MultiBodySimulator::contact_overlap`]).
    pub max_contact_overlap: f64,
    /// The smallest distance between samples of different objects over the run (m; `None`
    /// when no two came within d̂).
    pub min_contact_gap: Option<f64>,
    /// The mechanical energy at the start and at the end (J): kinetic, elastic, gravity (from
    /// each object's rest frame), penalties and contact
    /// ([`reduced_sim::MultiBodySimulator::mechanical_energy`]).
    pub energy: [f64; 2],
    /// The largest rise of that energy over one step (J; 0 when it only fell): friction and
    /// backward Euler only take energy out, so a rise is put in by moving colliders or a step
    /// gone wrong.
    pub max_energy_rise: f64,
    /// Frames written (per object).
    pub frames_written: usize,
    /// Setup: geometry, bases, cubatures, samples (s).
    pub setup_seconds: f64,
    /// The `[simulation]` settings the run used, every default filled in (each object's own
    /// basis is in its file; `None` in summaries written before they were recorded).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub simulation: Option<SimulationSpec>,
    /// Every object's output points at the last step (m), for a preview; not in
    /// `summary.json`.
    #[serde(skip)]
    pub final_positions: Vec<Vector3<f64>>,
}

/// Runs a scene of several objects with stable Neo-Hookean elasticity and writes each
/// object's frames (`<out_dir>/<name>/frame_NNNNN.ply` / `.vtk`, every `output_every` steps
/// and the last), `<out_dir>/colliders_NNNNN.ply` with the colliders' surfaces at the same
/// frames ([`crate::ColliderFrames`]) and `<out_dir>/summary.json`. Cubatures are cached under `cache_dir` when
/// one is given.
///
/// # Errors
/// [`SimulateError`] naming the stage; frames already written stay valid files.
pub fn simulate_objects(
    file: &ObjectsFile,
    out_dir: &Path,
    cache_dir: Option<&Path>,
    progress: &dyn Progress,
) -> Result<ObjectsReport, SimulateError> {
    let start = Instant::now();
    let mut bodies = Vec::with_capacity(file.objects.len());
    let mut outputs = Vec::with_capacity(file.objects.len());
    let mut summaries = Vec::with_capacity(file.objects.len());
    for object in &file.objects {
        let (body, output, summary) = prepare_object(file, object, out_dir, cache_dir, progress)?;
        bodies.push(body);
        outputs.push(output);
        summaries.push(summary);
    }
    let mut sim = MultiBodySimulator::new(bodies, file.contact).map_err(SimulateError::Objects)?;
    let setup_seconds = start.elapsed().as_secs_f64();

    let steps = file.simulation.steps;
    let collider_frames = crate::ColliderFrames::new(out_dir, &file.scene.colliders);
    let write_all =
        |sim: &MultiBodySimulator<StableNeoHookean>, outputs: &mut [ObjectOutput], index: usize| {
            for (body, output) in sim.bodies().iter().zip(outputs.iter_mut()) {
                let state = body.simulator().state();
                output.write(index, &state.z, state.time)?;
            }
            if let Some(body) = sim.bodies().first() {
                collider_frames.write(index, body.simulator().state().time)?;
            }
            Ok::<(), SimulateError>(())
        };
    write_all(&sim, &mut outputs, 0)?;
    let mut statistics = StepStatistics::new(&sim);
    let mut frames_written = 1;
    progress.begin(steps, "simulate");
    run_steps(
        &mut sim,
        steps,
        &mut statistics,
        |step, source| SimulateError::ObjectStep { step, source },
        |sim, step, _, _| {
            for (summary, body) in summaries.iter_mut().zip(sim.bodies()) {
                if let Some(d) = body.simulator().max_held_deviation() {
                    summary.max_held_deviation =
                        Some(summary.max_held_deviation.unwrap_or(0.0).max(d));
                }
            }
            if step % file.simulation.output_every == 0 || step == steps {
                write_all(sim, &mut outputs, step)?;
                frames_written += 1;
            }
            progress.advance();
            Ok(())
        },
    )?;
    progress.finish();
    for (summary, output) in summaries.iter_mut().zip(&outputs) {
        summary.stress.clone_from(&output.summary);
    }
    let s = &statistics;
    let report = ObjectsReport {
        objects: summaries,
        steps,
        ms_per_step: 1e3 * s.per_step(s.stepping),
        ms_split_per_step: s.split.map(|x| 1e3 * s.per_step(x)),
        iterations_per_step: s.per_step(s.iterations as f64),
        hessians_per_step: s.per_step(s.hessians as f64),
        line_search_cuts_per_step: s.per_step(s.line_search_cuts as f64),
        joint_solves_per_step: s.per_step(s.joint_groups as f64),
        unconverged_steps: s.unconverged,
        max_penetration: s.max_penetration,
        max_contact_overlap: s.max_overlap,
        min_contact_gap: s.min_gap,
        energy: s.energy,
        max_energy_rise: s.max_energy_rise,
        frames_written,
        setup_seconds,
        simulation: Some(file.simulation),
        final_positions: sim
            .bodies()
            .iter()
            .zip(&outputs)
            .flat_map(|(b, o)| o.map.positions(&b.simulator().state().z))
            .collect(),
    };
    write_summary(out_dir, &report)?;
    Ok(report)
}

/// One object of `file` prepared as a one-object file is ([`ObjectSetup`]), placed, with its
/// contact samples, frames under `<out_dir>/<name>/` and the start of its summary.
///
/// # Errors
/// [`SimulateError`] naming the stage.
fn prepare_object(
    file: &ObjectsFile,
    object: &ObjectSpec,
    out_dir: &Path,
    cache_dir: Option<&Path>,
    progress: &dyn Progress,
) -> Result<(Body<StableNeoHookean>, ObjectOutput, ObjectSummary), SimulateError> {
    // Bodies in contact with each other take many more Newton iterations per step, which
    // the automatic quadrature weighs.
    let planned = match file.objects.len() {
        1 => PlannedRun::single_body(file.simulation.steps),
        _ => PlannedRun::multibody(file.simulation.steps),
    };
    let scene = object.scene(&file.scene);
    // An object with nothing to hold is held by nothing, whatever the file's pins say.
    let simulation_spec = SimulationSpec {
        pins: if object.constraints.is_empty() {
            PinHold::Penalty
        } else {
            file.simulation.pins
        },
        ..file.simulation
    };
    let description = ObjectDescription {
        geometry: &object.geometry,
        scale: object.scale,
        material: &object.material,
        basis: &object.basis,
        simulation: &simulation_spec,
        scene: &scene,
        label: format!("{}: ", object.name),
    };
    let (setup, splats) = ObjectSetup::prepare(&description, progress)?;
    progress.status(&format!("{}: elastic quadrature", object.name));
    let simulation = setup
        .simulation(&scene, &simulation_spec, cache_dir)
        .with_placement(Some(object.placement()));
    let (simulator, quadrature) = prepare_simulator_for(&simulation, planned, &[])?;
    let samples = setup.geometry.contact_samples(file.contact.radius);
    let contact_samples = samples.len();
    let samples = DeformationMap::new(&setup.basis, &samples).map_err(SimulateError::OutputMap)?;
    let body = Body::new(simulator, samples).map_err(SimulateError::Objects)?;
    let output = setup.output(&out_dir.join(&object.name), splats, file.simulation.stress)?;
    let summary = ObjectSummary {
        name: object.name.clone(),
        simulation_points: setup.points.len(),
        quadrature,
        contact_samples,
        basis_seconds: setup.basis_seconds,
        stress: None,
        max_held_deviation: None,
    };
    Ok((body, output, summary))
}
