//! The `freeform` binary end to end: the demo in its tiny configuration, `simulate` on a small
//! scene file, clear errors for malformed scene files, a basis and a preview of a real 3DGS file.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("freeform-cli-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn freeform(args: &[&str], dir: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_freeform"))
        .args(args)
        .args(["--quiet", "--out"])
        .arg(dir.join("out"))
        .arg("--cache")
        .arg(dir.join("cache"))
        .output()
        .expect("the freeform binary runs")
}

/// Fails the test with the run's standard error unless it exited successfully.
#[track_caller]
fn assert_success(run: &Output) {
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
}

#[test]
fn quick_demo_runs_end_to_end_tracks_the_fem_reuses_its_cache_and_is_bit_reproducible() {
    let dir = scratch("demo");
    let first = freeform(&["demo", "--quick", "--json"], &dir);
    assert_success(&first);
    let summary: serde_json::Value = serde_json::from_slice(&first.stdout).unwrap();
    let mse = summary["normalized_mse"].as_f64().unwrap();
    // 20 steps of free bending: both sag ~0.26 m at the tip; FreeForm with m = 6 stays within
    // a few percent of the tip motion, far below the 1e-3 of a wrong sign or a frozen beam.
    assert!(mse > 0.0 && mse < 1e-4, "normalized MSE {mse}");
    let (ours, fem) = (
        summary["tip_y_final"]["ours"].as_f64().unwrap(),
        summary["tip_y_final"]["fem"].as_f64().unwrap(),
    );
    assert!(
        fem < -0.1 && (ours - fem).abs() < 0.1 * fem.abs(),
        "tip {ours} vs FEM {fem}"
    );
    assert_eq!(summary["fem_cached"], false);
    for file in [
        "summary.json",
        "tip_displacement.csv",
        "tip_displacement.svg",
        "freeform_0020.vtk",
        "fem_0000.vtk",
    ] {
        assert!(dir.join("out/demo").join(file).is_file(), "{file} missing");
    }
    // Bit-identical results: again from the cached reference, and from a fresh cache (a new FEM
    // run). Parallel float sums used to associate differently from run to run (1e-7 relative
    // drift in this MSE); energies are now summed in index order.
    let second = freeform(&["demo", "--quick", "--json"], &dir);
    assert_success(&second);
    let again: serde_json::Value = serde_json::from_slice(&second.stdout).unwrap();
    assert_eq!(again["fem_cached"], true);
    let fresh_dir = scratch("demo-fresh");
    let third = freeform(&["demo", "--quick", "--json"], &fresh_dir);
    assert_success(&third);
    let fresh: serde_json::Value = serde_json::from_slice(&third.stdout).unwrap();
    assert_eq!(fresh["fem_cached"], false);
    for other in [&again, &fresh] {
        assert_eq!(other["normalized_mse"], summary["normalized_mse"]);
        assert_eq!(other["normalized_max"], summary["normalized_max"]);
        assert_eq!(other["tip_y_final"], summary["tip_y_final"]);
    }
}

const BOX_SCENE: &str = r#"
[geometry]
box = { min = [0, 0, 0], max = [1, 0.25, 0.25] }

[material]
youngs_modulus = 1e5
poisson_ratio = 0.3
density = 1000

[basis]
modes = 4
kernels = 60
basis_points = 1500

[simulation]
time_step = 0.01
steps = 6
simulation_points = 500
output_every = 3

[scene]
gravity = [0, -9.8, 0]
[[scene.constraints]]
region = { below = { axis = 0, value = 0.1 } }
motion = "rest"
"#;

