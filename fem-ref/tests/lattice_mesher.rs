//! The lattice mesher on every shared mesh: valid, conforming, watertight, close to the surface,
//! volume within 1%.

use std::collections::HashMap;

use fem_ref::{
    InteriorFeature, LatticeMesherError, LatticeMesherParams, LatticeMesherReport,
    LatticeRefinement, TetMesh, VolumeTarget, tetrahedralize, tetrahedralize_to_volume,
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
fn a_vertex_plane_puts_lattice_vertices_exactly_on_it_and_no_tetrahedron_across_it() {
    // A tilted box and a plane x = 0.137 that no default lattice plane hits (cells of 1/12):
    // with the plane asked for, vertices lie on it exactly and every tetrahedron away from the
    // surface is on one side (boundary vertices snapped onto the surface may leave the plane).
    let surface = rotated(
        &TriangleMesh::cuboid(Vector3::zeros(), Vector3::new(1.0, 0.5, 0.4)),
        Vector3::new(0.1, 0.2, -0.15),
    );
    let plane = surface.bounding_box().min.x + 0.137;
    for refinement in [LatticeRefinement::Uniform, graded(12, 1).refinement] {
        let params = |vertex_planes| LatticeMesherParams {
            cells_across: 12,
            refinement,
            vertex_planes,
            ..LatticeMesherParams::default()
        };
        let crossing = |mesh: &TetMesh| {
            let boundary: std::collections::HashSet<usize> =
                outward_boundary_faces(mesh).into_iter().flatten().collect();
            mesh.tets()
                .iter()
                .filter(|t| {
                    let xs = t.map(|v| mesh.vertices()[v].x - plane);
                    xs.iter().any(|&x| x < -1e-12)
                        && xs.iter().any(|&x| x > 1e-12)
                        && !t.iter().any(|v| boundary.contains(v))
                })
                .count()
        };
        let (free, free_report) = tetrahedralize(&surface, &params([None; 3])).unwrap();
        assert!(
            crossing(&free) > 0,
            "{refinement:?}: the default lattice already fits"
        );
        let (aligned, report) =
            tetrahedralize(&surface, &params([Some(plane), None, None])).unwrap();
        let on_plane = aligned.vertices().iter().filter(|v| v.x == plane).count();
        assert!(
            on_plane > 20,
            "{refinement:?}: {on_plane} vertices on the plane"
        );
        assert_eq!(crossing(&aligned), 0, "{refinement:?}");
        // The shift costs no accuracy: the volume is as close as the default lattice's.
        assert!(
            report.relative_volume_error.abs() < free_report.relative_volume_error.abs() + 0.01,
            "{refinement:?}: volume {:+.4} against {:+.4}",
            report.relative_volume_error,
            free_report.relative_volume_error
        );
    }
    let bad = LatticeMesherParams {
        vertex_planes: [None, Some(f64::NAN), None],
        ..LatticeMesherParams::default()
    };
    let message = tetrahedralize(&surface, &bad).unwrap_err().to_string();
    assert!(message.contains("vertex plane"), "{message}");
}

#[test]
fn a_cell_size_dividing_two_planes_distance_puts_both_on_vertex_planes() {
    // Planes x = min + 0.137 and x = min + 0.737 on the tilted box: 0.6 apart, 7.2 default
    // cells of 1/12. With h = 0.6 / 7 and a vertex plane through the first, the second is a
    // vertex plane too.
    let surface = rotated(
        &TriangleMesh::cuboid(Vector3::zeros(), Vector3::new(1.0, 0.5, 0.4)),
        Vector3::new(0.1, 0.2, -0.15),
    );
    let min = surface.bounding_box().min.x;
    let (first, second) = (min + 0.137, min + 0.737);
    for refinement in [LatticeRefinement::Uniform, graded(12, 1).refinement] {
        let params = |cell_size| LatticeMesherParams {
            cells_across: 12,
            refinement,
            vertex_planes: [Some(first), None, None],
            cell_size,
            ..LatticeMesherParams::default()
        };
        let on = |mesh: &TetMesh, plane: f64| {
            mesh.vertices()
                .iter()
                .filter(|v| (v.x - plane).abs() < 1e-12)
                .count()
        };
        let (default, _) = tetrahedralize(&surface, &params(None)).unwrap();
        assert_eq!(on(&default, second), 0, "{refinement:?}");
        let (aligned, report) = tetrahedralize(&surface, &params(Some(0.6 / 7.0))).unwrap();
        assert_eq!(report.cell_size, 0.6 / 7.0);
        assert!(on(&aligned, first) > 20, "{refinement:?}");
        assert!(on(&aligned, second) > 20, "{refinement:?}");
        assert!(
            report.relative_volume_error.abs() < 0.05,
            "{refinement:?}: volume {:+.4}",
            report.relative_volume_error
        );
    }
    for bad in [0.0, -0.1, f64::INFINITY, f64::NAN] {
        let message = tetrahedralize(
            &surface,
            &LatticeMesherParams {
                cell_size: Some(bad),
                ..LatticeMesherParams::default()
            },
        )
        .unwrap_err()
        .to_string();
        assert!(message.contains("cell_size"), "{bad}: {message}");
    }
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
fn the_volume_ladder_grows_by_its_factor_rounded_up_and_stops_at_its_finest_lattice() {
    let ladder = |first: usize, target: &VolumeTarget| {
        std::iter::successors(Some(first), |&c| target.next_cells_across(c)).collect::<Vec<_>>()
    };
    let graded = VolumeTarget {
        max_cells_across: 36,
        ..VolumeTarget::default()
    };
    assert_eq!(ladder(16, &graded), [16, 24, 36]);
    assert_eq!(ladder(10, &graded), [10, 15, 23, 35, 36]);
    // A growth that rounds to no new cell still adds one.
    let slow = VolumeTarget {
        growth: 1.01,
        max_cells_across: 4,
        ..VolumeTarget::default()
    };
    assert_eq!(ladder(2, &slow), [2, 3, 4]);
    assert_eq!(ladder(40, &graded), [40]);
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

/// Graded options: `cells_across`, up to `max_halvings` halvings, tolerance 0.05.
fn graded(cells_across: usize, max_halvings: usize) -> LatticeMesherParams {
    LatticeMesherParams {
        cells_across,
        refinement: LatticeRefinement::Graded {
            max_halvings,
            linearity_tolerance: 0.05,
        },
        ..LatticeMesherParams::default()
    }
}

/// `surface` rotated by the rotation vector `axis_angle` (rad) about the origin, so its faces
/// fall on no lattice plane.
fn rotated(surface: &TriangleMesh, axis_angle: Vector3<f64>) -> TriangleMesh {
    let rotation = nalgebra::Rotation3::new(axis_angle);
    TriangleMesh::new(
        surface.vertices().iter().map(|p| rotation * p).collect(),
        surface.triangles().to_vec(),
    )
    .unwrap()
}

/// A closed tube along z: outer radius `outer`, inner `inner`, length `length`, `segments`
/// facets around.
fn tube(outer: f64, inner: f64, length: f64, segments: usize) -> TriangleMesh {
    let ring = |radius: f64, z: f64| -> Vec<Vector3<f64>> {
        (0..segments)
            .map(|s| {
                let angle = std::f64::consts::TAU * s as f64 / segments as f64;
                Vector3::new(radius * angle.cos(), radius * angle.sin(), z)
            })
            .collect()
    };
    // Rings: 0 outer bottom, 1 outer top, 2 inner bottom, 3 inner top.
    let vertices = [
        ring(outer, 0.0),
        ring(outer, length),
        ring(inner, 0.0),
        ring(inner, length),
    ]
    .concat();
    let id = |ring: usize, s: usize| ring * segments + s % segments;
    let mut triangles = Vec::new();
    let mut quad = |a: usize, b: usize, c: usize, d: usize| {
        triangles.push([a, b, c]);
        triangles.push([a, c, d]);
    };
    for s in 0..segments {
        let t = s + 1;
        quad(id(0, s), id(0, t), id(1, t), id(1, s)); // outer wall, facing out
        quad(id(2, s), id(3, s), id(3, t), id(2, t)); // inner wall, facing the axis
        quad(id(1, s), id(1, t), id(3, t), id(3, s)); // top annulus, facing +z
        quad(id(0, s), id(2, s), id(2, t), id(0, t)); // bottom annulus, facing −z
    }
    TriangleMesh::new(vertices, triangles).unwrap()
}

/// Checks a graded mesh of `surface`: volume within `tolerance`, conforming and watertight, no
/// tetrahedron flatter than 3°; returns the report.
fn assert_graded_mesh_holds_the_volume(
    name: &str,
    surface: &TriangleMesh,
    params: &LatticeMesherParams,
    tolerance: f64,
) -> LatticeMesherReport {
    let meshed = tetrahedralize(surface, params).unwrap_or_else(|e| panic!("{name}: {e}"));
    assert_holds_the_volume(name, surface, meshed, tolerance)
}

/// [`assert_graded_mesh_holds_the_volume`] on a mesh already made.
fn assert_holds_the_volume(
    name: &str,
    surface: &TriangleMesh,
    (mesh, report): (TetMesh, LatticeMesherReport),
    tolerance: f64,
) -> LatticeMesherReport {
    assert_watertight(&outward_boundary_faces(&mesh));
    let error = (mesh.volume() - surface.volume()) / surface.volume();
    println!(
        "{name}: {} tets, volume {:+.3}%, deepest bisection {}, dihedral {:.1}°–{:.1}°, {:.2} s",
        report.tets,
        100.0 * error,
        report.deepest_bisection,
        report.quality.min_dihedral_degrees,
        report.quality.max_dihedral_degrees,
        report.seconds
    );
    assert!(
        error.abs() <= tolerance,
        "{name}: volume off by {error:+.4}"
    );
    assert!(
        report.quality.min_dihedral_degrees > 3.0,
        "{name}: dihedral angle {:.2}°",
        report.quality.min_dihedral_degrees
    );
    report
}

#[test]
fn graded_lattice_meshes_a_thin_tilted_plate_within_three_percent_of_its_volume() {
    // 1 × 1 × 0.02: 0.32 of a 16-cell lattice's spacing thick, tilted off the lattice planes.
    let plate = rotated(
        &TriangleMesh::cuboid(Vector3::repeat(-0.5), Vector3::new(0.5, 0.5, -0.48)),
        Vector3::new(0.3, -0.2, 0.1),
    );
    let uniform = tetrahedralize(
        &plate,
        &LatticeMesherParams {
            cells_across: 16,
            ..LatticeMesherParams::default()
        },
    );
    let uniform_error = match uniform {
        Ok((mesh, _)) => (mesh.volume() - plate.volume()) / plate.volume(),
        Err(LatticeMesherError::NothingInside { .. }) => -1.0,
        Err(e) => panic!("{e}"),
    };
    assert!(
        uniform_error < -0.1,
        "the uniform lattice keeps {uniform_error:+.3}"
    );
    // Three halvings: the finest spacing (≈ 0.01) is half the thickness.
    let report = assert_graded_mesh_holds_the_volume("plate", &plate, &graded(16, 3), 0.03);
    assert!(report.deepest_bisection > 0);
}

#[test]
fn graded_lattice_meshes_a_thin_walled_tube_within_three_percent_of_its_volume() {
    // Wall 0.04 thick on a radius of 0.5: 0.64 of the 16-cell spacing.
    let pipe = rotated(&tube(0.5, 0.46, 1.0, 64), Vector3::new(0.2, 0.4, 0.0));
    assert_graded_mesh_holds_the_volume("tube", &pipe, &graded(16, 2), 0.03);
}

#[test]
fn graded_lattices_hold_every_shared_mesh_within_three_percent_under_a_tet_budget() {
    // The FEM references' graded setting (eval's `ShapeFemParams::graded`): 16 cells across,
    // two halvings near the surface, the base lattice ×1.5 up to 36 until within 3%.
    let target = VolumeTarget {
        max_relative_error: 0.03,
        max_cells_across: 36,
        growth: 1.5,
    };
    const MAX_TETS: usize = 250_000;
    for path in shared_meshes() {
        let name = path.file_name().unwrap().to_string_lossy().into_owned();
        let surface = read_triangle_mesh(&path).unwrap().normalized().0;
        let meshed = tetrahedralize_to_volume(&surface, &graded(16, 2), &target)
            .unwrap_or_else(|e| panic!("{name}: {e}"));
        let report = assert_holds_the_volume(&name, &surface, meshed, 0.03);
        assert!(
            report.tets <= MAX_TETS,
            "{name}: {} tetrahedra, over the budget of {MAX_TETS}",
            report.tets
        );
    }
}

/// The longest edge of `mesh` with one end strictly inside `feature`'s negative side and the
/// other strictly outside (an edge that crosses it), 0 when none does.
fn longest_crossing_edge(mesh: &TetMesh, feature: &InteriorFeature) -> f64 {
    let level = |v: usize| feature.level(&mesh.vertices()[v]);
    mesh.edges()
        .into_iter()
        .filter(|&[a, b]| level(a) * level(b) < 0.0)
        .map(|[a, b]| (mesh.vertices()[a] - mesh.vertices()[b]).norm())
        .fold(0.0, f64::max)
}

#[test]
fn a_graded_lattice_refines_every_edge_that_crosses_an_interior_sphere_to_its_finest_spacing() {
    // A unit cube (tilted, so the surface is refined too) with a sphere of radius 0.3 about a
    // point off the lattice; 8 cells across (h = 1/8 of the box's side), two halvings: every
    // edge crossing the sphere is then at most a finest cell's body diagonal, √3 h / 4, where
    // the lattice alone leaves edges of a whole cell (up to √3 h).
    let cube = rotated(
        &TriangleMesh::cuboid(Vector3::repeat(-0.5), Vector3::repeat(0.5)),
        Vector3::new(0.2, -0.1, 0.15),
    );
    let sphere = InteriorFeature::Sphere {
        center: Vector3::new(0.07, -0.03, 0.11),
        radius: 0.3,
    };
    let plain = graded(8, 2);
    let (mesh, report) = tetrahedralize(&cube, &plain).unwrap();
    let h = report.cell_size;
    let coarse = longest_crossing_edge(&mesh, &sphere);
    assert!(
        coarse > 0.9 * h,
        "the lattice alone crosses with {coarse} (h = {h})"
    );
    let refined = LatticeMesherParams {
        refine_across: vec![sphere],
        ..plain
    };
    let meshed = tetrahedralize(&cube, &refined).unwrap();
    let fine = longest_crossing_edge(&meshed.0, &sphere);
    assert!(
        fine <= 3f64.sqrt() * h / 4.0 + 1e-12,
        "refined, an edge of {fine} crosses (finest body diagonal {})",
        3f64.sqrt() * h / 4.0
    );
    // Still a conforming, watertight mesh of the same solid, and graded: under a third of the
    // tetrahedra of the uniform lattice at the finest spacing (the sphere's shell and the
    // tilted faces are a large part of this small cube).
    let report = assert_holds_the_volume("cube with a refined sphere", &cube, meshed, 0.03);
    let (finest, _) = tetrahedralize(
        &cube,
        &LatticeMesherParams {
            cells_across: 32,
            ..LatticeMesherParams::default()
        },
    )
    .unwrap();
    assert!(
        3 * report.tets < finest.tets().len(),
        "{} tets refined, {} on the finest uniform lattice (plain graded {})",
        report.tets,
        finest.tets().len(),
        mesh.tets().len()
    );
}

#[test]
fn interior_features_need_a_graded_lattice_and_finite_numbers() {
    let cube = TriangleMesh::cuboid(Vector3::zeros(), Vector3::repeat(1.0));
    let sphere = InteriorFeature::Sphere {
        center: Vector3::repeat(0.5),
        radius: 0.2,
    };
    let uniform = LatticeMesherParams {
        cells_across: 4,
        refine_across: vec![sphere],
        ..LatticeMesherParams::default()
    };
    let message = tetrahedralize(&cube, &uniform).unwrap_err().to_string();
    assert!(message.contains("graded"), "{message}");
    for bad in [
        InteriorFeature::Sphere {
            center: Vector3::new(f64::NAN, 0.0, 0.0),
            radius: 0.2,
        },
        InteriorFeature::Sphere {
            center: Vector3::zeros(),
            radius: 0.0,
        },
        InteriorFeature::Plane {
            axis: 3,
            value: 0.5,
        },
    ] {
        let params = LatticeMesherParams {
            refine_across: vec![bad],
            ..graded(4, 1)
        };
        let message = tetrahedralize(&cube, &params).unwrap_err().to_string();
        assert!(message.contains("interior feature"), "{message}");
    }
}
