//! A small CPU rasterizer for the previews: a pinhole projection, z-buffered Lambert-shaded
//! triangles, translucent triangles over them, depth-tested discs for points.

use freeform::Camera;
use nalgebra::Vector3;

/// Linear RGB in [0, 1].
pub(crate) type Rgb = [f64; 3];

/// An image with a depth buffer (view depth, m).
pub(crate) struct Canvas {
    pub width: usize,
    pub height: usize,
    pub rgb: Vec<Rgb>,
    depth: Vec<f64>,
}

impl Canvas {
    /// A `width × height` canvas filled with `background`.
    pub fn new(width: usize, height: usize, background: Rgb) -> Self {
        Canvas {
            width,
            height,
            rgb: vec![background; width * height],
            depth: vec![f64::INFINITY; width * height],
        }
    }

    /// Copies `other` into this canvas with its top-left corner at `(x, y)` (clipped).
    pub fn paste(&mut self, other: &Canvas, x: usize, y: usize) {
        for j in 0..other.height.min(self.height.saturating_sub(y)) {
            for i in 0..other.width.min(self.width.saturating_sub(x)) {
                self.rgb[(y + j) * self.width + x + i] = other.rgb[j * other.width + i];
            }
        }
    }

    /// Fills the rectangle `[x, x + w) × [y, y + h)` (clipped).
    pub fn fill(&mut self, x: usize, y: usize, w: usize, h: usize, colour: Rgb) {
        for j in y..(y + h).min(self.height) {
            for i in x..(x + w).min(self.width) {
                self.rgb[j * self.width + i] = colour;
            }
        }
    }

    /// The image as 8-bit sRGB-ish bytes (the colours are written as they are).
    pub fn bytes(&self) -> Vec<u8> {
        self.rgb
            .iter()
            .flat_map(|c| c.map(|v| (v.clamp(0.0, 1.0) * 255.0).round() as u8))
            .collect()
    }
}

/// Projects world points (m) to pixels of a canvas through a [`Camera`].
pub(crate) struct Projector {
    eye: Vector3<f64>,
    right: Vector3<f64>,
    up: Vector3<f64>,
    forward: Vector3<f64>,
    focal: f64,
    centre: (f64, f64),
}

impl Projector {
    /// The projection of `camera` onto a `width × height` canvas.
    pub fn new(camera: &Camera, width: usize, height: usize) -> Self {
        let forward = (camera.target - camera.eye).normalize();
        let right = forward.cross(&camera.up).normalize();
        Projector {
            eye: camera.eye,
            right,
            up: right.cross(&forward),
            forward,
            focal: 0.5 * height as f64 / (0.5 * camera.fov_y_degrees.to_radians()).tan(),
            centre: (0.5 * width as f64, 0.5 * height as f64),
        }
    }

    /// Pixel coordinates and view depth of `p`; `None` behind the camera.
    pub fn project(&self, p: &Vector3<f64>) -> Option<[f64; 3]> {
        let d = p - self.eye;
        let z = d.dot(&self.forward);
        (z > 1e-9).then(|| {
            [
                self.centre.0 + self.focal * d.dot(&self.right) / z,
                self.centre.1 - self.focal * d.dot(&self.up) / z,
                z,
            ]
        })
    }

    /// The pixels across a length `size` (m) at view depth `z` (m).
    pub fn pixels(&self, size: f64, z: f64) -> f64 {
        self.focal * size / z
    }

    /// Lambert shading of a surface with normal `n`, lit from over the viewer's shoulder and
    /// from both sides (a surface seen from behind is lit as its front).
    pub fn shade(&self, n: &Vector3<f64>) -> f64 {
        let light = (-self.forward + 0.6 * self.up + 0.3 * self.right).normalize();
        0.35 + 0.65 * n.dot(&light).abs()
    }
}

/// How [`draw_triangles`] writes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Blend {
    /// Opaque, depth-tested and written.
    Opaque,
    /// Over what is drawn with this opacity, depth-tested but not written.
    Translucent(f64),
}