#[test]
fn simulate_writes_ply_and_vtk_frames_of_the_deformed_surface() {
    let dir = scratch("simulate");
    let scene = dir.join("box.toml");
    std::fs::write(&scene, BOX_SCENE).unwrap();
    let run = freeform(&["simulate", scene.to_str().unwrap()], &dir);
    assert_success(&run);
    let out = dir.join("out/box");
    for frame in ["frame_00000", "frame_00003", "frame_00006"] {
        let ply = std::fs::read_to_string(out.join(frame).with_extension("ply")).unwrap();
        assert!(ply.starts_with("ply\n") && ply.contains("element face 12"));
        assert!(out.join(frame).with_extension("vtk").is_file());
    }
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    // Gravity pulls the free end down: something moved, and by less than the box is long.
    let moved = summary["final_max_displacement"].as_f64().unwrap();
    assert!(moved > 1e-4 && moved < 1.0, "{moved}");
    // The printed line names the run's Newton iterations and Hessians per step.
    let stdout = String::from_utf8_lossy(&run.stdout);
    let expected = format!(
        "{:.1} Newton iterations ({:.2} Hessians) per step",
        summary["iterations_per_step"].as_f64().unwrap(),
        summary["hessians_per_step"].as_f64().unwrap()
    );
    assert!(stdout.contains(&expected), "{expected} not in {stdout}");
    // An 800 × 600 picture of the run, and a page that plays its three frames.
    let png = std::fs::read(out.join("preview.png")).unwrap();
    assert_eq!(&png[1..4], b"PNG");
    assert_eq!(u32::from_be_bytes(png[16..20].try_into().unwrap()), 800);
    assert_eq!(u32::from_be_bytes(png[20..24].try_into().unwrap()), 600);
    let page = std::fs::read_to_string(out.join("view.html")).unwrap();
    assert!(
        page.contains(r#""frames":[0,3,6]"#),
        "the page lists the frames"
    );
    assert!(
        stdout.contains("view.html, ") && stdout.contains("(3 frames)"),
        "{stdout}"
    );
}

#[test]
fn view_of_a_folder_without_frames_says_so() {
    let dir = scratch("view-empty");
    let run = freeform(&["view", dir.to_str().unwrap()], &dir);
    assert!(!run.status.success());
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(
        stderr.contains("no frames") && stderr.contains("freeform simulate"),
        "{stderr}"
    );
}

#[test]
fn malformed_scene_files_fail_with_an_error_naming_the_field() {
    let dir = scratch("malformed");
    let cases = [
        (
            BOX_SCENE.replace("youngs_modulus", "young_modulus"),
            "young_modulus",
        ),
        (BOX_SCENE.replace("density = 1000\n", ""), "density"),
        (BOX_SCENE.replace("modes = 4", "modes = 60"), "basis.modes"),
        (
            BOX_SCENE.replace("poisson_ratio = 0.3", "poisson_ratio = 0.5"),
            "material",
        ),
        (BOX_SCENE.replace("axis = 0", "axis = 7"), "axis"),
        (
            BOX_SCENE.replace("time_step = 0.01", "time_step = \"fast\""),
            "time_step",
        ),
        (
            BOX_SCENE.replace("steps = 6\n", "steps = 0\n"),
            "simulation.steps",
        ),
        (
            BOX_SCENE.replace("youngs_modulus = 1e5", "youngs_modulus = -1e5"),
            "material",
        ),
        (
            BOX_SCENE.replace("time_step = 0.01", "time_step = nan"),
            "time_step",
        ),
    ];
    for (i, (text, field)) in cases.iter().enumerate() {
        let scene = dir.join(format!("bad{i}.toml"));
        std::fs::write(&scene, text).unwrap();
        let run = freeform(&["simulate", scene.to_str().unwrap()], &dir);
        assert!(!run.status.success(), "case {i} should fail");
        let stderr = String::from_utf8_lossy(&run.stderr);
        assert!(stderr.contains(field), "case {i}: {stderr}");
        assert!(
            stderr.contains(&format!("bad{i}.toml")),
            "case {i} names the file: {stderr}"
        );
        assert!(
            !dir.join(format!("out/bad{i}")).exists(),
            "case {i} wrote output"
        );
    }
    let missing = freeform(&["simulate", dir.join("nope.toml").to_str().unwrap()], &dir);
    assert!(!missing.status.success());
    assert!(String::from_utf8_lossy(&missing.stderr).contains("nope.toml"));
}

/// The first step of a splat workflow: a real 3DGS file (no face element) gets a basis.
#[test]
fn basis_of_the_shared_3dgs_donut_is_built_from_its_splat_centres() {
    let dir = scratch("donut-basis");
    let save = dir.join("donut.basis");
    let splat = test_support::fixtures::shared_splat();
    let run = freeform(
        &[
            "basis",
            splat.to_str().unwrap(),
            "--basis-points",
            "3000",
            "--kernels",
            "200",
            "--modes",
            "6",
            "--save",
            save.to_str().unwrap(),
        ],
        &dir,
    );
    let stdout = String::from_utf8_lossy(&run.stdout);
    assert_success(&run);
    assert!(stdout.contains("N = 3000 points"), "{stdout}");
    let basis = skin_eigen::SkinningBasis::load(&save).unwrap();
    assert_eq!(basis.modes(), 6);
}

#[test]
fn render_draws_the_shared_donut_to_a_png_of_the_asked_size() {
    let dir = scratch("donut-render");
    let splat = test_support::fixtures::shared_splat();
    let run = freeform(
        &[
            "render",
            splat.to_str().unwrap(),
            "--size",
            "96",
            "--up",
            "z",
        ],
        &dir,
    );
    assert_success(&run);
    let png = std::fs::read(dir.join("out/render/donut_mipsplatting_fused.png")).unwrap();
    // PNG signature, then the IHDR chunk: width and height, big-endian, at bytes 16..24.
    assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n");
    assert_eq!(&png[16..24], &[0, 0, 0, 96, 0, 0, 0, 96]);
    // A missing file is a named error, not a panic.
    let run = freeform(&["render", "no-such-file.ply"], &dir);
    assert!(!run.status.success());
    assert!(String::from_utf8_lossy(&run.stderr).contains("no-such-file.ply"));
}

#[test]
fn a_scene_file_runs_the_shared_donut_as_a_plain_point_cloud_filled_inside() {
    let dir = scratch("donut-points");
    let splat = test_support::fixtures::shared_splat();
    let scene = dir.join("donut_points.toml");
    std::fs::write(
        &scene,
        format!(
            "[geometry]\npoints = \"{}\"\nfill_interior = true\n[material]\n\
             youngs_modulus = 1e5\npoisson_ratio = 0.45\n\
             density = 1000\n[basis]\nmodes = 4\nkernels = 100\npoints = 3000\n[simulation]\n\
             time_step = 0.01\nsteps = 3\npoints = 1000\n[scene]\ngravity = [0, 0, -9.8]\n",
            splat.display()
        ),
    )
    .unwrap();
    let run = freeform(&["simulate", scene.to_str().unwrap()], &dir);
    assert_success(&run);
    // Every splat centre is written as a point per frame; free fall moves the cloud by
    // backward Euler's g h² n(n+1)/2 after n = 3 steps.
    let summary: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(dir.join("out/donut_points/summary.json")).unwrap(),
    )
    .unwrap();
    // 1000 of the splat centres, and as many again filling the inside.
    let points = summary["simulation_points"].as_u64().unwrap();
    assert!(points > 1500 && points < 3500, "{points} simulation points");
    let moved = summary["final_max_displacement"].as_f64().unwrap();
    let expected = 9.8 * 0.01 * 0.01 * 3.0 * 4.0 / 2.0;
    assert!((moved - expected).abs() < 1e-6, "{moved} vs {expected}");
    let ply = std::fs::read(dir.join("out/donut_points/frame_00003.ply")).unwrap();
    let header = String::from_utf8_lossy(&ply[..ply.len().min(400)]).to_string();
    assert!(header.contains("element vertex 45624"), "{header}");
    // The viewer page reads the deformed splats back.
    let page = std::fs::read_to_string(dir.join("out/donut_points/view.html")).unwrap();
    assert!(page.contains(r#""points":45624"#));
}
