//! The `freeform-paper` binary end to end: the stress suite's quick run and the shapes tables
//! (2 and 7) on a real mesh beside a broken one, cached-only runs and the convergence check.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use test_support::fixtures::shared_mesh;

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("freeform-cli-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn freeform_paper(args: &[&str], dir: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_freeform-paper"))
        .args(args)
        .args(["--quiet", "--out"])
        .arg(dir.join("out"))
        .arg("--cache")
        .arg(dir.join("cache"))
        .output()
        .expect("the freeform-paper binary runs")
}

/// A `meshes/` folder in `dir` holding a copy of the shared bunny.
fn bunny_folder(dir: &Path) -> PathBuf {
    let meshes = dir.join("meshes");
    std::fs::create_dir_all(&meshes).unwrap();
    std::fs::copy(shared_mesh("bunny.obj"), meshes.join("bunny.obj")).unwrap();
    meshes
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
fn stress_quick_finishes_every_case_finite_and_reports_failures_by_name() {
    let dir = scratch("stress");
    let run = freeform_paper(&["stress", "--quick", "--json"], &dir);
    assert_success(&run);
    let outcomes: serde_json::Value = serde_json::from_slice(&run.stdout).unwrap();
    let outcomes = outcomes.as_array().unwrap();
    assert_eq!(outcomes.len(), 10);
    let case = |name: &str| {
        outcomes
            .iter()
            .find(|o| o["case"]["name"] == name)
            .unwrap_or_else(|| panic!("no case {name}"))
    };
    for o in outcomes {
        assert_eq!(o["all_finite"], true, "{o}");
        assert!(o["status"].get("panicked").is_none(), "{o}");
    }
    // A plate one point thick cannot carry linear RKPM: a named error, not a crash.
    let plate = &case("plate one point thick")["status"]["error"];
    assert!(
        plate
            .as_str()
            .unwrap()
            .contains("singular RKPM moment matrix"),
        "{plate}"
    );
    assert!(
        plate
            .as_str()
            .unwrap()
            .contains("thinner than the point spacing"),
        "{plate}"
    );
    // The fast twist crushes material and the diagnostic sees it: det F falls to about 0.2
    // with the library's tangent (exact where the step system is definite); the projected
    // tangent at every point found inverted minimizers here (det F < 0).
    let twist = case("Twist 4× faster (8640°/s)");
    assert!(twist["min_det_f"].as_f64().unwrap() < 0.5, "{twist}");
    // Gravity and floor only: backward Euler must not create energy.
    for name in [
        "Bend ν = 0.499",
        "Bend dt = 0.1",
        "cube at 10 m/s onto a floor",
        "layered sphere, contrast 1e4",
    ] {
        let o = case(name);
        assert_eq!(o["status"], "finished", "{o}");
        let growth = o["max_energy_growth"].as_f64().unwrap();
        assert!(growth < 1e-3, "{name}: energy grew by {growth}");
    }
    // The FEM reference at ν = 0.499 runs too (no energy balance for it).
    let fem = case("FEM Bend ν = 0.499");
    assert_eq!(fem["status"], "finished", "{fem}");
    assert_eq!(fem["unconverged_steps"], 0, "{fem}");
    let det = fem["min_det_f"].as_f64().unwrap();
    // Nearly incompressible: volume kept to 2% while the beam sags.
    assert!((det - 1.0).abs() < 0.02, "{fem}");
    // The impact and the sphere reach the floor and compress (det F < 1).
    for name in [
        "cube at 10 m/s onto a floor",
        "layered sphere, contrast 1e4",
    ] {
        let det = case(name)["min_det_f"].as_f64().unwrap();
        assert!(det < 0.999, "{name}: min det F {det}");
    }
    assert!(dir.join("out/stress/stress.md").is_file());
    let _ = std::fs::remove_dir_all(&dir);
}

fn table(tables: &serde_json::Value, number: u64) -> &serde_json::Value {
    tables
        .as_array()
        .unwrap()
        .iter()
        .find(|t| t["table"] == number)
        .unwrap()
}

#[test]
fn a_quick_shape_run_fills_tables_2_and_7_reports_a_broken_mesh_and_reuses_its_caches() {
    let dir = scratch("shape-quick");
    let meshes = bunny_folder(&dir);
    // An open surface: one triangle.
    std::fs::write(
        meshes.join("open.obj"),
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
    )
    .unwrap();
    let args = [
        "table",
        "2",
        "7",
        "--quick",
        "--json",
        "--meshes",
        meshes.to_str().unwrap(),
    ];
    let first = freeform_paper(&args, &dir);
    assert_success(&first);
    let tables: serde_json::Value = serde_json::from_slice(&first.stdout).unwrap();
    let rows = first_run_scores_the_bunny_and_names_the_open_mesh(&tables);
    let rows = rows.as_slice();
    // Again: every FEM trajectory and the network come from the cache, the numbers are the same.
    let second = freeform_paper(&args, &dir);
    assert_success(&second);
    let again: serde_json::Value = serde_json::from_slice(&second.stdout).unwrap();
    a_rerun_reads_every_reference_from_the_cache(rows, &again);
    // `--cached-only` computes nothing and scores the same rows from the cache.
    let cached_only = freeform_paper(&[&args[..], &["--cached-only"]].concat(), &dir);
    assert_success(&cached_only);
    let cached_only: serde_json::Value = serde_json::from_slice(&cached_only.stdout).unwrap();
    for (a, b) in rows
        .iter()
        .zip(table(&cached_only, 2)["shapes"].as_array().unwrap())
    {
        for key in [
            "ours_mse",
            "simplicits_mse",
            "exact_mse",
            "trusted",
            "error",
        ] {
            assert_eq!(a[key], b[key], "{key}");
        }
    }

    // `--simulation-points` and the fast step reach the shapes: about twice the points, more of
    // them in every held region, FreeForm on a cubature of fewer, Simplicits on every one of
    // them, the same cached references.
    let denser_args = [
        &args[..],
        &[
            "--set",
            "settings.simulation_points=2000",
            "--set",
            "settings.quadrature={ kind = \"cubature\" }",
            "--set",
            "simplicits_quadrature={ kind = \"full\" }",
            "--set",
            "settings.hessian_reuse={ while_contracting = { contraction = 0.7 } }",
        ],
    ]
    .concat();
    let denser = freeform_paper(&denser_args, &dir);
    assert_success(&denser);
    let denser: serde_json::Value = serde_json::from_slice(&denser.stdout).unwrap();
    let denser = table(&denser, 2);
    assert_eq!(denser["settings"]["settings"]["simulation_points"], 2000);
    assert_eq!(
        denser["settings"]["settings"]["quadrature"]["kind"],
        "cubature"
    );
    assert_eq!(denser["settings"]["simplicits_quadrature"]["kind"], "full");
    let held = |row: &serde_json::Value| -> u64 {
        row["region_points"]
            .as_array()
            .unwrap()
            .iter()
            .map(|n| n.as_u64().unwrap())
            .sum()
    };
    for (a, b) in rows
        .iter()
        .zip(denser["shapes"].as_array().unwrap())
        .filter(|(a, _)| a["name"] == "bunny.obj")
    {
        assert_eq!(b["fem"]["cached"], true);
        assert!(held(b) > held(a), "{} → {}", held(a), held(b));
        for method in ["ours", "simplicits"] {
            let points = |row: &serde_json::Value| {
                row[format!("{method}_quadrature_points")].as_u64().unwrap()
            };
            assert!(points(a) > 900, "every point of the quick grid: {a}");
            if method == "ours" {
                assert!(points(b) < points(a), "a cubature of fewer: {b}");
            } else {
                assert!(points(b) > 1800, "every point of the denser grid: {b}");
            }
            assert!(b[format!("{method}_ms_per_step")].as_f64().unwrap() > 0.0);
        }
    }
}

fn first_run_scores_the_bunny_and_names_the_open_mesh(
    tables: &serde_json::Value,
) -> Vec<serde_json::Value> {
    let t2 = table(tables, 2);
    let rows = t2["shapes"].as_array().unwrap();
    assert_eq!(rows.len(), 6, "three conditions for each of the two files");
    for row in rows.iter().filter(|r| r["name"] == "bunny.obj") {
        assert!(row["error"].is_null(), "{row}");
        assert_eq!(row["youngs_modulus"], 1e5, "the bunny is organic");
        for key in ["ours_mse", "ours_max", "simplicits_mse", "simplicits_max"] {
            let v = row[key].as_f64().unwrap_or(f64::NAN);
            // Ten steps move the pulled regions by 0.02 L: errors are positive and far below L.
            assert!(v > 0.0 && v < 0.1, "{key} = {v} in {row}");
        }
        assert_eq!(row["fem"]["cached"], false);
    }
    let broken: Vec<&serde_json::Value> = rows.iter().filter(|r| r["name"] == "open.obj").collect();
    assert_eq!(broken.len(), 3);
    for row in broken {
        let error = row["error"].as_str().unwrap();
        assert!(
            error.contains("open") || error.contains("boundary"),
            "{error}"
        );
        assert!(row["ours_mse"].is_null());
    }
    let averages = t2["averages"].as_array().unwrap();
    let all: Vec<_> = averages
        .iter()
        .filter(|a| a["collection"] == "all")
        .collect();
    assert_eq!(all.len(), 3);
    // The quality gate: a bunny row is trusted exactly when its (coarse, 6-cell) FEM mesh keeps
    // the volume within 3% (its FEM converged), and only trusted rows are averaged.
    for a in &all {
        let bunny = rows
            .iter()
            .find(|r| r["name"] == "bunny.obj" && r["bc"] == a["bc"])
            .unwrap();
        let volume_error = bunny["fem_volume_error"].as_f64().unwrap();
        let trusted = volume_error.abs() <= 0.03;
        assert_eq!(bunny["trusted"], trusted, "{bunny}");
        assert_eq!(bunny["why_untrusted"].is_null(), trusted, "{bunny}");
        assert_eq!(
            a["shapes"],
            usize::from(trusted),
            "only the bunny can be averaged: {a}"
        );
    }
    let t7 = table(tables, 7);
    let fits: Vec<f64> = t7["shapes"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|r| r["ours_fitting_residual"].as_f64())
        .collect();
    assert_eq!(fits.len(), 3);
    assert!(fits.iter().all(|f| *f > 0.0 && *f < 0.1), "{fits:?}");
    rows.clone()
}

fn a_rerun_reads_every_reference_from_the_cache(
    rows: &[serde_json::Value],
    again: &serde_json::Value,
) {
    for (a, b) in rows
        .iter()
        .zip(table(again, 2)["shapes"].as_array().unwrap())
    {
        for key in ["ours_mse", "ours_max", "simplicits_mse", "simplicits_max"] {
            assert_eq!(a[key], b[key], "{key}");
        }
        if a["name"] == "bunny.obj" {
            assert_eq!(b["fem"]["cached"], true);
        }
    }
}

#[test]
fn a_cached_only_shape_run_on_an_empty_cache_computes_nothing_and_scores_no_row() {
    let dir = scratch("shape-cached-only");
    let meshes = bunny_folder(&dir);
    let args = [
        "table",
        "2",
        "--quick",
        "--json",
        "--cached-only",
        "--meshes",
        meshes.to_str().unwrap(),
    ];
    let run = freeform_paper(&[&args[..], &["--set", "simplicits=none"]].concat(), &dir);
    assert_success(&run);
    let t2: serde_json::Value = serde_json::from_slice(&run.stdout).unwrap();
    let rows = t2["shapes"].as_array().unwrap();
    assert_eq!(rows.len(), 3);
    for row in rows {
        let error = row["error"].as_str().unwrap_or_default();
        assert!(
            error.starts_with("FEM bunny.obj") && error.contains("is not in the cache"),
            "{row}"
        );
        assert_eq!(row["trusted"], false);
        assert!(row["ours_mse"].is_null());
    }
    for average in t2["averages"].as_array().unwrap() {
        assert_eq!(average["shapes"], 0, "{average}");
    }
    let markdown = std::fs::read_to_string(dir.join("out").join("table2.md")).unwrap();
    assert!(markdown.contains("**Cached only:**"), "{markdown}");
    // Nor is a network trained: the shape says which one it lacks.
    let run = freeform_paper(&args, &dir);
    assert_success(&run);
    let t2: serde_json::Value = serde_json::from_slice(&run.stdout).unwrap();
    for row in t2["shapes"].as_array().unwrap() {
        let error = row["error"].as_str().unwrap_or_default();
        assert!(
            error.contains("Simplicits m = 6 (a readable network) is not in the cache"),
            "{row}"
        );
    }
    for computed in ["fem", "simplicits"] {
        let folder = dir.join("cache").join(computed);
        let entries = std::fs::read_dir(&folder).map_or(0, |d| d.count());
        assert_eq!(entries, 0, "{} holds {entries} entries", folder.display());
    }
    // A damaged network is reported too, and left as it is rather than trained again.
    let fix_side = [
        "table",
        "2",
        "--quick",
        "--json",
        "--set",
        "boundaries=[\"fix_side\"]",
        "--meshes",
        meshes.to_str().unwrap(),
    ];
    assert_success(&freeform_paper(&fix_side, &dir));
    let networks: Vec<PathBuf> = std::fs::read_dir(dir.join("cache").join("simplicits"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    assert_eq!(networks.len(), 1, "{networks:?}");
    std::fs::write(&networks[0], "damaged").unwrap();
    let run = freeform_paper(&[&fix_side[..], &["--cached-only"]].concat(), &dir);
    assert_success(&run);
    let t2: serde_json::Value = serde_json::from_slice(&run.stdout).unwrap();
    let error = t2["shapes"][0]["error"].as_str().unwrap_or_default();
    assert!(
        error.contains("Simplicits m = 6 (a readable network)"),
        "{error}"
    );
    assert_eq!(std::fs::read(&networks[0]).unwrap(), b"damaged");
}

#[test]
fn an_unknown_only_name_is_an_error_listing_the_meshes() {
    let dir = scratch("shape-only");
    let meshes = shared_mesh("bunny.obj").parent().unwrap().to_path_buf();
    let out = freeform_paper(
        &[
            "table",
            "2",
            "--quick",
            "--meshes",
            meshes.to_str().unwrap(),
            "--only",
            "teapot",
        ],
        &dir,
    );
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("--only teapot") && stderr.contains("bunny.obj"),
        "{stderr}"
    );
    let missing = freeform_paper(&["table", "2", "--quick"], &dir);
    assert!(!missing.status.success());
    assert!(String::from_utf8_lossy(&missing.stderr).contains("--meshes"));
}

#[test]
fn a_quick_convergence_check_measures_each_run_conditions_finer_change_on_either_mesher() {
    // Fix side and Pull farthest only: on uniform lattices both share the shape's finer mesh;
    // on graded ones each has its own (the clamp on a vertex plane, the pulled balls' edges
    // refined). Every row gets its finer reference's change, and Pull boundary is not run.
    let dir = scratch("shape-convergence");
    let meshes = bunny_folder(&dir);
    for (mesher, preset) in [
        ("uniform", "shapes-quick"),
        ("graded", "shapes-quick-graded"),
    ] {
        let run = freeform_paper(
            &[
                "table",
                "2",
                "7",
                "--preset",
                preset,
                "--json",
                "--set",
                "simplicits=none",
                "--set",
                "exact_pins=none",
                "--set",
                "check_convergence=true",
                "--set",
                "boundaries=[\"fix_side\", \"pull_farthest\"]",
                "--meshes",
                meshes.to_str().unwrap(),
            ],
            &dir,
        );
        assert_success(&run);
        let tables: serde_json::Value = serde_json::from_slice(&run.stdout).unwrap();
        let rows = table(&tables, 2)["shapes"].as_array().unwrap().clone();
        let bcs: Vec<&str> = rows.iter().map(|r| r["bc"].as_str().unwrap()).collect();
        assert_eq!(bcs, ["fix_side", "pull_farthest"], "{mesher}");
        for row in &rows {
            let change = row["reference_change"].as_f64().unwrap_or(f64::NAN);
            assert!(
                change > 0.0 && change < 0.1,
                "{mesher}: the finer reference's change {change} in {row}"
            );
        }
    }
}
