//! Reading geometry files: closed triangle meshes (OBJ, STL, PLY) and point clouds (PLY,
//! including 3D Gaussian Splatting files).
//!
//! Parsing is delegated to `tobj` (OBJ), `stl_io` (binary and ASCII STL) and `serde-ply` (PLY,
//! with the property list taken from the header). Every mesh is welded by exact coordinate
//! equality (STL has no shared vertices; split OBJ groups get joined) and validated with
//! [`TriangleMesh::new`].

use std::io::{BufReader, Cursor};
use std::path::{Path, PathBuf};

use nalgebra::{Quaternion, UnitQuaternion, Vector3};
use serde::Deserialize;

use crate::point_cloud::{GaussianSplatAttributes, PointCloud};
use crate::triangle_mesh::{MeshValidationError, TriangleMesh, weld_exact_duplicates};

/// A geometry file could not be turned into a mesh or point cloud.
#[derive(Debug, thiserror::Error)]
pub enum GeometryReadError {
    /// The file could not be read.
    #[error("{path}: cannot read the file: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        source: std::io::Error,
    },
    /// The extension is not one of obj, stl, ply.
    #[error("{path}: unsupported file type (expected .obj, .stl or .ply)")]
    UnsupportedFormat {
        /// The file.
        path: PathBuf,
    },
    /// The file's contents are malformed or truncated.
    #[error("{path}: malformed {format} file: {message}")]
    Parse {
        /// The file.
        path: PathBuf,
        /// "OBJ", "STL" or "PLY".
        format: &'static str,
        /// What the parser reported.
        message: String,
    },
    /// A PLY file lacks a required element or property.
    #[error("{path}: PLY element `{element}` has no property `{property}`")]
    MissingProperty {
        /// The file.
        path: PathBuf,
        /// Element name (e.g. "vertex").
        element: String,
        /// Property name (e.g. "x").
        property: String,
    },
    /// The file parsed but holds no usable data (no faces for a mesh, no vertices for a cloud).
    #[error("{path}: {what}")]
    NoData {
        /// The file.
        path: PathBuf,
        /// What is missing.
        what: String,
    },
    /// A face is not a triangle.
    #[error("{path}: face {face} has {corners} corners; only triangle meshes are supported")]
    NonTriangleFace {
        /// The file.
        path: PathBuf,
        /// Face index.
        face: usize,
        /// Its number of corners.
        corners: usize,
    },
    /// The geometry is not the closed boundary of a solid.
    #[error("{path}: {source}")]
    InvalidMesh {
        /// The file.
        path: PathBuf,
        /// The validation failure.
        source: MeshValidationError,
    },
    /// A point-cloud coordinate is NaN or infinite.
    #[error("{path}: point {index} has a non-finite coordinate")]
    NonFinitePoint {
        /// The file.
        path: PathBuf,
        /// Index of the point.
        index: usize,
    },
}

/// Geometry file formats, chosen by extension (case-insensitive).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GeometryFormat {
    /// Wavefront OBJ (`v`, `f` lines; `f a//n` and `f a/t/n` allowed).
    Obj,
    /// STL, binary or ASCII.
    Stl,
    /// Stanford PLY, ASCII or binary.
    Ply,
}

impl GeometryFormat {
    /// The format named by the path's extension.
    ///
    /// # Errors
    /// [`GeometryReadError::UnsupportedFormat`] for any other extension.
    pub fn from_path(path: &Path) -> Result<Self, GeometryReadError> {
        match path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase)
            .as_deref()
        {
            Some("obj") => Ok(GeometryFormat::Obj),
            Some("stl") => Ok(GeometryFormat::Stl),
            Some("ply") => Ok(GeometryFormat::Ply),
            _ => Err(GeometryReadError::UnsupportedFormat {
                path: path.to_owned(),
            }),
        }
    }
}

/// Reads a closed triangle mesh from an OBJ, STL or PLY file, welds exact duplicate vertices
/// and validates it (closed, consistently and outwardly oriented, finite, non-empty).
///
/// Coordinates are returned in the file's units; see [`TriangleMesh::normalized`].
///
/// # Errors
/// [`GeometryReadError`] naming the file and the problem.
pub fn read_triangle_mesh(path: impl AsRef<Path>) -> Result<TriangleMesh, GeometryReadError> {
    let path = path.as_ref();
    let format = GeometryFormat::from_path(path)?;
    let bytes = read_bytes(path)?;
    parse_triangle_mesh(&bytes, format, path)
}

