//! The sparse pattern of the Newton system on free degrees of freedom, its element scatter
//! table and the reused symbolic Cholesky analysis (DESIGN 3.8).

use faer::Side;
use faer::sparse::linalg::solvers::SymbolicLlt;
use faer::sparse::{SparseColMat, SparseColMatRef, Triplet};
use hyperelastic::HyperelasticMaterial;

use crate::fem_model::FemModel;

/// Sentinel of the scatter table: the entry is dropped (a fixed DOF or the upper triangle).
const DROPPED: u32 = u32::MAX;

/// Lower-triangular CSC pattern over the free DOFs plus, per element, where each of its
/// `(3·npe)²` local Hessian entries lands in the value array.
pub(crate) struct SparseSystem {
    /// Free index of each DOF (3 per node), or `usize::MAX` when fixed.
    pub(crate) free_index: Vec<usize>,
    pub(crate) free_count: usize,
    pattern: SparseColMat<usize, f64>,
    scatter: Vec<u32>,
    pub(crate) symbolic: SymbolicLlt<usize>,
}

impl SparseSystem {
    pub(crate) fn new<M: HyperelasticMaterial>(
        model: &FemModel<M>,
        fixed_nodes: &[bool],
    ) -> Result<Self, faer::sparse::FaerError> {
        let mesh = model.mesh();
        let mut free_index = vec![usize::MAX; 3 * mesh.nodes().len()];
        let mut free_count = 0;
        for (node, &fixed) in fixed_nodes.iter().enumerate() {
            if !fixed {
                for i in 0..3 {
                    free_index[3 * node + i] = free_count;
                    free_count += 1;
                }
            }
        }
        let npe = mesh.order().nodes_per_element();
        let n = 3 * npe;
        let free = &free_index;
        let local_dofs = |e: usize| -> Vec<usize> {
            mesh.element(e)
                .iter()
                .flat_map(|&node| (0..3).map(move |i| free[3 * node + i]))
                .collect()
        };
        let mut triplets = Vec::new();
        for e in 0..mesh.element_count() {
            let dofs = local_dofs(e);
            for &r in &dofs {
                for &c in &dofs {
                    if r != usize::MAX && c != usize::MAX && r >= c {
                        triplets.push(Triplet::new(r, c, 0.0));
                    }
                }
            }
        }
        let pattern = SparseColMat::try_new_from_triplets(free_count, free_count, &triplets)
            .map_err(|_| faer::sparse::FaerError::OutOfMemory)?;
        drop(triplets);
        let col_ptr = pattern.symbolic().col_ptr().to_vec();
        let row_idx = pattern.symbolic().row_idx().to_vec();
        let position = |r: usize, c: usize| -> u32 {
            let rows = &row_idx[col_ptr[c]..col_ptr[c + 1]];
            let k = rows.binary_search(&r).expect("entry in the pattern");
            (col_ptr[c] + k) as u32
        };
        let mut scatter = vec![DROPPED; mesh.element_count() * n * n];
        for e in 0..mesh.element_count() {
            let dofs = local_dofs(e);
            for (a, &r) in dofs.iter().enumerate() {
                for (b, &c) in dofs.iter().enumerate() {
                    if r != usize::MAX && c != usize::MAX && r >= c {
                        scatter[e * n * n + a * n + b] = position(r, c);
                    }
                }
            }
        }
        let symbolic = SymbolicLlt::try_new(pattern.symbolic(), Side::Lower)?;
        Ok(SparseSystem {
            free_index,
            free_count,
            pattern,
            scatter,
            symbolic,
        })
    }

    /// Number of stored (lower-triangle) entries.
    pub(crate) fn nonzeros(&self) -> usize {
        self.pattern.symbolic().row_idx().len()
    }

    /// Adds element e's local Hessian (row-major, `(3·npe)²`) into `values`.
    pub(crate) fn scatter_element(&self, e: usize, local: &[f64], values: &mut [f64]) {
        let table = &self.scatter[e * local.len()..(e + 1) * local.len()];
        for (&slot, &v) in table.iter().zip(local) {
            if slot != DROPPED {
                values[slot as usize] += v;
            }
        }
    }

    /// Adds `v` at (r, c) of the lower triangle (free indices, r ≥ c, entry in the pattern).
    pub(crate) fn add(&self, r: usize, c: usize, v: f64, values: &mut [f64]) {
        let (r, c) = if r >= c { (r, c) } else { (c, r) };
        let sym = self.pattern.symbolic();
        let rows = &sym.row_idx()[sym.col_ptr()[c]..sym.col_ptr()[c + 1]];
        let k = rows.binary_search(&r).expect("entry in the pattern");
        values[sym.col_ptr()[c] + k] += v;
    }

    /// The matrix with `values` on this pattern.
    pub(crate) fn matrix<'a>(&'a self, values: &'a [f64]) -> SparseColMatRef<'a, usize, f64> {
        SparseColMatRef::new(self.pattern.symbolic(), values)
    }
}
