//! The joint incremental potential of a contact-connected group of objects.

use std::ops::Range;

use faer::linalg::solvers::{Llt, Solve};
use faer::{Mat, Side};
use hyperelastic::HyperelasticMaterial;
use nalgebra::{Matrix3, Vector3};
use optimize::NewtonObjective;
use rayon::prelude::*;

use crate::contact::body_contact::{
    BodyContactModel, BodyContactParams, LaggedPair, PairFriction, RelativeDerivatives, SamplePair,
    add_cross_hessians, lagged_friction, repulsion_derivatives,
};
use crate::model::deformation_map::DeformationMap;
use crate::step::hessian_tangent::{HessianTangent, StepTangents};
use crate::step::incremental_potential::IncrementalPotential;

/// The pair ends on one object: sample, x-gradient and x-Hessian of each.
#[derive(Default)]
pub(super) struct PairEnds {
    points: Vec<usize>,
    forces: Vec<Vector3<f64>>,
    stiffnesses: Vec<Matrix3<f64>>,
}

/// The joint incremental potential of a contact-connected group (module docs).
pub(super) struct GroupPotential<'a, M: HyperelasticMaterial> {
    pub(super) potentials: Vec<IncrementalPotential<'a, M>>,
    /// With objects holding regions exactly: the entries of the joint z Newton solves for
    /// (ascending); `None` when all are free.
    pub(super) free: Option<Vec<usize>>,
    /// Start of each object's coordinates in the joint z, then its length.
    pub(super) offsets: Vec<usize>,
    /// Each object's deformation map at its samples that take part.
    pub(super) samples: Vec<DeformationMap>,
    /// Candidate pairs, as (slot, sample in `samples[slot]`), with κ of each (Pa/m²).
    pub(super) candidates: Vec<(SamplePair, f64)>,
    /// The contact pairs of this solve with their lagged normals ([`GroupPotential::lag`]).
    pub(super) pairs: Vec<LaggedPair>,
    /// Each object's samples that take part, where they were at the step's start (m).
    pub(super) start: Vec<Vec<Vector3<f64>>>,
    pub(super) contact: BodyContactParams,
    pub(super) friction: Vec<PairFriction>,
    /// ε = ε_v h (m).
    pub(super) epsilon: f64,
}

impl<M: HyperelasticMaterial> StepTangents for GroupPotential<'_, M> {
    fn tangents(&self) -> Vec<HessianTangent> {
        self.potentials.iter().map(|p| p.tangent).collect()
    }

    fn set_tangents(&mut self, tangents: &[HessianTangent]) {
        for (potential, &tangent) in self.potentials.iter_mut().zip(tangents) {
            potential.tangent = tangent;
        }
    }
}

