//! A CPU preview of a 3D Gaussian Splatting object: each splat projected to a 2D Gaussian
//! (the EWA / 3DGS rule `Σ₂ = J W Σ Wᵀ Jᵀ + 0.3 I`, J the Jacobian of the pinhole projection
//! at the splat's centre, W the camera rotation, 0.3 px² the 3DGS low-pass), sorted by depth
//! and alpha-blended front to back with its degree-0 colour:
//!
//! ```text
//! α_i(p) = min(0.99, o_i · exp(−½ (p − μ_i)ᵀ Σ₂⁻¹ (p − μ_i)))     (skipped below 1/255)
//! C(p)   = Σ_i c_i α_i Π_{j<i} (1 − α_j) + T(p) · background
//! ```
//!
//! with `o_i = sigmoid(opacity)` and `c_i = clamp(0.5 + C₀ f_dc, 0, 1)`, `C₀ = 0.2820948`
//! (the file conventions of 3DGS). A preview to look at frames without a GPU viewer, not a
//! renderer: no higher-order spherical harmonics, no anti-aliasing beyond the low-pass.

use nalgebra::{Matrix2, Matrix3, Vector2, Vector3};
use rkpm_core::Aabb;
use thiserror::Error;

use crate::splats::SplatTable;

/// `C₀`, the degree-0 spherical-harmonic constant of the 3DGS colour convention.
const SH_C0: f64 = 0.282_094_791_773_878_14;

/// One splat as the preview draws it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PreviewSplat {
    /// Centre μ (file units).
    pub position: Vector3<f64>,
    /// Covariance Σ (file units²).
    pub covariance: Matrix3<f64>,
    /// Opacity in [0, 1] (the file stores its logit).
    pub opacity: f64,
    /// Linear RGB in [0, 1].
    pub colour: [f64; 3],
}

/// A pinhole camera looking from `eye` at `target`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    /// Camera centre (file units).
    pub eye: Vector3<f64>,
    /// The point at the image centre.
    pub target: Vector3<f64>,
    /// The direction that points up in the image (not parallel to `target − eye`).
    pub up: Vector3<f64>,
    /// Vertical field of view (degrees, in (0, 180)).
    pub fov_y_degrees: f64,
}

impl Camera {
    /// A camera that frames the sphere around `points`' bounding box: looking at its centre
    /// from `azimuth_degrees` about `up` and `elevation_degrees` above the plane normal to it,
    /// at the distance where the sphere fills the 40° field of view.
    pub fn framing(
        points: &[Vector3<f64>],
        up: Vector3<f64>,
        azimuth_degrees: f64,
        elevation_degrees: f64,
    ) -> Camera {
        let fov_y_degrees: f64 = 40.0;
        let (center, radius) = Aabb::from_points(points).map_or((Vector3::zeros(), 1.0), |b| {
            (b.center(), (0.5 * b.extent().norm()).max(1e-9))
        });
        let up = up.normalize();
        // Any direction normal to `up` as azimuth 0.
        let side = if up.x.abs() < 0.9 {
            Vector3::x()
        } else {
            Vector3::y()
        };
        let e0 = (side - up * up.dot(&side)).normalize();
        let e1 = up.cross(&e0);
        let (a, b) = (azimuth_degrees.to_radians(), elevation_degrees.to_radians());
        let direction = (e0 * a.cos() + e1 * a.sin()) * b.cos() + up * b.sin();
        let distance = 1.1 * radius / (0.5 * fov_y_degrees.to_radians()).sin();
        Camera {
            eye: center + direction * distance,
            target: center,
            up,
            fov_y_degrees,
        }
    }
}

/// Image size, camera and background of a preview.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PreviewParams {
    /// Pixels across.
    pub width: usize,
    /// Pixels down.
    pub height: usize,
    /// The camera.
    pub camera: Camera,
    /// Linear RGB in [0, 1] behind the object.
    pub background: [f64; 3],
}

