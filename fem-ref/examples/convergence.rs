//! Mesh-convergence study of the FEM reference on the beam scenes of design §4.1: Bend (tip y
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

use beam::{BeamScene, TangentArg, run_beam};
use fem_ref::ElementOrder;
use hyperelastic::HessianTangent;

/// Which scenes to run.
#[derive(Clone, Copy, clap::ValueEnum)]
enum Scenes {
    Bend,
    Twist,
    Both,
}

/// Command-line options.
#[derive(clap::Parser)]
struct Args {
    /// P1 resolutions (elements across the 1 m side), comma-separated.
    #[arg(long, value_delimiter = ',', default_values_t = [2, 4, 8])]
    p1: Vec<usize>,
    /// P2 resolutions, comma-separated.
    #[arg(long, value_delimiter = ',', default_values_t = [2, 4, 6])]
    p2: Vec<usize>,
    /// Scenes.
    #[arg(long, value_enum, default_value_t = Scenes::Both)]
    scene: Scenes,
    /// Element tangent.
    #[arg(long, value_enum, default_value_t = TangentArg::Psd)]
    tangent: TangentArg,
}

fn run() -> Result<(), String> {
    let args: Args = clap::Parser::parse();
    let (p1, p2) = (args.p1, args.p2);
    let scenes = match args.scene {
        Scenes::Both => vec![BeamScene::Bend, BeamScene::Twist],
        Scenes::Bend => vec![BeamScene::Bend],
        Scenes::Twist => vec![BeamScene::Twist],
    };
    let tangent: HessianTangent = args.tangent.into();
    for scene in scenes {
        let (steps, at, what) = match scene {
            BeamScene::Bend => (100, [50, 100], "tip y (m)"),
            BeamScene::Twist => (30, [15, 30], "section RMS displacement (m)"),
        };
        println!("\n## {scene:?}: {what}, {steps} steps of 0.01 s\n");
        println!(
            "| order | res | DOFs | t₁ | value t₁ | Δ vs previous | t₂ | value t₂ | Δ vs previous | s/step | Newton it./step |"
        );
        println!("|---|---|---|---|---|---|---|---|---|---|---|");
        for (order, resolutions) in [(ElementOrder::Linear, &p1), (ElementOrder::Quadratic, &p2)] {
            let mut previous: Option<Vec<f64>> = None;
            for &res in resolutions {
                let run = run_beam(
                    scene,
                    order,
                    res,
                    steps,
                    &at,
                    tangent,
                    optimize::NewtonParams::default(),
                )?;
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
