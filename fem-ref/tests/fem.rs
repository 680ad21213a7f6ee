//! Ground truth for the FEM reference: finite differences, the patch test, rigid motions and
//! Euler-Bernoulli.

use std::ops::ControlFlow;
use std::sync::Arc;

use fem_ref::{
    DirichletRegion, ElementOrder, FactorMemoryLimit, FemMesh, FemModel, FemParams, FemScene,
    FemSetupError, FemSimulator, FillReducingOrdering, MassKind, NodeTarget, PointInterpolation,
    TetMesh,
};
use hyperelastic::MaterialSample;
use hyperelastic::{HessianTangent, StableNeoHookean, Tangent};
use nalgebra::{DMatrix, Matrix3, Rotation3, Vector3};
use optimize::NewtonParams;
use test_support::finite_difference;

const MATERIAL: MaterialSample = MaterialSample {
    youngs_modulus: 1e6,
    poisson_ratio: 0.45,
    density: 1000.0,
};

/// The end x = 0 of `model` held at rest, gravity along −y.
fn cantilever_under_gravity(model: &FemModel<StableNeoHookean>) -> FemScene {
    let nodes = model.mesh().nodes();
    FemScene {
        gravity: Some(Vector3::new(0.0, -9.8, 0.0)),
        dirichlet: vec![DirichletRegion {
            nodes: (0..nodes.len()).filter(|&i| nodes[i].x < 1e-9).collect(),
            target: NodeTarget::Rest,
        }],
        floor: None,
    }
}

fn model(cells: [usize; 3], size: Vector3<f64>, order: ElementOrder) -> FemModel<StableNeoHookean> {
    let mesh = FemMesh::new(
        TetMesh::cuboid(Vector3::zeros(), size, cells).unwrap(),
        order,
    );
    let n = mesh.element_count();
    FemModel::new(
        mesh,
        &vec![MATERIAL; n],
        StableNeoHookean,
        MassKind::Consistent,
    )
    .unwrap()
}

fn flat(points: &[Vector3<f64>]) -> Vec<f64> {
    points.iter().flat_map(|p| [p.x, p.y, p.z]).collect()
}

/// A deterministic deformation of amplitude about 0.1 (no inversion).
fn perturbed(model: &FemModel<StableNeoHookean>) -> Vec<f64> {
    flat(model.mesh().nodes())
        .iter()
        .enumerate()
        .map(|(i, x)| x + 0.05 * ((i as f64 * 1.3).sin() + 0.5 * (i as f64 * 0.37).cos()))
        .collect()
}

#[test]
fn element_gradient_and_hessian_match_finite_differences() {
    for order in [ElementOrder::Linear, ElementOrder::Quadratic] {
        let model = model([1, 1, 1], Vector3::new(1.0, 1.0, 1.0), order);
        let x = perturbed(&model);
        let n = x.len();
        let gradient = model.elastic_gradient(&x);
        let numeric = finite_difference::gradient(|x| model.elastic_energy(x), &x, 1e-6);
        let err = finite_difference::relative_error(
            &DMatrix::from_column_slice(n, 1, &gradient),
            &DMatrix::from_column_slice(n, 1, numeric.as_slice()),
            1e-12,
        );
        assert!(err < 1e-6, "{order:?} gradient: relative error {err:e}");

        // Assemble the exact Hessian from element blocks (also checks element gradients).
        let mut hessian = DMatrix::zeros(n, n);
        let mut from_elements = vec![0.0; n];
        for e in 0..model.mesh().element_count() {
            let g = model.element_gradient(e, &x);
            let h = model.element_hessian(e, &x, Tangent::Exact, 0.0);
            let dofs: Vec<usize> = model
                .mesh()
                .element(e)
                .iter()
                .flat_map(|&node| (0..3).map(move |i| 3 * node + i))
                .collect();
            let k = dofs.len();
            for (a, &r) in dofs.iter().enumerate() {
                from_elements[r] += g[a];
                for (b, &c) in dofs.iter().enumerate() {
                    hessian[(r, c)] += h[a * k + b];
                }
            }
        }
        let diff: f64 = from_elements
            .iter()
            .zip(&gradient)
            .map(|(a, b)| (a - b).abs())
            .sum();
        assert!(diff < 1e-9 * gradient.iter().map(|g| g.abs()).sum::<f64>());
        let numeric = finite_difference::jacobian(|x| model.elastic_gradient(x), &x, 1e-6);
        let err = finite_difference::relative_error(&hessian, &numeric, 1e-12);
        assert!(err < 1e-6, "{order:?} Hessian: relative error {err:e}");
    }
}

