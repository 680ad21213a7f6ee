//! Tables 2 and 7 on hand-made studies.

use std::path::PathBuf;

use serde_json::{Value, json};

use super::{table2, table7};
use crate::shapes::boundary::ShapeBoundary;
use crate::shapes::catalog::ShapeCollection;
use crate::shapes::config::ShapeStudyConfig;
use crate::shapes::reference::{FemMeshSummary, ShapeFemParams};
use crate::shapes::result::{FemRunSummary, MethodScores, ShapeResult, ShapeRow, ShapeStudy};

fn scores(mse: f64) -> MethodScores {
    MethodScores {
        mse,
        max: mse.sqrt(),
        fitting_residual: 0.1 * mse,
        ms_per_step: 1.0,
        quadrature_points: 100,
        unconverged_steps: 0,
        max_pin_deviation: 0.0,
    }
}

/// A shape with one row per boundary condition, its FEM mesh off by `volume_error` and its
/// FEM runs leaving `unconverged` steps, our MSE `mse` everywhere.
fn shape(name: &str, volume_error: f64, unconverged: usize, mse: f64) -> ShapeResult {
    ShapeResult {
        name: name.into(),
        title: name.into(),
        collection: ShapeCollection::Other,
        class: None,
        youngs_modulus: 1e5,
        basis_points: 1000,
        basis_seconds: Some(1.0),
        training_seconds: None,
        fem_mesh: Some(FemMeshSummary {
            cells_across: 8,
            vertices: 100,
            tets: 300,
            relative_volume_error: volume_error,
            dropped_pieces: 0,
            dropped_volume_fraction: 0.0,
        }),
        fem_seconds: Some(1.0),
        rows: ShapeBoundary::ALL
            .iter()
            .map(|&boundary| ShapeRow {
                fem: Some(FemRunSummary {
                    region_nodes: vec![10],
                    max_displacement: 0.1,
                    dofs: 300,
                    seconds_per_step: 0.01,
                    iterations_per_step: 2.0,
                    unconverged_steps: unconverged,
                    cached: false,
                }),
                ours: Some(scores(mse)),
                region_points: vec![5],
                ..ShapeRow::new(boundary)
            })
            .collect(),
        error: None,
    }
}

#[test]
fn a_partial_study_says_which_shapes_are_not_finished_and_a_complete_one_says_nothing() {
    let mut config = ShapeStudyConfig::full(
        vec![
            PathBuf::from("meshes/done.obj"),
            PathBuf::from("meshes/later.stl"),
        ],
        PathBuf::from("unused"),
    );
    config.simplicits = None;
    let partial = ShapeStudy {
        config,
        shapes: vec![shape("done.obj", 0.0, 0, 1e-3)],
        seconds: 1.0,
    };
    let complete = ShapeStudy {
        shapes: vec![
            shape("done.obj", 0.0, 0, 1e-3),
            shape("later.stl", 0.0, 0, 2e-3),
        ],
        ..partial.clone()
    };
    for (table, complete_table) in [
        (table2(&partial), table2(&complete)),
        (table7(&partial), table7(&complete)),
    ] {
        let said = "**Partial:** 1 of 2 shapes finished";
        assert!(table.markdown.contains(said), "{}", table.markdown);
        assert!(table.markdown.contains("not yet: later.stl."));
        assert_eq!(table.json["unfinished"], json!(["later.stl"]));
        assert_eq!(table.json["shapes"].as_array().unwrap().len(), 3);
        assert!(!complete_table.markdown.contains("Partial"));
        assert_eq!(complete_table.json["unfinished"], json!([]));
        assert_eq!(complete_table.json["shapes"].as_array().unwrap().len(), 6);
    }
}

