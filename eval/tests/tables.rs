//! The beam tables on a tiny study: the JSON rows carry the fields the CLI promises, the paper's
//! numbers sit beside ours, and Table 5's ratio is FEM time over ours.

use baselines::SimplicitsParams;
use eval::beam::BeamTest;
use eval::beam_study::{BeamStudyConfig, run_beam_study};
use eval::fem_reference::FemResolution;
use eval::progress::Progress;
use eval::reduced_beam::ReducedSettings;
use eval::tables::{table1, table5, table6, write_table};
use fem_ref::ElementOrder;

#[test]
fn tiny_study_fills_tables_1_5_6_with_paper_columns_and_consistent_json() {
    let dir = std::env::temp_dir().join(format!("freeform-tables-{}", std::process::id()));
    let config = BeamStudyConfig {
        modes: vec![6],
        tests: BeamTest::ALL.to_vec(),
        settings: ReducedSettings {
            kernels: 80,
            basis_points: 2000,
            simulation_points: 600,
            ..ReducedSettings::default()
        },
        steps: Some(8),
        fem: FemResolution {
            order: ElementOrder::Quadratic,
            cells_per_metre: 2,
        },
        simplicits: Some(SimplicitsParams {
            steps: 30,
            points_per_step: 100,
            transforms_per_step: 2,
            ..SimplicitsParams::default()
        }),
        cache_dir: dir.join("cache"),
    };
    let study = run_beam_study(
        &config,
        &Progress {
            quiet: true,
            ..Default::default()
        },
    )
    .unwrap();
    assert_eq!(study.rows.len(), 2);

    let t1 = table1(&study);
    let rows = t1.json["rows"].as_array().unwrap();
    assert_eq!(rows.len(), 2);
    for (row, test) in rows.iter().zip(["bend", "twist"]) {
        assert_eq!(row["test"], test);
        assert_eq!(row["m"], 6);
        let mse = row["ours_mse"].as_f64().unwrap();
        let max = row["ours_max"].as_f64().unwrap();
        // max² ≥ mean of squares, both positive and finite.
        assert!(mse > 0.0 && max * max >= mse && max.is_finite(), "{row}");
    }
    assert_eq!(rows[0]["paper_ours_mse"].as_f64(), Some(7.80e-3));
    // The baseline ran through the same pipeline (a 30-step network: only finiteness matters).
    for row in rows {
        let mse = row["simplicits_mse"].as_f64().unwrap();
        assert!(mse.is_finite() && mse > 0.0, "{row}");
    }
    assert_eq!(rows[1]["paper_ours_mse"].as_f64(), Some(1.56e-4));
    assert!(t1.markdown.contains("| bend | 6 |") && t1.markdown.contains("7.80e-3"));
    assert!(
        t1.markdown.contains("P2 res 2"),
        "settings name the FEM resolution"
    );

    let t5 = table5(&study);
    let r = &t5.json["rows"][0];
    let fem_ms = t5.json["fem_ms_per_step"].as_f64().unwrap();
    let ratio = r["fem_over_ours"].as_f64().unwrap();
    assert!((ratio - fem_ms / r["ours_ms_per_step"].as_f64().unwrap()).abs() < 1e-9 * ratio);
    assert_eq!(r["paper_ours_ms"].as_f64(), Some(3.01));

    let t6 = table6(&study);
    let residual = t6.json["rows"][0]["ours_fitting_residual"]
        .as_f64()
        .unwrap();
    assert!(residual > 0.0 && residual < 0.1, "{residual}");

    let files = write_table(&t1, &dir.join("out")).unwrap();
    assert_eq!(files.len(), 3);
    let csv = std::fs::read_to_string(&files[2]).unwrap();
    assert!(
        csv.starts_with("test,m,ours_mse,ours_max,simplicits_mse,simplicits_max,paper_ours_mse")
    );
    assert_eq!(csv.lines().count(), 3);

    // A second study loads the network from the cache: the same Simplicits numbers.
    let again = run_beam_study(
        &config,
        &Progress {
            quiet: true,
            ..Default::default()
        },
    )
    .unwrap();
    assert_eq!(table1(&again).json["rows"], t1.json["rows"]);
}