#[test]
fn patch_test_reproduces_affine_fields_exactly_and_rigid_motions_cost_nothing() {
    let a = Matrix3::new(1.1, 0.05, -0.02, 0.03, 0.95, 0.04, -0.01, 0.02, 1.05);
    let b = Vector3::new(0.1, -0.2, 0.05);
    for order in [ElementOrder::Linear, ElementOrder::Quadratic] {
        let model = model([3, 3, 3], Vector3::new(1.0, 1.0, 1.0), order);
        let nodes = model.mesh().nodes().to_vec();
        let boundary: Vec<usize> = (0..nodes.len())
            .filter(|&i| {
                nodes[i]
                    .iter()
                    .any(|c| c.abs() < 1e-12 || (c - 1.0).abs() < 1e-12)
            })
            .collect();
        let interior = nodes.len() - boundary.len();
        assert!(interior > 0);
        let scene = FemScene {
            dirichlet: vec![DirichletRegion {
                nodes: boundary,
                target: NodeTarget::Moving(Arc::new(move |x, _| a * x + b)),
            }],
            ..Default::default()
        };
        let params = FemParams {
            newton: NewtonParams {
                tolerance: 1e-12,
                ..Default::default()
            },
            ..Default::default()
        };
        let mut sim = FemSimulator::new(model, scene, params).unwrap();
        let report = sim.solve_static(0.0).unwrap();
        assert!(report.converged(), "{report:?}");
        let worst = sim
            .positions()
            .iter()
            .zip(&nodes)
            .map(|(x, rest)| (x - (a * rest + b)).norm())
            .fold(0.0, f64::max);
        assert!(
            worst < 1e-10,
            "{order:?}: affine field missed by {worst:e} m ({interior} free nodes)"
        );

        // Rigid motion: zero elastic force at every node.
        let model = self::model([2, 2, 2], Vector3::new(1.0, 1.0, 1.0), order);
        let r = Rotation3::from_scaled_axis(Vector3::new(0.4, -0.9, 0.3)).into_inner();
        let moved: Vec<Vector3<f64>> = model.mesh().nodes().iter().map(|p| r * p + b).collect();
        let x = flat(&moved);
        let max_abs = |v: Vec<f64>| v.iter().map(|g| g.abs()).fold(0.0, f64::max);
        let force = max_abs(model.elastic_gradient(&x));
        let scale = max_abs(model.elastic_gradient(&perturbed(&model)));
        assert!(
            force < 1e-10 * scale,
            "{order:?}: rigid force {force:e} N vs {scale:e} N"
        );
        let energy = model.elastic_energy(&x);
        assert!(energy.abs() < 1e-12 * model.elastic_energy(&perturbed(&model)));
    }
}

/// A 10 × 1 × 1 m beam (9.5 m span) clamped on x ≤ 0.5, ν = 0.3, 1% of gravity: linear regime.
/// Euler-Bernoulli δ = qL⁴/(8EI); Timoshenko's shear term adds 1.2% at this slenderness.
#[test]
fn static_p2_cantilever_is_within_two_percent_of_euler_bernoulli() {
    let material = MaterialSample {
        youngs_modulus: 5e6,
        poisson_ratio: 0.3,
        density: 1000.0,
    };
    let g = 0.098;
    let length = 10.0f64;
    let tets =
        TetMesh::cuboid(Vector3::zeros(), Vector3::new(length, 1.0, 1.0), [20, 2, 2]).unwrap();
    let mesh = FemMesh::new(tets, ElementOrder::Quadratic);
    let n = mesh.element_count();
    let model = FemModel::new(
        mesh,
        &vec![material; n],
        StableNeoHookean,
        MassKind::Consistent,
    )
    .unwrap();
    let nodes = model.mesh().nodes().to_vec();
    let clamped: Vec<usize> = (0..nodes.len())
        .filter(|&i| nodes[i].x <= 0.5 + 1e-9)
        .collect();
    let face: Vec<Vector3<f64>> = (0..11)
        .flat_map(|a| (0..11).map(move |c| Vector3::new(length, a as f64 / 10.0, c as f64 / 10.0)))
        .collect();
    let probe = PointInterpolation::new(model.mesh(), &face).unwrap();
    let scene = FemScene {
        gravity: Some(Vector3::new(0.0, -g, 0.0)),
        dirichlet: vec![DirichletRegion {
            nodes: clamped,
            target: NodeTarget::Rest,
        }],
        floor: None,
    };
    let mut sim = FemSimulator::new(model, scene, FemParams::default()).unwrap();
    assert!(sim.solve_static(0.0).unwrap().converged());
    let x = probe.interpolate(&sim.positions());
    let tip = -x.iter().zip(&face).map(|(x, r)| x.y - r.y).sum::<f64>() / face.len() as f64;
    let span = length - 0.5;
    let euler_bernoulli =
        material.density * g * span.powi(4) / (8.0 * material.youngs_modulus / 12.0);
    let ratio = tip / euler_bernoulli;
    eprintln!(
        "P2 cantilever tip {tip:.6e} m, Euler-Bernoulli {euler_bernoulli:.6e} m, ratio {ratio:.4}"
    );
    assert!((ratio - 1.0).abs() < 0.02, "ratio {ratio:.4}");
}