/// A `width × height` preview of `points` (m) seen from 30° about and 20° above `up`
/// ([`Camera::framing`]), on white: each point a round splat of radius `0.3 · sqrt(A / n)` (A
/// the surface area of the points' bounding box, so about the spacing of n points on a
/// surface), coloured by `values` on [`point_splats`]' scale (grey without), with `opacity`
/// per point in [0, 1] (opaque without).
///
/// # Errors
/// [`PreviewError::Params`] for a `values` or `opacity` that does not hold one entry per
/// point, an empty size, or an `up` that is zero or not finite.
pub fn points_preview(
    points: &[Vector3<f64>],
    values: Option<&[f64]>,
    opacity: Option<&[f64]>,
    up: Vector3<f64>,
    width: usize,
    height: usize,
) -> Result<PreviewImage, PreviewError> {
    for (what, given) in [("values", values), ("opacity", opacity)] {
        if let Some(given) = given
            && given.len() != points.len()
        {
            return Err(PreviewError::Params(format!(
                "{} {what} for {} points",
                given.len(),
                points.len()
            )));
        }
    }
    if !(up.iter().all(|c| c.is_finite()) && up.norm() > 0.0) {
        return Err(PreviewError::Params(format!(
            "the up direction must be finite and non-zero, got {up:?}"
        )));
    }
    let extent = Aabb::from_points(points).map_or(Vector3::repeat(1.0), |b| b.extent());
    let area = 2.0 * (extent.x * extent.y + extent.y * extent.z + extent.z * extent.x);
    let radius = 0.3 * (area / points.len().max(1) as f64).sqrt();
    let mut splats = point_splats(points, values, radius);
    if let Some(opacity) = opacity {
        for (splat, &alpha) in splats.iter_mut().zip(opacity) {
            splat.opacity = alpha;
        }
    }
    let params = PreviewParams {
        width,
        height,
        camera: Camera::framing(points, up, 30.0, 20.0),
        background: [1.0, 1.0, 1.0],
    };
    render_preview(&splats, &params)
}

/// An RGB image, rows from the top, 8 bits per channel.
#[derive(Clone, Debug, PartialEq)]
pub struct PreviewImage {
    /// Pixels across.
    pub width: usize,
    /// Pixels down.
    pub height: usize,
    /// `width × height` pixels, row-major from the top-left.
    pub pixels: Vec<[u8; 3]>,
}

impl PreviewImage {
    /// The pixel in column `x`, row `y` (from the top-left).
    pub fn pixel(&self, x: usize, y: usize) -> [u8; 3] {
        self.pixels[y * self.width + x]
    }
}

/// A preview cannot be drawn.
#[derive(Debug, Error, PartialEq)]
pub enum PreviewError {
    /// Image size or camera unusable.
    #[error("invalid preview options: {0}")]
    Params(String),
    /// The splat file lacks a property the preview needs.
    #[error("the splat file has no `{0}` property")]
    MissingProperty(&'static str),
}

/// Points drawn as round splats of `radius` (file units), opaque, coloured by `values` on a
/// blue → white → red ramp from 0 to the 98th percentile of the values (e.g. the von Mises
/// stress; the few above it red), or light grey without values: a preview of a deformed
/// surface or cloud.
///
/// # Panics
/// If `values` is given with a length other than `points.len()`.
pub fn point_splats(
    points: &[Vector3<f64>],
    values: Option<&[f64]>,
    radius: f64,
) -> Vec<PreviewSplat> {
    if let Some(values) = values {
        assert_eq!(values.len(), points.len(), "one value per point");
    }
    let largest = values.map_or(0.0, |v| {
        let mut sorted: Vec<f64> = v.iter().copied().filter(|x| x.is_finite()).collect();
        sorted.sort_by(f64::total_cmp);
        sorted
            .get((0.98 * sorted.len() as f64) as usize)
            .or(sorted.last())
            .copied()
            .unwrap_or(0.0)
    });
    points
        .iter()
        .enumerate()
        .map(|(i, &position)| {
            let colour = match values {
                Some(values) if largest > 0.0 => {
                    let s = (values[i] / largest).clamp(0.0, 1.0);
                    if s < 0.5 {
                        let t = 2.0 * s;
                        [0.1 + 0.9 * t, 0.2 + 0.8 * t, 0.9 + 0.1 * t]
                    } else {
                        let t = 2.0 * (s - 0.5);
                        [1.0, 1.0 - 0.85 * t, 1.0 - 0.9 * t]
                    }
                }
                _ => [0.8, 0.8, 0.8],
            };
            PreviewSplat {
                position,
                covariance: Matrix3::identity() * (radius * radius),
                opacity: 1.0,
                colour,
            }
        })
        .collect()
}

/// The splats of a 3DGS table as the preview draws them (opacity through the sigmoid, colour
/// from `f_dc_0..2`).
///
/// # Errors
/// [`PreviewError::MissingProperty`] for a file without `opacity` or `f_dc_0..2`.
pub fn preview_splats(table: &SplatTable) -> Result<Vec<PreviewSplat>, PreviewError> {
    let column = |name: &'static str| {
        table
            .column(name)
            .ok_or(PreviewError::MissingProperty(name))
    };
    let opacity = column("opacity")?;
    let dc = [column("f_dc_0")?, column("f_dc_1")?, column("f_dc_2")?];
    Ok(table
        .positions()
        .into_iter()
        .zip(table.covariances())
        .enumerate()
        .map(|(i, (position, covariance))| PreviewSplat {
            position,
            covariance,
            opacity: 1.0 / (1.0 + (-opacity[i]).exp()),
            colour: std::array::from_fn(|c| (0.5 + SH_C0 * dc[c][i]).clamp(0.0, 1.0)),
        })
        .collect())
}

