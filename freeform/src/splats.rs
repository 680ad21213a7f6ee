//! 3D Gaussian Splatting files, deformed: the vertex table read as it is (every property kept,
//! in its order and type), and each splat's centre moved and covariance transformed by the
//! deformation gradient at its centre, `Σ' = F Σ Fᵀ` (PhysGaussian's rule), written back as
//! log-scales and a unit `(w, x, y, z)` quaternion in the same layout.
//!
//! Scope: binary little-endian PLY with one `vertex` element of scalar properties (what 3DGS
//! trainers write). Higher-order spherical harmonics (`f_rest_*`, degree 1 to 3, channel-major
//! as 3DGS writes them) are rotated by the polar rotation R of F (PhysGaussian's rule,
//! [`crate::spherical_harmonics`]); opacity, DC colour and every other property pass through
//! untouched.

use std::path::{Path, PathBuf};

use hyperelastic::polar_rotation;
use nalgebra::{DVector, Matrix3, Quaternion, SymmetricEigen, UnitQuaternion, Vector3};

use crate::spherical_harmonics::{ShRotation, degree_of_rest_columns, rest_coefficients};
use thiserror::Error;

/// A 3DGS file could not be read, deformed or written.
#[derive(Debug, Error)]
pub enum SplatFileError {
    /// The file could not be read.
    #[error("{path}: cannot read the file")]
    Read {
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// The header or data is not a supported 3DGS PLY.
    #[error("{path}: {problem}")]
    Format {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        problem: String,
    },
    /// A property every 3DGS file has is missing.
    #[error("{path}: the vertex element has no `{property}` property")]
    MissingProperty {
        /// The file.
        path: PathBuf,
        /// The property.
        property: &'static str,
    },
    /// Positions or deformation gradients do not match the splats.
    #[error("{given} {what} for {splats} splats")]
    CountMismatch {
        /// "positions" or "deformation gradients".
        what: &'static str,
        /// How many were given.
        given: usize,
        /// How many splats there are.
        splats: usize,
    },
    /// The file could not be written.
    #[error(transparent)]
    Write(#[from] artifact::ArtifactError),
}

/// A scalar type of a PLY property.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    fn parse(name: &str) -> Option<Self> {
        Some(match name {
            "char" | "int8" => Scalar::I8,
            "uchar" | "uint8" => Scalar::U8,
            "short" | "int16" => Scalar::I16,
            "ushort" | "uint16" => Scalar::U16,
            "int" | "int32" => Scalar::I32,
            "uint" | "uint32" => Scalar::U32,
            "float" | "float32" => Scalar::F32,
            "double" | "float64" => Scalar::F64,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }
}

/// One property of the vertex element: its name, type and byte offset in a row.
#[derive(Clone, Debug, PartialEq)]
struct Property {
    name: String,
    scalar: Scalar,
    offset: usize,
}

/// The vertex table of a 3DGS PLY file, byte for byte, with typed access to the properties
/// the deformation changes.
#[derive(Clone, Debug, PartialEq)]
pub struct SplatTable {
    header: String,
    properties: Vec<Property>,
    row_size: usize,
    rows: Vec<u8>,
    count: usize,
    columns: Columns,
}

/// The column indices of the properties a deformation rewrites.
#[derive(Clone, Debug, PartialEq)]
struct Columns {
    position: [usize; 3],
    scale: [usize; 3],
    rotation: [usize; 4],
    /// `f_rest_0, f_rest_1, …` in order, and their SH degree, when there are 9, 24 or 45.
    sh_rest: Option<(Vec<usize>, usize)>,
}

impl SplatTable {
    /// Reads a binary little-endian 3DGS PLY (one `vertex` element of scalar properties).
    ///
    /// # Errors
    /// [`SplatFileError::Read`], or [`SplatFileError::Format`] naming what is unsupported or
    /// truncated; [`SplatFileError::MissingProperty`] for a file without `x`, `scale_0` or
    /// `rot_0` and their siblings.
    pub fn read(path: &Path) -> Result<Self, SplatFileError> {
        let bytes = std::fs::read(path).map_err(|source| SplatFileError::Read {
            path: path.to_owned(),
            source,
        })?;
        Self::parse(&bytes, path)
    }

    fn parse(bytes: &[u8], path: &Path) -> Result<Self, SplatFileError> {
        let bad = |problem: String| SplatFileError::Format {
            path: path.to_owned(),
            problem,
        };
        let end = b"end_header\n";
        let header_end = bytes
            .windows(end.len())
            .position(|w| w == end)
            .ok_or_else(|| bad("no `end_header` line".into()))?
            + end.len();
        let header = std::str::from_utf8(&bytes[..header_end])
            .map_err(|_| bad("the header is not text".into()))?
            .to_string();
        let mut lines = header.lines();
        if lines.next() != Some("ply") {
            return Err(bad("not a PLY file".into()));
        }
        let (mut count, mut properties, mut row_size, mut in_vertex) = (None, Vec::new(), 0, false);
        for line in lines {
            let words: Vec<&str> = line.split_whitespace().collect();
            match words.as_slice() {
                ["format", "binary_little_endian", _] => {}
                ["format", other, _] => {
                    return Err(bad(format!(
                        "format {other} (3DGS files are binary_little_endian)"
                    )));
                }
                ["element", "vertex", n] => {
                    count = Some(
                        n.parse::<usize>()
                            .map_err(|_| bad(format!("vertex count {n}")))?,
                    );
                    in_vertex = true;
                }
                ["element", name, _] => {
                    return Err(bad(format!(
                        "element `{name}` (a 3DGS file has only vertices)"
                    )));
                }
                ["property", "list", ..] => {
                    return Err(bad("a list property (a 3DGS file has only scalars)".into()));
                }
                ["property", ty, name] if in_vertex => {
                    let scalar =
                        Scalar::parse(ty).ok_or_else(|| bad(format!("property type {ty}")))?;
                    properties.push(Property {
                        name: name.to_string(),
                        scalar,
                        offset: row_size,
                    });
                    row_size += scalar.size();
                }
                _ => {}
            }
        }
        let count = count.ok_or_else(|| bad("no vertex element".into()))?;
        let rows = bytes[header_end..].to_vec();
        if rows.len() != count * row_size {
            return Err(bad(format!(
                "{} bytes of vertex data for {count} vertices of {row_size} bytes",
                rows.len()
            )));
        }
        let columns = Self::columns(&properties, path)?;
        Ok(SplatTable {
            header,
            properties,
            row_size,
            rows,
            count,
            columns,
        })
    }

    fn columns(properties: &[Property], path: &Path) -> Result<Columns, SplatFileError> {
        let find = |property: &'static str| {
            properties
                .iter()
                .position(|p| p.name == property)
                .ok_or_else(|| SplatFileError::MissingProperty {
                    path: path.to_owned(),
                    property,
                })
        };
        Ok(Columns {
            position: [find("x")?, find("y")?, find("z")?],
            scale: [find("scale_0")?, find("scale_1")?, find("scale_2")?],
            rotation: [
                find("rot_0")?,
                find("rot_1")?,
                find("rot_2")?,
                find("rot_3")?,
            ],
            sh_rest: {
                let rest: Vec<usize> = (0..)
                    .map_while(|k| {
                        let name = format!("f_rest_{k}");
                        properties.iter().position(|p| p.name == name)
                    })
                    .collect();
                degree_of_rest_columns(rest.len()).map(|degree| (rest, degree))
            },
        })
    }

    /// Number of splats.
    pub fn len(&self) -> usize {
        self.count
    }

    /// Whether the file holds no splat.
    pub fn is_empty(&self) -> bool {
        self.count == 0
    }

    /// The property names, in file order.
    pub fn property_names(&self) -> Vec<&str> {
        self.properties.iter().map(|p| p.name.as_str()).collect()
    }

    /// The values of property `name` for every splat, or `None` if the file has none.
    pub fn column(&self, name: &str) -> Option<Vec<f64>> {
        let column = self.properties.iter().position(|p| p.name == name)?;
        Some((0..self.count).map(|i| self.get(i, column)).collect())
    }

    fn get(&self, row: usize, column: usize) -> f64 {
        let p = &self.properties[column];
        let at = row * self.row_size + p.offset;
        let b = &self.rows[at..at + p.scalar.size()];
        match p.scalar {
            Scalar::I8 => f64::from(b[0] as i8),
            Scalar::U8 => f64::from(b[0]),
            Scalar::I16 => f64::from(i16::from_le_bytes([b[0], b[1]])),
            Scalar::U16 => f64::from(u16::from_le_bytes([b[0], b[1]])),
            Scalar::I32 => f64::from(i32::from_le_bytes([b[0], b[1], b[2], b[3]])),
            Scalar::U32 => f64::from(u32::from_le_bytes([b[0], b[1], b[2], b[3]])),
            Scalar::F32 => f64::from(f32::from_le_bytes([b[0], b[1], b[2], b[3]])),
            Scalar::F64 => f64::from_le_bytes(b.try_into().unwrap_or([0; 8])),
        }
    }

    /// Writes `value` into a float column (the columns a deformation rewrites are floats in
    /// every 3DGS file; an integer column is left as it was).
    fn set(&mut self, row: usize, column: usize, value: f64) {
        let p = &self.properties[column];
        let at = row * self.row_size + p.offset;
        match p.scalar {
            Scalar::F32 => self.rows[at..at + 4].copy_from_slice(&(value as f32).to_le_bytes()),
            Scalar::F64 => self.rows[at..at + 8].copy_from_slice(&value.to_le_bytes()),
            _ => {}
        }
    }

    /// Splat centres (file units).
    pub fn positions(&self) -> Vec<Vector3<f64>> {
        let c = &self.columns;
        (0..self.count)
            .map(|i| Vector3::from_fn(|d, _| self.get(i, c.position[d])))
            .collect()
    }

    /// Splat covariances `Σ = R diag(exp(2 s)) Rᵀ` (file units²), R from the `(w, x, y, z)`
    /// quaternion `rot_0..3` (normalized), s the log-scales `scale_0..2`.
    pub fn covariances(&self) -> Vec<Matrix3<f64>> {
        let c = &self.columns;
        (0..self.count)
            .map(|i| {
                let q = UnitQuaternion::from_quaternion(Quaternion::new(
                    self.get(i, c.rotation[0]),
                    self.get(i, c.rotation[1]),
                    self.get(i, c.rotation[2]),
                    self.get(i, c.rotation[3]),
                ));
                let r = q.to_rotation_matrix().into_inner();
                let s = Vector3::from_fn(|d, _| (2.0 * self.get(i, c.scale[d])).exp());
                r * Matrix3::from_diagonal(&s) * r.transpose()
            })
            .collect()
    }

    /// The table deformed: centre i moved to `positions[i]`, covariance `Σ' = F_i Σ F_iᵀ`
    /// written back as log-scales `½ ln λ` and the unit quaternion (det +1, w ≥ 0) of Σ''s
    /// eigenvectors. Returns the table and the number of splats with `det F ≤ 0` (inverted;
    /// their covariance is still `F Σ Fᵀ`, a valid ellipsoid).
    ///
    /// # Errors
    /// [`SplatFileError::CountMismatch`] when the slices do not have one entry per splat.
    pub fn deformed(
        &self,
        positions: &[Vector3<f64>],
        gradients: &[Matrix3<f64>],
    ) -> Result<(SplatTable, usize), SplatFileError> {
        for (what, given) in [
            ("positions", positions.len()),
            ("deformation gradients", gradients.len()),
        ] {
            if given != self.count {
                return Err(SplatFileError::CountMismatch {
                    what,
                    given,
                    splats: self.count,
                });
            }
        }
        let c = &self.columns;
        let mut out = self.clone();
        let mut inverted = 0;
        let sh = c
            .sh_rest
            .as_ref()
            .map(|(columns, degree)| (columns, *degree, ShRotation::new(*degree)));
        for (i, (sigma, (x, f))) in self
            .covariances()
            .into_iter()
            .zip(positions.iter().zip(gradients))
            .enumerate()
        {
            inverted += usize::from(f.determinant() <= 0.0);
            for d in 0..3 {
                out.set(i, c.position[d], x[d]);
            }
            let (log_scales, rotation) = scale_and_rotation(&(f * sigma * f.transpose()));
            for d in 0..3 {
                out.set(i, c.scale[d], log_scales[d]);
            }
            let q = rotation.quaternion();
            for (k, v) in [q.w, q.i, q.j, q.k].into_iter().enumerate() {
                out.set(i, c.rotation[k], v);
            }
            if let Some((columns, degree, rotation)) = &sh {
                let t = rotation.matrix(&polar_rotation(f));
                let n = rest_coefficients(*degree);
                for channel in columns.chunks(n) {
                    let coefficients =
                        DVector::from_iterator(n, channel.iter().map(|&col| self.get(i, col)));
                    for (&col, v) in channel.iter().zip((&t * coefficients).iter()) {
                        out.set(i, col, *v);
                    }
                }
            }
        }
        Ok((out, inverted))
    }

    /// The file's bytes: the header as read and the vertex rows.
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut bytes = self.header.as_bytes().to_vec();
        bytes.extend_from_slice(&self.rows);
        bytes
    }

