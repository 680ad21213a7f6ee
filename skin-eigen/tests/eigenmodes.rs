//! Skinning eigenmodes: matrix properties, eigen accuracy, convergence to the analytic box
//! spectrum, the cos(πx/5) first mode, material awareness, and save/load.

use std::f64::consts::PI;

use faer::{Mat, Side};
use hyperelastic::LameParameters;
use nalgebra::Vector3;
use rkpm_core::{IntegrationPoints, sample_box_grid};
use skin_eigen::{
    AssembledMatrices, BasisFileError, BasisParams, BasisStage, EigenSolverChoice, SkinningBasis,
    SubspaceParams, WeightSpaceMatrices, assemble_weight_space_matrices, build_basis,
    build_basis_observed,
};

const BEAM: [f64; 3] = [5.0, 1.0, 1.0];

fn beam_points(spacing: f64) -> IntegrationPoints {
    sample_box_grid(Vector3::zeros(), Vector3::from(BEAM), spacing).unwrap()
}

fn lame() -> LameParameters {
    LameParameters::from_young_poisson(5e6, 0.45).unwrap()
}

fn params(kernels: usize, modes: usize) -> BasisParams {
    BasisParams::default()
        .with_modes(modes)
        .with_kernels(kernels)
}

fn beam_basis(
    spacing: f64,
    kernels: usize,
    modes: usize,
) -> (SkinningBasis, WeightSpaceMatrices, IntegrationPoints) {
    let points = beam_points(spacing);
    let materials = vec![lame(); points.len()];
    let (basis, _, matrices) = build_basis(&points, &materials, &params(kernels, modes)).unwrap();
    let AssembledMatrices::Dense(matrices) = matrices else {
        panic!("small K is solved densely")
    };
    (basis, matrices, points)
}

fn to_faer(m: &nalgebra::DMatrix<f64>) -> Mat<f64> {
    Mat::from_fn(m.nrows(), m.ncols(), |i, j| m[(i, j)])
}

fn analytic_beam(count: usize) -> Vec<f64> {
    let mut v: Vec<f64> = (0..10)
        .flat_map(|i| (0..4).flat_map(move |j| (0..4).map(move |k| (i, j, k))))
        .map(|(i, j, k)| PI * PI * ((i * i) as f64 / 25.0 + (j * j + k * k) as f64))
        .filter(|&v| v > 0.0)
        .collect();
    v.sort_by(f64::total_cmp);
    v.truncate(count);
    v
}

#[test]
fn mass_is_spd_and_hessian_is_psd_with_constants_in_its_null_space() {
    let (_, m, _) = beam_basis(0.1, 150, 4);
    let k = m.mass.nrows();
    let mass_eigs = m.mass.self_adjoint_eigenvalues(Side::Lower).unwrap();
    assert!(
        mass_eigs[0] > 0.0,
        "𝓜 not positive definite: λ_min = {}",
        mass_eigs[0]
    );
    let hess_eigs = m.hessian.self_adjoint_eigenvalues(Side::Lower).unwrap();
    assert!(
        hess_eigs[0] > -1e-10 * hess_eigs[k - 1],
        "H_w not PSD: λ_min = {}",
        hess_eigs[0]
    );
    for i in 0..k {
        for j in 0..k {
            assert_eq!(m.mass[(i, j)], m.mass[(j, i)]);
            assert_eq!(m.hessian[(i, j)], m.hessian[(j, i)]);
        }
    }
    // Σ_l (H_w)_kl = Σ_i v_i (λ+4μ) ∇ϕ_k · Σ_l ∇ϕ_l = 0 by the reproducing condition Σ∇ϕ = 0.
    let ones = Mat::<f64>::from_fn(k, 1, |_, _| 1.0);
    let h1 = &m.hessian * &ones;
    let max_entry = (0..k).map(|i| m.hessian[(i, i)].abs()).fold(0.0, f64::max);
    assert!(
        (0..k).all(|i| h1[(i, 0)].abs() < 1e-10 * max_entry),
        "constants are not in the null space of H_w"
    );
}

