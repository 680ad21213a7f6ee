//! The static projections on a small basis.

use fem_ref::ElementOrder;
use reduced_sim::DeformationMap;
use skin_eigen::SkinningBasis;

use super::static_reference::{
    StaticReference, field_errors, projections, reference_error, static_reference, static_scene,
};
use crate::beam_protocol::reduced::build_beam_basis;
use crate::beam_scenario::beam_material;
use crate::fem_reference::FemResolution;
use crate::reduced_settings::ReducedSettings;

fn small_basis() -> SkinningBasis {
    let settings = ReducedSettings {
        modes: 4,
        kernels: 120,
        basis_points: 3000,
        ..ReducedSettings::default()
    };
    build_beam_basis(&settings).unwrap().basis
}

/// P1 tetrahedra at `cells_per_metre`.
fn linear(cells_per_metre: usize) -> FemResolution {
    FemResolution {
        order: ElementOrder::Linear,
        cells_per_metre,
    }
}

fn coarse_reference() -> StaticReference {
    static_reference(&static_scene(1e-3), linear(2), beam_material()).unwrap()
}

#[test]
fn a_static_reference_checked_against_its_own_resolution_has_no_error() {
    let reference = coarse_reference();
    let error =
        reference_error(&reference, &static_scene(1e-3), linear(2), beam_material()).unwrap();
    assert!(error.mse < 1e-24, "MSE {:e}", error.mse);
    assert!(error.tip_change.abs() < 1e-12, "tip {:e}", error.tip_change);
}

#[test]
fn a_coarse_linear_reference_is_stiffer_than_a_finer_one() {
    // P1 tetrahedra lock in bending and stiffen as the mesh coarsens: the res 2 reference's
    // tip moves less than the res 3 one's, and its field differs.
    let reference = coarse_reference();
    let error =
        reference_error(&reference, &static_scene(1e-3), linear(3), beam_material()).unwrap();
    assert!(
        error.mse > 0.0 && error.mse.is_finite(),
        "MSE {:e}",
        error.mse
    );
    assert!(
        error.tip_change < -0.01,
        "tip change {:+e}",
        error.tip_change
    );
}

#[test]
fn both_projections_reproduce_a_field_the_subspace_contains() {
    let basis = small_basis();
    let mut reference = coarse_reference();
    let map = DeformationMap::new(&basis, &reference.nodes).unwrap();
    let z: Vec<f64> = (0..map.layout().len())
        .map(|i| 1e-3 * ((i * 7919) % 13) as f64 / 13.0 - 5e-4)
        .collect();
    reference.displacements = map.displacements(&z);
    let (l2, energy) = projections(&basis, &reference).unwrap();
    for field in [l2, energy] {
        let (_, relative) = field_errors(&field, &reference.displacements);
        assert!(relative < 1e-7, "relative error {relative}");
    }
}

#[test]
fn the_l2_projection_has_the_smallest_mse_in_the_subspace() {
    let basis = small_basis();
    let reference = coarse_reference();
    let (l2, energy) = projections(&basis, &reference).unwrap();
    let (best, _) = field_errors(&l2, &reference.displacements);
    let (other, _) = field_errors(&energy, &reference.displacements);
    assert!(best > 0.0, "the FEM field is not in a 4-mode subspace");
    assert!(best <= other, "L2 {best:e} above energy {other:e}");
}

#[test]
fn the_energy_projection_keeps_the_held_nodes_in_place() {
    let basis = small_basis();
    let reference = coarse_reference();
    let (_, energy) = projections(&basis, &reference).unwrap();
    let largest = reference
        .displacements
        .iter()
        .map(|d| d.norm())
        .fold(0.0, f64::max);
    let held: Vec<usize> = (0..reference.nodes.len())
        .filter(|&i| reference.held[i])
        .collect();
    assert!(!held.is_empty(), "the Bend holds a region");
    let drift = held.iter().map(|&i| energy[i].norm()).fold(0.0, f64::max);
    assert!(
        drift <= 1e-2 * largest,
        "held nodes moved {drift:e} against the field's largest {largest:e}"
    );
}

