//! The sparse pattern of the Newton system on free degrees of freedom, its element scatter
//! table and the reused symbolic Cholesky analysis (design §3.8).

use std::sync::{Arc, Mutex, PoisonError};

use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::perm::PermRef;
use faer::sparse::linalg::cholesky::{
    LltRef, SymbolicCholesky, SymmetricOrdering, factorize_symbolic_cholesky,
};
use faer::sparse::{SparseColMat, SparseColMatRef, Triplet};
use faer::{Conj, MatMut, Par, Side};
use hyperelastic::HyperelasticMaterial;

use crate::factor_memory::FactorMemoryLimit;
use crate::fem_model::FemModel;
use crate::fill_reducing_ordering::{FillReducingOrdering, nested_dissection_of_node_triples};

/// The sparse system could not be set up.
#[derive(Debug, thiserror::Error)]
pub(crate) enum SystemSetupError {
    /// faer ran out of memory or rejected the pattern.
    #[error("{0}")]
    Faer(#[from] faer::sparse::FaerError),
    /// The nested-dissection ordering failed.
    #[error("nested-dissection ordering: {0}")]
    Ordering(#[from] nested_dissection::NestedDissectionError),
    /// The factors would need more memory than allowed.
    #[error("the Cholesky factors of {dofs} DOFs need {bytes} bytes, over the limit of {limit}")]
    FactorTooLarge {
        /// Free DOFs.
        dofs: usize,
        /// Nonzeros of one factor.
        factor_nonzeros: usize,
        /// Bytes needed (two factors and the workspace).
        bytes: u64,
        /// The limit (bytes).
        limit: u64,
    },
}

/// Sentinel of the scatter table: the entry is dropped (a fixed DOF or the upper triangle).
const DROPPED: u32 = u32::MAX;

/// Lower-triangular CSC pattern over the free DOFs plus, per element, where each of its
/// `(3·npe)²` local Hessian entries lands in the value array.
pub(crate) struct SparseSystem {
    /// Free index of each DOF (3 per node), or `usize::MAX` when fixed.
    pub(crate) free_index: Vec<usize>,
    pub(crate) free_count: usize,
    /// [`Self::factor_bytes`].
    factor_bytes: u64,
    pattern: SparseColMat<usize, f64>,
    scatter: Vec<u32>,
    symbolic: SymbolicCholesky<usize>,
    /// Parallelism of the numeric factorization and the solves.
    par: Par,
    /// Scratch of the factorization and the solves, kept so they do not page in fresh memory.
    workspace: Mutex<MemBuffer>,
    /// Value arrays of dropped factors, reused by the next factorization.
    spare_factors: Arc<Mutex<Vec<Vec<f64>>>>,
}

/// A numeric Cholesky factor `L` (`LLᵀ = PAPᵀ`, the fill-reducing permutation P of the
/// system's symbolic analysis): the values of `L` on the symbolic pattern. Dropping it hands
/// its array back to the system for the next factorization.
pub(crate) struct NumericFactor {
    l_values: Vec<f64>,
    spare: Arc<Mutex<Vec<Vec<f64>>>>,
}

impl Drop for NumericFactor {
    fn drop(&mut self) {
        let mut spare = self.spare.lock().unwrap_or_else(PoisonError::into_inner);
        // One spare is enough: a carried factor and the fresh one replacing it.
        if spare.is_empty() {
            spare.push(std::mem::take(&mut self.l_values));
        }
    }
}

impl SparseSystem {
    pub(crate) fn new<M: HyperelasticMaterial>(
        model: &FemModel<M>,
        fixed_nodes: &[bool],
        ordering: FillReducingOrdering,
        memory: FactorMemoryLimit,
    ) -> Result<Self, SystemSetupError> {
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
            .map_err(|_| SystemSetupError::Faer(faer::sparse::FaerError::OutOfMemory))?;
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
        // A geometric nested dissection tried before METIS left 1.2–1.4× AMD's fill on the beam.
        let minimum_degree = || {
            factorize_symbolic_cholesky(
                pattern.symbolic(),
                Side::Lower,
                SymmetricOrdering::Amd,
                Default::default(),
            )
        };
        let nested_dissection = || -> Result<SymbolicCholesky<usize>, SystemSetupError> {
            let (forward, inverse) = nested_dissection_of_node_triples(pattern.symbolic())?;
            Ok(factorize_symbolic_cholesky(
                pattern.symbolic(),
                Side::Lower,
                SymmetricOrdering::Custom(PermRef::new_checked(&forward, &inverse, free_count)),
                Default::default(),
            )?)
        };
        let symbolic = match ordering {
            FillReducingOrdering::ApproximateMinimumDegree => minimum_degree()?,
            FillReducingOrdering::NestedDissection => nested_dissection()?,
            FillReducingOrdering::SmallerFactor => {
                let (amd, nd) = (minimum_degree()?, nested_dissection()?);
                // A tie goes to minimum degree (equal fill, and it factored faster there).
                if nd.len_val() < amd.len_val() {
                    nd
                } else {
                    amd
                }
            }
        };
        // On 2 cores the parallel factorization is 1.3× faster than the sequential one (beam,
        // 27k DOFs).
        let par = faer::get_global_parallelism();
        let scratch = StackReq::any_of(&[
            symbolic.factorize_numeric_llt_scratch::<f64>(par, Default::default()),
            symbolic.solve_in_place_scratch::<f64>(1, par),
        ]);
        // A carried (or previous) factor and the fresh one live at once, beside the workspace.
        let bytes = 2 * 8 * symbolic.len_val() as u64 + scratch.unaligned_bytes_required() as u64;
        if let Some(limit) = memory.bytes()
            && bytes > limit
        {
            return Err(SystemSetupError::FactorTooLarge {
                dofs: free_count,
                factor_nonzeros: symbolic.len_val(),
                bytes,
                limit,
            });
        }
        let workspace = Mutex::new(
            MemBuffer::try_new(scratch)
                .map_err(|_| SystemSetupError::Faer(faer::sparse::FaerError::OutOfMemory))?,
        );
        Ok(SparseSystem {
            factor_bytes: bytes,
            free_index,
            free_count,
            pattern,
            scatter,
            symbolic,
            par,
            workspace,
            spare_factors: Arc::new(Mutex::new(Vec::new())),
        })
    }

    /// The Cholesky factor of the matrix with `values` on this pattern, or `None` when it is
    /// not numerically positive definite.
    pub(crate) fn factorize(&self, values: &[f64]) -> Option<NumericFactor> {
        let spare = self
            .spare_factors
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .pop();
        let mut l_values = spare.unwrap_or_default();
        // The factorization zeroes the array itself.
        l_values.resize(self.symbolic.len_val(), 0.0);
        let mut workspace = self
            .workspace
            .lock()
            .unwrap_or_else(PoisonError::into_inner);
        let positive_definite = self
            .symbolic
            .factorize_numeric_llt(
                &mut l_values,
                self.matrix(values),
                Side::Lower,
                Default::default(),
                self.par,
                MemStack::new(&mut workspace),
                Default::default(),
            )
            .is_ok();
        let factor = NumericFactor {
            l_values,
            spare: Arc::clone(&self.spare_factors),
        };
        positive_definite.then_some(factor)
    }

    /// Solves `A x = rhs` in place with `factor` (of A).
    pub(crate) fn solve_in_place(&self, factor: &NumericFactor, rhs: &mut [f64]) {
        let mut workspace = self
            .workspace
            .lock()
            .unwrap_or_else(PoisonError::into_inner);
        let n = rhs.len();
        LltRef::new(&self.symbolic, &factor.l_values).solve_in_place_with_conj(
            Conj::No,
            MatMut::from_column_major_slice_mut(rhs, n, 1),
            self.par,
            MemStack::new(&mut workspace),
        );
    }

    /// Number of stored (lower-triangle) entries.
    pub(crate) fn nonzeros(&self) -> usize {
        self.pattern.symbolic().row_idx().len()
    }

    /// Number of stored entries of the Cholesky factor L.
    pub(crate) fn factor_nonzeros(&self) -> usize {
        self.symbolic.len_val()
    }

    /// Bytes the factors need: two factors (a carried or previous one and the fresh one) and
    /// the factorization's workspace, what the memory limit is checked against.
    pub(crate) fn factor_bytes(&self) -> u64 {
        self.factor_bytes
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