#[test]
fn a_study_of_one_condition_lists_only_its_rows_and_averages_no_shape_for_the_others() {
    let mut config = ShapeStudyConfig::full(Vec::new(), PathBuf::from("unused"));
    config.simplicits = None;
    config.boundaries = vec![ShapeBoundary::PullFarthest];
    config.fem = ShapeFemParams::graded();
    let mut pulled = shape("pulled", 0.0, 0, 1e-3);
    pulled
        .rows
        .retain(|r| r.boundary == ShapeBoundary::PullFarthest);
    let study = ShapeStudy {
        config,
        shapes: vec![pulled],
        seconds: 1.0,
    };
    for table in [table2(&study), table7(&study)] {
        // The settings name the references' own lattices and the Pulls' factor reuse.
        for said in [
            "along Pull farthest's pulled balls' spheres",
            "the Pulls' references and Fix side's where E ≥ 1e7 Pa to 1e-8, the Cholesky \
             factor carried",
        ] {
            assert!(table.markdown.contains(said), "{said}: {}", table.markdown);
        }
        let rows = table.json["shapes"].as_array().unwrap();
        assert_eq!(rows.len(), 1, "{rows:?}");
        assert_eq!(rows[0]["bc"], "pull_farthest");
        for average in table.json["averages"].as_array().unwrap() {
            // (Table 2 names the condition "bc", Table 7 "boundary".)
            let bc = average.get("bc").or_else(|| average.get("boundary"));
            let n = average["shapes"].as_u64();
            let expected = u64::from(bc.is_some_and(|bc| bc == "pull_farthest"));
            assert_eq!(n, Some(expected), "{average}");
        }
    }
}

#[test]
fn the_step_time_section_averages_every_row_a_method_ran() {
    let mut config = ShapeStudyConfig::full(Vec::new(), PathBuf::from("unused"));
    config.simplicits = None;
    let fast = shape("fast", 0.0, 0, 1e-3);
    let mut slow = shape("slow", 0.0, 0, 1e-3);
    for row in &mut slow.rows {
        row.ours = Some(MethodScores {
            ms_per_step: 3.0,
            quadrature_points: 300,
            ..scores(1e-3)
        });
    }
    let study = ShapeStudy {
        config,
        shapes: vec![fast, slow],
        seconds: 1.0,
    };
    let md = table2(&study).markdown;
    // Three rows at 1 ms on 100 points, three at 3 ms on 300: mean 2, sd 1; the median of
    // six counts is the upper middle one.
    assert!(
        md.contains("- FreeForm: 2.0 ± 1.0 ms a step on a median of 300 quadrature points (n = 6)"),
        "{md}"
    );
    assert!(!md.contains("- Simplicits:"), "not run: {md}");
}

#[test]
fn convergence_checks_report_their_finer_runs_and_their_time_per_shape() {
    let mut config = ShapeStudyConfig::full(Vec::new(), PathBuf::from("unused"));
    config.simplicits = None;
    let steps = config.boundary.steps as f64;
    // Two of "checked"'s rows ran a check of 1234 DOFs at 2 s a step; "unchecked" none.
    let mut checked = shape("checked", 0.0, 0, 1e-3);
    for row in &mut checked.rows[..2] {
        row.reference_check = row.fem.clone().map(|fem| FemRunSummary {
            dofs: 1234,
            seconds_per_step: 2.0,
            ..fem
        });
        row.reference_change = Some(1e-6);
    }
    let study = ShapeStudy {
        config,
        shapes: vec![checked, shape("unchecked", 0.0, 0, 1e-3)],
        seconds: 1.0,
    };
    let t2 = table2(&study);
    let rows = t2.json["shapes"].as_array().unwrap();
    let checks: Vec<&Value> = rows.iter().map(|r| &r["reference_check"]).collect();
    assert_eq!(checks[0]["dofs"], 1234);
    assert_eq!(checks[1]["seconds_per_step"], 2.0);
    assert!(checks[2].is_null() && checks[3].is_null(), "{checks:?}");
    let expected = format!(
        "- FEM convergence checks (the 1.5× finer references): {:.2} ± 0.00 s (n = 1)",
        2.0 * 2.0 * steps
    );
    assert!(t2.markdown.contains(&expected), "{}", t2.markdown);
}

