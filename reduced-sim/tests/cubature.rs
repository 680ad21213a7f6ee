//! The elastic quadrature: every point reproduces the model exactly, an optimized cubature
//! integrates its training poses' reduced forces to its stated error and unseen poses to a
//! looser one with non-negative weights, and a simulation on it follows the full one.

mod support;

use hyperelastic::{StableNeoHookean, Tangent};
use reduced_sim::quadrature::cubature::{
    cubature_cache_path, force_error, force_weights, optimize_cubature_cached, training_poses,
};
use reduced_sim::{
    CubatureError, CubatureParams, CubatureStop, ElasticQuadrature, QuadratureError,
    QuadratureRule, ReducedModel, SimulationParams, Simulator, optimize_cubature,
};
use support::bar_model;

/// Poses the cubature was not trained on: its generator with another seed.
fn unseen_poses<M: hyperelastic::HyperelasticMaterial>(
    model: &ReducedModel<M>,
    params: &CubatureParams,
) -> Vec<Vec<f64>> {
    training_poses(
        model,
        &CubatureParams {
            seed: 12345,
            ..*params
        },
    )
    .unwrap()
}

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
    let recomputed = force_error(&model, &quadrature, &poses, &weights).unwrap();
    assert!(
        (recomputed - report.training_error).abs() <= 1e-6 + 1e-3 * report.training_error,
        "recomputed {recomputed:e}, reported {:e}",
        report.training_error
    );
    // Unseen poses: another seed. The stated bound is five times the tolerance (on the beam,
    // unseen poses came out 2.5-3.2× the training error at m = 6-32; 3.1× here).
    let unseen = unseen_poses(&model, &params);
    let error = force_error(&model, &quadrature, &unseen, &weights).unwrap();
    assert!(
        error <= 5.0 * params.tolerance,
        "unseen-pose force error {error:e}"
    );
    // The plain norm is bounded too (all weights one).
    let plain = force_error(&model, &quadrature, &unseen, &vec![1.0; weights.len()]).unwrap();
    assert!(plain <= 0.1, "plain-norm unseen force error {plain:e}");
}

/// The bar's mean tip deflection (m) over 30 steps of the cantilever under gravity on the model
/// `make_model` builds, integrated by `rule`, and the quadrature's report.
fn tip_deflections(
    make_model: fn() -> ReducedModel<StableNeoHookean>,
    rule: QuadratureRule,
) -> (Vec<f64>, reduced_sim::QuadratureReport) {
    let (model, report) = rule.apply(make_model()).unwrap();
    let scene = support::cantilever_scene(&model, 0.3);
    let mut sim = Simulator::new(model, &scene, SimulationParams::default()).unwrap();
    let tip: Vec<usize> = sim.model().points_where(|x| x.x >= 2.9);
    let mut deflection = Vec::new();
    for _ in 0..30 {
        assert!(sim.step().unwrap().converged());
        let x = sim.model().deformation_map().positions(&sim.state().z);
        let rest = sim.model().rest_positions();
        deflection.push(tip.iter().map(|&i| x[i].y - rest[i].y).sum::<f64>() / tip.len() as f64);
    }
    (deflection, report)
}

