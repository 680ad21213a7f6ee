//! Total-Lagrangian SPH neighbourhoods and corrected kernel gradients, fixed at rest
//! (Kugelstadt et al. 2021, Eq. 8; design §3.10).

use nalgebra::{Matrix3, Vector3};
use rayon::prelude::*;
use rkpm_core::SpatialIndex;

use crate::sph::cubic_spline::CubicSplineKernel;
use crate::sph::simulator::SphError;

/// The neighbours N(i) of every particle (rest distance below the kernel support, i itself
/// left out) and the corrected gradient weights
///
/// ```text
/// ỹ_ij = V_j L_i ∇W(X_i − X_j),   L_i = A_i⁻ᵀ,   A_i = Σ_j V_j (X_j − X_i) ∇W(X_i − X_j)ᵀ,
/// ```
///
/// so that the deformation gradient F_i = Σ_j (x_j − x_i) ỹ_ijᵀ is exact for every affine
/// motion x = B X + c (F_i = B), at the boundary too. Stored row by row (CSR): the entries of
/// particle i are `offsets[i]..offsets[i + 1]`; `reverse[e]` is the position of i in N(j)
/// for the entry e = (i, j) (neighbourhoods are symmetric), which turns every scatter into a
/// parallel gather.
#[derive(Clone, Debug)]
pub struct CorrectedGradients {
    offsets: Vec<usize>,
    neighbours: Vec<usize>,
    weights: Vec<Vector3<f64>>,
    reverse: Vec<usize>,
    corrections: Vec<Matrix3<f64>>,
}

impl CorrectedGradients {
    /// Neighbourhoods and corrected gradients of particles at rest positions `rest` (m) with
    /// volumes `volumes` (m³) for `kernel`.
    ///
    /// # Errors
    /// [`SphError::IsolatedParticle`] for a particle whose neighbours do not span 3D (A_i
    /// singular: fewer than three neighbours off one plane, e.g. a sheet one particle thick).
    pub fn new(
        rest: &[Vector3<f64>],
        volumes: &[f64],
        kernel: &CubicSplineKernel,
    ) -> Result<Self, SphError> {
        let n = rest.len();
        let index = SpatialIndex::new(rest);
        let h = kernel.support();
        let lists: Vec<Vec<usize>> = rest
            .par_iter()
            .enumerate()
            .map(|(i, x)| {
                let mut list: Vec<usize> = index
                    .within(x, h)
                    .into_iter()
                    .filter(|&(j, d)| j != i && d < h * (1.0 - 1e-12))
                    .map(|(j, _)| j)
                    .collect();
                list.sort_unstable();
                list
            })
            .collect();
        let mut offsets = Vec::with_capacity(n + 1);
        offsets.push(0);
        for list in &lists {
            offsets.push(offsets.last().copied().unwrap_or(0) + list.len());
        }
        let neighbours: Vec<usize> = lists.into_iter().flatten().collect();
        let corrections: Vec<Result<Matrix3<f64>, SphError>> = (0..n)
            .into_par_iter()
            .map(|i| {
                let mut a = Matrix3::zeros();
                for &j in &neighbours[offsets[i]..offsets[i + 1]] {
                    a += volumes[j]
                        * (rest[j] - rest[i])
                        * kernel.gradient(&(rest[i] - rest[j])).transpose();
                }
                let scale = a.norm().max(f64::MIN_POSITIVE);
                match a.try_inverse() {
                    Some(inverse) if a.determinant().abs() > 1e-9 * scale.powi(3) => {
                        Ok(inverse.transpose())
                    }
                    _ => Err(SphError::IsolatedParticle {
                        particle: i,
                        neighbours: offsets[i + 1] - offsets[i],
                    }),
                }
            })
            .collect();
        let corrections = corrections.into_iter().collect::<Result<Vec<_>, _>>()?;
        let weights: Vec<Vector3<f64>> = (0..n)
            .into_par_iter()
            .flat_map_iter(|i| {
                let (l, x) = (&corrections[i], rest[i]);
                neighbours[offsets[i]..offsets[i + 1]]
                    .iter()
                    .map(move |&j| volumes[j] * (l * kernel.gradient(&(x - rest[j]))))
            })
            .collect();
        let reverse: Vec<usize> = (0..n)
            .into_par_iter()
            .flat_map_iter(|i| {
                let (neighbours, offsets) = (&neighbours, &offsets);
                neighbours[offsets[i]..offsets[i + 1]]
                    .iter()
                    .map(move |&j| {
                        let row = &neighbours[offsets[j]..offsets[j + 1]];
                        offsets[j] + row.binary_search(&i).expect("symmetric neighbourhoods")
                    })
            })
            .collect();
        Ok(CorrectedGradients {
            offsets,
            neighbours,
            weights,
            reverse,
            corrections,
        })
    }