#[test]
fn the_pool_check_compares_2m_eigenvalues_per_kernel_count_on_twice_the_points() {
    let config = super::ConvergenceConfig {
        modes: vec![4, 6],
        kernels: vec![80, 120],
        settings: ReducedSettings {
            basis_points: 1500,
            ..ReducedSettings::default()
        },
        ..super::ConvergenceConfig::quick(std::path::PathBuf::from("unused"))
    };
    let rows = super::pool_check::pool_checks(&config).unwrap();
    assert_eq!(rows.len(), 2);
    for (row, kernels) in rows.iter().zip([80, 120]) {
        assert_eq!(row.kernels, kernels);
        assert_eq!(row.eigenvalues, 12, "2 × the largest m");
        assert_eq!(row.check.eigenvalues.len(), 12);
        let ratio = row.check.finer_points as f64 / row.check.points as f64;
        assert!((1.6..2.4).contains(&ratio), "{ratio}");
        assert!(row.check.max_relative_change.is_finite() && row.check.max_relative_change > 0.0);
        assert_eq!(
            row.converged,
            row.check.max_relative_change <= super::POOL_TOLERANCE
        );
    }
}

/// A static row before it is measured.
fn blank_row(treatment: super::BoundaryTreatment) -> super::ConvergenceRow {
    super::ConvergenceRow {
        m: 6,
        kernels: 120,
        ..super::ConvergenceRow::unmeasured(
            super::ConvergenceTest::StaticBend,
            beam_material().poisson_ratio,
            treatment,
            super::VolumetricTerm::Pointwise,
        )
    }
}

#[test]
fn a_nitsche_held_static_bend_bends_like_the_weighted_basis_and_meets_its_clamp() {
    use super::BoundaryTreatment;
    let settings = ReducedSettings {
        modes: 6,
        kernels: 120,
        basis_points: 3000,
        simulation_points: 3000,
        pins: freeform::PinHold::WEIGHTED,
        ..ReducedSettings::default()
    };
    let config = super::ConvergenceConfig::quick(std::path::PathBuf::from("unused"));
    let scene = static_scene(1e-3);
    let reference = coarse_reference();
    let mut weighted = blank_row(BoundaryTreatment::Weighted);
    let basis = crate::beam_protocol::reduced::build_beam_basis_for(
        crate::beam_scenario::BeamTest::Bend,
        &settings,
    )
    .unwrap()
    .basis;
    super::study::static_row(
        &mut weighted,
        &basis,
        None,
        None,
        &settings,
        beam_material(),
        &scene,
        &reference,
        &config,
    )
    .unwrap();
    let nitsche_settings = BoundaryTreatment::Nitsche.settings(&settings).unwrap();
    let free_basis = super::nitsche_row::free_part_basis(
        crate::beam_scenario::BeamTest::Bend,
        &nitsche_settings,
        2.0,
    )
    .unwrap();
    let mut nitsche = blank_row(BoundaryTreatment::Nitsche);
    let held = super::nitsche_row::NitscheBeam {
        basis: &free_basis,
        pressure: None,
        settings: &nitsche_settings,
        material: beam_material(),
        factor: 2.0,
        cache_dir: std::path::Path::new("unused"),
    };
    super::nitsche_row::nitsche_static_row(&mut nitsche, &held, &scene, &reference).unwrap();
    // Both tips within a tenth of each other's deflection (the P1 res 2 reference is stiff,
    // so both ratios are positive), and the interface within 1% of the tip's deflection.
    let tip = |row: &super::ConvergenceRow| 1.0 + row.tip_ratio;
    assert!(
        (tip(&nitsche) / tip(&weighted) - 1.0).abs() < 0.1,
        "Nitsche tip {:+.3}, weighted {:+.3}",
        nitsche.tip_ratio,
        weighted.tip_ratio
    );
    let deflection = reference.displacements[reference.tip].norm() * tip(&nitsche);
    assert!(
        nitsche.held_drift < 0.01 * deflection,
        "interface gap {:e} m against a tip deflection of {deflection:e} m",
        nitsche.held_drift
    );
}
