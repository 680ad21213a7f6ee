//! The shapes experiment (Tables 2 and 7): the three boundary conditions select the intended
//! regions, and `freeform table 2 7 --quick` runs end to end on a real mesh, reporting a broken
//! one with its reason and going on.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use eval::scene_spec::Motion;
use eval::shape_boundary::{ShapeBoundary, ShapeBoundaryParams};
use nalgebra::Vector3;
use rkpm_core::TriangleMesh;
use test_support::fixtures::{scratch_dir, shared_mesh};

/// Cell size of the test grid: 1/16, so no cell centre lies on a slab plane (0.131, 1.869).
const H: f64 = 0.0625;

/// The 1 × 2 × 0.5 m box (y longest, L = 2) and the centres of its 16 × 32 × 8 cells.
fn box_and_cell_centres() -> (TriangleMesh, Vec<Vector3<f64>>) {
    let max = Vector3::new(1.0, 2.0, 0.5);
    let mut points = Vec::new();
    for i in 0..16 {
        for j in 0..32 {
            for k in 0..8 {
                points.push(Vector3::new(
                    (i as f64 + 0.5) * H,
                    (j as f64 + 0.5) * H,
                    (k as f64 + 0.5) * H,
                ));
            }
        }
    }
    (TriangleMesh::cuboid(Vector3::zeros(), max), points)
}

#[test]
fn fix_side_holds_the_min_x_slab_of_five_percent_of_the_largest_side_under_gravity() {
    let (surface, points) = box_and_cell_centres();
    let scene = ShapeBoundary::FixSide.scene(&surface, &points, &ShapeBoundaryParams::default());
    assert_eq!(scene.gravity, Some(Vector3::new(0.0, -9.8, 0.0)));
    let selected = scene.select(&points, "cell centres").unwrap();
    assert_eq!(selected.len(), 1);
    assert_eq!(scene.constraints[0].motion, Motion::Rest);
    // x ≤ x_min + 0.05 · L = 0.031 + 0.1, x_min the smallest candidate's: the two cell layers
    // at x = 0.031 and 0.094, 32 × 8 cells each.
    assert_eq!(selected[0].len(), 2 * 32 * 8);
    for (i, p) in points.iter().enumerate() {
        assert_eq!(selected[0].contains(&i), p.x < 0.13, "{p:?}");
    }
}

#[test]
fn pull_boundary_moves_both_ends_of_the_longest_axis_apart() {
    let (surface, points) = box_and_cell_centres();
    let params = ShapeBoundaryParams::default();
    let scene = ShapeBoundary::PullBoundary.scene(&surface, &points, &params);
    assert_eq!(scene.gravity, None);
    let selected = scene.select(&points, "cell centres").unwrap();
    assert_eq!(selected.len(), 2);
    // The longest axis is y (2 m): slabs 0.1 thick from the extreme candidates (y = 0.031 and
    // 1.969), two layers of 16 × 8 cells each.
    let ends: [fn(&Vector3<f64>) -> bool; 2] = [|p| p.y < 0.13, |p| p.y > 1.87];
    for (region, inside) in selected.iter().zip(ends) {
        assert_eq!(region.len(), 2 * 16 * 8);
        for (i, p) in points.iter().enumerate() {
            assert_eq!(region.contains(&i), inside(p), "{p:?}");
        }
    }
    // Each end moves at 0.2 L/s = 0.4 m/s along ∓y.
    let t = 0.25;
    let p = Vector3::new(0.5, 0.0, 0.25);
    let q = Vector3::new(0.5, 2.0, 0.25);
    let moved_low = scene.constraints[0].motion.at(&p, t);
    let moved_high = scene.constraints[1].motion.at(&q, t);
    assert!((moved_low - Vector3::new(0.5, -0.1, 0.25)).norm() < 1e-12);
    assert!((moved_high - Vector3::new(0.5, 2.1, 0.25)).norm() < 1e-12);
}

