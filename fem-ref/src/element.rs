//! Linear (P1, 4-node) and quadratic (P2, 10-node) tetrahedral elements: nodes, shape
//! functions in barycentric coordinates, quadrature, exact integrals (design §3.8).

use std::collections::HashMap;

use nalgebra::{Matrix3, Vector3, Vector4};
use serde::{Deserialize, Serialize};

use crate::tet_mesh::{TET_EDGES, TetMesh};

/// Polynomial order of the elements.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ElementOrder {
    /// P1: 4 corner nodes, constant strain, one quadrature point. Locks at ν = 0.45.
    #[serde(alias = "Linear")]
    Linear,
    /// P2: 4 corners + 6 edge midpoints (VTK order: edges 01, 12, 02, 03, 13, 23), linear
    /// strain, 4-point degree-2 quadrature.
    #[serde(alias = "Quadratic")]
    Quadratic,
}

impl ElementOrder {
    /// Nodes per element (4 or 10).
    pub fn nodes_per_element(self) -> usize {
        match self {
            ElementOrder::Linear => 4,
            ElementOrder::Quadratic => 10,
        }
    }
}

/// A finite-element mesh: nodes (m) and per-element node lists over a linear tet mesh.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FemMesh {
    order: ElementOrder,
    tets: TetMesh,
    nodes: Vec<Vector3<f64>>,
    /// `nodes_per_element` indices per element, flat.
    elements: Vec<usize>,
}

impl FemMesh {
    /// Elements of `order` on `tets`. For P2 the edge nodes are the straight edges' midpoints,
    /// shared between neighbouring elements; node indices `0..V` are the tet vertices.
    pub fn new(tets: TetMesh, order: ElementOrder) -> Self {
        let mut nodes = tets.vertices().to_vec();
        let mut elements = Vec::with_capacity(tets.tets().len() * order.nodes_per_element());
        let mut edge_nodes: HashMap<[usize; 2], usize> = HashMap::new();
        for tet in tets.tets() {
            elements.extend_from_slice(tet);
            if order == ElementOrder::Quadratic {
                for [a, b] in TET_EDGES {
                    let key = [tet[a].min(tet[b]), tet[a].max(tet[b])];
                    let node = *edge_nodes.entry(key).or_insert_with(|| {
                        nodes.push(0.5 * (nodes[key[0]] + nodes[key[1]]));
                        nodes.len() - 1
                    });
                    elements.push(node);
                }
            }
        }
        FemMesh {
            order,
            tets,
            nodes,
            elements,
        }
    }

    /// Element order.
    pub fn order(&self) -> ElementOrder {
        self.order
    }

    /// The underlying linear tet mesh.
    pub fn tet_mesh(&self) -> &TetMesh {
        &self.tets
    }

    /// Node rest positions (m): the tet vertices first, then (P2) edge midpoints.
    pub fn nodes(&self) -> &[Vector3<f64>] {
        &self.nodes
    }

    /// Number of elements.
    pub fn element_count(&self) -> usize {
        self.tets.tets().len()
    }

    /// Node indices of element `e`.
    pub fn element(&self, e: usize) -> &[usize] {
        let n = self.order.nodes_per_element();
        &self.elements[e * n..(e + 1) * n]
    }
}

/// Barycentric-coordinate gradients `∇λ_0..∇λ_3` (1/m) of a tetrahedron with edge matrix
/// `D = [x1-x0, x2-x0, x3-x0]`: rows of D⁻¹ for λ_1..λ_3, and minus their sum for λ_0.
pub fn barycentric_gradients(edge_matrix: &Matrix3<f64>) -> Option<[Vector3<f64>; 4]> {
    let inv = edge_matrix.try_inverse()?;
    let g1 = inv.row(0).transpose();
    let g2 = inv.row(1).transpose();
    let g3 = inv.row(2).transpose();
    Some([-(g1 + g2 + g3), g1, g2, g3])
}

/// Shape function values at barycentric coordinates λ (sum 1).
///
/// P1: `N_i = λ_i`. P2: corners `N_i = λ_i(2λ_i - 1)`, edge (i, j) nodes `N = 4λ_iλ_j`.
pub fn shape_values(order: ElementOrder, lambda: &Vector4<f64>) -> Vec<f64> {
    match order {
        ElementOrder::Linear => lambda.iter().copied().collect(),
        ElementOrder::Quadratic => {
            let mut v: Vec<f64> = lambda.iter().map(|l| l * (2.0 * l - 1.0)).collect();
            v.extend(TET_EDGES.iter().map(|[i, j]| 4.0 * lambda[*i] * lambda[*j]));
            v
        }
    }
}

/// Shape function gradients (1/m) at λ, from the barycentric gradients.
///
/// P2: corners `(4λ_i - 1)∇λ_i`, edges `4(λ_j∇λ_i + λ_i∇λ_j)`.
pub fn shape_gradients(
    order: ElementOrder,
    lambda: &Vector4<f64>,
    grad_lambda: &[Vector3<f64>; 4],
) -> Vec<Vector3<f64>> {
    match order {
        ElementOrder::Linear => grad_lambda.to_vec(),
        ElementOrder::Quadratic => {
            let mut g: Vec<Vector3<f64>> = (0..4)
                .map(|i| (4.0 * lambda[i] - 1.0) * grad_lambda[i])
                .collect();
            g.extend(
                TET_EDGES.iter().map(|[i, j]| {
                    4.0 * (lambda[*j] * grad_lambda[*i] + lambda[*i] * grad_lambda[*j])
                }),
            );
            g
        }
    }
}

