//! Mesh-convergence study of the FEM reference on the beam scenes of DESIGN 4.1: Bend (tip y
//! at t = 0.5 s and 1.0 s) and Twist (RMS displacement of the x = 2.5 m section at t = 0.17 s
//! and 0.34 s), for P1 and P2 at increasing resolution, with the change from the previous level.
//!
//! ```sh
//! cargo run --release -p fem-ref --example convergence -- --p1 2,4,8 --p2 2,4,6
//! ```
//! Options: `--p1 LIST`, `--p2 LIST` (resolutions, elements across the 1 m side; even values
//! keep the plane x = 0.5 on element faces), `--scene bend|twist|both` (default both),
//! `--tangent psd|exact`.

#[path = "common/beam.rs"]
mod beam;

use beam::{BeamScene, run_beam};
use fem_ref::ElementOrder;
use hyperelastic::Tangent;

fn list(args: &[String], name: &str, default: &[usize]) -> Result<Vec<usize>, String> {
    match args.iter().position(|a| a == name) {
        None => Ok(default.to_vec()),
        Some(i) => args
            .get(i + 1)
            .ok_or_else(|| format!("{name} needs a list"))?
            .split(',')
            .filter(|s| !s.is_empty())
            .map(|s| s.parse().map_err(|_| format!("{name}: bad resolution {s}")))
            .collect(),
    }
}

fn run() -> Result<(), String> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let p1 = list(&args, "--p1", &[2, 4, 8])?;
    let p2 = list(&args, "--p2", &[2, 4, 6])?;
    let scenes = match args
        .iter()
        .position(|a| a == "--scene")
        .and_then(|i| args.get(i + 1))
        .map(String::as_str)
    {
        None | Some("both") => vec![BeamScene::Bend, BeamScene::Twist],
        Some("bend") => vec![BeamScene::Bend],
        Some("twist") => vec![BeamScene::Twist],
        Some(other) => return Err(format!("--scene must be bend, twist or both, not {other}")),
    };
    let tangent = if args.iter().any(|a| a == "exact") {
        Tangent::Exact
    } else {
        Tangent::ProjectedPsd
    };
    for scene in scenes {
        let (steps, at, what) = match scene {
            BeamScene::Bend => (100, [50, 100], "tip y (m)"),
            BeamScene::Twist => (34, [17, 34], "section RMS displacement (m)"),
        };
        println!("\n## {scene:?}: {what}, {steps} steps of 0.01 s\n");
        println!(
            "| order | res | DOFs | t₁ | value t₁ | Δ vs previous | t₂ | value t₂ | Δ vs previous | s/step | Newton it./step |"
        );
        println!("|---|---|---|---|---|---|---|---|---|---|---|");
        for (order, resolutions) in [(ElementOrder::Linear, &p1), (ElementOrder::Quadratic, &p2)] {
            let mut previous: Option<Vec<f64>> = None;
            for &res in resolutions {
                let run = run_beam(scene, order, res, steps, &at, tangent, 1e-6)?;
                let values: Vec<f64> = run.probes.iter().map(|p| p.1).collect();
                let delta = |k: usize| match &previous {
                    Some(p) => format!("{:+.3e}", values[k] - p[k]),
                    None => "—".into(),
                };
                println!(
                    "| {} | {res} | {} | {:.2} | {:.6} | {} | {:.2} | {:.6} | {} | {:.3} | {:.2} |",
                    if order == ElementOrder::Linear {
                        "P1"
                    } else {
                        "P2"
                    },
                    run.dofs,
                    run.probes[0].0,
                    values[0],
                    delta(0),
                    run.probes[1].0,
                    values[1],
                    delta(1),
                    run.seconds_per_step,
                    run.iterations_per_step,
                );
                previous = Some(values);
            }
        }
    }
    Ok(())
}

fn main() {
    if let Err(e) = run() {
        eprintln!("convergence: {e}");
        std::process::exit(1);
    }
}
