//! `freeform render`: CPU previews of 3DGS files (`freeform::splat_preview`) as PNG.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result, bail};
use freeform::{Camera, PreviewImage, PreviewParams, SplatTable, preview_splats, render_preview};
use nalgebra::Vector3;

/// The world axis that points up in the images.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub(crate) enum UpAxis {
    /// +x.
    X,
    /// +y.
    Y,
    /// +z.
    Z,
}

/// How to draw the previews.
#[derive(clap::Args, Debug)]
pub(crate) struct RenderOptions {
    /// Image width and height (pixels).
    #[arg(long, default_value_t = 512)]
    size: usize,
    /// The world axis that points up in the image.
    #[arg(long, value_enum, default_value_t = UpAxis::Y)]
    up: UpAxis,
    /// Camera azimuth about the up axis (degrees).
    #[arg(long, default_value_t = 30.0, allow_negative_numbers = true)]
    azimuth: f64,
    /// Camera elevation above the plane normal to the up axis (degrees).
    #[arg(long, default_value_t = 20.0, allow_negative_numbers = true)]
    elevation: f64,
}

/// Draws every file with one camera (framing the first file), writing `<out>/render/<stem>.png`.
pub(crate) fn run(files: &[PathBuf], options: &RenderOptions, out: &Path) -> Result<()> {
    if options.size == 0 || options.size > 8192 {
        bail!("--size must be 1 to 8192 pixels, got {}", options.size);
    }
    let up = match options.up {
        UpAxis::X => Vector3::x(),
        UpAxis::Y => Vector3::y(),
        UpAxis::Z => Vector3::z(),
    };
    let dir = out.join("render");
    std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
    let mut camera = None;
    for file in files {
        let start = Instant::now();
        let table = SplatTable::read(file)?;
        let splats = preview_splats(&table).with_context(|| file.display().to_string())?;
        let read_seconds = start.elapsed().as_secs_f64();
        let camera = *camera.get_or_insert_with(|| {
            let centres: Vec<Vector3<f64>> = splats.iter().map(|s| s.position).collect();
            Camera::framing(&centres, up, options.azimuth, options.elevation)
        });
        let params = PreviewParams {
            width: options.size,
            height: options.size,
            camera,
            background: [1.0, 1.0, 1.0],
        };
        let start = Instant::now();
        let image = render_preview(&splats, &params)?;
        let render_seconds = start.elapsed().as_secs_f64();
        let stem = file.file_stem().unwrap_or_default().to_string_lossy();
        let png = dir.join(format!("{stem}.png"));
        write_png(&image, &png)?;
        println!(
            "{} splats from {}: read {read_seconds:.2} s, drawn in {render_seconds:.2} s → {}",
            splats.len(),
            file.display(),
            png.display()
        );
    }
    Ok(())
}

/// Writes `image` as an 8-bit RGB PNG.
pub(crate) fn write_png(image: &PreviewImage, path: &Path) -> Result<()> {
    let width = u32::try_from(image.width).context("image width")?;
    let height = u32::try_from(image.height).context("image height")?;
    let mut rgb = Vec::with_capacity(3 * image.width * image.height);
    for y in 0..image.height {
        for x in 0..image.width {
            rgb.extend_from_slice(&image.pixel(x, y));
        }
    }
    let mut bytes = Vec::new();
    let mut encoder = png::Encoder::new(&mut bytes, width, height);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    encoder
        .write_header()
        .and_then(|mut writer| writer.write_image_data(&rgb))
        .with_context(|| format!("encoding {}", path.display()))?;
    artifact::write_atomically(path, &bytes)?;
    Ok(())
}
