//! How much of each surface's volume the lattice mesher keeps at several resolutions:
//! `cargo run --release -p fem-ref --example mesh_volumes -- data/meshes 16 24 32 48`.
//! A setting `gN:H:T` meshes graded: N cells across, at most H halvings near the surface,
//! linearity tolerance T (e.g. `g16:3:0.05`), optionally `gN:H:T:G` with the snap's dihedral
//! guard G (degrees, default 10) or `gN:H:T:G:S` with the snap fraction S too. Each column:
//! volume error, P2 DOFs, smallest dihedral angle, seconds.

use std::time::Instant;

use fem_ref::{LatticeMesherParams, LatticeRefinement, TetMesh, tetrahedralize};
use rkpm_core::read_triangle_mesh;

fn main() {
    let mut args = std::env::args().skip(1);
    let dir = args.next().expect("a folder of meshes");
    let settings: Vec<(String, LatticeMesherParams)> =
        args.map(|a| (a.clone(), setting(&a))).collect();
    let mut paths: Vec<_> = std::fs::read_dir(&dir)
        .expect("readable folder")
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            matches!(
                p.extension().and_then(|e| e.to_str()),
                Some("obj" | "stl" | "ply")
            )
        })
        .collect();
    paths.sort();
    for path in paths {
        let name = path.file_stem().unwrap().to_string_lossy().to_string();
        let surface = match read_triangle_mesh(&path) {
            Ok(s) => s.normalized().0,
            Err(e) => {
                println!("{name}: {e}");
                continue;
            }
        };
        let mut line = format!("{name:>28}");
        for (label, params) in &settings {
            let start = Instant::now();
            match tetrahedralize(&surface, params) {
                Ok((mesh, report)) => {
                    line += &format!(
                        "  {label}: {:+.3} ({} P2 DOFs, {:.0}°, {:.1}s, held {:?}/{}, deepest {})",
                        report.relative_volume_error,
                        p2_dofs(&mesh),
                        report.quality.min_dihedral_degrees,
                        start.elapsed().as_secs_f64(),
                        report.boundary_vertices_held_back,
                        report.boundary_vertices,
                        report.deepest_bisection,
                    )
                }
                Err(e) => line += &format!("  {label}: {e}"),
            }
        }
        println!("{line}");
    }
}

/// `N` (uniform) or `gN:H:T` (graded) as mesher options.
fn setting(arg: &str) -> LatticeMesherParams {
    let parse = |s: &str| s.parse::<f64>().expect("a number");
    match arg.strip_prefix('g') {
        None => LatticeMesherParams {
            cells_across: parse(arg) as usize,
            ..Default::default()
        },
        Some(graded) => {
            let parts: Vec<f64> = graded.split(':').map(parse).collect();
            let defaults = LatticeMesherParams::default();
            let (cells, halvings, tolerance, guard, snap) = match parts[..] {
                [c, h, t] => (
                    c,
                    h,
                    t,
                    defaults.min_dihedral_guard_degrees,
                    defaults.snap_fraction,
                ),
                [c, h, t, g] => (c, h, t, g, defaults.snap_fraction),
                [c, h, t, g, s] => (c, h, t, g, s),
                _ => panic!("gN:H:T[:G[:S]], got {arg}"),
            };
            LatticeMesherParams {
                cells_across: cells as usize,
                refinement: LatticeRefinement::Graded {
                    max_halvings: halvings as usize,
                    linearity_tolerance: tolerance,
                },
                min_dihedral_guard_degrees: guard,
                snap_fraction: snap,
                ..defaults
            }
        }
    }
}

/// Degrees of freedom of P2 elements on `mesh`: three per vertex and per edge.
fn p2_dofs(mesh: &TetMesh) -> usize {
    3 * (mesh.vertices().len() + mesh.edges().len())
}
