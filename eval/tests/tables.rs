//! The beam tables on a tiny study: the JSON rows carry the fields the CLI promises, the paper's
//! numbers sit beside ours, and Table 5's ratio is FEM time over ours.

use baselines::SimplicitsParams;
use eval::beam::study::{BeamStudy, run_beam_study};
use eval::beam::tables::{table1, table5, table6, twist_error_plot};
use eval::beam_protocol::study_config::BeamStudyConfig;
use eval::beam_scenario::BeamTest;
use eval::fem_reference::FemResolution;
use eval::particle_baselines::mpm::MpmStudyConfig;
use eval::particle_baselines::particle_baseline::ParticleMethod;
use eval::particle_baselines::sph::SphStudyConfig;
use eval::reduced_settings::ReducedSettings;
use eval::report::table::{RenderedTable, write_table};
use fem_ref::ElementOrder;
use freeform::terminal_progress::TerminalProgress;
use optimize::NewtonParams;

fn quiet() -> TerminalProgress {
    TerminalProgress {
        quiet: true,
        ..Default::default()
    }
}

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
        fem_newton: NewtonParams::default(),
        simplicits: Some(SimplicitsParams {
            steps: 30,
            points_per_step: 100,
            transforms_per_step: 2,
            ..SimplicitsParams::default()
        }),
        cache_dir: dir.join("cache"),
        exact_pins: None,
        mpm: Some(MpmStudyConfig {
            spacings: vec![0.25],
            ..MpmStudyConfig::default()
        }),
        sph: Some(SphStudyConfig {
            spacings: vec![0.25],
            ..SphStudyConfig::default()
        }),
    };
    let study = run_beam_study(&config, &quiet()).unwrap();
    assert_eq!(study.rows.len(), 2);

    let t1 = table1(&study);
    table1_rows_carry_ours_beside_the_paper(&t1);
    per_frame_errors_average_to_each_row(&study);
    the_twist_plot_has_a_curve_per_method(&study);
    particle_rows_are_scored_like_the_rest(&t1, &study);
    tables_5_and_6_carry_ratios_and_residuals(&study);
    let files = write_table(&t1, &dir.join("out")).unwrap();
    assert_eq!(files.len(), 3);
    let csv = std::fs::read_to_string(&files[2]).unwrap();
    assert!(
        csv.starts_with(
            "test,m,ours_mse,ours_max,exact_mse,exact_max,exact_max_pin_deviation,simplicits_mse,simplicits_max,paper_ours_mse"
        )
    );
    assert_eq!(csv.lines().count(), 3);

    // A second study loads the network from the cache: the same Simplicits numbers.
    let again = run_beam_study(&config, &quiet()).unwrap();
    assert_eq!(table1(&again).json["rows"], t1.json["rows"]);
    assert_eq!(
        table1(&again).json["particle_baselines"],
        t1.json["particle_baselines"],
        "MPM and SPH trajectories come back from the cache"
    );
}

fn table1_rows_carry_ours_beside_the_paper(t1: &RenderedTable) {
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
}

fn per_frame_errors_average_to_each_row(study: &BeamStudy) {
    // Per-frame errors: one per step, and their mean is the row's MSE.
    for r in &study.rows {
        let frames = &r.ours_per_frame_mse;
        assert_eq!(frames.len(), 8);
        let mean = frames.iter().sum::<f64>() / frames.len() as f64;
        assert!(
            (mean - r.ours_mse).abs() <= 1e-12 * r.ours_mse,
            "{mean} vs {}",
            r.ours_mse
        );
        let s = r.simplicits.as_ref().unwrap();
        let mean = s.per_frame_mse.iter().sum::<f64>() / s.per_frame_mse.len() as f64;
        assert!((mean - s.mse).abs() <= 1e-12 * s.mse);
    }
    for p in &study.particle_baselines {
        let mse = p.mse.expect("scored");
        let mean = p.per_frame_mse.iter().sum::<f64>() / p.per_frame_mse.len() as f64;
        assert_eq!(p.per_frame_mse.len(), 8);
        assert!((mean - mse).abs() <= 1e-12 * mse, "{mean} vs {mse}");
    }
}

fn the_twist_plot_has_a_curve_per_method(study: &BeamStudy) {
    let plot = twist_error_plot(study).expect("a Twist row to plot");
    let labels: Vec<&str> = plot.series.iter().map(|s| s.label.as_str()).collect();
    assert_eq!(
        labels,
        [
            "FreeForm m = 6",
            "Simplicits m = 6",
            "MPM Δx = 0.25 m",
            "SPH spacing = 0.25 m"
        ]
    );
    assert_eq!(plot.series[0].points.len(), 8);
    assert!(
        (plot.series[0].points[7].0 - 0.08).abs() < 1e-12,
        "x is t = frame · h"
    );
}

