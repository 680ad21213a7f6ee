//! Shards of the shapes study merge row by row: refused when they disagree, partial when rows
//! are missing, and rendered tables imported as shards render the same tables.

mod common;

use std::path::{Path, PathBuf};

use eval::shapes::boundary::ShapeBoundary;
use eval::shapes::catalog::ShapeCollection;
use eval::shapes::config::ShapeStudyConfig;
use eval::shapes::merge::{MergeError, merge_shards};
use eval::shapes::result::{MethodScores, ShapeResult, ShapeRow, ShapeStudy};
use eval::shapes::shard::Shard;

use common::numbers;

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
        err.to_string()
            .contains("`rows[fix_side].ours.fitting_residual`"),
        "{err}"
    );
}

/// `shape(name, mse)` with a row for every condition of `boundaries`.
fn shape_with_rows(name: &str, boundaries: &[ShapeBoundary]) -> ShapeResult {
    let one = shape(name, 1e-3);
    ShapeResult {
        rows: boundaries
            .iter()
            .map(|&b| ShapeRow {
                boundary: b,
                ..one.rows[0].clone()
            })
            .collect(),
        ..one
    }
}

#[test]
fn rows_of_one_shape_in_two_shards_merge_into_the_whole_shape_and_missing_rows_are_named() {
    let mut config = ShapeStudyConfig::quick(Vec::new(), PathBuf::from("cache"));
    config.boundaries = ShapeBoundary::ALL.to_vec();
    let names = ["a.obj", "b.obj"];
    let whole = shard(
        &config,
        &names,
        vec![
            shape_with_rows("a.obj", &ShapeBoundary::ALL),
            shape_with_rows("b.obj", &ShapeBoundary::ALL),
        ],
    );
    let (fix, pulls) = (
        [ShapeBoundary::FixSide],
        [ShapeBoundary::PullFarthest, ShapeBoundary::PullBoundary],
    );
    let part = |boundaries: &[ShapeBoundary], shapes: &[&str]| {
        let mut c = config.clone();
        c.boundaries = boundaries.to_vec();
        shard(
            &c,
            &names,
            shapes
                .iter()
                .map(|n| shape_with_rows(n, boundaries))
                .collect(),
        )
    };
    // The pulls first: the merge puts each shape's rows in the conditions' order.
    let parts = vec![
        ("pulls.json".into(), part(&pulls, &["a.obj", "b.obj"])),
        ("fix.json".into(), part(&fix, &["a.obj", "b.obj"])),
    ];
    let single = merge_shards(&[("whole.json".into(), whole)]).unwrap();
    let merged = merge_shards(&parts).unwrap();
    assert_eq!(merged.config.boundaries, ShapeBoundary::ALL.to_vec());
    assert!(merged.unfinished_rows().is_empty());
    for (a, b) in [
        (
            eval::shapes::tables::table2(&single),
            eval::shapes::tables::table2(&merged),
        ),
        (
            eval::shapes::tables::table7(&single),
            eval::shapes::tables::table7(&merged),
        ),
    ] {
        assert_eq!(numbers(&a.json), numbers(&b.json));
    }
    // Each shard ran its own references: their FEM seconds add up.
    assert_eq!(merged.shapes[0].fem_seconds, Some(4.0));

    // b's Pulls in no shard: two rows missing, named, and the tables say Partial.
    let missing = vec![
        parts[1].clone(),
        ("a-pulls.json".into(), part(&pulls, &["a.obj"])),
    ];
    let partial = merge_shards(&missing).unwrap();
    assert_eq!(
        partial.unfinished_rows(),
        vec!["b.obj (Pull farthest)", "b.obj (Pull boundary)"]
    );
    let table = eval::shapes::tables::table2(&partial);
    assert!(
        table
            .markdown
            .contains("**Partial:** rows not yet: b.obj (Pull farthest), b.obj (Pull boundary)"),
        "{}",
        table.markdown
    );
    assert_eq!(table.json["unfinished_rows"].as_array().unwrap().len(), 2);
}

#[test]
fn factor_reuse_is_compared_row_by_row_where_it_covers_the_reference() {
    use eval::shapes::reference::ReferenceFactorReuse;
    let mut pulls = ShapeStudyConfig::quick(Vec::new(), PathBuf::from("cache"));
    pulls.boundaries = ShapeBoundary::ALL.to_vec();
    pulls.fem.factor_reuse = ReferenceFactorReuse::Pulls;
    let mut stiff_too = pulls.clone();
    stiff_too.fem.factor_reuse = ReferenceFactorReuse::PullsAndStiffFixSide;
    let names = ["soft.obj", "stiff.obj"];
    let soft = shape_with_rows("soft.obj", &ShapeBoundary::ALL);
    let mut stiff = shape_with_rows("stiff.obj", &ShapeBoundary::ALL);
    stiff.youngs_modulus = 1e8;
    // A soft shape's rows: both settings reuse the factor on the same references.
    let agree = [
        (
            "a.json".into(),
            shard(&stiff_too, &names, vec![stiff.clone()]),
        ),
        ("b.json".into(), shard(&pulls, &names, vec![soft])),
    ];
    assert_eq!(merge_shards(&agree).unwrap().shapes.len(), 2);
    // A stiff shape's Fix side: one reused the factor, the other did not.
    let differ = [
        (
            "a.json".into(),
            shard(&stiff_too, &names, vec![stiff.clone()]),
        ),
        ("b.json".into(), shard(&pulls, &names, vec![stiff])),
    ];
    let err = merge_shards(&differ).unwrap_err();
    assert!(
        matches!(err, MergeError::SettingsDiffer { ref field, .. } if field == "fem.factor_reuse[stiff.obj fix_side]"),
        "{err}"
    );
}

