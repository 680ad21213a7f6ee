//! The splat preview against its definition: two splats on the optical axis, where the
//! projected covariance is exactly `(f σ / z)² I + 0.3 I`, drawn front to back whatever their
//! order in the input.

use freeform::{Camera, PreviewError, PreviewParams, PreviewSplat, render_preview};
use nalgebra::{Matrix3, Vector3};

const SIZE: usize = 64;
/// f = (64 / 2) / tan(45°) = 32 px for a 90° field of view.
const FOCAL: f64 = 32.0;

fn splat(z: f64, sigma: f64, colour: [f64; 3]) -> PreviewSplat {
    PreviewSplat {
        position: Vector3::new(0.0, 0.0, z),
        covariance: Matrix3::identity() * sigma * sigma,
        opacity: 0.9,
        colour,
    }
}

fn params() -> PreviewParams {
    PreviewParams {
        width: SIZE,
        height: SIZE,
        camera: Camera {
            eye: Vector3::new(0.0, 0.0, 5.0),
            target: Vector3::zeros(),
            up: Vector3::y(),
            fov_y_degrees: 90.0,
        },
        background: [0.0, 1.0, 0.0],
    }
}

/// α of an on-axis splat at depth `depth` (σ in world units) at pixel (x, y).
fn alpha(depth: f64, sigma: f64, x: usize, y: usize) -> f64 {
    let variance = (FOCAL * sigma / depth).powi(2) + 0.3;
    let (dx, dy) = (x as f64 + 0.5 - 32.0, y as f64 + 0.5 - 32.0);
    let a = (0.9 * (-0.5 * (dx * dx + dy * dy) / variance).exp()).min(0.99);
    if a < 1.0 / 255.0 { 0.0 } else { a }
}

#[test]
fn two_splats_on_the_axis_blend_front_to_back_to_the_expected_pixels() {
    // Red in front (depth 5, σ = 0.5), blue behind (depth 7, σ = 2), given back to front.
    let (red, blue) = ([1.0, 0.0, 0.0], [0.0, 0.0, 1.0]);
    let splats = [splat(-2.0, 2.0, blue), splat(0.0, 0.5, red)];
    let image = render_preview(&splats, &params()).unwrap();
    for (x, y) in [(32, 32), (35, 30), (44, 32), (32, 20), (0, 0)] {
        let (a_red, a_blue) = (alpha(5.0, 0.5, x, y), alpha(7.0, 2.0, x, y));
        let t = (1.0 - a_red) * (1.0 - a_blue);
        let expected = [
            a_red,
            t, // the green background behind both
            (1.0 - a_red) * a_blue,
        ]
        .map(|v| (v * 255.0).round() as u8);
        let got = image.pixel(x, y);
        for c in 0..3 {
            assert!(
                (i32::from(got[c]) - i32::from(expected[c])).abs() <= 1,
                "pixel ({x}, {y}): {got:?}, expected {expected:?}"
            );
        }
    }
    // The centre is mostly red (the front splat), the corner the background.
    assert!(image.pixel(32, 32)[0] > 200);
    assert_eq!(image.pixel(0, 0), [0, 255, 0]);
}

#[test]
fn unusable_previews_are_named_errors() {
    let mut p = params();
    p.width = 0;
    assert!(matches!(
        render_preview(&[], &p),
        Err(PreviewError::Params(_))
    ));
    let mut p = params();
    p.camera.up = Vector3::z();
    assert!(matches!(
        render_preview(&[], &p),
        Err(PreviewError::Params(_))
    ));
    let mut p = params();
    p.camera.fov_y_degrees = 180.0;
    assert!(matches!(
        render_preview(&[], &p),
        Err(PreviewError::Params(_))
    ));
}

#[test]
fn point_splats_ramp_from_blue_at_zero_to_red_at_the_98th_percentile() {
    let points = vec![nalgebra::Vector3::zeros(); 100];
    let values: Vec<f64> = (0..100).map(f64::from).collect();
    let splats = freeform::point_splats(&points, Some(&values), 0.1);
    assert_eq!(splats[0].colour, [0.1, 0.2, 0.9]);
    // 98 is the 98th percentile: red, and so is everything above it.
    for k in [98, 99] {
        assert!((splats[k].colour[0] - 1.0).abs() < 1e-12 && splats[k].colour[1] < 0.2);
    }
    // Half of it is white.
    let white = splats[49].colour;
    assert!(white.iter().all(|&c| c > 0.98), "{white:?}");
    assert!((splats[3].covariance - nalgebra::Matrix3::identity() * 0.01).norm() < 1e-15);
    let grey = freeform::point_splats(&points, None, 0.1);
    assert!(grey.iter().all(|s| s.colour == [0.8, 0.8, 0.8]));
}
