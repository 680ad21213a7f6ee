//! One term of a step's incremental potential, and the point where it is evaluated.

use std::cell::OnceCell;

use faer::Mat;
use hyperelastic::Tangent;
use nalgebra::Vector3;

use crate::model::deformation_map::DeformationMap;

/// Where a [`StepTerm`] is evaluated: one body's reduced coordinates z (length 12(m + 1), the
/// [`crate::ReducedLayout`]) at time t, with the map `x_i(z) = X_i + B_iᵀ z` of its integration
/// points and their volumes.
pub struct TermPoint<'a> {
    /// The integration points' map: rest positions X_i (m) and rows B_i (`4(m+1)`, one per
    /// point, [`DeformationMap::position_row`]).
    pub map: &'a DeformationMap,
    /// The integration points' volumes v_i (m³), one per point of `map`.
    pub volumes: &'a [f64],
    /// The reduced coordinates z.
    pub z: &'a [f64],
    /// The time (s) the term is evaluated at: the end of the step, `t + h`.
    pub time: f64,
    positions: OnceCell<Vec<Vector3<f64>>>,
}

impl<'a> TermPoint<'a> {
    /// The point z at `time` (s) on `map`'s points with volumes `volumes` (m³).
    pub fn new(map: &'a DeformationMap, volumes: &'a [f64], z: &'a [f64], time: f64) -> Self {
        TermPoint {
            map,
            volumes,
            z,
            time,
            positions: OnceCell::new(),
        }
    }

    /// The same map, volumes and time at another z.
    pub fn at(&self, z: &'a [f64]) -> Self {
        TermPoint::new(self.map, self.volumes, z, self.time)
    }

    /// The deformed positions `x_i(z)` (m) of every integration point, computed once and
    /// shared by the terms that ask.
    pub fn positions(&self) -> &[Vector3<f64>] {
        self.positions.get_or_init(|| self.map.positions(self.z))
    }
}

/// One term `E_k(z, t)` of the incremental potential (Eq. 2 with backward Euler, design §3.7):
/// gravity, the pin penalty, the floor, the colliders, friction, or a user's own (a spring, a
/// muscle, a magnetic force). The simulator sums its terms with inertia and elasticity; a term
/// is added with [`crate::Simulator::add_term`] and checked with [`crate::check_term`].
///
/// Energies in J, gradients `∂E/∂z` of length 12(m + 1) in J, Hessians `∂²E/∂z²` dense
/// 12(m+1) square in J. z is ordered `[z_x, z_y, z_z]`, each `4(m+1)` long, so the position of
/// point i along axis r is `X_i[r] + B_i · z[r·4(m+1)..(r+1)·4(m+1)]`.
///
/// Every method adds to what it is given (a running sum), so terms compose in any number.
pub trait StepTerm: Send + Sync {
    /// A short name for reports and errors ("gravity", "spring to target").
    fn name(&self) -> &str;

    /// Adds `E_k(z, t)` (J, up to a constant) to `energy`. Non-finite where the term is
    /// infinite (a barrier at contact).
    fn add_energy(&self, at: &TermPoint<'_>, energy: &mut f64);

    /// Adds `∂E_k/∂z` to `gradient` and, when given, `∂²E_k/∂z²` to `hessian`. For tangents
    /// other than [`Tangent::Exact`] a term may leave out an indefinite part of its Hessian
    /// (Newton needs a positive definite sum); with [`Tangent::Exact`] it must be the exact
    /// Hessian.
    fn add_derivatives(
        &self,
        at: &TermPoint<'_>,
        tangent: Tangent,
        gradient: &mut [f64],
        hessian: Option<&mut Mat<f64>>,
    );

    /// The largest fraction α ∈ [0, 1] of `step` that the line search may take from z
    /// (a barrier keeps iterates out of contact this way); 1 by default.
    fn max_step(&self, at: &TermPoint<'_>, step: &[f64]) -> f64 {
        let _ = (at, step);
        1.0
    }

    /// `E_k(z, t)` alone (J).
    fn energy(&self, at: &TermPoint<'_>) -> f64 {
        let mut energy = 0.0;
        self.add_energy(at, &mut energy);
        energy
    }
}
