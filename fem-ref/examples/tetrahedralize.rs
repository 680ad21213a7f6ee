//! Tetrahedralizes closed surface meshes with the lattice mesher and prints one Markdown row per
//! file: size, volume error, quality, time. Shapes are first scaled so their largest
//! bounding-box side is 1.
//!
//! ```sh
//! cargo run --release -p fem-ref --example tetrahedralize -- ../shared/data/meshes/*.stl --cells 32
//! ```
//! Options: `--cells N` (lattice cells across the largest side, default 32), `--snap F` (default
//! 0.25), `--guard DEG` (default 5).

use fem_ref::{LatticeMesherParams, tetrahedralize};
use rkpm_core::read_triangle_mesh;

fn value<T: std::str::FromStr>(args: &[String], name: &str, default: T) -> Result<T, String> {
    match args.iter().position(|a| a == name) {
        None => Ok(default),
        Some(i) => args
            .get(i + 1)
            .and_then(|v| v.parse().ok())
            .ok_or_else(|| format!("{name} needs a valid value")),
    }
}

fn run() -> Result<(), String> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let defaults = LatticeMesherParams::default();
    let params = LatticeMesherParams {
        cells_across: value(&args, "--cells", defaults.cells_across)?,
        snap_fraction: value(&args, "--snap", defaults.snap_fraction)?,
        min_dihedral_guard_degrees: value(&args, "--guard", defaults.min_dihedral_guard_degrees)?,
    };
    let mut files = Vec::new();
    let mut skip_next = false;
    for a in &args {
        if skip_next {
            skip_next = false;
        } else if a.starts_with("--") {
            skip_next = true;
        } else {
            files.push(a.clone());
        }
    }
    if files.is_empty() {
        return Err("give one or more mesh files (OBJ, STL, PLY)".into());
    }
    println!(
        "| file | vertices | tets | volume error | min dihedral | max dihedral | held back (part/all) | max boundary gap / h | s |"
    );
    println!("|---|---|---|---|---|---|---|---|---|");
    for file in files {
        let name = std::path::Path::new(&file)
            .file_name()
            .map_or(file.clone(), |n| n.to_string_lossy().into_owned());
        let surface = match read_triangle_mesh(&file) {
            Ok(mesh) => mesh.normalized().0,
            Err(e) => {
                println!("| {name} | failed to read: {e} |");
                continue;
            }
        };
        match tetrahedralize(&surface, &params) {
            Ok((_, r)) => println!(
                "| {name} | {} | {} | {:+.3}% | {:.1}° | {:.1}° | {}/{} | {:.3} | {:.2} |",
                r.vertices,
                r.tets,
                100.0 * r.relative_volume_error,
                r.quality.min_dihedral_degrees,
                r.quality.max_dihedral_degrees,
                r.boundary_vertices_held_back[0],
                r.boundary_vertices_held_back[1],
                r.max_boundary_distance / r.cell_size,
                r.seconds
            ),
            Err(e) => println!("| {name} | failed: {e} |"),
        }
    }
    Ok(())
}

fn main() {
    if let Err(e) = run() {
        eprintln!("error: {e}");
        std::process::exit(2);
    }
}
