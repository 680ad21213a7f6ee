//! A line plot of a few time series as a self-contained SVG file, so the user's binary needs
//! no plotting crate.

use std::fmt::Write;

/// One line of a plot.
pub(crate) struct Series<'a> {
    /// Legend text.
    pub(crate) label: String,
    /// `(x, y)` points in drawing order.
    pub(crate) points: &'a [(f64, f64)],
    /// An SVG colour (`"#1f77b4"`).
    pub(crate) colour: &'static str,
}

/// A plot's title, axis labels and lines.
pub(crate) struct LinePlot<'a> {
    pub(crate) title: String,
    pub(crate) x_label: &'static str,
    pub(crate) y_label: &'static str,
    pub(crate) series: Vec<Series<'a>>,
}

const WIDTH: f64 = 720.0;
const HEIGHT: f64 = 440.0;
const LEFT: f64 = 80.0;
const RIGHT: f64 = 20.0;
const TOP: f64 = 40.0;
const BOTTOM: f64 = 60.0;
const TICKS: usize = 5;

impl LinePlot<'_> {
    /// The plot as SVG text: axes with five labelled ticks each, the lines, a legend.
    pub(crate) fn svg(&self) -> String {
        let all = self.series.iter().flat_map(|s| s.points.iter());
        let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
        for &(x, y) in all.filter(|(x, y)| x.is_finite() && y.is_finite()) {
            (x0, x1, y0, y1) = (x0.min(x), x1.max(x), y0.min(y), y1.max(y));
        }
        if x0 > x1 {
            (x0, x1, y0, y1) = (0.0, 1.0, 0.0, 1.0);
        }
        let (x1, y1) = (x1.max(x0 + 1e-12), y1.max(y0 + 1e-12));
        let (plot_w, plot_h) = (WIDTH - LEFT - RIGHT, HEIGHT - TOP - BOTTOM);
        let px = |x: f64| LEFT + (x - x0) / (x1 - x0) * plot_w;
        let py = |y: f64| TOP + (y1 - y) / (y1 - y0) * plot_h;
        let mut svg = format!(
            "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{WIDTH}\" height=\"{HEIGHT}\" \
             font-family=\"sans-serif\" font-size=\"13\">\n<rect width=\"100%\" height=\"100%\" \
             fill=\"white\"/>\n<text x=\"{}\" y=\"24\" text-anchor=\"middle\" font-size=\"15\">{}</text>\n\
             <rect x=\"{LEFT}\" y=\"{TOP}\" width=\"{plot_w}\" height=\"{plot_h}\" fill=\"none\" \
             stroke=\"black\"/>\n",
            WIDTH / 2.0,
            escape(&self.title)
        );
        for i in 0..=TICKS {
            let f = i as f64 / TICKS as f64;
            let (x, y) = (x0 + f * (x1 - x0), y0 + f * (y1 - y0));
            let _ = writeln!(
                svg,
                "<text x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"middle\">{x:.3}</text>\n\
                 <text x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"end\">{y:.3}</text>\n\
                 <line x1=\"{LEFT}\" x2=\"{:.1}\" y1=\"{:.1}\" y2=\"{:.1}\" stroke=\"#ddd\"/>",
                px(x),
                TOP + plot_h + 18.0,
                LEFT - 6.0,
                py(y) + 4.0,
                LEFT + plot_w,
                py(y),
                py(y)
            );
        }
        let _ = writeln!(
            svg,
            "<text x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"middle\">{}</text>\n\
             <text transform=\"translate(18 {:.1}) rotate(-90)\" text-anchor=\"middle\">{}</text>",
            LEFT + plot_w / 2.0,
            HEIGHT - 16.0,
            escape(self.x_label),
            TOP + plot_h / 2.0,
            escape(self.y_label)
        );
        for (k, series) in self.series.iter().enumerate() {
            let path: Vec<String> = series
                .points
                .iter()
                .filter(|(x, y)| x.is_finite() && y.is_finite())
                .map(|&(x, y)| format!("{:.2},{:.2}", px(x), py(y)))
                .collect();
            let legend_y = TOP + 18.0 + 18.0 * k as f64;
            let _ = writeln!(
                svg,
                "<polyline fill=\"none\" stroke=\"{c}\" stroke-width=\"2\" points=\"{}\"/>\n\
                 <line x1=\"{:.1}\" x2=\"{:.1}\" y1=\"{legend_y:.1}\" y2=\"{legend_y:.1}\" \
                 stroke=\"{c}\" stroke-width=\"2\"/>\n<text x=\"{:.1}\" y=\"{:.1}\">{}</text>",
                path.join(" "),
                LEFT + plot_w - 230.0,
                LEFT + plot_w - 205.0,
                LEFT + plot_w - 198.0,
                legend_y + 4.0,
                escape(&series.label),
                c = series.colour,
            );
        }
        svg.push_str("</svg>\n");
        svg
    }
}

/// `text` with the characters XML reserves escaped.
fn escape(text: &str) -> String {
    text.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_plot_draws_each_series_as_a_polyline_inside_its_frame_with_escaped_labels() {
        let a = [(0.0, 0.0), (1.0, -2.0)];
        let b = [(0.0, 0.0), (0.5, f64::NAN), (1.0, -1.0)];
        let svg = LinePlot {
            title: "tip <y>".into(),
            x_label: "time (s)",
            y_label: "y (m)",
            series: vec![
                Series {
                    label: "FEM".into(),
                    points: &a,
                    colour: "#000",
                },
                Series {
                    label: "ours & theirs".into(),
                    points: &b,
                    colour: "#f00",
                },
            ],
        }
        .svg();
        assert_eq!(svg.matches("<polyline").count(), 2);
        assert!(svg.contains("tip &lt;y&gt;") && svg.contains("ours &amp; theirs"));
        // The first point (x = 0, the top of y's range) is the frame's upper-left corner.
        assert!(
            svg.contains(&format!("points=\"{LEFT:.2},{TOP:.2} ")),
            "{svg}"
        );
        assert!(!svg.contains("NaN"));
    }
}
