//! The projected volumetric term: its gradient and exact Hessian against central differences,
//! also where the inversion barrier acts, the full pressure space giving back the pointwise
//! energy, the PSD tangent staying PSD, the inversion guard (and a step whose prediction it
//! refuses), and clear errors.

mod support;

use hyperelastic::{LinearElastic, MaterialSample, StableNeoHookean, Tangent};
use nalgebra::{DMatrix, Vector3};
use reduced_sim::{
    ProjectedDilatationError, ProjectedDilatationParams, ReducedModel, ReducedState, Scene,
    SimulationParams, Simulator,
};
use support::BEAM_MATERIAL;
use test_support::finite_difference::{gradient, jacobian, relative_error};

/// A 2 × 0.5 × 0.5 m box model (4 modes) and its pressure values: 1, the affine functions
/// and two smooth functions of x.
fn model() -> ReducedModel<StableNeoHookean> {
    model_of(&BEAM_MATERIAL)
}

/// [`model`] of `material`.
fn model_of(material: &MaterialSample) -> ReducedModel<StableNeoHookean> {
    let (basis, points) = support::box_basis(Vector3::new(2.0, 0.5, 0.5), 0.125, 80, 4, material);
    let model = support::uniform_model(&basis, &points, material);
    let pressure = DMatrix::from_fn(points.len(), 6, |i, b| {
        let x = points.positions()[i];
        match b {
            0 => 1.0,
            1..=3 => x[b - 1],
            4 => (std::f64::consts::PI * x.x / 2.0).cos(),
            _ => (std::f64::consts::PI * x.x).cos(),
        }
    });
    model
        .with_projected_dilatation(pressure, ProjectedDilatationParams::default())
        .unwrap()
}

/// A deformed configuration: rest plus a fixed moderate perturbation.
fn probe(len: usize) -> Vec<f64> {
    (0..len)
        .map(|i| 0.03 * ((i * 7 % 11) as f64 / 11.0 - 0.5))
        .collect()
}

/// The elastic gradient of `model` at `z` matches central differences of its energy (relative
/// error < 1e-6) and its exact Hessian those of its gradient (< 1e-5), with step `h`.
fn assert_derivatives_match_central_differences(
    model: &ReducedModel<StableNeoHookean>,
    z: &[f64],
    h: f64,
) {
    let g = model.elastic_gradient(z);
    let fd = gradient(|z| model.elastic_energy(z), z, h);
    let g = DMatrix::from_column_slice(g.len(), 1, &g);
    let fd = DMatrix::from_column_slice(fd.len(), 1, fd.as_slice());
    let gradient_error = relative_error(&g, &fd, 1e-8);
    assert!(gradient_error < 1e-6, "gradient vs FD: {gradient_error:e}");
    let hessian = model.elastic_hessian(z, Tangent::Exact);
    let hessian = DMatrix::from_fn(z.len(), z.len(), |i, j| hessian[(i, j)]);
    let fd_hessian = jacobian(|z| model.elastic_gradient(z), z, h);
    let hessian_error = relative_error(&hessian, &fd_hessian, 1e-8);
    assert!(hessian_error < 1e-5, "Hessian vs FD: {hessian_error:e}");
}

#[test]
fn the_projected_terms_gradient_and_exact_hessian_match_central_differences() {
    assert_derivatives_match_central_differences(&model(), &probe(12 * 5), 1e-6);
}

#[test]
fn a_pressure_function_per_point_gives_back_the_pointwise_energy() {
    let (basis, points) =
        support::box_basis(Vector3::new(2.0, 0.5, 0.5), 0.25, 30, 2, &BEAM_MATERIAL);
    let pointwise = support::uniform_model(&basis, &points, &BEAM_MATERIAL);
    let n = points.len();
    let projected = support::uniform_model(&basis, &points, &BEAM_MATERIAL)
        .with_projected_dilatation(
            DMatrix::identity(n, n),
            ProjectedDilatationParams::default(),
        )
        .unwrap();
    let z = probe(12 * 3);
    let (a, b) = (pointwise.elastic_energy(&z), projected.elastic_energy(&z));
    assert!((a - b).abs() <= 1e-10 * a.abs(), "{a} vs {b}");
    let (ga, gb) = (
        pointwise.elastic_gradient(&z),
        projected.elastic_gradient(&z),
    );
    let scale = ga.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    for (x, y) in ga.iter().zip(&gb) {
        assert!((x - y).abs() <= 1e-9 * scale, "{x} vs {y}");
    }
}