#[test]
fn cached_trajectory_is_reused_and_any_input_change_misses() {
    use fem_ref::{TrajectoryCache, TrajectoryCacheError};
    let dir = test_support::fixtures::scratch_dir("fem-trajectory-cache");
    let cache = TrajectoryCache::new(&dir);
    let simulator = |g: f64| {
        let model = model([2, 1, 1], Vector3::new(2.0, 1.0, 1.0), ElementOrder::Linear);
        let fixed: Vec<usize> = (0..model.mesh().nodes().len())
            .filter(|&i| model.mesh().nodes()[i].x < 1e-9)
            .collect();
        let scene = FemScene {
            gravity: Some(Vector3::new(0.0, -g, 0.0)),
            dirichlet: vec![DirichletRegion {
                nodes: fixed,
                target: NodeTarget::Rest,
            }],
            floor: None,
        };
        FemSimulator::new(model, scene, FemParams::default()).unwrap()
    };
    let mut steps_run = 0;
    let first = simulator(9.8)
        .run_cached(3, "test", &cache, |_| {
            steps_run += 1;
            ControlFlow::Continue(())
        })
        .unwrap();
    assert!(!first.from_cache && steps_run == 3 && first.trajectory.frames.len() == 4);
    let second = simulator(9.8)
        .run_cached(3, "test", &cache, |_| panic!())
        .unwrap();
    assert!(second.from_cache);
    assert_eq!(first.trajectory, second.trajectory);
    // A different load, label or step count is a different trajectory.
    let a = simulator(9.8).trajectory_key("test", 3);
    assert_ne!(a, simulator(9.7).trajectory_key("test", 3));
    assert_ne!(a, simulator(9.8).trajectory_key("other", 3));
    assert_ne!(a, simulator(9.8).trajectory_key("test", 4));
    // A damaged file is reported, not trusted.
    std::fs::write(cache.path(a), b"FFTRAJ\x01\x00\x00\x00garbage").unwrap();
    assert!(matches!(
        cache.load(a),
        Err(TrajectoryCacheError::Format { .. })
    ));
}

/// With the Cholesky factor carried across steps (chord steps while they contract), a P2
/// cantilever falling under gravity follows the fresh-Hessian trajectory to within the Newton
/// tolerance's reach (both at 1e-9: nodes within 1e-7 m, 3e-8 of the beam's length; 3e-9 m
/// measured), with far fewer factorizations (1 against 44 measured).
#[test]
fn a_step_with_a_carried_factorization_reaches_the_fresh_hessian_state() {
    let run = |hessian_reuse: optimize::HessianReuse| {
        let model = model(
            [6, 2, 2],
            Vector3::new(3.0, 1.0, 1.0),
            ElementOrder::Quadratic,
        );
        let scene = cantilever_under_gravity(&model);
        let params = FemParams {
            newton: NewtonParams {
                tolerance: 1e-9,
                hessian_reuse,
                ..NewtonParams::default()
            },
            ..FemParams::default()
        };
        let mut sim = FemSimulator::new(model, scene, params).unwrap();
        let mut factorizations = 0;
        for _ in 0..20 {
            let report = sim.step().unwrap();
            assert!(report.converged());
            factorizations += report.hessian_assemblies;
        }
        (sim.positions(), factorizations)
    };
    let (fresh, fresh_factorizations) = run(optimize::HessianReuse::Never);
    let (reused, reused_factorizations) =
        run(optimize::HessianReuse::WhileContracting { contraction: 0.5 });
    let deviation = fresh
        .iter()
        .zip(&reused)
        .map(|(a, b)| (a - b).norm())
        .fold(0.0, f64::max);
    eprintln!(
        "deviation {deviation:e} m; factorizations {reused_factorizations} reused, {fresh_factorizations} fresh"
    );
    assert!(deviation < 1e-7, "largest node deviation {deviation} m");
    assert!(
        2 * reused_factorizations <= fresh_factorizations,
        "{reused_factorizations} factorizations with reuse, {fresh_factorizations} fresh"
    );
}

