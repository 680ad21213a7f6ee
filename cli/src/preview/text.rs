//! Labels on the previews, in the 8 × 8 bitmap font of `font8x8` (public domain).

use font8x8::{BASIC_FONTS, UnicodeFonts};

use super::raster::{Canvas, Rgb};

/// Pixels across `text` at `scale`.
#[cfg(test)]
fn text_width(text: &str, scale: usize) -> usize {
    8 * scale * text.chars().count()
}

/// Writes `text` with its top-left corner at `(x, y)`, each font pixel `scale` pixels wide;
/// characters outside basic Latin are drawn as `?`.
pub(crate) fn draw_text(
    canvas: &mut Canvas,
    x: usize,
    y: usize,
    text: &str,
    scale: usize,
    colour: Rgb,
) {
    for (n, ch) in text.chars().enumerate() {
        let glyph = BASIC_FONTS
            .get(ch)
            .or_else(|| BASIC_FONTS.get('?'))
            .unwrap_or([0; 8]);
        for (row, bits) in glyph.iter().enumerate() {
            for col in 0..8 {
                if bits >> col & 1 == 1 {
                    canvas.fill(
                        x + 8 * scale * n + col * scale,
                        y + row * scale,
                        scale,
                        scale,
                        colour,
                    );
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn text_marks_pixels_only_inside_its_box() {
        let mut canvas = Canvas::new(40, 12, [1.0; 3]);
        draw_text(&mut canvas, 2, 2, "Pa", 1, [0.0; 3]);
        let dark: Vec<(usize, usize)> = (0..12)
            .flat_map(|y| (0..40).map(move |x| (x, y)))
            .filter(|&(x, y)| canvas.rgb[y * 40 + x] == [0.0; 3])
            .collect();
        assert!(!dark.is_empty());
        assert!(
            dark.iter()
                .all(|&(x, y)| (2..2 + text_width("Pa", 1)).contains(&x) && (2..10).contains(&y))
        );
    }
}
