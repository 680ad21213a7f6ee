//! `preview.png`: a run at a glance. One frame large (the most stressed one when the run wrote
//! the stress, else the last; shaded surfaces or point discs coloured by von Mises stress,
//! else by displacement, or splats in their own colours; the
//! floor as a checkerboard; the colliders translucent), the colour bar with its quantity and
//! unit, and a strip of five frames across the run, all from one camera 30° about and 20°
//! above the scene's up.

mod colour_map;
mod raster;
mod text;

use std::path::Path;

use anyhow::{Context, Result};
use freeform::Camera;
use nalgebra::Vector3;

use crate::output_frames::{ObjectFrames, RunOutput, Scalar};
use crate::viewer_page::colour_range;
use colour_map::viridis;
use raster::{Blend, Canvas, Projector, Rgb, draw_discs, draw_triangles};
use text::draw_text;

const MAIN: (usize, usize) = (640, 480);
const LEGEND_WIDTH: usize = 160;
const STRIP: usize = 5;
const THUMB: (usize, usize) = (160, 120);
const BACKGROUND: Rgb = [0.96, 0.96, 0.97];
const INK: Rgb = [0.1, 0.1, 0.12];
const COLLIDER: Rgb = [0.45, 0.62, 0.85];

/// How [`write_preview`] coloured the objects.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct PreviewColouring {
    /// The scalar, or `None` for splats in their own colours.
    pub scalar: Option<Scalar>,
    /// The top of the colour bar (the 99th percentile over the frames drawn).
    pub max: f64,
}

/// Writes `png`, a preview of `run`.
///
/// # Errors
/// When the run has no frames or the file cannot be written.
pub(crate) fn write_preview(run: &RunOutput, png: &Path) -> Result<PreviewColouring> {
    let indices = run.frame_indices();
    let last = *indices.last().context("the objects share no frame")?;
    let strip: Vec<usize> = (0..STRIP)
        .map(|i| indices[i * (indices.len() - 1) / (STRIP - 1)])
        .collect();
    let splats = run.objects.iter().all(|o| o.colours.is_some());
    let scalar = (!splats).then(|| run.scalars()[0]);
    let max = scalar.map_or(0.0, |s| {
        let values: Vec<f64> = run
            .objects
            .iter()
            .flat_map(|o| o.frames.iter().filter(|f| strip.contains(&f.index)))
            .filter_map(|f| s.values(f))
            .flatten()
            .copied()
            .collect();
        colour_range(&values).0
    });
    let colouring = PreviewColouring { scalar, max };
    let (shown, why) = match scalar {
        Some(Scalar::VonMises) => (most_stressed(run, &indices), "  (most stressed)"),
        _ => (last, ""),
    };
    let camera = framing(run, &strip);
    let (width, height) = (MAIN.0 + LEGEND_WIDTH, MAIN.1 + THUMB.1);
    let mut image = Canvas::new(width, height, BACKGROUND);
    image.paste(&draw_frame(run, shown, &camera, MAIN, &colouring), 0, 0);
    draw_text(&mut image, 10, 10, &title(run, shown), 2, INK);
    draw_text(&mut image, 10, 30, why.trim_start(), 1, INK);
    draw_legend(&mut image, MAIN.0, &colouring);
    for (n, &index) in strip.iter().enumerate() {
        let x = n * THUMB.0;
        image.paste(
            &draw_frame(run, index, &camera, THUMB, &colouring),
            x,
            MAIN.1,
        );
        draw_text(
            &mut image,
            x + 4,
            MAIN.1 + 4,
            &time_label(run, index),
            1,
            INK,
        );
        image.fill(x, MAIN.1, 1, THUMB.1, [0.7; 3]);
    }
    image.fill(0, MAIN.1, width, 1, [0.7; 3]);
    write_rgb_png(&image, png)?;
    Ok(colouring)
}

/// The frame whose 99th percentile of von Mises stress over all objects is largest.
fn most_stressed(run: &RunOutput, indices: &[usize]) -> usize {
    let level = |k: usize| {
        let values: Vec<f64> = run
            .objects
            .iter()
            .flat_map(|o| o.frames.iter().filter(|f| f.index == k))
            .filter_map(|f| f.von_mises.as_deref())
            .flatten()
            .copied()
            .collect();
        colour_range(&values).0
    };
    indices
        .iter()
        .copied()
        .max_by(|&a, &b| level(a).total_cmp(&level(b)))
        .unwrap_or(0)
}

/// The camera of every panel: framing the objects over the strip's frames and the colliders
/// at the last frame.
fn framing(run: &RunOutput, frames: &[usize]) -> Camera {
    let mut points: Vec<Vector3<f64>> = run
        .objects
        .iter()
        .flat_map(|o| o.frames.iter().filter(|f| frames.contains(&f.index)))
        .flat_map(|f| f.positions.iter().copied())
        .collect();
    if let Some(c) = frames.last().and_then(|&k| run.colliders_at(k)) {
        points.extend_from_slice(&c.vertices);
    }
    Camera::framing(&points, run.up(), 30.0, 20.0)
}