/// A definite tangent on demand ([`HessianTangent::ExactWhenDefinite`]'s projection,
/// [`HessianTangent::ExactElseAbsolute`]'s absolute eigenvalues) changes the Newton path, not
/// the solution: a P1 beam twisted at 2160°/s to 720° (the Twist scene, E = 1 MPa), where the
/// exact tangent alone fails to factor, reaches the projected-Newton state within the
/// tolerance's reach (all at 1e-9: nodes within 1e-6 m) in fewer Newton iterations (the
/// projected tangent is too stiff where the twist compresses the material).
#[test]
fn exact_tangent_with_a_definite_fallback_reaches_the_projected_newton_state_in_fewer_iterations() {
    let run = |tangent: HessianTangent| {
        let model = model(
            [20, 4, 4],
            Vector3::new(5.0, 1.0, 1.0),
            ElementOrder::Linear,
        );
        let nodes = model.mesh().nodes().to_vec();
        let select = |keep: &dyn Fn(&Vector3<f64>) -> bool| -> Vec<usize> {
            (0..nodes.len()).filter(|&i| keep(&nodes[i])).collect()
        };
        let scene = FemScene {
            gravity: None,
            dirichlet: vec![
                DirichletRegion {
                    nodes: select(&|x| x.x < 1e-9),
                    target: NodeTarget::Rest,
                },
                DirichletRegion {
                    nodes: select(&|x| x.x > 5.0 - 1e-9),
                    target: NodeTarget::Moving(Arc::new(|x, t| {
                        let axis = Vector3::new(x.x, 0.5, 0.5);
                        let angle = (2160.0 * t).min(720.0).to_radians();
                        axis + Rotation3::from_axis_angle(&Vector3::x_axis(), angle) * (x - axis)
                    })),
                },
            ],
            floor: None,
        };
        let params = FemParams {
            newton: NewtonParams {
                tolerance: 1e-9,
                max_iterations: 60,
                ..NewtonParams::default()
            },
            tangent,
            ..FemParams::default()
        };
        let mut sim = FemSimulator::new(model, scene, params).unwrap();
        let mut iterations = 0;
        for _ in 0..30 {
            let report = sim.step()?;
            assert!(report.converged(), "{tangent:?}: {report:?}");
            iterations += report.iterations;
        }
        Ok::<_, optimize::NewtonError>((sim.positions(), iterations))
    };
    let (projected, projected_iterations) = run(HessianTangent::ProjectedPsd).unwrap();
    let (on_demand, on_demand_iterations) = run(HessianTangent::ExactWhenDefinite).unwrap();
    // The exact tangent alone loses definiteness on the way: the fallback is exercised.
    let exact = run(HessianTangent::Exact);
    assert!(
        matches!(
            exact,
            Err(optimize::NewtonError::NotPositiveDefinite { .. })
        ),
        "the exact tangent stayed definite"
    );
    let (absolute, absolute_iterations) = run(HessianTangent::ExactElseAbsolute).unwrap();
    for (fallback, state, iterations) in [
        ("projection", &on_demand, on_demand_iterations),
        ("absolute eigenvalues", &absolute, absolute_iterations),
    ] {
        let deviation = projected
            .iter()
            .zip(state)
            .map(|(a, b)| (a - b).norm())
            .fold(0.0, f64::max);
        eprintln!(
            "{fallback} on demand: deviation {deviation:e} m; Newton iterations {iterations}, \
             {projected_iterations} projected"
        );
        assert!(
            deviation < 1e-6,
            "{fallback}: largest node deviation {deviation} m"
        );
        assert!(
            iterations < projected_iterations,
            "{fallback}: {iterations} iterations on demand, {projected_iterations} projected"
        );
    }
}

/// The elimination order changes the factorization's fill and nothing but round-off: a P2
/// cantilever (12 × 4 × 4 cells) falling under gravity for 10 steps ends at the same node
/// positions with nested dissection as with approximate minimum degree (within 1e-12 m);
/// nested dissection's factor has fewer entries there, and the default keeps the smaller.
#[test]
fn the_elimination_order_changes_the_fill_not_the_states_and_the_default_keeps_the_smaller() {
    let run = |ordering: FillReducingOrdering| {
        let model = model(
            [12, 4, 4],
            Vector3::new(3.0, 1.0, 1.0),
            ElementOrder::Quadratic,
        );
        let scene = cantilever_under_gravity(&model);
        let params = FemParams {
            newton: NewtonParams {
                tolerance: 1e-10,
                ..NewtonParams::default()
            },
            ordering,
            ..FemParams::default()
        };
        let mut sim = FemSimulator::new(model, scene, params).unwrap();
        for _ in 0..10 {
            assert!(sim.step().unwrap().converged());
        }
        (sim.positions(), sim.factor_nonzeros())
    };
    let (amd, amd_fill) = run(FillReducingOrdering::ApproximateMinimumDegree);
    let (nested, nested_fill) = run(FillReducingOrdering::NestedDissection);
    let (default, default_fill) = run(FillReducingOrdering::default());
    let deviation = amd
        .iter()
        .zip(&nested)
        .map(|(a, b)| (a - b).norm())
        .fold(0.0, f64::max);
    eprintln!("deviation {deviation:e} m; factor entries {nested_fill} nested, {amd_fill} AMD");
    assert!(deviation < 1e-12, "largest node deviation {deviation} m");
    assert!(
        nested_fill < amd_fill,
        "nested dissection {nested_fill} factor entries, AMD {amd_fill}"
    );
    assert_eq!(default_fill, nested_fill.min(amd_fill));
    assert_eq!(default, nested);
}

