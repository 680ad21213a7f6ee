//! Every example scene in `freeform/examples/scenes` loads and passes validation, so the
//! README's commands do not fail on a typo; the robot arm's links form one chain.

use std::path::Path;
use std::sync::Mutex;

use freeform::{ObjectsFile, Progress, SceneFile};

/// Keeps the status lines a run reports.
#[derive(Default)]
struct StatusLines(Mutex<Vec<String>>);

impl Progress for StatusLines {
    fn status(&self, line: &str) {
        self.0.lock().unwrap().push(line.to_string());
    }
}

#[test]
fn every_example_scene_loads_and_validates() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/scenes");
    let mut loaded = 0;
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().and_then(|e| e.to_str()) != Some("toml") {
            continue;
        }
        if ObjectsFile::describes(&path) {
            ObjectsFile::load(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        } else {
            SceneFile::load(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        }
        loaded += 1;
    }
    assert!(loaded >= 6, "{loaded} example scenes");
    let arm = ObjectsFile::load(&dir.join("robot_arm.toml")).unwrap();
    let parents: Vec<Option<usize>> = arm.scene.colliders.iter().map(|c| c.parent).collect();
    assert_eq!(parents, [None, Some(0), Some(1), Some(2), Some(3)]);
}

/// A scene file with only a shape, a material and one held region takes every other setting
/// from the library's defaults (the region held by the weighted basis, the projected volumetric
/// term, 40 000 points), and runs: its free end sags under gravity while the held end stays
/// where it was.
#[test]
fn the_minimal_scene_takes_the_library_defaults_and_runs() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/scenes/minimal.toml");
    let mut file = SceneFile::load(&path).unwrap();
    assert_eq!(file.basis, freeform::BasisSpec::default());
    assert_eq!(file.simulation, freeform::SimulationSpec::default());
    assert_eq!(
        (
            file.basis.modes,
            file.basis.kernels,
            file.basis.basis_points
        ),
        (16, 1000, 40_000)
    );
    assert_eq!(file.simulation.pins, freeform::PinHold::WEIGHTED);
    assert_eq!(
        file.simulation.pressure,
        Some(freeform::PressureSpaceParams::default())
    );
    assert_eq!(
        (
            file.simulation.steps,
            file.simulation.simulation_points,
            file.simulation.time_step
        ),
        (100, 40_000, 0.01)
    );
    // The same file, smaller, so the run takes a second: the defaults above are what a user
    // gets; what is checked here is that a file this short runs and moves as it should.
    file.basis = freeform::BasisSpec {
        modes: 6,
        kernels: 150,
        basis_points: 3000,
    };
    file.simulation.steps = 10;
    file.simulation.simulation_points = 1000;
    let out = test_support::fixtures::scratch_dir("freeform-minimal-scene");
    let lines = StatusLines::default();
    let report = freeform::simulate_scene_file(&file, &out, None, &lines).unwrap();
    // The run says how it holds the region and integrates the volume.
    let basis_line = lines
        .0
        .into_inner()
        .unwrap()
        .into_iter()
        .find(|l| l.starts_with("basis:"))
        .expect("a basis status line");
    assert!(
        basis_line.contains("regions held exactly by a weighted basis")
            && basis_line.contains("volumetric term projected onto a pressure space"),
        "{basis_line}"
    );
    assert_eq!(report.unconverged_steps, 0);
    let sag = report.final_max_displacement;
    assert!(sag > 1e-3, "the free end sags: {sag} m");
    assert!(
        report.max_held_deviation < 1e-12,
        "the held end stays while the free end sags {sag} m: {} m",
        report.max_held_deviation
    );
    assert!(out.join("frame_00010.ply").is_file());
    // summary.json records the settings the run took, defaults filled in.
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    let simulation: freeform::SimulationSpec =
        serde_json::from_value(summary["simulation"].clone()).unwrap();
    assert_eq!(simulation, file.simulation);
    assert_eq!(simulation.pins, freeform::PinHold::WEIGHTED);
    let basis: freeform::BasisSpec = serde_json::from_value(summary["basis"].clone()).unwrap();
    assert_eq!(basis, file.basis);
    let _ = std::fs::remove_dir_all(&out);
}
