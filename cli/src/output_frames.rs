//! A `simulate` run's output folder read back, for the viewer and the preview: its objects
//! (the folder itself for one object, one sub-folder each for several), their frames (the VTK
//! files with positions, triangles and von Mises stress, or the 3DGS PLY files of a splat
//! scene), the colliders' surfaces per frame and the scene's floor and up (`scene.json`).

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use freeform::{SceneSpec, SplatTable, preview_splats};
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

/// What `simulate` writes beside the frames for the viewer (`scene.json`): the time step, the
/// scene's up and its floor.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub(crate) struct SceneInfo {
    /// h (s): frame `NNNNN` is at `NNNNN · h`.
    pub time_step: f64,
    /// The unit direction against gravity (+y without gravity).
    pub up: [f64; 3],
    /// The floor `n · x = offset` (unit n, m), if any.
    pub floor: Option<FloorInfo>,
}

/// The floor plane `n · x = offset`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub(crate) struct FloorInfo {
    /// Unit normal, pointing into the allowed side.
    pub normal: [f64; 3],
    /// Offset (m).
    pub offset: f64,
}

impl SceneInfo {
    /// The file's name in an output folder.
    pub const FILE: &'static str = "scene.json";

    /// The viewer's description of `scene` stepped by `time_step` (s).
    pub fn new(scene: &SceneSpec, time_step: f64) -> Self {
        let up = scene
            .gravity
            .filter(|g| g.norm() > 0.0)
            .map_or(Vector3::y(), |g| -g.normalize());
        SceneInfo {
            time_step,
            up: up.into(),
            floor: scene.floor.map(|f| {
                let n = f.normal.norm();
                FloorInfo {
                    normal: (f.normal / n).into(),
                    offset: f.offset / n,
                }
            }),
        }
    }

    /// Writes `scene.json` into `dir`.
    pub fn write(&self, dir: &Path) -> Result<()> {
        let path = dir.join(Self::FILE);
        artifact::write_atomically(&path, &serde_json::to_vec_pretty(self)?)?;
        Ok(())
    }
}

/// One object's frames.
#[derive(Clone, Debug)]
pub(crate) struct ObjectFrames {
    /// The folder's name.
    pub name: String,
    /// The surface's triangles (vertex indices), or `None` for points.
    pub triangles: Option<Vec<[u32; 3]>>,
    /// Each point's colour (linear RGB in [0, 1]) for a splat scene (its DC colour).
    pub colours: Option<Vec<[f32; 3]>>,
    /// The frames, by increasing index.
    pub frames: Vec<ObjectFrame>,
}

/// One object at one frame.
#[derive(Clone, Debug)]
pub(crate) struct ObjectFrame {
    /// The step the frame was written at.
    pub index: usize,
    /// Point positions (m).
    pub positions: Vec<Vector3<f64>>,
    /// Each point's displacement since the object's first frame, |x − x₀| (m): the motion
    /// the run made (a placed object's VTK displacement also holds its placement).
    pub displacement: Vec<f64>,
    /// Each point's von Mises stress (Pa), when the run wrote the stress.
    pub von_mises: Option<Vec<f64>>,
}

/// All colliders' surfaces at one frame, as one triangle mesh.
#[derive(Clone, Debug)]
pub(crate) struct ColliderFrame {
    /// The step the frame was written at.
    pub index: usize,
    /// Vertex positions (m).
    pub vertices: Vec<Vector3<f64>>,
    /// Triangles (vertex indices).
    pub triangles: Vec<[u32; 3]>,
}

/// A run's output folder, read back.
#[derive(Clone, Debug)]
pub(crate) struct RunOutput {
    /// The folder.
    pub dir: PathBuf,
    /// The objects, by name.
    pub objects: Vec<ObjectFrames>,
    /// The colliders per frame (empty without colliders).
    pub colliders: Vec<ColliderFrame>,
    /// The floor, the up direction and the time step (defaults when `scene.json` is missing:
    /// +y up, no floor, frames labelled by step).
    pub scene: Option<SceneInfo>,
}

/// A scalar per point that the viewer and the preview colour by.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Scalar {
    /// von Mises stress (Pa).
    VonMises,
    /// |x − x₀| since the first frame (m).
    Displacement,
}

