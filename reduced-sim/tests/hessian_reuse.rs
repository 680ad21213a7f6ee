//! Carrying the Hessian factorization across steps (`HessianReuse::WhileContracting`): the same
//! trajectory as fresh Hessians to within the Newton tolerance, fewer assemblies, and
//! non-convergence still reported.

mod support;

use hyperelastic::StableNeoHookean;
use nalgebra::Vector3;
use optimize::{HessianReuse, NewtonParams};
use reduced_sim::{ReducedModel, SimulationParams, Simulator};
use support::BEAM_MATERIAL;

fn bend(hessian_reuse: HessianReuse, max_iterations: usize) -> Simulator<StableNeoHookean> {
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
        ..Default::default()
    };
    Simulator::new(model, &scene, params).unwrap()
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
    // The next step starts from the carried factor: one chord step, still not converged.
    let second = sim.step().unwrap();
    assert!(!second.converged());
    assert_eq!(second.iterations, 1);
}
