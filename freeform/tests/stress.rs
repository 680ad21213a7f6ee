//! Stress output (Sec. 9.3): the Cauchy stress through a basis's deformation map equals the
//! material's closed form, and a scene file with `stress = true` writes it into its frames.

use std::path::PathBuf;

use freeform::{Geometry, SceneFile, Silent, StressField, simulate_scene_file};
use hyperelastic::{LameParameters, MaterialSample, StableNeoHookean};
use nalgebra::{Matrix3, Vector3};
use reduced_sim::DeformationMap;
use skin_eigen::{BasisParams, build_basis};

fn scratch_dir(name: &str) -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Stable Neo-Hookean (Eq. 16) under `F = diag(s, 1, 1)`: with `λ̄ = λ + μ`, `γ = 1 + μ/λ̄`,
/// `P = μF + λ̄(J − γ) cof F`, `J = s`, `cof F = diag(1, s, s)`, so
/// `σ₁₁ = μ s + λ̄(s − γ)` and `σ₂₂ = σ₃₃ = μ/s + λ̄(s − γ)`.
fn uniaxial_closed_form(lame: &LameParameters, s: f64) -> (f64, f64) {
    let (lambda, mu) = (lame.lambda(), lame.mu());
    let lambda_bar = lambda + mu;
    let gamma = 1.0 + mu / lambda_bar;
    (
        mu * s + lambda_bar * (s - gamma),
        mu / s + lambda_bar * (s - gamma),
    )
}

#[test]
fn a_uniform_uniaxial_stretch_through_a_basis_gives_the_closed_form_stress_at_every_point() {
    let geometry = Geometry::cuboid(Vector3::zeros(), Vector3::new(2.0, 1.0, 1.0));
    let points = geometry.integration_points(400).unwrap();
    let material = MaterialSample {
        youngs_modulus: 1e5,
        poisson_ratio: 0.45,
        density: 1000.0,
    };
    let lame = material.lame_parameters().unwrap();
    let params = BasisParams::default().with_modes(4).with_kernels(60);
    let (basis, _, _) = build_basis(&points, &vec![lame; points.len()], &params).unwrap();
    let map = DeformationMap::new(&basis, points.positions()).unwrap();
    for stretch in [0.7, 1.0, 1.3] {
        let z = map.layout().affine_motion(
            &Matrix3::from_diagonal(&Vector3::new(stretch, 1.0, 1.0)),
            &Vector3::new(0.1, -0.2, 0.3),
        );
        let field = StressField::new(
            &StableNeoHookean,
            &vec![lame; points.len()],
            &map.deformation_gradients(&z),
        )
        .unwrap();
        let (axial, lateral) = uniaxial_closed_form(&lame, stretch);
        let scale = axial.abs().max(lateral.abs()).max(lame.mu());
        let want = Matrix3::from_diagonal(&Vector3::new(axial, lateral, lateral));
        let mut principal = [axial, lateral, lateral];
        principal.sort_by(|a, b| b.total_cmp(a));
        assert!(field.inverted.is_empty());
        for sample in &field.samples {
            assert!(
                (sample.cauchy - want).norm() <= 1e-10 * scale,
                "stretch {stretch}: σ = {}, closed form {want}",
                sample.cauchy
            );
            for (got, want) in sample.principal.iter().zip(principal) {
                assert!((got - want).abs() <= 1e-10 * scale);
            }
            assert!((sample.von_mises - (axial - lateral).abs()).abs() <= 1e-10 * scale);
        }
    }
}

#[test]
fn an_inverted_point_is_flagged_and_written_as_zero_stress_not_nan() {
    let lame = LameParameters::from_young_poisson(1e5, 0.3).unwrap();
    let gradients = [Matrix3::identity(), -Matrix3::identity()];
    let field = StressField::new(&StableNeoHookean, &[lame, lame], &gradients).unwrap();
    assert_eq!(field.inverted, vec![1]);
    assert_eq!(field.samples[1].von_mises, 0.0);
    assert!(field.samples[0].von_mises.abs() < 1e-9);
    assert!(StressField::new(&StableNeoHookean, &[lame], &gradients).is_err());
}

