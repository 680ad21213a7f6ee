//! Every example scene in `freeform/examples/scenes` loads and passes validation, so the
//! README's commands do not fail on a typo; the robot arm's links form one chain.

use std::path::Path;

use freeform::{ObjectsFile, SceneFile};

#[test]
fn every_example_scene_loads_and_validates() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/scenes");
    let mut loaded = 0;
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().and_then(|e| e.to_str()) != Some("toml") {
            continue;
        }
        if ObjectsFile::describes(&path) {
            ObjectsFile::load(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        } else {
            SceneFile::load(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        }
        loaded += 1;
    }
    assert!(loaded >= 6, "{loaded} example scenes");
    let arm = ObjectsFile::load(&dir.join("robot_arm.toml")).unwrap();
    let parents: Vec<Option<usize>> = arm.scene.colliders.iter().map(|c| c.parent).collect();
    assert_eq!(parents, [None, Some(0), Some(1), Some(2), Some(3)]);
}