/// The cubature's run of `make_model`'s bar stays within twice its force tolerance (of the
/// largest deflection) of the run on every point, on fewer than a fifth of the points.
fn assert_the_cubature_follows_the_full_quadrature(
    make_model: fn() -> ReducedModel<StableNeoHookean>,
) {
    let (full, full_report) = tip_deflections(make_model, QuadratureRule::Full);
    let (cubature, report) =
        tip_deflections(make_model, QuadratureRule::Cubature(cubature_params()));
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
fn a_bar_bending_on_a_cubature_follows_the_full_quadrature_to_within_twice_its_force_tolerance() {
    assert_the_cubature_follows_the_full_quadrature(bar_model);
}

#[test]
fn a_bar_with_a_projected_dilatation_on_a_cubature_follows_the_full_quadrature_likewise() {
    assert_the_cubature_follows_the_full_quadrature(bar_model_with_pressure);
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
    for batch_spacing in [-1.0, f64::NAN] {
        let bad = CubatureParams {
            batch_spacing,
            ..CubatureParams::DEFAULT
        };
        assert!(matches!(
            optimize_cubature(&model, &bad),
            Err(CubatureError::Params(message)) if message.contains("batch_spacing")
        ));
    }
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

/// The bar with its volumetric term projected onto 1, x, y, z and a smooth function of x.
fn bar_model_with_pressure() -> ReducedModel<StableNeoHookean> {
    let model = bar_model();
    let positions = model.rest_positions().to_vec();
    let pressure = nalgebra::DMatrix::from_fn(positions.len(), 5, |i, b| match b {
        0 => 1.0,
        1..=3 => positions[i][b - 1],
        _ => (std::f64::consts::PI * positions[i].x / 3.0).cos(),
    });
    model
        .with_projected_dilatation(pressure, reduced_sim::ProjectedDilatationParams::default())
        .unwrap()
}

#[test]
fn a_cubature_of_a_projected_dilatation_reaches_its_tolerance_and_its_model_follows_unseen_forces()
{
    let model = bar_model_with_pressure();
    let params = CubatureParams::DEFAULT;
    let (quadrature, report) = optimize_cubature(&model, &params).unwrap();
    assert!(report.reached_tolerance, "{report:?}");
    // Its own validation poses, some of which compress points past the inversion barrier's
    // start, are scored without the barrier, as its training is.
    assert!(
        report.validation_error <= 10.0 * params.tolerance,
        "{report:?}"
    );
    // Unseen poses, on the model integrated by the cubature (its pressure projection formed
    // on the cubature's points), against the full model: force_error says the same.
    let unseen = unseen_poses(&model, &params);
    let weights = force_weights(&model, params.time_step);
    let error = force_error(&model, &quadrature, &unseen, &weights).unwrap();
    assert!(
        error <= 10.0 * params.tolerance,
        "unseen-pose force error {error:e}"
    );
    // The recomputation uses the simulated forces, which hold the inversion barrier that the
    // error leaves out: on the poses where it acts at no point (full and integrated) the two
    // are the same.
    let integrated = bar_model_with_pressure()
        .with_elastic_quadrature(quadrature.clone())
        .unwrap();
    let untouched: Vec<Vec<f64>> = unseen
        .iter()
        .zip(model.elastic_gradients(&unseen))
        .filter(|(z, unbarred)| {
            let barred = model.elastic_gradient(z);
            let scale = unbarred.iter().fold(0.0f64, |m, g| m.max(g.abs()));
            let same = barred
                .iter()
                .zip(unbarred)
                .all(|(a, b)| (a - b).abs() <= 1e-9 * scale);
            same && integrated.elastic_energy(z).is_finite()
                && integrated.elastic_gradient(z).iter().all(|g| g.is_finite())
        })
        .map(|(z, _)| z.clone())
        .collect();
    assert!(
        untouched.len() * 2 > unseen.len(),
        "{} of {}",
        untouched.len(),
        unseen.len()
    );
    let error = force_error(&model, &quadrature, &untouched, &weights).unwrap();
    let unseen = untouched;
    let full: Vec<Vec<f64>> = unseen.iter().map(|z| model.elastic_gradient(z)).collect();
    let mut sum = 0.0;
    for (z, f) in unseen.iter().zip(&full) {
        let g = integrated.elastic_gradient(z);
        let norm = |v: &dyn Fn(usize) -> f64| (0..f.len()).map(|k| v(k).powi(2)).sum::<f64>();
        sum += norm(&|k| (g[k] - f[k]) * weights[k]) / norm(&|k| f[k] * weights[k]);
    }
    let recomputed = (sum / unseen.len() as f64).sqrt();
    assert!(
        (recomputed - error).abs() <= 1e-9 * error,
        "{recomputed:e} vs {error:e}"
    );
}

#[test]
fn a_model_with_a_projected_dilatation_does_not_share_a_cached_cubature_with_one_without() {
    let dir = std::env::temp_dir();
    let params = CubatureParams::DEFAULT;
    assert_ne!(
        cubature_cache_path(&bar_model(), &params, &dir),
        cubature_cache_path(&bar_model_with_pressure(), &params, &dir)
    );
}

#[test]
fn the_report_names_what_stopped_the_selection() {
    let model = bar_model();
    let run = |params: CubatureParams| optimize_cubature(&model, &params).unwrap().1;
    let reached = run(cubature_params());
    assert_eq!(reached.stop, CubatureStop::Tolerance, "{reached:?}");
    let budget = run(CubatureParams {
        max_points: 8,
        ..cubature_params()
    });
    assert!(!budget.reached_tolerance);
    assert_eq!(budget.stop, CubatureStop::PointBudget, "{budget:?}");
    assert_eq!(budget.points, 8);
    let pool = run(CubatureParams {
        candidates: 40,
        tolerance: 1e-6,
        ..cubature_params()
    });
    assert!(!pool.reached_tolerance);
    assert_eq!(pool.stop, CubatureStop::Candidates, "{pool:?}");
    assert!(pool.points <= 40);
}
