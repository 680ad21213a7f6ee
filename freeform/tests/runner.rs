//! The library layer end to end: geometry → integration points → basis → one runner → frames,
//! checked against backward Euler's exact free fall, and its errors.

use std::path::Path;

use freeform::{
    Constraint, FrameWriter, Geometry, GeometryError, Motion, Region, RunError, SceneSpec,
    SceneSpecError, Simulation, run,
};
use hyperelastic::{MaterialField, MaterialSample, StableNeoHookean};
use nalgebra::Vector3;
use reduced_sim::{DeformationMap, QuadratureRule, SimulationParams};
use rkpm_core::IntegrationPoints;
use skin_eigen::{BasisParams, SkinningBasis, build_basis};
use test_support::fixtures::scratch_dir;

const RUBBER: MaterialSample = MaterialSample {
    youngs_modulus: 1e5,
    poisson_ratio: 0.3,
    density: 1000.0,
};
const H: f64 = 0.01;
const G: f64 = 9.8;

fn small_basis(geometry: &Geometry) -> SkinningBasis {
    let points = geometry.integration_points(800).unwrap();
    let lame = vec![RUBBER.lame_parameters().unwrap(); points.len()];
    let params = BasisParams::default().with_modes(4).with_kernels(60);
    build_basis(&points, &lame, &params).unwrap().0
}

/// `RUBBER` everywhere, stable Neo-Hookean, h = `H`.
fn rubber<'a>(
    basis: &'a SkinningBasis,
    points: &'a IntegrationPoints,
    scene: &'a SceneSpec,
) -> Simulation<'a, SkinningBasis, StableNeoHookean> {
    static MATERIAL: std::sync::LazyLock<MaterialField> =
        std::sync::LazyLock::new(|| MaterialField::Uniform(RUBBER));
    Simulation::new(basis, points, &MATERIAL, StableNeoHookean, scene).with_params(
        SimulationParams {
            time_step: H,
            ..Default::default()
        },
    )
}

fn falling(scene: &SceneSpec) -> SceneSpec {
    SceneSpec {
        gravity: Some(Vector3::new(0.0, -G, 0.0)),
        ..scene.clone()
    }
}

/// Backward Euler from rest under gravity alone: v_n = n g h, x_n = x_0 − g h² n(n+1)/2. The
/// reduced space holds every translation and a translation has no elastic energy, so the
/// reduced solution is exactly this.
fn free_fall_drop(steps: usize) -> f64 {
    G * H * H * (steps * (steps + 1)) as f64 / 2.0
}

fn assert_falls_as_backward_euler(geometry: &Geometry, dir: &Path) {
    let basis = small_basis(geometry);
    let points = geometry.integration_points(300).unwrap();
    let scene = falling(&SceneSpec::default());
    let simulation = rubber(&basis, &points, &scene);
    let writer = FrameWriter::new(dir, geometry);
    let map = DeformationMap::new(&basis, writer.rest_positions()).unwrap();
    let steps = 5;
    let mut largest_error: f64 = 0.0;
    let report = run(&simulation, steps, |frame| {
        let x = map.positions(&frame.simulator.state().z);
        for (x, rest) in x.iter().zip(writer.rest_positions()) {
            let expected = rest - Vector3::y() * free_fall_drop(frame.index);
            largest_error = largest_error.max((x - expected).norm());
        }
        writer.write(frame.index, &x, frame.time)?;
        Ok(())
    })
    .unwrap();
    assert_eq!(report.steps, steps);
    assert_eq!(report.unconverged_steps, 0);
    assert_eq!(report.simulation_points, points.len());
    assert!(
        largest_error < 1e-8,
        "largest distance from exact backward-Euler free fall {largest_error:.3e} m"
    );
    for index in 0..=steps {
        let ply = std::fs::read_to_string(dir.join(format!("frame_{index:05}.ply"))).unwrap();
        let count = format!("element vertex {}\n", writer.rest_positions().len());
        assert!(ply.contains(&count), "frame {index}: {ply:.200}");
        assert!(dir.join(format!("frame_{index:05}.vtk")).is_file());
    }
}

#[test]
fn a_box_surface_falls_exactly_as_backward_euler_and_every_frame_is_written() {
    let geometry = Geometry::cuboid(Vector3::zeros(), Vector3::new(1.0, 0.25, 0.25));
    assert_falls_as_backward_euler(&geometry, &scratch_dir("freeform-box-fall"));
}