#[test]
fn a_factor_over_the_memory_limit_is_refused_at_setup_with_its_size_and_one_within_it_runs() {
    let simulator = |factor_memory: FactorMemoryLimit| {
        let model = model(
            [6, 2, 2],
            Vector3::new(3.0, 1.0, 1.0),
            ElementOrder::Quadratic,
        );
        let scene = cantilever_under_gravity(&model);
        FemSimulator::new(
            model,
            scene,
            FemParams {
                factor_memory,
                ..FemParams::default()
            },
        )
    };
    let Err(FemSetupError::FactorTooLarge {
        dofs,
        factor_nonzeros,
        bytes,
        limit,
    }) = simulator(FactorMemoryLimit::Bytes(1))
    else {
        panic!("a one-byte limit must refuse the factor");
    };
    assert_eq!(limit, 1);
    assert!(
        dofs > 0 && factor_nonzeros >= dofs,
        "{dofs} DOFs, {factor_nonzeros} nonzeros"
    );
    // Two factors of 8-byte values at least.
    assert!(bytes >= 16 * factor_nonzeros as u64, "{bytes} bytes");
    let message = simulator(FactorMemoryLimit::Bytes(bytes - 1))
        .err()
        .expect("one byte short is refused")
        .to_string();
    assert!(message.contains(&format!("{dofs} DOFs")), "{message}");
    // Exactly the need is allowed, and the simulator steps with the factor it sized.
    let mut sim = simulator(FactorMemoryLimit::Bytes(bytes)).expect("the need itself fits");
    assert!(sim.step().unwrap().converged());
    assert_eq!(sim.factor_nonzeros(), factor_nonzeros);
    assert!(simulator(FactorMemoryLimit::Unlimited).is_ok());
}

/// A soft P1 cantilever (E = 2 kPa, 4 × 1 × 1 m) falling under gravity with Newton capped at
/// `max_iterations` and steps split `failed_step_halvings` deep.
fn soft_falling_cantilever(
    time_step: f64,
    max_iterations: usize,
    failed_step_halvings: usize,
) -> FemSimulator<StableNeoHookean> {
    let (model, scene, params) =
        soft_falling_cantilever_inputs(time_step, max_iterations, failed_step_halvings);
    FemSimulator::new(model, scene, params).unwrap()
}

/// What [`soft_falling_cantilever`] builds its simulator from.
fn soft_falling_cantilever_inputs(
    time_step: f64,
    max_iterations: usize,
    failed_step_halvings: usize,
) -> (FemModel<StableNeoHookean>, FemScene, FemParams) {
    let mesh = FemMesh::new(
        TetMesh::cuboid(Vector3::zeros(), Vector3::new(4.0, 1.0, 1.0), [4, 1, 1]).unwrap(),
        ElementOrder::Linear,
    );
    let soft = MaterialSample {
        youngs_modulus: 2e3,
        ..MATERIAL
    };
    let n = mesh.element_count();
    let model =
        FemModel::new(mesh, &vec![soft; n], StableNeoHookean, MassKind::Consistent).unwrap();
    let scene = cantilever_under_gravity(&model);
    let params = FemParams {
        time_step,
        newton: NewtonParams {
            max_iterations,
            tolerance: 1e-10,
            ..NewtonParams::default()
        },
        failed_step_halvings,
        ..FemParams::default()
    };
    (model, scene, params)
}

