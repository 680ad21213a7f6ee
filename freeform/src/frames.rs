//! Files a user opens: per-frame PLY (MeshLab, Blender) and legacy VTK (ParaView) of deformed
//! surfaces, point clouds or tet meshes. [`FrameWriter`] writes every file through
//! [`artifact::write_atomically`] (unique temporary name, fsync, rename), so an interrupted run
//! never leaves a half-written file that looks like a result.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use artifact::{ArtifactError, write_atomically};
use nalgebra::Vector3;

use crate::geometry::Geometry;

/// Writes `frame_NNNNN.ply` and `frame_NNNNN.vtk` of a deformed geometry into one folder: a
/// triangle surface for a mesh, vertices for a point cloud; the VTK carries the displacement
/// from rest as point data.
#[derive(Clone, Debug)]
pub struct FrameWriter {
    dir: PathBuf,
    rest: Vec<Vector3<f64>>,
    triangles: Option<Vec<[usize; 3]>>,
}

impl FrameWriter {
    /// A writer into `dir` for `geometry`'s display points ([`Geometry::display_points`]).
    pub fn new(dir: impl Into<PathBuf>, geometry: &Geometry) -> Self {
        FrameWriter {
            dir: dir.into(),
            rest: geometry.display_points().to_vec(),
            triangles: geometry.surface().map(|s| s.triangles().to_vec()),
        }
    }

    /// The rest positions the frames deform (m): where a [`reduced_sim::DeformationMap`] for
    /// the frames must be evaluated.
    pub fn rest_positions(&self) -> &[Vector3<f64>] {
        &self.rest
    }

    /// Writes frame `index` at time `time` (s) with the display points at `positions` (m, in
    /// the order of [`FrameWriter::rest_positions`]); returns the two files.
    ///
    /// # Errors
    /// [`ArtifactError`] naming the file that could not be written.
    pub fn write(
        &self,
        index: usize,
        positions: &[Vector3<f64>],
        time: f64,
    ) -> Result<[PathBuf; 2], ArtifactError> {
        let name = self.dir.join(format!("frame_{index:05}"));
        let (ply, vtk) = (name.with_extension("ply"), name.with_extension("vtk"));
        match &self.triangles {
            Some(triangles) => {
                write_atomically(&ply, triangle_mesh_ply(positions, triangles).as_bytes())?;
                write_atomically(
                    &vtk,
                    unstructured_grid_vtk(positions, &self.rest, triangles, time).as_bytes(),
                )?;
            }
            None => {
                write_atomically(&ply, point_cloud_ply(positions).as_bytes())?;
                let vertices: Vec<[usize; 1]> = (0..positions.len()).map(|i| [i]).collect();
                write_atomically(
                    &vtk,
                    unstructured_grid_vtk(positions, &self.rest, &vertices, time).as_bytes(),
                )?;
            }
        }
        Ok([ply, vtk])
    }

    /// The folder written into.
    pub fn dir(&self) -> &Path {
        &self.dir
    }
}

/// ASCII PLY of points (no faces).
pub fn point_cloud_ply(vertices: &[Vector3<f64>]) -> String {
    let mut s = format!(
        "ply\nformat ascii 1.0\ncomment FreeForm frame\nelement vertex {}\nproperty float x\n\
         property float y\nproperty float z\nend_header\n",
        vertices.len()
    );
    for v in vertices {
        let _ = writeln!(s, "{} {} {}", v.x, v.y, v.z);
    }
    s
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

/// Legacy-VTK unstructured grid (ASCII): vertices (cell type 1), triangles (type 5) or
/// tetrahedra (type 10), with the displacement from `rest` as point data.
pub fn unstructured_grid_vtk<const N: usize>(
    positions: &[Vector3<f64>],
    rest: &[Vector3<f64>],
    cells: &[[usize; N]],
    time: f64,
) -> String {
    let cell_type = match N {
        1 => 1,
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
        let cloud = point_cloud_ply(&v);
        assert!(cloud.contains("element vertex 4\n") && !cloud.contains("element face"));
        assert_eq!(cloud.lines().count(), 8 + 4);
    }
}