/// Draws triangles of `vertices` (m) with a colour per vertex, flat-shaded per face.
pub(crate) fn draw_triangles(
    canvas: &mut Canvas,
    projector: &Projector,
    vertices: &[Vector3<f64>],
    triangles: &[[u32; 3]],
    colour: impl Fn(usize) -> Rgb,
    blend: Blend,
) {
    let projected: Vec<Option<[f64; 3]>> = vertices.iter().map(|v| projector.project(v)).collect();
    for t in triangles {
        let [a, b, c] = t.map(|i| i as usize);
        let (Some(pa), Some(pb), Some(pc)) = (projected[a], projected[b], projected[c]) else {
            continue;
        };
        let normal = (vertices[b] - vertices[a]).cross(&(vertices[c] - vertices[a]));
        let norm = normal.norm();
        if norm == 0.0 {
            continue;
        }
        let shade = projector.shade(&(normal / norm));
        let area = (pb[0] - pa[0]) * (pc[1] - pa[1]) - (pb[1] - pa[1]) * (pc[0] - pa[0]);
        if area.abs() < 1e-12 {
            continue;
        }
        let (ca, cb, cc) = (colour(a), colour(b), colour(c));
        let x0 = pa[0].min(pb[0]).min(pc[0]).floor().max(0.0) as usize;
        let y0 = pa[1].min(pb[1]).min(pc[1]).floor().max(0.0) as usize;
        let x1 = (pa[0].max(pb[0]).max(pc[0]).ceil() as usize).min(canvas.width);
        let y1 = (pa[1].max(pb[1]).max(pc[1]).ceil() as usize).min(canvas.height);
        for y in y0..y1 {
            for x in x0..x1 {
                let (px, py) = (x as f64 + 0.5, y as f64 + 0.5);
                let w0 = ((pb[0] - px) * (pc[1] - py) - (pb[1] - py) * (pc[0] - px)) / area;
                let w1 = ((pc[0] - px) * (pa[1] - py) - (pc[1] - py) * (pa[0] - px)) / area;
                let w2 = 1.0 - w0 - w1;
                if w0 < 0.0 || w1 < 0.0 || w2 < 0.0 {
                    continue;
                }
                let z = w0 * pa[2] + w1 * pb[2] + w2 * pc[2];
                let k = y * canvas.width + x;
                if z >= canvas.depth[k] {
                    continue;
                }
                let lit: Rgb =
                    std::array::from_fn(|i| shade * (w0 * ca[i] + w1 * cb[i] + w2 * cc[i]));
                match blend {
                    Blend::Opaque => {
                        canvas.depth[k] = z;
                        canvas.rgb[k] = lit;
                    }
                    Blend::Translucent(alpha) => {
                        let under = canvas.rgb[k];
                        canvas.rgb[k] =
                            std::array::from_fn(|i| (1.0 - alpha) * under[i] + alpha * lit[i]);
                    }
                }
            }
        }
    }
}

/// Draws each point as an opaque disc of `radius` (m), depth-tested, in its colour.
pub(crate) fn draw_discs(
    canvas: &mut Canvas,
    projector: &Projector,
    points: &[Vector3<f64>],
    radius: f64,
    colour: impl Fn(usize) -> Rgb,
) {
    for (i, p) in points.iter().enumerate() {
        let Some([cx, cy, z]) = projector.project(p) else {
            continue;
        };
        let r = projector.pixels(radius, z).max(0.7);
        let x0 = (cx - r).floor().max(0.0) as usize;
        let y0 = (cy - r).floor().max(0.0) as usize;
        let x1 = ((cx + r).ceil().max(0.0) as usize).min(canvas.width);
        let y1 = ((cy + r).ceil().max(0.0) as usize).min(canvas.height);
        let c = colour(i);
        for y in y0..y1 {
            for x in x0..x1 {
                let (dx, dy) = (x as f64 + 0.5 - cx, y as f64 + 0.5 - cy);
                let d2 = (dx * dx + dy * dy) / (r * r);
                let k = y * canvas.width + x;
                if d2 <= 1.0 && z < canvas.depth[k] {
                    canvas.depth[k] = z;
                    // A little darker towards the rim, so discs read as round.
                    let shade = 1.0 - 0.35 * d2;
                    canvas.rgb[k] = c.map(|v| v * shade);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn camera() -> Camera {
        Camera {
            eye: Vector3::new(0.0, 0.0, 5.0),
            target: Vector3::zeros(),
            up: Vector3::y(),
            fov_y_degrees: 40.0,
        }
    }

    #[test]
    fn the_target_projects_to_the_centre_and_up_to_the_top() {
        let projector = Projector::new(&camera(), 200, 100);
        let [x, y, z] = projector.project(&Vector3::zeros()).unwrap();
        assert!((x - 100.0).abs() < 1e-12 && (y - 50.0).abs() < 1e-12 && (z - 5.0).abs() < 1e-12);
        let [_, y_up, _] = projector.project(&Vector3::y()).unwrap();
        assert!(y_up < 50.0);
        assert!(projector.project(&Vector3::new(0.0, 0.0, 6.0)).is_none());
    }

    #[test]
    fn the_nearer_of_two_overlapping_triangles_is_drawn() {
        let projector = Projector::new(&camera(), 64, 64);
        let mut canvas = Canvas::new(64, 64, [1.0; 3]);
        let square = |z: f64| {
            vec![
                Vector3::new(-1.0, -1.0, z),
                Vector3::new(1.0, -1.0, z),
                Vector3::new(1.0, 1.0, z),
                Vector3::new(-1.0, 1.0, z),
            ]
        };
        let faces = [[0, 1, 2], [0, 2, 3]];
        draw_triangles(
            &mut canvas,
            &projector,
            &square(1.0),
            &faces,
            |_| [1.0, 0.0, 0.0],
            Blend::Opaque,
        );
        draw_triangles(
            &mut canvas,
            &projector,
            &square(0.0),
            &faces,
            |_| [0.0, 0.0, 1.0],
            Blend::Opaque,
        );
        let centre = canvas.rgb[32 * 64 + 32];
        assert!(centre[0] > 0.3 && centre[2] == 0.0, "{centre:?}");
        assert_eq!(canvas.rgb[0], [1.0; 3], "the corner stays background");
    }
}
