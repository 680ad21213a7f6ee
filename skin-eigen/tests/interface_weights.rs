//! Weights held weakly on an interface (`build_basis_with_interface`): the beam's spectrum with
//! one end Dirichlet against the analytic one, weights that vanish there, insensitivity to the
//! stabilization, a second interface's region handle against the linear harmonic weight, and
//! bad interfaces refused by name.

use std::f64::consts::PI;

use hyperelastic::LameParameters;
use nalgebra::Vector3;
use rkpm_core::sample_box_grid;
use skin_eigen::{
    BasisError, BasisParams, SkinningBasis, WeightInterface, build_basis_with_interface,
    build_basis_with_interfaces,
};

fn lame() -> LameParameters {
    LameParameters::from_young_poisson(5e6, 0.45).unwrap()
}

/// The face x = 0 of the 5 × 1 × 1 m beam, `n × n` midpoint samples, normal −x.
fn end_face(n: usize) -> WeightInterface {
    let h = 1.0 / n as f64;
    let samples: Vec<Vector3<f64>> = (0..n * n)
        .map(|k| Vector3::new(0.0, ((k % n) as f64 + 0.5) * h, ((k / n) as f64 + 0.5) * h))
        .collect();
    let count = samples.len();
    WeightInterface {
        samples,
        areas: vec![h * h; count],
        normals: vec![-Vector3::x(); count],
        material: lame(),
        stabilization_factor: 2.0,
    }
}

fn basis(interface: &WeightInterface, modes: usize) -> SkinningBasis {
    let points = sample_box_grid(Vector3::zeros(), Vector3::new(5.0, 1.0, 1.0), 0.1).unwrap();
    let materials = vec![lame(); points.len()];
    let params = BasisParams::default().with_modes(modes).with_kernels(250);
    build_basis_with_interface(&points, &materials, &params, interface)
        .unwrap()
        .0
}

/// `π²((i + ½)²/25 + j² + k²)`: −Δw = λw on the beam, w = 0 at x = 0, ∂_N w = 0 elsewhere.
fn analytic(count: usize) -> Vec<f64> {
    let mut values: Vec<f64> = (0..8)
        .flat_map(|i| (0..3).flat_map(move |j| (0..3).map(move |k| (i, j, k))))
        .map(|(i, j, k)| {
            let x = i as f64 + 0.5;
            PI * PI * (x * x / 25.0 + (j * j + k * k) as f64)
        })
        .collect();
    values.sort_by(f64::total_cmp);
    values.truncate(count);
    values
}

fn relative_errors(basis: &SkinningBasis) -> Vec<f64> {
    let kappa = lame().weight_space_hessian_modulus();
    basis
        .eigenvalues()
        .iter()
        .zip(analytic(basis.eigenvalues().len()))
        .map(|(l, a)| (l / kappa - a).abs() / a)
        .collect()
}

#[test]
fn weights_held_on_an_end_have_the_analytic_quarter_wave_spectrum() {
    let held = basis(&end_face(10), 6);
    let errors = relative_errors(&held);
    println!("relative eigenvalue errors {errors:?}");
    assert!(
        errors.iter().all(|e| *e < 0.02),
        "relative eigenvalue errors {errors:?}"
    );
}

#[test]
fn weights_held_on_an_end_vanish_there_and_the_constant_handle_stays() {
    let held = basis(&end_face(10), 3);
    let probe: Vec<Vector3<f64>> = (0..=50)
        .map(|i| Vector3::new(0.1 * i as f64, 0.45, 0.55))
        .collect();
    let w = held.evaluate(&probe).unwrap().weights;
    assert!((0..probe.len()).all(|i| w[(i, 0)] == 1.0));
    // The first mode is sin(πx/10): zero at the held end, largest at the free one.
    let largest = (0..probe.len())
        .map(|i| w[(i, 1)].abs())
        .fold(0.0, f64::max);
    assert!(
        w[(0, 1)].abs() < 0.03 * largest,
        "{} of {largest}",
        w[(0, 1)]
    );
    assert!(w[(50, 1)].abs() > 0.95 * largest);
}

#[test]
fn the_held_spectrum_hardly_depends_on_the_stabilization() {
    let two = basis(&end_face(10), 6);
    let ten = basis(
        &WeightInterface {
            stabilization_factor: 10.0,
            ..end_face(10)
        },
        6,
    );
    for (a, b) in two.eigenvalues().iter().zip(ten.eigenvalues()) {
        assert!((a - b).abs() < 0.01 * a, "{a} at s = 2, {b} at s = 10");
    }
}

#[test]
fn bad_interfaces_are_refused_by_name() {
    let points = sample_box_grid(Vector3::zeros(), Vector3::new(1.0, 1.0, 1.0), 0.2).unwrap();
    let materials = vec![lame(); points.len()];
    let params = BasisParams::default().with_modes(2).with_kernels(30);
    let refused = |interface: WeightInterface| {
        matches!(
            build_basis_with_interface(&points, &materials, &params, &interface),
            Err(BasisError::Interface(_))
        )
    };
    let face = end_face(2);
    assert!(refused(WeightInterface {
        samples: Vec::new(),
        areas: Vec::new(),
        normals: Vec::new(),
        ..face.clone()
    }));
    assert!(refused(WeightInterface {
        areas: vec![0.25; 3],
        ..face.clone()
    }));
    assert!(refused(WeightInterface {
        normals: vec![Vector3::new(-2.0, 0.0, 0.0); 4],
        ..face.clone()
    }));
    assert!(refused(WeightInterface {
        stabilization_factor: 0.0,
        ..face.clone()
    }));
    assert!(refused(WeightInterface {
        areas: vec![f64::NAN; 4],
        ..face
    }));
}

#[test]
fn a_second_interface_gets_a_region_handle_that_is_linear_between_the_two_ends() {
    // The harmonic weight that is 0 at x = 0 and 1 at x = 5 with free sides is x/5.
    let far_end = WeightInterface {
        samples: end_face(10)
            .samples
            .iter()
            .map(|x| Vector3::new(5.0, x.y, x.z))
            .collect(),
        normals: vec![Vector3::x(); 100],
        ..end_face(10)
    };
    let points = sample_box_grid(Vector3::zeros(), Vector3::new(5.0, 1.0, 1.0), 0.1).unwrap();
    let materials = vec![lame(); points.len()];
    let params = BasisParams::default().with_modes(4).with_kernels(250);
    let (basis, _, _) =
        build_basis_with_interfaces(&points, &materials, &params, &[end_face(10), far_end])
            .unwrap();
    assert_eq!(
        basis.handles(),
        1 + 1 + 4,
        "constant, one region handle, four modes"
    );
    let probe: Vec<Vector3<f64>> = (0..=50)
        .map(|i| Vector3::new(0.1 * i as f64, 0.45, 0.55))
        .collect();
    let w = basis.evaluate(&probe).unwrap().weights;
    let error = probe
        .iter()
        .enumerate()
        .map(|(i, x)| (w[(i, 1)] - x.x / 5.0).abs())
        .fold(0.0, f64::max);
    assert!(error < 0.02, "largest distance from x/5: {error}");
    // The modes vanish at both ends.
    let largest = (0..probe.len())
        .map(|i| w[(i, 2)].abs())
        .fold(0.0, f64::max);
    assert!(w[(0, 2)].abs() < 0.03 * largest && w[(50, 2)].abs() < 0.03 * largest);
}
