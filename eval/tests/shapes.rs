//! The shapes experiment (Tables 2 and 7): the three boundary conditions select the intended
//! regions (the end-to-end `freeform-paper table 2 7 --quick` run is in `cli.rs`).

use eval::shapes::boundary::{ShapeBoundary, ShapeBoundaryParams};
use eval::shapes::config::ShapeStudyConfig;
use eval::shapes::reference::ShapeFemParams;
use eval::shapes::study::run_shape_study;
use fem_ref::{InteriorFeature, tetrahedralize};
use freeform::scene::{Motion, SceneSpec};
use freeform::terminal_progress::TerminalProgress;
use freeform::{PinHold, PressureSpaceParams};
use nalgebra::Vector3;
use rkpm_core::TriangleMesh;
use std::sync::Mutex;

/// Cell size of the test grid: 1/16, so no cell centre lies on a slab plane (0.1, 1.9).
const H: f64 = 0.0625;

/// The 1 × 2 × 0.5 m box (y longest, L = 2) and the centres of its 16 × 32 × 8 cells.
fn box_and_cell_centres() -> (TriangleMesh, Vec<Vector3<f64>>) {
    let max = Vector3::new(1.0, 2.0, 0.5);
    let mut points = Vec::new();
    for i in 0..16 {
        for j in 0..32 {
            for k in 0..8 {
                points.push(Vector3::new(
                    (i as f64 + 0.5) * H,
                    (j as f64 + 0.5) * H,
                    (k as f64 + 0.5) * H,
                ));
            }
        }
    }
    (TriangleMesh::cuboid(Vector3::zeros(), max), points)
}

#[test]
fn fix_side_holds_the_min_x_slab_of_five_percent_of_the_largest_side_under_gravity() {
    let (surface, points) = box_and_cell_centres();
    let scene = ShapeBoundary::FixSide.scene(&surface, &points, &ShapeBoundaryParams::default());
    assert_eq!(scene.gravity, Some(Vector3::new(0.0, -9.8, 0.0)));
    let selected = scene.select(&points, "cell centres").unwrap();
    assert_eq!(selected.len(), 1);
    assert_eq!(scene.constraints[0].motion, Motion::Rest);
    // x ≤ x_min + 0.05 · L = 0.031 + 0.1, x_min the smallest candidate's: the two cell layers
    // at x = 0.031 and 0.094, 32 × 8 cells each.
    assert_eq!(selected[0].len(), 2 * 32 * 8);
    for (i, p) in points.iter().enumerate() {
        assert_eq!(selected[0].contains(&i), p.x < 0.13, "{p:?}");
    }
}

#[test]
fn pull_boundary_moves_both_ends_of_the_longest_axis_apart() {
    let (surface, points) = box_and_cell_centres();
    let params = ShapeBoundaryParams::default();
    let scene = ShapeBoundary::PullBoundary.scene(&surface, &points, &params);
    assert_eq!(scene.gravity, None);
    let selected = scene.select(&points, "cell centres").unwrap();
    assert_eq!(selected.len(), 2);
    // The longest axis is y (2 m): slabs 0.1 thick from the extreme candidates (y = 0.031 and
    // 1.969), two layers of 16 × 8 cells each.
    let ends: [fn(&Vector3<f64>) -> bool; 2] = [|p| p.y < 0.13, |p| p.y > 1.87];
    for (region, inside) in selected.iter().zip(ends) {
        assert_eq!(region.len(), 2 * 16 * 8);
        for (i, p) in points.iter().enumerate() {
            assert_eq!(region.contains(&i), inside(p), "{p:?}");
        }
    }
    // Each end moves at 0.2 L/s = 0.4 m/s along ∓y.
    let t = 0.25;
    let p = Vector3::new(0.5, 0.0, 0.25);
    let q = Vector3::new(0.5, 2.0, 0.25);
    let moved_low = scene.constraints[0].motion.at(&p, t);
    let moved_high = scene.constraints[1].motion.at(&q, t);
    assert!((moved_low - Vector3::new(0.5, -0.1, 0.25)).norm() < 1e-12);
    assert!((moved_high - Vector3::new(0.5, 2.1, 0.25)).norm() < 1e-12);
}

