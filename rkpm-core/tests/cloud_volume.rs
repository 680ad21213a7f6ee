//! The volume of a solid from a point cloud (`CloudVolume::FilledVoxels`): a cloud sampled on a
//! closed mesh's surface (as a 3DGS file samples its object) or inside it gives the mesh's
//! volume, where the occupied-cell estimate measures only a shell.

use nalgebra::Vector3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rkpm_core::{
    CloudVolume, GridSamplingParams, InsideTest, IntegrationPoints, PointCloud,
    PointCloudSamplingParams, TriangleMesh, read_triangle_mesh, sample_grid, sample_point_cloud,
};
use test_support::fixtures::shared_data_dir;

/// `n` points drawn uniformly (by area) on the surface of `mesh`, seeded.
fn surface_cloud(mesh: &TriangleMesh, n: usize, seed: u64) -> PointCloud {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut cumulative = Vec::with_capacity(mesh.triangles().len());
    let mut total = 0.0;
    for t in 0..mesh.triangles().len() {
        let [a, b, c] = mesh.triangle_corners(t);
        total += 0.5 * (b - a).cross(&(c - a)).norm();
        cumulative.push(total);
    }
    let points = (0..n)
        .map(|_| {
            let r = rng.random::<f64>() * total;
            let t = cumulative
                .partition_point(|&s| s < r)
                .min(cumulative.len() - 1);
            let [a, b, c] = mesh.triangle_corners(t);
            let (mut u, mut v) = (rng.random::<f64>(), rng.random::<f64>());
            if u + v > 1.0 {
                (u, v) = (1.0 - u, 1.0 - v);
            }
            a + (b - a) * u + (c - a) * v
        })
        .collect();
    PointCloud::new(points, None)
}

fn estimate(cloud: &PointCloud, volume: CloudVolume) -> f64 {
    let params = PointCloudSamplingParams {
        max_points: cloud.len(),
        volume,
        ..PointCloudSamplingParams::default()
    };
    sample_point_cloud(cloud, &params)
        .unwrap()
        .volumes()
        .iter()
        .sum()
}

#[test]
fn a_cloud_on_a_closed_meshs_surface_gives_the_enclosed_volume_within_ten_percent() {
    for name in ["bunny.obj", "spot_low_resolution.obj"] {
        let mesh = read_triangle_mesh(shared_data_dir().join("meshes").join(name))
            .unwrap()
            .normalized()
            .0;
        let exact = mesh.volume();
        let cloud = surface_cloud(&mesh, 20_000, 7);
        let filled = estimate(&cloud, PointCloudSamplingParams::default().volume);
        let shell = estimate(&cloud, CloudVolume::VoxelEstimate { cell_factor: 1.0 });
        println!("{name}: exact {exact:.4} m³, filled {filled:.4}, occupied cells {shell:.4}");
        assert!(
            (filled / exact - 1.0).abs() < 0.1,
            "{name}: filled-voxel estimate {filled:.4} m³ against {exact:.4} m³"
        );
        // The occupied-cell estimate sees a shell, far from the solid's volume.
        assert!(shell < 0.7 * exact, "{name}: shell estimate {shell:.4} m³");
    }
}

#[test]
fn a_cloud_filling_a_box_gives_the_box_volume_within_ten_percent() {
    let (size, n) = (Vector3::new(2.0, 1.0, 0.5), 20_000);
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let points = (0..n)
        .map(|_| size.map(|l| l * rng.random::<f64>()))
        .collect();
    let filled = estimate(
        &PointCloud::new(points, None),
        PointCloudSamplingParams::default().volume,
    );
    println!("box: exact 1 m³, filled {filled:.4}");
    assert!(
        (filled / 1.0 - 1.0).abs() < 0.1,
        "filled-voxel estimate {filled:.4} m³ of a 1 m³ box"
    );
}

/// `∫ |x − x̄|² dV / V` of integration points (m²): how far from its centroid the mass lies.
fn spread(points: &IntegrationPoints) -> f64 {
    let volume: f64 = points.volumes().iter().sum();
    let centroid = points
        .positions()
        .iter()
        .zip(points.volumes())
        .fold(Vector3::zeros(), |acc, (x, v)| acc + x * *v)
        / volume;
    points
        .positions()
        .iter()
        .zip(points.volumes())
        .map(|(x, v)| (x - centroid).norm_squared() * v)
        .sum::<f64>()
        / volume
}

#[test]
fn filling_a_surface_cloud_puts_the_mass_inside_where_the_solid_has_it() {
    let mesh = read_triangle_mesh(shared_data_dir().join("meshes").join("bunny.obj"))
        .unwrap()
        .normalized()
        .0;
    let solid = sample_grid(
        &mesh,
        &GridSamplingParams {
            target_points: 20_000,
        },
    )
    .unwrap();
    let cloud = surface_cloud(&mesh, 20_000, 11);
    let shell = sample_point_cloud(
        &cloud,
        &PointCloudSamplingParams {
            max_points: cloud.len(),
            ..PointCloudSamplingParams::default()
        },
    )
    .unwrap();
    let filled = sample_point_cloud(
        &cloud,
        &PointCloudSamplingParams {
            max_points: cloud.len(),
            fill_interior: true,
            ..PointCloudSamplingParams::default()
        },
    )
    .unwrap();
    // Same total volume; the added points lie inside the surface.
    let total = |p: &IntegrationPoints| p.volumes().iter().sum::<f64>();
    assert!((total(&filled) / total(&shell) - 1.0).abs() < 1e-9);
    let added = &filled.positions()[cloud.len()..];
    assert!(
        added.len() > 1000 && added.len() < 40_000,
        "{} inner points for 20 000 asked",
        added.len()
    );
    // The closing fills concavities narrower than about 4 cells: a few points may sit there.
    let inside = InsideTest::new(&mesh).contains_all(added);
    let outside = inside.iter().filter(|&&k| !k).count();
    println!(
        "{} points added inside, {outside} of them outside the surface",
        added.len()
    );
    assert!(
        outside * 100 <= added.len(),
        "{outside} of {} added points outside",
        added.len()
    );
    // The spread of the mass about its centroid: the shell's is far from the solid's, the
    // filled cloud's close to it.
    let (exact, on_shell, with_fill) = (spread(&solid), spread(&shell), spread(&filled));
    println!("spread: solid {exact:.5} m², shell {on_shell:.5}, filled {with_fill:.5}");
    assert!(
        (with_fill / exact - 1.0).abs() < 0.1,
        "filled {with_fill:.5} vs solid {exact:.5}"
    );
    assert!(
        on_shell / exact > 1.2,
        "shell {on_shell:.5} vs solid {exact:.5}"
    );
}
