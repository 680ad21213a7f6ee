//! Shared setup of the reduced-sim integration tests: small RKPM bases of boxes.

#![allow(dead_code)]

use hyperelastic::MaterialSample;
use hyperelastic::{LameParameters, StableNeoHookean};
use nalgebra::Vector3;
use reduced_sim::ReducedModel;
use rkpm_core::{IntegrationPoints, sample_box_grid};
use skin_eigen::{BasisParams, SkinningBasis, build_basis};

/// An RKPM skinning basis of the box [0, size] sampled on a grid of spacing `spacing`, with
/// `kernels` kernels and `modes` modes, for a uniform material; returns the basis and its
/// integration points.
pub fn box_basis(
    size: Vector3<f64>,
    spacing: f64,
    kernels: usize,
    modes: usize,
    material: &MaterialSample,
) -> (SkinningBasis, IntegrationPoints) {
    let points = sample_box_grid(Vector3::zeros(), size, spacing).expect("valid box");
    let lame = LameParameters::from_young_poisson(material.youngs_modulus, material.poisson_ratio)
        .expect("valid material");
    let params = BasisParams::default()
        .with_modes(modes)
        .with_kernels(kernels);
    let (basis, _, _) = build_basis(&points, &vec![lame; points.len()], &params).expect("basis");
    (basis, points)
}

/// The model of `basis` on `points` with one uniform material.
pub fn uniform_model(
    basis: &SkinningBasis,
    points: &IntegrationPoints,
    material: &MaterialSample,
) -> ReducedModel<StableNeoHookean> {
    ReducedModel::new(
        basis,
        points,
        &vec![*material; points.len()],
        StableNeoHookean,
    )
    .expect("valid model")
}

/// The beam material of design §4.1: E = 5 MPa, ν = 0.45, ρ = 1000 kg/m³.
pub const BEAM_MATERIAL: MaterialSample = MaterialSample {
    youngs_modulus: 5e6,
    poisson_ratio: 0.45,
    density: 1000.0,
};

/// Gravity (9.8 m/s² along -y) on `model` with the points at x ≤ `pinned_below` (m) held at
/// rest: the cantilever scenes of these tests.
pub fn cantilever_scene<M: hyperelastic::HyperelasticMaterial>(
    model: &ReducedModel<M>,
    pinned_below: f64,
) -> reduced_sim::Scene {
    reduced_sim::Scene {
        gravity: Some(Vector3::new(0.0, -9.8, 0.0)),
        pins: vec![reduced_sim::PinnedRegion {
            points: model.points_where(|x| x.x <= pinned_below),
            target: reduced_sim::PinTarget::Rest,
        }],
        floor: None,
        held: Vec::new(),
        colliders: Vec::new(),
    }
}

/// A 3 × 1 × 1 m bar of [`BEAM_MATERIAL`], 200 kernels, 6 modes, on a 0.1 m grid (3000
/// points), integrated on every point.
pub fn bar_model() -> ReducedModel<StableNeoHookean> {
    let (basis, points) = box_basis(Vector3::new(3.0, 1.0, 1.0), 0.1, 200, 6, &BEAM_MATERIAL);
    uniform_model(&basis, &points, &BEAM_MATERIAL)
}