/// Quadrature on a tetrahedron: barycentric points and weights summing to 1 (multiply by the
/// volume). P1: the centroid. P2: the symmetric 4-point rule, exact for degree 2 (the P2
/// stiffness of linear elasticity is integrated exactly).
pub fn quadrature(order: ElementOrder) -> Vec<(Vector4<f64>, f64)> {
    match order {
        ElementOrder::Linear => vec![(Vector4::repeat(0.25), 1.0)],
        ElementOrder::Quadratic => {
            let a = 0.585_410_196_624_968_5;
            let b = 0.138_196_601_125_010_5;
            (0..4)
                .map(|i| {
                    let mut l = Vector4::repeat(b);
                    l[i] = a;
                    (l, 0.25)
                })
                .collect()
        }
    }
}

/// A polynomial in the barycentric coordinates: `Σ c · λ0^a0 λ1^a1 λ2^a2 λ3^a3`.
#[derive(Clone, Debug, Default)]
pub(crate) struct BarycentricPolynomial(Vec<(f64, [u32; 4])>);

impl BarycentricPolynomial {
    /// The shape functions of `order` as polynomials.
    pub(crate) fn shape_functions(order: ElementOrder) -> Vec<Self> {
        let unit = |i: usize| {
            let mut e = [0; 4];
            e[i] = 1;
            e
        };
        match order {
            ElementOrder::Linear => (0..4).map(|i| Self(vec![(1.0, unit(i))])).collect(),
            ElementOrder::Quadratic => {
                let mut v: Vec<Self> = (0..4)
                    .map(|i| {
                        let mut sq = [0; 4];
                        sq[i] = 2;
                        Self(vec![(2.0, sq), (-1.0, unit(i))])
                    })
                    .collect();
                v.extend(TET_EDGES.iter().map(|[i, j]| {
                    let mut e = [0; 4];
                    e[*i] = 1;
                    e[*j] = 1;
                    Self(vec![(4.0, e)])
                }));
                v
            }
        }
    }

    pub(crate) fn times(&self, other: &Self) -> Self {
        let mut out = Vec::with_capacity(self.0.len() * other.0.len());
        for (c, a) in &self.0 {
            for (d, b) in &other.0 {
                out.push((c * d, [a[0] + b[0], a[1] + b[1], a[2] + b[2], a[3] + b[3]]));
            }
        }
        Self(out)
    }

    /// `∫_T p dV / V`, exactly: `∫ λ0^a λ1^b λ2^c λ3^d dV = 6V a!b!c!d! / (a+b+c+d+3)!`.
    pub(crate) fn mean_over_tet(&self) -> f64 {
        let factorial = |n: u32| (1..=n).map(f64::from).product::<f64>();
        self.0
            .iter()
            .map(|(c, e)| {
                let s: u32 = e.iter().sum();
                c * 6.0 * e.iter().map(|&k| factorial(k)).product::<f64>() / factorial(s + 3)
            })
            .sum()
    }
}

/// The element mass matrix divided by ρV: `∫ N_a N_b dV / V` (exact), nodes_per_element².
pub fn reference_mass_matrix(order: ElementOrder) -> Vec<f64> {
    let n = BarycentricPolynomial::shape_functions(order);
    let k = n.len();
    let mut m = vec![0.0; k * k];
    for a in 0..k {
        for b in 0..k {
            m[a * k + b] = n[a].times(&n[b]).mean_over_tet();
        }
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exact_mass_matrices_match_textbook_values() {
        // P1: V/20 (2 on the diagonal, 1 off it).
        let m = reference_mass_matrix(ElementOrder::Linear);
        assert!((m[0] - 0.1).abs() < 1e-15 && (m[1] - 0.05).abs() < 1e-15);
        // P2: the entries sum to 1 (partition of unity), corner-corner diagonal 6/420,
        // edge-edge diagonal 32/420.
        let m = reference_mass_matrix(ElementOrder::Quadratic);
        assert!((m.iter().sum::<f64>() - 1.0).abs() < 1e-14);
        assert!((m[0] - 6.0 / 420.0).abs() < 1e-15);
        assert!((m[4 * 10 + 4] - 32.0 / 420.0).abs() < 1e-15);
    }

    #[test]
    fn quadratic_shape_functions_are_nodal_and_sum_to_one() {
        let corners = [Vector4::x(), Vector4::y(), Vector4::z(), Vector4::w()];
        let mut points = corners.to_vec();
        points.extend(
            TET_EDGES
                .iter()
                .map(|[i, j]| 0.5 * (corners[*i] + corners[*j])),
        );
        for (p, lambda) in points.iter().enumerate() {
            let v = shape_values(ElementOrder::Quadratic, lambda);
            for (n, value) in v.iter().enumerate() {
                let expected = if n == p { 1.0 } else { 0.0 };
                assert!((value - expected).abs() < 1e-15);
            }
        }
        let lambda = Vector4::new(0.1, 0.2, 0.3, 0.4);
        let sum: f64 = shape_values(ElementOrder::Quadratic, &lambda).iter().sum();
        assert!((sum - 1.0).abs() < 1e-15);
    }
}