/// Frame `index` drawn into a `size` canvas.
fn draw_frame(
    run: &RunOutput,
    index: usize,
    camera: &Camera,
    size: (usize, usize),
    colouring: &PreviewColouring,
) -> Canvas {
    let mut canvas = Canvas::new(size.0, size.1, BACKGROUND);
    let projector = Projector::new(camera, size.0, size.1);
    let radius =
        (camera.eye - camera.target).norm() * (0.5 * camera.fov_y_degrees.to_radians()).sin();
    if let Some(floor) = run.scene.as_ref().and_then(|s| s.floor) {
        draw_floor(
            &mut canvas,
            &projector,
            camera.target,
            radius,
            floor.normal.into(),
            floor.offset,
        );
    }
    for object in &run.objects {
        let Some(frame) = object.frames.iter().find(|f| f.index == index) else {
            continue;
        };
        let colour = |i: usize| -> Rgb {
            match (colouring.scalar, &object.colours) {
                (Some(s), _) => s.values(frame).map_or([0.7; 3], |v| {
                    viridis(if colouring.max > 0.0 {
                        v[i] / colouring.max
                    } else {
                        0.0
                    })
                }),
                (None, Some(c)) => c[i].map(f64::from),
                (None, None) => [0.7; 3],
            }
        };
        match &object.triangles {
            Some(t) => draw_triangles(
                &mut canvas,
                &projector,
                &frame.positions,
                t,
                colour,
                Blend::Opaque,
            ),
            None => draw_discs(
                &mut canvas,
                &projector,
                &frame.positions,
                disc_radius(object),
                colour,
            ),
        }
    }
    if let Some(c) = run.colliders_at(index) {
        draw_triangles(
            &mut canvas,
            &projector,
            &c.vertices,
            &c.triangles,
            |_| COLLIDER,
            Blend::Translucent(0.35),
        );
    }
    canvas
}

/// About half the spacing of a cloud's points on its bounding box's surface (m).
fn disc_radius(object: &ObjectFrames) -> f64 {
    let points = &object.frames[0].positions;
    let (lo, hi) = points.iter().fold(
        (
            Vector3::repeat(f64::INFINITY),
            Vector3::repeat(f64::NEG_INFINITY),
        ),
        |(lo, hi), p| (lo.inf(p), hi.sup(p)),
    );
    let e = hi - lo;
    let area = 2.0 * (e.x * e.y + e.y * e.z + e.z * e.x);
    0.6 * (area / points.len().max(1) as f64).sqrt()
}

/// A checkerboard square of the floor `n · x = offset` around the foot of `centre`.
fn draw_floor(
    canvas: &mut Canvas,
    projector: &Projector,
    centre: Vector3<f64>,
    radius: f64,
    normal: Vector3<f64>,
    offset: f64,
) {
    let origin = centre - normal * (normal.dot(&centre) - offset);
    let side = if normal.x.abs() < 0.9 {
        Vector3::x()
    } else {
        Vector3::y()
    };
    let e0 = (side - normal * normal.dot(&side)).normalize();
    let e1 = normal.cross(&e0);
    let (cells, half) = (12usize, 2.0 * radius);
    let cell = 2.0 * half / cells as f64;
    for i in 0..cells {
        for j in 0..cells {
            let corner = origin + e0 * (i as f64 * cell - half) + e1 * (j as f64 * cell - half);
            let quad = [
                corner,
                corner + e0 * cell,
                corner + (e0 + e1) * cell,
                corner + e1 * cell,
            ];
            let shade = if (i + j) % 2 == 0 {
                [0.86; 3]
            } else {
                [0.78; 3]
            };
            draw_triangles(
                canvas,
                projector,
                &quad,
                &[[0, 1, 2], [0, 2, 3]],
                |_| shade,
                Blend::Opaque,
            );
        }
    }
}

/// The colour bar (or a note for splats) in the legend column starting at `x0`.
fn draw_legend(image: &mut Canvas, x0: usize, colouring: &PreviewColouring) {
    let Some(scalar) = colouring.scalar else {
        draw_text(image, x0 + 8, 20, "splats in their", 1, INK);
        draw_text(image, x0 + 8, 32, "own colours", 1, INK);
        return;
    };
    let words: Vec<&str> = scalar.label().split(' ').collect();
    let mut y = 20;
    for word in words {
        draw_text(image, x0 + 8, y, word, 1, INK);
        y += 12;
    }
    draw_text(image, x0 + 8, y, &format!("({})", scalar.unit()), 1, INK);
    let (bar_x, bar_y, bar_w, bar_h) = (x0 + 8, y + 20, 24, 300);
    for j in 0..bar_h {
        let t = 1.0 - j as f64 / (bar_h - 1) as f64;
        image.fill(bar_x, bar_y + j, bar_w, 1, viridis(t));
    }
    for q in 0..=4 {
        let t = 1.0 - q as f64 / 4.0;
        let label = format!("{:.2e}", t * colouring.max);
        let ty = bar_y + q * (bar_h - 1) / 4;
        image.fill(bar_x + bar_w, ty, 4, 1, INK);
        draw_text(
            image,
            bar_x + bar_w + 6,
            ty.saturating_sub(4),
            &label,
            1,
            INK,
        );
    }
}

/// `"<name>  t = 1.000 s"` for frame `index`.
fn title(run: &RunOutput, index: usize) -> String {
    let name = run
        .dir
        .file_name()
        .map_or_else(String::new, |n| n.to_string_lossy().into_owned());
    format!("{name}  {}", time_label(run, index))
}

/// `"t = 0.250 s"`, or `"step 25"` without a time step.
fn time_label(run: &RunOutput, index: usize) -> String {
    match &run.scene {
        Some(s) => format!("t = {:.3} s", index as f64 * s.time_step),
        None => format!("step {index}"),
    }
}

/// Writes `canvas` as an 8-bit RGB PNG.
fn write_rgb_png(canvas: &Canvas, path: &Path) -> Result<()> {
    let mut bytes = Vec::new();
    let mut encoder = png::Encoder::new(
        &mut bytes,
        u32::try_from(canvas.width)?,
        u32::try_from(canvas.height)?,
    );
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    encoder
        .write_header()
        .and_then(|mut writer| writer.write_image_data(&canvas.bytes()))
        .with_context(|| format!("encoding {}", path.display()))?;
    artifact::write_atomically(path, &bytes)?;
    Ok(())
}