#[test]
fn eigenpairs_have_small_residual_and_are_mass_orthonormal() {
    let (basis, m, _) = beam_basis(0.1, 200, 12);
    let c = to_faer(basis.coefficients());
    let hc = &m.hessian * &c;
    let mc = &m.mass * &c;
    let mut residual = 0.0f64;
    for (j, &lambda) in basis.eigenvalues().iter().enumerate() {
        let r: f64 = (0..c.nrows())
            .map(|i| (hc[(i, j)] - lambda * mc[(i, j)]).powi(2))
            .sum::<f64>()
            .sqrt();
        residual = residual.max(r / (m.hessian.norm_l2() * c.col(j).norm_l2()));
    }
    assert!(residual < 1e-10, "eigen residual {residual:e}");
    let gram = c.transpose() * &mc;
    let mut worst = 0.0f64;
    for i in 0..gram.nrows() {
        for j in 0..gram.ncols() {
            worst = worst.max((gram[(i, j)] - if i == j { 1.0 } else { 0.0 }).abs());
        }
    }
    assert!(worst < 1e-10, "cᵀ𝓜c - I = {worst:e}");
    assert!(basis.eigenvalues().windows(2).all(|w| w[0] <= w[1]));
    assert!(basis.metadata().constant_eigenvalue.abs() < 1e-8 * basis.eigenvalues()[0]);
}

/// Eigenvalues of H_w/(λ+4μ) approach π²(i²/25 + j² + k²) as K and the integration density
/// grow.
#[test]
fn box_eigenvalues_approach_the_analytic_spectrum_under_refinement() {
    let expected = analytic_beam(6);
    let mut previous = f64::INFINITY;
    for (spacing, kernels) in [(0.125, 100), (0.1, 250), (0.08, 600)] {
        let (basis, _, _) = beam_basis(spacing, kernels, 6);
        let err = basis
            .eigenvalues()
            .iter()
            .zip(&expected)
            .map(|(l, a)| (l / lame().weight_space_hessian_modulus() - a).abs() / a)
            .fold(0.0, f64::max);
        println!("h = {spacing}, K = {kernels}: max relative eigenvalue error {err:.3e}");
        assert!(
            err < previous,
            "error did not decrease: {err} after {previous}"
        );
        previous = err;
    }
    assert!(previous < 0.02, "finest error {previous}");
}

#[test]
fn first_beam_mode_is_cos_pi_x_over_5() {
    let (basis, _, points) = beam_basis(0.1, 250, 3);
    let w = basis.evaluate(points.positions()).unwrap().weights;
    let (mut dot, mut nw, mut nc) = (0.0, 0.0, 0.0);
    for (i, x) in points.positions().iter().enumerate() {
        let (a, b, v) = (w[(i, 1)], (PI * x.x / 5.0).cos(), points.volumes()[i]);
        dot += v * a * b;
        nw += v * a * a;
        nc += v * b * b;
    }
    let correlation = (dot / (nw * nc).sqrt()).abs();
    assert!(
        correlation > 0.99,
        "correlation with cos(πx/5) = {correlation}"
    );
    // The constant handle comes first and is exactly 1.
    assert!((0..w.nrows()).all(|i| w[(i, 0)] == 1.0));
}

/// A bar whose half x > 2.5 is 100× stiffer: the low modes deform (have weight gradients)
/// mostly in the soft half (Sec. 3.2, material-aware modes).
#[test]
fn low_modes_of_a_half_stiff_bar_deform_the_soft_half() {
    let points = beam_points(0.1);
    let soft = lame();
    let materials: Vec<LameParameters> = points
        .positions()
        .iter()
        .map(|x| if x.x > 2.5 { soft.scaled(100.0) } else { soft })
        .collect();
    let (basis, _, _) = build_basis(&points, &materials, &params(250, 3)).unwrap();
    let g = basis.evaluate(points.positions()).unwrap().gradients;
    for mode in 1..=3 {
        let (mut soft_energy, mut total) = (0.0, 0.0);
        for (i, x) in points.positions().iter().enumerate() {
            let e = points.volumes()[i] * (0..3).map(|d| g[d][(i, mode)].powi(2)).sum::<f64>();
            total += e;
            if x.x < 2.5 {
                soft_energy += e;
            }
        }
        assert!(
            soft_energy / total > 0.9,
            "mode {mode}: only {:.1}% of |∇W|² in the soft half",
            100.0 * soft_energy / total
        );
    }
}

