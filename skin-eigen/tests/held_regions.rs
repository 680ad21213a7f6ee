//! Bases with exactly held regions: region weights 1 on their region and 0 on the
//! others, summing to one everywhere; modes that vanish on the regions; clear errors.

use hyperelastic::LameParameters;
use nalgebra::Vector3;
use rkpm_core::{IntegrationPoints, evaluate_shape_functions, place_kernels, sample_box_grid};
use skin_eigen::{
    AssembledMatrices, BasisError, BasisParams, EigenParams, RegionConstraintParams, RegionError,
    assemble_weight_space_matrices, build_basis_with_regions, solve_constrained_modes,
};

fn bar() -> (IntegrationPoints, Vec<LameParameters>) {
    let points = sample_box_grid(Vector3::zeros(), Vector3::new(5.0, 1.0, 1.0), 0.125).unwrap();
    let lame = LameParameters::from_young_poisson(5e6, 0.45).unwrap();
    let materials = vec![lame; points.len()];
    (points, materials)
}

/// The points with x < 0.5 and those with x > 4.5: the two ends of the bar.
fn ends(points: &IntegrationPoints) -> Vec<Vec<usize>> {
    let select = |keep: &dyn Fn(f64) -> bool| -> Vec<usize> {
        (0..points.len())
            .filter(|&i| keep(points.positions()[i].x))
            .collect()
    };
    vec![select(&|x| x < 0.5), select(&|x| x > 4.5)]
}

/// The rest positions of the points `regions` index.
fn at(points: &IntegrationPoints, regions: &[Vec<usize>]) -> Vec<Vec<Vector3<f64>>> {
    regions
        .iter()
        .map(|r| r.iter().map(|&i| points.positions()[i]).collect())
        .collect()
}

fn params() -> BasisParams {
    BasisParams::default().with_kernels(200).with_modes(6)
}

#[test]
fn region_weights_are_one_on_their_region_zero_on_the_others_and_sum_to_one() {
    let (points, materials) = bar();
    let regions = ends(&points);
    let params = params();
    let kernels = place_kernels(points.positions(), &params.kernels).unwrap();
    let shape =
        evaluate_shape_functions(&kernels, points.positions(), &params.shape_functions).unwrap();
    let matrices = assemble_weight_space_matrices(&shape, points.volumes(), &materials).unwrap();
    let modes = solve_constrained_modes(
        &matrices,
        &kernels,
        &params.shape_functions,
        &at(&points, &regions),
        &EigenParams {
            modes: 6,
            ..EigenParams::default()
        },
        &RegionConstraintParams::default(),
    )
    .unwrap();
    let a = &modes.region_coefficients;
    let weight = |i: usize, r: usize| -> f64 {
        shape
            .kernels(i)
            .iter()
            .zip(shape.values(i))
            .map(|(&k, &phi)| phi * a[(k as usize, r)])
            .sum()
    };
    let mut worst_region = 0.0_f64;
    for r in 0..regions.len() {
        for (s, other) in regions.iter().enumerate() {
            for &i in other {
                let expected = f64::from(r == s);
                worst_region = worst_region.max((weight(i, r) - expected).abs());
            }
        }
    }
    assert!(
        worst_region < 1e-6,
        "region weights off by {worst_region:e}"
    );
    let worst_sum = (0..points.len())
        .map(|i| (weight(i, 0) + weight(i, 1) - 1.0).abs())
        .fold(0.0, f64::max);
    assert!(
        worst_sum < 1e-6,
        "region weights sum to one within {worst_sum:e} only"
    );
    // Between the ends the weights are a smooth ramp, not 0/1 everywhere.
    let middle = (0..points.len())
        .filter(|&i| (points.positions()[i].x - 2.5).abs() < 0.1)
        .map(|i| weight(i, 1))
        .fold(f64::NAN, f64::max);
    assert!(
        (0.2..0.8).contains(&middle),
        "region 1's weight in the middle of the bar is {middle}"
    );
    assert!(
        modes.max_mode_value_on_regions < 1e-6,
        "modes reach {:e} on the regions",
        modes.max_mode_value_on_regions
    );
    assert!(modes.orthonormality_error < 1e-9);
    assert!(modes.eigenvalues.windows(2).all(|w| w[0] <= w[1]));
    assert!(
        modes.eigenvalues[0] > 0.0,
        "a held bar has no free mode of zero energy"
    );
}

#[test]
fn a_basis_with_held_regions_evaluates_constant_region_weights_then_vanishing_modes() {
    let (points, materials) = bar();
    let regions = ends(&points);
    let (basis, report, matrices) = build_basis_with_regions(
        &points,
        &materials,
        &params(),
        &at(&points, &regions),
        &RegionConstraintParams::default(),
        &[],
    )
    .unwrap();
    assert!(matches!(matrices, AssembledMatrices::Dense(_)));
    assert_eq!(basis.held_regions(), 2);
    assert_eq!(basis.handles(), 1 + 1 + 6);
    let held = report.held_regions.expect("a held-regions report");
    assert_eq!(held.regions, 2);
    let w = basis.evaluate(points.positions()).unwrap().weights;
    for (r, region) in regions.iter().enumerate() {
        for &i in region {
            assert_eq!(w[(i, 0)], 1.0);
            assert!((w[(i, 1)] - r as f64).abs() < 1e-6, "w_1 = {}", w[(i, 1)]);
            for j in 2..basis.handles() {
                assert!(
                    w[(i, j)].abs() < 1e-6,
                    "mode {j} is {} on region {r}",
                    w[(i, j)]
                );
            }
        }
    }
    let dir = test_support::fixtures::scratch_dir("held_regions_basis");
    let path = dir.join("held.ffbasis");
    basis.save(&path).unwrap();
    let loaded = skin_eigen::SkinningBasis::load(&path).unwrap();
    assert_eq!(loaded, basis);
}

#[test]
fn bad_regions_are_named() {
    let (points, materials) = bar();
    let run = |regions: &[Vec<usize>]| {
        build_basis_with_regions(
            &points,
            &materials,
            &params(),
            &at(&points, regions),
            &RegionConstraintParams::default(),
            &[],
        )
        .err()
    };
    assert!(matches!(
        run(&[]),
        Some(BasisError::Regions(RegionError::NoRegions))
    ));
    assert!(matches!(
        run(&[vec![0], vec![]]),
        Some(BasisError::Regions(RegionError::EmptyRegion { region: 1 }))
    ));
    let far = build_basis_with_regions(
        &points,
        &materials,
        &params(),
        &[vec![Vector3::new(50.0, 0.0, 0.0)]],
        &RegionConstraintParams::default(),
        &[],
    );
    assert!(matches!(
        far,
        Err(BasisError::Regions(RegionError::ShapeFunctions(_)))
    ));
    assert!(matches!(
        run(&[vec![0, 1], vec![1]]),
        Some(BasisError::Regions(RegionError::NotSeparable { .. }))
    ));
    // Two slabs that touch cannot carry weights 1 and 0 across one point spacing.
    let slab = |lo: f64, hi: f64| -> Vec<usize> {
        (0..points.len())
            .filter(|&i| (lo..hi).contains(&points.positions()[i].x))
            .collect()
    };
    let adjacent = [slab(0.0, 0.5), slab(0.5, 1.0)];
    assert!(matches!(
        run(&adjacent),
        Some(BasisError::Regions(RegionError::NotSeparable { .. }))
    ));
}
