//! The Table 3 ablations: both losses' gradients against central differences, the Hessian loss
//! on the grid against the exact answer (the eigen subspace), and the training loop's contracts.

use baselines::{
    CoefficientLoss, CoefficientTrainingError, CoefficientTrainingParams, QuadratureBatch,
    TrainedCoefficients, TrainingPoints, random_handle_loss, sample_in_cells, train_coefficients,
    weight_hessian_loss,
};
use faer::Mat;
use hyperelastic::LameParameters;
use nalgebra::{DMatrix, DVector, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rkpm_core::{
    IntegrationPoints, KernelParams, Kernels, ShapeFunctionParams, evaluate_shape_functions,
    place_kernels, sample_box_grid,
};
use skin_eigen::{BasisParams, assemble_weight_space_matrices, build_basis};
use test_support::finite_difference;

/// A 1 × 0.6 × 0.4 box: distinct lowest Laplacian-like modes (x: 1, y: 2.8, x²: 4 in units of
/// π²), so the 2-mode eigen subspace is well separated.
fn box_grid() -> (IntegrationPoints, Vec<LameParameters>) {
    let grid = sample_box_grid(Vector3::zeros(), Vector3::new(1.0, 0.6, 0.4), 0.1).unwrap();
    let lame = vec![LameParameters::from_young_poisson(1e5, 0.3).unwrap(); grid.len()];
    (grid, lame)
}

/// 20 kernels placed on the grid as ours are.
fn twenty_kernels(grid: &IntegrationPoints) -> Kernels {
    place_kernels(
        grid.positions(),
        &KernelParams {
            count: 20,
            ..KernelParams::default()
        },
    )
    .unwrap()
}

fn small_params(loss: CoefficientLoss, points: TrainingPoints) -> CoefficientTrainingParams {
    CoefficientTrainingParams {
        modes: 2,
        kernels: KernelParams {
            count: 30,
            ..KernelParams::default()
        },
        steps: 40,
        points_per_step: 60,
        transforms_per_step: 3,
        ..CoefficientTrainingParams::new(loss, points)
    }
}

#[test]
fn random_handle_loss_gradient_matches_central_differences() {
    let (grid, lame) = box_grid();
    let kernels = twenty_kernels(&grid);
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let (positions, sources) = sample_in_cells(&grid, 15, &mut rng);
    let shape =
        evaluate_shape_functions(&kernels, &positions, &ShapeFunctionParams::default()).unwrap();
    let batch = QuadratureBatch {
        shape: &shape,
        rows: (0..15).collect(),
        positions,
        volumes: vec![0.24 / 15.0; 15],
        lame: sources.iter().map(|&i| lame[i]).collect(),
    };
    let m = 3;
    // Large handle transforms, so the Neo-Hookean half of the ramp is well away from linear.
    let transforms: Vec<Vec<[f64; 12]>> = (0..2)
        .map(|_| {
            (0..m)
                .map(|_| std::array::from_fn(|_| rng.random_range(-0.4..0.4)))
                .collect()
        })
        .collect();
    let c: Vec<f64> = (0..20 * m).map(|_| rng.random_range(-0.5..0.5)).collect();
    let params = CoefficientTrainingParams {
        ortho_weight: 3.0,
        ..CoefficientTrainingParams::new(CoefficientLoss::RandomHandles, TrainingPoints::Random)
    };
    let (_, analytic) = random_handle_loss(&c, m, &batch, &transforms, 0.6, &params);
    let numeric = finite_difference::gradient(
        |x| {
            random_handle_loss(x, m, &batch, &transforms, 0.6, &params)
                .0
                .total
        },
        &c,
        1e-6,
    );
    let error = finite_difference::relative_error(
        &DMatrix::from_column_slice(c.len(), 1, &analytic),
        &DMatrix::from_column_slice(c.len(), 1, numeric.as_slice()),
        1e-8,
    );
    assert!(error < 1e-6, "relative gradient error {error:e}");
}

#[test]
fn weight_hessian_loss_gradient_matches_central_differences() {
    let (grid, lame) = box_grid();
    let kernels = twenty_kernels(&grid);
    let shape =
        evaluate_shape_functions(&kernels, grid.positions(), &ShapeFunctionParams::default())
            .unwrap();
    let batch = QuadratureBatch {
        shape: &shape,
        rows: (0..grid.len()).collect(),
        positions: grid.positions().to_vec(),
        volumes: grid.volumes().to_vec(),
        lame: lame.clone(),
    };
    let m = 3;
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let c: Vec<f64> = (0..20 * m).map(|_| rng.random_range(-1.0..1.0)).collect();
    let scale = lame[0].weight_space_hessian_modulus();
    let loss = |x: &[f64]| {
        let (hc, mc) = batch.weight_forms(x, m);
        weight_hessian_loss(x, &hc, &mc, scale, 50.0)
    };
    let (_, analytic) = loss(&c);
    let numeric = finite_difference::gradient(|x| loss(x).0.total, &c, 1e-6);
    let error = finite_difference::relative_error(
        &DMatrix::from_column_slice(c.len(), 1, &analytic),
        &DMatrix::from_column_slice(c.len(), 1, numeric.as_slice()),
        1e-8,
    );
    assert!(error < 1e-6, "relative gradient error {error:e}");

    // The batch forms are the assembled matrices times c.
    let matrices = assemble_weight_space_matrices(&shape, grid.volumes(), &lame).unwrap();
    let cm = Mat::from_fn(20, m, |a, j| c[a * m + j]);
    let (hc, mc) = batch.weight_forms(&c, m);
    let dh = (&hc - &matrices.hessian * &cm).norm_max() / hc.norm_max();
    let dm = (&mc - &matrices.mass * &cm).norm_max() / mc.norm_max();
    assert!(dh < 1e-12 && dm < 1e-12, "{dh:e} {dm:e}");
}

#[test]
fn hessian_loss_on_the_grid_converges_to_the_eigen_subspace() {
    // The penalized objective's minimizers span the m lowest eigenvectors of H_w c = λ𝓜c.
    let (grid, lame) = box_grid();
    // A softer penalty than the default 1e6 so that Adam converges in a few thousand steps
    // (the minimizer's span does not depend on the weight).
    let params = CoefficientTrainingParams {
        steps: 6000,
        learning_rate: 1e-2,
        ortho_weight: 1e3,
        ..small_params(CoefficientLoss::WeightHessian, TrainingPoints::Grid)
    };
    let trained = train_coefficients(&grid, &lame, &params, |_, _| {}).unwrap();
    let (eigen, _, _) = build_basis(
        &grid,
        &lame,
        &BasisParams::default().with_modes(2).with_kernels(30),
    )
    .unwrap();
    let kernels = trained.basis.kernels();
    assert_eq!(kernels, eigen.kernels(), "the same kernels as ours");
    let shape =
        evaluate_shape_functions(kernels, grid.positions(), &ShapeFunctionParams::default())
            .unwrap();
    let mass = assemble_weight_space_matrices(&shape, grid.volumes(), &lame)
        .unwrap()
        .mass;
    let mass = DMatrix::from_fn(30, 30, |a, b| mass[(a, b)]);
    let (e, t) = (eigen.coefficients(), trained.basis.coefficients());
    // 𝓜-orthogonal projection of the trained columns onto the eigen span (eᵀ𝓜e = I).
    let projected = e * (e.transpose() * &mass * t);
    let residual = t - &projected;
    for j in 0..2 {
        let norm = |v: DVector<f64>| (v.transpose() * &mass * &v)[(0, 0)].sqrt();
        let outside = norm(residual.column(j).into()) / norm(t.column(j).into());
        assert!(
            outside < 1e-2,
            "column {j}: {outside:e} of its 𝓜-norm outside the eigen span"
        );
    }
    // The Ritz values are the two eigenvalues (the constant mode dropped).
    let (q, lambda) = (trained.basis.eigenvalues(), eigen.eigenvalues());
    for (a, b) in q.iter().zip(lambda) {
        assert!((a - b).abs() < 1e-4 * b, "{q:?} vs {lambda:?}");
    }
}

#[test]
fn short_training_lowers_the_loss_and_is_deterministic_for_every_variant() {
    let (grid, lame) = box_grid();
    for loss in [
        CoefficientLoss::RandomHandles,
        CoefficientLoss::WeightHessian,
    ] {
        for points in [TrainingPoints::Random, TrainingPoints::Grid] {
            let params = small_params(loss, points);
            let a = train_coefficients(&grid, &lame, &params, |_, _| {}).unwrap();
            assert!(
                a.report.last.total < a.report.first.total,
                "{}: {:?} → {:?}",
                params.label(),
                a.report.first,
                a.report.last
            );
            let b = train_coefficients(&grid, &lame, &params, |_, _| {}).unwrap();
            assert_eq!(
                a.basis.coefficients(),
                b.basis.coefficients(),
                "{}",
                params.label()
            );
            assert_eq!(a.basis.modes(), 2);
            assert!(a.basis.eigenvalues().windows(2).all(|w| w[0] <= w[1]));
        }
    }
}

#[test]
fn random_training_points_fill_the_solid_uniformly() {
    let (grid, _) = box_grid();
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    let (points, sources) = sample_in_cells(&grid, 20_000, &mut rng);
    assert!(sources.iter().all(|&i| i < grid.len()));
    let size = Vector3::new(1.0, 0.6, 0.4);
    assert!(
        points
            .iter()
            .all(|p| (0..3).all(|d| p[d] >= -1e-12 && p[d] <= size[d] + 1e-12))
    );
    // Points off the grid (not cell centres), and each half of the box along x holds half.
    assert!(points.iter().all(|p| !grid.positions().contains(p)));
    let left = points.iter().filter(|p| p.x < 0.5).count() as f64 / 20_000.0;
    assert!((left - 0.5).abs() < 0.02, "{left}");
    let mean = points.iter().sum::<Vector3<f64>>() / 20_000.0;
    assert!((mean - size / 2.0).norm() < 0.01, "{mean:?}");
}

#[test]
fn saved_coefficients_reload_identically() {
    let (grid, lame) = box_grid();
    let params = small_params(CoefficientLoss::WeightHessian, TrainingPoints::Random);
    let trained = train_coefficients(&grid, &lame, &params, |_, _| {}).unwrap();
    let path = test_support::fixtures::scratch_dir("coefficients").join("c.model");
    trained.save(&path).unwrap();
    let loaded = TrainedCoefficients::load(&path).unwrap();
    assert_eq!(loaded.basis.coefficients(), trained.basis.coefficients());
    assert_eq!(loaded.basis.kernels(), trained.basis.kernels());
    assert_eq!(loaded.basis.eigenvalues(), trained.basis.eigenvalues());
    assert_eq!(
        (loaded.params, loaded.report),
        (trained.params, trained.report)
    );
}

#[test]
fn impossible_requests_are_named_errors() {
    let (grid, lame) = box_grid();
    let too_many_modes = CoefficientTrainingParams {
        modes: 30,
        ..small_params(CoefficientLoss::WeightHessian, TrainingPoints::Grid)
    };
    let error = train_coefficients(&grid, &lame, &too_many_modes, |_, _| {}).unwrap_err();
    assert!(
        matches!(error, CoefficientTrainingError::Invalid(ref s) if s.contains("m = 30")),
        "{error}"
    );
    let no_steps = CoefficientTrainingParams {
        steps: 0,
        ..small_params(CoefficientLoss::RandomHandles, TrainingPoints::Grid)
    };
    assert!(train_coefficients(&grid, &lame, &no_steps, |_, _| {}).is_err());
    let mismatched = train_coefficients(&grid, &lame[1..], &no_steps, |_, _| {}).unwrap_err();
    assert!(
        mismatched.to_string().contains("material entries"),
        "{mismatched}"
    );
}
