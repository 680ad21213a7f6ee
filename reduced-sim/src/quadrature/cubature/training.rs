//! Training poses drawn from the basis alone.

use hyperelastic::HyperelasticMaterial;
use nalgebra::{Matrix3, Rotation3, Unit, Vector3};
use rand::seq::index::sample;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

use crate::model::deformation_map::DeformationMap;
use crate::model::reduced_model::ReducedModel;

use super::{CubatureError, CubatureParams, check_pose_ranges};

/// Training poses z (length 12(m+1) each) from the basis alone, seeded by `params.seed`:
/// `poses_per_amplitude` random handle poses for each amplitude, then `field_poses` twists and
/// bends, as described in the module docs and [`CubatureParams`].
///
/// # Errors
/// [`CubatureError::Params`] for an amplitude that is not finite and positive.
pub fn training_poses<M: HyperelasticMaterial>(
    model: &ReducedModel<M>,
    params: &CubatureParams,
) -> Result<Vec<Vec<f64>>, CubatureError> {
    let amplitudes = params.amplitudes();
    let (poses_per_amplitude, max_rotation, seed) =
        (params.poses_per_amplitude, params.max_rotation, params.seed);
    check_pose_ranges(params, &amplitudes)?;
    let map = model.deformation_map();
    let layout = map.layout();
    let n4 = layout.block_len();
    // Strain is measured on a subset of points (cheap and plenty for an RMS).
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let probe = map.subset(&sample(&mut rng, map.len(), map.len().min(200)).into_vec());
    // RMS of each handle's weight, so every handle's transform moves points comparably.
    let weight_scale: Vec<f64> = (0..layout.handles())
        .map(|j| {
            let sum: f64 = (0..probe.len())
                .map(|i| probe.position_row(i)[4 * j + 3].powi(2))
                .sum();
            (sum / probe.len() as f64).sqrt().max(1e-12)
        })
        .collect();
    let extent = model.bounds().largest_side();
    let mut poses = Vec::with_capacity(amplitudes.len() * poses_per_amplitude);
    for amplitude in amplitudes {
        for _ in 0..poses_per_amplitude {
            let mut direction = vec![0.0; layout.len()];
            for (j, scale) in weight_scale.iter().enumerate().skip(1) {
                let axis = random_unit(&mut rng);
                let angle = rng.random_range(-max_rotation..=max_rotation);
                let stretch = Matrix3::from_fn(|_, _| 0.3 * normal(&mut rng));
                let a = Rotation3::from_axis_angle(&axis, angle).matrix()
                    * (Matrix3::identity() + stretch)
                    - Matrix3::identity();
                for r in 0..3 {
                    for c in 0..3 {
                        direction[layout.index(j, r, c)] = a[(r, c)] / scale;
                    }
                    direction[layout.index(j, r, 3)] = 0.3 * extent * normal(&mut rng) / scale;
                }
            }
            let t = scale_to_strain(&probe, &direction, amplitude);
            poses.push(direction.iter().map(|d| d * t).collect());
        }
    }
    let center = model.bounds().center();
    let mut fields = Vec::with_capacity(params.field_poses);
    for k in 0..params.field_poses {
        let axis = random_unit(&mut rng);
        let twist = k % 2 == 0;
        // A bend turns slabs across `axis` about a perpendicular axis; a twist about `axis`.
        let turn_axis = if twist {
            axis
        } else {
            let other = random_unit(&mut rng);
            Unit::new_normalize(axis.cross(&other))
        };
        let total = if twist {
            rng.random_range(-params.max_twist..=params.max_twist)
        } else {
            rng.random_range(-params.max_bend..=params.max_bend)
        };
        let displacement: Vec<Vector3<f64>> = model
            .rest_positions()
            .par_iter()
            .map(|x| {
                let r = x - center;
                let angle = total * r.dot(&axis) / extent;
                Rotation3::from_axis_angle(&turn_axis, angle) * r - r
            })
            .collect();
        fields.push(displacement);
    }
    poses.extend(model.project_fields(&fields));
    debug_assert!(poses.iter().all(|p: &Vec<f64>| p.len() == 3 * n4));
    Ok(poses)
}

/// The factor t making the RMS Green strain `‖(FᵀF − I)/2‖_F` of `t·direction` over the
/// probe points equal `amplitude` (bisection on a monotone-enough function, t in
/// [1e-12, 1e6]).
fn scale_to_strain(probe: &DeformationMap, direction: &[f64], amplitude: f64) -> f64 {
    let strain = |t: f64| {
        let z: Vec<f64> = direction.iter().map(|d| d * t).collect();
        let f = probe.deformation_gradients(&z);
        let sum: f64 = f
            .iter()
            .map(|f| (0.5 * (f.transpose() * f - Matrix3::identity())).norm_squared())
            .sum();
        (sum / f.len().max(1) as f64).sqrt()
    };
    // Bracket [t/2, t] by doubling or halving from 1.
    let mut hi = 1.0;
    if strain(hi) < amplitude {
        while strain(hi) < amplitude && hi < 1e6 {
            hi *= 2.0;
        }
    } else {
        while strain(0.5 * hi) >= amplitude && hi > 1e-12 {
            hi *= 0.5;
        }
    }
    let mut lo = 0.5 * hi;
    // 20 halvings of a bracket [t, 2t] give t to 1e-6 relative: plenty for a pose amplitude.
    for _ in 0..20 {
        let mid = 0.5 * (lo + hi);
        if strain(mid) < amplitude {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// A direction uniform on the sphere.
fn random_unit(rng: &mut ChaCha8Rng) -> Unit<Vector3<f64>> {
    loop {
        let v = Vector3::new(normal(rng), normal(rng), normal(rng));
        if v.norm() > 1e-6 {
            return Unit::new_normalize(v);
        }
    }
}

/// A standard normal sample (Box–Muller).
fn normal(rng: &mut ChaCha8Rng) -> f64 {
    let u: f64 = rng.random_range(f64::MIN_POSITIVE..1.0);
    let v: f64 = rng.random_range(0.0..1.0);
    (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
}
