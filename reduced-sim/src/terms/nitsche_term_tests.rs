use std::sync::Arc;

use hyperelastic::{MaterialSample, StableNeoHookean};
use nalgebra::{DMatrix, Rotation3};

use super::*;
use crate::model::analytic_field::{AnalyticField, analytic_model, probe_z};
use crate::model::reduced_model::ReducedModel;
use crate::terms::scene_terms::term_point;
use crate::terms::term_check::{TermCheckParams, check_term};

/// The analytic model's material (E = 1 MPa, ν = 0.4).
fn lame() -> LameParameters {
    MaterialSample {
        youngs_modulus: 1e6,
        poisson_ratio: 0.4,
        density: 1000.0,
    }
    .lame_parameters()
    .unwrap()
}

/// Midpoint samples of the face `x = x_face` of the 2 × 1 × 1 m block, `n × n` of them, with
/// the outward normal `±x`.
fn face(x_face: f64, n: usize) -> (Vec<Vector3<f64>>, Vec<f64>, Vec<Vector3<f64>>) {
    let h = 1.0 / n as f64;
    let samples: Vec<Vector3<f64>> = (0..n * n)
        .map(|k| {
            Vector3::new(
                x_face,
                (k % n) as f64 * h + 0.5 * h,
                (k / n) as f64 * h + 0.5 * h,
            )
        })
        .collect();
    let normal = Vector3::new(if x_face > 1.0 { 1.0 } else { -1.0 }, 0.0, 0.0);
    let count = samples.len();
    (samples, vec![h * h; count], vec![normal; count])
}

fn interface(
    x_face: f64,
    target: PinTarget,
    factor: f64,
) -> (NitscheInterface<StableNeoHookean>, NitscheReport) {
    let (model, _) = analytic_model();
    let rest = model.elastic_hessian(
        &vec![0.0; model.deformation_map().layout().len()],
        Tangent::Exact,
    );
    let (samples, areas, normals) = face(x_face, 8);
    NitscheInterface::new(
        &AnalyticField,
        &samples,
        &areas,
        &normals,
        StableNeoHookean,
        lame(),
        target,
        rest.as_ref(),
        &NitscheParams {
            stabilization_factor: factor,
        },
    )
    .unwrap()
}

#[test]
fn nitsche_gradient_and_hessian_match_central_differences_with_a_moving_target() {
    let (model, _) = analytic_model();
    let turn = PinTarget::Moving(Arc::new(|x: &Vector3<f64>, t: f64| {
        Rotation3::from_axis_angle(&Vector3::x_axis(), 0.3 * t) * x
            + Vector3::new(0.01 * t, 0.0, 0.0)
    }));
    let (term, report) = interface(0.0, turn, 2.0);
    assert_eq!(report.samples, 64);
    assert!((report.area - 1.0).abs() < 1e-12);
    let z = probe_z(model.deformation_map().layout().len(), 0.02);
    for time in [0.0, 0.5] {
        let at = term_point(&model, &z, time);
        let check = check_term(&term, &at, &TermCheckParams::default()).unwrap();
        assert!(check.hessian_error < 1e-5, "{check:?}");
    }
}

#[test]
fn nitsche_tangents_other_than_exact_leave_out_only_the_term_proportional_to_the_gap() {
    let (model, _) = analytic_model();
    let (term, _) = interface(0.0, PinTarget::Rest, 2.0);
    let len = model.deformation_map().layout().len();
    let hessian_at = |z: &[f64], tangent| {
        let mut gradient = vec![0.0; len];
        let mut h = Mat::zeros(len, len);
        term.add_derivatives(
            &term_point(&model, z, 0.0),
            tangent,
            &mut gradient,
            Some(&mut h),
        );
        h
    };
    // At rest the gap is zero: every tangent is the exact Hessian.
    let rest = vec![0.0; len];
    let gap =
        (&hessian_at(&rest, Tangent::Exact) - &hessian_at(&rest, Tangent::ProjectedPsd)).norm_max();
    assert_eq!(gap, 0.0);
    // Away from the targets they differ.
    let z = probe_z(len, 0.02);
    let exact = hessian_at(&z, Tangent::Exact);
    let difference = (&exact - &hessian_at(&z, Tangent::ProjectedPsd)).norm_max();
    assert!(difference > 1e-6 * exact.norm_max(), "{difference}");
}

