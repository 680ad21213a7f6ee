//! A finite-element model: mesh, per-element materials, precomputed shape-function gradients at
//! quadrature points, mass matrix, and element energies, forces and tangents (design §3.8).

use hyperelastic::MaterialSample;
use hyperelastic::{
    HyperelasticMaterial, LameParameters, MaterialParameterError, Matrix9, Tangent,
};
use nalgebra::{Matrix3, Vector3};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::element::{
    FemMesh, barycentric_gradients, quadrature, reference_mass_matrix, shape_gradients,
};

/// How the mass matrix is formed.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum MassKind {
    /// `M_ab = ∫ ρ N_a N_b dV`, integrated exactly (default; the reference).
    #[default]
    #[serde(alias = "Consistent")]
    Consistent,
    /// Diagonal HRZ lumping: each element's consistent diagonal scaled to the element's mass.
    /// (Row-sum lumping would give P2 corner nodes negative mass.)
    #[serde(alias = "Lumped")]
    Lumped,
}

/// The model could not be built.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum FemModelError {
    /// One material per element is required.
    #[error("{materials} materials given for {elements} elements")]
    MaterialCount {
        /// Given.
        materials: usize,
        /// Elements.
        elements: usize,
    },
    /// An element's material is invalid.
    #[error("material of element {element}: {source}")]
    Material {
        /// Element.
        element: usize,
        /// Why.
        #[source]
        source: MaterialParameterError,
    },
    /// An element's density is not finite and positive.
    #[error("density of element {element} must be finite and positive, got {density} kg/m³")]
    Density {
        /// Element.
        element: usize,
        /// Value.
        density: f64,
    },
}

/// A symmetric node-by-node matrix in compressed rows (the mass matrix).
#[derive(Clone, Debug)]
pub(crate) struct NodeMatrix {
    row_start: Vec<usize>,
    columns: Vec<usize>,
    values: Vec<f64>,
}

impl NodeMatrix {
    /// `y_a = Σ_b M_ab x_b` for 3-vectors per node (flat, 3 per node).
    pub(crate) fn apply(&self, x: &[f64]) -> Vec<f64> {
        let mut y = vec![0.0; x.len()];
        y.par_chunks_mut(3).enumerate().for_each(|(a, ya)| {
            for k in self.row_start[a]..self.row_start[a + 1] {
                let (b, m) = (self.columns[k], self.values[k]);
                for i in 0..3 {
                    ya[i] += m * x[3 * b + i];
                }
            }
        });
        y
    }
}

/// A P1 or P2 tetrahedral model with per-element materials.
pub struct FemModel<M: HyperelasticMaterial> {
    mesh: FemMesh,
    material: M,
    lame: Vec<LameParameters>,
    densities: Vec<f64>,
    mass_kind: MassKind,
    /// Per element × quadrature point: weight w = V · ŵ (m³).
    qp_weights: Vec<f64>,
    /// Per element × quadrature point × node: ∇N (1/m).
    qp_gradients: Vec<Vector3<f64>>,
    element_mass: Vec<f64>,
    mass: NodeMatrix,
    /// ∫ ρ N_a dV per node (kg): the consistent gravity load divided by g.
    node_mass: Vec<f64>,
    /// Lumped (HRZ) volume per node (m³), positive: weights of node penalties.
    node_volume: Vec<f64>,
    total_mass: f64,
}