/// Draws `splats` as described in the module docs.
///
/// # Errors
/// [`PreviewError::Params`] for an empty image, a field of view outside (0°, 180°), or a
/// camera whose `up` is parallel to its viewing direction.
#[allow(non_snake_case)]
pub fn render_preview(
    splats: &[PreviewSplat],
    params: &PreviewParams,
) -> Result<PreviewImage, PreviewError> {
    let (width, height) = (params.width, params.height);
    let camera = &params.camera;
    if width == 0 || height == 0 {
        return Err(PreviewError::Params(format!(
            "the image is {width} × {height} pixels"
        )));
    }
    if !(camera.fov_y_degrees > 0.0 && camera.fov_y_degrees < 180.0) {
        return Err(PreviewError::Params(format!(
            "the field of view is {}°, not in (0°, 180°)",
            camera.fov_y_degrees
        )));
    }
    let forward = (camera.target - camera.eye).normalize();
    let right = forward.cross(&camera.up);
    if !(right.norm() > 1e-9) || !forward.iter().all(|v| v.is_finite()) {
        return Err(PreviewError::Params(
            "the camera's up is parallel to its viewing direction (or eye = target)".into(),
        ));
    }
    let right = right.normalize();
    let down = forward.cross(&right);
    // W: world → camera (x right, y down, z forward), rows of the camera frame.
    let W = Matrix3::from_rows(&[right.transpose(), down.transpose(), forward.transpose()]);
    let f = 0.5 * height as f64 / (0.5 * camera.fov_y_degrees.to_radians()).tan();
    let (cx, cy) = (0.5 * width as f64, 0.5 * height as f64);

    // Project every splat in front of the camera; sort front to back.
    struct Projected {
        depth: f64,
        center: Vector2<f64>,
        conic: Matrix2<f64>,
        radius: f64,
        opacity: f64,
        colour: [f64; 3],
    }
    let mut projected: Vec<Projected> = splats
        .iter()
        .filter_map(|s| {
            let t = W * (s.position - camera.eye);
            if t.z <= 1e-9 || !t.iter().all(|v| v.is_finite()) {
                return None;
            }
            let J = nalgebra::Matrix2x3::new(
                f / t.z,
                0.0,
                -f * t.x / (t.z * t.z),
                0.0,
                f / t.z,
                -f * t.y / (t.z * t.z),
            );
            let cov2 =
                J * W * s.covariance * W.transpose() * J.transpose() + Matrix2::identity() * 0.3;
            let conic = cov2.try_inverse()?;
            let largest = cov2.symmetric_eigenvalues().max();
            Some(Projected {
                depth: t.z,
                center: Vector2::new(cx + f * t.x / t.z, cy + f * t.y / t.z),
                conic,
                radius: 3.0 * largest.sqrt(),
                opacity: s.opacity,
                colour: s.colour,
            })
        })
        .collect();
    projected.sort_by(|a, b| a.depth.total_cmp(&b.depth));

    let mut colour = vec![[0.0f64; 3]; width * height];
    let mut transmittance = vec![1.0f64; width * height];
    for s in &projected {
        let x0 = (s.center.x - s.radius).floor().max(0.0) as usize;
        let y0 = (s.center.y - s.radius).floor().max(0.0) as usize;
        let x1 = ((s.center.x + s.radius).ceil().max(0.0) as usize).min(width);
        let y1 = ((s.center.y + s.radius).ceil().max(0.0) as usize).min(height);
        for y in y0..y1 {
            for x in x0..x1 {
                let n = y * width + x;
                if transmittance[n] < 1e-4 {
                    continue;
                }
                // Pixel centres at half-integers.
                let d = Vector2::new(x as f64 + 0.5, y as f64 + 0.5) - s.center;
                let alpha = (s.opacity * (-0.5 * d.dot(&(s.conic * d))).exp()).min(0.99);
                if alpha < 1.0 / 255.0 {
                    continue;
                }
                for (out, c) in colour[n].iter_mut().zip(s.colour) {
                    *out += c * alpha * transmittance[n];
                }
                transmittance[n] *= 1.0 - alpha;
            }
        }
    }
    let to_byte = |v: f64| (v.clamp(0.0, 1.0) * 255.0).round() as u8;
    let pixels = colour
        .iter()
        .zip(&transmittance)
        .map(|(c, t)| std::array::from_fn(|k| to_byte(c[k] + t * params.background[k])))
        .collect();
    Ok(PreviewImage {
        width,
        height,
        pixels,
    })
}