/// Parses a closed triangle mesh from in-memory bytes (`path` is used in error messages).
///
/// # Errors
/// As [`read_triangle_mesh`].
pub fn parse_triangle_mesh(
    bytes: &[u8],
    format: GeometryFormat,
    path: &Path,
) -> Result<TriangleMesh, GeometryReadError> {
    let (vertices, triangles) = match format {
        GeometryFormat::Obj => parse_obj(bytes, path)?,
        GeometryFormat::Stl => parse_stl(bytes, path)?,
        GeometryFormat::Ply => parse_ply_mesh(bytes, path)?,
    };
    let (vertices, triangles) = weld_exact_duplicates(&vertices, &triangles);
    TriangleMesh::new(vertices, triangles).map_err(|source| GeometryReadError::InvalidMesh {
        path: path.to_owned(),
        source,
    })
}

/// Reads a point cloud from a PLY file: the `vertex` element's `x, y, z`, plus the 3D Gaussian
/// Splatting attributes (`opacity`, `scale_0..2`, `rot_0..3`) when all of them are present.
/// Any other properties (colours, normals, spherical harmonics) are accepted and ignored.
///
/// # Errors
/// [`GeometryReadError`] for unreadable, malformed or truncated files, a missing `vertex`
/// element or coordinate property, an empty cloud, or non-finite coordinates.
pub fn read_point_cloud(path: impl AsRef<Path>) -> Result<PointCloud, GeometryReadError> {
    let path = path.as_ref();
    if GeometryFormat::from_path(path)? != GeometryFormat::Ply {
        return Err(GeometryReadError::UnsupportedFormat {
            path: path.to_owned(),
        });
    }
    parse_point_cloud(&read_bytes(path)?, path)
}

fn read_bytes(path: &Path) -> Result<Vec<u8>, GeometryReadError> {
    std::fs::read(path).map_err(|source| GeometryReadError::Io {
        path: path.to_owned(),
        source,
    })
}

type Soup = (Vec<Vector3<f64>>, Vec<[usize; 3]>);

fn parse_obj(bytes: &[u8], path: &Path) -> Result<Soup, GeometryReadError> {
    let options = tobj::LoadOptions {
        triangulate: false,
        single_index: false,
        ignore_points: true,
        ignore_lines: true,
    };
    let parse_error = |message: String| GeometryReadError::Parse {
        path: path.to_owned(),
        format: "OBJ",
        message,
    };
    let (models, _) = tobj::load_obj_buf(&mut BufReader::new(Cursor::new(bytes)), &options, |_| {
        Err(tobj::LoadError::OpenFileFailed)
    })
    .map_err(|e| parse_error(e.to_string()))?;
    let mut vertices = Vec::new();
    let mut triangles = Vec::new();
    let mut face = 0;
    for model in &models {
        let mesh = &model.mesh;
        let base = vertices.len();
        vertices.extend(
            mesh.positions
                .chunks_exact(3)
                .map(|p| Vector3::new(p[0], p[1], p[2]).cast::<f64>()),
        );
        let mut start = 0;
        // `face_arities` is empty when every face is a triangle.
        let arities: Vec<u32> = if mesh.face_arities.is_empty() {
            vec![3; mesh.indices.len() / 3]
        } else {
            mesh.face_arities.clone()
        };
        for arity in arities {
            let arity = arity as usize;
            if arity != 3 {
                return Err(GeometryReadError::NonTriangleFace {
                    path: path.to_owned(),
                    face,
                    corners: arity,
                });
            }
            let idx = &mesh.indices[start..start + 3];
            triangles.push([0, 1, 2].map(|k| base + idx[k] as usize));
            start += 3;
            face += 1;
        }
    }
    if triangles.is_empty() {
        return Err(GeometryReadError::NoData {
            path: path.to_owned(),
            what: "the OBJ file has no faces".into(),
        });
    }
    Ok((vertices, triangles))
}