/// The stretch `F = diag(stretch, q, q)` of uniaxial stress: q with `P_yy = 0` (bisection).
fn uniaxial(stretch: f64) -> Matrix3<f64> {
    let p_yy = |q: f64| {
        StableNeoHookean.first_piola_kirchhoff(
            &lame(),
            &Matrix3::from_diagonal(&Vector3::new(stretch, q, q)),
        )[(1, 1)]
    };
    let (mut low, mut high) = (0.5, 1.5);
    for _ in 0..200 {
        let mid = 0.5 * (low + high);
        if p_yy(mid) > 0.0 {
            high = mid;
        } else {
            low = mid;
        }
    }
    Matrix3::from_diagonal(&Vector3::new(
        stretch,
        0.5 * (low + high),
        0.5 * (low + high),
    ))
}

/// The uniaxial stretch `F = uniaxial(1.05)` as the constant handle's affine map, z = F − I,
/// and the target F X.
fn stretch(model: &ReducedModel<StableNeoHookean>) -> (Vec<f64>, PinTarget) {
    let f = uniaxial(1.05);
    let n4 = model.deformation_map().layout().block_len();
    let mut z = vec![0.0; model.deformation_map().layout().len()];
    for r in 0..3 {
        for c in 0..3 {
            z[r * n4 + c] = f[(r, c)] - if r == c { 1.0 } else { 0.0 };
        }
    }
    (
        z,
        PinTarget::Moving(Arc::new(move |x: &Vector3<f64>, _| f * x)),
    )
}

/// Asserts that at the stretch z the elastic force on the constant handle's coordinates is
/// substantial and that `ends` balance it to 1e-9 of it.
fn assert_ends_balance_the_stretch(
    model: &ReducedModel<StableNeoHookean>,
    z: &[f64],
    ends: &[&NitscheInterface<StableNeoHookean>],
    tangent: Tangent,
) {
    let n4 = model.deformation_map().layout().block_len();
    let elastic = model.elastic_gradient(z);
    let mut total = elastic.clone();
    let at = term_point(model, z, 0.0);
    for end in ends {
        end.add_derivatives(&at, tangent, &mut total, None);
    }
    let constant_handle: Vec<usize> = (0..3)
        .flat_map(|r| (0..4).map(move |c| r * n4 + c))
        .collect();
    let largest = |g: &[f64]| {
        constant_handle
            .iter()
            .map(|&i| g[i].abs())
            .fold(0.0, f64::max)
    };
    assert!(
        largest(&elastic) > 1e3,
        "the stretch should load the ends: {}",
        largest(&elastic)
    );
    assert!(
        largest(&total) < 1e-9 * largest(&elastic),
        "residual {} against elastic {}",
        largest(&total),
        largest(&elastic)
    );
}

#[test]
fn nitsche_is_consistent_an_exact_stretch_held_at_both_ends_leaves_no_residual() {
    // Both ends held at the uniaxial stretch F X: the affine state z = F − I is the exact
    // solution (lateral faces traction free). On the constant handle's coordinates, which the
    // grid and the face samples integrate exactly, the elastic force and the two interfaces'
    // cancel; a penalty (zero force at zero gap) leaves the elastic force unbalanced.
    let (model, _) = analytic_model();
    let (z, stretched) = stretch(&model);
    let (left, _) = interface(0.0, stretched.clone(), 2.0);
    let (right, _) = interface(2.0, stretched, 2.0);
    assert_ends_balance_the_stretch(&model, &z, &[&left, &right], Tangent::Exact);
    assert!(left.max_gap(&z, 0.0) < 1e-12 && right.max_gap(&z, 0.0) < 1e-12);
}

