//! The shared 3DGS donut through `SplatTable`: a byte-exact round trip, every untouched
//! property kept, and `Σ' = F Σ Fᵀ` written back to within the file's float precision.

use freeform::spherical_harmonics;
use freeform::{SplatFileError, SplatTable};
use nalgebra::{Matrix3, Vector3};
use test_support::fixtures::{scratch_dir, shared_splat};

fn relative(a: &Matrix3<f64>, b: &Matrix3<f64>) -> f64 {
    (a - b).norm() / b.norm()
}

#[test]
fn the_donut_round_trips_byte_for_byte() {
    let path = shared_splat();
    let table = SplatTable::read(&path).unwrap();
    assert_eq!(table.len(), 45_624);
    assert_eq!(table.property_names()[..4], ["x", "y", "z", "f_dc_0"]);
    assert_eq!(table.to_bytes(), std::fs::read(&path).unwrap());
    let out = scratch_dir("splat-round-trip").join("donut.ply");
    table.write(&out).unwrap();
    assert_eq!(SplatTable::read(&out).unwrap(), table);
}

#[test]
fn an_affine_deformation_moves_centres_and_maps_covariances_by_f_sigma_ft() {
    let table = SplatTable::read(&shared_splat()).unwrap();
    let f = Matrix3::new(1.3, 0.2, 0.0, -0.1, 0.9, 0.3, 0.05, 0.0, 1.1);
    let shift = Vector3::new(0.1, -0.2, 0.3);
    let positions: Vec<Vector3<f64>> = table.positions().iter().map(|x| f * x + shift).collect();
    let gradients = vec![f; table.len()];
    let (deformed, inverted) = table.deformed(&positions, &gradients).unwrap();
    assert_eq!(inverted, 0);
    let before = table.covariances();
    let after = deformed.covariances();
    let worst = before
        .iter()
        .zip(&after)
        .map(|(s, t)| relative(t, &(f * s * f.transpose())))
        .fold(0.0, f64::max);
    // Scales and quaternions are stored as f32: about 1e-7 relative per entry.
    assert!(
        worst < 1e-5,
        "largest relative covariance error {worst:.2e}"
    );
    for (p, q) in deformed.positions().iter().zip(&positions) {
        assert!((p - q).norm() < 1e-6 * q.norm().max(1.0));
    }
    for name in ["opacity", "f_dc_0", "f_dc_1", "f_dc_2"] {
        assert_eq!(deformed.column(name), table.column(name), "{name} changed");
    }
    // The identity keeps every covariance.
    let (same, _) = table
        .deformed(&table.positions(), &vec![Matrix3::identity(); table.len()])
        .unwrap();
    let worst = before
        .iter()
        .zip(same.covariances())
        .map(|(s, t)| relative(&t, s))
        .fold(0.0, f64::max);
    assert!(worst < 1e-5, "identity changed a covariance by {worst:.2e}");
    assert_eq!(same.positions(), table.positions());
}

#[test]
fn wrong_counts_and_non_3dgs_files_are_named_errors() {
    let table = SplatTable::read(&shared_splat()).unwrap();
    let err = table.deformed(&[], &[]).unwrap_err();
    assert!(
        matches!(err, SplatFileError::CountMismatch { given: 0, .. }),
        "{err}"
    );
    let dir = scratch_dir("splat-bad");
    let ascii = dir.join("ascii.ply");
    std::fs::write(
        &ascii,
        "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nend_header\n0\n",
    )
    .unwrap();
    let err = SplatTable::read(&ascii).unwrap_err();
    assert!(err.to_string().contains("binary_little_endian"), "{err}");
    let plain = dir.join("plain.ply");
    let mut bytes = b"ply\nformat binary_little_endian 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\nend_header\n".to_vec();
    bytes.extend([0u8; 12]);
    std::fs::write(&plain, bytes).unwrap();
    let err = SplatTable::read(&plain).unwrap_err();
    assert!(
        matches!(
            err,
            SplatFileError::MissingProperty {
                property: "scale_0",
                ..
            }
        ),
        "{err}"
    );
    let truncated = dir.join("truncated.ply");
    let mut bytes = std::fs::read(shared_splat()).unwrap();
    bytes.truncate(bytes.len() - 3);
    std::fs::write(&truncated, bytes).unwrap();
    assert!(matches!(
        SplatTable::read(&truncated).unwrap_err(),
        SplatFileError::Format { .. }
    ));
}