/// At h = 0.2 s the first step of [`soft_falling_cantilever`] needs 18 Newton iterations,
/// each half of it at h = 0.1 s 5 and 7: capped at 10, the whole step fails and its halves
/// converge. Split, the step lands where two backward-Euler steps of h/2 do.
#[test]
fn a_step_that_fails_whole_is_taken_as_two_backward_euler_half_steps() {
    let mut whole = soft_falling_cantilever(0.2, 10, 0);
    assert!(!whole.step().unwrap().converged());
    let mut split = soft_falling_cantilever(0.2, 10, 1);
    let report = split.step().unwrap();
    assert!(report.converged());
    assert_eq!(split.split_steps(), 1);
    assert!(
        report.iterations > 10,
        "{} iterations: the failed whole step's 10 are counted",
        report.iterations
    );
    let mut halves = soft_falling_cantilever(0.1, 100, 0);
    assert!(halves.step().unwrap().converged() && halves.step().unwrap().converged());
    assert_eq!(split.time(), 0.2);
    let deviation = |a: Vec<Vector3<f64>>, b: Vec<Vector3<f64>>| {
        a.iter()
            .zip(&b)
            .map(|(p, q)| (p - q).norm())
            .fold(0.0, f64::max)
    };
    let positions = deviation(split.positions(), halves.positions());
    let velocities = deviation(split.velocities(), halves.velocities());
    assert!(positions < 1e-8, "positions differ by {positions} m");
    assert!(velocities < 1e-7, "velocities differ by {velocities} m/s");
    // Capped at 10 with no level left to split into, the step stays unconverged.
    let mut shallow = soft_falling_cantilever(0.4, 10, 1);
    assert!(!shallow.step().unwrap().converged());
}

/// A trajectory that split a step is cached under its own key; a run that may split does not
/// take an unsplit run's unconverged trajectory, and converged ones serve every depth.
#[test]
fn split_trajectories_are_cached_apart_and_unconverged_ones_are_not_served_to_splitting_runs() {
    use fem_ref::TrajectoryCache;
    let dir = test_support::fixtures::scratch_dir("fem-split-cache");
    let cache = TrajectoryCache::new(&dir);
    let run = |h: f64, halvings: usize, expect_cached: bool| {
        let mut computed = 0;
        let run = soft_falling_cantilever(h, 10, halvings)
            .run_cached(2, "falling", &cache, |_| {
                computed += 1;
                ControlFlow::Continue(())
            })
            .unwrap();
        assert_eq!(run.from_cache, expect_cached, "h {h}, {halvings} halvings");
        assert_eq!(computed, if run.from_cache { 0 } else { 2 });
        run.trajectory
    };
    let unsplit = run(0.2, 0, false);
    assert!(!unsplit.converged[0]);
    let split = run(0.2, 1, false);
    assert!(split.converged.iter().all(|&c| c));
    assert_eq!(run(0.2, 1, true), split);
    assert_eq!(run(0.2, 0, true), unsplit);
    // Every step converged whole: one trajectory for every depth.
    let smooth = run(0.025, 2, false);
    assert!(smooth.converged.iter().all(|&c| c));
    assert_eq!(run(0.025, 0, true), smooth);
    let key = |halvings| soft_falling_cantilever(0.2, 10, halvings).split_trajectory_key("x", 2);
    assert_ne!(key(1), key(2));
    assert_eq!(
        soft_falling_cantilever(0.2, 10, 1).trajectory_key("x", 2),
        soft_falling_cantilever(0.2, 10, 2).trajectory_key("x", 2)
    );
}

/// `load_cached` finds a run from the simulator's inputs alone, exactly where `run_cached`
/// would serve it: not before it is stored, not an unsplit run's unconverged trajectory to a
/// run that may split, not under another label or step count, not for a scene `new` refuses.
#[test]
fn a_cached_run_is_found_from_the_simulators_inputs_exactly_where_run_cached_serves_it() {
    use fem_ref::{FemFloor, TrajectoryCache};
    let dir = test_support::fixtures::scratch_dir("fem-load-cached");
    let cache = TrajectoryCache::new(&dir);
    let load = |h: f64, halvings: usize, steps: usize, label: &str| {
        let (model, scene, params) = soft_falling_cantilever_inputs(h, 10, halvings);
        FemSimulator::load_cached(&model, &scene, &params, steps, label, &cache).unwrap()
    };
    assert_eq!(load(0.2, 0, 2, "falling"), None);
    let unsplit = soft_falling_cantilever(0.2, 10, 0)
        .run_cached(2, "falling", &cache, |_| ControlFlow::Continue(()))
        .unwrap()
        .trajectory;
    assert!(!unsplit.converged[0]);
    assert_eq!(load(0.2, 0, 2, "falling"), Some(unsplit));
    assert_eq!(load(0.2, 1, 2, "falling"), None);
    let split = soft_falling_cantilever(0.2, 10, 1)
        .run_cached(2, "falling", &cache, |_| ControlFlow::Continue(()))
        .unwrap()
        .trajectory;
    assert_eq!(load(0.2, 1, 2, "falling"), Some(split));
    assert_eq!(load(0.2, 1, 3, "falling"), None);
    assert_eq!(load(0.2, 1, 2, "other"), None);
    let (model, mut scene, params) = soft_falling_cantilever_inputs(0.2, 10, 0);
    scene.floor = Some(FemFloor {
        normal: Vector3::zeros(),
        offset: 0.0,
        floor_factor: 1e4,
    });
    assert_eq!(
        FemSimulator::load_cached(&model, &scene, &params, 2, "falling", &cache).unwrap(),
        None
    );
}