impl<M: HyperelasticMaterial> FemModel<M> {
    /// Precomputes element data and assembles the mass matrix.
    ///
    /// # Errors
    /// [`FemModelError`] for a wrong material count or an invalid material or density.
    pub fn new(
        mesh: FemMesh,
        materials: &[MaterialSample],
        material: M,
        mass_kind: MassKind,
    ) -> Result<Self, FemModelError> {
        let elements = mesh.element_count();
        if materials.len() != elements {
            return Err(FemModelError::MaterialCount {
                materials: materials.len(),
                elements,
            });
        }
        let mut lame = Vec::with_capacity(elements);
        let mut densities = Vec::with_capacity(elements);
        for (element, s) in materials.iter().enumerate() {
            lame.push(
                s.lame_parameters()
                    .map_err(|source| FemModelError::Material { element, source })?,
            );
            if !(s.density > 0.0 && s.density.is_finite()) {
                return Err(FemModelError::Density {
                    element,
                    density: s.density,
                });
            }
            densities.push(s.density);
        }
        let order = mesh.order();
        let npe = order.nodes_per_element();
        let rule = quadrature(order);
        let mut qp_weights = Vec::with_capacity(elements * rule.len());
        let mut qp_gradients = Vec::with_capacity(elements * rule.len() * npe);
        for e in 0..elements {
            let tets = mesh.tet_mesh();
            let volume = tets.tet_volume(e);
            let grad_lambda = barycentric_gradients(&tets.edge_matrix(e))
                .expect("TetMesh guarantees positive volumes");
            for (lambda, w) in &rule {
                qp_weights.push(volume * w);
                qp_gradients.extend(shape_gradients(order, lambda, &grad_lambda));
            }
        }
        let reference = reference_mass_matrix(order);
        let element_mass = match mass_kind {
            MassKind::Consistent => reference.clone(),
            MassKind::Lumped => {
                let diagonal: f64 = (0..npe).map(|a| reference[a * npe + a]).sum();
                (0..npe * npe)
                    .map(|k| {
                        let (a, b) = (k / npe, k % npe);
                        if a == b { reference[k] / diagonal } else { 0.0 }
                    })
                    .collect()
            }
        };
        let node_count = mesh.nodes().len();
        let mut rows: Vec<Vec<(usize, f64)>> = vec![Vec::new(); node_count];
        let mut node_mass = vec![0.0; node_count];
        let mut node_volume = vec![0.0; node_count];
        let diagonal: f64 = (0..npe).map(|a| reference[a * npe + a]).sum();
        for (e, density) in densities.iter().enumerate() {
            let volume = mesh.tet_mesh().tet_volume(e);
            let rho_v = density * volume;
            let nodes = mesh.element(e);
            for a in 0..npe {
                let row_integral: f64 = (0..npe).map(|b| reference[a * npe + b]).sum();
                node_mass[nodes[a]] += rho_v * row_integral;
                node_volume[nodes[a]] += volume * reference[a * npe + a] / diagonal;
                for b in 0..npe {
                    let m = element_mass[a * npe + b];
                    if m != 0.0 {
                        rows[nodes[a]].push((nodes[b], rho_v * m));
                    }
                }
            }
        }
        let mut mass = NodeMatrix {
            row_start: vec![0],
            columns: Vec::new(),
            values: Vec::new(),
        };
        for mut row in rows {
            row.sort_by_key(|(b, _)| *b);
            let mut last = usize::MAX;
            for (b, m) in row {
                if b == last {
                    *mass.values.last_mut().expect("pushed before") += m;
                } else {
                    mass.columns.push(b);
                    mass.values.push(m);
                    last = b;
                }
            }
            mass.row_start.push(mass.columns.len());
        }
        let total_mass = node_mass.iter().sum();
        Ok(FemModel {
            mesh,
            material,
            lame,
            densities,
            mass_kind,
            qp_weights,
            qp_gradients,
            element_mass,
            mass,
            node_mass,
            node_volume,
            total_mass,
        })
    }

    /// The mesh.
    pub fn mesh(&self) -> &FemMesh {
        &self.mesh
    }

    /// The constitutive model.
    pub fn material(&self) -> &M {
        &self.material
    }

    /// Lamé parameters per element.
    pub fn lame_parameters(&self) -> &[LameParameters] {
        &self.lame
    }

    /// Densities per element (kg/m³).
    pub fn densities(&self) -> &[f64] {
        &self.densities
    }

    /// The mass matrix kind.
    pub fn mass_kind(&self) -> MassKind {
        self.mass_kind
    }

    /// Total mass (kg).
    pub fn total_mass(&self) -> f64 {
        self.total_mass
    }

    /// `∫ ρ N_a dV` per node (kg); gravity's nodal load is this times g.
    pub fn node_masses(&self) -> &[f64] {
        &self.node_mass
    }

    /// Positive lumped volume per node (m³), the weight of per-node penalties (floor).
    pub fn node_volumes(&self) -> &[f64] {
        &self.node_volume
    }

    /// `M x` for a flat vector of 3 entries per node.
    pub fn apply_mass(&self, x: &[f64]) -> Vec<f64> {
        self.mass.apply(x)
    }

    /// Largest p-wave modulus λ + 2μ over the elements (Pa).
    pub fn max_p_wave_modulus(&self) -> f64 {
        self.lame
            .iter()
            .map(|l| l.p_wave_modulus())
            .fold(0.0, f64::max)
    }

    fn quadrature_points(&self) -> usize {
        quadrature(self.mesh.order()).len()
    }

    /// Deformation gradient at quadrature point q of element e: `F = Σ_a x_a ∇N_aᵀ`.
    fn deformation_gradient(&self, e: usize, q: usize, x: &[f64]) -> Matrix3<f64> {
        let npe = self.mesh.order().nodes_per_element();
        let nq = self.quadrature_points();
        let grads = &self.qp_gradients[(e * nq + q) * npe..(e * nq + q + 1) * npe];
        let mut f = Matrix3::zeros();
        for (&node, g) in self.mesh.element(e).iter().zip(grads) {
            let xa = Vector3::new(x[3 * node], x[3 * node + 1], x[3 * node + 2]);
            f += xa * g.transpose();
        }
        f
    }

    /// Deformation gradients at every quadrature point, element-major.
    pub fn deformation_gradients(&self, x: &[f64]) -> Vec<Matrix3<f64>> {
        let nq = self.quadrature_points();
        (0..self.mesh.element_count() * nq)
            .into_par_iter()
            .map(|k| self.deformation_gradient(k / nq, k % nq, x))
            .collect()
    }

