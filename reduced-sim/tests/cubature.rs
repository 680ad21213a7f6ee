//! The elastic quadrature: every point reproduces the model exactly, an optimized cubature
//! integrates its training poses' reduced forces to its stated error and unseen poses to a
//! looser one with non-negative weights, and a simulation on it follows the full one.

mod support;

use hyperelastic::Tangent;
use reduced_sim::quadrature::cubature::{
    cubature_cache_path, force_error, force_weights, optimize_cubature_cached, training_poses,
};
use reduced_sim::{
    CubatureError, CubatureParams, ElasticQuadrature, QuadratureError, QuadratureRule,
    SimulationParams, Simulator, optimize_cubature,
};
use support::bar_model;

fn cubature_params() -> CubatureParams {
    CubatureParams {
        tolerance: 0.01,
        ..CubatureParams::DEFAULT
    }
}

#[test]
fn the_full_quadrature_reproduces_the_models_energy_gradient_and_hessian_bit_for_bit() {
    let model = bar_model();
    let poses = training_poses(&model, &cubature_params()).unwrap();
    let z = &poses[poses.len() - 1];
    let (e, g, h) = (
        model.elastic_energy(z),
        model.elastic_gradient(z),
        model.elastic_hessian(z, Tangent::ProjectedPsd),
    );
    let full = ElasticQuadrature::full(model.volumes()).unwrap();
    let model = model.with_elastic_quadrature(full).unwrap();
    assert_eq!(model.elastic_energy(z), e);
    assert_eq!(model.elastic_gradient(z), g);
    assert!(model.elastic_hessian(z, Tangent::ProjectedPsd) == h);
}

#[test]
fn a_cubature_integrates_its_training_forces_to_its_tolerance_and_unseen_poses_within_five_times_it()
 {
    let model = bar_model();
    let params = cubature_params();
    let (quadrature, report) = optimize_cubature(&model, &params).unwrap();
    assert!(report.reached_tolerance, "{report:?}");
    assert!(report.training_error <= params.tolerance, "{report:?}");
    assert!(quadrature.weights().iter().all(|&w| w >= 0.0));
    assert_eq!(report.points, quadrature.len());
    assert!(
        quadrature.len() < model.volumes().len() / 5,
        "{} of {} points",
        quadrature.len(),
        model.volumes().len()
    );
    // The stated training error, recomputed independently from the quadrature alone.
    let weights = force_weights(&model, params.time_step);
    let poses = training_poses(&model, &params).unwrap();
    let recomputed = force_error(&model, &quadrature, &poses, &weights);
    assert!(
        (recomputed - report.training_error).abs() <= 1e-6 + 1e-3 * report.training_error,
        "recomputed {recomputed:e}, reported {:e}",
        report.training_error
    );
    // Unseen poses: another seed. The stated bound is five times the tolerance (on the beam,
    // unseen poses came out 2.5-3.2× the training error at m = 6-32; 3.1× here).
    let unseen = training_poses(
        &model,
        &CubatureParams {
            seed: 12345,
            ..params
        },
    )
    .unwrap();
    let error = force_error(&model, &quadrature, &unseen, &weights);
    assert!(
        error <= 5.0 * params.tolerance,
        "unseen-pose force error {error:e}"
    );
    // The plain norm is bounded too (all weights one).
    let plain = force_error(&model, &quadrature, &unseen, &vec![1.0; weights.len()]);
    assert!(plain <= 0.1, "plain-norm unseen force error {plain:e}");
}

#[test]
fn a_bar_bending_on_a_cubature_follows_the_full_quadrature_to_within_twice_its_force_tolerance() {
    let run = |rule: QuadratureRule| {
        let (model, report) = rule.apply(bar_model()).unwrap();
        let scene = support::cantilever_scene(&model, 0.3);
        let mut sim = Simulator::new(model, &scene, SimulationParams::default()).unwrap();
        let tip: Vec<usize> = sim.model().points_where(|x| x.x >= 2.9);
        let mut deflection = Vec::new();
        for _ in 0..30 {
            assert!(sim.step().unwrap().converged());
            let x = sim.model().deformation_map().positions(&sim.state().z);
            let rest = sim.model().rest_positions();
            deflection
                .push(tip.iter().map(|&i| x[i].y - rest[i].y).sum::<f64>() / tip.len() as f64);
        }
        (deflection, report)
    };
    let (full, full_report) = run(QuadratureRule::Full);
    let (cubature, report) = run(QuadratureRule::Cubature(cubature_params()));
    assert_eq!(full_report.points, 3000);
    assert!(report.points < 600, "{report:?}");
    let scale = full.iter().fold(0.0_f64, |m, d| m.max(d.abs()));
    assert!(scale > 0.01, "the bar must bend: {scale} m");
    // Near-linear response: a relative force error ε moves the solution by about ε relative;
    // allow twice the cubature's tolerance (1%) of the largest deflection.
    let bound = 2.0 * cubature_params().tolerance * scale;
    for (step, (a, b)) in full.iter().zip(&cubature).enumerate() {
        assert!(
            (a - b).abs() <= bound,
            "step {step}: tip deflection {b} m on the cubature, {a} m on every point"
        );
    }
}