/// The smallest eigenvalue of the rest elastic Hessian plus the interface's, relative to the
/// largest.
fn smallest_relative_eigenvalue(factor: f64) -> f64 {
    let (model, _) = analytic_model();
    let len = model.deformation_map().layout().len();
    let rest = vec![0.0; len];
    let mut h = model.elastic_hessian(&rest, Tangent::Exact);
    let (term, _) = interface(0.0, PinTarget::Rest, factor);
    let mut gradient = vec![0.0; len];
    term.add_derivatives(
        &term_point(&model, &rest, 0.0),
        Tangent::Exact,
        &mut gradient,
        Some(&mut h),
    );
    let dense = nalgebra::DMatrix::from_fn(len, len, |i, j| 0.5 * (h[(i, j)] + h[(j, i)]));
    let values = dense.symmetric_eigenvalues();
    values.min() / values.max()
}

#[test]
fn the_stabilization_from_the_trace_bound_makes_the_held_body_definite_and_a_small_one_does_not() {
    assert!(smallest_relative_eigenvalue(2.0) > 0.0);
    assert!(smallest_relative_eigenvalue(1.0) > 0.0);
    // Far below the bound the symmetric terms make the sum indefinite.
    assert!(smallest_relative_eigenvalue(0.01) < 0.0);
}

#[test]
fn nitsche_interfaces_reject_bad_samples_by_name() {
    let (model, _) = analytic_model();
    let rest = model.elastic_hessian(
        &vec![0.0; model.deformation_map().layout().len()],
        Tangent::Exact,
    );
    let build = |samples: &[Vector3<f64>], areas: &[f64], normals: &[Vector3<f64>], factor| {
        NitscheInterface::new(
            &AnalyticField,
            samples,
            areas,
            normals,
            StableNeoHookean,
            lame(),
            PinTarget::Rest,
            rest.as_ref(),
            &NitscheParams {
                stabilization_factor: factor,
            },
        )
        .map(|_| ())
    };
    let x = [Vector3::new(0.0, 0.5, 0.5)];
    let n = [Vector3::new(-1.0, 0.0, 0.0)];
    assert!(matches!(
        build(&[], &[], &[], 2.0),
        Err(NitscheError::NoSamples)
    ));
    assert!(matches!(
        build(&x, &[1.0, 1.0], &n, 2.0),
        Err(NitscheError::LengthMismatch { areas: 2, .. })
    ));
    assert!(matches!(
        build(&x, &[1.0], &[Vector3::new(-2.0, 0.0, 0.0)], 2.0),
        Err(NitscheError::BadSample { index: 0, .. })
    ));
    assert!(matches!(
        build(&x, &[f64::NAN], &n, 2.0),
        Err(NitscheError::BadSample { .. })
    ));
    assert!(matches!(
        build(&x, &[1.0], &n, 0.0),
        Err(NitscheError::Params(_))
    ));
    let nan = [Vector3::new(f64::NAN, 0.0, 0.0)];
    assert!(matches!(
        build(&nan, &[1.0], &n, 2.0),
        Err(NitscheError::Map(_))
    ));
}

/// The pressure functions `[1, x, y, z, x²]` at `x` (N × 5).
fn pressure_functions(x: &[Vector3<f64>]) -> DMatrix<f64> {
    DMatrix::from_fn(x.len(), 5, |i, b| match b {
        0 => 1.0,
        4 => x[i].x * x[i].x,
        _ => x[i][b - 1],
    })
}

/// The analytic model with a projected dilatation over [`pressure_functions`].
fn projected_model() -> ReducedModel<StableNeoHookean> {
    let (model, points) = analytic_model();
    model
        .with_projected_dilatation(
            pressure_functions(points.positions()),
            crate::ProjectedDilatationParams::default(),
        )
        .unwrap()
}

