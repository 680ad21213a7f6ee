//! The elastic quadrature chosen in a scene file: parsed with its defaults, reported, and
//! exact for motions without strain.

use std::path::PathBuf;

use freeform::{SceneFile, Silent, simulate_scene_file};
use reduced_sim::{CubatureParams, QuadratureRule, SimulationParams};

fn scratch_dir(name: &str) -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn box_scene(quadrature: &str) -> String {
    format!(
        "[geometry]\nbox = {{ min = [0, 0, 0], max = [2, 1, 1] }}\n[material]\n\
         youngs_modulus = 1e5\npoisson_ratio = 0.45\ndensity = 1000\n[basis]\nmodes = 6\n\
         kernels = 150\npoints = 3000\n[simulation]\ntime_step = 0.01\nsteps = 5\npoints = 2000\n\
         {quadrature}\n[scene]\ngravity = [0, -9.8, 0]\n"
    )
}

#[test]
fn a_scene_file_picks_a_quadrature_with_defaults_for_the_fields_it_leaves_out() {
    let dir = scratch_dir("quadrature-parse");
    let path = dir.join("cubature.toml");
    std::fs::write(
        &path,
        box_scene("quadrature = { kind = \"cubature\", tolerance = 0.01 }"),
    )
    .unwrap();
    let file = SceneFile::load(&path).unwrap();
    assert_eq!(
        file.simulation.quadrature,
        QuadratureRule::Cubature(CubatureParams {
            tolerance: 0.01,
            ..CubatureParams::DEFAULT
        })
    );
    let path = dir.join("default.toml");
    std::fs::write(&path, box_scene("")).unwrap();
    let default = SceneFile::load(&path).unwrap().simulation;
    assert_eq!(
        default.quadrature,
        QuadratureRule::Automatic(CubatureParams::DEFAULT)
    );
    let path = dir.join("automatic.toml");
    std::fs::write(
        &path,
        box_scene("quadrature = { kind = \"automatic\", max_points = 500 }"),
    )
    .unwrap();
    assert_eq!(
        SceneFile::load(&path).unwrap().simulation.quadrature,
        QuadratureRule::Automatic(CubatureParams {
            max_points: 500,
            ..CubatureParams::DEFAULT
        })
    );
    assert_eq!(default.hessian_reuse, SimulationParams::HESSIAN_REUSE);
    let path = dir.join("paper.toml");
    std::fs::write(
        &path,
        box_scene("quadrature = { kind = \"full\" }\nhessian_reuse = false"),
    )
    .unwrap();
    let paper = SceneFile::load(&path).unwrap().simulation;
    assert_eq!(paper.quadrature, QuadratureRule::PAPER);
    assert_eq!(paper.hessian_reuse, optimize::HessianReuse::Never);
    let path = dir.join("bad.toml");
    std::fs::write(&path, box_scene("quadrature = { kind = \"gauss\" }")).unwrap();
    let message = SceneFile::load(&path).unwrap_err().to_string();
    assert!(message.contains("gauss"), "{message}");
}

#[test]
fn a_falling_box_on_a_cubature_falls_exactly_as_on_every_point() {
    // Free fall is a rigid translation: no strain, so any quadrature integrates its (zero)
    // elastic force exactly and both runs drop by backward Euler's g h² n(n+1)/2.
    let dir = scratch_dir("quadrature-fall");
    let mut drops = Vec::new();
    for (name, line) in [
        ("full", "quadrature = { kind = \"full\" }"),
        (
            "cubature",
            "quadrature = { kind = \"cubature\", tolerance = 0.02 }",
        ),
    ] {
        let path = dir.join(format!("{name}.toml"));
        std::fs::write(&path, box_scene(line)).unwrap();
        let file = SceneFile::load(&path).unwrap();
        let report = simulate_scene_file(&file, &dir.join(name), None, &Silent).unwrap();
        let quadrature = report.quadrature.unwrap();
        assert_eq!(quadrature.kind, name);
        if name == "cubature" {
            assert!(quadrature.points < report.simulation_points);
            assert!(quadrature.cubature.unwrap().reached_tolerance);
        } else {
            assert_eq!(quadrature.points, report.simulation_points);
        }
        drops.push(report.final_max_displacement);
    }
    let expected = 9.8 * 0.01 * 0.01 * 5.0 * 6.0 / 2.0;
    for drop in drops {
        assert!(
            (drop - expected).abs() < 1e-9,
            "dropped {drop} m, expected {expected} m"
        );
    }
}

#[test]
fn a_scene_file_with_exact_pins_holds_its_clamped_end_on_target() {
    let dir = scratch_dir("exact-pins");
    let clamp = "[[scene.constraints]]\nregion = { below = { axis = 0, value = 0.3 } }\nmotion = \"rest\"\n";
    let mut deviations = Vec::new();
    for pins in ["pins = \"penalty\"", "pins = { exact = { inset = 0.0 } }"] {
        let path = dir.join("scene.toml");
        std::fs::write(&path, box_scene(pins) + clamp).unwrap();
        let file = SceneFile::load(&path).unwrap();
        let out = dir.join(if pins.contains("exact") {
            "exact"
        } else {
            "penalty"
        });
        let report = simulate_scene_file(&file, &out, None, &Silent).unwrap();
        assert_eq!(report.unconverged_steps, 0);
        assert!(report.final_max_displacement > 1e-4, "the box sags");
        deviations.push(if pins.contains("exact") {
            report.max_held_deviation
        } else {
            report.max_pin_deviation
        });
    }
    // The penalty lets the clamped end sag a little; the exact pins hold it (≤ 1e-4 L).
    assert!(deviations[0] > 1e-6, "penalty drift {:e} m", deviations[0]);
    assert!(deviations[1] <= 2e-4, "exact drift {:e} m", deviations[1]);
    assert!(deviations[1] < 1e-3 * deviations[0], "{deviations:?}");
}

#[test]
fn a_scene_file_with_weighted_pins_and_a_projected_volumetric_term_holds_its_clamp_exactly() {
    let dir = scratch_dir("weighted-pins");
    let clamp = "[[scene.constraints]]\nregion = { below = { axis = 0, value = 0.3 } }\nmotion = \"rest\"\n";
    let mut sags = Vec::new();
    for pressure in [
        "pressure = \"pointwise\"",
        "pressure = { mode_fraction = 1.0, retained_shear_multiple = 2.0 }",
    ] {
        let settings =
            format!("pins = {{ weighted = {{ transition_fraction = 1.0 }} }}\n{pressure}");
        let path = dir.join("scene.toml");
        std::fs::write(&path, box_scene(&settings) + clamp).unwrap();
        let file = SceneFile::load(&path).unwrap();
        let pointwise = pressure.contains("pointwise");
        assert_eq!(file.simulation.pressure.is_none(), pointwise);
        let out = dir.join(if pointwise { "pointwise" } else { "projected" });
        let report = simulate_scene_file(&file, &out, None, &Silent).unwrap();
        assert_eq!(report.unconverged_steps, 0);
        assert!(
            report.max_held_deviation < 1e-12,
            "held drift {:e} m",
            report.max_held_deviation
        );
        sags.push(report.final_max_displacement);
    }
    // The option reaches the simulation (the trajectories differ).
    assert!((sags[1] - sags[0]).abs() > 1e-6 * sags[0], "{sags:?}");
}