#[test]
fn a_constant_pressure_softens_the_rest_stiffness_and_the_projected_tangent_stays_psd() {
    let model = model();
    let (basis, points) =
        support::box_basis(Vector3::new(2.0, 0.5, 0.5), 0.125, 80, 4, &BEAM_MATERIAL);
    let pointwise = support::uniform_model(&basis, &points, &BEAM_MATERIAL);
    let rest = vec![0.0; 60];
    let soft = model.elastic_hessian(&rest, Tangent::Exact);
    let stiff = pointwise.elastic_hessian(&rest, Tangent::Exact);
    // The projection never adds volumetric stiffness: stiff − soft is PSD at rest.
    let difference = DMatrix::from_fn(60, 60, |i, j| stiff[(i, j)] - soft[(i, j)]);
    let smallest = difference.symmetric_eigenvalues().min();
    let scale = DMatrix::from_fn(60, 60, |i, j| stiff[(i, j)])
        .symmetric_eigenvalues()
        .max();
    assert!(smallest > -1e-10 * scale, "{smallest:e}");
    let projected = model.elastic_hessian(&probe(60), Tangent::ProjectedPsd);
    let projected = DMatrix::from_fn(60, 60, |i, j| projected[(i, j)]);
    assert!(projected.symmetric_eigenvalues().min() > -1e-9 * scale);
}

#[test]
fn the_gradient_and_exact_hessian_match_central_differences_where_the_inversion_barrier_acts() {
    let model = model();
    // Handle 0's affine part −0.6 I: F ≈ 0.4 I, J ≈ 0.064 < Ĵ = 0.1 at every point.
    let layout = reduced_sim::ReducedLayout::new(5);
    let mut z: Vec<f64> = probe(60).iter().map(|v| 0.02 * v).collect();
    for r in 0..3 {
        z[layout.index(0, r, r)] -= 0.6;
    }
    assert!(model.elastic_energy(&z).is_finite());
    assert_derivatives_match_central_differences(&model, &z, 1e-7);
}

#[test]
fn an_inverted_point_makes_the_energy_infinite() {
    let model = model();
    let mut z = vec![0.0; 60];
    // Handle 0's affine part −2 I: F = −I everywhere, J = −1.
    let layout = reduced_sim::ReducedLayout::new(5);
    for r in 0..3 {
        z[layout.index(0, r, r)] = -2.0;
    }
    assert_eq!(model.elastic_energy(&z), f64::INFINITY);
}

#[test]
fn bad_pressure_spaces_and_materials_are_named() {
    let (basis, points) =
        support::box_basis(Vector3::new(2.0, 0.5, 0.5), 0.25, 30, 2, &BEAM_MATERIAL);
    let n = points.len();
    let build = || support::uniform_model(&basis, &points, &BEAM_MATERIAL);
    assert!(matches!(
        build().with_projected_dilatation(
            DMatrix::from_element(n + 1, 1, 1.0),
            ProjectedDilatationParams::default()
        ),
        Err(ProjectedDilatationError::RowCount { .. })
    ));
    assert!(matches!(
        build().with_projected_dilatation(
            DMatrix::from_element(n, 2, 1.0),
            ProjectedDilatationParams::default()
        ),
        Err(ProjectedDilatationError::DependentFunctions { size: 2 })
    ));
    assert!(matches!(
        build().with_projected_dilatation(
            DMatrix::from_element(n, 1, f64::NAN),
            ProjectedDilatationParams::default()
        ),
        Err(ProjectedDilatationError::Empty)
    ));
    let linear = ReducedModel::new(&basis, &points, &vec![BEAM_MATERIAL; n], LinearElastic)
        .unwrap()
        .with_projected_dilatation(
            DMatrix::from_element(n, 1, 1.0),
            ProjectedDilatationParams::default(),
        );
    assert!(matches!(
        linear,
        Err(ProjectedDilatationError::NoVolumetricPart { .. })
    ));
}

