//! Every shared mesh loads, validates and has its published volume; the inside test agrees
//! with the divergence-theorem volume; the 3DGS file loads with its header-defined layout.

use rkpm_core::{GridSamplingParams, read_point_cloud, read_triangle_mesh, sample_grid};
use test_support::fixtures::{shared_data_dir, shared_meshes, shared_splat};

/// `file → volume` from the shared manifest (file units³).
fn manifest_volumes() -> Vec<(String, f64)> {
    let text = std::fs::read_to_string(shared_data_dir().join("meshes_manifest.csv")).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let volume_col = header.iter().position(|h| *h == "volume").unwrap();
    // Fields before `volume` may contain quoted commas; count columns from the end instead.
    let from_end = header.len() - volume_col;
    lines
        .map(|line| {
            let fields: Vec<&str> = line.split(',').collect();
            (
                fields[0].to_string(),
                fields[fields.len() - from_end].parse().unwrap(),
            )
        })
        .collect()
}

#[test]
fn every_shared_mesh_is_closed_with_the_manifest_volume() {
    let volumes = manifest_volumes();
    let paths = shared_meshes();
    assert_eq!(paths.len(), volumes.len());
    for path in paths {
        let name = path.file_name().unwrap().to_str().unwrap();
        let mesh = read_triangle_mesh(&path).unwrap_or_else(|e| panic!("{e}"));
        let expected = volumes.iter().find(|(f, _)| f == name).unwrap().1;
        let rel = (mesh.volume() - expected).abs() / expected;
        assert!(
            rel < 1e-6,
            "{name}: volume {} vs manifest {expected}",
            mesh.volume()
        );
        let (unit, _) = mesh.normalized();
        assert!((unit.bounding_box().largest_side() - 1.0).abs() < 1e-12);
    }
}

#[test]
fn grid_inside_fraction_matches_divergence_volume_within_one_percent() {
    for path in shared_meshes() {
        let (mesh, _) = read_triangle_mesh(&path).unwrap().normalized();
        let points = sample_grid(
            &mesh,
            &GridSamplingParams {
                target_points: 2_000_000,
            },
        )
        .unwrap();
        let rel = (points.total_volume() - mesh.volume()).abs() / mesh.volume();
        println!(
            "{:32} {:8} points  grid volume error {:.3}%",
            path.display().to_string().rsplit('/').next().unwrap(),
            points.len(),
            100.0 * rel
        );
        assert!(
            rel < 0.01,
            "{}: grid volume {} vs {}",
            path.display(),
            points.total_volume(),
            mesh.volume()
        );
    }
}

/// The fast ray test must agree with the exact generalized winding number everywhere,
/// including points on grid planes through vertices (degenerate rays).
#[test]
fn ray_inside_test_agrees_with_exact_winding_number() {
    use nalgebra::Vector3;
    use rkpm_core::InsideTest;
    for path in shared_meshes() {
        let (mesh, _) = read_triangle_mesh(&path).unwrap().normalized();
        let test = InsideTest::new(&mesh);
        let bbox = mesh.bounding_box();
        // A lattice that passes through bounding-box planes and (for axis-aligned meshes)
        // through vertices and edges, plus a deterministic irrational-ish offset lattice.
        let n = 9;
        let mut disagreements = 0;
        for offset in [0.0, 0.013_579] {
            for i in 0..n * n * n {
                let f = Vector3::new((i / (n * n)) as f64, ((i / n) % n) as f64, (i % n) as f64);
                let q = bbox.min
                    + (f / (n - 1) as f64 + Vector3::repeat(offset)).component_mul(&bbox.extent());
                let w = test.winding_number(&q);
                // Points on the surface (w ≈ ½) may go either way.
                if (w - 0.5).abs() > 0.1 && test.contains(&q) != (w > 0.5) {
                    disagreements += 1;
                }
            }
        }
        assert_eq!(disagreements, 0, "{}", path.display());
    }
}

#[test]
fn gaussian_splat_file_loads_with_header_defined_properties() {
    let cloud = read_point_cloud(shared_splat()).unwrap();
    assert_eq!(cloud.len(), 45_624);
    let splats = cloud.splats().expect("the file has 3DGS attributes");
    assert_eq!(splats.rotations.len(), 45_624);
    let bbox = cloud.bounding_box().unwrap();
    assert!((bbox.min.x - -0.1032).abs() < 1e-3 && (bbox.max.y - 0.1095).abs() < 1e-3);
    // Scales are logs of small standard deviations (README: from -9.66 to -3.38).
    let (lo, hi) = splats
        .log_scales
        .iter()
        .flatten()
        .fold((f64::MAX, f64::MIN), |(a, b), &s| (a.min(s), b.max(s)));
    assert!(lo > -9.7 && hi < -3.3, "{lo} {hi}");
    assert!(
        splats
            .rotations
            .iter()
            .all(|q| (q.quaternion().norm() - 1.0).abs() < 1e-12)
    );
}
