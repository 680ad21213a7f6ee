//! Tables 3 and 4 on a tiny study: all six Table 3 rows in the paper's order with the paper's
//! numbers beside ours, the Table 4 rows for both methods, a cached rerun that reloads every
//! trained model and reproduces the numbers, and random simulation points that differ from the
//! grid.

use baselines::SimplicitsParams;
use eval::ablation::study::{AblationStudyConfig, run_ablation_study};
use eval::ablation::tables::{table3, table4};
use eval::beam_protocol::study_config::BeamStudyConfig;
use eval::beam_scenario::BeamTest;
use eval::fem_reference::FemResolution;
use eval::reduced_settings::{ReducedSettings, SimulationSampling};
use fem_ref::ElementOrder;
use freeform::terminal_progress::TerminalProgress;
use optimize::NewtonParams;

fn tiny_config(cache: std::path::PathBuf) -> AblationStudyConfig {
    AblationStudyConfig::full(BeamStudyConfig {
        exact_pins: None,
        mpm: None,
        sph: None,
        modes: vec![4],
        tests: BeamTest::ALL.to_vec(),
        settings: ReducedSettings {
            kernels: 80,
            basis_points: 2000,
            simulation_points: 600,
            ..ReducedSettings::default()
        },
        steps: Some(6),
        fem: FemResolution {
            order: ElementOrder::Quadratic,
            cells_per_metre: 2,
        },
        fem_newton: NewtonParams::default(),
        simplicits: Some(SimplicitsParams {
            steps: 20,
            points_per_step: 100,
            transforms_per_step: 2,
            ..SimplicitsParams::default()
        }),
        cache_dir: cache,
    })
}

#[test]
fn tiny_ablation_study_fills_tables_3_and_4_and_reloads_its_models_from_the_cache() {
    let dir = std::env::temp_dir().join(format!("freeform-ablation-{}", std::process::id()));
    let config = tiny_config(dir.join("cache"));
    let quiet = TerminalProgress {
        quiet: true,
        ..Default::default()
    };
    let study = run_ablation_study(&config, &quiet).unwrap();

    let methods: Vec<&str> = study.table3.iter().map(|r| r.method.as_str()).collect();
    assert_eq!(
        methods,
        [
            "Simplicits",
            "random-z + random points",
            "random-z + grid points",
            "Hessian + random points",
            "Hessian + grid points",
            "eigen solve (ours)"
        ]
    );
    for row in &study.table3 {
        for test in BeamTest::ALL {
            let mse = row.mse(test).unwrap();
            assert!(mse.is_finite() && mse > 0.0, "{}: {mse}", row.method);
        }
        assert!(!row.cached, "a fresh cache trains everything");
    }
    let t3 = table3(&study);
    let rows = t3.json["rows"].as_array().unwrap();
    assert_eq!(rows.len(), 6);
    assert_eq!(rows[4]["paper_twist_mse"].as_f64(), Some(3.49e-5));
    assert_eq!(rows[5]["paper_seconds"].as_f64(), Some(3.93));
    assert!(t3.markdown.contains("| Hessian + grid points |") && t3.markdown.contains("4.45e-4"));

    let t4 = table4(&study);
    let rows = t4.json["rows"].as_array().unwrap();
    assert_eq!(rows.len(), 4);
    for row in rows {
        let (grid, random) = (
            row["grid_mse"].as_f64().unwrap(),
            row["random_mse"].as_f64().unwrap(),
        );
        assert!(grid > 0.0 && random > 0.0 && grid != random, "{row}");
    }
    assert_eq!(rows[2]["paper_random_mse"].as_f64(), Some(9.42e-4));

    // Second run: every trained model from the cache, the same numbers bit for bit.
    let again = run_ablation_study(&config, &quiet).unwrap();
    for (a, b) in study.table3.iter().zip(&again.table3) {
        assert_eq!(a.scores, b.scores, "{}", a.method);
        assert_eq!(b.cached, b.loss.is_some(), "{}", b.method);
    }
    assert_eq!(study.table4, again.table4);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn random_simulation_points_fill_the_beam_with_equal_volumes_and_as_many_as_the_grid() {
    let grid = SimulationSampling::Grid.beam_points(3000).unwrap();
    let random = SimulationSampling::Random { seed: 1 }
        .beam_points(3000)
        .unwrap();
    assert_eq!(grid.len(), random.len());
    assert!((random.total_volume() - 5.0).abs() < 1e-9);
    let v = random.volumes()[0];
    assert!(random.volumes().iter().all(|&x| x == v));
    assert!(
        random.positions().iter().all(|p| {
            p.x > 0.0 && p.x < 5.0 && p.y > 0.0 && p.y < 1.0 && p.z > 0.0 && p.z < 1.0
        })
    );
    let other = SimulationSampling::Random { seed: 2 }
        .beam_points(3000)
        .unwrap();
    assert_ne!(random.positions(), other.positions());
}
