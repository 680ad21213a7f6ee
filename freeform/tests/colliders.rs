//! Kinematic colliders: a box pushed by a moving box collider takes on the pusher's
//! speed, and a fast pusher does not pass through it.

mod support;

use freeform::SceneSpec;
use nalgebra::{UnitQuaternion, Vector3};
use reduced_sim::{Collider, ColliderShape, Keyframe, SimulationParams};
use support::{H, mean_x, run_cube};

const SIDE: f64 = 0.2;
/// Half the pusher's thickness (m).
const PUSHER: f64 = 0.05;

/// A pusher plate moving along +x at `speed` (m/s), its front face at x = −0.01 m at t = 0.
fn pusher(speed: f64, duration: f64) -> Collider {
    let key = |time: f64| Keyframe {
        time,
        rotation: UnitQuaternion::identity(),
        translation: Vector3::new(-0.01 - PUSHER + speed * time, 0.5 * SIDE, 0.5 * SIDE),
    };
    Collider {
        shape: ColliderShape::Box {
            half_extents: Vector3::new(PUSHER, 0.75 * SIDE, 0.75 * SIDE),
        },
        path: vec![key(0.0), key(duration)],
        friction: 0.0,
        parent: None,
    }
}

/// Per frame: the cube's mean x and its smallest x (m); the integration point spacing (m); the
/// run's deepest penetration (m).
fn push(speed: f64, steps: usize) -> (Vec<(f64, f64)>, f64, f64) {
    let scene = SceneSpec {
        colliders: vec![pusher(speed, steps as f64 * H)],
        ..Default::default()
    };
    let mut frames = Vec::new();
    let mut spacing = 0.0;
    let report = run_cube(SIDE, &scene, steps, |positions, volumes| {
        let back = positions.iter().map(|x| x.x).fold(f64::INFINITY, f64::min);
        frames.push((mean_x(positions, volumes), back));
        spacing = (volumes.iter().sum::<f64>() / volumes.len() as f64).cbrt();
    });
    (frames, spacing, report.max_penetration)
}

#[test]
fn a_pushed_box_moves_at_the_pushers_speed_after_contact() {
    let speed = 0.2;
    let (frames, spacing, penetration) = push(speed, 80);
    // Penalty contact: the bound, 2% of the contact spacing.
    assert!(penetration < 0.02 * spacing, "penetration {penetration} m");
    // Contact starts at 0.05 s; by 0.4 s the contact spring has brought the box up to speed.
    let velocity = (frames[80].0 - frames[40].0) / (40.0 * H);
    assert!(
        (velocity - speed).abs() <= 0.05 * speed,
        "box at {velocity} m/s behind a pusher at {speed} m/s"
    );
}

#[test]
fn a_pusher_moving_half_a_point_spacing_per_step_does_not_pass_through_the_box() {
    let (_, spacing, _) = push(0.0, 1);
    let speed = 0.5 * spacing / H;
    let steps = 40;
    let (frames, _, penetration) = push(speed, steps);
    assert!(penetration < 0.02 * spacing, "penetration {penetration} m");
    for (n, &(_, back)) in frames.iter().enumerate() {
        let face = -0.01 + speed * n as f64 * H;
        // The pusher's front face never gets past the box's trailing points by more than a
        // point spacing: it pushes the box, it does not tunnel through it.
        assert!(
            face - back < spacing,
            "step {n}: pusher face at {face} m, box's back at {back} m (spacing {spacing} m)"
        );
    }
    // And the box went ahead of it.
    assert!(frames[steps].0 > 0.5 * SIDE + 0.5 * speed * steps as f64 * H);
}

#[test]
fn a_scene_file_with_a_moving_collider_and_floor_friction_runs_and_refuses_bad_colliders() {
    let dir = test_support::fixtures::scratch_dir("colliders-scene");
    let scene = |radius: f64| {
        format!(
            "[geometry]\nbox = {{ min = [0, 0, 0], max = [0.4, 0.2, 0.2] }}\n[material]\n\
             youngs_modulus = 1e5\npoisson_ratio = 0.3\ndensity = 1000\n[basis]\nmodes = 4\n\
             kernels = 60\npoints = 800\n[simulation]\ntime_step = 0.01\nsteps = 5\npoints = 600\n\
             [scene]\ngravity = [0, -9.8, 0]\n\
             floor = {{ normal = [0, 1, 0], offset = 0, friction = 0.5 }}\n\
             [[scene.colliders]]\nshape = {{ sphere = {{ radius = {radius} }} }}\nfriction = 0.3\n\
             path = [{{ time = 0, translation = [-0.1, 0.1, 0.1] }}, \
             {{ time = 1, translation = [0.9, 0.1, 0.1], rotation = [0, 0, 0, 1] }}]\n"
        )
    };
    let path = dir.join("push.toml");
    std::fs::write(&path, scene(0.08)).unwrap();
    let file = freeform::SceneFile::load(&path).unwrap();
    assert_eq!(file.scene.colliders.len(), 1);
    let report =
        freeform::simulate_scene_file(&file, &dir.join("out"), None, &freeform::Silent).unwrap();
    assert_eq!(report.frames_written, 6);
    // The sphere is written beside every frame, where its path has it (x = -0.1 + t m).
    let last = std::fs::read_to_string(dir.join("out").join("colliders_00005.ply")).unwrap();
    let xs: Vec<f64> = last
        .lines()
        .skip_while(|l| *l != "end_header")
        .skip(1)
        .filter_map(|l| {
            let v: Vec<f64> = l.split(' ').filter_map(|w| w.parse().ok()).collect();
            (v.len() == 3).then(|| v[0])
        })
        .collect();
    let centre = xs.iter().sum::<f64>() / xs.len() as f64;
    assert!(
        (centre - (-0.1 + 0.05)).abs() < 1e-9,
        "sphere centre x {centre}"
    );
    std::fs::write(&path, scene(-0.08)).unwrap();
    let error = freeform::SceneFile::load(&path).unwrap_err().to_string();
    assert!(
        error.contains("colliders[0]") && error.contains("radius"),
        "{error}"
    );
}

