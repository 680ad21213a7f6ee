//! RKPM shape functions: the four reproducing conditions (DESIGN 3.3), gradients against
//! central differences, equivalence with the paper's unshifted Eqs. 7-11, singularity reports.

use nalgebra::Vector3;
use proptest::prelude::*;
use rkpm_core::{
    GridSamplingParams, IntegrationPoints, KernelParams, KernelWindow, Kernels, ShapeFunctionError,
    ShapeFunctionParams, ShapeFunctions, evaluate_shape_functions, place_kernels,
    read_triangle_mesh, sample_box_grid, sample_grid, shape_function_values_unshifted,
};
use test_support::fixtures::shared_mesh;

/// Largest violation of the four reproducing conditions (positions relative to `scale`).
fn reproducing_error(
    shape: &ShapeFunctions,
    kernels: &Kernels,
    queries: &[Vector3<f64>],
    scale: f64,
) -> f64 {
    shape.reproducing_errors(kernels, queries, scale).max()
}

/// Grid points in the box [0, sides] with the given spacing, and `count` kernels placed on them.
fn box_layout(sides: [f64; 3], spacing: f64, count: usize) -> (IntegrationPoints, Kernels) {
    let points = sample_box_grid(Vector3::zeros(), Vector3::from(sides), spacing).unwrap();
    let kernels = place_kernels(
        points.positions(),
        &KernelParams {
            count,
            ..Default::default()
        },
    )
    .unwrap();
    (points, kernels)
}

fn random_kernels(centers: Vec<[f64; 3]>, radius: f64) -> Kernels {
    let n = centers.len();
    Kernels::new(
        centers.into_iter().map(Vector3::from).collect(),
        vec![radius; n],
    )
    .unwrap()
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]

    /// Random kernel layouts in a box of side 2 around an offset origin (so the unshifted form
    /// would be poorly conditioned) and random query points inside them.
    #[test]
    fn reproducing_conditions_hold_for_random_layouts(
        centers in proptest::collection::vec(test_support::strategies::point_in_box(0.0, 2.0), 30..80),
        queries in proptest::collection::vec(test_support::strategies::point_in_box(0.3, 1.7), 1..20),
        radius in 0.6..1.5f64,
        offset in -100.0..100.0f64,
    ) {
        let shift = Vector3::repeat(offset);
        let kernels = random_kernels(centers.iter().map(|c| (Vector3::from(*c) + shift).into()).collect(), radius);
        let queries: Vec<Vector3<f64>> = queries.iter().map(|q| Vector3::from(*q) + shift).collect();
        match evaluate_shape_functions(&kernels, &queries, &ShapeFunctionParams::default()) {
            Ok(shape) => {
                let err = reproducing_error(&shape, &kernels, &queries, 2.0);
                prop_assert!(err < 1e-10, "reproducing error {err:e}");
            }
            // Sparse random layouts may leave a point without 4 non-coplanar kernels; that
            // must be reported, and the report must be true.
            Err(ShapeFunctionError::SingularMomentMatrix { kernels_in_reach, reciprocal_condition, .. }) => {
                prop_assert!(kernels_in_reach < 4 || reciprocal_condition < 1e-12);
            }
            Err(e) => prop_assert!(false, "unexpected error {e}"),
        }
    }
}

const WINDOWS: [KernelWindow; 2] = [KernelWindow::Gaussian, KernelWindow::CubicBSpline];

#[test]
fn reproducing_conditions_hold_on_the_beam_for_every_window() {
    let (points, kernels) = box_layout([5.0, 1.0, 1.0], 0.1, 400);
    for window in WINDOWS {
        let shape = evaluate_shape_functions(
            &kernels,
            points.positions(),
            &ShapeFunctionParams {
                window,
                ..Default::default()
            },
        )
        .unwrap();
        let err = reproducing_error(&shape, &kernels, points.positions(), 5.0);
        assert!(err < 1e-10, "{window:?}: beam reproducing error {err:e}");
    }
}

