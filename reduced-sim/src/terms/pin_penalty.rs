//! The penalty that holds pinned regions at their targets.

use std::sync::{Arc, Mutex};

use faer::{Accum, Mat, MatRef, Par};
use hyperelastic::Tangent;
use nalgebra::Vector3;

use crate::model::reduced_model::add_block_diagonal_product;
use crate::terms::pinned_points::PinnedPoints;
use crate::terms::step_term::{StepTerm, TermPoint};

/// `E_pin(z, t) = κ/2 Σ_pinned v_i |x_i(z) − t_i(t)|²` (J; design §3.7) over every penalized
/// region: quadratic in z with the constant Hessian block `H = κ Σ v_i B_i B_iᵀ` (`4(m+1)`
/// square, on each axis) and gradient `H z_r + c_r(t)`.
pub(crate) struct PinPenalty {
    regions: Vec<PinnedPoints>,
    /// κ_pin (Pa/m²).
    stiffness: f64,
    /// `H = κ Σ_pinned v_i b_i b_iᵀ`.
    hessian_block: Mat<f64>,
    /// The targets and `c(t)` of the last time asked (a step asks at one time many times).
    last: Mutex<Option<Arc<PinTargets>>>,
}

/// Every region's targets at one time, and the gradient at z = 0 they give.
struct PinTargets {
    time: f64,
    targets: Vec<Vec<Vector3<f64>>>,
    /// `c_r = κ Σ_i v_i B_i (X_i − t_i)_r` (`3 · 4(m+1)`).
    gradient_at_zero: Vec<f64>,
}

impl PinPenalty {
    /// The penalty of stiffness κ (Pa/m²) on `regions` (none empty), with rows of `4(m+1)`.
    pub(crate) fn new(regions: Vec<PinnedPoints>, stiffness: f64, block_len: usize) -> Self {
        let n4 = block_len;
        let mut hessian_block = Mat::zeros(n4, n4);
        for region in &regions {
            let scaled: Vec<f64> = region
                .b
                .chunks_exact(n4)
                .zip(&region.volumes)
                .flat_map(|(bi, v)| bi.iter().map(move |x| x * v * stiffness))
                .collect();
            let p = region.rest.len();
            faer::linalg::matmul::matmul(
                hessian_block.as_mut(),
                Accum::Add,
                MatRef::from_column_major_slice(&scaled, n4, p),
                MatRef::from_column_major_slice(&region.b, n4, p).transpose(),
                1.0,
                Par::rayon(0),
            );
        }
        crate::model::reduced_model::symmetrize(&mut hessian_block);
        PinPenalty {
            regions,
            stiffness,
            hessian_block,
            last: Mutex::new(None),
        }
    }

    /// The largest distance (m) of a penalized point from its target at `at`.
    pub(crate) fn max_deviation(&self, at: &TermPoint<'_>) -> f64 {
        self.regions
            .iter()
            .map(|r| r.max_deviation(at.map, at.z, at.time))
            .fold(0.0, f64::max)
    }

    /// The targets at `time` (s), computed once per time.
    fn targets(&self, time: f64) -> Arc<PinTargets> {
        let mut last = self.last.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(known) = last.as_ref()
            && known.time == time
        {
            return Arc::clone(known);
        }
        let targets: Vec<Vec<Vector3<f64>>> =
            self.regions.iter().map(|r| r.targets(time)).collect();
        let n4 = self.hessian_block.nrows();
        let mut gradient_at_zero = vec![0.0; 3 * n4];
        for (region, targets) in self.regions.iter().zip(&targets) {
            let p = region.rest.len();
            // c = B_pin · D, D[i, r] = κ v_i (X_i − t_i)_r (`P × 3`), c column-major `n4 × 3`.
            let mut d = vec![0.0; 3 * p];
            for (i, (x, t)) in region.rest.iter().zip(targets).enumerate() {
                let w = self.stiffness * region.volumes[i];
                for r in 0..3 {
                    d[r * p + i] = w * (x[r] - t[r]);
                }
            }
            faer::linalg::matmul::matmul(
                faer::MatMut::from_column_major_slice_mut(&mut gradient_at_zero, n4, 3),
                Accum::Add,
                MatRef::from_column_major_slice(&region.b, n4, p),
                MatRef::from_column_major_slice(&d, p, 3),
                1.0,
                Par::Seq,
            );
        }
        let known = Arc::new(PinTargets {
            time,
            targets,
            gradient_at_zero,
        });
        *last = Some(Arc::clone(&known));
        known
    }
}

impl StepTerm for PinPenalty {
    fn name(&self) -> &str {
        "pin penalty"
    }

    fn add_energy(&self, at: &TermPoint<'_>, energy: &mut f64) {
        let known = self.targets(at.time);
        for (region, targets) in self.regions.iter().zip(&known.targets) {
            let x = region.positions(at.map, at.z);
            for ((x, t), v) in x.iter().zip(targets).zip(&region.volumes) {
                *energy += 0.5 * self.stiffness * v * (x - t).norm_squared();
            }
        }
    }

    fn add_derivatives(
        &self,
        at: &TermPoint<'_>,
        _tangent: Tangent,
        gradient: &mut [f64],
        hessian: Option<&mut Mat<f64>>,
    ) {
        // ∂E/∂z_r = κ Σ v_i b_i (x_i − t_i)_r = H z_r + c_r, x_i = X_i + b_iᵀ z_r.
        let known = self.targets(at.time);
        for (gk, ck) in gradient.iter_mut().zip(&known.gradient_at_zero) {
            *gk += ck;
        }
        add_block_diagonal_product(gradient, &self.hessian_block, at.z, 1.0);
        if let Some(hessian) = hessian {
            let n4 = self.hessian_block.nrows();
            for r in 0..3 {
                for b in 0..n4 {
                    for a in 0..n4 {
                        hessian[(r * n4 + a, r * n4 + b)] += self.hessian_block[(a, b)];
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::analytic_field::{analytic_model, probe_z};
    use crate::scene::{PinTarget, PinnedRegion};
    use crate::terms::scene_terms::term_point;
    use crate::terms::term_check::{TermCheckParams, check_term};

    #[test]
    fn the_pin_penalty_passes_the_term_check_and_is_half_k_v_d_squared() {
        let (model, _) = analytic_model();
        let map = model.deformation_map();
        let regions = [
            PinnedRegion {
                points: model.points_where(|x| x.x < 0.3),
                target: PinTarget::Rest,
            },
            PinnedRegion {
                points: model.points_where(|x| x.x > 1.7),
                target: PinTarget::Moving(Arc::new(|x, t| x + Vector3::new(0.0, 0.1 * t, 0.0))),
            },
        ];
        let stiffness = 2e5;
        let term = PinPenalty::new(
            regions
                .iter()
                .map(|r| PinnedPoints::new(map, model.volumes(), r))
                .collect(),
            stiffness,
            map.layout().block_len(),
        );
        let z = probe_z(map.layout().len(), 0.02);
        for time in [0.0, 0.7] {
            let at = term_point(&model, &z, time);
            check_term(&term, &at, &TermCheckParams::default()).unwrap();
            let expected: f64 = regions
                .iter()
                .flat_map(|r| r.points.iter().map(move |&i| (i, &r.target)))
                .map(|(i, target)| {
                    let d = map.position(i, &z) - target.at(&map.rest_positions()[i], time);
                    0.5 * stiffness * model.volumes()[i] * d.norm_squared()
                })
                .sum();
            let energy = term.energy(&at);
            assert!(
                (energy - expected).abs() < 1e-10 * expected,
                "{energy} vs {expected}"
            );
        }
    }
}