#[test]
fn pull_farthest_pulls_four_distinct_corners_outward_within_the_radius() {
    let (surface, points) = box_and_cell_centres();
    let params = ShapeBoundaryParams::default();
    let centre = Vector3::new(0.5, 1.0, 0.25);
    let lo = [H / 2.0; 3];
    let hi = [1.0 - H / 2.0, 2.0 - H / 2.0, 0.5 - H / 2.0];
    let corner_of = |p: &Vector3<f64>| {
        (0..3).all(|a| (p[a] - lo[a]).abs() < 1e-12 || (p[a] - hi[a]).abs() < 1e-12)
    };
    // Sampling among all cells: the first two are opposite corners (the farthest from the
    // centre, ties to the lowest index, then the farthest from it).
    let first_two = eval::shapes::boundary::farthest_points(&points, centre, 2);
    assert!((first_two[0] - Vector3::from(lo)).norm() < 1e-12);
    assert!(
        (first_two[1] - Vector3::from(hi)).norm() < 1e-12,
        "{first_two:?}"
    );
    // Patches centred on the corner cells.
    let corners: Vec<Vector3<f64>> = points.iter().filter(|p| corner_of(p)).copied().collect();
    assert_eq!(corners.len(), 8);
    let scene = ShapeBoundary::PullFarthest.scene(&surface, &corners, &params);
    assert_eq!(scene.gravity, None);
    assert_eq!(scene.constraints.len(), 4);
    // Lattice points (a, b, c) ≥ 0 of the octant with |(a, b, c)| · H ≤ 0.1 · L = 0.2: the cells
    // within the radius of a corner cell (the radius, 3.2 cells, stays inside the box).
    let mut octant = 0;
    for a in 0..4 {
        for b in 0..4 {
            for c in 0..4 {
                if ((a * a + b * b + c * c) as f64).sqrt() * H <= 0.2 {
                    octant += 1;
                }
            }
        }
    }
    let selected = scene.select(&points, "cell centres").unwrap();
    let mut centres = Vec::new();
    for (constraint, region) in scene.constraints.iter().zip(&selected) {
        let freeform::scene::Region::Ball { center, radius } = constraint.region else {
            panic!("a pulled patch is a ball, got {:?}", constraint.region);
        };
        assert!(
            corner_of(&center),
            "patch centre {center:?} is not a corner cell"
        );
        assert!((radius - 0.2).abs() < 1e-12);
        assert_eq!(region.len(), octant, "patch at {center:?}");
        let Motion::Translate { velocity } = constraint.motion else {
            panic!("a pulled patch translates, got {:?}", constraint.motion);
        };
        let outward = (center - centre).normalize();
        assert!((velocity - outward * 0.4).norm() < 1e-12, "{velocity:?}");
        centres.push(center);
    }
    for (i, a) in centres.iter().enumerate() {
        for b in &centres[i + 1..] {
            assert!((a - b).norm() > 1.0, "patches {a:?} and {b:?} are close");
        }
    }
}

/// `boundary`'s scene on `surface` (the box), slabs measured from its own vertices.
fn box_scene(surface: &TriangleMesh, boundary: ShapeBoundary) -> SceneSpec {
    boundary.scene(surface, surface.vertices(), &ShapeBoundaryParams::default())
}

/// The positions of the FEM mesh vertices each of `boundary`'s regions holds, on the lattice
/// `fem` meshes the box's reference on at 16 cells across (L = 2).
fn held_nodes(
    surface: &TriangleMesh,
    fem: &ShapeFemParams,
    boundary: ShapeBoundary,
) -> Vec<Vec<Vector3<f64>>> {
    let scene = box_scene(surface, boundary);
    let condition = fem.condition_lattice(boundary, &scene);
    let (mesh, _) = tetrahedralize(surface, &fem.lattice_through(16, 2.0, &condition)).unwrap();
    let held = scene.select(mesh.vertices(), "mesh vertices").unwrap();
    held.iter()
        .map(|region| region.iter().map(|&i| mesh.vertices()[i]).collect())
        .collect()
}

#[test]
fn fix_sides_reference_on_the_shifted_lattice_holds_nodes_up_to_the_slabs_face() {
    // The 1 × 2 × 0.5 box at 16 cells across (h = 0.125): the clamp's face x = 0.1 lies
    // between the default lattice's vertex planes x = 0 and 0.125.
    let (surface, _) = box_and_cell_centres();
    let mut fem = ShapeFemParams {
        clamp_on_lattice_plane: false,
        ..ShapeFemParams::graded()
    };
    let deepest_held = |fem: &ShapeFemParams| {
        held_nodes(&surface, fem, ShapeBoundary::FixSide)[0]
            .iter()
            .map(|p| p.x)
            .fold(f64::NEG_INFINITY, f64::max)
    };
    // (Bisection midpoints on the plane round to within 1e-16 of it.)
    let unshifted = deepest_held(&fem);
    assert!(
        unshifted.abs() < 1e-12,
        "the unshifted lattice stops at x = 0: {unshifted}"
    );
    fem.clamp_on_lattice_plane = true;
    let shifted = deepest_held(&fem);
    assert!(
        (shifted - 0.1).abs() < 1e-12,
        "the shifted lattice reaches the face: {shifted}"
    );
    // Other conditions keep the shape's one mesh.
    fem.pull_slabs_on_lattice_planes = false;
    for other in [ShapeBoundary::PullBoundary, ShapeBoundary::PullFarthest] {
        assert_eq!(fem.slab_faces(other, &box_scene(&surface, other)), None);
    }
}