impl Scalar {
    /// The name shown beside the colour bar.
    pub fn label(self) -> &'static str {
        match self {
            Scalar::VonMises => "von Mises stress",
            Scalar::Displacement => "displacement from start",
        }
    }

    /// The SI unit.
    pub fn unit(self) -> &'static str {
        match self {
            Scalar::VonMises => "Pa",
            Scalar::Displacement => "m",
        }
    }

    /// The scalar's values at `frame`, if the run wrote them.
    pub fn values(self, frame: &ObjectFrame) -> Option<&[f64]> {
        match self {
            Scalar::VonMises => frame.von_mises.as_deref(),
            Scalar::Displacement => Some(&frame.displacement),
        }
    }
}

impl RunOutput {
    /// Reads the output folder `dir` of `freeform simulate`.
    ///
    /// # Errors
    /// When `dir` holds no frames, or a frame file cannot be read or parsed (naming it).
    pub fn read(dir: &Path) -> Result<Self> {
        let mut object_dirs = Vec::new();
        if !frame_indices(dir)?.is_empty() {
            object_dirs.push(dir.to_path_buf());
        } else {
            let mut entries: Vec<PathBuf> = std::fs::read_dir(dir)
                .with_context(|| format!("{}: cannot list the folder", dir.display()))?
                .filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| p.is_dir())
                .collect();
            entries.sort();
            for entry in entries {
                if !frame_indices(&entry)?.is_empty() {
                    object_dirs.push(entry);
                }
            }
        }
        if object_dirs.is_empty() {
            bail!(
                "{}: no frames (frame_NNNNN.ply) here or in its sub-folders; run `freeform \
                 simulate` first",
                dir.display()
            );
        }
        let objects = object_dirs
            .iter()
            .map(|d| read_object(d))
            .collect::<Result<Vec<_>>>()?;
        let mut colliders = Vec::new();
        for index in numbered_files(dir, "colliders_", "ply")? {
            let path = dir.join(format!("colliders_{index:05}.ply"));
            colliders.push(read_collider_ply(&path, index)?);
        }
        let scene_path = dir.join(SceneInfo::FILE);
        let scene =
            if scene_path.exists() {
                let bytes = std::fs::read(&scene_path)
                    .with_context(|| format!("{}: cannot read", scene_path.display()))?;
                Some(serde_json::from_slice(&bytes).with_context(|| {
                    format!("{}: not a scene description", scene_path.display())
                })?)
            } else {
                None
            };
        Ok(RunOutput {
            dir: dir.to_path_buf(),
            objects,
            colliders,
            scene,
        })
    }

    /// The frame indices every object has, increasing.
    pub fn frame_indices(&self) -> Vec<usize> {
        let mut common: Option<BTreeSet<usize>> = None;
        for object in &self.objects {
            let indices: BTreeSet<usize> = object.frames.iter().map(|f| f.index).collect();
            common = Some(match common {
                None => indices,
                Some(c) => c.intersection(&indices).copied().collect(),
            });
        }
        common.unwrap_or_default().into_iter().collect()
    }

    /// The colour scalar: von Mises where every frame of every object has it, else the
    /// displacement.
    pub fn scalars(&self) -> Vec<Scalar> {
        let stress = self
            .objects
            .iter()
            .all(|o| o.frames.iter().all(|f| f.von_mises.is_some()));
        if stress {
            vec![Scalar::VonMises, Scalar::Displacement]
        } else {
            vec![Scalar::Displacement]
        }
    }

    /// The up direction (+y without `scene.json`).
    pub fn up(&self) -> Vector3<f64> {
        self.scene.as_ref().map_or(Vector3::y(), |s| s.up.into())
    }

    /// The collider surfaces written at frame `index`, if any.
    pub fn colliders_at(&self, index: usize) -> Option<&ColliderFrame> {
        self.colliders.iter().find(|c| c.index == index)
    }
}

/// The indices `N` of `frame_N.ply` files in `dir`, increasing.
fn frame_indices(dir: &Path) -> Result<Vec<usize>> {
    numbered_files(dir, "frame_", "ply")
}

