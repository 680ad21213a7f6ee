//! Scene files with several objects: validation names the field, and two boxes
//! dropped on each other write every object's frames and stay apart by the contact distance.

use std::path::{Path, PathBuf};

use freeform::reduced_sim::QuadratureRule;
use freeform::{
    Constraint, Geometry, Motion, ObjectsFile, PinHold, Region, Silent, simulate_objects,
};

/// A fresh folder under the target directory for `name`.
fn scratch(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join("objects")
        .join(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Two 0.2 m boxes, the upper 0.25 m above the lower resting on a floor, with `extra` TOML
/// appended (at the end of the upper object's table).
fn two_boxes(extra: &str) -> String {
    format!(
        r#"
[simulation]
time_step = 0.01
steps = 40
points = 300
output_every = 20
quadrature = {{ kind = "full" }}

[scene]
gravity = [0, -9.8, 0]
floor = {{ normal = [0, 1, 0], offset = 0 }}

[contact]
radius = 0.02

[[objects]]
name = "lower"
geometry = {{ box = {{ min = [0, 0, 0], max = [0.2, 0.2, 0.2] }} }}
material = {{ youngs_modulus = 1e6, poisson_ratio = 0.3, density = 1000 }}
basis = {{ modes = 4, kernels = 60, points = 800 }}
position = [0, 0.01, 0]

[[objects]]
name = "upper"
geometry = {{ box = {{ min = [0, 0, 0], max = [0.2, 0.2, 0.2] }} }}
material = {{ youngs_modulus = 1e6, poisson_ratio = 0.3, density = 1000 }}
basis = {{ modes = 4, kernels = 60, points = 800 }}
position = [0.03, 0.26, 0.02]
{extra}
"#
    )
}

fn load(dir: &Path, text: &str) -> Result<ObjectsFile, freeform::SceneFileError> {
    let path = dir.join("scene.toml");
    std::fs::write(&path, text).unwrap();
    assert!(ObjectsFile::describes(&path));
    ObjectsFile::load(&path)
}

#[test]
fn an_objects_file_with_a_bad_field_is_refused_naming_it() {
    let dir = scratch("invalid");
    let cases = [
        (two_boxes("").replace("\"upper\"", "\"lower\""), "objects[1].name"),
        (two_boxes("scale = -1"), "objects[1].scale"),
        (two_boxes("").replace("radius = 0.02", "radius = 0"), "contact"),
        (
            two_boxes("").replace("modes = 4, kernels = 60", "modes = 60, kernels = 60"),
            "objects[0].basis.modes",
        ),
        (
            two_boxes("").replace(
                "[contact]",
                "[[scene.constraints]]\nregion = { below = { axis = 1, value = 0.05 } }\nmotion = \"rest\"\n[contact]",
            ),
            "scene.constraints",
        ),
        (
            two_boxes("").replace("time_step = 0.01", "time_step = 0.01\nnewton_tolerance = -1e-6"),
            "simulation.newton_tolerance",
        ),
        (
            two_boxes("").replace("time_step = 0.01", "time_step = 0.01\nfloor_stiffness_factor = 0"),
            "simulation.floor_stiffness_factor",
        ),
        (
            two_boxes("").replace(
                "time_step = 0.01",
                "time_step = 0.01\nfloor_contact = { barrier = { distance = -0.01 } }",
            ),
            "simulation.floor_contact.barrier.distance",
        ),
    ];
    for (text, field) in cases {
        let err = load(&dir, &text).unwrap_err().to_string();
        assert!(err.contains(field), "expected {field} in: {err}");
    }
    // A valid tolerance reaches Newton; without one, Newton's default.
    let tight = two_boxes("").replace(
        "time_step = 0.01",
        "time_step = 0.01\nnewton_tolerance = 3e-5",
    );
    let params = load(&dir, &tight).unwrap().simulation.simulation_params();
    assert_eq!(params.newton.tolerance, 3e-5);
    let stiff = two_boxes("").replace(
        "time_step = 0.01",
        "time_step = 0.01\nfloor_stiffness_factor = 1e5",
    );
    let params = load(&dir, &stiff).unwrap().simulation.simulation_params();
    assert_eq!(params.penalty.floor_factor, 1e5);
    let exact = two_boxes("").replace(
        "time_step = 0.01",
        "time_step = 0.01\ntangent = \"exact_when_definite\"",
    );
    let params = load(&dir, &exact).unwrap().simulation.simulation_params();
    assert_eq!(
        params.tangent,
        reduced_sim::HessianTangent::ExactWhenDefinite
    );
    let barrier = two_boxes("").replace(
        "time_step = 0.01",
        "time_step = 0.01\nfloor_contact = { barrier = { distance = 0.01 } }",
    );
    let params = load(&dir, &barrier).unwrap().simulation.simulation_params();
    assert_eq!(
        params.penalty.floor_contact,
        reduced_sim::FloorContact::Barrier { distance: 0.01 }
    );
    let params = load(&dir, &two_boxes(""))
        .unwrap()
        .simulation
        .simulation_params();
    assert_eq!(
        params.newton.tolerance,
        optimize::NewtonParams::default().tolerance
    );
    assert_eq!(
        params.penalty.floor_contact,
        reduced_sim::FloorContact::Penalty
    );
    let one_object = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/scenes/pusher.toml");
    assert!(!ObjectsFile::describes(&one_object));
}

#[test]
fn two_boxes_dropped_on_each_other_write_frames_and_rest_a_contact_distance_apart() {
    let dir = scratch("two_boxes");
    let file = load(&dir, &two_boxes("")).unwrap();
    let out = dir.join("out");
    let report = simulate_objects(&file, &out, None, &Silent).unwrap();
    assert_eq!(report.unconverged_steps, 0, "{report:?}");
    assert_eq!(report.frames_written, 3);
    for name in ["lower", "upper"] {
        for frame in ["frame_00000", "frame_00020", "frame_00040"] {
            for ext in ["ply", "vtk"] {
                let path = out.join(name).join(format!("{frame}.{ext}"));
                assert!(path.is_file(), "{} missing", path.display());
            }
        }
    }
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    assert!(summary["ms_per_step"].as_f64().unwrap() > 0.0);
    assert!(summary["max_penetration"].as_f64().is_some());
    // The settings the run took, defaults filled in, read back as they were.
    let recorded: freeform::SimulationSpec =
        serde_json::from_value(summary["simulation"].clone()).unwrap();
    assert_eq!(recorded, file.simulation);
    // The upper box fell 0.05 m onto the lower and rests on it: the closest samples of the two
    // came near the contact distance (0.02 m), and no pair got deeper than 2% of it into the
    // other's contact shell (or into the floor).
    let gap = report.min_contact_gap.expect("the boxes touched");
    assert!(
        gap > 0.5 * 0.02 && gap < 0.02,
        "closest samples {gap} m apart"
    );
    assert!(
        report.max_penetration <= 0.02 * 0.02,
        "penetration {} m",
        report.max_penetration
    );
    // Resting: the lower box's vertices end below the upper's.
    let (lower, upper) = report
        .final_positions
        .split_at(report.final_positions.len() / 2);
    let top_of_lower = lower.iter().map(|x| x.y).fold(f64::NEG_INFINITY, f64::max);
    let bottom_of_upper = upper.iter().map(|x| x.y).fold(f64::INFINITY, f64::min);
    let separation = bottom_of_upper - top_of_lower;
    assert!(
        separation > 0.0 && separation < 0.03,
        "the upper box's bottom is {separation} m above the lower's top"
    );
}

#[test]
fn a_splat_object_beside_a_box_writes_3dgs_frames_falling_as_it_would_alone() {
    let dir = scratch("splats");
    let donut = test_support::fixtures::shared_splat();
    let text = format!(
        r#"
[simulation]
time_step = 0.01
steps = 4
points = 1000
output_every = 2
quadrature = {{ kind = "full" }}

[scene]
gravity = [0, 0, -9.8]

[contact]
radius = 0.02

[[objects]]
name = "donut"
geometry = {{ splats = {donut:?} }}
material = {{ youngs_modulus = 1e5, poisson_ratio = 0.45, density = 1000 }}
basis = {{ modes = 4, kernels = 100, points = 3000 }}

[[objects]]
name = "box"
geometry = {{ box = {{ min = [0, 0, 0], max = [0.2, 0.2, 0.2] }} }}
material = {{ youngs_modulus = 1e6, poisson_ratio = 0.3, density = 1000 }}
basis = {{ modes = 4, kernels = 60, points = 800 }}
position = [5, 5, 5]
"#
    );
    let file = load(&dir, &text).unwrap();
    let out = dir.join("out");
    let report = simulate_objects(&file, &out, None, &Silent).unwrap();
    assert_eq!(report.joint_solves_per_step, 0.0);
    let input = freeform::SplatTable::read(&donut).unwrap();
    let last = freeform::SplatTable::read(&out.join("donut").join("frame_00004.ply")).unwrap();
    assert_eq!(last.property_names(), input.property_names());
    // Free fall: every centre drops by backward Euler's g h² n(n+1)/2 = 9.8e-3 m.
    let drop = 9.8 * 1e-4 * 10.0;
    for (p, q) in last.positions().iter().zip(input.positions()) {
        assert!((q.z - p.z - drop).abs() < 1e-5 && (p.xy() - q.xy()).norm() < 1e-5);
    }
}

#[test]
fn with_barriers_everywhere_two_boxes_dropped_on_each_other_never_penetrate() {
    let dir = scratch("two_boxes_barrier");
    let text = two_boxes("")
        .replace(
            "time_step = 0.01",
            "time_step = 0.01\nfloor_contact = { barrier = { distance = 0.02 } }",
        )
        .replace("radius = 0.02", "radius = 0.02\nmodel = \"barrier\"");
    let report =
        simulate_objects(&load(&dir, &text).unwrap(), &dir.join("out"), None, &Silent).unwrap();
    assert_eq!(report.unconverged_steps, 0, "{report:?}");
    // No integration point reached the floor, no pair of samples closed (the barrier's line
    // search keeps every gap positive), and the boxes did meet.
    assert_eq!(report.max_penetration, 0.0);
    let gap = report.min_contact_gap.expect("the boxes touched");
    assert!(gap > 0.0 && gap < 0.02, "closest samples {gap} m apart");
    // Resting on the floor: the lowest integration points (the grid's half spacing, 1.5 cm,
    // inside the surface) a little within the barrier's reach (2 cm), so the surface clears it.
    let bottom = report
        .final_positions
        .iter()
        .map(|x| x.y)
        .fold(f64::INFINITY, f64::min);
    assert!(bottom > 0.0 && bottom < 0.01, "lowest vertex at {bottom} m");
}

/// The container example, made small (400 points per object, 10 steps), with stress output and
/// the box hung by its top face on exact pins: every object writes its stress, the box stays
/// where it was placed (rotated, 1.45 m up) while the armadillo falls, and its held points stay
/// on their targets.
#[test]
fn the_container_with_stress_and_a_box_held_by_exact_pins_runs_and_holds_the_box() {
    let dir = scratch("container_held");
    let example = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/scenes/container.toml");
    let mut file = ObjectsFile::load(&example).unwrap();
    file.simulation.steps = 10;
    file.simulation.output_every = 5;
    file.simulation.simulation_points = 400;
    file.simulation.stress = true;
    file.simulation.pins = PinHold::Exact { inset: 0.0 };
    file.simulation.quadrature = QuadratureRule::Full;
    for object in &mut file.objects {
        object.basis.basis_points = 2000;
        object.basis.kernels = 80;
        object.basis.modes = 6;
    }
    let boxed = file.objects.iter().position(|o| o.name == "box").unwrap();
    file.objects[boxed].constraints = vec![Constraint {
        region: Region::Above {
            axis: 1,
            value: 0.17,
        },
        motion: Motion::Rest,
    }];
    let report = simulate_objects(&file, &dir, None, &Silent).unwrap();
    assert_eq!(report.unconverged_steps, 0, "{report:?}");
    for object in &report.objects {
        let stress = object.stress.as_ref().expect("stress for every object");
        assert!(stress.max_von_mises > 0.0, "{}: {stress:?}", object.name);
        assert!(dir.join(&object.name).join("points_00010.vtk").is_file());
    }
    let held = report.objects[boxed]
        .max_held_deviation
        .expect("the box is held");
    assert!(held < 1e-9, "held points {held} m from their targets");
    let moved = |name: &str| {
        let frame = |i: usize| {
            Geometry::read(&dir.join(name).join(format!("frame_{i:05}.ply")))
                .unwrap()
                .display_points()
                .to_vec()
        };
        frame(0)
            .iter()
            .zip(frame(10))
            .map(|(a, b)| (a - b).norm())
            .fold(0.0, f64::max)
    };
    let (boxed_moved, armadillo_moved) = (moved("box"), moved("armadillo"));
    // Free fall over 0.1 s is 4.9 cm; the hung box only sags elastically.
    assert!(
        armadillo_moved > 0.03,
        "the armadillo fell {armadillo_moved} m"
    );
    assert!(boxed_moved < 0.002, "the held box moved {boxed_moved} m");
}

/// With no floor, the lower box is held by its bottom layer exactly (`pins = { exact = … }`):
/// the upper box lands on it and rests there, solved together with a body whose held
/// coordinates are prescribed, and the held points never leave their targets.
#[test]
fn a_box_dropped_on_a_box_held_by_exact_pins_rests_on_it() {
    let dir = scratch("held_lower_box");
    let text = two_boxes("")
        .replace("floor = { normal = [0, 1, 0], offset = 0 }\n", "")
        .replace(
            "quadrature = { kind = \"full\" }",
            "quadrature = { kind = \"full\" }\npins = { exact = { inset = 0.0 } }",
        )
        .replace(
            "position = [0, 0.01, 0]\n",
            "position = [0, 0.01, 0]\n\n[[objects.constraints]]\nregion = { below = { axis = 1, value = 0.03 } }\nmotion = \"rest\"\n",
        );
    let file = load(&dir, &text).unwrap();
    assert_eq!(file.objects[0].constraints.len(), 1);
    assert!(file.scene.floor.is_none());
    let report = simulate_objects(&file, &dir.join("out"), None, &Silent).unwrap();
    assert_eq!(report.unconverged_steps, 0, "{report:?}");
    assert!(
        report.joint_solves_per_step > 0.0,
        "the boxes were solved together"
    );
    let held = report.objects[0].max_held_deviation.expect("held");
    assert!(held < 1e-9, "held points {held} m from their targets");
    assert!(report.objects[1].max_held_deviation.is_none());
    let (lower, upper) = report
        .final_positions
        .split_at(report.final_positions.len() / 2);
    let bottom_of_lower = lower.iter().map(|x| x.y).fold(f64::INFINITY, f64::min);
    let top_of_lower = lower.iter().map(|x| x.y).fold(f64::NEG_INFINITY, f64::max);
    let bottom_of_upper = upper.iter().map(|x| x.y).fold(f64::INFINITY, f64::min);
    assert!(
        (bottom_of_lower - 0.01).abs() < 1e-3,
        "the held box's bottom is at {bottom_of_lower} m"
    );
    let separation = bottom_of_upper - top_of_lower;
    assert!(
        separation > 0.0 && separation < 0.03,
        "the upper box's bottom is {separation} m above the lower's top"
    );
}
