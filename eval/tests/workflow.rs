//! Table 2 as tasks: shards of the quick study merge into the tables a single process writes,
//! the stages run one by one give the same rows, and two reference tasks on one cache compute
//! the reference once (the merging rules themselves: `merge.rs`).

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use serde_json::Value;

mod common;

use common::numbers;
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
    // Estimated before any numeric work, each reference has the DOFs of its run; with the
    // convergence check, each check is estimated too, on its finer mesh.
    let estimate = |extra: &[&str]| -> Value {
        let args = [
            &["--cache", "cache-stages"][..],
            &study,
            extra,
            &["--plan", "--estimate"],
        ];
        let plan: Value = serde_json::from_slice(&paper(&dir, &args.concat()).stdout).unwrap();
        plan["estimates"]["references"].clone()
    };
    let estimates = estimate(&[]);
    for row in single[0]["shapes"].as_array().unwrap() {
        let e = estimates
            .as_array()
            .unwrap()
            .iter()
            .find(|e| e["shape"] == row["name"] && e["boundary"] == row["bc"])
            .unwrap();
        assert_eq!(e["reference"]["dofs"], row["fem"]["dofs"], "{e}");
        assert!(e["reference"]["factor_bytes"].as_u64().unwrap() > 0);
    }
    // (A check whose finer mesh cannot hold a region says why, as its run would.)
    let checks = estimate(&["--set", "check_convergence=true"]);
    for e in checks.as_array().unwrap() {
        match e["check"]["dofs"].as_u64() {
            Some(dofs) => assert!(dofs > e["reference"]["dofs"].as_u64().unwrap(), "{e}"),
            None => assert!(e["error"].is_string(), "{e}"),
        }
    }
    assert!(
        checks
            .as_array()
            .unwrap()
            .iter()
            .any(|e| e["check"].is_object())
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