fn parse_stl(bytes: &[u8], path: &Path) -> Result<Soup, GeometryReadError> {
    let parse_error = |message: String| GeometryReadError::Parse {
        path: path.to_owned(),
        format: "STL",
        message,
    };
    if bytes.is_empty() {
        return Err(parse_error("the file is empty".into()));
    }
    // stl_io trusts the binary header's triangle count; check it against the file size first so
    // a truncated file is reported as such.
    let looks_ascii = bytes.trim_ascii_start().starts_with(b"solid")
        && bytes.windows(5).take(1024).any(|w| w == b"facet");
    if !looks_ascii {
        if bytes.len() < 84 {
            return Err(parse_error(format!(
                "binary STL shorter than its 84-byte header ({} bytes)",
                bytes.len()
            )));
        }
        let count = u32::from_le_bytes(bytes[80..84].try_into().expect("4 bytes")) as usize;
        let expected = 84 + 50 * count;
        if bytes.len() < expected {
            return Err(parse_error(format!(
                "truncated binary STL: the header announces {count} triangles ({expected} bytes) \
                 but the file has {} bytes",
                bytes.len()
            )));
        }
    }
    let mesh = stl_io::read_stl(&mut Cursor::new(bytes)).map_err(|e| parse_error(e.to_string()))?;
    let vertices = mesh
        .vertices
        .iter()
        .map(|v| Vector3::new(v[0], v[1], v[2]).cast::<f64>())
        .collect();
    let triangles: Vec<[usize; 3]> = mesh.faces.iter().map(|f| f.vertices).collect();
    if triangles.is_empty() {
        return Err(GeometryReadError::NoData {
            path: path.to_owned(),
            what: "the STL file has no triangles".into(),
        });
    }
    Ok((vertices, triangles))
}

/// One PLY vertex row: coordinates plus the optional 3DGS attributes. Properties not named
/// here are skipped by serde.
///
/// `#[serde(default)]` on every optional field is load-bearing: for binary files serde-ply
/// serves the fields as a sequence with absent properties as missing elements, which serde
/// only accepts for fields with a default (without it, every binary PLY lacking one of the
/// 3DGS attributes failed with "invalid length 3, expected struct PlyVertexRow").
#[derive(Deserialize)]
struct PlyVertexRow {
    x: f64,
    y: f64,
    z: f64,
    #[serde(default)]
    opacity: Option<f64>,
    #[serde(default)]
    scale_0: Option<f64>,
    #[serde(default)]
    scale_1: Option<f64>,
    #[serde(default)]
    scale_2: Option<f64>,
    #[serde(default)]
    rot_0: Option<f64>,
    #[serde(default)]
    rot_1: Option<f64>,
    #[serde(default)]
    rot_2: Option<f64>,
    #[serde(default)]
    rot_3: Option<f64>,
}

#[derive(Deserialize)]
struct PlyFaceRow {
    #[serde(alias = "vertex_index")]
    vertex_indices: Vec<i64>,
}

/// A row of an element we do not use; its values are read and dropped.
#[derive(Deserialize)]
struct PlySkippedRow {}

struct PlyContents {
    vertices: Vec<PlyVertexRow>,
    faces: Option<Vec<PlyFaceRow>>,
}

fn parse_ply(bytes: &[u8], path: &Path) -> Result<PlyContents, GeometryReadError> {
    let parse_error = |message: String| GeometryReadError::Parse {
        path: path.to_owned(),
        format: "PLY",
        message,
    };
    let mut reader = serde_ply::PlyReader::from_reader(BufReader::new(Cursor::new(bytes)))
        .map_err(|e| parse_error(e.to_string()))?;
    let missing = |element: &str, property: &str| GeometryReadError::MissingProperty {
        path: path.to_owned(),
        element: element.into(),
        property: property.into(),
    };
    let header = reader.header().clone();
    let vertex_def = header
        .elem_defs
        .iter()
        .find(|e| e.name == "vertex")
        .ok_or_else(|| missing("vertex", "x"))?;
    for axis in ["x", "y", "z"] {
        if !vertex_def.has_property(axis) {
            return Err(missing("vertex", axis));
        }
    }
    let mut vertices = None;
    let mut faces = None;
    for def in &header.elem_defs {
        match def.name.as_str() {
            "vertex" => {
                vertices = Some(
                    reader
                        .next_element::<Vec<PlyVertexRow>>()
                        .map_err(|e| parse_error(format!("vertex data: {e}")))?,
                );
            }
            "face" => {
                if !def.has_property("vertex_indices") && !def.has_property("vertex_index") {
                    return Err(missing("face", "vertex_indices"));
                }
                faces = Some(
                    reader
                        .next_element::<Vec<PlyFaceRow>>()
                        .map_err(|e| parse_error(format!("face data: {e}")))?,
                );
            }
            other => {
                reader
                    .next_element::<Vec<PlySkippedRow>>()
                    .map_err(|e| parse_error(format!("{other} data: {e}")))?;
            }
        }
        let read = match def.name.as_str() {
            "vertex" => vertices.as_ref().map_or(0, Vec::len),
            "face" => faces.as_ref().map_or(0, Vec::len),
            _ => def.count,
        };
        if read != def.count {
            return Err(parse_error(format!(
                "element `{}` announces {} rows but {read} were read (truncated file?)",
                def.name, def.count
            )));
        }
    }
    Ok(PlyContents {
        vertices: vertices.unwrap_or_default(),
        faces,
    })
}