impl<M: HyperelasticMaterial> GroupPotential<'_, M> {
    pub(super) fn range(&self, slot: usize) -> Range<usize> {
        self.offsets[slot]..self.offsets[slot + 1]
    }

    /// Every object's sample positions at the joint z.
    pub(super) fn positions(&self, z: &[f64]) -> Vec<Vec<Vector3<f64>>> {
        (0..self.samples.len())
            .map(|s| self.samples[s].positions(&z[self.range(s)]))
            .collect()
    }

    pub(super) fn relative(positions: &[Vec<Vector3<f64>>], pair: &SamplePair) -> Vector3<f64> {
        positions[pair.a.0][pair.a.1] - positions[pair.b.0][pair.b.1]
    }

    /// The contact pairs lagged at z: every candidate, with the normal `p/‖p‖` there (pairs
    /// at one point, with no normal, are left out).
    pub(super) fn lag(&self, z: &[f64]) -> Vec<LaggedPair> {
        let positions = self.positions(z);
        self.candidates
            .iter()
            .filter_map(|&(pair, stiffness)| {
                let p = Self::relative(&positions, &pair);
                let d = p.norm();
                (d > 0.0).then(|| LaggedPair {
                    pair,
                    normal: p / d,
                    stiffness,
                })
            })
            .collect()
    }

    /// The friction of the pairs touching at z, slips measured from the step's start.
    pub(super) fn lagged_friction(&self, z: &[f64]) -> Vec<PairFriction> {
        lagged_friction(&self.contact, &self.pairs, &self.positions(z), &self.start)
    }

    /// Every pair's (and friction's) derivatives in its relative position, with the pair.
    pub(super) fn pair_derivatives(&self, z: &[f64]) -> Vec<(SamplePair, RelativeDerivatives)> {
        let positions = self.positions(z);
        let mut out = Vec::new();
        for lagged in &self.pairs {
            let p = Self::relative(&positions, &lagged.pair);
            if let Some(d) =
                repulsion_derivatives(&self.contact, lagged.stiffness, &lagged.normal, &p)
                && d.gradient != Vector3::zeros()
            {
                out.push((lagged.pair, d));
            }
        }
        for f in &self.friction {
            let p = Self::relative(&positions, &f.pair);
            out.push((f.pair, f.derivatives(&p, self.epsilon)));
        }
        out
    }

    /// Adds the pair terms' gradient (and Hessian) to the joint ones.
    fn add_pair_derivatives(
        &self,
        z: &[f64],
        gradient: &mut [f64],
        hessian: Option<&mut Mat<f64>>,
    ) {
        let terms = self.pair_derivatives(z);
        let slots = self.samples.len();
        // Per object: the sample, force and stiffness of each end of each pair.
        let mut ends: Vec<PairEnds> = (0..slots).map(|_| PairEnds::default()).collect();
        for (pair, d) in &terms {
            for (end, sign) in [(pair.a, 1.0), (pair.b, -1.0)] {
                ends[end.0].points.push(end.1);
                ends[end.0].forces.push(d.gradient * sign);
                ends[end.0].stiffnesses.push(d.hessian);
            }
        }
        for (s, end) in ends.iter().enumerate() {
            let range = self.range(s);
            self.samples[s].add_point_gradients(&end.points, &end.forces, &mut gradient[range]);
        }
        let Some(hessian) = hessian else {
            return;
        };
        for (s, end) in ends.iter().enumerate() {
            if end.points.is_empty() {
                continue;
            }
            let n = self.range(s).len();
            let mut block = Mat::zeros(n, n);
            self.samples[s].add_point_hessians(&end.points, &end.stiffnesses, &mut block);
            let o = self.offsets[s];
            for j in 0..n {
                for i in 0..n {
                    hessian[(o + i, o + j)] += block[(i, j)];
                }
            }
        }
        for sa in 0..slots {
            for sb in sa + 1..slots {
                let between: Vec<&(SamplePair, RelativeDerivatives)> = terms
                    .iter()
                    .filter(|(p, _)| p.a.0 == sa && p.b.0 == sb)
                    .collect();
                if between.is_empty() {
                    continue;
                }
                let points_a: Vec<usize> = between.iter().map(|(p, _)| p.a.1).collect();
                let points_b: Vec<usize> = between.iter().map(|(p, _)| p.b.1).collect();
                let stiffnesses: Vec<Matrix3<f64>> =
                    between.iter().map(|(_, d)| d.hessian).collect();
                let (ra, rb) = (self.range(sa), self.range(sb));
                add_cross_hessians(
                    &self.samples[sa],
                    &points_a,
                    &self.samples[sb],
                    &points_b,
                    &stiffnesses,
                    hessian
                        .as_mut()
                        .submatrix_mut(ra.start, rb.start, ra.len(), rb.len()),
                );
                for j in rb.clone() {
                    for i in ra.clone() {
                        hessian[(j, i)] = hessian[(i, j)];
                    }
                }
            }
        }
    }
}

