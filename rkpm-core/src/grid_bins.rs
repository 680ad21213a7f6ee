//! Boxes binned on the cells of a uniform grid: the broad phase of point queries against
//! triangles ([`crate::InsideTest`], on a 2D grid) and tetrahedra (`fem_ref`'s point location,
//! on a 3D one).
//!
//! Each item is an axis-aligned box; it is listed in every cell its box meets (cells found by
//! clamping the box's corners into the grid), and a query reads the one cell holding its point.
//! Storage is compressed rows built by one counting sort, `O(items · cells each meets)`.

/// Per cell of a uniform `dims[0] × … × dims[N−1]` grid with corner `origin` and cell sides
/// `cell`, the indices of the boxes that meet it, ascending.
///
/// Postcondition of [`GridBins::new`]: box `i = (lo, hi)` is listed in cell `c` exactly when
/// `cell_of(lo)[k] ≤ c[k] ≤ cell_of(hi)[k]` for every axis `k`; in particular a point `p`
/// inside box `i` finds `i` in [`GridBins::items_at`]`(p)`.
#[derive(Clone, Debug)]
pub struct GridBins<const N: usize> {
    origin: [f64; N],
    cell: [f64; N],
    dims: [usize; N],
    /// Items of flat cell `f`: `items[starts[f]..starts[f + 1]]`.
    starts: Vec<usize>,
    items: Vec<u32>,
}

impl<const N: usize> GridBins<N> {
    /// Bins boxes `0..boxes.len()`, each given by its lower and upper corner (units of
    /// `origin`).
    ///
    /// # Panics
    /// If a dimension is zero, a cell side is not positive, or there are more than `u32::MAX`
    /// boxes (the callers size the grid themselves; any of these is a bug in the caller).
    pub fn new(
        origin: [f64; N],
        cell: [f64; N],
        dims: [usize; N],
        boxes: &[([f64; N], [f64; N])],
    ) -> Self {
        assert!(dims.iter().all(|&d| d > 0), "a grid with an empty axis");
        assert!(cell.iter().all(|&c| c > 0.0), "cell sides must be positive");
        assert!(boxes.len() <= u32::MAX as usize, "too many boxes to bin");
        let mut bins = GridBins {
            origin,
            cell,
            dims,
            starts: Vec::new(),
            items: Vec::new(),
        };
        let ranges: Vec<_> = boxes
            .iter()
            .map(|(lo, hi)| (bins.cell_of(*lo), bins.cell_of(*hi)))
            .collect();
        let cells: usize = dims.iter().product();
        let mut counts = vec![0usize; cells + 1];
        for (from, to) in &ranges {
            bins.for_each_cell(from, to, |f| counts[f + 1] += 1);
        }
        for f in 0..cells {
            counts[f + 1] += counts[f];
        }
        let mut next = counts.clone();
        let mut items = vec![0u32; counts[cells]];
        for (i, (from, to)) in ranges.iter().enumerate() {
            bins.for_each_cell(from, to, |f| {
                items[next[f]] = i as u32;
                next[f] += 1;
            });
        }
        bins.starts = counts;
        bins.items = items;
        bins
    }

    /// Cells per axis.
    pub fn dims(&self) -> [usize; N] {
        self.dims
    }

    /// The cell holding `p`, clamped into the grid (a NaN coordinate gives cell 0 on its axis).
    pub fn cell_of(&self, p: [f64; N]) -> [usize; N] {
        std::array::from_fn(|k| {
            let i = ((p[k] - self.origin[k]) / self.cell[k]).floor();
            // `as usize` saturates: negative and NaN give 0.
            (i as usize).min(self.dims[k] - 1)
        })
    }

    /// The boxes listed in the cell holding `p` (every box that contains `p`, and others
    /// nearby), ascending.
    pub fn items_at(&self, p: [f64; N]) -> &[u32] {
        let f = self.flat(&self.cell_of(p));
        &self.items[self.starts[f]..self.starts[f + 1]]
    }

    /// Row-major flat index (the last axis fastest).
    fn flat(&self, cell: &[usize; N]) -> usize {
        (0..N).fold(0, |f, k| f * self.dims[k] + cell[k])
    }

    /// Calls `visit` with the flat index of every cell in `from..=to` (per axis).
    fn for_each_cell(&self, from: &[usize; N], to: &[usize; N], mut visit: impl FnMut(usize)) {
        let mut cell = *from;
        loop {
            visit(self.flat(&cell));
            // Odometer: advance the last axis, carrying into the earlier ones.
            let mut k = N;
            loop {
                if k == 0 {
                    return;
                }
                k -= 1;
                if cell[k] < to[k] {
                    cell[k] += 1;
                    break;
                }
                cell[k] = from[k];
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_cell_lists_exactly_the_boxes_that_meet_it_in_ascending_order() {
        // Unit cells on [0, 3) × [0, 4) × [0, 2), corner at (−1, 0, 2).
        let bins_of = |boxes: &[([f64; 3], [f64; 3])]| {
            GridBins::new([-1.0, 0.0, 2.0], [1.0, 1.0, 1.0], [3, 4, 2], boxes)
        };
        let boxes = [
            ([-5.0, -5.0, -5.0], [9.0, 9.0, 9.0]), // all cells (clamped)
            ([0.2, 2.5, 3.1], [0.7, 2.6, 3.9]),    // cell (1, 2, 1) only
            ([-1.0, 1.0, 2.0], [0.5, 3.5, 2.5]),   // x 0..=1, y 1..=3, z 0
            ([1.1, 0.1, 3.2], [1.2, 0.2, 3.3]),    // cell (2, 0, 1)
        ];
        let bins = bins_of(&boxes);
        assert_eq!(bins.dims(), [3, 4, 2]);
        let expected_ranges = [
            ([0, 0, 0], [2, 3, 1]),
            ([1, 2, 1], [1, 2, 1]),
            ([0, 1, 0], [1, 3, 0]),
            ([2, 0, 1], [2, 0, 1]),
        ];
        let mut listed = 0;
        for x in 0..3 {
            for y in 0..4 {
                for z in 0..2 {
                    let cell = [x, y, z];
                    let expected: Vec<u32> = expected_ranges
                        .iter()
                        .enumerate()
                        .filter(|(_, (from, to))| {
                            (0..3).all(|k| from[k] <= cell[k] && cell[k] <= to[k])
                        })
                        .map(|(i, _)| i as u32)
                        .collect();
                    let centre = [x as f64 - 0.5, y as f64 + 0.5, z as f64 + 2.5];
                    assert_eq!(bins.cell_of(centre), cell);
                    assert_eq!(bins.items_at(centre), expected.as_slice(), "cell {cell:?}");
                    listed += expected.len();
                }
            }
        }
        // 24 + 1 + 6 + 1 cell memberships.
        assert_eq!(listed, 32);
    }

    #[test]
    fn points_off_the_grid_and_nan_are_clamped_into_it() {
        let bins = GridBins::new([0.0, 0.0], [0.5, 2.0], [4, 3], &[]);
        assert_eq!(bins.cell_of([-3.0, 100.0]), [0, 2]);
        assert_eq!(bins.cell_of([f64::NAN, 1.9]), [0, 0]);
        assert_eq!(bins.cell_of([1.99, 5.99]), [3, 2]);
        assert!(bins.items_at([1.0, 1.0]).is_empty());
    }
}