fn projected_interface(
    model: &ReducedModel<StableNeoHookean>,
    x_face: f64,
    target: PinTarget,
) -> NitscheInterface<StableNeoHookean> {
    let (samples, areas, normals) = face(x_face, 8);
    NitscheInterface::on_model(
        &AnalyticField,
        model,
        &samples,
        &areas,
        &normals,
        lame(),
        target,
        Some(&pressure_functions(&samples)),
        &NitscheParams::default(),
    )
    .unwrap()
    .0
}

#[test]
fn with_a_projected_pressure_the_gradient_matches_central_differences_of_the_energy() {
    let model = projected_model();
    let turn = PinTarget::Moving(Arc::new(|x: &Vector3<f64>, t: f64| {
        Rotation3::from_axis_angle(&Vector3::x_axis(), 0.3 * t) * x
    }));
    let term = projected_interface(&model, 0.0, turn);
    let z = probe_z(model.deformation_map().layout().len(), 0.02);
    let check = check_term(
        &term,
        &term_point(&model, &z, 0.5),
        &TermCheckParams::default(),
    )
    .unwrap();
    assert!(check.gradient_error < 1e-6, "{check:?}");
}

#[test]
fn with_a_projected_pressure_the_tangent_where_the_targets_are_met_is_the_exact_hessian() {
    // Targets where z puts the samples: the gap and the terms the tangent leaves out vanish,
    // so it must equal the Hessian by central differences of the gradient.
    let model = projected_model();
    let len = model.deformation_map().layout().len();
    let z = probe_z(len, 0.02);
    let (samples, _, _) = face(0.0, 8);
    let placed: Vec<(Vector3<f64>, Vector3<f64>)> = samples
        .iter()
        .copied()
        .zip(
            DeformationMap::new(&AnalyticField, &samples)
                .unwrap()
                .positions(&z),
        )
        .collect();
    let met = PinTarget::Moving(Arc::new(move |x: &Vector3<f64>, _| {
        placed
            .iter()
            .find(|(rest, _)| rest == x)
            .map_or(*x, |(_, at)| *at)
    }));
    let term = projected_interface(&model, 0.0, met);
    let at = term_point(&model, &z, 0.0);
    assert!(term.max_gap(&z, 0.0) < 1e-12);
    let hessian_with = |tangent| {
        let mut gradient = vec![0.0; len];
        let mut h = Mat::zeros(len, len);
        term.add_derivatives(&at, tangent, &mut gradient, Some(&mut h));
        h
    };
    let exact = hessian_with(Tangent::Exact);
    let tangent = hessian_with(Tangent::ProjectedPsd);
    let error = (&exact - &tangent).norm_max() / exact.norm_max();
    assert!(error < 1e-6, "relative difference {error:e}");
}

#[test]
fn with_a_projected_pressure_an_exact_stretch_held_at_both_ends_leaves_no_residual() {
    let model = projected_model();
    let (z, stretched) = stretch(&model);
    let left = projected_interface(&model, 0.0, stretched.clone());
    let right = projected_interface(&model, 2.0, stretched);
    assert_ends_balance_the_stretch(&model, &z, &[&left, &right], Tangent::ProjectedPsd);
}

#[test]
fn pressure_values_must_match_the_models_projection() {
    let model = projected_model();
    let (samples, areas, normals) = face(0.0, 2);
    let build = |values: Option<&DMatrix<f64>>| {
        NitscheInterface::on_model(
            &AnalyticField,
            &model,
            &samples,
            &areas,
            &normals,
            lame(),
            PinTarget::Rest,
            values,
            &NitscheParams::default(),
        )
        .map(|_| ())
    };
    assert!(matches!(
        build(None),
        Err(NitscheError::PressureValues { expected: 5, .. })
    ));
    let too_few = DMatrix::zeros(4, 3);
    assert!(matches!(
        build(Some(&too_few)),
        Err(NitscheError::PressureValues { functions: 3, .. })
    ));
    assert!(build(Some(&pressure_functions(&samples))).is_ok());
}
