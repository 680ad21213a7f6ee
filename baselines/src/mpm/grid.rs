//! The background grid of one MPM substep: a dense block of nodes covering the stencils of
//! every particle and tracer (node n at n Δx, so the lattice never moves), and the slab
//! colouring that lets particle-to-grid scatter run in parallel without atomics and without
//! order-dependent sums.
//!
//! Nodes are stored with the longest axis slowest. Particles are bucketed by the slab of
//! [`SLAB_CELLS`] node rows their first stencil node falls in; a slab's particles write rows
//! `[s W, s W + W + 2)`, so slabs of the same parity never share a node. Even slabs scatter in
//! parallel, then odd ones; inside a slab particles go in index order. The sums therefore do
//! not depend on the number of threads.

use nalgebra::Vector3;

use crate::mpm::quadratic_stencil::QuadraticStencil;

/// Node rows per slab (W ≥ 2 keeps same-parity slabs disjoint).
pub const SLAB_CELLS: usize = 4;

/// A node: momentum (kg·m/s) then mass (kg) during the scatter; velocity (m/s) then mass after
/// [`BackgroundGrid::momentum_to_velocity`].
pub type Node = [f64; 4];

/// Where a block of grid nodes lies and how it is stored.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct GridLayout {
    /// Δx (m).
    pub spacing: f64,
    /// Global index of the block's first node per axis.
    pub lo: [i64; 3],
    /// Nodes per axis.
    pub dims: [usize; 3],
    /// Axes from slowest to fastest in storage (`order[0]` is the slab axis).
    pub order: [usize; 3],
}

/// A dense block of grid nodes.
#[derive(Clone, Debug, Default)]
pub struct BackgroundGrid {
    /// Where the block lies.
    pub layout: GridLayout,
    /// The nodes.
    pub nodes: Vec<Node>,
}

impl BackgroundGrid {
    /// Resizes the block to cover the stencils of every point of `points` (m) and zeroes it.
    /// `points` must be finite and non-empty.
    pub fn fit<'a>(&mut self, spacing: f64, points: impl Iterator<Item = &'a Vector3<f64>>) {
        let mut min = Vector3::repeat(f64::INFINITY);
        let mut max = Vector3::repeat(f64::NEG_INFINITY);
        for p in points {
            min = min.inf(p);
            max = max.sup(p);
        }
        let inverse = 1.0 / spacing;
        self.layout.spacing = spacing;
        for a in 0..3 {
            let first = (min[a] * inverse - 0.5).floor() as i64;
            let last = (max[a] * inverse - 0.5).floor() as i64 + 2;
            self.layout.lo[a] = first;
            self.layout.dims[a] = (last - first + 1) as usize;
        }
        let mut order = [0, 1, 2];
        order.sort_by_key(|&a| std::cmp::Reverse(self.layout.dims[a]));
        self.layout.order = order;
        let count = self.layout.dims.iter().product();
        self.nodes.clear();
        self.nodes.resize(count, [0.0; 4]);
    }

    /// The mutable row ranges of the slabs of one parity (`colour` 0 or 1), each with its slab
    /// index and first row; the ranges are disjoint.
    pub fn slabs_of_colour(&mut self, colour: usize) -> Vec<(usize, usize, &mut [Node])> {
        let stride = self.layout.row_stride();
        let rows = self.layout.rows();
        let slabs = self.layout.slabs();
        let mut rest: &mut [Node] = &mut self.nodes;
        let mut consumed_rows = 0;
        let mut out = Vec::new();
        for s in (colour..slabs).step_by(2) {
            let start = s * SLAB_CELLS;
            let end = (start + SLAB_CELLS + 2).min(rows);
            let tail = std::mem::take(&mut rest);
            let (_, tail) = tail.split_at_mut((start - consumed_rows) * stride);
            let (mine, tail) = tail.split_at_mut((end - start) * stride);
            out.push((s, start, mine));
            rest = tail;
            consumed_rows = end;
        }
        out
    }
}

impl GridLayout {
    /// Nodes per row of the slab axis (the stride of one row).
    pub fn row_stride(&self) -> usize {
        self.dims[self.order[1]] * self.dims[self.order[2]]
    }

    /// Rows along the slab axis.
    pub fn rows(&self) -> usize {
        self.dims[self.order[0]]
    }

    /// Storage index of node `base + (i, j, k)` of `stencil`, counted from row `first_row`.
    pub fn local_index(
        &self,
        stencil: &QuadraticStencil,
        offset: [usize; 3],
        first_row: usize,
    ) -> usize {
        let local = |a: usize| (stencil.base[a] + offset[a] as i64 - self.lo[a]) as usize;
        let [a0, a1, a2] = self.order;
        ((local(a0) - first_row) * self.dims[a1] + local(a1)) * self.dims[a2] + local(a2)
    }

    /// Storage index of node `base + (i, j, k)` of `stencil` in the whole block.
    pub fn index(&self, stencil: &QuadraticStencil, offset: [usize; 3]) -> usize {
        self.local_index(stencil, offset, 0)
    }

    /// The slab a point with `stencil` scatters into.
    pub fn slab(&self, stencil: &QuadraticStencil) -> usize {
        let a0 = self.order[0];
        (stencil.base[a0] - self.lo[a0]) as usize / SLAB_CELLS
    }

    /// Number of slabs.
    pub fn slabs(&self) -> usize {
        self.rows().div_ceil(SLAB_CELLS)
    }

    /// Position (m) of node `index` of the block.
    pub fn node_position(&self, index: usize) -> Vector3<f64> {
        let [a0, a1, a2] = self.order;
        let mut local = [0usize; 3];
        local[a2] = index % self.dims[a2];
        local[a1] = (index / self.dims[a2]) % self.dims[a1];
        local[a0] = index / (self.dims[a2] * self.dims[a1]);
        Vector3::from_fn(|a, _| (self.lo[a] + local[a] as i64) as f64 * self.spacing)
    }
}
