//! The elimination order of the FEM's sparse Cholesky factorization (design §3.8).

use faer::sparse::SymbolicSparseColMatRef;
use nested_dissection::{NestedDissectionError, nested_dissection_order};
use serde::{Deserialize, Serialize};

/// How the Newton system's unknowns are ordered before the Cholesky factorization
/// `LLᵀ = PAPᵀ`. The order changes how many entries `L` has (its fill), hence the time and
/// memory of each factorization, and nothing else but round-off: converged states agree to the
/// Newton tolerance, so the order is not part of a trajectory's cache key.
///
/// Neither order wins everywhere (`eval` example `shape_reference_timing --ordering`, P2 graded
/// shape references, Pull farthest, 2 cores; factor entries and factorization + solve seconds
/// per step, nested dissection against minimum degree):
///
/// | mesh | free DOFs | entries ND / AMD | s/step ND / AMD |
/// |---|---|---|---|
/// | beam P2 res 6 (Bend) | 27k | | 0.38 / 0.53–0.60 |
/// | hand | 39k | 7.24M / 6.75M | 0.32 / 0.28 |
/// | bunny | 94k | 31.8M / 39.0M | 1.30 / 1.60 |
/// | 37881 | 265k | 99.3M / 152.2M | 10.3 / 16.4 |
/// | scorpion | 374k | 94.8M / 94.6M | 6.9 / 5.2 |
/// | 243015 | 417k | 147M / 207M | 14.2 / 23.8 |
///
/// Hence the default analyses both (symbolically: well under a second at 400k DOFs, against
/// seconds per factorization) and keeps the smaller factor.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FillReducingOrdering {
    /// Approximate minimum degree on the degrees of freedom (faer's default; the references'
    /// order before the ordering study of the shapes' references).
    #[serde(alias = "ApproximateMinimumDegree")]
    ApproximateMinimumDegree,
    /// Nested dissection (METIS 5) on the graph of the free nodes, each node's three degrees
    /// of freedom kept together.
    #[serde(alias = "NestedDissection")]
    NestedDissection,
    /// Both analysed, the one whose factor has fewer entries kept (a tie goes to minimum
    /// degree; the default).
    #[default]
    #[serde(alias = "SmallerFactor")]
    SmallerFactor,
}

/// The nested-dissection order of a system whose free degrees of freedom come in triples, one
/// per node (free DOF `3k + i` is component i of free node k): METIS orders the nodes, and
/// each node's three DOFs follow one another. `lower` is the system's lower-triangular pattern
/// (`3n × 3n`). Returns (forward, inverse) DOF permutations with `forward[k]` the DOF
/// eliminated k-th and `inverse[forward[k]] = k`.
///
/// # Errors
/// [`NestedDissectionError`] from METIS (a system beyond 32-bit indices).
pub(crate) fn nested_dissection_of_node_triples(
    lower: SymbolicSparseColMatRef<'_, usize>,
) -> Result<(Vec<usize>, Vec<usize>), NestedDissectionError> {
    let dofs = lower.ncols();
    debug_assert_eq!(dofs % 3, 0, "free DOFs come in triples");
    let nodes = dofs / 3;
    // Node adjacency from the first DOF's column of each node: rows below the diagonal give
    // the pairs (a, b) with b > a, listed from both ends.
    let mut pairs: Vec<(usize, usize)> = Vec::new();
    for a in 0..nodes {
        let column = 3 * a;
        let rows = &lower.row_idx()[lower.col_ptr()[column]..lower.col_ptr()[column + 1]];
        let mut last = usize::MAX;
        for &r in rows {
            let b = r / 3;
            if b != a && b != last {
                pairs.push((a, b));
                pairs.push((b, a));
                last = b;
            }
        }
    }
    pairs.sort_unstable();
    pairs.dedup();
    let mut offsets = vec![0; nodes + 1];
    for &(a, _) in &pairs {
        offsets[a + 1] += 1;
    }
    for a in 0..nodes {
        offsets[a + 1] += offsets[a];
    }
    let neighbours: Vec<usize> = pairs.into_iter().map(|(_, b)| b).collect();
    let node_order = nested_dissection_order(&offsets, &neighbours)?;
    let forward: Vec<usize> = node_order
        .iter()
        .flat_map(|&node| (0..3).map(move |i| 3 * node + i))
        .collect();
    let mut inverse = vec![0; dofs];
    for (k, &dof) in forward.iter().enumerate() {
        inverse[dof] = k;
    }
    Ok((forward, inverse))
}