#[test]
fn pull_boundarys_reference_on_the_aligned_lattice_holds_nodes_up_to_both_slabs_faces() {
    // The 1 × 2 × 0.5 box (L = 2) pulled along y: slabs y ≤ 0.1 and y ≥ 1.9, faces 1.8 apart.
    // At 16 cells across (h = 0.125, graded down to h/4 near the surface) neither face is a
    // vertex plane; aligned, h = 1.8/14 and both are.
    let (surface, _) = box_and_cell_centres();
    let mut fem = ShapeFemParams {
        pull_slabs_on_lattice_planes: false,
        // (Refined along the faces, the unaligned lattice's nodes would come within a
        // quarter cell of them; this test is about the alignment alone.)
        refine_pulled_slab_faces: false,
        ..ShapeFemParams::graded()
    };
    // How deep each pulled region's nodes reach into the body: its innermost node's y.
    let innermost = |fem: &ShapeFemParams| {
        let held = held_nodes(&surface, fem, ShapeBoundary::PullBoundary);
        (
            held[0]
                .iter()
                .map(|p| p.y)
                .fold(f64::NEG_INFINITY, f64::max),
            held[1].iter().map(|p| p.y).fold(f64::INFINITY, f64::min),
        )
    };
    let (low, high) = innermost(&fem);
    assert!(
        low < 0.1 - 0.01 && high > 1.9 + 0.01,
        "the unaligned lattice stops short of both faces: {low}, {high}"
    );
    fem.pull_slabs_on_lattice_planes = true;
    let scene = box_scene(&surface, ShapeBoundary::PullBoundary);
    let faces = fem.slab_faces(ShapeBoundary::PullBoundary, &scene).unwrap();
    assert_eq!((faces.axis, faces.first, faces.second), (1, 0.1, Some(1.9)));
    let (low, high) = innermost(&fem);
    assert!(
        (low - 0.1).abs() < 1e-12 && (high - 1.9).abs() < 1e-12,
        "the aligned lattice reaches both faces: {low}, {high}"
    );
}

#[test]
fn pull_farthests_reference_on_the_refined_lattice_resolves_each_pulled_balls_edge_to_a_quarter_cell()
 {
    // The 1 × 2 × 0.5 box (L = 2) at 16 cells across (h = 0.125): the pulled balls (radius
    // 0.2 about four corners) cut the lattice's cells, so the nodes the FEM pulls match each
    // ball only to a cell; refined along the spheres, every edge that crosses one is a finest
    // cell's (two halvings: at most √3 h / 4).
    let (surface, _) = box_and_cell_centres();
    let scene = box_scene(&surface, ShapeBoundary::PullFarthest);
    let spheres: Vec<InteriorFeature> = scene
        .constraints
        .iter()
        .map(|c| match c.region {
            freeform::scene::Region::Ball { center, radius } => {
                InteriorFeature::Sphere { center, radius }
            }
            ref other => panic!("a pulled patch is a ball, got {other:?}"),
        })
        .collect();
    let longest_crossing = |fem: &ShapeFemParams| {
        let condition = fem.condition_lattice(ShapeBoundary::PullFarthest, &scene);
        let (mesh, report) =
            tetrahedralize(&surface, &fem.lattice_through(16, 2.0, &condition)).unwrap();
        let v = mesh.vertices();
        let crossing = mesh
            .edges()
            .into_iter()
            .filter(|&[a, b]| {
                spheres
                    .iter()
                    .any(|sphere| sphere.level(&v[a]) * sphere.level(&v[b]) < 0.0)
            })
            .map(|[a, b]| (v[a] - v[b]).norm())
            .fold(0.0, f64::max);
        (crossing, report.cell_size)
    };
    let mut fem = ShapeFemParams {
        refine_pulled_patch_edges: false,
        refine_pulled_slab_faces: false,
        ..ShapeFemParams::graded()
    };
    let (plain, h) = longest_crossing(&fem);
    assert!((h - 0.125).abs() < 1e-12);
    assert!(
        plain >= h,
        "the shape's lattice crosses the spheres with edges of {plain}"
    );
    fem.refine_pulled_patch_edges = true;
    let (refined, _) = longest_crossing(&fem);
    assert!(
        refined <= 3f64.sqrt() * h / 4.0 + 1e-12,
        "refined, an edge of {refined} crosses a sphere"
    );
    // The other conditions are not refined, Pull boundary's slab faces only when asked.
    for other in [ShapeBoundary::FixSide, ShapeBoundary::PullBoundary] {
        assert!(
            fem.refined_edges(other, &box_scene(&surface, other))
                .is_empty()
        );
    }
    fem.refine_pulled_slab_faces = true;
    let pull_boundary = box_scene(&surface, ShapeBoundary::PullBoundary);
    assert_eq!(
        fem.refined_edges(ShapeBoundary::PullBoundary, &pull_boundary),
        vec![
            InteriorFeature::Plane {
                axis: 1,
                value: 0.1
            },
            InteriorFeature::Plane {
                axis: 1,
                value: 1.9
            }
        ]
    );
}

