//! `view.html`: one self-contained page that plays a run's frames in a browser with no server
//! and no network (`cli/viewer/`: the page, its script and the bundled part of three.js).
//!
//! The frames travel as one base64 blob of little-endian 4-byte words: per object its
//! triangles (u32) and splat colours (f32 RGB) once, and per kept frame its positions (f32 xyz,
//! m) and each scalar (f32); per frame the colliders' vertices (f32) and triangles (u32). A
//! JSON block (`freeform-meta`) gives every array's offset in words. When the whole run would
//! pass the size limit, frames are dropped evenly (the first and the last kept) and the page
//! and the report say how many.

use std::path::{Path, PathBuf};

use anyhow::{Result, bail};
use base64::Engine;
use nalgebra::Vector3;
use serde_json::{Value, json};

use crate::output_frames::{RunOutput, Scalar};

const PAGE: &str = include_str!("../viewer/viewer.html");
const VIEWER_JS: &str = include_str!("../viewer/viewer.js");
const THREE_JS: &str = include_str!("../viewer/vendor/three-subset.js");

/// How the page is written.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct ViewerParams {
    /// The largest file to write (bytes, default 100 MB): frames are dropped evenly to stay
    /// under it.
    pub max_bytes: usize,
}

impl Default for ViewerParams {
    fn default() -> Self {
        ViewerParams {
            max_bytes: 100_000_000,
        }
    }
}

/// What [`write_viewer`] wrote.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct ViewerReport {
    /// The page.
    pub path: PathBuf,
    /// Its size (bytes).
    pub bytes: usize,
    /// Frames in the page.
    pub frames: usize,
    /// Frames the run wrote.
    pub frames_written: usize,
}

/// Writes `view.html` for `run` into its folder.
///
/// # Errors
/// When even the first frame does not fit in `params.max_bytes`, or the file cannot be written.
pub(crate) fn write_viewer(run: &RunOutput, params: &ViewerParams) -> Result<ViewerReport> {
    let all = run.frame_indices();
    if all.is_empty() {
        bail!("{}: the objects share no frame index", run.dir.display());
    }
    let scalars = run.scalars();
    let fixed = PAGE.len() + VIEWER_JS.len() + THREE_JS.len() + 4096 * (1 + run.objects.len());
    let per_frame = 4 * base64_len(frame_words(run, all[0], &scalars)) / 3 + 256;
    let statics = 4 * base64_len(static_words(run)) / 3;
    let room = params.max_bytes.saturating_sub(fixed + statics);
    let keep = (room / per_frame.max(1)).min(all.len());
    if keep == 0 {
        bail!(
            "a page of even one frame needs about {} bytes, over the limit of {} bytes",
            fixed + statics + per_frame,
            params.max_bytes
        );
    }
    let kept: Vec<usize> = if keep >= all.len() {
        all.clone()
    } else if keep == 1 {
        vec![all[0]]
    } else {
        (0..keep)
            .map(|i| all[(i * (all.len() - 1)) / (keep - 1)])
            .collect()
    };
    let mut notes = Vec::new();
    if kept.len() < all.len() {
        notes.push(format!(
            "{} of the run's {} frames dropped (evenly, first and last kept) to stay under {} MB.",
            all.len() - kept.len(),
            all.len(),
            params.max_bytes as f64 / 1e6
        ));
    }
    let (meta, blob) = encode(run, &kept, &scalars, notes);
    let meta = serde_json::to_string(&meta)?.replace('<', "\\u003c");
    let title = html_escape(&meta_title(run));
    let page = PAGE
        .replace("{{TITLE}}", &title)
        .replace("{{META_JSON}}", &meta)
        .replace(
            "{{DATA_BASE64}}",
            &base64::engine::general_purpose::STANDARD.encode(blob),
        )
        .replace("{{VENDOR_JS}}", THREE_JS)
        .replace("{{VIEWER_JS}}", VIEWER_JS);
    let path = run.dir.join("view.html");
    artifact::write_atomically(&path, page.as_bytes())?;
    Ok(ViewerReport {
        path,
        bytes: page.len(),
        frames: kept.len(),
        frames_written: all.len(),
    })
}

/// Base64 characters for `words` 4-byte words.
fn base64_len(words: usize) -> usize {
    (4 * words).div_ceil(3) * 4
}

/// Words of one frame: every object's positions and scalars, and the colliders'.
fn frame_words(run: &RunOutput, index: usize, scalars: &[Scalar]) -> usize {
    let objects: usize = run
        .objects
        .iter()
        .map(|o| o.frames[0].positions.len() * (3 + scalars.len()))
        .sum();
    objects
        + run
            .colliders_at(index)
            .map_or(0, |c| 3 * (c.vertices.len() + c.triangles.len()))
}