#[test]
fn references_that_lost_volume_stalled_or_change_under_refinement_are_named_and_left_out_of_the_averages()
 {
    let mut config = ShapeStudyConfig::full(Vec::new(), PathBuf::from("unused"));
    config.simplicits = None;
    // A reference 1.5× finer changes "coarse" by half its method error: not converged;
    // "good" by a hundredth of it.
    let mut coarse = shape("coarse", 0.0, 0, 1e-3);
    for row in &mut coarse.rows {
        row.reference_change = Some(5e-4);
    }
    let mut good = shape("good", -0.02, 0, 1e-4);
    for row in &mut good.rows {
        row.reference_change = Some(1e-6);
    }
    // Fix side ran on its own mesh (a shifted lattice), which lost a tenth of the volume
    // while the shape's mesh kept it: that row alone is out.
    let mut clamped = shape("clamped", 0.0, 0, 1e-2);
    for row in &mut clamped.rows {
        row.reference_change = Some(1e-6);
    }
    clamped.rows[0].fem_mesh = clamped.fem_mesh.map(|m| FemMeshSummary {
        relative_volume_error: -0.1,
        ..m
    });
    assert_eq!(clamped.rows[0].boundary, ShapeBoundary::FixSide);
    let study = ShapeStudy {
        config,
        shapes: vec![
            good,
            shape("thin", -0.40, 0, 1e-1),
            shape("stalled", 0.01, 2, 1e-2),
            coarse,
            clamped,
        ],
        seconds: 1.0,
    };
    let t2 = table2(&study);
    let rows = t2.json["shapes"].as_array().unwrap();
    let of = |name: &str| rows.iter().find(|r| r["name"] == name).unwrap();
    assert_eq!(of("good")["trusted"], true);
    assert_eq!(of("thin")["trusted"], false);
    assert!(
        of("thin")["why_untrusted"]
            .as_str()
            .unwrap()
            .contains("-40.0% of the surface's volume"),
        "{}",
        of("thin")
    );
    assert!((of("thin")["fem_volume_error"].as_f64().unwrap() + 0.4).abs() < 1e-12);
    assert!(
        of("stalled")["why_untrusted"]
            .as_str()
            .unwrap()
            .contains("2 steps unconverged")
    );
    assert!(
        of("coarse")["why_untrusted"]
            .as_str()
            .unwrap()
            .contains("finer reference changes it by 5.00e-4"),
        "{}",
        of("coarse")
    );
    assert_eq!(of("good")["reference_change"].as_f64(), Some(1e-6));
    let clamped_rows: Vec<&Value> = rows.iter().filter(|r| r["name"] == "clamped").collect();
    let (fix, pulls) = clamped_rows.split_first().unwrap();
    assert_eq!(fix["bc"], "fix_side");
    assert_eq!(fix["trusted"], false);
    assert!(
        fix["why_untrusted"]
            .as_str()
            .unwrap()
            .contains("-10.0% of the surface's volume"),
        "{fix}"
    );
    assert_eq!(fix["fem_volume_error"].as_f64(), Some(-0.1));
    for pull in pulls {
        assert_eq!(pull["trusted"], true, "{pull}");
        assert_eq!(pull["fem_volume_error"].as_f64(), Some(0.0));
    }
    // Only the trusted rows enter the averages: Fix side has "good" alone, the Pulls
    // "good" and "clamped".
    for average in t2.json["averages"].as_array().unwrap() {
        let (shapes, mse) = if average["bc"] == "fix_side" {
            (1, 1e-4)
        } else {
            (2, 0.5 * (1e-4 + 1e-2))
        };
        assert_eq!(average["shapes"], shapes, "{average}");
        let ours = average["ours_mse"].as_f64().unwrap();
        assert!((ours - mse).abs() < 1e-15, "{average}");
    }
    assert!(t2.markdown.contains("no trustworthy reference"));
    let t7 = table7(&study);
    let averages = t7.json["averages"].as_array().unwrap();
    // Per collection, in ShapeBoundary::ALL's order: Fix side, Pull farthest, Pull boundary.
    assert!(!averages.is_empty());
    for collection in averages.chunks(3) {
        let shapes: Vec<&Value> = collection.iter().map(|a| &a["shapes"]).collect();
        assert_eq!(shapes, [1, 2, 2], "{collection:?}");
    }
}

#[test]
fn the_settings_line_names_the_projected_volumetric_term_and_the_hold_only_when_set() {
    let study = |settings| ShapeStudy {
        config: ShapeStudyConfig {
            settings,
            simplicits: None,
            ..ShapeStudyConfig::full(Vec::new(), PathBuf::from("unused"))
        },
        shapes: vec![shape("one", 0.0, 0, 1e-3)],
        seconds: 1.0,
    };
    let paper = ShapeStudyConfig::full(Vec::new(), PathBuf::from("unused")).settings;
    let md = table2(&study(paper)).markdown;
    assert!(
        md.contains("; pin penalty κ_pin = 3e3 · max E / L²"),
        "{md}"
    );
    assert!(!md.contains("volumetric term"), "{md}");
    let md = table2(&study(paper.converging())).markdown;
    assert!(
        md.contains(
            "; regions held exactly by a weighted basis (transition 1 × the object's thickness"
        ),
        "{md}"
    );
    assert!(
        md.contains("; volumetric term projected onto a pressure space of the constant"),
        "{md}"
    );
}
