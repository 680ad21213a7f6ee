//! How much of the particle baselines' distance to the FEM is a time step, theirs or the
//! reference's? Runs the FEM (P2 res 4) of a beam test with backward Euler at h = 0.01 s (the
//! tables' reference) and at h = 0.001 s, MPM at Δx = 0.1 m (explicit, Δt = 1e-4 s) and SPH at
//! spacing 0.1 m with 1, 5 and 25 steps per 0.01 s frame, and prints the normalized MSE of each
//! against both references at the FEM vertices over the 0.01 s frames.
//!
//! `cargo run --release -p eval --example mpm_time_step -- [twist|bend] [steps of 0.01 s]`
//! (default: twist, its 30 steps)

use std::path::PathBuf;

use eval::beam_scenario::{
    BEAM_MAX, BEAM_MIN, BEAM_TIME_STEP, BeamTest, beam_length_scale, beam_material,
};
use eval::particle_baselines::mpm::{MpmStudyConfig, run_mpm_beam};
use eval::particle_baselines::particle_baseline::ParticleBeamRun;
use eval::particle_baselines::sph::{SphStudyConfig, run_sph_beam};
use fem_ref::{ElementOrder, FillReducingOrdering, TetMesh};
use freeform::fem_reference::{FemProblem, run_fem};
use freeform::metrics::trajectory_errors;
use freeform::terminal_progress::{BarProgress, TerminalProgress};
use hyperelastic::HessianTangent;
use optimize::NewtonParams;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let test = match args.get(1).map(String::as_str) {
        None | Some("twist") => BeamTest::Twist,
        Some("bend") => BeamTest::Bend,
        Some(other) => return Err(format!("unknown test {other}").into()),
    };
    let steps: usize = args.get(2).map_or(Ok(test.steps()), |s| s.parse())?;
    let cache = PathBuf::from(std::env::var("FREEFORM_CACHE").unwrap_or("freeform-cache".into()));
    let progress = TerminalProgress::default();
    let tets = TetMesh::cuboid(BEAM_MIN, BEAM_MAX, [20, 4, 4])?;
    let run = |h: f64, substeps: usize| {
        run_fem(
            &FemProblem {
                tets: tets.clone(),
                order: ElementOrder::Quadratic,
                material: beam_material(),
                scene: &test.scene(),
                time_step: h,
                newton: NewtonParams::default(),
                tangent: HessianTangent::ProjectedPsd,
                ordering: FillReducingOrdering::default(),
                failed_step_halvings: 0,
                steps: steps * substeps,
            },
            &format!("{} P2 res 4 h = {h}", test.name()),
            &cache,
            &BarProgress::new(progress),
        )
    };
    let coarse = run(BEAM_TIME_STEP, 1)?;
    let fine = run(BEAM_TIME_STEP / 10.0, 10)?;
    let ParticleBeamRun {
        row: mpm,
        frames: mpm_frames,
    } = run_mpm_beam(
        test,
        0.1,
        &MpmStudyConfig::default(),
        steps,
        &coarse,
        &cache,
        &progress,
    )?;
    let l = beam_length_scale();
    let coarse_frames = coarse.vertex_frames();
    let fine_frames: Vec<_> = fine.vertex_frames().into_iter().step_by(10).collect();
    let mse = |a: &[Vec<_>], b: &[Vec<_>]| -> Result<f64, freeform::metrics::MetricsError> {
        Ok(trajectory_errors(&a[1..], &b[1..], l)?.normalized_mse)
    };
    println!(
        "{} over {steps} frames of 0.01 s, normalized MSE at the {} FEM vertices (P2 res 4):",
        test.name(),
        coarse.vertices().len()
    );
    println!(
        "  FEM h = 0.01 vs FEM h = 0.001: {:.3e}",
        mse(&coarse_frames, &fine_frames)?
    );
    println!(
        "  MPM Δx = 0.1 vs FEM h = 0.01:  {:.3e} (as the row: {:?})",
        mse(&mpm_frames, &coarse_frames)?,
        mpm.mse
    );
    println!(
        "  MPM Δx = 0.1 vs FEM h = 0.001: {:.3e}",
        mse(&mpm_frames, &fine_frames)?
    );
    for substeps in [1, 5, 25] {
        let ParticleBeamRun { frames, .. } = run_sph_beam(
            test,
            0.1,
            &SphStudyConfig::default().with_substeps(substeps),
            steps,
            &coarse,
            &cache,
            &progress,
        )?;
        println!(
            "  SPH spacing 0.1, Δt = {:.4} s: {:.3e} vs FEM h = 0.01, {:.3e} vs FEM h = 0.001",
            BEAM_TIME_STEP / substeps as f64,
            mse(&frames, &coarse_frames)?,
            mse(&frames, &fine_frames)?
        );
    }
    Ok(())
}