/// The indices `N` of `{prefix}N.{extension}` files in `dir`, increasing.
fn numbered_files(dir: &Path, prefix: &str, extension: &str) -> Result<Vec<usize>> {
    let mut indices: Vec<usize> = std::fs::read_dir(dir)
        .with_context(|| format!("{}: cannot list the folder", dir.display()))?
        .filter_map(|entry| {
            let name = entry.ok()?.file_name().into_string().ok()?;
            let stem = name.strip_prefix(prefix)?.strip_suffix(extension)?;
            stem.strip_suffix('.')?.parse().ok()
        })
        .collect();
    indices.sort_unstable();
    Ok(indices)
}

/// One object's frames from `dir`: the VTK beside each PLY, or the PLY as a 3DGS file.
fn read_object(dir: &Path) -> Result<ObjectFrames> {
    let name = dir
        .file_name()
        .map_or_else(|| "object".into(), |n| n.to_string_lossy().into_owned());
    let mut object = ObjectFrames {
        name,
        triangles: None,
        colours: None,
        frames: Vec::new(),
    };
    for index in frame_indices(dir)? {
        let vtk = dir.join(format!("frame_{index:05}.vtk"));
        let frame = if vtk.exists() {
            let text = std::fs::read_to_string(&vtk)
                .with_context(|| format!("{}: cannot read", vtk.display()))?;
            let parsed = parse_vtk(&text)
                .with_context(|| format!("{}: not a FreeForm frame", vtk.display()))?;
            if object.triangles.is_none() && !parsed.triangles.is_empty() {
                object.triangles = Some(parsed.triangles);
            }
            ObjectFrame {
                index,
                positions: parsed.positions,
                displacement: Vec::new(),
                von_mises: parsed.von_mises,
            }
        } else {
            let ply = dir.join(format!("frame_{index:05}.ply"));
            let table = SplatTable::read(&ply)?;
            let splats = preview_splats(&table)?;
            if object.colours.is_none() {
                object.colours = Some(
                    splats
                        .iter()
                        .map(|s| s.colour.map(|c| c.clamp(0.0, 1.0) as f32))
                        .collect(),
                );
            }
            ObjectFrame {
                index,
                positions: splats.iter().map(|s| s.position).collect(),
                displacement: Vec::new(),
                von_mises: None,
            }
        };
        if let Some(first) = object.frames.first()
            && first.positions.len() != frame.positions.len()
        {
            bail!(
                "{}: frame {index} has {} points, frame {} had {}",
                dir.display(),
                frame.positions.len(),
                first.index,
                first.positions.len()
            );
        }
        object.frames.push(frame);
    }
    let start = object.frames[0].positions.clone();
    for frame in &mut object.frames {
        frame.displacement = frame
            .positions
            .iter()
            .zip(&start)
            .map(|(p, p0)| (p - p0).norm())
            .collect();
    }
    Ok(object)
}

/// What the viewer needs of one of `FrameWriter`'s VTK files.
struct VtkFrame {
    positions: Vec<Vector3<f64>>,
    triangles: Vec<[u32; 3]>,
    von_mises: Option<Vec<f64>>,
}