#[test]
fn the_spline_window_reaches_no_kernel_beyond_twice_its_radius() {
    let (points, kernels) = box_layout([2.0, 1.0, 1.0], 0.1, 150);
    let params = ShapeFunctionParams {
        window: KernelWindow::CubicBSpline,
        ..Default::default()
    };
    let shape = evaluate_shape_functions(&kernels, points.positions(), &params).unwrap();
    for (i, x) in points.positions().iter().enumerate() {
        for &k in shape.kernels(i) {
            let k = k as usize;
            assert!((x - kernels.centers()[k]).norm() < 2.0 * kernels.radii()[k]);
        }
    }
    let gaussian = evaluate_shape_functions(
        &kernels,
        points.positions(),
        &ShapeFunctionParams::default(),
    )
    .unwrap();
    assert!(shape.mean_kernels_per_point() < gaussian.mean_kernels_per_point());
}

#[test]
fn reproducing_conditions_hold_on_shared_meshes() {
    for name in ["bunny.obj", "37384.stl", "54725_sf.obj", "hand_closed.obj"] {
        let (mesh, _) = read_triangle_mesh(shared_mesh(name)).unwrap().normalized();
        let points = sample_grid(
            &mesh,
            &GridSamplingParams {
                target_points: 8000,
            },
        )
        .unwrap();
        let kernels = place_kernels(
            points.positions(),
            &KernelParams {
                count: 300,
                ..Default::default()
            },
        )
        .unwrap();
        let shape = evaluate_shape_functions(
            &kernels,
            points.positions(),
            &ShapeFunctionParams::default(),
        )
        .unwrap();
        let err = reproducing_error(&shape, &kernels, points.positions(), 1.0);
        assert!(err < 1e-10, "{name}: reproducing error {err:e}");
    }
}

#[test]
fn gradients_match_central_differences_for_every_window() {
    let (_, kernels) = box_layout([2.0, 1.0, 1.0], 0.1, 120);
    for window in WINDOWS {
        check_gradients(
            &kernels,
            &ShapeFunctionParams {
                cutoff: 6.0,
                window,
                ..Default::default()
            },
        );
    }
}

fn check_gradients(kernels: &Kernels, params: &ShapeFunctionParams) {
    let h = 1e-6;
    for q in [
        Vector3::new(0.31, 0.52, 0.47),
        Vector3::new(1.73, 0.11, 0.9),
        Vector3::new(0.05, 0.95, 0.02),
    ] {
        let at = |x: Vector3<f64>| evaluate_shape_functions(kernels, &[x], params).unwrap();
        let base = at(q);
        let mut probes = Vec::new();
        for d in 0..3 {
            let e = Vector3::ith(d, h);
            probes.push((at(q + e), at(q - e)));
        }
        // Central differences of ϕ_k per kernel (the support set is the same at q ± h here).
        let mut worst: f64 = 0.0;
        for (j, &k) in base.kernels(0).iter().enumerate() {
            let fd = Vector3::from_fn(|d, _| {
                let (plus, minus) = &probes[d];
                let value = |s: &ShapeFunctions| {
                    s.kernels(0)
                        .iter()
                        .position(|&kk| kk == k)
                        .map_or(0.0, |p| s.values(0)[p])
                };
                (value(plus) - value(minus)) / (2.0 * h)
            });
            let g = base.gradients(0)[j];
            worst = worst.max(
                (fd - g).norm()
                    / base
                        .gradients(0)
                        .iter()
                        .map(|g| g.norm())
                        .fold(0.0, f64::max),
            );
        }
        assert!(
            worst < 1e-6,
            "{:?}: gradient vs finite difference, relative error {worst:e} at {q:?}",
            params.window
        );
    }
}

