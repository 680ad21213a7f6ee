//! The lattice mesher on every shared mesh: valid, conforming, watertight, close to the surface,
//! volume within 1%.

use std::collections::HashMap;

use fem_ref::{
    LatticeMesherError, LatticeMesherParams, TetMesh, VolumeTarget, tetrahedralize,
    tetrahedralize_to_volume,
};
use nalgebra::Vector3;
use rkpm_core::{InsideTest, SurfaceDistance, TriangleMesh, read_triangle_mesh};
use test_support::fixtures::shared_meshes;

/// Boundary faces, each oriented outward (seen from outside, counter-clockwise), after checking
/// that no face is shared by more than two tetrahedra.
fn outward_boundary_faces(mesh: &TetMesh) -> Vec<[usize; 3]> {
    let mut faces: HashMap<[usize; 3], (u32, [usize; 3])> = HashMap::new();
    for tet in mesh.tets() {
        // Faces of a positively oriented tet (a, b, c, d), oriented outward.
        let [a, b, c, d] = *tet;
        for face in [[b, c, d], [a, d, c], [a, b, d], [a, c, b]] {
            let mut key = face;
            key.sort_unstable();
            let entry = faces.entry(key).or_insert((0, face));
            entry.0 += 1;
        }
    }
    assert!(
        faces.values().all(|&(count, _)| count <= 2),
        "a face is shared by more than two tetrahedra"
    );
    faces
        .into_values()
        .filter(|&(count, _)| count == 1)
        .map(|(_, face)| face)
        .collect()
}

/// Every directed boundary edge is matched by as many reverse uses: the boundary is a closed,
/// consistently oriented surface, so the mesh is conforming and has no cracks. Returns the
/// number of non-manifold boundary edges (two parts of the solid touching along a lattice edge,
/// where a feature is about one cell thin), which are allowed.
fn assert_watertight(faces: &[[usize; 3]]) -> usize {
    let mut directed: HashMap<(usize, usize), u32> = HashMap::new();
    for f in faces {
        for i in 0..3 {
            *directed.entry((f[i], f[(i + 1) % 3])).or_insert(0) += 1;
        }
    }
    let mut non_manifold = 0;
    for (&(a, b), &count) in &directed {
        let reverse = directed.get(&(b, a)).copied().unwrap_or(0);
        assert_eq!(
            count, reverse,
            "boundary edge {a}→{b} used {count} times but {b}→{a} {reverse} times: a crack"
        );
        if count > 1 {
            non_manifold += 1;
        }
    }
    non_manifold
}

#[test]
fn every_shared_mesh_gives_a_valid_watertight_tet_mesh_within_one_percent_volume() {
    println!(
        "| mesh | cells across | tets | volume error | min/max dihedral | non-manifold boundary edges | seconds |"
    );
    for path in shared_meshes() {
        let name = path.file_name().unwrap().to_string_lossy().into_owned();
        let surface: TriangleMesh = read_triangle_mesh(&path).unwrap().normalized().0;
        let (mesh, report) = tetrahedralize_to_volume(
            &surface,
            &LatticeMesherParams::default(),
            &VolumeTarget::default(),
        )
        .unwrap_or_else(|e| panic!("{name}: {e}"));
        // Conforming and watertight.
        let boundary = outward_boundary_faces(&mesh);
        let non_manifold = assert_watertight(&boundary);

        let cells_across = (1.0 / report.cell_size).round();
        println!(
            "| {name} | {cells_across} | {} | {:+.3}% | {:.1}°/{:.1}° | {non_manifold} | {:.2} |",
            report.tets,
            100.0 * report.relative_volume_error,
            report.quality.min_dihedral_degrees,
            report.quality.max_dihedral_degrees,
            report.seconds
        );

        // Volume, recomputed independently of the report.
        let error = (mesh.volume() - surface.volume()) / surface.volume();
        assert!(error.abs() <= 0.01, "{name}: volume off by {error:+.4}");

        // Every tetrahedron positive (TetMesh validates it) and none near-flat.
        let quality = mesh.quality();
        assert!(
            quality.min_dihedral_degrees > 5.0,
            "{name}: a tetrahedron with dihedral angle {:.2}°",
            quality.min_dihedral_degrees
        );

        // Nothing far outside the surface; boundary vertices on it up to a fraction of a cell.
        let inside = InsideTest::new(&surface);
        let distance = SurfaceDistance::new(&surface);
        let near = |p: &Vector3<f64>| distance.closest_point(p, 0.5 * report.cell_size).is_some();
        let away: Vec<Vector3<f64>> = mesh
            .vertices()
            .iter()
            .filter(|p| !near(p))
            .copied()
            .collect();
        let outside = inside.contains_all(&away).iter().filter(|&&i| !i).count();
        assert_eq!(
            outside, 0,
            "{name}: {outside} vertices lie over half a cell outside"
        );
        for v in boundary.iter().flatten() {
            assert!(
                near(&mesh.vertices()[*v]),
                "{name}: boundary vertex {v} is over half a cell off the surface"
            );
        }
    }
}