#[test]
fn a_splat_scene_writes_deformed_3dgs_frames_in_the_input_layout() {
    let dir = scratch_dir("splat-scene");
    let scene = dir.join("donut.toml");
    std::fs::write(
        &scene,
        format!(
            "[geometry]\nsplats = {:?}\n[material]\nyoungs_modulus = 1e5\npoisson_ratio = 0.45\n\
             density = 1000\n[basis]\nmodes = 4\nkernels = 100\npoints = 3000\n\
             [simulation]\ntime_step = 0.01\nsteps = 4\npoints = 1000\noutput_every = 2\n\
             [scene]\ngravity = [0, 0, -9.8]\n",
            shared_splat()
        ),
    )
    .unwrap();
    let file = freeform::SceneFile::load(&scene).unwrap();
    let out = dir.join("out");
    let report = freeform::simulate_scene_file(&file, &out, None, &freeform::Silent).unwrap();
    assert_eq!(report.frames_written, 3);
    assert_eq!(report.inverted_splats, 0);
    let input = SplatTable::read(&shared_splat()).unwrap();
    let first = SplatTable::read(&out.join("frame_00000.ply")).unwrap();
    let last = SplatTable::read(&out.join("frame_00004.ply")).unwrap();
    assert_eq!(last.property_names(), input.property_names());
    assert_eq!(last.column("opacity"), input.column("opacity"));
    // Frame 0 is the rest state: the same centres and covariances as the input (f32 rounding).
    for (a, b) in first.covariances().iter().zip(input.covariances()) {
        assert!(relative(a, &b) < 1e-5);
    }
    // Free fall, no support: every centre drops by backward Euler's g h² n(n+1)/2 = 9.8e-3 m.
    let drop = 9.8 * 1e-4 * 10.0;
    for (p, q) in last.positions().iter().zip(input.positions()) {
        assert!((q.z - p.z - drop).abs() < 1e-5 && (p.xy() - q.xy()).norm() < 1e-5);
    }
}

/// A binary 3DGS PLY of `n` splats with degree-3 harmonics (`f_rest_0..44`), deterministic
/// values, written under `dir`.
fn degree_three_file(dir: &std::path::Path, n: usize) -> std::path::PathBuf {
    let mut names: Vec<String> = ["x", "y", "z", "f_dc_0", "f_dc_1", "f_dc_2"]
        .map(String::from)
        .to_vec();
    names.extend((0..45).map(|k| format!("f_rest_{k}")));
    names.extend(
        [
            "opacity", "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3",
        ]
        .map(String::from),
    );
    let mut bytes = format!("ply\nformat binary_little_endian 1.0\nelement vertex {n}\n");
    for name in &names {
        bytes.push_str(&format!("property float {name}\n"));
    }
    bytes.push_str("end_header\n");
    let mut bytes = bytes.into_bytes();
    for i in 0..n {
        for (k, name) in names.iter().enumerate() {
            let v: f32 = match name.as_str() {
                "scale_0" | "scale_1" | "scale_2" => -3.0,
                "rot_0" => 1.0,
                "rot_1" | "rot_2" | "rot_3" => 0.0,
                _ => (((i * 31 + k * 17) % 23) as f32) / 11.0 - 1.0,
            };
            bytes.extend_from_slice(&v.to_le_bytes());
        }
    }
    let path = dir.join("degree3.ply");
    std::fs::write(&path, bytes).unwrap();
    path
}

#[test]
fn higher_order_harmonics_follow_the_polar_rotation_of_f() {
    let dir = scratch_dir("splat-harmonics");
    let table = SplatTable::read(&degree_three_file(&dir, 3)).unwrap();
    let rest = |t: &SplatTable| -> Vec<Vec<f64>> {
        (0..45)
            .map(|k| t.column(&format!("f_rest_{k}")).unwrap())
            .collect()
    };
    // The identity keeps them (to the file's f32 rounding).
    let (same, _) = table
        .deformed(&table.positions(), &vec![Matrix3::identity(); table.len()])
        .unwrap();
    let original = rest(&table);
    for (a, b) in original.iter().zip(&rest(&same)) {
        for (x, y) in a.iter().zip(b) {
            assert!((x - y).abs() < 1e-6, "identity moved {x} to {y}");
        }
    }
    // A stretched rotation: each channel's colour seen from d now is what was seen from Rᵀ d,
    // R the polar rotation of F (PhysGaussian's rule), checked on the SH functions themselves.
    let f = Matrix3::new(0.2, -1.1, 0.1, 0.9, 0.3, -0.2, 0.1, 0.2, 1.2);
    let (deformed, _) = table
        .deformed(&table.positions(), &vec![f; table.len()])
        .unwrap();
    let r = hyperelastic::polar_rotation(&f);
    let rotated = rest(&deformed);
    let colour = |coefficients: &[Vec<f64>], splat: usize, channel: usize, d: &Vector3<f64>| {
        spherical_harmonics::real_sh_basis(3, d)
            .iter()
            .enumerate()
            .map(|(k, y)| y * coefficients[channel * 15 + k][splat])
            .sum::<f64>()
    };
    for splat in 0..table.len() {
        for channel in 0..3 {
            for d in [Vector3::new(0.3, -0.5, 0.8), Vector3::new(-1.0, 0.2, 0.1)] {
                let d = d.normalize();
                let (now, before) = (
                    colour(&rotated, splat, channel, &d),
                    colour(&original, splat, channel, &(r.transpose() * d)),
                );
                assert!(
                    (now - before).abs() < 1e-5,
                    "splat {splat}, channel {channel}: {now} vs {before}"
                );
            }
        }
    }
    // Not the identity: the coefficients did change.
    assert!(original.iter().zip(&rotated).any(|(a, b)| a != b));
}
