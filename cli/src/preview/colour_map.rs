//! Viridis, the colour map of the previews and the viewer page (`cli/viewer/viewer.js` has
//! the same table).

use super::raster::Rgb;

/// matplotlib's viridis at 0, ¼, ½, ¾ and 1 (sRGB bytes).
const VIRIDIS: [[u8; 3]; 5] = [
    [0x44, 0x01, 0x54],
    [0x3b, 0x52, 0x8b],
    [0x21, 0x91, 0x8c],
    [0x5e, 0xc9, 0x62],
    [0xfd, 0xe7, 0x25],
];

/// Viridis at `t` (clamped to [0, 1]), linearly interpolated between its quartiles.
pub(crate) fn viridis(t: f64) -> Rgb {
    let s = if t.is_finite() {
        t.clamp(0.0, 1.0)
    } else {
        0.0
    } * (VIRIDIS.len() - 1) as f64;
    let i = (s.floor() as usize).min(VIRIDIS.len() - 2);
    let w = s - i as f64;
    std::array::from_fn(|k| {
        let (a, b) = (f64::from(VIRIDIS[i][k]), f64::from(VIRIDIS[i + 1][k]));
        (a + (b - a) * w) / 255.0
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn viridis_runs_from_dark_purple_to_yellow_and_clamps() {
        assert_eq!(viridis(0.0), viridis(-3.0));
        assert_eq!(viridis(1.0), viridis(7.0));
        let (low, high) = (viridis(0.0), viridis(1.0));
        assert!(low.iter().sum::<f64>() < 0.8 && high[0] > 0.9 && high[1] > 0.8 && high[2] < 0.2);
        assert_eq!(viridis(f64::NAN), low);
    }
}