#[test]
fn pull_farthest_pulls_four_distinct_corners_outward_within_the_radius() {
    let (surface, points) = box_and_cell_centres();
    let params = ShapeBoundaryParams::default();
    let centre = Vector3::new(0.5, 1.0, 0.25);
    let lo = [H / 2.0; 3];
    let hi = [1.0 - H / 2.0, 2.0 - H / 2.0, 0.5 - H / 2.0];
    let corner_of = |p: &Vector3<f64>| {
        (0..3).all(|a| (p[a] - lo[a]).abs() < 1e-12 || (p[a] - hi[a]).abs() < 1e-12)
    };
    // Sampling among all cells: the first two are opposite corners (the farthest from the
    // centre, ties to the lowest index, then the farthest from it).
    let first_two = eval::shape_boundary::farthest_points(&points, centre, 2);
    assert!((first_two[0] - Vector3::from(lo)).norm() < 1e-12);
    assert!(
        (first_two[1] - Vector3::from(hi)).norm() < 1e-12,
        "{first_two:?}"
    );
    // Patches centred on the corner cells.
    let corners: Vec<Vector3<f64>> = points.iter().filter(|p| corner_of(p)).copied().collect();
    assert_eq!(corners.len(), 8);
    let scene = ShapeBoundary::PullFarthest.scene(&surface, &corners, &params);
    assert_eq!(scene.gravity, None);
    assert_eq!(scene.constraints.len(), 4);
    // Lattice points (a, b, c) ≥ 0 of the octant with |(a, b, c)| · H ≤ 0.1 · L = 0.2: the cells
    // within the radius of a corner cell (the radius, 3.2 cells, stays inside the box).
    let mut octant = 0;
    for a in 0..4 {
        for b in 0..4 {
            for c in 0..4 {
                if ((a * a + b * b + c * c) as f64).sqrt() * H <= 0.2 {
                    octant += 1;
                }
            }
        }
    }
    let selected = scene.select(&points, "cell centres").unwrap();
    let mut centres = Vec::new();
    for (constraint, region) in scene.constraints.iter().zip(&selected) {
        let eval::scene_spec::Region::Ball { center, radius } = constraint.region else {
            panic!("a pulled patch is a ball, got {:?}", constraint.region);
        };
        assert!(
            corner_of(&center),
            "patch centre {center:?} is not a corner cell"
        );
        assert!((radius - 0.2).abs() < 1e-12);
        assert_eq!(region.len(), octant, "patch at {center:?}");
        let Motion::Translate { velocity } = constraint.motion else {
            panic!("a pulled patch translates, got {:?}", constraint.motion);
        };
        let outward = (center - centre).normalize();
        assert!((velocity - outward * 0.4).norm() < 1e-12, "{velocity:?}");
        centres.push(center);
    }
    for (i, a) in centres.iter().enumerate() {
        for b in &centres[i + 1..] {
            assert!((a - b).norm() > 1.0, "patches {a:?} and {b:?} are close");
        }
    }
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
    let dir = scratch_dir("shape-quick");
    let meshes: PathBuf = dir.join("meshes");
    std::fs::create_dir_all(&meshes).unwrap();
    std::fs::copy(shared_mesh("bunny.obj"), meshes.join("bunny.obj")).unwrap();
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
    let first = freeform(&args, &dir);
    assert!(
        first.status.success(),
        "{}",
        String::from_utf8_lossy(&first.stderr)
    );
    let tables: serde_json::Value = serde_json::from_slice(&first.stdout).unwrap();
    let t2 = table(&tables, 2);
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
    for a in &all {
        assert_eq!(a["shapes"], 1, "only the bunny is averaged: {a}");
    }
    let t7 = table(&tables, 7);
    let fits: Vec<f64> = t7["shapes"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|r| r["ours_fitting_residual"].as_f64())
        .collect();
    assert_eq!(fits.len(), 3);
    assert!(fits.iter().all(|f| *f > 0.0 && *f < 0.1), "{fits:?}");

    // Again: every FEM trajectory and the network come from the cache, the numbers are the same.
    let second = freeform(&args, &dir);
    assert!(second.status.success());
    let again: serde_json::Value = serde_json::from_slice(&second.stdout).unwrap();
    for (a, b) in rows
        .iter()
        .zip(table(&again, 2)["shapes"].as_array().unwrap())
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
fn an_unknown_only_name_is_an_error_listing_the_meshes() {
    let dir = scratch_dir("shape-only");
    let meshes = shared_mesh("bunny.obj").parent().unwrap().to_path_buf();
    let out = freeform(
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
    let missing = freeform(&["table", "2", "--quick"], &dir);
    assert!(!missing.status.success());
    assert!(String::from_utf8_lossy(&missing.stderr).contains("--meshes"));
}
