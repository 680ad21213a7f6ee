//! Files a user opens: per-frame PLY (MeshLab, Blender) and legacy VTK (ParaView) of deformed
//! surfaces or tet meshes. Every file is written to a temporary name and renamed, so an
//! interrupted run never leaves a half-written file that looks like a result.

use std::fmt::Write as _;
use std::path::Path;

use nalgebra::Vector3;

use crate::EvalError;

/// Writes `bytes` to `path` atomically ([`artifact::write_atomically`]: unique temporary file,
/// fsync, rename).
///
/// # Errors
/// [`EvalError::Artifact`] naming the path.
pub fn write_atomically(path: &Path, bytes: &[u8]) -> Result<(), EvalError> {
    Ok(artifact::write_atomically(path, bytes)?)
}

/// ASCII PLY of a triangle mesh with the given vertex positions.
pub fn triangle_mesh_ply(vertices: &[Vector3<f64>], triangles: &[[usize; 3]]) -> String {
    let mut s = format!(
        "ply\nformat ascii 1.0\ncomment FreeForm frame\nelement vertex {}\nproperty float x\n\
         property float y\nproperty float z\nelement face {}\nproperty list uchar int vertex_indices\nend_header\n",
        vertices.len(),
        triangles.len()
    );
    for v in vertices {
        let _ = writeln!(s, "{} {} {}", v.x, v.y, v.z);
    }
    for t in triangles {
        let _ = writeln!(s, "3 {} {} {}", t[0], t[1], t[2]);
    }
    s
}

/// Legacy-VTK unstructured grid (ASCII): triangles (cell type 5) or tetrahedra (type 10), with
/// the displacement from `rest` as point data.
pub fn unstructured_grid_vtk<const N: usize>(
    positions: &[Vector3<f64>],
    rest: &[Vector3<f64>],
    cells: &[[usize; N]],
    time: f64,
) -> String {
    let cell_type = match N {
        3 => 5,
        4 => 10,
        _ => 2,
    };
    let mut s = format!(
        "# vtk DataFile Version 3.0\nFreeForm frame t = {time} s\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS {} double\n",
        positions.len()
    );
    for p in positions {
        let _ = writeln!(s, "{} {} {}", p.x, p.y, p.z);
    }
    let _ = writeln!(s, "CELLS {} {}", cells.len(), cells.len() * (N + 1));
    for c in cells {
        s += &N.to_string();
        for v in c {
            let _ = write!(s, " {v}");
        }
        s.push('\n');
    }
    let _ = writeln!(s, "CELL_TYPES {}", cells.len());
    for _ in cells {
        let _ = writeln!(s, "{cell_type}");
    }
    let _ = writeln!(
        s,
        "POINT_DATA {}\nVECTORS displacement double",
        positions.len()
    );
    for (p, r) in positions.iter().zip(rest) {
        let d = p - r;
        let _ = writeln!(s, "{} {} {}", d.x, d.y, d.z);
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ply_and_vtk_headers_state_the_counts_written() {
        let v = vec![Vector3::zeros(), Vector3::x(), Vector3::y(), Vector3::z()];
        let ply = triangle_mesh_ply(&v, &[[0, 1, 2], [0, 2, 3]]);
        assert!(ply.contains("element vertex 4\n") && ply.contains("element face 2\n"));
        assert_eq!(ply.lines().count(), 10 + 4 + 2);
        let vtk = unstructured_grid_vtk(&v, &v, &[[0, 1, 2, 3]], 0.5);
        assert!(vtk.contains("CELLS 1 5\n4 0 1 2 3\n"));
        assert!(vtk.contains("CELL_TYPES 1\n10\n"));
        assert!(vtk.contains("POINT_DATA 4\nVECTORS displacement double\n0 0 0\n"));
    }
}