#[test]
fn saved_basis_reloads_with_identical_weights_and_rejects_other_versions() {
    let (basis, _, points) = beam_basis(0.125, 100, 4);
    let dir = test_support::fixtures::scratch_dir("skin_eigen_save_load");
    let path = dir.join("beam.basis");
    basis.save(&path).unwrap();
    let loaded = SkinningBasis::load(&path).unwrap();
    assert_eq!(loaded, basis);
    // The built basis returns the weights it kept at its points; the loaded one evaluates.
    assert!(basis.keeps_weights_at(points.positions()));
    assert!(!loaded.keeps_weights_at(points.positions()));
    assert_eq!(
        loaded.evaluate(points.positions()).unwrap(),
        basis.evaluate(points.positions()).unwrap()
    );

    let mut bytes = std::fs::read(&path).unwrap();
    bytes[8] = 99;
    std::fs::write(&path, &bytes).unwrap();
    assert!(matches!(
        SkinningBasis::load(&path),
        Err(BasisFileError::IncompatibleVersion { found: 99, .. })
    ));
    std::fs::write(&path, b"not a basis").unwrap();
    assert!(matches!(
        SkinningBasis::load(&path),
        Err(BasisFileError::NotABasisFile { .. })
    ));
    let mut truncated = std::fs::read(dir.join("beam.basis")).unwrap_or_default();
    truncated.clear();
    truncated.extend(b"FFBASIS\0");
    truncated.extend(skin_eigen::BASIS_FORMAT_VERSION.to_le_bytes());
    truncated.extend([1, 2, 3]);
    std::fs::write(&path, &truncated).unwrap();
    assert!(matches!(
        SkinningBasis::load(&path),
        Err(BasisFileError::Corrupt { .. })
    ));
}

#[test]
fn a_quadratic_reproduction_basis_reloads_with_its_reproduction_and_weights() {
    let points = beam_points(0.125);
    let materials = vec![lame(); points.len()];
    let mut quadratic = params(100, 4);
    quadratic.shape_functions.reproduction = rkpm_core::Reproduction::Quadratic;
    let (basis, _, _) = build_basis(&points, &materials, &quadratic).unwrap();
    let path = test_support::fixtures::scratch_dir("skin_eigen_quadratic").join("beam.basis");
    basis.save(&path).unwrap();
    let loaded = SkinningBasis::load(&path).unwrap();
    assert_eq!(loaded, basis);
    assert_eq!(
        loaded.evaluate(points.positions()).unwrap(),
        basis.evaluate(points.positions()).unwrap()
    );
    // The linear basis on the same points and kernels has other weights.
    let (linear, _, _) = build_basis(&points, &materials, &params(100, 4)).unwrap();
    assert_ne!(
        linear.evaluate(points.positions()).unwrap(),
        loaded.evaluate(points.positions()).unwrap()
    );
}

#[test]
fn more_modes_than_kernels_is_a_clear_error() {
    let points = beam_points(0.25);
    let materials = vec![lame(); points.len()];
    let err = build_basis(&points, &materials, &params(20, 25)).unwrap_err();
    assert!(err.to_string().contains("modes"), "{err}");
}

#[test]
fn an_observed_build_reports_each_stage_once_in_order_and_builds_the_same_basis() {
    let points = beam_points(0.25);
    let materials = vec![lame(); points.len()];
    let stages = std::sync::Mutex::new(Vec::new());
    let observed = build_basis_observed(&points, &materials, &params(60, 4), &|stage| {
        stages.lock().unwrap().push(stage)
    })
    .unwrap()
    .0;
    assert_eq!(stages.into_inner().unwrap(), BasisStage::ALL.to_vec());
    let plain = build_basis(&points, &materials, &params(60, 4)).unwrap().0;
    assert_eq!(observed.eigenvalues(), plain.eigenvalues());
}

