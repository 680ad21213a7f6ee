#![doc = include_str!("../README.md")]

use std::sync::Mutex;

use thiserror::Error;

/// METIS draws from GKlib's random number generator, whose state is one process-wide array,
/// not per thread: two orderings at once would race on it (a data race in C) and each get a
/// sequence the other perturbed, so the same graph could be ordered differently from run to
/// run. Every call holds this lock; each call seeds the generator afresh.
static METIS: Mutex<()> = Mutex::new(());

/// A graph METIS cannot order.
#[derive(Clone, Debug, Error, PartialEq, Eq)]
pub enum NestedDissectionError {
    /// `offsets` does not start at 0, is not non-decreasing, or does not end at
    /// `neighbours.len()`.
    #[error(
        "adjacency offsets must start at 0, not decrease and end at the {neighbours} neighbours"
    )]
    Offsets {
        /// Neighbour entries given.
        neighbours: usize,
    },
    /// A neighbour index is not a vertex, or is the vertex itself.
    #[error(
        "vertex {vertex} lists {neighbour} as a neighbour, which is not another vertex of the {vertices}"
    )]
    Neighbour {
        /// The vertex.
        vertex: usize,
        /// The bad neighbour.
        neighbour: usize,
        /// Vertices in the graph.
        vertices: usize,
    },
    /// `a` lists `b` but `b` does not list `a`.
    #[error("the adjacency is not symmetric: {a} lists {b} but {b} does not list {a}")]
    NotSymmetric {
        /// The vertex listing the edge.
        a: usize,
        /// The vertex not listing it back.
        b: usize,
    },
    /// More vertices or edges than METIS's 32-bit indices hold.
    #[error(
        "the graph ({vertices} vertices, {neighbours} neighbour entries) is too large for 32-bit METIS"
    )]
    TooLarge {
        /// Vertices.
        vertices: usize,
        /// Neighbour entries.
        neighbours: usize,
    },
    /// METIS returned an error code.
    #[error("METIS_NodeND failed with code {code} (-2: input, -3: memory, -4: other)")]
    Metis {
        /// `METIS_ERROR_INPUT` = −2, `METIS_ERROR_MEMORY` = −3, `METIS_ERROR` = −4.
        code: i32,
    },
}