/// Words written once: triangles and splat colours.
fn static_words(run: &RunOutput) -> usize {
    run.objects
        .iter()
        .map(|o| {
            3 * o.triangles.as_ref().map_or(0, Vec::len)
                + 3 * o.colours.as_ref().map_or(0, Vec::len)
        })
        .sum()
}

fn meta_title(run: &RunOutput) -> String {
    run.dir
        .file_name()
        .map_or_else(|| "run".into(), |n| n.to_string_lossy().into_owned())
}

fn html_escape(text: &str) -> String {
    text.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

/// The blob of 4-byte words, with the offset (in words) of what is pushed.
#[derive(Default)]
struct Blob(Vec<u8>);

impl Blob {
    fn floats(&mut self, values: impl IntoIterator<Item = f32>) -> usize {
        let offset = self.0.len() / 4;
        for v in values {
            self.0.extend_from_slice(&v.to_le_bytes());
        }
        offset
    }

    fn points(&mut self, points: &[Vector3<f64>]) -> usize {
        self.floats(
            points
                .iter()
                .flat_map(|p| [p.x as f32, p.y as f32, p.z as f32]),
        )
    }

    fn triangles(&mut self, triangles: &[[u32; 3]]) -> usize {
        let offset = self.0.len() / 4;
        for v in triangles.iter().flatten() {
            self.0.extend_from_slice(&v.to_le_bytes());
        }
        offset
    }
}

/// The page's metadata and blob for the frames `kept`.
fn encode(
    run: &RunOutput,
    kept: &[usize],
    scalars: &[Scalar],
    notes: Vec<String>,
) -> (Value, Vec<u8>) {
    let mut blob = Blob::default();
    let (mut lo, mut hi) = (
        Vector3::repeat(f64::INFINITY),
        Vector3::repeat(f64::NEG_INFINITY),
    );
    let mut objects = Vec::new();
    // Each scalar's colour range: 0 to the 99th percentile of every kept value.
    let mut ranges: Vec<Vec<f64>> = vec![Vec::new(); scalars.len()];
    for object in &run.objects {
        let triangles = object
            .triangles
            .as_ref()
            .map(|t| json!({ "offset": blob.triangles(t), "count": t.len() }));
        let colours = object
            .colours
            .as_ref()
            .map(|c| blob.floats(c.iter().flatten().copied()));
        let frames: Vec<_> = kept
            .iter()
            .map(|&k| {
                object
                    .frames
                    .iter()
                    .find(|f| f.index == k)
                    .expect("a common frame")
            })
            .collect();
        let mut positions = Vec::new();
        for frame in &frames {
            for p in &frame.positions {
                lo = lo.inf(p);
                hi = hi.sup(p);
            }
            positions.push(blob.points(&frame.positions));
        }
        let mut by_scalar = serde_json::Map::new();
        for (s, scalar) in scalars.iter().enumerate() {
            let offsets: Vec<usize> = frames
                .iter()
                .map(|frame| {
                    let values = scalar.values(frame).expect("every frame has the scalar");
                    ranges[s].extend_from_slice(values);
                    blob.floats(values.iter().map(|&v| v as f32))
                })
                .collect();
            by_scalar.insert(scalar_key(*scalar).into(), json!(offsets));
        }
        objects.push(json!({
            "name": object.name,
            "points": object.frames[0].positions.len(),
            "triangles": triangles,
            "colours": colours,
            "positions": positions,
            "scalars": by_scalar,
        }));
    }
    let colliders: Vec<Value> = kept
        .iter()
        .map(|&k| match run.colliders_at(k) {
            Some(c) => json!({
                "positions": blob.points(&c.vertices),
                "vertices": c.vertices.len(),
                "triangles": blob.triangles(&c.triangles),
                "count": c.triangles.len(),
            }),
            None => Value::Null,
        })
        .collect();
    let scalars: Vec<Value> = scalars
        .iter()
        .zip(&ranges)
        .map(|(scalar, values)| {
            let (max, clipped) = colour_range(values);
            json!({
                "key": scalar_key(*scalar),
                "label": scalar.label(),
                "unit": scalar.unit(),
                "max": max,
                "clipped": clipped,
            })
        })
        .collect();
    let scene = run.scene.as_ref();
    let meta = json!({
        "title": meta_title(run),
        "time_step": scene.map(|s| s.time_step),
        "up": run.up().as_slice(),
        "floor": scene.and_then(|s| s.floor),
        "frames": kept,
        "bounds": { "min": lo.as_slice(), "max": hi.as_slice() },
        "scalars": scalars,
        "objects": objects,
        "colliders": colliders,
        "notes": notes,
    });
    (meta, blob.0)
}

/// The top of a scalar's colour bar: the 99th percentile of `values` (so a few outliers do not
/// wash the field out), and whether larger values were clipped to it.
pub(crate) fn colour_range(values: &[f64]) -> (f64, bool) {
    let mut finite: Vec<f64> = values.iter().copied().filter(|v| v.is_finite()).collect();
    if finite.is_empty() {
        return (0.0, false);
    }
    finite.sort_unstable_by(f64::total_cmp);
    let top = finite[((finite.len() - 1) * 99) / 100];
    (top, finite[finite.len() - 1] > top)
}

fn scalar_key(scalar: Scalar) -> &'static str {
    match scalar {
        Scalar::VonMises => "von_mises",
        Scalar::Displacement => "displacement",
    }
}