    /// Number of particles.
    pub fn len(&self) -> usize {
        self.offsets.len() - 1
    }

    /// Whether there are no particles.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The entries `offsets[i]..offsets[i + 1]` of particle i.
    pub fn entries(&self, i: usize) -> std::ops::Range<usize> {
        self.offsets[i]..self.offsets[i + 1]
    }

    /// Neighbour j of entry e.
    pub fn neighbour(&self, e: usize) -> usize {
        self.neighbours[e]
    }

    /// The neighbours of particle i, ascending.
    pub fn neighbours(&self, i: usize) -> &[usize] {
        &self.neighbours[self.entries(i)]
    }

    /// ỹ_ij of entry e = (i, j), the weight of x_j − x_i in F_i (1/m).
    pub fn weight(&self, e: usize) -> &Vector3<f64> {
        &self.weights[e]
    }

    /// The weights ỹ_ij of particle i, in the order of [`CorrectedGradients::neighbours`].
    pub fn weights(&self, i: usize) -> &[Vector3<f64>] {
        &self.weights[self.entries(i)]
    }

    /// The entry (j, i) of entry e = (i, j).
    pub fn reverse(&self, e: usize) -> usize {
        self.reverse[e]
    }

    /// The correction matrix L_i.
    pub fn correction(&self, i: usize) -> &Matrix3<f64> {
        &self.corrections[i]
    }

    /// Total number of (i, j) entries.
    pub fn entry_count(&self) -> usize {
        self.neighbours.len()
    }

    /// The gradient Σ_j (u_j − u_i) ỹ_ijᵀ of the particle field `u` at particle i: the
    /// deformation gradient F_i for u = positions, the velocity gradient for velocities.
    pub fn field_gradient(&self, i: usize, u: &[Vector3<f64>]) -> Matrix3<f64> {
        let mut g = Matrix3::zeros();
        for e in self.entries(i) {
            g += (u[self.neighbours[e]] - u[i]) * self.weights[e].transpose();
        }
        g
    }

    /// [`CorrectedGradients::field_gradient`] at every particle.
    pub fn field_gradients(&self, u: &[Vector3<f64>]) -> Vec<Matrix3<f64>> {
        (0..self.len())
            .into_par_iter()
            .map(|i| self.field_gradient(i, u))
            .collect()
    }

    /// The gradient of Σ_i P_i : F_i with respect to every x_k, for per-particle 3 × 3
    /// "stresses" `p` (P_i = V_i ∂Ψ/∂F_i gives the elastic force's negative):
    ///
    /// ```text
    /// g_k = Σ_{i ∈ N(k)} P_i ỹ_ik − P_k Σ_j ỹ_kj,
    /// ```
    ///
    /// computed as a gather (parallel, deterministic).
    pub fn stress_divergence(&self, p: &[Matrix3<f64>]) -> Vec<Vector3<f64>> {
        (0..self.len())
            .into_par_iter()
            .map(|k| {
                let mut g = Vector3::zeros();
                let mut own = Vector3::zeros();
                for e in self.entries(k) {
                    let i = self.neighbours[e];
                    g += p[i] * self.weights[self.reverse[e]];
                    own += self.weights[e];
                }
                g - p[k] * own
            })
            .collect()
    }

    /// The gradient of Σ_(i,j) w_ijᵀ (x_j − x_i) with respect to every x_k, for one vector
    /// `w` per entry: g_k = Σ_{i ∈ N(k)} w_ik − Σ_j w_kj.
    pub fn pair_divergence(&self, w: &[Vector3<f64>]) -> Vec<Vector3<f64>> {
        (0..self.len())
            .into_par_iter()
            .map(|k| {
                let mut g = Vector3::zeros();
                for e in self.entries(k) {
                    g += w[self.reverse[e]] - w[e];
                }
                g
            })
            .collect()
    }
}