/// A fill-reducing elimination order of the undirected graph given in compressed adjacency
/// form: the neighbours of vertex v are `neighbours[offsets[v]..offsets[v + 1]]` (each edge
/// listed from both ends, no self-loops; `offsets` has `vertices + 1` entries).
///
/// Returns `order` with `order[k]` = the vertex eliminated k-th, i.e. row k of the permuted
/// matrix `PAPᵀ` is row `order[k]` of A (METIS's `perm`). It is a permutation of
/// `0..vertices`. Deterministic: METIS's default options, fixed seed, one call at a time in
/// the process (concurrent callers wait; the ordering is a small part of a factorization).
///
/// ```
/// // A path 0 – 1 – 2.
/// let order = nested_dissection::nested_dissection_order(&[0, 1, 3, 4], &[1, 0, 2, 1]).unwrap();
/// let mut sorted = order.clone();
/// sorted.sort();
/// assert_eq!(sorted, [0, 1, 2]);
/// ```
///
/// # Errors
/// [`NestedDissectionError`]: malformed or asymmetric adjacency, a graph beyond 32-bit
/// indices, or a METIS failure.
pub fn nested_dissection_order(
    offsets: &[usize],
    neighbours: &[usize],
) -> Result<Vec<usize>, NestedDissectionError> {
    let vertices = offsets.len().saturating_sub(1);
    let offsets_ok = offsets.first() == Some(&0)
        && offsets.windows(2).all(|w| w[0] <= w[1])
        && offsets.last() == Some(&neighbours.len());
    if !offsets_ok {
        return Err(NestedDissectionError::Offsets {
            neighbours: neighbours.len(),
        });
    }
    if vertices == 0 {
        return Ok(Vec::new());
    }
    let too_large = i32::try_from(vertices).is_err() || i32::try_from(neighbours.len()).is_err();
    if too_large {
        return Err(NestedDissectionError::TooLarge {
            vertices,
            neighbours: neighbours.len(),
        });
    }
    let listed = |a: usize, b: usize| neighbours[offsets[a]..offsets[a + 1]].contains(&b);
    for vertex in 0..vertices {
        for &neighbour in &neighbours[offsets[vertex]..offsets[vertex + 1]] {
            if neighbour >= vertices || neighbour == vertex {
                return Err(NestedDissectionError::Neighbour {
                    vertex,
                    neighbour,
                    vertices,
                });
            }
            if !listed(neighbour, vertex) {
                return Err(NestedDissectionError::NotSymmetric {
                    a: vertex,
                    b: neighbour,
                });
            }
        }
    }
    // Checked above: every value fits in i32.
    let mut xadj: Vec<i32> = offsets.iter().map(|&o| o as i32).collect();
    let mut adjncy: Vec<i32> = neighbours.iter().map(|&n| n as i32).collect();
    let mut nvtxs = vertices as i32;
    let mut options = [0 as metis_sys::idx_t; metis_sys::METIS_NOPTIONS as usize];
    let mut perm = vec![0 as metis_sys::idx_t; vertices];
    let mut iperm = vec![0 as metis_sys::idx_t; vertices];
    // A panic cannot leave METIS's state half-written (it never unwinds through C here), so a
    // poisoned lock is still good.
    let _metis = METIS
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner());
    // SAFETY: `options` has METIS_NOPTIONS entries, as METIS_SetDefaultOptions writes; `xadj`
    // has nvtxs + 1 entries ending at adjncy.len(), every adjncy entry is a vertex other than
    // its own (checked above), `perm` and `iperm` have nvtxs entries, and the null vertex
    // weights mean "unit weights". METIS reads these and writes only perm and iperm.
    #[allow(unsafe_code)]
    let code = unsafe {
        metis_sys::METIS_SetDefaultOptions(options.as_mut_ptr());
        metis_sys::METIS_NodeND(
            &mut nvtxs,
            xadj.as_mut_ptr(),
            adjncy.as_mut_ptr(),
            std::ptr::null_mut(),
            options.as_mut_ptr(),
            perm.as_mut_ptr(),
            iperm.as_mut_ptr(),
        )
    };
    if code != metis_sys::rstatus_et_METIS_OK {
        return Err(NestedDissectionError::Metis { code });
    }
    Ok(perm.into_iter().map(|p| p as usize).collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The 5-point Laplacian's graph on an n × n grid.
    fn grid_graph(n: usize) -> (Vec<usize>, Vec<usize>) {
        let mut offsets = vec![0];
        let mut neighbours = Vec::new();
        for i in 0..n {
            for j in 0..n {
                if i > 0 {
                    neighbours.push((i - 1) * n + j);
                }
                if i + 1 < n {
                    neighbours.push((i + 1) * n + j);
                }
                if j > 0 {
                    neighbours.push(i * n + j - 1);
                }
                if j + 1 < n {
                    neighbours.push(i * n + j + 1);
                }
                offsets.push(neighbours.len());
            }
        }
        (offsets, neighbours)
    }

    /// Entries of the Cholesky factor of the grid graph's matrix eliminated in `order`
    /// (symbolic elimination: eliminating v joins its not-yet-eliminated neighbours).
    fn factor_entries(offsets: &[usize], neighbours: &[usize], order: &[usize]) -> usize {
        let n = offsets.len() - 1;
        let mut position = vec![0; n];
        for (k, &v) in order.iter().enumerate() {
            position[v] = k;
        }
        let mut adjacency: Vec<std::collections::BTreeSet<usize>> = (0..n)
            .map(|v| {
                neighbours[offsets[v]..offsets[v + 1]]
                    .iter()
                    .copied()
                    .collect()
            })
            .collect();
        let mut entries = 0;
        for &v in order {
            let later: Vec<usize> = adjacency[v]
                .iter()
                .copied()
                .filter(|&u| position[u] > position[v])
                .collect();
            entries += later.len() + 1;
            for &a in &later {
                for &b in &later {
                    if a != b {
                        adjacency[a].insert(b);
                    }
                }
            }
        }
        entries
    }

    #[test]
    fn the_order_is_a_permutation_and_fills_a_grid_less_than_the_natural_order() {
        let n = 40;
        let (offsets, neighbours) = grid_graph(n);
        let order = nested_dissection_order(&offsets, &neighbours).unwrap();
        let mut seen = vec![false; n * n];
        for &v in &order {
            assert!(!seen[v], "vertex {v} twice");
            seen[v] = true;
        }
        assert!(seen.iter().all(|&s| s));
        let natural: Vec<usize> = (0..n * n).collect();
        let nested = factor_entries(&offsets, &neighbours, &order);
        let banded = factor_entries(&offsets, &neighbours, &natural);
        // The natural order of an n × n grid fills the band: about n³ = 64 000 entries;
        // nested dissection O(n² log n).
        assert!(
            (nested as f64) < 0.5 * banded as f64,
            "nested dissection {nested} entries, natural order {banded}"
        );
    }

    #[test]
    fn orderings_made_on_many_threads_at_once_equal_the_one_made_alone() {
        // Graphs large enough that METIS coarsens them with random matchings.
        let graphs: Vec<(Vec<usize>, Vec<usize>)> = [30, 31, 32, 33].map(grid_graph).into();
        let alone: Vec<Vec<usize>> = graphs
            .iter()
            .map(|(o, n)| nested_dissection_order(o, n).unwrap())
            .collect();
        std::thread::scope(|scope| {
            let handles: Vec<_> = (0..8)
                .map(|t| {
                    let (graphs, alone) = (&graphs, &alone);
                    scope.spawn(move || {
                        for round in 0..5 {
                            let g = (t + round) % graphs.len();
                            let (o, n) = &graphs[g];
                            assert_eq!(
                                nested_dissection_order(o, n).unwrap(),
                                alone[g],
                                "thread {t}, round {round}, graph {g}"
                            );
                        }
                    })
                })
                .collect();
            for h in handles {
                h.join().unwrap();
            }
        });
    }

    #[test]
    fn malformed_graphs_are_refused_by_name() {
        assert_eq!(nested_dissection_order(&[0], &[]), Ok(Vec::new()));
        assert_eq!(
            nested_dissection_order(&[0, 1, 1], &[1]),
            Err(NestedDissectionError::NotSymmetric { a: 0, b: 1 })
        );
        assert_eq!(
            nested_dissection_order(&[0, 1, 2], &[0, 0]),
            Err(NestedDissectionError::Neighbour {
                vertex: 0,
                neighbour: 0,
                vertices: 2
            })
        );
        assert_eq!(
            nested_dissection_order(&[0, 1, 2], &[5, 0]),
            Err(NestedDissectionError::Neighbour {
                vertex: 0,
                neighbour: 5,
                vertices: 2
            })
        );
        assert_eq!(
            nested_dissection_order(&[0, 2, 1], &[1, 0]),
            Err(NestedDissectionError::Offsets { neighbours: 2 })
        );
    }
}