#[test]
fn a_point_cloud_file_gets_points_a_basis_and_a_run_that_falls_exactly() {
    let dir = scratch_dir("freeform-cloud-fall");
    // A plain PLY cloud (no faces): an 8 × 4 × 4 lattice filling a 1 × 0.5 × 0.5 m block.
    let mut ply = String::from(
        "ply\nformat ascii 1.0\nelement vertex 128\nproperty float x\nproperty float y\n\
         property float z\nend_header\n",
    );
    for i in 0..8 {
        for j in 0..4 {
            for k in 0..4 {
                let p = [i as f64 + 0.5, j as f64 + 0.5, k as f64 + 0.5].map(|c| c / 8.0);
                ply += &format!("{} {} {}\n", p[0], p[1], p[2]);
            }
        }
    }
    let file = dir.join("block.ply");
    std::fs::write(&file, ply).unwrap();
    let geometry = Geometry::read(&file).unwrap();
    assert!(matches!(geometry, Geometry::Cloud(_)));
    assert_eq!(geometry.integration_points(1000).unwrap().len(), 128);
    assert_falls_as_backward_euler(&geometry, &dir.join("frames"));
}

#[test]
fn a_region_that_holds_no_point_stops_the_run_before_any_frame_with_the_region_named() {
    let geometry = Geometry::cuboid(Vector3::zeros(), Vector3::new(1.0, 0.25, 0.25));
    let basis = small_basis(&geometry);
    let points = geometry.integration_points(300).unwrap();
    let scene = falling(&SceneSpec {
        constraints: vec![Constraint {
            region: Region::Below {
                axis: 0,
                value: -1.0,
            },
            motion: Motion::Rest,
        }],
        ..Default::default()
    });
    let simulation = rubber(&basis, &points, &scene);
    let mut frames = 0;
    let err = run(&simulation, 3, |_| {
        frames += 1;
        Ok(())
    })
    .unwrap_err();
    assert_eq!(frames, 0);
    assert!(
        matches!(
            err,
            RunError::Scene(SceneSpecError::EmptyRegion { index: 0, .. })
        ),
        "{err}"
    );
}

#[test]
fn an_observer_error_stops_the_run_and_keeps_its_source_and_frame() {
    let geometry = Geometry::cuboid(Vector3::zeros(), Vector3::new(1.0, 0.25, 0.25));
    let basis = small_basis(&geometry);
    let points = geometry.integration_points(300).unwrap();
    let scene = falling(&SceneSpec::default());
    let simulation = rubber(&basis, &points, &scene);
    let err = run(&simulation, 10, |frame| {
        if frame.index == 2 {
            Err("disk full".into())
        } else {
            Ok(())
        }
    })
    .unwrap_err();
    let RunError::Observer { frame, source } = &err else {
        panic!("{err}");
    };
    assert_eq!(*frame, 2);
    assert_eq!(source.to_string(), "disk full");
}

#[test]
fn an_empty_or_missing_geometry_file_is_a_named_error() {
    let dir = scratch_dir("freeform-bad-geometry");
    let empty = dir.join("empty.ply");
    std::fs::write(
        &empty,
        "ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\n\
         property float z\nend_header\n",
    )
    .unwrap();
    let err = Geometry::read(&empty).unwrap_err();
    assert!(
        matches!(
            err,
            GeometryError::Unreadable { .. } | GeometryError::Read(_)
        ),
        "{err}"
    );
    assert!(err.to_string().contains("empty.ply"), "{err}");
    let missing = Geometry::read(&dir.join("missing.obj")).unwrap_err();
    assert!(
        matches!(missing, GeometryError::Missing { .. }),
        "{missing}"
    );
}

/// A 2 × 0.4 × 0.4 m bar with x ≤ 0.2 fixed and x ≥ 1.8 turning about the bar's axis at
/// 720°/s: the beam Twist in small.
fn twisted_bar() -> (Geometry, SceneSpec) {
    let geometry = Geometry::cuboid(Vector3::zeros(), Vector3::new(2.0, 0.4, 0.4));
    let scene = SceneSpec {
        constraints: vec![
            Constraint {
                region: Region::Below {
                    axis: 0,
                    value: 0.2,
                },
                motion: Motion::Rest,
            },
            Constraint {
                region: Region::Above {
                    axis: 0,
                    value: 1.8,
                },
                motion: Motion::Rotate {
                    center: Vector3::new(1.9, 0.2, 0.2),
                    axis: Vector3::x(),
                    rate_degrees_per_second: 720.0,
                    max_angle_degrees: 720.0,
                },
            },
        ],
        ..SceneSpec::default()
    };
    (geometry, scene)
}

/// The twisted bar with its weighted basis (m = 6, K = 150 on 3000 points), 600 simulation
/// points and the Lamé parameters of the basis points.
struct WeightedBar {
    scene: SceneSpec,
    basis_points: IntegrationPoints,
    points: IntegrationPoints,
    lame: Vec<hyperelastic::LameParameters>,
    params: BasisParams,
    basis: SkinningBasis,
    max_mode_value_on_regions: f64,
}

