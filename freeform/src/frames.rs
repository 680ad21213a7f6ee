//! Files a user opens: per-frame PLY (MeshLab, Blender) and legacy VTK (ParaView) of deformed
//! surfaces, point clouds or tet meshes. [`FrameWriter`] writes every file through
//! [`artifact::write_atomically`] (unique temporary name, fsync, rename), so an interrupted run
//! never leaves a half-written file that looks like a result.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use artifact::{ArtifactError, write_atomically};
use nalgebra::Vector3;

use crate::geometry::Geometry;
use crate::stress_field::StressField;

/// Writes `frame_NNNNN.ply` and `frame_NNNNN.vtk` of a deformed geometry into one folder: a
/// triangle surface for a mesh, vertices for a point cloud; the VTK carries the displacement
/// from rest as point data, and the stress when given ([`FrameWriter::write_with_stress`]);
/// `points_NNNNN.vtk` holds the integration points ([`FrameWriter::write_points`]).
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
        self.write_with_stress(index, positions, time, None)
    }

    /// [`FrameWriter::write`], with the stress at the display points (one sample per point, in
    /// their order) as VTK point data when given.
    ///
    /// # Errors
    /// [`ArtifactError`] naming the file that could not be written.
    ///
    /// # Panics
    /// If `stress` does not hold one sample per display point.
    pub fn write_with_stress(
        &self,
        index: usize,
        positions: &[Vector3<f64>],
        time: f64,
        stress: Option<&StressField>,
    ) -> Result<[PathBuf; 2], ArtifactError> {
        let name = self.dir.join(format!("frame_{index:05}"));
        let (ply, vtk) = (name.with_extension("ply"), name.with_extension("vtk"));
        match &self.triangles {
            Some(triangles) => {
                write_atomically(&ply, triangle_mesh_ply(positions, triangles).as_bytes())?;
                write_atomically(
                    &vtk,
                    unstructured_grid_vtk(positions, &self.rest, triangles, time, stress)
                        .as_bytes(),
                )?;
            }
            None => {
                write_atomically(&ply, point_cloud_ply(positions).as_bytes())?;
                let vertices: Vec<[usize; 1]> = (0..positions.len()).map(|i| [i]).collect();
                write_atomically(
                    &vtk,
                    unstructured_grid_vtk(positions, &self.rest, &vertices, time, stress)
                        .as_bytes(),
                )?;
            }
        }
        Ok([ply, vtk])
    }

    /// Writes `points_NNNNN.vtk`: integration points at `positions` (m), their displacement
    /// from `rest` and, when given, their stress; returns the file.
    ///
    /// # Errors
    /// [`ArtifactError`] naming the file that could not be written.
    ///
    /// # Panics
    /// If `rest` or `stress` does not hold one entry per point.
    pub fn write_points(
        &self,
        index: usize,
        positions: &[Vector3<f64>],
        rest: &[Vector3<f64>],
        time: f64,
        stress: Option<&StressField>,
    ) -> Result<PathBuf, ArtifactError> {
        let vtk = self.dir.join(format!("points_{index:05}.vtk"));
        let vertices: Vec<[usize; 1]> = (0..positions.len()).map(|i| [i]).collect();
        write_atomically(
            &vtk,
            unstructured_grid_vtk(positions, rest, &vertices, time, stress).as_bytes(),
        )?;
        Ok(vtk)
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
/// tetrahedra (type 10), with the displacement from `rest` as point data and, when `stress` is
/// given, `cauchy_stress` (tensor, Pa), `principal_stresses` (σ₁ ≥ σ₂ ≥ σ₃, Pa),
/// `von_mises_stress` (Pa) and `inverted` (1 where det F ≤ 0 and the stress is written as 0).
///
/// # Panics
/// If `rest` or `stress` does not hold one entry per position.
pub fn unstructured_grid_vtk<const N: usize>(
    positions: &[Vector3<f64>],
    rest: &[Vector3<f64>],
    cells: &[[usize; N]],
    time: f64,
    stress: Option<&StressField>,
) -> String {
    assert_eq!(rest.len(), positions.len(), "one rest position per point");
    if let Some(stress) = stress {
        assert_eq!(stress.len(), positions.len(), "one stress sample per point");
    }
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
    if let Some(stress) = stress {
        write_stress_point_data(&mut s, stress);
    }
    s
}

/// The stress arrays of [`unstructured_grid_vtk`], appended after its `POINT_DATA` header.
fn write_stress_point_data(s: &mut String, stress: &StressField) {
    s.push_str("TENSORS cauchy_stress double\n");
    for sample in &stress.samples {
        for r in 0..3 {
            let row = sample.cauchy.row(r);
            let _ = writeln!(s, "{} {} {}", row[0], row[1], row[2]);
        }
    }
    s.push_str("VECTORS principal_stresses double\n");
    for sample in &stress.samples {
        let p = sample.principal;
        let _ = writeln!(s, "{} {} {}", p.x, p.y, p.z);
    }
    s.push_str("SCALARS von_mises_stress double 1\nLOOKUP_TABLE default\n");
    for sample in &stress.samples {
        let _ = writeln!(s, "{}", sample.von_mises);
    }
    s.push_str("SCALARS inverted int 1\nLOOKUP_TABLE default\n");
    let mut inverted = stress.inverted.iter().peekable();
    for i in 0..stress.len() {
        let flag = inverted.next_if_eq(&&i).is_some();
        let _ = writeln!(s, "{}", u8::from(flag));
    }
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
        let vtk = unstructured_grid_vtk(&v, &v, &[[0, 1, 2, 3]], 0.5, None);
        assert!(vtk.contains("CELLS 1 5\n4 0 1 2 3\n"));
        assert!(vtk.contains("CELL_TYPES 1\n10\n"));
        assert!(vtk.contains("POINT_DATA 4\nVECTORS displacement double\n0 0 0\n"));
        let cloud = point_cloud_ply(&v);
        assert!(cloud.contains("element vertex 4\n") && !cloud.contains("element face"));
        assert_eq!(cloud.lines().count(), 8 + 4);
    }

    #[test]
    fn the_stress_arrays_hold_one_value_per_point_in_order_with_the_inverted_flagged() {
        use hyperelastic::StressSample;
        use nalgebra::Matrix3;
        let v = vec![Vector3::zeros(), Vector3::x(), Vector3::y()];
        let sample = |k: f64| StressSample {
            cauchy: Matrix3::from_fn(|r, c| k + (3 * r + c) as f64),
            principal: Vector3::new(3.0 * k, 2.0 * k, k),
            von_mises: 10.0 * k,
        };
        let stress = StressField {
            samples: vec![sample(1.0), sample(0.0), sample(2.0)],
            inverted: vec![1],
        };
        let vtk = unstructured_grid_vtk(&v, &v, &[[0], [1], [2]], 0.0, Some(&stress));
        let after = |header: &str| -> Vec<String> {
            let start = vtk.find(header).unwrap() + header.len();
            vtk[start..].lines().take(9).map(str::to_string).collect()
        };
        assert_eq!(
            after("TENSORS cauchy_stress double\n")[..3],
            ["1 2 3", "4 5 6", "7 8 9"]
        );
        assert_eq!(after("TENSORS cauchy_stress double\n")[6], "2 3 4");
        assert_eq!(
            after("VECTORS principal_stresses double\n")[..3],
            ["3 2 1", "0 0 0", "6 4 2"]
        );
        assert_eq!(
            after("SCALARS von_mises_stress double 1\nLOOKUP_TABLE default\n")[..3],
            ["10", "0", "20"]
        );
        assert_eq!(
            after("SCALARS inverted int 1\nLOOKUP_TABLE default\n")[..3],
            ["0", "1", "0"]
        );
    }
}
