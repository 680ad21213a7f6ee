//! Displacements of the SPH particles carried to other points (the FEM vertices the metrics
//! are taken at) by a linearly consistent moving-least-squares interpolant at rest.

use nalgebra::{Matrix4, Vector3, Vector4};
use rayon::prelude::*;
use rkpm_core::SpatialIndex;

use crate::sph::cubic_spline::CubicSplineKernel;
use crate::sph::simulator::SphError;

/// Support radii tried, as multiples of the kernel support, when a point has too few
/// particles around it for a linear fit.
const SUPPORT_FACTORS: [f64; 3] = [1.0, 1.5, 2.0];

/// For each query point X_q, weights φ_qj over the particles within the kernel support such
/// that the displacement there is u(X_q) = Σ_j φ_qj u_j, with
///
/// ```text
/// φ_qj = V_j W(X_j − X_q) p(X_j − X_q)ᵀ M_q⁻¹ e₁,   p(d) = (1, d/h),
/// M_q = Σ_j V_j W(X_j − X_q) p(X_j − X_q) p(X_j − X_q)ᵀ,
/// ```
///
/// which reproduces every affine displacement field exactly (on the surface too, where a
/// plain SPH sum would be short of neighbours).
#[derive(Clone, Debug)]
pub struct ParticleInterpolation {
    rest: Vec<Vector3<f64>>,
    weights: Vec<Vec<(usize, f64)>>,
}

impl ParticleInterpolation {
    /// Weights at `queries` (rest positions, m) from particles at `particles` (rest, m) with
    /// `volumes` (m³) and `kernel`.
    ///
    /// # Errors
    /// [`SphError::ProbeOutside`] for a query with too few particles around it for a linear
    /// fit even at twice the kernel support (it lies outside the body), or a non-finite query.
    pub fn new(
        particles: &[Vector3<f64>],
        volumes: &[f64],
        kernel: &CubicSplineKernel,
        queries: &[Vector3<f64>],
    ) -> Result<Self, SphError> {
        let index = SpatialIndex::new(particles);
        let weights: Vec<Result<Vec<(usize, f64)>, SphError>> = queries
            .par_iter()
            .enumerate()
            .map(|(q, x)| {
                if !x.iter().all(|c| c.is_finite()) {
                    return Err(SphError::ProbeOutside { probe: q });
                }
                SUPPORT_FACTORS
                    .iter()
                    .find_map(|factor| {
                        let kernel = CubicSplineKernel::new(factor * kernel.support());
                        linear_fit(&index, particles, volumes, &kernel, x)
                    })
                    .ok_or(SphError::ProbeOutside { probe: q })
            })
            .collect();
        Ok(ParticleInterpolation {
            rest: queries.to_vec(),
            weights: weights.into_iter().collect::<Result<_, _>>()?,
        })
    }

    /// The queries' positions X_q + Σ_j φ_qj (x_j − X_j) for particle positions `positions`
    /// and rest positions `rest` (m).
    pub fn positions(
        &self,
        rest: &[Vector3<f64>],
        positions: &[Vector3<f64>],
    ) -> Vec<Vector3<f64>> {
        self.weights
            .par_iter()
            .zip(&self.rest)
            .map(|(w, x)| {
                x + w
                    .iter()
                    .map(|&(j, phi)| phi * (positions[j] - rest[j]))
                    .sum::<Vector3<f64>>()
            })
            .collect()
    }

    /// Number of query points.
    pub fn len(&self) -> usize {
        self.rest.len()
    }

    /// Whether there are no query points.
    pub fn is_empty(&self) -> bool {
        self.rest.is_empty()
    }
}

/// The linear MLS weights at `x`, or `None` when the moment matrix is (nearly) singular.
fn linear_fit(
    index: &SpatialIndex,
    particles: &[Vector3<f64>],
    volumes: &[f64],
    kernel: &CubicSplineKernel,
    x: &Vector3<f64>,
) -> Option<Vec<(usize, f64)>> {
    let h = kernel.support();
    let mut near: Vec<(usize, f64, Vector4<f64>)> = index
        .within(x, h)
        .into_iter()
        .filter_map(|(j, _)| {
            let d = particles[j] - x;
            let w = volumes[j] * kernel.value(&d);
            (w > 0.0).then(|| (j, w, Vector4::new(1.0, d.x / h, d.y / h, d.z / h)))
        })
        .collect();
    near.sort_unstable_by_key(|&(j, _, _)| j);
    let moment: Matrix4<f64> = near.iter().map(|(_, w, p)| *w * p * p.transpose()).sum();
    let scale = moment.norm();
    if near.len() < 4 || !(scale > 0.0) {
        return None;
    }
    let eigen = moment.symmetric_eigenvalues();
    if eigen.min() < 1e-8 * eigen.max() {
        return None;
    }
    let inverse = moment.try_inverse()?;
    let c = inverse.column(0).into_owned();
    Some(
        near.into_iter()
            .map(|(j, w, p)| (j, w * p.dot(&c)))
            .collect(),
    )
}