    /// Elastic energy `Σ_e Σ_q w_q Ψ(F_q)` (J) of node positions x (flat, m).
    pub fn elastic_energy(&self, x: &[f64]) -> f64 {
        let nq = self.quadrature_points();
        // Per-point terms in parallel, summed in index order, so the result does not depend on
        // how rayon split the work.
        let terms: Vec<f64> = (0..self.mesh.element_count() * nq)
            .into_par_iter()
            .map(|k| {
                let e = k / nq;
                let f = self.deformation_gradient(e, k % nq, x);
                self.qp_weights[k] * self.material.energy_density(&self.lame[e], &f)
            })
            .collect();
        terms.iter().sum()
    }

    /// Element e's Hessian (`(3·npe)²`, row-major, N/m, node-major DOFs `3a + i`) at node
    /// positions x (flat, m), with `mass_scale · M_e ⊗ I₃` added (`mass_scale = 1/h²` gives the
    /// backward-Euler system; 0 the elastic tangent alone):
    /// `K_ab[i][j] = Σ_q w_q Σ_kl ∂P_ik/∂F_jl ∇N_a[k] ∇N_b[l]`.
    pub fn element_hessian(
        &self,
        e: usize,
        x: &[f64],
        tangent: Tangent,
        mass_scale: f64,
    ) -> Vec<f64> {
        let npe = self.mesh.order().nodes_per_element();
        let nq = self.quadrature_points();
        let n = 3 * npe;
        let mut hessian = vec![0.0; n * n];
        let lame = &self.lame[e];
        for q in 0..nq {
            let k = e * nq + q;
            let w = self.qp_weights[k];
            let grads = &self.qp_gradients[k * npe..(k + 1) * npe];
            let f = self.deformation_gradient(e, q, x);
            let d: Matrix9 = self.material.tangent_stress_derivative(lame, &f, tangent) * w;
            // Y_b[(3k + i), j] = Σ_l D[(3k + i), (3l + j)] ∇N_b[l]; K_ab[i][j] = Σ_k ∇N_a[k] Y_b.
            for (b, gb) in grads.iter().enumerate() {
                let mut y = [[0.0; 3]; 9];
                for (row, yr) in y.iter_mut().enumerate() {
                    for (j, yj) in yr.iter_mut().enumerate() {
                        *yj = (0..3).map(|l| d[(row, 3 * l + j)] * gb[l]).sum();
                    }
                }
                for (a, ga) in grads.iter().enumerate() {
                    for i in 0..3 {
                        for j in 0..3 {
                            let v: f64 = (0..3).map(|kk| ga[kk] * y[3 * kk + i][j]).sum();
                            hessian[(3 * a + i) * n + 3 * b + j] += v;
                        }
                    }
                }
            }
        }
        if mass_scale != 0.0 {
            let rho_v = self.densities[e] * self.mesh.tet_mesh().tet_volume(e);
            for a in 0..npe {
                for b in 0..npe {
                    let m = mass_scale * rho_v * self.element_mass[a * npe + b];
                    for i in 0..3 {
                        hessian[(3 * a + i) * n + 3 * b + i] += m;
                    }
                }
            }
        }
        hessian
    }

    /// Element e's elastic gradient `g_a = Σ_q w_q P(F_q) ∇N_a` (3·npe entries, node-major:
    /// `[a][i]` at `3a + i`, N) at node positions x (flat, m).
    pub fn element_gradient(&self, e: usize, x: &[f64]) -> Vec<f64> {
        let npe = self.mesh.order().nodes_per_element();
        let nq = self.quadrature_points();
        let mut g = vec![0.0; 3 * npe];
        for q in 0..nq {
            let k = e * nq + q;
            let f = self.deformation_gradient(e, q, x);
            let p = self.material.first_piola_kirchhoff(&self.lame[e], &f);
            for (a, ga) in self.qp_gradients[k * npe..(k + 1) * npe].iter().enumerate() {
                let force = self.qp_weights[k] * p * ga;
                for i in 0..3 {
                    g[3 * a + i] += force[i];
                }
            }
        }
        g
    }

    /// Elastic gradient `∂E_el/∂x` (N, flat) at x.
    pub fn elastic_gradient(&self, x: &[f64]) -> Vec<f64> {
        let per_element: Vec<Vec<f64>> = (0..self.mesh.element_count())
            .into_par_iter()
            .map(|e| self.element_gradient(e, x))
            .collect();
        let mut gradient = vec![0.0; x.len()];
        for (e, g) in per_element.iter().enumerate() {
            for (a, &node) in self.mesh.element(e).iter().enumerate() {
                for i in 0..3 {
                    gradient[3 * node + i] += g[3 * a + i];
                }
            }
        }
        gradient
    }
}
