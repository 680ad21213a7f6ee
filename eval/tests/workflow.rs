//! Table 2 as tasks: shards of the quick study merge into the tables a single process writes,
//! `merge` refuses shards it cannot combine and says which shapes are missing, and the stages
//! run one by one give the same rows.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use eval::shapes::boundary::ShapeBoundary;
use eval::shapes::catalog::ShapeCollection;
use eval::shapes::config::ShapeStudyConfig;
use eval::shapes::result::{MethodScores, ShapeResult, ShapeRow, ShapeStudy};
use eval::shapes::shard::{MergeError, Shard, merge_shards};
use serde_json::Value;

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("freeform-workflow-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(dir.join("meshes")).unwrap();
    // Two of the shared shapes, small enough for the quick study in seconds.
    let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("../data/meshes");
    for mesh in ["37620.stl", "93070.stl"] {
        std::fs::copy(data.join(mesh), dir.join("meshes").join(mesh)).unwrap();
    }
    dir
}

/// `freeform-paper ARGS` in `dir` with one thread.
fn paper(dir: &Path, args: &[&str]) -> Output {
    let run = Command::new(env!("CARGO_BIN_EXE_freeform-paper"))
        .current_dir(dir)
        .env("RAYON_NUM_THREADS", "1")
        .arg("--quiet")
        .args(args)
        .output()
        .unwrap();
    assert!(
        run.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&run.stderr)
    );
    run
}

/// `value` without its timing fields and the folders a run was given.
fn numbers(value: &Value) -> Value {
    const LEFT_OUT: [&str; 7] = [
        "seconds",
        "ms_per_step",
        "cached",
        "wall",
        "cache_dir",
        "meshes",
        "fem_over",
    ];
    match value {
        Value::Object(map) => Value::Object(
            map.iter()
                .filter(|(k, _)| !LEFT_OUT.iter().any(|t| k.contains(t)))
                .map(|(k, v)| (k.clone(), numbers(v)))
                .collect(),
        ),
        Value::Array(items) => Value::Array(items.iter().map(numbers).collect()),
        other => other.clone(),
    }
}

fn tables(dir: &Path, out: &str) -> Vec<Value> {
    ["table2.json", "table7.json"]
        .iter()
        .map(|f| serde_json::from_slice(&std::fs::read(dir.join(out).join(f)).unwrap()).unwrap())
        .collect()
}

#[test]
fn two_shards_in_fresh_caches_merge_into_the_tables_of_one_process_and_stages_give_the_same_rows() {
    let dir = scratch("shards");
    let study = ["table", "2", "7", "--quick", "--meshes", "meshes"];
    paper(
        &dir,
        &[&["--out", "single", "--cache", "cache-single"][..], &study].concat(),
    );
    for i in 0..2 {
        let (cache, shard) = (format!("cache{i}"), format!("shard{i}.json"));
        let part = format!("{i}/2");
        paper(
            &dir,
            &[
                &["--out", "part", "--cache", &cache][..],
                &study,
                &["--shard", &part, "--shard-out", &shard],
            ]
            .concat(),
        );
    }
    paper(
        &dir,
        &["--out", "merged", "merge", "shard1.json", "shard0.json"],
    );
    let (single, merged) = (tables(&dir, "single"), tables(&dir, "merged"));
    for (a, b) in single.iter().zip(&merged) {
        assert_eq!(numbers(a), numbers(b), "table {}", a["table"]);
    }
    // The same study as stages, one shape at a time, into one cache: the same rows.
    let plan: Value = serde_json::from_slice(
        &paper(
            &dir,
            &[&["--cache", "cache-stages"][..], &study, &["--plan"]].concat(),
        )
        .stdout,
    )
    .unwrap();
    let stages: Vec<String> = plan["stages"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s.as_str().unwrap().to_string())
        .collect();
    assert_eq!(
        stages,
        ["train", "reference", "row"],
        "the quick study checks no convergence"
    );
    let mut shards = Vec::new();
    for shape in ["37620.stl", "93070.stl"] {
        for stage in &stages {
            let shard = format!("{shape}.json");
            let receipt = format!("{shape}.{stage}.receipt.json");
            let mut args = vec!["--cache", "cache-stages", "--out", "stages"];
            args.extend(study);
            args.extend(["--only", shape, "--stage", stage, "--receipt", &receipt]);
            if stage == "row" {
                args.extend(["--shard-out", &shard]);
                shards.push(shard.clone());
            }
            paper(&dir, &args);
            let receipt: Value =
                serde_json::from_slice(&std::fs::read(dir.join(&receipt)).unwrap()).unwrap();
            assert_eq!(receipt["shapes"], serde_json::json!([shape]));
            assert_eq!(receipt["settings_key"], plan["settings_key"]);
        }
    }
    let mut args = vec!["--out", "from-stages", "merge"];
    args.extend(shards.iter().map(String::as_str));
    paper(&dir, &args);
    for (a, b) in single.iter().zip(&tables(&dir, "from-stages")) {
        assert_eq!(numbers(a), numbers(b), "table {} from stages", a["table"]);
    }
}

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

fn shape(name: &str, mse: f64) -> ShapeResult {
    ShapeResult {
        name: name.into(),
        title: name.into(),
        collection: ShapeCollection::Other,
        class: None,
        youngs_modulus: 1e5,
        basis_points: 1000,
        basis_seconds: Some(1.0),
        training_seconds: None,
        fem_mesh: None,
        fem_seconds: Some(2.0),
        rows: vec![ShapeRow {
            ours: Some(scores(mse)),
            region_points: vec![10],
            ..ShapeRow::new(ShapeBoundary::FixSide)
        }],
        error: None,
    }
}