#[test]
fn invalid_quadratures_and_options_are_refused_with_the_problem_named() {
    assert_eq!(
        ElasticQuadrature::new(vec![0, 1], vec![1.0]),
        Err(QuadratureError::Count {
            points: 2,
            weights: 1
        })
    );
    assert_eq!(
        ElasticQuadrature::new(vec![], vec![]),
        Err(QuadratureError::Empty)
    );
    assert_eq!(
        ElasticQuadrature::new(vec![3, 1], vec![1.0, -2.0]),
        Err(QuadratureError::Weight {
            index: 1,
            weight: -2.0
        })
    );
    assert_eq!(
        ElasticQuadrature::new(vec![3, 3], vec![1.0, 2.0]),
        Err(QuadratureError::Duplicate { point: 3 })
    );
    assert_eq!(
        ElasticQuadrature::random_subset(&[1.0; 4], 5, 0),
        Err(QuadratureError::SubsetTooLarge {
            requested: 5,
            available: 4
        })
    );
    let model = bar_model();
    let n = model.volumes().len();
    assert!(matches!(
        bar_model().with_elastic_quadrature(ElasticQuadrature::new(vec![n], vec![1.0]).unwrap()),
        Err(QuadratureError::OutOfRange { point, points }) if point == n && points == n
    ));
    let bad = CubatureParams {
        tolerance: 0.0,
        ..CubatureParams::DEFAULT
    };
    assert!(matches!(
        optimize_cubature(&model, &bad),
        Err(CubatureError::Params(_))
    ));
    // A range the poses are drawn from that is not finite is refused before any draw.
    let bad = CubatureParams {
        max_twist: f64::NAN,
        ..CubatureParams::DEFAULT
    };
    assert!(matches!(
        training_poses(&model, &bad),
        Err(CubatureError::Params(message)) if message.contains("max_twist")
    ));
    let subset = ElasticQuadrature::random_subset(model.volumes(), 100, 1).unwrap();
    let total: f64 = model.volumes().iter().sum();
    assert!((subset.total_weight() - total).abs() < 1e-12 * total);
    let on_subset = model.with_elastic_quadrature(subset).unwrap();
    assert!(matches!(
        optimize_cubature(&on_subset, &CubatureParams::DEFAULT),
        Err(CubatureError::NotFull)
    ));
}

#[test]
fn a_cached_cubature_is_reloaded_identical_and_a_corrupt_cache_file_is_replaced() {
    let dir = std::path::PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("cubature-cache");
    let _ = std::fs::remove_dir_all(&dir);
    let model = bar_model();
    let params = CubatureParams {
        tolerance: 0.02,
        ..CubatureParams::DEFAULT
    };
    let (first, report) = optimize_cubature_cached(&model, &params, &dir).unwrap();
    assert!(
        !report.cached && report.cache_warning.is_none(),
        "{report:?}"
    );
    let (again, report) = optimize_cubature_cached(&model, &params, &dir).unwrap();
    assert!(report.cached);
    assert_eq!(again, first);
    // Other options are another entry.
    let other = CubatureParams {
        tolerance: 0.05,
        ..params
    };
    assert_ne!(
        cubature_cache_path(&model, &other, &dir),
        cubature_cache_path(&model, &params, &dir)
    );
    // A corrupt file is optimized again and overwritten.
    std::fs::write(
        cubature_cache_path(&model, &params, &dir),
        b"not a cubature",
    )
    .unwrap();
    let (rebuilt, report) = optimize_cubature_cached(&model, &params, &dir).unwrap();
    assert!(!report.cached);
    assert_eq!(rebuilt, first);
    assert!(
        optimize_cubature_cached(&model, &params, &dir)
            .unwrap()
            .1
            .cached
    );
}