/// Parses the legacy ASCII unstructured grid that `freeform::FrameWriter` writes.
fn parse_vtk(text: &str) -> Result<VtkFrame> {
    // The first two lines (version, title) may hold anything.
    let body = text.splitn(3, '\n').nth(2).context("no header")?;
    let mut tokens = body.split_ascii_whitespace();
    let mut frame = VtkFrame {
        positions: Vec::new(),
        triangles: Vec::new(),
        von_mises: None,
    };
    let number = |tokens: &mut std::str::SplitAsciiWhitespace<'_>| -> Result<f64> {
        let token = tokens.next().context("the file ends early")?;
        token
            .parse::<f64>()
            .with_context(|| format!("`{token}` is not a number"))
    };
    while let Some(token) = tokens.next() {
        match token {
            "POINTS" => {
                let n = number(&mut tokens)? as usize;
                tokens.next();
                frame.positions = (0..n)
                    .map(|_| {
                        Ok(Vector3::new(
                            number(&mut tokens)?,
                            number(&mut tokens)?,
                            number(&mut tokens)?,
                        ))
                    })
                    .collect::<Result<_>>()?;
            }
            "CELLS" => {
                let cells = number(&mut tokens)? as usize;
                number(&mut tokens)?;
                for _ in 0..cells {
                    let size = number(&mut tokens)? as usize;
                    let ids = (0..size)
                        .map(|_| Ok(number(&mut tokens)? as u32))
                        .collect::<Result<Vec<u32>>>()?;
                    if let [a, b, c] = ids[..] {
                        frame.triangles.push([a, b, c]);
                    }
                }
            }
            "VECTORS" | "TENSORS" | "SCALARS" => {
                let name = tokens.next().context("a data array without a name")?;
                tokens.next();
                let n = frame.positions.len();
                let components = match token {
                    "VECTORS" => 3,
                    "TENSORS" => 9,
                    _ => {
                        // `SCALARS name type 1` then `LOOKUP_TABLE default`.
                        tokens.next();
                        tokens.next();
                        tokens.next();
                        1
                    }
                };
                let values = (0..n * components)
                    .map(|_| number(&mut tokens))
                    .collect::<Result<Vec<f64>>>()?;
                if name == "von_mises_stress" {
                    frame.von_mises = Some(values);
                }
            }
            _ => {}
        }
    }
    if frame.positions.is_empty() {
        bail!("no POINTS");
    }
    Ok(frame)
}

/// Frame `index` of the colliders from an ASCII triangle-mesh PLY written by `freeform`
/// (`colliders_NNNNN.ply`).
fn read_collider_ply(path: &Path, index: usize) -> Result<ColliderFrame> {
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("{}: cannot read", path.display()))?;
    let parse = || -> Result<ColliderFrame> {
        let (header, body) = text.split_once("end_header\n").context("no end_header")?;
        let count = |element: &str| -> usize {
            header
                .lines()
                .find_map(|l| {
                    l.strip_prefix(&format!("element {element} "))?
                        .trim()
                        .parse()
                        .ok()
                })
                .unwrap_or(0)
        };
        let (nv, nf) = (count("vertex"), count("face"));
        let mut lines = body.lines();
        let mut vertices = Vec::with_capacity(nv);
        for _ in 0..nv {
            let v: Vec<f64> = lines
                .next()
                .context("fewer vertices than the header says")?
                .split_ascii_whitespace()
                .take(3)
                .map(str::parse)
                .collect::<Result<_, _>>()?;
            if v.len() != 3 {
                bail!("a vertex without three coordinates");
            }
            vertices.push(Vector3::new(v[0], v[1], v[2]));
        }
        let mut triangles = Vec::with_capacity(nf);
        for _ in 0..nf {
            let f: Vec<u32> = lines
                .next()
                .context("fewer faces than the header says")?
                .split_ascii_whitespace()
                .map(str::parse)
                .collect::<Result<_, _>>()?;
            match f[..] {
                [3, a, b, c] if (a.max(b).max(c) as usize) < nv => triangles.push([a, b, c]),
                _ => bail!("a face that is not a triangle of the vertices"),
            }
        }
        Ok(ColliderFrame {
            index,
            vertices,
            triangles,
        })
    };
    parse().with_context(|| format!("{}: not a triangle-mesh PLY", path.display()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_frame_writers_vtk_reads_back_with_its_points_and_triangles() {
        let rest = vec![Vector3::zeros(), Vector3::x(), Vector3::y()];
        let moved: Vec<_> = rest
            .iter()
            .map(|p| p + Vector3::new(0.0, 0.0, 0.5))
            .collect();
        let text = freeform::frames::unstructured_grid_vtk(&moved, &rest, &[[0, 1, 2]], 0.1, None);
        let frame = parse_vtk(&text).unwrap();
        assert_eq!(frame.positions, moved);
        assert_eq!(frame.triangles, vec![[0, 1, 2]]);
        assert!(frame.von_mises.is_none());
    }

    #[test]
    fn a_truncated_vtk_is_an_error_not_a_short_frame() {
        let rest = vec![Vector3::zeros(), Vector3::x(), Vector3::y()];
        let text = freeform::frames::unstructured_grid_vtk(&rest, &rest, &[[0, 1, 2]], 0.0, None);
        let cut = &text[..text.len() - 8];
        assert!(parse_vtk(cut).is_err());
    }
}