#[test]
fn a_scene_with_stress_writes_it_for_the_surface_and_the_integration_points() {
    let dir = scratch_dir("stress-scene");
    let path = dir.join("hanging.toml");
    std::fs::write(
        &path,
        "[geometry]\nbox = { min = [0, 0, 0], max = [2, 0.5, 0.5] }\n[material]\n\
         youngs_modulus = 1e5\npoisson_ratio = 0.45\ndensity = 1000\n[basis]\nmodes = 6\n\
         kernels = 150\npoints = 2000\n[simulation]\ntime_step = 0.01\nsteps = 4\npoints = 1500\n\
         output_every = 2\nstress = true\n[scene]\ngravity = [0, -9.8, 0]\n\
         [[scene.constraints]]\nregion = { below = { axis = 0, value = 0.1 } }\nmotion = \"rest\"\n",
    )
    .unwrap();
    let file = SceneFile::load(&path).unwrap();
    assert!(file.simulation.stress);
    let out = dir.join("out");
    let report = simulate_scene_file(&file, &out, None, &Silent).unwrap();
    let stress = report.stress.expect("the run was asked for the stress");
    // A cantilever hanging under gravity is stressed; far below its modulus at this sag.
    assert!(stress.max_von_mises > 0.0 && stress.max_von_mises < 1e5);
    assert!(stress.max_von_mises_output > 0.0);
    assert_eq!(stress.most_inverted, 0);
    for index in [0, 2, 4] {
        let frame = std::fs::read_to_string(out.join(format!("frame_{index:05}.vtk"))).unwrap();
        let points = std::fs::read_to_string(out.join(format!("points_{index:05}.vtk"))).unwrap();
        for vtk in [&frame, &points] {
            assert!(vtk.contains("TENSORS cauchy_stress double\n"));
            assert!(vtk.contains("SCALARS von_mises_stress double 1\n"));
        }
        assert!(points.contains(&format!("POINTS {} double\n", report.simulation_points)));
    }
    // Frame 0 is the rest state: no stress.
    let rest = std::fs::read_to_string(out.join("points_00000.vtk")).unwrap();
    let start = rest
        .find("SCALARS von_mises_stress double 1\nLOOKUP_TABLE default\n")
        .unwrap();
    let first: f64 = rest[start..].lines().nth(2).unwrap().parse().unwrap();
    assert!(first.abs() < 1e-6);
}

#[test]
fn material_regions_give_each_shell_its_own_material_and_stress_and_bad_ones_are_named() {
    let dir = scratch_dir("material-regions");
    let path = dir.join("layers.toml");
    let scene = |inner_modulus: f64| {
        format!(
            "[geometry]\nbox = {{ min = [0, 0, 0], max = [1, 1, 1] }}\n[material]\n\
             youngs_modulus = 1e5\npoisson_ratio = 0.3\ndensity = 1000\n\
             [[material.regions]]\nregion = {{ ball = {{ center = [0.5, 0.5, 0.5], radius = 0.4 }} }}\n\
             youngs_modulus = 1e6\npoisson_ratio = 0.3\ndensity = 2000\n\
             [[material.regions]]\nregion = {{ ball = {{ center = [0.5, 0.5, 0.5], radius = 0.2 }} }}\n\
             youngs_modulus = {inner_modulus}\npoisson_ratio = 0.3\ndensity = 3000\n\
             [basis]\nmodes = 4\nkernels = 60\npoints = 800\n\
             [simulation]\ntime_step = 0.01\nsteps = 1\npoints = 500\n[scene]\n"
        )
    };
    std::fs::write(&path, scene(1e7)).unwrap();
    let file = SceneFile::load(&path).unwrap();
    let at = |x: f64| file.material.at(&Vector3::new(x, 0.5, 0.5));
    // The later region wins where they overlap: core, middle shell, outside.
    assert_eq!((at(0.5).youngs_modulus, at(0.5).density), (1e7, 3000.0));
    assert_eq!(at(0.2).youngs_modulus, 1e6);
    assert_eq!(at(0.05).youngs_modulus, 1e5);
    // The same stretch stresses each part in proportion to its modulus (same ν).
    let stretch = Matrix3::from_diagonal(&Vector3::new(1.01, 1.0, 1.0));
    let lame: Vec<LameParameters> = [0.5, 0.2, 0.05]
        .iter()
        .map(|&x| at(x).lame_parameters().unwrap())
        .collect();
    let field = StressField::new(&StableNeoHookean, &lame, &[stretch; 3]).unwrap();
    let axial: Vec<f64> = field.samples.iter().map(|s| s.cauchy[(0, 0)]).collect();
    assert!((axial[0] / axial[1] - 10.0).abs() < 1e-9 && (axial[1] / axial[2] - 10.0).abs() < 1e-9);
    std::fs::write(&path, scene(-1.0)).unwrap();
    let error = SceneFile::load(&path).unwrap_err().to_string();
    assert!(error.contains("material.regions[1]"), "{error}");
}