    /// Writes the table atomically ([`artifact::write_atomically`]).
    ///
    /// # Errors
    /// [`SplatFileError::Write`] naming the file.
    pub fn write(&self, path: &Path) -> Result<(), SplatFileError> {
        Ok(artifact::write_atomically(path, &self.to_bytes())?)
    }
}

/// Log-scales `½ ln λ_k` and the rotation (det +1, w ≥ 0) whose columns are the eigenvectors of
/// a symmetric positive (semi-)definite covariance; eigenvalues are clamped to 1e-30 so that a
/// flattened splat keeps a finite log-scale.
pub fn scale_and_rotation(covariance: &Matrix3<f64>) -> (Vector3<f64>, UnitQuaternion<f64>) {
    let eigen = SymmetricEigen::new(*covariance);
    let mut axes = eigen.eigenvectors;
    if axes.determinant() < 0.0 {
        let flipped = -axes.column(2);
        axes.set_column(2, &flipped);
    }
    let rotation =
        UnitQuaternion::from_rotation_matrix(&nalgebra::Rotation3::from_matrix_unchecked(axes));
    let rotation = if rotation.w < 0.0 {
        UnitQuaternion::new_unchecked(-rotation.into_inner())
    } else {
        rotation
    };
    let log_scales = eigen.eigenvalues.map(|l| 0.5 * l.max(1e-30).ln());
    (log_scales, rotation)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn covariance(log_scales: &Vector3<f64>, rotation: &UnitQuaternion<f64>) -> Matrix3<f64> {
        let r = rotation.to_rotation_matrix().into_inner();
        r * Matrix3::from_diagonal(&log_scales.map(|s| (2.0 * s).exp())) * r.transpose()
    }

    #[test]
    fn scale_and_rotation_reproduce_an_affinely_deformed_covariance() {
        let sigma = covariance(
            &Vector3::new(-3.0, -2.5, -4.0),
            &UnitQuaternion::from_euler_angles(0.3, -0.7, 1.1),
        );
        let f = Matrix3::new(1.2, 0.3, -0.1, 0.05, 0.8, 0.2, -0.4, 0.1, 1.5);
        let target = f * sigma * f.transpose();
        let (s, q) = scale_and_rotation(&target);
        let rebuilt = covariance(&s, &q);
        assert!((rebuilt - target).norm() < 1e-6 * target.norm());
        assert!((q.norm() - 1.0).abs() < 1e-12 && q.w >= 0.0);
    }

    #[test]
    fn a_rigid_rotation_keeps_the_scales_and_rotates_the_ellipsoid() {
        let scales = Vector3::new(-1.0, -2.0, -3.0);
        let q0 = UnitQuaternion::from_euler_angles(0.2, 0.1, -0.5);
        let r = UnitQuaternion::from_euler_angles(1.0, -0.4, 0.7);
        let rm = r.to_rotation_matrix().into_inner();
        let (s, q) = scale_and_rotation(&(rm * covariance(&scales, &q0) * rm.transpose()));
        let mut sorted = [s.x, s.y, s.z];
        sorted.sort_by(f64::total_cmp);
        assert!((sorted[0] + 3.0).abs() < 1e-9 && (sorted[1] + 2.0).abs() < 1e-9);
        assert!((sorted[2] + 1.0).abs() < 1e-9);
        // The largest axis of the new ellipsoid is the rotated largest axis of the old one.
        let old_axis = q0 * Vector3::x();
        let k = (0..3).max_by(|&a, &b| s[a].total_cmp(&s[b])).unwrap_or(0);
        let new_axis = q * Vector3::ith(k, 1.0);
        assert!((new_axis.dot(&(r * old_axis))).abs() > 1.0 - 1e-9);
    }
}
