//! Drops Spot the cow onto a floor and writes PLY + VTK frames, using only the library layer.
//!
//! `cargo run --release -p freeform --example drop_on_floor [MESH] [OUT]`
use freeform::{FloorSpec, FrameWriter, Geometry, SceneSpec, Simulation, build_basis, run};
use hyperelastic::{MaterialField, MaterialSample, StableNeoHookean};
use nalgebra::Vector3;
use reduced_sim::DeformationMap;
use skin_eigen::BasisParams;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let mesh = args
        .next()
        .unwrap_or("data/meshes/spot_low_resolution.obj".into());
    let out = args.next().unwrap_or("freeform-out/drop_on_floor".into());
    let geometry = Geometry::read(mesh.as_ref())?.normalized(); // largest side 1 m
    let rubber = MaterialSample {
        youngs_modulus: 1e5,
        poisson_ratio: 0.45,
        density: 1000.0,
    };
    let material = MaterialField::Uniform(rubber);
    let points = geometry.integration_points(5000)?;
    let (basis, _) = build_basis(
        &points,
        &material,
        &BasisParams::default().with_modes(16).with_kernels(400),
    )?;
    let scene = SceneSpec {
        gravity: Some(Vector3::new(0.0, -9.8, 0.0)),
        floor: Some(FloorSpec {
            normal: Vector3::y(),
            offset: -0.3,
            friction: 0.0,
        }), // 0.3 m below the cow
        ..Default::default()
    };
    // The library's defaults: h = 0.01 s, an optimized cubature.
    let simulation = Simulation::new(&basis, &points, &material, StableNeoHookean, &scene);
    let frames = FrameWriter::new(&out, &geometry);
    let surface = DeformationMap::new(&basis, frames.rest_positions())?;
    let report = run(&simulation, 60, |frame| {
        let x = surface.positions(&frame.simulator.state().z);
        frames.write(frame.index, &x, frame.time)?;
        Ok(())
    })?;
    println!(
        "61 frames in {out}; {:.2} ms/step, {} unconverged steps",
        report.ms_per_step, report.unconverged_steps
    );
    Ok(())
}