/// The iterative (sparse, shift-invert subspace) solver reproduces the dense solver's
/// eigenvalues and weight fields.
#[test]
fn iterative_solver_matches_dense_solver() {
    let points = beam_points(0.1);
    let materials = vec![lame(); points.len()];
    let dense = build_basis(&points, &materials, &params(300, 8)).unwrap().0;
    let iterative_params = BasisParams {
        solver: EigenSolverChoice::Iterative(SubspaceParams::default()),
        ..params(300, 8)
    };
    let (iterative, report, matrices) =
        build_basis(&points, &materials, &iterative_params).unwrap();
    assert!(matches!(matrices, AssembledMatrices::Sparse(_)));
    assert!(
        report.eigen_relative_residual < 1e-10,
        "residual {:e}",
        report.eigen_relative_residual
    );
    assert!(
        report.orthonormality_error < 1e-10,
        "orthonormality {:e}",
        report.orthonormality_error
    );
    for (a, b) in dense.eigenvalues().iter().zip(iterative.eigenvalues()) {
        assert!((a - b).abs() < 1e-9 * a, "{a} vs {b}");
    }
    // Modes 1 and 2 are simple: the weight fields agree up to sign.
    let (wd, wi) = (
        dense.evaluate(points.positions()).unwrap().weights,
        iterative.evaluate(points.positions()).unwrap().weights,
    );
    for mode in 1..=2 {
        let sign = (wd.column(mode).dot(&wi.column(mode))).signum();
        let diff = (wd.column(mode) - wi.column(mode) * sign).amax();
        assert!(
            diff < 1e-7 * wd.column(mode).amax(),
            "mode {mode}: {diff:e}"
        );
    }
}

#[test]
fn weight_space_assembly_is_bit_identical_on_one_and_three_threads() {
    // Each entry of 𝓜 and H_w is summed over points in index order, whatever the thread count.
    let points = beam_points(0.2);
    let materials = vec![lame(); points.len()];
    let kernels = rkpm_core::place_kernels(
        points.positions(),
        &rkpm_core::KernelParams {
            count: 150,
            ..Default::default()
        },
    )
    .unwrap();
    let cutoff = rkpm_core::ShapeFunctionParams::default();
    let shape = rkpm_core::evaluate_shape_functions(&kernels, points.positions(), &cutoff).unwrap();
    let assemble = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| {
                let dense =
                    assemble_weight_space_matrices(&shape, points.volumes(), &materials).unwrap();
                let sparse = skin_eigen::assemble_sparse_weight_space_matrices(
                    &shape,
                    &kernels,
                    cutoff.cutoff,
                    points.volumes(),
                    &materials,
                )
                .unwrap();
                (dense, sparse.mass.to_dense(), sparse.hessian.to_dense())
            })
    };
    let (one, three) = (assemble(1), assemble(3));
    assert!(one.0.mass == three.0.mass && one.0.hessian == three.0.hessian);
    assert!(one.1 == three.1 && one.2 == three.2);
    // Dense and sparse agree (same sums, different storage).
    assert!(one.0.mass == one.1 && one.0.hessian == one.2);
}

#[test]
fn a_thin_plate_with_compact_kernels_gets_a_basis_by_widening_them_and_names_the_point_without() {
    use rkpm_core::{CoverageParams, KernelWindow, ShapeFunctionError};
    use skin_eigen::BasisError;
    // Two layers of points (spacing 0.05 m in a plate 0.1 m thick) and cubic B-spline kernels
    // (support 2 r): some points see only kernels in one plane.
    let points = sample_box_grid(Vector3::zeros(), Vector3::new(2.0, 2.0, 0.1), 0.05).unwrap();
    let materials = vec![lame(); points.len()];
    let mut compact = params(200, 6);
    compact.shape_functions.window = KernelWindow::CubicBSpline;
    compact.kernels.radius_scale = 0.6;
    compact.kernels.min_radius_factor = 1.0;
    let as_placed = BasisParams {
        coverage: CoverageParams {
            max_rounds: 0,
            ..CoverageParams::default()
        },
        ..compact
    };
    let Err(error) = build_basis(&points, &materials, &as_placed) else {
        panic!("the plate must have points the compact kernels as placed leave singular")
    };
    assert!(
        matches!(
            error,
            BasisError::ShapeFunctions(ShapeFunctionError::SingularMomentMatrix { .. })
        ),
        "{error}"
    );

    let (basis, report, _) = build_basis(&points, &materials, &compact).unwrap();
    assert!(
        report.coverage.singular_points > 0 && report.coverage.widened_kernels > 0,
        "{:?}",
        report.coverage
    );
    assert!(report.orthonormality_error < 1e-8, "{report:?}");
    assert_eq!(basis.modes(), 6);

    // The beam's Gaussian kernels cover every point: nothing is widened.
    let beam = beam_points(0.25);
    let (_, report, _) = build_basis(&beam, &vec![lame(); beam.len()], &params(100, 6)).unwrap();
    assert_eq!(report.coverage, rkpm_core::CoverageReport::default());
}