fn shard(config: &ShapeStudyConfig, names: &[&str], shapes: Vec<ShapeResult>) -> Shard {
    let study = ShapeStudy {
        config: config.clone(),
        shapes,
        seconds: 1.0,
    };
    Shard::new(&study, names.iter().map(|n| n.to_string()).collect(), 0.0)
}

#[test]
fn merge_refuses_other_settings_and_conflicting_rows_by_name_and_names_the_missing_shapes() {
    let config = ShapeStudyConfig::quick(Vec::new(), PathBuf::from("cache"));
    let names = ["a.obj", "b.obj", "c.obj", "d.obj", "e.obj", "f.obj"];
    let shards: Vec<(PathBuf, Shard)> = names[..5]
        .iter()
        .enumerate()
        .map(|(i, n)| {
            (
                PathBuf::from(format!("s{i}.json")),
                shard(&config, &names, vec![shape(n, 1e-3)]),
            )
        })
        .collect();
    // Five of six: the study is partial and the sixth is named.
    let study = merge_shards(&shards).unwrap();
    assert_eq!(study.shapes.len(), 5);
    assert_eq!(study.unfinished(), vec!["f.obj".to_string()]);
    let table = eval::shapes::tables::table2(&study);
    assert!(
        table.markdown.contains("**Partial:** 5 of 6 shapes") && table.markdown.contains("f.obj")
    );

    // A shard of other settings is refused with the setting named.
    let mut other = config.clone();
    other.settings.modes = 16;
    let mut with_other = shards.clone();
    with_other.push((
        "other.json".into(),
        shard(&other, &names, vec![shape("f.obj", 1e-3)]),
    ));
    let err = merge_shards(&with_other).unwrap_err();
    assert!(
        matches!(err, MergeError::SettingsDiffer { ref field, .. } if field == "settings.modes"),
        "{err}"
    );
    assert!(err.to_string().contains("other.json") && err.to_string().contains("settings.modes"));

    // The same shape twice: equal outside timing is fine, a different MSE is a conflict.
    let mut again = shards.clone();
    let mut slower = shape("a.obj", 1e-3);
    slower.basis_seconds = Some(99.0);
    again.push(("again.json".into(), shard(&config, &names, vec![slower])));
    assert_eq!(merge_shards(&again).unwrap().shapes.len(), 5);
    let mut conflicting = shards;
    conflicting.push((
        "conflict.json".into(),
        shard(&config, &names, vec![shape("a.obj", 2e-3)]),
    ));
    let err = merge_shards(&conflicting).unwrap_err();
    assert!(
        matches!(err, MergeError::Conflict { ref shape, .. } if shape == "a.obj"),
        "{err}"
    );
    assert!(
        err.to_string().contains("`rows[0].ours.fitting_residual`"),
        "{err}"
    );
}

#[test]
fn a_shard_reads_back_bit_for_bit_and_a_foreign_file_is_refused() {
    let dir = scratch("roundtrip");
    let config = ShapeStudyConfig::quick(Vec::new(), PathBuf::from("cache"));
    let written = shard(&config, &["a.obj"], vec![shape("a.obj", 0.1 + 0.2)]);
    let path = dir.join("a.json");
    written.write(&path).unwrap();
    assert_eq!(Shard::read(&path).unwrap(), written);
    std::fs::write(dir.join("other.json"), br#"{"format": "something else"}"#).unwrap();
    let err = Shard::read(&dir.join("other.json")).unwrap_err();
    assert!(err.to_string().contains("not a shard"), "{err}");
}

#[test]
fn two_concurrent_reference_tasks_on_one_cache_compute_the_reference_once() {
    let dir = scratch("concurrent");
    let task = || {
        Command::new(env!("CARGO_BIN_EXE_freeform-paper"))
            .current_dir(&dir)
            .env("RAYON_NUM_THREADS", "1")
            .args([
                "--cache",
                "shared-cache",
                "--out",
                "out",
                "table",
                "2",
                "7",
                "--quick",
            ])
            .args([
                "--meshes",
                "meshes",
                "--only",
                "93070.stl",
                "--boundaries",
                "fix_side",
            ])
            .args(["--stage", "reference"])
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap()
    };
    let (a, b) = (task(), task());
    let logs: Vec<String> = [a, b]
        .into_iter()
        .map(|child| {
            let out = child.wait_with_output().unwrap();
            assert!(
                out.status.success(),
                "{}",
                String::from_utf8_lossy(&out.stderr)
            );
            String::from_utf8_lossy(&out.stderr).into_owned()
        })
        .collect();
    let computed = logs.iter().filter(|log| log.contains(" DOFs in ")).count();
    let loaded = logs
        .iter()
        .filter(|log| log.contains("loaded from the cache"))
        .count();
    assert_eq!((computed, loaded), (1, 1), "{logs:#?}");
    let fem = dir.join("shared-cache/fem");
    let locks = std::fs::read_dir(&fem)
        .unwrap()
        .filter(|e| {
            e.as_ref()
                .unwrap()
                .file_name()
                .to_string_lossy()
                .ends_with(".lock")
        })
        .count();
    assert_eq!(locks, 0, "no lock is left behind");
}