/// A cube dropped 2 cm onto a slab: the slab as a closed triangle mesh (signed distance from its
/// closest point and inside test) moves the cube exactly as the analytic box does.
#[test]
fn a_mesh_box_collider_moves_the_cube_as_the_analytic_box_does() {
    let half = Vector3::new(0.3, 0.05, 0.3);
    let centre = Vector3::new(0.5 * SIDE, -0.02 - half.y, 0.5 * SIDE);
    let slab = |shape: ColliderShape| SceneSpec {
        gravity: Some(Vector3::new(0.0, -9.8, 0.0)),
        colliders: vec![Collider::fixed(shape, UnitQuaternion::identity(), centre)],
        ..Default::default()
    };
    let mesh = rkpm_core::TriangleMesh::cuboid(-half, half);
    let trajectory = |scene: &SceneSpec| {
        let mut heights = Vec::new();
        run_cube(SIDE, scene, 30, |positions, _| {
            heights.push(positions.iter().map(|x| x.y).fold(f64::INFINITY, f64::min));
        });
        heights
    };
    let analytic = trajectory(&slab(ColliderShape::Box { half_extents: half }));
    let from_mesh = trajectory(&slab(ColliderShape::Mesh(
        reduced_sim::MeshShape::from_mesh(mesh, 0.02),
    )));
    // It lands: the lowest point falls from 0 to the slab's top (−0.02 m) and stays there.
    let last = *analytic.last().unwrap();
    assert!((last + 0.02).abs() < 2e-3, "lowest point at {last} m");
    // The two distances agree to round-off, so the runs differ only where round-off tips a
    // Newton decision (a chord step with the carried Hessian accepted in one run and not in the
    // other). Each run stops once a step moves the mass by less than Newton's tolerance
    // (1e-6 L RMS); chord steps contracting by 0.7 leave at most 0.7 / 0.3 of that step, and the
    // lowest point may move more than the RMS, so the heights agree to ten times it (2 µm): a
    // wrong distance or normal would move them by millimetres.
    let tolerance = 10.0 * SimulationParams::default().newton.tolerance * SIDE;
    for (k, (a, m)) in analytic.iter().zip(&from_mesh).enumerate() {
        assert!(
            (a - m).abs() < tolerance,
            "frame {k}: analytic {a} m, mesh {m} m"
        );
    }
}

/// A plane collider (`shape = "plane"` in scene files) turned to face the cube from below is
/// the floor: the same fall and rest, to round-off.
#[test]
fn a_plane_collider_under_the_cube_acts_as_the_floor() {
    let gravity = Some(Vector3::new(0.0, -9.8, 0.0));
    let floor = SceneSpec {
        gravity,
        floor: Some(freeform::FloorSpec {
            normal: Vector3::y(),
            offset: -0.02,
            friction: 0.0,
        }),
        ..Default::default()
    };
    let shape: ColliderShape = toml::from_str::<toml::Value>("shape = \"plane\"")
        .unwrap()
        .get("shape")
        .unwrap()
        .clone()
        .try_into()
        .unwrap();
    assert_eq!(shape, ColliderShape::Plane);
    let plane = SceneSpec {
        gravity,
        colliders: vec![Collider::fixed(
            shape,
            UnitQuaternion::identity(),
            Vector3::new(0.0, -0.02, 0.0),
        )],
        ..Default::default()
    };
    let trajectory = |scene: &SceneSpec| {
        let mut heights = Vec::new();
        run_cube(SIDE, scene, 30, |positions, _| {
            heights.push(positions.iter().map(|x| x.y).fold(f64::INFINITY, f64::min));
        });
        heights
    };
    let (on_floor, on_plane) = (trajectory(&floor), trajectory(&plane));
    assert!((on_floor.last().unwrap() + 0.02).abs() < 2e-3);
    for (k, (a, b)) in on_floor.iter().zip(&on_plane).enumerate() {
        assert!((a - b).abs() < 1e-9, "frame {k}: floor {a} m, plane {b} m");
    }
}