#[test]
fn a_modulus_kept_pointwise_up_to_c_shear_moduli_gives_back_the_pointwise_energy_when_it_covers_lambda()
 {
    // ν = 0.45: λ = 9 μ. With c = 9 nothing is projected; with c = 4 part of it is.
    let (basis, points) =
        support::box_basis(Vector3::new(2.0, 0.5, 0.5), 0.25, 30, 2, &BEAM_MATERIAL);
    let n = points.len();
    let z = probe(12 * 3);
    let pointwise = support::uniform_model(&basis, &points, &BEAM_MATERIAL).elastic_energy(&z);
    let with = |c: f64| {
        support::uniform_model(&basis, &points, &BEAM_MATERIAL)
            .with_projected_dilatation(
                DMatrix::from_element(n, 1, 1.0),
                ProjectedDilatationParams {
                    retained_shear_multiple: c,
                },
            )
            .unwrap()
            .elastic_energy(&z)
    };
    assert!((with(9.0 + 1e-9) - pointwise).abs() <= 1e-12 * pointwise.abs());
    let (partial, full) = (with(4.0), with(0.0));
    assert!(
        full < partial && partial < pointwise,
        "{full} < {partial} < {pointwise}"
    );
    let negative = support::uniform_model(&basis, &points, &BEAM_MATERIAL)
        .with_projected_dilatation(
            DMatrix::from_element(n, 1, 1.0),
            ProjectedDilatationParams {
                retained_shear_multiple: -1.0,
            },
        );
    assert!(matches!(
        negative,
        Err(ProjectedDilatationError::RetainedMultiple { .. })
    ));
}

#[test]
fn a_step_whose_inertial_prediction_inverts_a_point_starts_where_the_energy_is_finite() {
    // Stiff enough that the implicit step stays well inside J > 0 (h²E / (ρ L²) = 200 on the
    // 0.5 m side): the step's solution is finite while its inertial prediction is not.
    let model = model_of(&MaterialSample {
        youngs_modulus: 5e8,
        ..BEAM_MATERIAL
    });
    let layout = reduced_sim::ReducedLayout::new(5);
    // Handle 0's affine part compressing at 101 /s: the prediction z + h ż has F = −0.01 I
    // everywhere, where the projected term's energy is +∞.
    let mut velocity = vec![0.0; 60];
    for r in 0..3 {
        velocity[layout.index(0, r, r)] = -101.0;
    }
    let scene = Scene {
        gravity: None,
        pins: Vec::new(),
        floor: None,
        held: Vec::new(),
        colliders: Vec::new(),
    };
    let mut simulator = Simulator::new(model, &scene, SimulationParams::default()).unwrap();
    simulator
        .set_state(ReducedState {
            z: vec![0.0; 60],
            velocity,
            time: 0.0,
        })
        .unwrap();
    let predicted = simulator.predicted_coordinates();
    assert_eq!(simulator.model().elastic_energy(&predicted), f64::INFINITY);
    let report = simulator
        .step()
        .expect("the step starts from a finite energy");
    assert!(report.converged(), "{report:?}");
    let z = &simulator.state().z;
    // Compressed, far from inverted: every point's J above 1/2, their mean below 1.
    let jacobians: Vec<f64> = simulator
        .model()
        .deformation_map()
        .deformation_gradients(z)
        .iter()
        .map(|f| f.determinant())
        .collect();
    assert!(jacobians.iter().all(|&j| j > 0.5), "{jacobians:?}");
    let mean = jacobians.iter().sum::<f64>() / jacobians.len() as f64;
    assert!(mean < 1.0, "mean J = {mean}");
}