fn weighted_bar() -> WeightedBar {
    let (geometry, scene) = twisted_bar();
    let basis_points = geometry.integration_points(3000).unwrap();
    let points = geometry.integration_points(600).unwrap();
    let lame = vec![RUBBER.lame_parameters().unwrap(); basis_points.len()];
    let params = BasisParams::default().with_modes(6).with_kernels(150);
    let (basis, report) = freeform::PinHold::WEIGHTED
        .build_basis(
            &scene,
            &basis_points,
            &lame,
            points.positions(),
            &[],
            params,
        )
        .unwrap();
    WeightedBar {
        scene,
        basis_points,
        points,
        lame,
        params,
        basis,
        max_mode_value_on_regions: report.held_regions.unwrap().max_mode_value_on_regions,
    }
}

#[test]
fn a_weighted_basis_holds_a_fixed_and_a_turning_end_exactly() {
    let bar = weighted_bar();
    assert_eq!(bar.max_mode_value_on_regions, 0.0);
    let simulation =
        rubber(&bar.basis, &bar.points, &bar.scene).with_pin_hold(freeform::PinHold::WEIGHTED);
    let run_report = run(&simulation, 10, |_| Ok(())).unwrap();
    assert!(run_report.region_points.iter().all(|&n| n > 0));
    assert!(
        run_report.max_held_deviation < 1e-12,
        "held points drift by {:e} m",
        run_report.max_held_deviation
    );
}

#[test]
fn on_a_bar_whose_ends_are_held_across_the_held_material_distance_is_the_regions_own() {
    let bar = weighted_bar();
    let shape = freeform::PinHold::Weighted {
        transition_fraction: 1.0,
        distance: freeform::WeightDistance::RegionShape,
        split_cut_cells: false,
    };
    let (basis, _) = shape
        .build_basis(
            &bar.scene,
            &bar.basis_points,
            &bar.lame,
            bar.points.positions(),
            &[],
            bar.params,
        )
        .unwrap();
    let measures_to_held_material =
        |basis: &SkinningBasis| basis.region_weight().unwrap().held_material().is_some();
    assert!(
        measures_to_held_material(&bar.basis),
        "the default measures to the held material"
    );
    assert!(!measures_to_held_material(&basis));
    let (a, b) = (
        bar.basis.evaluate(bar.points.positions()).unwrap(),
        basis.evaluate(bar.points.positions()).unwrap(),
    );
    assert_eq!(a.weights, b.weights);
    assert_eq!(a.gradients, b.gradients);
}

#[test]
fn a_weighted_hold_of_a_scene_without_constraints_builds_the_plain_basis() {
    let (geometry, _) = twisted_bar();
    let free = falling(&SceneSpec::default());
    let basis_points = geometry.integration_points(1500).unwrap();
    let points = geometry.integration_points(300).unwrap();
    let lame = vec![RUBBER.lame_parameters().unwrap(); basis_points.len()];
    let params = BasisParams::default().with_modes(4).with_kernels(80);
    let build = |hold: freeform::PinHold| {
        hold.build_basis(&free, &basis_points, &lame, points.positions(), &[], params)
            .unwrap()
            .0
    };
    let (weighted, plain) = (
        build(freeform::PinHold::WEIGHTED),
        build(freeform::PinHold::Penalty),
    );
    assert!(weighted.region_weight().is_none());
    let (a, b) = (
        weighted.evaluate(points.positions()).unwrap(),
        plain.evaluate(points.positions()).unwrap(),
    );
    assert_eq!(a.weights, b.weights);
    let simulation = rubber(&weighted, &points, &free).with_pin_hold(freeform::PinHold::WEIGHTED);
    let report = run(&simulation, 3, |_| Ok(())).unwrap();
    assert!(report.region_points.is_empty());
}

#[test]
fn a_projected_volumetric_term_runs_holds_its_regions_and_reports_inf_sup_constants() {
    let bar = weighted_bar();
    let hold = freeform::PinHold::WEIGHTED;
    let space = freeform::PressureSpace::build(
        &bar.scene,
        hold,
        &bar.basis_points,
        &bar.lame,
        bar.params,
        // RUBBER has ν = 0.3 (λ = 1.5 μ): keep nothing pointwise, so that something is projected.
        &freeform::PressureSpaceParams {
            mode_fraction: 3.0,
            affine: true,
            retained_shear_multiple: 0.0,
        },
        None,
    )
    .unwrap();
    // The constant, the three affine functions and ⌈3 · (6 + 1)⌉ = 21 Neumann modes.
    assert_eq!(space.functions(), 1 + 3 + 21);
    let values = space.values(bar.points.positions()).unwrap();
    for (i, x) in bar.points.positions().iter().enumerate() {
        let held = x.x <= 0.2 || x.x >= 1.8;
        assert_eq!(values[(i, 0)], if held { 0.0 } else { 1.0 });
    }
    let simulation = rubber(&bar.basis, &bar.points, &bar.scene)
        .with_pin_hold(hold)
        .with_pressure(Some(&space));
    let report = run(&simulation, 5, |_| Ok(())).unwrap();
    assert!(report.max_held_deviation < 1e-12);
    let betas = freeform::pressure_inf_sup(&simulation, &[0, 2, 4])
        .unwrap()
        .unwrap();
    assert_eq!(betas.len(), 3);
    assert!(betas.iter().all(|b| b.is_finite() && *b > 0.0), "{betas:?}");
    assert_eq!(space.truncated(2).functions(), 1 + 3 + 2);
}

