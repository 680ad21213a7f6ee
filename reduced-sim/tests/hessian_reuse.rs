//! Carrying the Hessian factorization across steps (`HessianReuse::WhileContracting`): the same
//! trajectory as fresh Hessians to within the Newton tolerance, fewer assemblies,
//! non-convergence still reported, and a fresh factorization at the age cap and whenever the
//! floor contacts change.

mod support;

use hyperelastic::StableNeoHookean;
use nalgebra::Vector3;
use optimize::{HessianReuse, NewtonParams};
use reduced_sim::{Floor, ReducedModel, ReducedState, Scene, SimulationParams, Simulator};
use support::BEAM_MATERIAL;

const REUSE: HessianReuse = HessianReuse::WhileContracting { contraction: 0.5 };

fn bend(hessian_reuse: HessianReuse, max_iterations: usize) -> Simulator<StableNeoHookean> {
    bend_with_age(
        hessian_reuse,
        max_iterations,
        SimulationParams::default().hessian_max_age,
    )
}

fn bend_with_age(
    hessian_reuse: HessianReuse,
    max_iterations: usize,
    hessian_max_age: usize,
) -> Simulator<StableNeoHookean> {
    let (basis, points) =
        support::box_basis(Vector3::new(3.0, 1.0, 1.0), 0.125, 200, 6, &BEAM_MATERIAL);
    let model: ReducedModel<StableNeoHookean> =
        support::uniform_model(&basis, &points, &BEAM_MATERIAL);
    let scene = support::cantilever_scene(&model, 0.5);
    let params = SimulationParams {
        newton: NewtonParams {
            hessian_reuse,
            max_iterations,
            ..Default::default()
        },
        hessian_max_age,
        ..Default::default()
    };
    Simulator::new(model, &scene, params).unwrap()
}

/// The longest run of consecutive steps without a Hessian assembly in `steps` steps.
fn longest_run_without_assembly(sim: &mut Simulator<StableNeoHookean>, steps: usize) -> usize {
    let (mut run, mut longest) = (0, 0);
    for _ in 0..steps {
        let report = sim.step().unwrap();
        assert!(report.converged());
        run = if report.hessian_assemblies > 0 {
            0
        } else {
            run + 1
        };
        longest = longest.max(run);
    }
    longest
}

#[test]
fn a_factorization_is_carried_across_at_most_hessian_max_age_steps() {
    let capped = longest_run_without_assembly(&mut bend_with_age(REUSE, 40, 3), 30);
    assert!(
        capped <= 2,
        "with an age cap of 3 steps, {capped} steps in a row reused one factorization"
    );
    // Without the cap the same run carries a factorization longer: the cap is what stops it.
    let uncapped = longest_run_without_assembly(&mut bend_with_age(REUSE, 40, 1000), 30);
    assert!(
        uncapped > 2,
        "uncapped, the longest run without an assembly was only {uncapped} steps"
    );
}

#[test]
fn a_change_of_the_floor_contacts_forces_a_fresh_factorization() {
    let (basis, points) =
        support::box_basis(Vector3::new(1.0, 1.0, 1.0), 0.125, 100, 6, &BEAM_MATERIAL);
    let model: ReducedModel<StableNeoHookean> =
        support::uniform_model(&basis, &points, &BEAM_MATERIAL);
    let floor = Floor {
        normal: Vector3::y(),
        offset: -0.05,
        friction: 0.0,
    };
    let scene = Scene {
        gravity: Some(Vector3::new(0.0, -9.8, 0.0)),
        pins: Vec::new(),
        floor: Some(floor),
        held: Vec::new(),
        colliders: Vec::new(),
    };
    let params = SimulationParams {
        newton: NewtonParams {
            hessian_reuse: REUSE,
            max_iterations: 40,
            ..Default::default()
        },
        ..Default::default()
    };
    let mut sim = Simulator::new(model, &scene, params).unwrap();
    let layout = sim.model().deformation_map().layout();
    let falling = ReducedState {
        z: layout.rest(),
        velocity: layout.uniform_velocity(&Vector3::new(0.0, -1.0, 0.0)),
        time: 0.0,
    };
    sim.set_state(falling).unwrap();
    let contacts = |sim: &Simulator<StableNeoHookean>| -> Vec<usize> {
        let x = sim.model().deformation_map().positions(&sim.state().z);
        (0..x.len()).filter(|&i| x[i].y < floor.offset).collect()
    };
    // A step that follows a change of the contact set must assemble (its carried
    // factorization was dropped); steps under unchanged contacts may reuse.
    let mut previous = contacts(&sim);
    let mut changed = false;
    let (mut forced, mut reused) = (0, 0);
    for step in 1..=40 {
        let report = sim.step().unwrap();
        assert!(report.converged(), "step {step}");
        if changed {
            forced += 1;
            assert!(
                report.hessian_assemblies > 0,
                "step {step} follows a change of the floor contacts but assembled no Hessian"
            );
        } else if report.hessian_assemblies == 0 {
            reused += 1;
        }
        let now = contacts(&sim);
        changed = now != previous;
        previous = now;
    }
    assert!(forced > 0, "the box never touched the floor");
    assert!(reused > 0, "no step reused a factorization");
}

#[test]
fn reusing_the_hessian_follows_the_fresh_hessian_trajectory_with_fewer_assemblies() {
    let reuse = HessianReuse::WhileContracting { contraction: 0.5 };
    let (mut fresh, mut reused) = (bend(HessianReuse::Never, 20), bend(reuse, 40));
    let (mut fresh_assemblies, mut reused_assemblies, mut lagged) = (0, 0, 0);
    let mut largest_gap: f64 = 0.0;
    for _ in 0..40 {
        let a = fresh.step().unwrap();
        let b = reused.step().unwrap();
        assert!(a.converged() && b.converged());
        fresh_assemblies += a.hessian_assemblies;
        reused_assemblies += b.hessian_assemblies;
        lagged += b.lagged_steps;
        let map = fresh.model().deformation_map();
        let (x, y) = (
            map.positions(&fresh.state().z),
            map.positions(&reused.state().z),
        );
        for (p, q) in x.iter().zip(&y) {
            largest_gap = largest_gap.max((p - q).norm());
        }
    }
    // Both stop when a Newton step moves the mass by less than 1e-6 · L (L = 3 m) RMS; the
    // states may differ by about that per step, not more.
    assert!(
        largest_gap < 40.0 * 1e-6 * 3.0,
        "largest distance between the two trajectories {largest_gap:.3e} m"
    );
    assert!(lagged > 0, "no chord step was taken");
    assert!(
        reused_assemblies < fresh_assemblies,
        "{reused_assemblies} Hessians with reuse, {fresh_assemblies} without"
    );
    println!(
        "40 Bend steps: {fresh_assemblies} Hessians fresh, {reused_assemblies} with reuse \
         ({lagged} chord steps); largest gap {largest_gap:.2e} m"
    );
}

#[test]
fn a_reused_step_that_does_not_converge_still_says_so() {
    let reuse = HessianReuse::WhileContracting { contraction: 0.5 };
    let mut sim = bend(reuse, 1);
    let first = sim.step().unwrap();
    assert!(!first.converged());
    // The next step starts from the carried factor: one chord step, not converged, so the
    // step is solved again with a fresh Hessian (one iteration), still not converged; the
    // report counts both attempts.
    let second = sim.step().unwrap();
    assert!(!second.converged());
    assert_eq!(
        (
            second.iterations,
            second.lagged_steps,
            second.hessian_assemblies
        ),
        (2, 1, 1)
    );
}