fn particle_rows_are_scored_like_the_rest(t1: &RenderedTable, study: &BeamStudy) {
    // MPM and SPH on both tests at the one spacing, scored at the FEM vertices like the rest.
    let particles = t1.json["particle_baselines"].as_array().unwrap();
    assert_eq!(particles.len(), 4, "{particles:?}");
    for p in particles {
        assert_eq!(p["spacing"].as_f64(), Some(0.25));
        let mse = p["mse"].as_f64().unwrap();
        let max = p["max"].as_f64().unwrap();
        assert!(mse > 0.0 && max * max >= mse && max.is_finite(), "{p}");
        assert!(p["ms_per_step"].as_f64().unwrap() > 0.0);
        let (substeps, paper) = match p["method"].as_str() {
            // Δt = 1e-4 s in 0.01 s frames.
            Some("mpm") => (100, [1.42e-3, 2.34e-5]),
            // One implicit step per frame, with its conjugate-gradient iterations counted.
            Some("sph") => {
                assert!(p["iterations_per_step"].as_f64().unwrap() >= 1.0, "{p}");
                (1, [6.57e-4, 1.33e-4])
            }
            other => panic!("unexpected method {other:?}"),
        };
        assert_eq!(p["substeps_per_step"].as_u64(), Some(substeps), "{p}");
        let test = usize::from(p["test"] == "twist");
        assert_eq!(p["paper_mse"].as_f64(), Some(paper[test]), "{p}");
        assert!(p["failure"].is_null(), "{p}");
    }
    assert!(t1.markdown.contains("### MPM (ours)"));
    assert!(t1.markdown.contains("### SPH (ours)"));
    assert_eq!(
        study
            .particle_baselines
            .iter()
            .filter(|p| p.method == ParticleMethod::Sph)
            .count(),
        2
    );
}

fn tables_5_and_6_carry_ratios_and_residuals(study: &BeamStudy) {
    let t5 = table5(study);
    let r = &t5.json["rows"][0];
    let fem_ms = t5.json["fem_ms_per_step"].as_f64().unwrap();
    let ratio = r["fem_over_ours"].as_f64().unwrap();
    assert!((ratio - fem_ms / r["ours_ms_per_step"].as_f64().unwrap()).abs() < 1e-9 * ratio);
    assert_eq!(r["paper_ours_ms"].as_f64(), Some(3.01));
    let particles = t5.json["particle_baselines"].as_array().unwrap();
    assert_eq!(
        particles.len(),
        2,
        "Table 5 times the Bend only, once per method"
    );
    assert_eq!(t5.json["paper_mpm_ms"].as_f64(), Some(23.1));
    assert_eq!(t5.json["paper_sph_ms"].as_f64(), Some(37.8));

    let t6 = table6(study);
    let residual = t6.json["rows"][0]["ours_fitting_residual"]
        .as_f64()
        .unwrap();
    assert!(residual > 0.0 && residual < 0.1, "{residual}");
}

/// Both tests at `modes` on K = 60 kernels, 3 steps against a linear FEM at 2 cells per metre,
/// no baselines, cached under `dir`: a study of seconds.
fn coarse_study(modes: Vec<usize>, dir: &std::path::Path) -> BeamStudyConfig {
    BeamStudyConfig {
        modes,
        tests: BeamTest::ALL.to_vec(),
        settings: ReducedSettings {
            kernels: 60,
            basis_points: 1500,
            simulation_points: 400,
            ..ReducedSettings::default()
        },
        steps: Some(3),
        fem: FemResolution {
            order: ElementOrder::Linear,
            cells_per_metre: 2,
        },
        fem_newton: NewtonParams::default(),
        simplicits: None,
        cache_dir: dir.join("cache"),
        exact_pins: None,
        mpm: None,
        sph: None,
    }
}