#[test]
fn an_automatic_quadrature_decides_after_the_warm_up_and_reports_what_it_chose() {
    let geometry = Geometry::cuboid(Vector3::zeros(), Vector3::new(1.0, 0.25, 0.25));
    let basis = small_basis(&geometry);
    let points = geometry.integration_points(600).unwrap();
    let scene = falling(&SceneSpec::default());
    let cubature = reduced_sim::CubatureParams {
        tolerance: 0.02,
        ..Default::default()
    };
    let cache = scratch_dir("freeform-automatic-quadrature");
    let simulation = rubber(&basis, &points, &scene)
        .with_quadrature(QuadratureRule::Automatic(cubature))
        .with_cache_dir(Some(&cache));
    let steps = 40;
    let mut largest_error: f64 = 0.0;
    let map = DeformationMap::new(&basis, points.positions()).unwrap();
    let mut check = |index: usize, z: &[f64]| {
        for (x, rest) in map.positions(z).iter().zip(points.positions()) {
            let expected = rest - Vector3::y() * free_fall_drop(index);
            largest_error = largest_error.max((x - expected).norm());
        }
    };
    let report = run(&simulation, steps, |frame| {
        check(frame.index, &frame.simulator.state().z);
        Ok(())
    })
    .unwrap();
    // Whichever quadrature it chose, a translation has no elastic energy.
    assert!(largest_error < 1e-8, "{largest_error:e} m from free fall");
    let quadrature = &report.quadrature;
    let choice = quadrature
        .choice
        .expect("an automatic rule reports its choice");
    // The first 3 steps (a twentieth, at least 3) ran on every point.
    assert_eq!(choice.planned_steps, steps - 3);
    assert_eq!(quadrature.kind == "cubature", choice.chose_cubature);
    assert_eq!(quadrature.cubature.is_some(), choice.chose_cubature);
    assert_eq!(quadrature.points < points.len(), choice.chose_cubature);
    assert!(report.setup_seconds >= choice.spent_seconds);

    // With the cubature in the cache, the run uses it from the first step.
    let model = reduced_sim::ReducedModel::new(
        &basis,
        &points,
        &vec![RUBBER; points.len()],
        StableNeoHookean,
    )
    .unwrap();
    let (cached, _) =
        reduced_sim::quadrature::cubature::optimize_cubature_cached(&model, &cubature, &cache)
            .unwrap();
    let report = run(&simulation, steps, |_| Ok(())).unwrap();
    let choice = report.quadrature.choice.unwrap();
    assert!(choice.chose_cubature && choice.planned_steps == steps);
    assert_eq!(report.quadrature.points, cached.len());
    assert!(report.quadrature.cubature.unwrap().cached);
}

#[test]
fn a_prepared_simulator_steps_exactly_as_the_runner() {
    let geometry = Geometry::cuboid(Vector3::zeros(), Vector3::new(1.0, 0.25, 0.25));
    let basis = small_basis(&geometry);
    let points = geometry.integration_points(300).unwrap();
    let scene = SceneSpec {
        constraints: vec![Constraint {
            region: Region::Below {
                axis: 0,
                value: 0.1,
            },
            motion: Motion::Rest,
        }],
        ..falling(&SceneSpec::default())
    };
    let simulation = rubber(&basis, &points, &scene).with_quadrature(QuadratureRule::Full);
    let mut last = Vec::new();
    run(&simulation, 5, |frame| {
        last = frame.simulator.state().z.clone();
        Ok(())
    })
    .unwrap();
    let (mut sim, quadrature) = freeform::prepare_simulator(&simulation, 5, &[]).unwrap();
    assert_eq!(quadrature.kind, "full");
    for _ in 0..5 {
        assert!(sim.step().unwrap().converged());
    }
    assert_eq!(sim.state().z, last);
    assert!(last.iter().any(|&z| z != 0.0), "the bar must move");
}