/// [`soft_falling_cantilever`] at h = 0.2 s (its first step splits) saving a checkpoint
/// after every step.
fn checkpointing_split_cantilever() -> FemSimulator<StableNeoHookean> {
    let (model, scene, params) = soft_falling_cantilever_inputs(0.2, 10, 1);
    let every_step = Some(std::time::Duration::ZERO);
    let params = FemParams {
        checkpoint_interval: every_step,
        ..params
    };
    FemSimulator::new(model, scene, params).unwrap()
}

/// The parts of a trajectory a resumed run must reproduce exactly (all but the wall time).
fn computed_parts(t: &fem_ref::Trajectory) -> impl PartialEq + std::fmt::Debug + '_ {
    (&t.times, &t.frames, &t.iterations, &t.converged)
}

/// A run stopped by its caller saves what it computed and is not stored as finished; the
/// next run of the same inputs goes on from there (the progress callback first hears the
/// resumed step count) and ends bit for bit where the uninterrupted run does, after which
/// the checkpoint is gone.
#[test]
fn a_stopped_run_resumes_from_its_checkpoint_to_the_uninterrupted_trajectory_bit_for_bit() {
    use fem_ref::{FemRunError, RunProgress, TrajectoryCache};
    let dir = test_support::fixtures::scratch_dir("fem-checkpoint-stop");
    let whole = TrajectoryCache::new(dir.join("whole"));
    let uninterrupted = soft_falling_cantilever(0.05, 60, 0)
        .run_cached(4, "falling", &whole, |_| ControlFlow::Continue(()))
        .unwrap();
    assert!(uninterrupted.trajectory.iterations.iter().all(|&i| i > 1));
    let cache = TrajectoryCache::new(dir.join("stopped"));
    let key = soft_falling_cantilever(0.05, 60, 0).trajectory_key("falling", 4);
    assert_eq!(
        soft_falling_cantilever(0.05, 60, 0).checkpoint_key("falling", 4),
        key
    );
    let stopped = soft_falling_cantilever(0.05, 60, 0).run_cached(4, "falling", &cache, |event| {
        if event.steps_done() == 2 {
            ControlFlow::Break(())
        } else {
            ControlFlow::Continue(())
        }
    });
    match stopped {
        Err(FemRunError::Stopped {
            step: 2,
            steps: 4,
            checkpoint,
        }) => assert_eq!(checkpoint, cache.checkpoint_path(key)),
        other => panic!("expected a stop after step 2, got {other:?}"),
    }
    assert_eq!(
        cache.load(key).unwrap(),
        None,
        "a stopped run is not finished"
    );
    assert_eq!(cache.load_checkpoint(key).unwrap().unwrap().steps_done(), 2);
    // Stopped again at once: nothing computed, the checkpoint stays.
    let again = soft_falling_cantilever(0.05, 60, 0)
        .run_cached(4, "falling", &cache, |_| ControlFlow::Break(()));
    assert!(matches!(again, Err(FemRunError::Stopped { step: 2, .. })));
    let mut heard = Vec::new();
    let resumed = soft_falling_cantilever(0.05, 60, 0)
        .run_cached(4, "falling", &cache, |event| {
            heard.push(event);
            ControlFlow::Continue(())
        })
        .unwrap();
    assert_eq!(
        heard,
        [
            RunProgress::Resumed { steps_done: 2 },
            RunProgress::Stepped { step: 3 },
            RunProgress::Stepped { step: 4 }
        ]
    );
    assert!(!resumed.from_cache && resumed.checkpoint_error.is_none());
    assert_eq!(resumed.resumed_steps, 2);
    assert_eq!(
        computed_parts(&resumed.trajectory),
        computed_parts(&uninterrupted.trajectory)
    );
    assert_eq!(cache.load_checkpoint(key).unwrap(), None);
    assert_eq!(cache.load(key).unwrap(), Some(resumed.trajectory));
}

