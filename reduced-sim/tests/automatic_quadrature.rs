//! The automatic quadrature: a cubature only when its training fits the budget of what it can
//! save, a cached one used as it is, a note that spares a second futile attempt, the budget
//! itself, and a simulator that switches quadrature between steps as if built with it.

mod support;

use reduced_sim::quadrature::automatic_quadrature::{SAVING_SHARE, cubature_if_it_pays};
use reduced_sim::quadrature::cubature::{
    CubatureCacheFile, cubature_cache_path, optimize_cubature_cached, optimize_cubature_within,
};
use reduced_sim::{
    CubatureBudget, CubatureError, CubatureParams, ElasticCost, PlannedRun, QuadratureRule,
    SimulationParams, Simulator, optimize_cubature,
};
use support::bar_model;

fn params() -> CubatureParams {
    CubatureParams {
        tolerance: 0.02,
        ..CubatureParams::DEFAULT
    }
}

fn fresh_dir(name: &str) -> std::path::PathBuf {
    let dir = std::path::PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(name);
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

#[test]
fn the_budget_is_what_a_cubature_of_its_size_can_still_save() {
    let budget = CubatureBudget {
        full_run_seconds: 10.0,
        full_points: 1000,
    };
    assert_eq!(budget.seconds(0), 10.0);
    assert!((budget.seconds(250) - 7.5).abs() < 1e-12);
    assert_eq!(budget.seconds(1000), 0.0);
    assert_eq!(budget.seconds(5000), 0.0);
}

#[test]
fn a_cubature_with_no_time_stops_over_budget_and_with_ample_time_is_the_unbudgeted_one() {
    let model = bar_model();
    let none = CubatureBudget {
        full_run_seconds: 0.0,
        full_points: 3000,
    };
    match optimize_cubature_within(&model, &params(), &none) {
        Err(CubatureError::OverBudget { seconds, budget }) => {
            assert!(seconds > 0.0 && budget == 0.0, "{seconds} {budget}")
        }
        other => panic!("expected OverBudget, got {other:?}"),
    }
    let ample = CubatureBudget {
        full_run_seconds: 1e9,
        full_points: 3000,
    };
    let (within, _) = optimize_cubature_within(&model, &params(), &ample).unwrap();
    let (unbudgeted, _) = optimize_cubature(&model, &params()).unwrap();
    assert_eq!(within, unbudgeted);
}

#[test]
fn a_run_too_short_to_pay_keeps_every_point_and_notes_it_so_a_like_run_does_not_try_again() {
    let dir = fresh_dir("automatic-short-run");
    let model = bar_model();
    let cache = CubatureCacheFile::new(&model, &params(), &dir);
    let short = cubature_if_it_pays(&model, &params(), Some(&cache), 10, 0.0).unwrap();
    assert!(short.cubature.is_none());
    assert!(!short.choice.chose_cubature && !short.choice.noted_over_budget);
    assert_eq!(short.choice.planned_steps, 10);
    assert_eq!(cache.path(), cubature_cache_path(&model, &params(), &dir));
    assert!(cache.path().with_extension("over-budget").is_file());
    // The note spares a run predicted at most twice as long ...
    let noted = cubature_if_it_pays(&model, &params(), Some(&cache), 10, 0.0).unwrap();
    assert!(noted.cubature.is_none() && noted.choice.noted_over_budget);
    // ... but not a long one, which trains, keeps and caches the cubature.
    let long = cubature_if_it_pays(&model, &params(), Some(&cache), 1000, 1e9).unwrap();
    let (quadrature, report) = long.cubature.expect("a long run pays for a cubature");
    assert!(long.choice.chose_cubature && !report.cached);
    assert!(
        (long.choice.budget_seconds
            - SAVING_SHARE * 1e9 * (1.0 - quadrature.len() as f64 / 3000.0))
            .abs()
            < 1e-3
    );
    let (cached, report) = optimize_cubature_cached(&model, &params(), &dir).unwrap();
    assert!(report.cached);
    assert_eq!(cached, quadrature);
}

#[test]
fn the_automatic_rule_uses_a_cached_cubature_and_without_a_planned_run_is_the_cubature() {
    let dir = fresh_dir("automatic-rule");
    let rule = QuadratureRule::Automatic(params());
    let (_, report) = rule.apply(bar_model()).unwrap();
    let (_, plain) = QuadratureRule::Cubature(params())
        .apply(bar_model())
        .unwrap();
    assert_eq!(report.kind, "cubature");
    assert_eq!(report.points, plain.points);
    assert!(report.choice.is_none());

    let (cubature, _) = optimize_cubature_cached(&bar_model(), &params(), &dir).unwrap();
    let (model, report) = rule
        .apply_for_run(bar_model(), Some(&dir), Some(&PlannedRun::single_body(1)))
        .unwrap();
    let choice = report
        .choice
        .expect("the automatic rule reports its choice");
    assert!(choice.chose_cubature && report.cubature.unwrap().cached);
    assert_eq!(model.elastic_quadrature(), Some(&cubature));
    // Without the cache, a one-step run cannot pay for training: every point.
    let (model, report) = rule
        .apply_for_run(bar_model(), None, Some(&PlannedRun::single_body(1)))
        .unwrap();
    let choice = report.choice.unwrap();
    assert_eq!(report.kind, "full");
    assert!(!choice.chose_cubature && choice.predicted_full_seconds > 0.0);
    assert!(model.elastic_quadrature().is_none());
}

#[test]
fn measured_evaluation_times_are_positive_and_predict_more_for_several_bodies() {
    let cost = ElasticCost::measure(&bar_model());
    assert!(
        cost.gradient_seconds > 0.0 && cost.hessian_seconds > 0.0,
        "{cost:?}"
    );
    assert!(cost.run(&PlannedRun::multibody(10)) > cost.run(&PlannedRun::single_body(10)));
}

#[test]
fn a_simulator_switched_to_a_cubature_steps_as_one_built_on_it_from_the_same_state() {
    let (cubature, _) = optimize_cubature(&bar_model(), &params()).unwrap();
    let model = bar_model();
    let scene = support::cantilever_scene(&model, 0.3);
    let mut switched = Simulator::new(model, &scene, SimulationParams::default()).unwrap();
    for _ in 0..3 {
        assert!(switched.step().unwrap().converged());
    }
    switched.set_elastic_quadrature(cubature.clone()).unwrap();
    let on_cubature = bar_model().with_elastic_quadrature(cubature).unwrap();
    let mut built = Simulator::new(on_cubature, &scene, SimulationParams::default()).unwrap();
    built.set_state(switched.state().clone()).unwrap();
    for _ in 0..3 {
        assert!(switched.step().unwrap().converged());
        assert!(built.step().unwrap().converged());
        assert_eq!(switched.state().z, built.state().z);
    }
}
