//! Weighted bases (WEB): modes exactly 0 and region handles exactly 1 or 0 on the held
//! regions, weight gradients that match finite differences, the clamped bar's analytic
//! spectrum, and clear errors.

use hyperelastic::LameParameters;
use nalgebra::Vector3;
use rkpm_core::{IntegrationPoints, sample_box_grid};
use skin_eigen::{
    BasisError, BasisParams, HeldRegionShape, RegionError, RegionWeight, SkinningBasis,
    build_basis, build_basis_sharing, build_weighted_basis, build_weighted_basis_sharing,
};

/// A 2 × 0.5 × 0.5 m bar on a 0.05 m grid.
fn bar() -> (IntegrationPoints, Vec<LameParameters>) {
    let points = sample_box_grid(Vector3::zeros(), Vector3::new(2.0, 0.5, 0.5), 0.05).unwrap();
    let lame = LameParameters::from_young_poisson(1e6, 0.3).unwrap();
    let materials = vec![lame; points.len()];
    (points, materials)
}

/// `x ≤ 0.2` held.
fn clamp() -> HeldRegionShape {
    HeldRegionShape::HalfSpace {
        normal: Vector3::x(),
        offset: 0.2,
    }
}

/// `x ≥ 1.8` held.
fn far_end() -> HeldRegionShape {
    HeldRegionShape::HalfSpace {
        normal: -Vector3::x(),
        offset: -1.8,
    }
}

fn build(regions: Vec<HeldRegionShape>, modes: usize) -> SkinningBasis {
    let (points, materials) = bar();
    let weight = RegionWeight::new(regions, 0.5).unwrap();
    let params = BasisParams::default().with_kernels(250).with_modes(modes);
    let (basis, report, _) =
        build_weighted_basis(&points, &materials, &params, &weight, &[]).unwrap();
    let held = report.held_regions.unwrap();
    assert_eq!(held.max_mode_value_on_regions, 0.0);
    assert_eq!(held.max_region_weight_error, 0.0);
    assert!(report.orthonormality_error < 1e-9, "{report:?}");
    basis
}

#[test]
fn modes_vanish_and_region_handles_are_one_or_zero_on_the_held_regions() {
    let basis = build(vec![clamp(), far_end()], 6);
    assert_eq!(basis.handles(), 1 + 1 + 6);
    let on_clamp = Vector3::new(0.1, 0.3, 0.2);
    let on_end = Vector3::new(1.95, 0.1, 0.4);
    let middle = Vector3::new(1.0, 0.25, 0.25);
    let w = basis.evaluate(&[on_clamp, on_end, middle]).unwrap();
    for j in 2..8 {
        assert_eq!(w.weights[(0, j)], 0.0);
        assert_eq!(w.weights[(1, j)], 0.0);
        for g in &w.gradients {
            assert_eq!(g[(0, j)], 0.0);
        }
    }
    assert_eq!(w.weights[(0, 1)], 0.0);
    assert_eq!(w.weights[(1, 1)], 1.0);
    // The harmonic extension between the ends is close to the linear blend along the bar.
    assert!(
        (w.weights[(2, 1)] - 0.5).abs() < 0.05,
        "{}",
        w.weights[(2, 1)]
    );
    assert!(w.weights.column(2).iter().skip(2).any(|&v| v.abs() > 0.1));
}

#[test]
fn weighted_weight_gradients_match_finite_differences() {
    let basis = build(vec![clamp(), far_end()], 4);
    let points = [
        Vector3::new(0.23, 0.21, 0.33),
        Vector3::new(0.9, 0.4, 0.1),
        Vector3::new(1.7, 0.12, 0.27),
    ];
    let w = basis.evaluate(&points).unwrap();
    let h = 1e-6;
    for (p, x) in points.iter().enumerate() {
        for d in 0..3 {
            let mut e = Vector3::zeros();
            e[d] = h;
            let plus = basis.evaluate(&[x + e]).unwrap().weights;
            let minus = basis.evaluate(&[x - e]).unwrap().weights;
            for j in 0..basis.handles() {
                let fd = (plus[(0, j)] - minus[(0, j)]) / (2.0 * h);
                let analytic = w.gradients[d][(p, j)];
                assert!(
                    (fd - analytic).abs() < 1e-5 * (1.0 + analytic.abs()),
                    "point {p}, axis {d}, handle {j}: {analytic} vs {fd}"
                );
            }
        }
    }
}

#[test]
fn clamped_bar_eigenvalues_approach_the_mixed_dirichlet_neumann_spectrum() {
    // Dirichlet at x = 0.2, Neumann at x = 2: λ_n = ((2n − 1) π / (2 · 1.8))² (λ + 4μ), the
    // lowest two below the first transverse Neumann mode (π / 0.5)².
    let basis = build(vec![clamp()], 2);
    let lame = bar().1[0];
    for (n, &value) in basis.eigenvalues().iter().enumerate() {
        let exact = ((2 * n + 1) as f64 * std::f64::consts::PI / 3.6).powi(2);
        let relative = value / lame.weight_space_hessian_modulus() / exact - 1.0;
        assert!(relative.abs() < 0.03, "λ_{} off by {relative}", n + 1);
    }
}