#[test]
fn the_study_hands_each_finished_shape_the_study_so_far_in_table_order_one_call_at_a_time() {
    // Unreadable files: each shape ends at once, with its error.
    let dir = test_support::fixtures::scratch_dir("shape-study-so-far");
    let names = ["a.obj", "b.stl", "c.ply"];
    for name in names {
        std::fs::write(dir.join(name), "not a mesh").unwrap();
    }
    let mut config = ShapeStudyConfig::quick(
        names.iter().map(|n| dir.join(n)).collect(),
        dir.join("cache"),
    );
    config.jobs = 2;
    let calls = Mutex::new(Vec::new());
    let quiet = TerminalProgress {
        quiet: true,
        hide_bars: true,
    };
    let study = run_shape_study(&config, &quiet, |shape, so_far| {
        let finished: Vec<String> = so_far.shapes.iter().map(|s| s.name.clone()).collect();
        assert!(finished.contains(&shape.name), "{finished:?}");
        assert!(shape.error.is_some());
        calls.lock().unwrap().push((finished, so_far.unfinished()));
    })
    .unwrap();
    let calls = calls.into_inner().unwrap();
    assert_eq!(calls.len(), 3);
    for (k, (finished, unfinished)) in calls.iter().enumerate() {
        // The k-th call sees k + 1 shapes, in the folder's order, and the rest as unfinished.
        assert_eq!(finished.len(), k + 1, "{calls:?}");
        let mut all: Vec<&String> = finished.iter().chain(unfinished).collect();
        all.sort();
        assert_eq!(all, names, "{calls:?}");
        let order: Vec<usize> = finished
            .iter()
            .map(|f| names.iter().position(|n| n == f).unwrap())
            .collect();
        assert!(order.windows(2).all(|w| w[0] < w[1]), "{calls:?}");
    }
    assert!(study.unfinished().is_empty());
    let returned: Vec<&str> = study.shapes.iter().map(|s| s.name.as_str()).collect();
    assert_eq!(returned, names);
}

#[test]
fn the_study_holds_regions_exactly_and_projects_the_volumetric_term_when_its_settings_say() {
    let data = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../data/meshes");
    let dir = test_support::fixtures::scratch_dir("shape-study-held");
    let quick = |pins, pressure| {
        let mut config = ShapeStudyConfig::quick(vec![data.join("93070.stl")], dir.join("cache"));
        config.simplicits = None;
        config.settings.pins = pins;
        config.settings.pressure = pressure;
        let quiet = TerminalProgress {
            quiet: true,
            hide_bars: true,
        };
        run_shape_study(&config, &quiet, |_, _| {}).unwrap().shapes[0]
            .rows
            .clone()
    };
    let penalty = quick(PinHold::Penalty, None);
    let held = quick(PinHold::WEIGHTED, Some(PressureSpaceParams::default()));
    assert_eq!(held.len(), 3);
    for (p, h) in penalty.iter().zip(&held) {
        assert_eq!(h.error, None, "{:?}", h.boundary);
        let (p, h) = (p.ours.as_ref().unwrap(), h.ours.as_ref().unwrap());
        // Every condition moves its regions by a prescribed motion: held exactly, they follow
        // it to rounding; the penalty lets them lag.
        assert!(h.max_pin_deviation < 1e-9, "{h:?}");
        assert!(p.max_pin_deviation > 1e3 * h.max_pin_deviation, "{p:?}");
        assert!(h.mse.is_finite() && h.mse != p.mse, "{h:?} against {p:?}");
    }
}
