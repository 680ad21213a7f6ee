//! How much of each surface's volume the lattice mesher keeps at several resolutions (issue 19):
//! `cargo run --release -p fem-ref --example mesh_volumes -- ../shared/data/meshes 16 24 32 48`.

use std::time::Instant;

use fem_ref::{LatticeMesherParams, tetrahedralize};
use rkpm_core::read_triangle_mesh;

fn main() {
    let mut args = std::env::args().skip(1);
    let dir = args.next().expect("a folder of meshes");
    let resolutions: Vec<usize> = args.map(|a| a.parse().expect("cells across")).collect();
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
        for &cells in &resolutions {
            let start = Instant::now();
            let params = LatticeMesherParams {
                cells_across: cells,
                ..Default::default()
            };
            match tetrahedralize(&surface, &params) {
                Ok((mesh, report)) => {
                    line += &format!(
                        "  {cells}: {:+.3} ({} v, {:.1}s)",
                        report.relative_volume_error,
                        mesh.vertices().len(),
                        start.elapsed().as_secs_f64()
                    )
                }
                Err(e) => line += &format!("  {cells}: {e}"),
            }
        }
        println!("{line}");
    }
}
