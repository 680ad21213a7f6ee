//! Line and scatter plots written as SVG, and as PNG when a TrueType font is found on the system
//! (text in a bitmap needs one; SVG leaves text to the viewer).

use std::path::{Path, PathBuf};

use plotters::prelude::*;

use crate::EvalError;

/// One named series of (x, y) points.
#[derive(Clone, Debug)]
pub struct Series {
    /// Legend label.
    pub label: String,
    /// Points in drawing order.
    pub points: Vec<(f64, f64)>,
    /// Draw lines between points (else markers only).
    pub line: bool,
    /// Palette index.
    pub color: usize,
}

/// Which axes are logarithmic.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AxisScale {
    /// Both linear.
    Linear,
    /// Both logarithmic.
    LogLog,
    /// Linear x, logarithmic y.
    LogY,
}

/// A plot to draw.
#[derive(Clone, Debug)]
pub struct PlotSpec {
    /// Title.
    pub title: String,
    /// Axis labels.
    pub x_label: String,
    /// Axis labels.
    pub y_label: String,
    /// Which axes are logarithmic.
    pub scale: AxisScale,
    /// The data.
    pub series: Vec<Series>,
}

/// Fonts tried, in order, for PNG output.
const FONT_CANDIDATES: [&str; 4] = [
    "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/TTF/DejaVuSans.ttf",
    "/System/Library/Fonts/Supplemental/Arial.ttf",
];

fn register_font() -> bool {
    use std::sync::OnceLock;
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    *REGISTERED.get_or_init(|| {
        for path in FONT_CANDIDATES {
            if let Ok(bytes) = std::fs::read(path) {
                let leaked: &'static [u8] = Box::leak(bytes.into_boxed_slice());
                if plotters::style::register_font("sans-serif", FontStyle::Normal, leaked).is_ok() {
                    return true;
                }
            }
        }
        false
    })
}

/// The axes' ranges `(x0, x1, y0, y1)` of `spec`: its finite points (positive on log axes)
/// with a margin, and room below a log-log plot's data for the legend.
fn axis_ranges(spec: &PlotSpec) -> Result<(f64, f64, f64, f64), String> {
    let all: Vec<(f64, f64)> = spec
        .series
        .iter()
        .flat_map(|s| s.points.iter().copied())
        .collect();
    let finite: Vec<(f64, f64)> = all
        .into_iter()
        .filter(|(x, y)| {
            x.is_finite()
                && y.is_finite()
                && match spec.scale {
                    AxisScale::Linear => true,
                    AxisScale::LogLog => *x > 0.0 && *y > 0.0,
                    AxisScale::LogY => *y > 0.0,
                }
        })
        .collect();
    if finite.is_empty() {
        return Err("nothing to plot".into());
    }
    let (mut x0, mut x1, mut y0, mut y1) = finite.iter().fold(
        (
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
        ),
        |(a, b, c, d), &(x, y)| (a.min(x), b.max(x), c.min(y), d.max(y)),
    );
    let (px, py) = (0.05 * (x1 - x0).max(1e-12), 0.05 * (y1 - y0).max(1e-12));
    (x0, x1) = match spec.scale {
        AxisScale::LogLog => (x0 / 1.5, x1 * 1.5),
        AxisScale::Linear | AxisScale::LogY => (x0 - px, x1 + px),
    };
    (y0, y1) = match spec.scale {
        // The legend sits in the lower left of a log-log plot: room below the data for it,
        // about 3.5% of the height per series.
        AxisScale::LogLog => {
            let decades = (y1 / y0).log10().max(1.0);
            let share = (0.02 + 0.035 * spec.series.len() as f64).min(0.6);
            (
                y0 / 2.0 / 10f64.powf(decades * share / (1.0 - share)),
                y1 * 2.0,
            )
        }
        AxisScale::LogY => (y0 / 2.0, y1 * 2.0),
        AxisScale::Linear => (y0 - py, y1 + py),
    };
    Ok((x0, x1, y0, y1))
}