/// A run killed part way (here: a panic in its progress callback) loses only what came after
/// its last interval checkpoint; a run that split steps keeps its split count across the
/// resume and is stored under the split key.
#[test]
fn a_killed_run_resumes_from_its_last_checkpoint_with_its_split_steps() {
    use fem_ref::TrajectoryCache;
    let dir = test_support::fixtures::scratch_dir("fem-checkpoint-kill");
    let whole = TrajectoryCache::new(dir.join("whole"));
    let mut reference = soft_falling_cantilever(0.2, 10, 1);
    let uninterrupted = reference
        .run_cached(3, "falling", &whole, |_| ControlFlow::Continue(()))
        .unwrap();
    assert!(
        reference.split_steps() >= 1,
        "h = 0.2 s splits its first step"
    );
    let cache = TrajectoryCache::new(dir.join("killed"));
    let killed = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        checkpointing_split_cantilever().run_cached(3, "falling", &cache, |event| {
            assert!(
                event.steps_done() < 2,
                "killed after step 2, before its checkpoint"
            );
            ControlFlow::Continue(())
        })
    }));
    assert!(killed.is_err());
    let split_key = reference.split_trajectory_key("falling", 3);
    assert_eq!(reference.checkpoint_key("falling", 3), split_key);
    assert_eq!(
        cache
            .load_checkpoint(split_key)
            .unwrap()
            .unwrap()
            .steps_done(),
        1
    );
    let mut resumed_sim = checkpointing_split_cantilever();
    let resumed = resumed_sim
        .run_cached(3, "falling", &cache, |_| ControlFlow::Continue(()))
        .unwrap();
    assert_eq!(resumed.resumed_steps, 1);
    assert_eq!(resumed_sim.split_steps(), reference.split_steps());
    assert_eq!(
        computed_parts(&resumed.trajectory),
        computed_parts(&uninterrupted.trajectory)
    );
    assert!(cache.load(split_key).unwrap().is_some());
    assert_eq!(cache.load_checkpoint(split_key).unwrap(), None);
}

/// A checkpoint that does not fit the run (another mesh's node count) or does not decode is
/// reported with its path, never resumed from.
#[test]
fn a_checkpoint_that_does_not_fit_the_run_is_reported_not_resumed() {
    use fem_ref::{FemRunError, RunCheckpoint, Trajectory, TrajectoryCache, TrajectoryCacheError};
    let dir = test_support::fixtures::scratch_dir("fem-checkpoint-mismatch");
    let cache = TrajectoryCache::new(&dir);
    let key = soft_falling_cantilever(0.05, 60, 0).trajectory_key("falling", 4);
    let foreign = RunCheckpoint {
        trajectory: Trajectory {
            times: vec![0.0, 0.05],
            frames: vec![vec![[0.0; 3]; 3]; 2],
            iterations: vec![3],
            converged: vec![true],
            seconds: 1.0,
        },
        velocities: vec![0.0; 9],
        split_steps: 0,
    };
    cache.store_checkpoint(key, &foreign).unwrap();
    let run = |cache: &TrajectoryCache| {
        soft_falling_cantilever(0.05, 60, 0)
            .run_cached(4, "falling", cache, |_| ControlFlow::Continue(()))
    };
    match run(&cache) {
        Err(FemRunError::CheckpointMismatch { path, reason }) => {
            assert_eq!(path, cache.checkpoint_path(key));
            assert!(reason.contains("nodes"), "{reason}");
        }
        other => panic!("expected a mismatch, got {other:?}"),
    }
    std::fs::write(cache.checkpoint_path(key), b"FFPART\x01\x00\x00\x00garbage").unwrap();
    assert!(matches!(
        run(&cache),
        Err(FemRunError::Cache(TrajectoryCacheError::Format { .. }))
    ));
    cache.remove_checkpoint(key).unwrap();
    assert!(run(&cache).is_ok());
}

#[test]
fn the_scenes_free_dofs_are_the_simulators_unknowns_and_a_scene_holding_every_node_is_refused() {
    use fem_ref::FemSetupError;
    for order in [ElementOrder::Linear, ElementOrder::Quadratic] {
        let model = model([3, 1, 1], Vector3::new(3.0, 1.0, 1.0), order);
        let scene = cantilever_under_gravity(&model);
        let nodes = model.mesh().nodes().len();
        let held = scene.dirichlet[0].nodes.len();
        assert!(held > 0 && held < nodes);
        assert_eq!(scene.free_dofs(nodes).unwrap(), 3 * (nodes - held));
        let sim = FemSimulator::new(model, scene.clone(), FemParams::default()).unwrap();
        assert_eq!(scene.free_dofs(nodes).unwrap(), sim.free_dofs());
    }
    let model = model([1, 1, 1], Vector3::new(1.0, 1.0, 1.0), ElementOrder::Linear);
    let nodes = model.mesh().nodes().len();
    let everything = FemScene {
        gravity: None,
        dirichlet: vec![DirichletRegion {
            nodes: (0..nodes).collect(),
            target: NodeTarget::Rest,
        }],
        floor: None,
    };
    assert!(matches!(
        everything.free_dofs(nodes),
        Err(FemSetupError::NothingFree)
    ));
}