#[test]
fn a_reference_with_unconverged_frames_is_refused_by_the_tables_with_the_frames_named() {
    let dir = std::env::temp_dir().join(format!("freeform-refused-{}", std::process::id()));
    let config = BeamStudyConfig {
        // One Newton iteration per step cannot converge a step of the Twist from rest.
        fem_newton: NewtonParams {
            max_iterations: 1,
            ..NewtonParams::default()
        },
        ..coarse_study(vec![4], &dir)
    };
    let study = run_beam_study(&config, &quiet()).unwrap();
    let twist = study
        .fem
        .iter()
        .find(|f| f.test == BeamTest::Twist)
        .unwrap();
    let why = twist
        .not_scored
        .as_deref()
        .expect("the Twist reference is refused");
    assert!(
        why.contains("did not converge at frame(s) 1, 2, 3 of 3 (cap 1 iterations)"),
        "{why}"
    );
    assert_eq!(twist.max_iterations, 1);
    assert_eq!(twist.unconverged_steps, 3);
    assert!(
        study.rows.iter().all(|r| r.test != BeamTest::Twist),
        "no Twist row is scored against it"
    );
    for table in [table1(&study), table6(&study)] {
        assert!(
            table.markdown.contains("**twist not scored**") && table.markdown.contains(why),
            "{}",
            table.markdown
        );
        let rows = table.json["rows"].as_array().unwrap();
        assert!(rows.iter().all(|r| r["test"] != "twist"), "{rows:?}");
    }
    assert!(twist_error_plot(&study).is_none());
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn table1_runs_both_pin_treatments_and_the_exact_rows_hold_their_regions() {
    let dir = std::env::temp_dir().join(format!("freeform-exact-{}", std::process::id()));
    let config = BeamStudyConfig {
        modes: vec![6],
        tests: BeamTest::ALL.to_vec(),
        // Kernels narrow enough (median radius ≈ 0.26 m) that the clamped end shrunk by 1.5
        // radii still holds a layer of simulation points.
        settings: ReducedSettings {
            kernels: 600,
            basis_points: 8000,
            simulation_points: 2000,
            ..ReducedSettings::default()
        },
        steps: Some(6),
        fem: FemResolution {
            order: ElementOrder::Quadratic,
            cells_per_metre: 2,
        },
        fem_newton: NewtonParams::default(),
        simplicits: None,
        cache_dir: dir.join("cache"),
        exact_pins: Some(1.5),
        mpm: None,
        sph: None,
    };
    let study = run_beam_study(&config, &quiet()).unwrap();
    let t1 = table1(&study);
    let rows = t1.json["rows"].as_array().unwrap();
    assert_eq!(rows.len(), 2);
    for row in rows {
        let mse = row["exact_mse"].as_f64().unwrap();
        let max = row["exact_max"].as_f64().unwrap();
        assert!(mse > 0.0 && max * max >= mse && max.is_finite(), "{row}");
        // The held points sit on their targets (≤ 1e-4 L, L = 5 m), the Twist's rotating end
        // included; the penalty lets its points drift.
        let held = row["exact_max_pin_deviation"].as_f64().unwrap();
        assert!(held <= 5e-4, "exact pins drift {held} m: {row}");
        assert!(row["max_pin_deviation"].as_f64().unwrap() > held, "{row}");
        assert!(row["exact_region_drift"].as_f64().unwrap().is_finite());
        assert!(row["exact_inset"].as_f64().unwrap() > 0.0);
    }
    assert!(t1.markdown.contains("Exact pins"), "{}", t1.markdown);
}

#[test]
fn a_run_that_fails_is_named_in_every_beam_table_and_the_other_rows_are_kept() {
    let dir = std::env::temp_dir().join(format!("freeform-failed-row-{}", std::process::id()));
    // m = 80 is not below K = 60: its basis cannot be built.
    let config = coarse_study(vec![4, 80], &dir);
    let study = run_beam_study(&config, &quiet()).unwrap();
    assert_eq!(study.rows.len(), 2);
    assert!(
        study
            .rows
            .iter()
            .all(|r| r.m == 4 && r.ours_mse.is_finite())
    );
    assert_eq!(study.failed_rows.len(), 2);
    for failed in &study.failed_rows {
        assert_eq!(failed.m, 80);
        assert!(
            failed.error.contains("asked for 80 modes"),
            "{}",
            failed.error
        );
    }
    for table in [table1(&study), table5(&study), table6(&study)] {
        assert!(
            table.markdown.contains("**bend m = 80 failed** (no row): ")
                && table
                    .markdown
                    .contains("**twist m = 80 failed** (no row): "),
            "{}",
            table.markdown
        );
    }
    let failed = table1(&study).json["failed_rows"].as_array().unwrap().len();
    assert_eq!(failed, 2);
    let _ = std::fs::remove_dir_all(&dir);
}