#[test]
fn a_rendered_table_imported_as_shards_renders_the_same_tables() {
    use eval::shapes::rendered_import::shards_from_rendered_tables;
    use eval::shapes::tables::{table2, table7};
    let mut config = ShapeStudyConfig::quick(Vec::new(), PathBuf::from("cache"));
    config.boundaries = ShapeBoundary::ALL.to_vec();
    let names = ["a.obj", "b.obj", "c.obj"];
    let mut a = shape_with_rows("a.obj", &ShapeBoundary::ALL);
    a.rows[1].exact = Some(MethodScores {
        max_pin_deviation: 1e-4,
        ..scores(2e-3)
    });
    a.rows[1].reference_change = Some(1e-7);
    a.rows[2].error = Some("the FEM run failed".into());
    a.rows[2].ours = None;
    let mut b = shape_with_rows("b.obj", &ShapeBoundary::ALL);
    b.rows.truncate(1);
    // Titles as a run gives a shape outside the catalog: its file stem.
    (a.title, b.title) = ("a".into(), "b".into());
    let original =
        merge_shards(&[("whole.json".into(), shard(&config, &names, vec![a, b]))]).unwrap();
    let rendered = table2(&original).json;
    let shards = shards_from_rendered_tables(&[("t/table2.json".into(), rendered)]).unwrap();
    let shard = shards[0].clone().unwrap();
    assert!(shard.imported_from.is_some());
    // b's two unattempted rows stay missing rather than becoming empty rows.
    assert_eq!(shard.shapes[1].rows.len(), 1);
    let imported = merge_shards(&[("imported.json".into(), shard)]).unwrap();
    assert_eq!(imported.unfinished(), vec!["c.obj".to_string()]);
    for (x, y) in [
        (table2(&original).json, table2(&imported).json),
        (table7(&original).json, table7(&imported).json),
    ] {
        assert_eq!(numbers(&x), numbers(&y));
    }
    // Every line but the wall time (the shards' own) is the same.
    let without_wall_time = |md: String| -> String {
        md.lines()
            .map(|l| l.split("Wall time of the study").next().unwrap_or(l))
            .collect::<Vec<_>>()
            .join("\n")
    };
    assert_eq!(
        without_wall_time(table2(&original).markdown),
        without_wall_time(table2(&imported).markdown)
    );

    // A later table's scored row replaces the earlier copy; the earlier keeps the rest.
    let mut later = original.clone();
    later.config.boundaries = vec![ShapeBoundary::PullBoundary];
    later.shapes.truncate(1);
    later.shapes[0].rows = vec![ShapeRow {
        boundary: ShapeBoundary::PullBoundary,
        ..original.shapes[0].rows[0].clone()
    }];
    let both = shards_from_rendered_tables(&[
        ("t/table2.json".into(), table2(&original).json),
        ("u/table2.json".into(), table2(&later).json),
    ])
    .unwrap();
    let rows = |s: &Option<Shard>| -> usize {
        s.as_ref()
            .map_or(0, |s| s.shapes.iter().map(|x| x.rows.len()).sum())
    };
    assert_eq!((rows(&both[0]), rows(&both[1])), (3, 1));
    let merged = merge_shards(&[
        ("t.json".into(), both[0].clone().unwrap()),
        ("u.json".into(), both[1].clone().unwrap()),
    ])
    .unwrap();
    assert!(merged.shapes[0].rows[2].ours.is_some());
}

#[test]
fn the_committed_shards_merge_into_72_trusted_rows_with_the_averages_the_readme_states() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../results/current-default/shards");
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    files.sort();
    let shards: Vec<(PathBuf, Shard)> = files
        .iter()
        .map(|f| (f.clone(), Shard::read(f).unwrap()))
        .collect();
    let study = merge_shards(&shards).unwrap();
    assert!(study.unfinished().is_empty() && study.unfinished_rows().is_empty());
    let table = eval::shapes::tables::table2(&study).json;
    let rows = table["shapes"].as_array().unwrap();
    assert_eq!(rows.len(), 72);
    assert!(rows.iter().all(|r| r["trusted"] == true));
    // The README's and RESULTS.md's averages over all 72 rows.
    let improvement = |bc: &str| -> String {
        let average = table["averages"]
            .as_array()
            .unwrap()
            .iter()
            .find(|a| a["collection"] == "all" && a["bc"] == bc)
            .unwrap();
        format!(
            "{:.1}",
            average["improvement_mse_percent"].as_f64().unwrap()
        )
    };
    assert_eq!(
        ["fix_side", "pull_farthest", "pull_boundary"].map(improvement),
        ["12.4", "42.2", "24.1"].map(String::from)
    );
}

#[test]
fn a_shard_reads_back_bit_for_bit_and_a_foreign_file_is_refused() {
    let dir = test_support::fixtures::scratch_dir("freeform-shard-roundtrip");
    let config = ShapeStudyConfig::quick(Vec::new(), PathBuf::from("cache"));
    let written = shard(&config, &["a.obj"], vec![shape("a.obj", 0.1 + 0.2)]);
    let path = dir.join("a.json");
    written.write(&path).unwrap();
    assert_eq!(Shard::read(&path).unwrap(), written);
    std::fs::write(dir.join("other.json"), br#"{"format": "something else"}"#).unwrap();
    let err = Shard::read(&dir.join("other.json")).unwrap_err();
    assert!(err.to_string().contains("not a shard"), "{err}");
}
