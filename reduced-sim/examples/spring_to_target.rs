//! A term written outside the crate: zero-length springs from a block's top face to a moving
//! hand, added to the simulator with `Simulator::add_term` after `check_term` has checked it.
//!
//! ```sh
//! cargo run --release -p reduced-sim --example spring_to_target
//! ```
//!
//! A 1 × 0.5 × 0.5 m rubber block (E = 1 MPa, ν = 0.4, ρ = 1000 kg/m³) hangs under gravity
//! from springs on its top layer of integration points; the hand they are tied to rises 0.2 m over the
//! first second and then holds. Prints the check's errors, then every 20 steps the time, the
//! hand's height and the mean stretch of the springs (m), which settles at the closed form
//! `M g / (P k)` (M the mass, P springs of stiffness k), the force balance of a body held by
//! springs alone.

use std::sync::Arc;

use faer::Mat;
use hyperelastic::{MaterialSample, StableNeoHookean, Tangent};
use nalgebra::Vector3;
use reduced_sim::{
    ReducedModel, Scene, SimulationParams, Simulator, StepTerm, TermCheckParams, TermPoint,
    check_term,
};
use rkpm_core::sample_box_grid;
use skin_eigen::{BasisParams, build_basis};

/// The hand's offset from the springs' rest anchors (m) at time t (s).
pub type HandPath = Arc<dyn Fn(f64) -> Vector3<f64> + Send + Sync>;

/// `E(z, t) = k/2 Σ_j |x_j(z) − (X_j + o(t))|²`: zero-length springs of stiffness k (N/m) from
/// integration points j to their rest positions moved by the hand's offset o(t). Quadratic in
/// z: on each axis r the gradient is `k Σ_j B_j (B_jᵀ z_r − o_r)` and the Hessian block
/// `k Σ_j B_j B_jᵀ`.
pub struct ZeroLengthSprings {
    /// The sprung integration points.
    pub points: Vec<usize>,
    /// Stiffness k of each spring (N/m).
    pub stiffness: f64,
    /// The hand's offset o(t) (m).
    pub hand: HandPath,
}

impl ZeroLengthSprings {
    /// Each spring's displacement `B_jᵀ z_r − o_r(t)` (m) and its row `B_j`.
    fn stretches<'a>(
        &'a self,
        at: &'a TermPoint<'_>,
    ) -> impl Iterator<Item = (Vector3<f64>, &'a [f64])> {
        let hand = (self.hand)(at.time);
        self.points.iter().map(move |&j| {
            let x = at.map.position(j, at.z);
            (
                x - at.map.rest_positions()[j] - hand,
                at.map.position_row(j),
            )
        })
    }
}

impl StepTerm for ZeroLengthSprings {
    fn name(&self) -> &str {
        "zero-length springs"
    }

    fn add_energy(&self, at: &TermPoint<'_>, energy: &mut f64) {
        for (stretch, _) in self.stretches(at) {
            *energy += 0.5 * self.stiffness * stretch.norm_squared();
        }
    }

    fn add_derivatives(
        &self,
        at: &TermPoint<'_>,
        _tangent: Tangent,
        gradient: &mut [f64],
        mut hessian: Option<&mut Mat<f64>>,
    ) {
        let n4 = at.map.layout().block_len();
        for (stretch, row) in self.stretches(at) {
            for r in 0..3 {
                for (a, ba) in row.iter().enumerate() {
                    gradient[r * n4 + a] += self.stiffness * stretch[r] * ba;
                    if let Some(hessian) = hessian.as_deref_mut() {
                        for (b, bb) in row.iter().enumerate() {
                            hessian[(r * n4 + a, r * n4 + b)] += self.stiffness * ba * bb;
                        }
                    }
                }
            }
        }
    }
}

/// The block's model: 1 × 0.5 × 0.5 m on a 0.1 m grid, 60 kernels, 6 modes.
pub fn block_model() -> ReducedModel<StableNeoHookean> {
    let material = MaterialSample {
        youngs_modulus: 1e6,
        poisson_ratio: 0.4,
        density: 1000.0,
    };
    let points =
        sample_box_grid(Vector3::zeros(), Vector3::new(1.0, 0.5, 0.5), 0.1).expect("a valid box");
    let lame = material.lame_parameters().expect("a valid material");
    let params = BasisParams::default().with_modes(6).with_kernels(60);
    let (basis, _, _) = build_basis(&points, &vec![lame; points.len()], &params).expect("a basis");
    ReducedModel::new(
        &basis,
        &points,
        &vec![material; points.len()],
        StableNeoHookean,
    )
    .expect("a model")
}

/// Springs of stiffness `stiffness` (N/m) on the top layer of `model`'s integration points
/// (the highest y, within 1 mm).
pub fn top_springs(
    model: &ReducedModel<StableNeoHookean>,
    stiffness: f64,
    hand: HandPath,
) -> ZeroLengthSprings {
    let rest = model.deformation_map().rest_positions();
    let top = rest.iter().map(|x| x.y).fold(f64::NEG_INFINITY, f64::max);
    ZeroLengthSprings {
        points: model.points_where(|x| x.y > top - 1e-3),
        stiffness,
        hand,
    }
}

/// The springs' mean stretch `mean_j (x_j − X_j − o(t))` (m) at the simulator's state.
pub fn mean_stretch(
    simulator: &Simulator<StableNeoHookean>,
    springs: &ZeroLengthSprings,
) -> Vector3<f64> {
    let state = simulator.state();
    let model = simulator.model();
    let at = TermPoint::new(
        model.deformation_map(),
        model.volumes(),
        &state.z,
        state.time,
    );
    let sum: Vector3<f64> = springs.stretches(&at).map(|(s, _)| s).sum();
    sum / springs.points.len() as f64
}

#[allow(dead_code)]
fn main() {
    let model = block_model();
    let hand: HandPath = Arc::new(|t: f64| Vector3::new(0.0, 0.2 * t.min(1.0), 0.0));
    let springs = top_springs(&model, 2e3, hand.clone());
    let count = springs.points.len();
    let z: Vec<f64> = (0..model.deformation_map().layout().len())
        .map(|i| 0.01 * (i as f64 * 0.7).sin())
        .collect();
    let probe = TermPoint::new(model.deformation_map(), model.volumes(), &z, 0.5);
    let report = check_term(&springs, &probe, &TermCheckParams::default())
        .expect("the springs pass the check");
    println!(
        "check: gradient {:.1e}, Hessian {:.1e}, symmetry {:.1e}",
        report.gradient_error, report.hessian_error, report.symmetry_error
    );
    let weight = model.total_mass() * 9.8;
    let scene = Scene {
        gravity: Some(Vector3::new(0.0, -9.8, 0.0)),
        ..Scene::default()
    };
    let mut simulator =
        Simulator::new(model, &scene, SimulationParams::default()).expect("a simulator");
    simulator.add_term(Box::new(top_springs(simulator.model(), 2e3, hand.clone())));
    println!(
        "{count} springs of 2e3 N/m; closed-form stretch M g / (P k) = {:.4} m",
        weight / (count as f64 * 2e3)
    );
    println!("{:>6} {:>8} {:>12}", "t (s)", "hand (m)", "stretch (m)");
    for step in 1..=300 {
        simulator.step().expect("a step");
        if step % 20 == 0 {
            let t = simulator.state().time;
            let stretch = mean_stretch(&simulator, &springs);
            println!("{t:>6.2} {:>8.3} {:>12.4}", hand(t).y, -stretch.y);
        }
    }
}