fn parse_ply_mesh(bytes: &[u8], path: &Path) -> Result<Soup, GeometryReadError> {
    let contents = parse_ply(bytes, path)?;
    // No face element at all: a point cloud (e.g. a 3DGS file), which callers that accept
    // clouds recognise by `NoData`.
    let faces = contents.faces.ok_or_else(|| GeometryReadError::NoData {
        path: path.to_owned(),
        what: "the PLY file has no face element (a point cloud, not a mesh)".into(),
    })?;
    let vertices = contents
        .vertices
        .iter()
        .map(|r| Vector3::new(r.x, r.y, r.z))
        .collect::<Vec<_>>();
    let mut triangles = Vec::with_capacity(faces.len());
    for (face, row) in faces.iter().enumerate() {
        if row.vertex_indices.len() != 3 {
            return Err(GeometryReadError::NonTriangleFace {
                path: path.to_owned(),
                face,
                corners: row.vertex_indices.len(),
            });
        }
        // Negative indices become out-of-range ones, which validation reports.
        triangles
            .push([0, 1, 2].map(|k| usize::try_from(row.vertex_indices[k]).unwrap_or(usize::MAX)));
    }
    if triangles.is_empty() {
        return Err(GeometryReadError::NoData {
            path: path.to_owned(),
            what: "the PLY file has no faces".into(),
        });
    }
    Ok((vertices, triangles))
}

/// Parses a PLY point cloud from in-memory bytes (`path` is used in error messages).
///
/// # Errors
/// As [`read_point_cloud`].
pub fn parse_point_cloud(bytes: &[u8], path: &Path) -> Result<PointCloud, GeometryReadError> {
    let rows = parse_ply(bytes, path)?.vertices;
    if rows.is_empty() {
        return Err(GeometryReadError::NoData {
            path: path.to_owned(),
            what: "the PLY file has no vertices".into(),
        });
    }
    let positions: Vec<Vector3<f64>> = rows.iter().map(|r| Vector3::new(r.x, r.y, r.z)).collect();
    if let Some(index) = positions
        .iter()
        .position(|p| !p.iter().all(|c| c.is_finite()))
    {
        return Err(GeometryReadError::NonFinitePoint {
            path: path.to_owned(),
            index,
        });
    }
    let splat_row = |r: &PlyVertexRow| -> Option<(f64, [f64; 3], UnitQuaternion<f64>)> {
        let quaternion = Quaternion::new(r.rot_0?, r.rot_1?, r.rot_2?, r.rot_3?);
        Some((
            r.opacity?,
            [r.scale_0?, r.scale_1?, r.scale_2?],
            // 3DGS stores unnormalized (w, x, y, z) quaternions.
            UnitQuaternion::try_new(quaternion, 0.0)?,
        ))
    };
    let splats: Option<Vec<_>> = rows.iter().map(splat_row).collect();
    let splats = splats.map(|rows| GaussianSplatAttributes {
        opacity_logits: rows.iter().map(|r| r.0).collect(),
        log_scales: rows.iter().map(|r| r.1).collect(),
        rotations: rows.iter().map(|r| r.2).collect(),
    });
    Ok(PointCloud::new(positions, splats))
}