#[test]
fn a_region_without_points_and_a_body_without_free_points_are_named() {
    let (points, materials) = bar();
    let params = BasisParams::default().with_kernels(100).with_modes(2);
    let outside = HeldRegionShape::Ball {
        center: Vector3::new(10.0, 0.0, 0.0),
        radius: 0.5,
    };
    let weight = RegionWeight::new(vec![clamp(), outside], 0.5).unwrap();
    assert!(matches!(
        build_weighted_basis(&points, &materials, &params, &weight, &[]),
        Err(BasisError::Regions(RegionError::EmptyRegion { region: 1 }))
    ));
    let everything = HeldRegionShape::HalfSpace {
        normal: Vector3::x(),
        offset: 5.0,
    };
    let weight = RegionWeight::new(vec![everything], 0.5).unwrap();
    assert!(matches!(
        build_weighted_basis(&points, &materials, &params, &weight, &[]),
        Err(BasisError::Regions(RegionError::NoFreePoints))
    ));
}

#[test]
fn a_non_finite_query_point_is_an_error_not_a_held_point() {
    let basis = build(vec![clamp()], 2);
    let error = basis
        .evaluate(&[
            Vector3::new(1.0, 0.2, 0.2),
            Vector3::new(f64::NAN, 0.0, 0.0),
        ])
        .unwrap_err();
    assert!(matches!(
        error,
        rkpm_core::ShapeFunctionError::NonFiniteQuery { point: 1 }
    ));
}

#[test]
fn weights_at_the_build_points_equal_a_fresh_evaluation_to_the_bit() {
    let (points, materials) = bar();
    let weight = RegionWeight::new(vec![clamp(), far_end()], 0.5).unwrap();
    let params = BasisParams::default().with_kernels(250).with_modes(4);
    // Evaluated at its own points later: the basis keeps its weights there.
    let (basis, _, _) =
        build_weighted_basis(&points, &materials, &params, &weight, &[points.positions()]).unwrap();
    assert!(basis.keeps_weights_at(points.positions()));
    assert!(!basis.keeps_weights_at(&points.positions()[1..]));
    assert!(!build(vec![clamp(), far_end()], 4).keeps_weights_at(points.positions()));
    // A saved and reloaded basis keeps no weights from its build: it evaluates afresh.
    let path = test_support::fixtures::scratch_dir("weighted_basis_build_points").join("bar.basis");
    basis.save(&path).unwrap();
    let fresh = SkinningBasis::load(&path).unwrap();
    assert!(!fresh.keeps_weights_at(points.positions()));
    assert_eq!(fresh, basis);
    let kept = basis.evaluate(points.positions()).unwrap();
    assert_eq!(kept, fresh.evaluate(points.positions()).unwrap());
    // Other points (here all but the first) are evaluated, and agree row by row.
    let others = basis.evaluate(&points.positions()[1..]).unwrap();
    for i in 1..points.len() {
        for j in 0..basis.handles() {
            assert_eq!(
                others.weights[(i - 1, j)],
                kept.weights[(i, j)],
                "({i}, {j})"
            );
            for d in 0..3 {
                assert_eq!(others.gradients[d][(i - 1, j)], kept.gradients[d][(i, j)]);
            }
        }
    }
}

#[test]
fn a_plain_basis_of_the_free_part_on_shared_shape_functions_equals_one_built_afresh() {
    let (points, materials) = bar();
    let weight = RegionWeight::new(vec![clamp()], 0.5).unwrap();
    let params = BasisParams::default().with_kernels(250).with_modes(4);
    let (_, _, _, shared) =
        build_weighted_basis_sharing(&points, &materials, &params, &weight, &[]).unwrap();
    let free: Vec<usize> = (0..points.len())
        .filter(|&i| weight.region_of(&points.positions()[i]).is_none())
        .collect();
    let free_points = IntegrationPoints::new(
        free.iter().map(|&i| points.positions()[i]).collect(),
        free.iter().map(|&i| points.volumes()[i]).collect(),
    )
    .unwrap();
    let free_materials: Vec<_> = free.iter().map(|&i| materials[i]).collect();
    let neumann = params.with_modes(6);
    assert!(shared.fit(free_points.positions(), &neumann));
    let (fresh, fresh_report, _) = build_basis(&free_points, &free_materials, &neumann).unwrap();
    let (reused, reused_report, _) =
        build_basis_sharing(&free_points, &free_materials, &neumann, Some(&shared)).unwrap();
    // Nothing placed or evaluated: the shared kernels and shape functions were used.
    assert_eq!(reused_report.timings.kernel_placement, 0.0);
    assert_eq!(reused_report.timings.shape_functions, 0.0);
    assert_eq!(reused, fresh);
    assert_eq!(reused.eigenvalues(), fresh.eigenvalues());
    assert_eq!(reused.coefficients(), fresh.coefficients());
    assert!(fresh_report.timings.kernel_placement > 0.0);
    // Other points or other kernel options do not fit: built afresh, and still a basis.
    let fewer_kernels = neumann.with_kernels(200);
    assert!(!shared.fit(free_points.positions(), &fewer_kernels));
    let (other, _, _) =
        build_basis_sharing(&free_points, &free_materials, &fewer_kernels, Some(&shared)).unwrap();
    assert_eq!(other.kernels().len(), 200);
    assert!(!shared.fit(&free_points.positions()[1..], &neumann));
}
