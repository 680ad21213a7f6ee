#![allow(dead_code)] // shared by several examples; each uses a part of it
//! The beam scenes of design §4.1 on the FEM reference, shared by the fem-ref examples.

use std::sync::Arc;
use std::time::Instant;

use fem_ref::{
    DirichletRegion, ElementOrder, FemMesh, FemModel, FemParams, FemScene, FemSimulator, MassKind,
    NodeTarget, PointInterpolation, TetMesh,
};
use hyperelastic::MaterialSample;
use hyperelastic::{HessianTangent, StableNeoHookean};
use nalgebra::{Rotation3, Vector3};
use optimize::NewtonParams;

/// Element tangent on the command line.
#[derive(Clone, Copy, Debug, clap::ValueEnum)]
pub enum TangentArg {
    /// PSD-projected element tangents.
    Psd,
    /// Exact element tangents.
    Exact,
    /// Exact element tangents, projected only when the exact Hessian fails to factor.
    ExactWhenDefinite,
}

impl From<TangentArg> for HessianTangent {
    fn from(t: TangentArg) -> HessianTangent {
        match t {
            TangentArg::Psd => HessianTangent::ProjectedPsd,
            TangentArg::Exact => HessianTangent::Exact,
            TangentArg::ExactWhenDefinite => HessianTangent::ExactWhenDefinite,
        }
    }
}

/// Bend or Twist.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BeamScene {
    /// Gravity, x ≤ 0.5 fixed.
    Bend,
    /// x ≤ 0.5 fixed, x ≥ 4.5 rotated about the beam axis by min(2160°/s · t, 720°).
    Twist,
}

/// What a run measured.
pub struct BeamRun {
    /// (time, mean y displacement of the x = 5 face lattice) per reported frame (Bend), or
    /// (time, RMS displacement of the x = 2.5 section lattice) (Twist), m.
    pub probes: Vec<(f64, f64)>,
    pub seconds_per_step: f64,
    pub assembly_per_step: f64,
    pub factorization_per_step: f64,
    pub iterations_per_step: f64,
    pub factorizations_per_step: f64,
    pub unconverged_steps: usize,
    pub dofs: usize,
    pub nonzeros: usize,
}

/// An 11 × 11 lattice on the section x = `x`.
pub fn section_lattice(x: f64) -> Vec<Vector3<f64>> {
    (0..11)
        .flat_map(|a| (0..11).map(move |b| Vector3::new(x, a as f64 / 10.0, b as f64 / 10.0)))
        .collect()
}

/// Runs `steps` steps of `scene` at `res` elements per metre, reporting the probe at the
/// given step numbers.
pub fn run_beam(
    scene: BeamScene,
    order: ElementOrder,
    res: usize,
    steps: usize,
    report_at: &[usize],
    tangent: HessianTangent,
    newton: NewtonParams,
) -> Result<BeamRun, String> {
    let tets = TetMesh::cuboid(
        Vector3::zeros(),
        Vector3::new(5.0, 1.0, 1.0),
        [5 * res, res, res],
    )
    .map_err(|e| e.to_string())?;
    let mesh = FemMesh::new(tets, order);
    let material = MaterialSample {
        youngs_modulus: 5e6,
        poisson_ratio: 0.45,
        density: 1000.0,
    };
    let elements = mesh.element_count();
    let model = FemModel::new(
        mesh,
        &vec![material; elements],
        StableNeoHookean,
        MassKind::Consistent,
    )
    .map_err(|e| e.to_string())?;
    let nodes = model.mesh().nodes();
    let select = |f: &dyn Fn(&Vector3<f64>) -> bool| -> Vec<usize> {
        (0..nodes.len()).filter(|&i| f(&nodes[i])).collect()
    };
    // Nodes on the plane x = 0.5 belong to the fixed region (tolerance 1e-9 m).
    let fixed = select(&|x| x.x <= 0.5 + 1e-9);
    let mut fem_scene = FemScene {
        dirichlet: vec![DirichletRegion {
            nodes: fixed,
            target: NodeTarget::Rest,
        }],
        ..Default::default()
    };
    let probe_points = match scene {
        BeamScene::Bend => {
            fem_scene.gravity = Some(Vector3::new(0.0, -9.8, 0.0));
            section_lattice(5.0)
        }
        BeamScene::Twist => {
            let twisted = select(&|x| x.x >= 4.5 - 1e-9);
            fem_scene.dirichlet.push(DirichletRegion {
                nodes: twisted,
                target: NodeTarget::Moving(Arc::new(|x, t| {
                    let angle = (2160.0 * t).min(720.0).to_radians();
                    let axis = Vector3::new(x.x, 0.5, 0.5);
                    let r = Rotation3::from_axis_angle(&Vector3::x_axis(), angle);
                    axis + r * (x - axis)
                })),
            });
            section_lattice(2.5)
        }
    };
    let probe = PointInterpolation::new(model.mesh(), &probe_points).map_err(|e| e.to_string())?;
    let params = FemParams {
        time_step: 0.01,
        newton,
        tangent,
        ..FemParams::default()
    };
    let mut sim = FemSimulator::new(model, fem_scene, params).map_err(|e| e.to_string())?;
    let (dofs, nonzeros) = (sim.free_dofs(), sim.matrix_nonzeros());
    let mut probes = Vec::new();
    let (mut iterations, mut factorizations, mut unconverged) = (0, 0, 0);
    let (mut assembly, mut factorization) = (0.0, 0.0);
    let t = Instant::now();
    for step in 1..=steps {
        let report = sim.step().map_err(|e| format!("step {step}: {e}"))?;
        iterations += report.iterations;
        factorizations += report.hessian_assemblies;
        unconverged += usize::from(!report.converged());
        assembly += report.timings.assembly;
        factorization += report.timings.solve;
        if report_at.contains(&step) {
            let x = probe.interpolate(&sim.positions());
            let value = match scene {
                BeamScene::Bend => {
                    x.iter()
                        .zip(&probe_points)
                        .map(|(x, r)| x.y - r.y)
                        .sum::<f64>()
                        / probe_points.len() as f64
                }
                BeamScene::Twist => (x
                    .iter()
                    .zip(&probe_points)
                    .map(|(x, r)| (x - r).norm_squared())
                    .sum::<f64>()
                    / probe_points.len() as f64)
                    .sqrt(),
            };
            probes.push((sim.time(), value));
        }
    }
    let n = steps as f64;
    Ok(BeamRun {
        probes,
        seconds_per_step: t.elapsed().as_secs_f64() / n,
        assembly_per_step: assembly / n,
        factorization_per_step: factorization / n,
        iterations_per_step: iterations as f64 / n,
        factorizations_per_step: factorizations as f64 / n,
        unconverged_steps: unconverged,
        dofs,
        nonzeros,
    })
}