impl<M: HyperelasticMaterial> NewtonObjective for GroupPotential<'_, M> {
    type Hessian = Mat<f64>;
    type Factor = Llt<f64>;

    fn energy(&self, z: &[f64]) -> f64 {
        // The objects' own terms side by side (summed in order: the same bits on any thread).
        let own: Vec<f64> = (0..self.potentials.len())
            .into_par_iter()
            .map(|s| self.potentials[s].energy(&z[self.range(s)]))
            .collect();
        let mut e: f64 = own.iter().sum();
        let positions = self.positions(z);
        let v = self.contact.sample_volume();
        for lagged in &self.pairs {
            let p = Self::relative(&positions, &lagged.pair);
            match self.contact.profile(lagged.normal.dot(&p)) {
                Some((psi, _, _)) => e += lagged.stiffness * v * psi,
                None => return f64::INFINITY,
            }
        }
        for f in &self.friction {
            e += f.energy(&Self::relative(&positions, &f.pair), self.epsilon);
        }
        e
    }

    fn gradient(&self, z: &[f64]) -> Vec<f64> {
        let own: Vec<Vec<f64>> = (0..self.potentials.len())
            .into_par_iter()
            .map(|s| self.potentials[s].gradient(&z[self.range(s)]))
            .collect();
        let mut gradient = own.concat();
        self.add_pair_derivatives(z, &mut gradient, None);
        match &self.free {
            None => gradient,
            Some(free) => free.iter().map(|&i| gradient[i]).collect(),
        }
    }

    fn gradient_and_hessian(&self, z: &[f64], _gradient: Option<Vec<f64>>) -> (Vec<f64>, Mat<f64>) {
        let n = z.len();
        let mut gradient = Vec::with_capacity(n);
        let mut hessian = Mat::zeros(n, n);
        let own: Vec<(Vec<f64>, Mat<f64>)> = (0..self.potentials.len())
            .into_par_iter()
            .map(|s| self.potentials[s].derivatives(&z[self.range(s)]))
            .collect();
        for (s, (g, h)) in own.into_iter().enumerate() {
            gradient.extend(g);
            let o = self.offsets[s];
            for j in 0..h.ncols() {
                for i in 0..h.nrows() {
                    hessian[(o + i, o + j)] = h[(i, j)];
                }
            }
        }
        self.add_pair_derivatives(z, &mut gradient, Some(&mut hessian));
        match &self.free {
            None => (gradient, hessian),
            Some(free) => (
                free.iter().map(|&i| gradient[i]).collect(),
                Mat::from_fn(free.len(), free.len(), |a, b| hessian[(free[a], free[b])]),
            ),
        }
    }

    fn factor(&self, hessian: Mat<f64>) -> Option<Llt<f64>> {
        hessian.llt(Side::Lower).ok()
    }

    fn solve(&self, factor: &Llt<f64>, gradient: &[f64]) -> Vec<f64> {
        let mut step = Mat::<f64>::from_fn(gradient.len(), 1, |i, _| -gradient[i]);
        factor.solve_in_place(step.as_mut());
        match &self.free {
            None => (0..gradient.len()).map(|i| step[(i, 0)]).collect(),
            Some(free) => {
                let mut full = vec![0.0; *self.offsets.last().expect("offsets")];
                for (a, &i) in free.iter().enumerate() {
                    full[i] = step[(a, 0)];
                }
                full
            }
        }
    }

    fn directional_derivative(&self, gradient: &[f64], step: &[f64]) -> f64 {
        match &self.free {
            None => gradient.iter().zip(step).map(|(g, s)| g * s).sum(),
            Some(free) => free.iter().zip(gradient).map(|(&i, g)| g * step[i]).sum(),
        }
    }

    /// The largest of the objects' step norms.
    fn step_norm(&self, dz: &[f64]) -> f64 {
        (0..self.potentials.len())
            .map(|s| self.potentials[s].step_norm(&dz[self.range(s)]))
            .fold(0.0, f64::max)
    }

    /// The largest α ≤ 1 within every object's own limit (a mesh collider's band) such that
    /// no contact pair's gap `d = n·p` shrinks by more than d̂/2
    /// past d̂ along the step, so no sample passes through the other's contact plane in one
    /// iteration without the line search seeing its energy; with the barrier also such that no
    /// gap shrinks below a tenth of its present value (d is linear in z along the step).
    fn max_step(&self, z: &[f64], step: &[f64]) -> f64 {
        let positions = self.positions(z);
        let moves: Vec<Vec<Vector3<f64>>> = (0..self.samples.len())
            .map(|s| self.samples[s].displacements(&step[self.range(s)]))
            .collect();
        let d_hat = self.contact.radius;
        let barrier = self.contact.model == BodyContactModel::Barrier;
        // Each object's own limit (a mesh collider's band).
        let mut alpha: f64 = (0..self.potentials.len())
            .into_par_iter()
            .map(|s| {
                let range = self.range(s);
                self.potentials[s].max_step(&z[range.clone()], &step[range])
            })
            .reduce(|| 1.0, f64::min);
        for lagged in &self.pairs {
            let gap = lagged.normal.dot(&Self::relative(&positions, &lagged.pair));
            let closing = -lagged.normal.dot(&Self::relative(&moves, &lagged.pair));
            if closing <= 0.0 || gap - closing >= d_hat {
                continue;
            }
            let enter = ((gap - d_hat) / closing).max(0.0);
            alpha = alpha.min(enter + 0.5 * d_hat / closing);
            if barrier && gap > 0.0 {
                alpha = alpha.min(0.9 * gap / closing);
            }
        }
        alpha
    }
}