#[test]
fn box_aligned_with_the_lattice_is_meshed_exactly() {
    // A box whose faces fall on lattice planes: every boundary vertex is on a face, so the volume
    // is exact and the mesh is the structured one (6 tetrahedra per cell).
    let surface = TriangleMesh::cuboid(Vector3::zeros(), Vector3::new(1.0, 0.5, 0.25));
    let (mesh, report) = tetrahedralize(
        &surface,
        &LatticeMesherParams {
            cells_across: 8,
            ..LatticeMesherParams::default()
        },
    )
    .unwrap();
    assert!((mesh.volume() - 0.125).abs() < 1e-12, "{}", mesh.volume());
    assert_eq!(report.tets, 6 * 8 * 4 * 2);
    assert!((report.quality.min_dihedral_degrees - 45.0).abs() < 1e-9);
}

#[test]
fn shape_thinner_than_the_lattice_is_an_error_naming_the_resolution() {
    let plate = TriangleMesh::cuboid(Vector3::zeros(), Vector3::new(1.0, 1.0, 1e-3));
    let coarse = LatticeMesherParams {
        cells_across: 4,
        ..LatticeMesherParams::default()
    };
    match tetrahedralize(&plate, &coarse) {
        Err(LatticeMesherError::NothingInside {
            cells_across: 4, ..
        }) => {}
        other => panic!("expected NothingInside, got {other:?}"),
    }
    let target = VolumeTarget {
        max_cells_across: 16,
        ..VolumeTarget::default()
    };
    match tetrahedralize_to_volume(&plate, &coarse, &target) {
        Err(
            e @ LatticeMesherError::VolumeNotReached {
                cells_across: 16, ..
            },
        ) => {
            assert!(e.to_string().contains("16 cells across"), "{e}")
        }
        other => panic!("expected VolumeNotReached, got {other:?}"),
    }
}

#[test]
fn invalid_parameters_are_rejected_with_the_parameter_named() {
    let surface = TriangleMesh::cuboid(Vector3::zeros(), Vector3::repeat(1.0));
    for (params, field) in [
        (
            LatticeMesherParams {
                cells_across: 0,
                ..LatticeMesherParams::default()
            },
            "cells_across",
        ),
        (
            LatticeMesherParams {
                snap_fraction: 0.5,
                ..LatticeMesherParams::default()
            },
            "snap_fraction",
        ),
        (
            LatticeMesherParams {
                min_dihedral_guard_degrees: f64::NAN,
                ..LatticeMesherParams::default()
            },
            "min_dihedral_guard_degrees",
        ),
    ] {
        let message = tetrahedralize(&surface, &params).unwrap_err().to_string();
        assert!(message.contains(field), "{message}");
    }
}