fn draw<DB: DrawingBackend>(
    root: DrawingArea<DB, plotters::coord::Shift>,
    spec: &PlotSpec,
) -> Result<(), String>
where
    DB::ErrorType: 'static,
{
    root.fill(&WHITE).map_err(|e| e.to_string())?;
    let (x0, x1, y0, y1) = axis_ranges(spec)?;
    let mut builder = ChartBuilder::on(&root);
    builder
        .caption(&spec.title, ("sans-serif", 22))
        .margin(15)
        .x_label_area_size(45)
        .y_label_area_size(70);
    macro_rules! body {
        ($chart:expr) => {{
            let mut chart = $chart;
            let log_y = spec.scale != AxisScale::Linear;
            let log_x = spec.scale == AxisScale::LogLog;
            let tick = |log: bool, v: f64| if log { log_tick(v) } else { format!("{v:.3}") };
            chart
                .configure_mesh()
                .x_label_formatter(&|v| tick(log_x, *v))
                .y_label_formatter(&|v| tick(log_y, *v))
                .x_desc(spec.x_label.as_str())
                .y_desc(spec.y_label.as_str())
                .label_style(("sans-serif", 14))
                .draw()
                .map_err(|e| e.to_string())?;
            for s in &spec.series {
                let color = Palette99::pick(s.color).to_rgba();
                let pts: Vec<(f64, f64)> = s
                    .points
                    .iter()
                    .copied()
                    .filter(|(x, y)| x.is_finite() && y.is_finite())
                    .collect();
                if s.line {
                    chart
                        .draw_series(LineSeries::new(pts.clone(), color.stroke_width(2)))
                        .map_err(|e| e.to_string())?
                        .label(s.label.as_str())
                        .legend(move |(x, y)| {
                            PathElement::new(vec![(x, y), (x + 18, y)], color.stroke_width(2))
                        });
                    chart
                        .draw_series(pts.iter().map(|&p| Circle::new(p, 3, color.filled())))
                        .map_err(|e| e.to_string())?;
                } else {
                    chart
                        .draw_series(pts.iter().map(|&p| Circle::new(p, 4, color.filled())))
                        .map_err(|e| e.to_string())?
                        .label(s.label.as_str())
                        .legend(move |(x, y)| Circle::new((x + 9, y), 4, color.filled()));
                }
            }
            chart
                .configure_series_labels()
                .position(match spec.scale {
                    AxisScale::LogLog => SeriesLabelPosition::LowerLeft,
                    AxisScale::Linear => SeriesLabelPosition::UpperRight,
                    AxisScale::LogY => SeriesLabelPosition::LowerRight,
                })
                .background_style(WHITE.mix(0.85))
                .border_style(BLACK)
                .label_font(("sans-serif", 14))
                .draw()
                .map_err(|e| e.to_string())?;
        }};
    }
    match spec.scale {
        AxisScale::LogLog => body!(
            builder
                .build_cartesian_2d((x0..x1).log_scale(), (y0..y1).log_scale())
                .map_err(|e| e.to_string())?
        ),
        AxisScale::LogY => body!(
            builder
                .build_cartesian_2d(x0..x1, (y0..y1).log_scale())
                .map_err(|e| e.to_string())?
        ),
        AxisScale::Linear => body!(
            builder
                .build_cartesian_2d(x0..x1, y0..y1)
                .map_err(|e| e.to_string())?
        ),
    }
    root.present().map_err(|e| e.to_string())?;
    Ok(())
}

/// Writes `<base>.svg`, and `<base>.png` when a font is available; returns the files written.
///
/// # Errors
/// [`EvalError::Plot`] if drawing fails.
pub fn write_plot(spec: &PlotSpec, base: &Path) -> Result<Vec<PathBuf>, EvalError> {
    if let Some(dir) = base.parent() {
        std::fs::create_dir_all(dir).map_err(|e| EvalError::io(dir, e))?;
    }
    let mut written = Vec::new();
    let font = register_font();
    let svg = base.with_extension("svg");
    draw(SVGBackend::new(&svg, (960, 640)).into_drawing_area(), spec).map_err(|message| {
        EvalError::Plot {
            path: svg.clone(),
            message,
        }
    })?;
    written.push(svg);
    if font {
        let png = base.with_extension("png");
        draw(
            BitMapBackend::new(&png, (960, 640)).into_drawing_area(),
            spec,
        )
        .map_err(|message| EvalError::Plot {
            path: png.clone(),
            message,
        })?;
        written.push(png);
    }
    Ok(written)
}

/// A log axis's label: only the ticks at 1, 2 and 5 times a power of ten are written (the
/// others would run into each other), in plain form between 0.01 and 1000, else as `1e-5`.
fn log_tick(v: f64) -> String {
    if !(v > 0.0 && v.is_finite()) {
        return String::new();
    }
    let decade = 10f64.powf(v.log10().floor());
    let lead = (v / decade).round();
    if ((v / decade) - lead).abs() > 1e-6 || !matches!(lead as u32, 1 | 2 | 5) {
        return String::new();
    }
    if (0.01..1000.0).contains(&v) {
        let text = format!("{v:.2}");
        text.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        format!("{v:.0e}")
    }
}

#[cfg(test)]
mod tests {
    use super::log_tick;

    #[test]
    fn log_ticks_label_one_two_and_five_per_decade_only() {
        let labels: Vec<String> = [1.0, 2.0, 3.0, 5.0, 8.0, 10.0, 20.0, 0.05, 1e-5, 2e-4, 7e-4]
            .map(log_tick)
            .to_vec();
        assert_eq!(
            labels,
            [
                "1", "2", "", "5", "", "10", "20", "0.05", "1e-5", "2e-4", ""
            ]
        );
        assert_eq!(log_tick(0.0), "");
    }
}