#[test]
fn shifted_form_equals_the_papers_unshifted_form_for_every_window() {
    let (points, kernels) = box_layout([2.0, 1.0, 1.0], 0.1, 100);
    for window in WINDOWS {
        let shape = evaluate_shape_functions(
            &kernels,
            points.positions(),
            &ShapeFunctionParams {
                window,
                ..Default::default()
            },
        )
        .unwrap();
        let mut worst: f64 = 0.0;
        for i in (0..points.len()).step_by(37) {
            let unshifted = shape_function_values_unshifted(
                &points.positions()[i],
                &kernels,
                window,
                shape.kernels(i),
            )
            .unwrap();
            for (a, b) in shape.values(i).iter().zip(&unshifted) {
                worst = worst.max((a - b).abs());
            }
        }
        assert!(
            worst < 1e-9,
            "{window:?}: shifted vs unshifted: max difference {worst:e}"
        );
    }
}

#[test]
fn isolated_query_reports_singular_moment_matrix_with_the_point() {
    let (_, kernels) = box_layout([1.0, 1.0, 1.0], 0.1, 50);
    let queries = [Vector3::new(0.5, 0.5, 0.5), Vector3::new(50.0, 0.5, 0.5)];
    let err =
        evaluate_shape_functions(&kernels, &queries, &ShapeFunctionParams::default()).unwrap_err();
    assert!(
        matches!(
            err,
            ShapeFunctionError::SingularMomentMatrix {
                point: 1,
                kernels_in_reach: 0,
                ..
            }
        ),
        "{err}"
    );
}

#[test]
fn coplanar_kernels_are_reported_singular_not_nan() {
    // All centres on the plane z = 0: M(X) has rank 3 everywhere.
    let centers: Vec<[f64; 3]> = (0..25)
        .map(|i| [(i % 5) as f64 * 0.25, (i / 5) as f64 * 0.25, 0.0])
        .collect();
    let kernels = random_kernels(centers, 0.5);
    let err = evaluate_shape_functions(
        &kernels,
        &[Vector3::new(0.5, 0.5, 0.1)],
        &ShapeFunctionParams::default(),
    )
    .unwrap_err();
    assert!(
        matches!(
            err,
            ShapeFunctionError::SingularMomentMatrix { point: 0, .. }
        ),
        "{err}"
    );
}

/// The cutoff trades sparsity for fidelity to the (untruncated) Gaussian RKPM functions: the
/// difference from a nearly untruncated cutoff 6 falls fast as the cutoff grows, while the
/// number of kernels per point grows.
#[test]
fn cutoff_changes_values_by_the_truncated_tail_only() {
    let (points, kernels) = box_layout([2.0, 1.0, 1.0], 0.1, 150);
    let eval = |cutoff| {
        evaluate_shape_functions(
            &kernels,
            points.positions(),
            &ShapeFunctionParams {
                cutoff,
                ..Default::default()
            },
        )
        .unwrap()
    };
    let reference = eval(6.0);
    let mut previous_error = f64::INFINITY;
    let mut previous_density = 0.0;
    for cutoff in [2.0, 3.0, 4.0] {
        let shape = eval(cutoff);
        let mut worst: f64 = 0.0;
        for i in 0..points.len() {
            for (&k, &phi) in shape.kernels(i).iter().zip(shape.values(i)) {
                let j = reference.kernels(i).iter().position(|&kk| kk == k).unwrap();
                worst = worst.max((phi - reference.values(i)[j]).abs());
            }
        }
        println!(
            "cutoff {cutoff}: max |Δϕ| = {worst:.2e}, {:.1} kernels/point",
            shape.mean_kernels_per_point()
        );
        assert!(
            worst < previous_error,
            "error must fall as the cutoff grows"
        );
        assert!(shape.mean_kernels_per_point() > previous_density);
        previous_error = worst;
        previous_density = shape.mean_kernels_per_point();
    }
    assert!(previous_error < 1e-4, "cutoff 4 vs 6: {previous_error:e}");
}