/// `freeform view DIR`: reads the run in `dir` and writes `dir/view.html`.
///
/// # Errors
/// As [`RunOutput::read`] and [`write_viewer`].
pub(crate) fn view(dir: &Path, params: &ViewerParams) -> Result<ViewerReport> {
    write_viewer(&RunOutput::read(dir)?, params)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::output_frames::{ObjectFrame, ObjectFrames};

    /// A run of `frames` frames of a cloud of `points` points falling along −y.
    fn falling_cloud(dir: &Path, frames: usize, points: usize) -> RunOutput {
        let rest: Vec<Vector3<f64>> = (0..points)
            .map(|i| Vector3::new(i as f64 * 0.01, 0.0, 0.0))
            .collect();
        let frames = (0..frames)
            .map(|k| ObjectFrame {
                index: 10 * k,
                positions: rest
                    .iter()
                    .map(|p| p - Vector3::y() * 0.01 * k as f64)
                    .collect(),
                displacement: vec![0.01 * k as f64; points],
                von_mises: None,
            })
            .collect();
        RunOutput {
            dir: dir.to_path_buf(),
            objects: vec![ObjectFrames {
                name: "cloud".into(),
                triangles: None,
                colours: None,
                frames,
            }],
            colliders: Vec::new(),
            scene: None,
        }
    }

    fn scratch(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("freeform-view-{name}-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    #[test]
    fn a_run_under_the_limit_keeps_every_frame() {
        let dir = scratch("all");
        let report =
            write_viewer(&falling_cloud(&dir, 12, 1000), &ViewerParams::default()).unwrap();
        assert_eq!((report.frames, report.frames_written), (12, 12));
        let page = std::fs::read_to_string(&report.path).unwrap();
        assert_eq!(page.len(), report.bytes);
        assert!(page.contains(r#""notes":[]"#));
    }

    #[test]
    fn past_the_limit_frames_are_dropped_evenly_keeping_the_ends_and_the_page_says_so() {
        let dir = scratch("limit");
        let run = falling_cloud(&dir, 40, 20_000);
        let full = write_viewer(&run, &ViewerParams::default()).unwrap();
        let max_bytes = full.bytes / 2;
        let report = write_viewer(&run, &ViewerParams { max_bytes }).unwrap();
        assert!(report.bytes <= max_bytes, "{} > {max_bytes}", report.bytes);
        assert!(
            report.frames > 2 && report.frames < 40,
            "{} frames",
            report.frames
        );
        let page = std::fs::read_to_string(&report.path).unwrap();
        let start = page.find(r#""frames":["#).unwrap() + 10;
        let listed: Vec<usize> = page[start..start + page[start..].find(']').unwrap()]
            .split(',')
            .map(|n| n.parse().unwrap())
            .collect();
        assert_eq!(listed.len(), report.frames);
        assert_eq!((listed[0], *listed.last().unwrap()), (0, 390));
        let gaps: Vec<usize> = listed.windows(2).map(|w| w[1] - w[0]).collect();
        assert!(
            gaps.iter().max().unwrap() - gaps.iter().min().unwrap() <= 10,
            "{gaps:?}"
        );
        assert!(page.contains(&format!(
            "{} of the run's 40 frames dropped",
            40 - report.frames
        )));
    }

    #[test]
    fn a_limit_below_one_frame_is_refused_with_the_size_needed() {
        let dir = scratch("tiny");
        let err = write_viewer(
            &falling_cloud(&dir, 3, 100),
            &ViewerParams { max_bytes: 1000 },
        )
        .unwrap_err()
        .to_string();
        assert!(err.contains("over the limit of 1000 bytes"), "{err}");
    }

    #[test]
    fn the_colour_range_is_the_99th_percentile_and_says_when_it_clips() {
        let mut values: Vec<f64> = (0..=100).map(f64::from).collect();
        assert_eq!(colour_range(&values), (99.0, true));
        values.push(f64::NAN);
        assert_eq!(colour_range(&values), (99.0, true));
        assert_eq!(colour_range(&[2.0; 10]), (2.0, false));
        assert_eq!(colour_range(&[]), (0.0, false));
    }
}
