//! One scene description gives both solvers the same constrained set and the same targets.

use eval::beam_scenario::{BEAM_TIME_STEP, BeamTest};
use fem_ref::{ElementOrder, FemMesh, TetMesh};
use freeform::scene::{SceneSpec, SceneSpecError};
use nalgebra::Vector3;

fn beam_nodes() -> Vec<Vector3<f64>> {
    let tets = TetMesh::cuboid(Vector3::zeros(), Vector3::new(5.0, 1.0, 1.0), [10, 2, 2]).unwrap();
    FemMesh::new(tets, ElementOrder::Quadratic).nodes().to_vec()
}

#[test]
fn both_solvers_get_the_same_pinned_sets_and_targets_for_every_beam_test() {
    let nodes = beam_nodes();
    for test in BeamTest::ALL {
        let spec = test.scene();
        let reduced = spec.reduced_scene(&nodes).unwrap();
        let fem = spec.fem_scene(&nodes, 1e4).unwrap();
        assert_eq!(reduced.gravity, fem.gravity);
        assert_eq!(reduced.pins.len(), fem.dirichlet.len());
        for (pin, region) in reduced.pins.iter().zip(&fem.dirichlet) {
            assert_eq!(pin.points, region.nodes);
            assert!(!pin.points.is_empty());
            for &i in &pin.points {
                for t in [0.0, 0.05, 1.0 / 12.0, 0.2, 1.0 / 3.0, 0.5] {
                    assert_eq!(pin.target.at(&nodes[i], t), region.target.at(&nodes[i], t));
                }
            }
        }
    }
}

#[test]
fn the_plane_x_half_is_pinned_and_points_just_past_it_are_not() {
    let spec = BeamTest::Bend.scene();
    let points = [
        Vector3::new(0.5, 0.3, 0.3),
        Vector3::new(0.5 + 1e-10, 0.3, 0.3),
        Vector3::new(0.5 + 1e-6, 0.3, 0.3),
        Vector3::new(0.0, 0.0, 0.0),
    ];
    let scene = spec.reduced_scene(&points).unwrap();
    assert_eq!(scene.pins[0].points, vec![0, 1, 3]);
}

#[test]
fn twist_targets_rotate_the_end_about_the_beam_axis() {
    let spec = BeamTest::Twist.scene();
    let nodes = beam_nodes();
    let fem = spec.fem_scene(&nodes, 1e4).unwrap();
    let twisted = &fem.dirichlet[1];
    assert!(twisted.nodes.iter().all(|&i| nodes[i].x >= 4.5 - 1e-9));
    let corner = Vector3::new(5.0, 0.0, 0.0);
    // 2160°/s: 180° at 1/12 s (y, z mirrored through the axis), 360° at 1/6 s, held at 720°.
    let half = twisted.target.at(&corner, 1.0 / 12.0);
    assert!(
        (half - Vector3::new(5.0, 1.0, 1.0)).norm() < 1e-12,
        "{half:?}"
    );
    for t in [1.0 / 6.0, 1.0 / 3.0, 1.0] {
        assert!((twisted.target.at(&corner, t) - corner).norm() < 1e-12);
    }
    // 90° at 1/24 s, right-handed about +x: (y, z) − 0.5 = (−0.5, −0.5) → (0.5, −0.5).
    let quarter = twisted.target.at(&corner, 1.0 / 24.0);
    assert!(
        (quarter - Vector3::new(5.0, 1.0, 0.0)).norm() < 1e-12,
        "{quarter:?}"
    );
}

#[test]
fn twist_runs_thirty_steps_to_648_degrees_and_both_solvers_see_the_same_thirty_targets() {
    let test = BeamTest::Twist;
    assert_eq!(test.steps(), 30);
    let spec = test.scene();
    let nodes = beam_nodes();
    let reduced = spec.reduced_scene(&nodes).unwrap();
    let fem = spec.fem_scene(&nodes, 1e4).unwrap();
    let (pin, region) = (&reduced.pins[1], &fem.dirichlet[1]);
    assert_eq!(pin.points, region.nodes);
    let corner = Vector3::new(5.0, 0.0, 0.0);
    for step in 1..=test.steps() {
        let t = step as f64 * BEAM_TIME_STEP;
        assert_eq!(pin.target.at(&corner, t), region.target.at(&corner, t));
    }
    // The last target: 2160°/s · 0.30 s = 648° = 720° − 72°, i.e. −72° about +x from the rest
    // offset (y, z) − 0.5 = (−0.5, −0.5).
    let last = region
        .target
        .at(&corner, test.steps() as f64 * BEAM_TIME_STEP);
    let angle = (-72.0f64).to_radians();
    let (c, s) = (angle.cos(), angle.sin());
    let expected = Vector3::new(5.0, 0.5 + (-0.5 * c + 0.5 * s), 0.5 + (-0.5 * s - 0.5 * c));
    assert!((last - expected).norm() < 1e-12, "{last:?} vs {expected:?}");
}

#[test]
fn a_region_that_selects_nothing_is_an_error_naming_it() {
    let spec = BeamTest::Twist.scene();
    let only_left = [Vector3::new(0.1, 0.5, 0.5)];
    match spec.reduced_scene(&only_left) {
        Err(SceneSpecError::EmptyRegion { index: 1, .. }) => {}
        other => panic!("expected EmptyRegion for constraint 1, got {other:?}"),
    }
    let bad: SceneSpec = serde_json::from_str(
        r#"{"constraints": [{"region": {"below": {"axis": 3, "value": 0.0}}, "motion": "rest"}]}"#,
    )
    .unwrap();
    let message = bad.validate().unwrap_err().to_string();
    assert!(
        message.contains("constraints[0].region: axis is 3"),
        "{message}"
    );
}

#[test]
fn a_ball_region_holds_the_points_within_its_radius_and_a_degenerate_ball_is_named() {
    let ball: SceneSpec = serde_json::from_str(
        r#"{"constraints": [{"region": {"ball": {"center": [1.0, 0.0, 0.0], "radius": 0.5}}, "motion": "rest"}]}"#,
    )
    .unwrap();
    let points = [
        Vector3::new(1.0, 0.0, 0.0),
        Vector3::new(1.5, 0.0, 0.0),
        Vector3::new(1.0, 0.3, 0.4),
        Vector3::new(1.0, 0.3, 0.41),
        Vector3::new(0.0, 0.0, 0.0),
    ];
    assert_eq!(ball.select(&points, "points").unwrap(), vec![vec![0, 1, 2]]);
    for radius in ["0.0", "-1.0"] {
        let bad: SceneSpec = serde_json::from_str(&format!(
            r#"{{"constraints": [{{"region": {{"ball": {{"center": [0, 0, 0], "radius": {radius}}}}}, "motion": "rest"}}]}}"#
        ))
        .unwrap();
        let message = bad.validate().unwrap_err().to_string();
        assert!(message.contains("constraints[0].region: ball"), "{message}");
    }
}
