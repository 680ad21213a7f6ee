//! Tables 3 and 4 (the training and sampling ablations on the beam) as Markdown beside the
//! paper's numbers, JSON and CSV.

use std::fmt::Write as _;

use serde_json::json;

use crate::ablation::study::AblationStudy;
use crate::beam_protocol::preamble::{score_or_why, settings_lines};
use crate::beam_scenario::BeamTest;
use crate::report::paper;
use crate::report::table::{RenderedTable, sci};

/// How the trained rows were trained.
fn training_line(study: &AblationStudy) -> String {
    let t = study.config.training();
    format!(
        "Trained rows: {} Adam steps (lr {:e}) on the same grid and kernels as our basis; \
         Simplicits and random-z: {} points × {} random handle sets per step, loss {} · \
         elastic + {:e} · orthogonality; Hessian: tr(cᵀH_w c)/max(λ+4μ) + {:e} · \
         mean((cᵀ𝓜c − I)²), m + 1 columns trained and the lowest Ritz pair dropped (the \
         constant). Random points: {} fresh uniform points per step; grid points: draws from the \
         grid (random-z) or the full grid quadrature (Hessian). Training times are wall time on \
         this machine ({} threads; the paper's are on a GPU), from the run that produced the \
         cached model.\n",
        t.steps,
        t.learning_rate,
        t.points_per_step,
        t.transforms_per_step,
        t.elastic_weight,
        t.ortho_weight,
        t.ortho_weight,
        t.points_per_step,
        rayon::current_num_threads()
    )
}

/// Table 3: Drop (Bend) and Twist MSE and training time of each way of finding the weights.
pub fn table3(study: &AblationStudy) -> RenderedTable {
    let m = study.config.modes();
    let mut md = format!("## Table 3: how the skinning weights are found (beam, m = {m})\n\n");
    md += &settings_lines(&study.config.base, &study.fem);
    md += &training_line(study);
    md += "\n| method | Drop MSE | Twist MSE | training (s) | final loss | paper Drop | paper Twist | paper s |\n";
    md += "|---|---|---|---|---|---|---|---|\n";
    let mut csv = String::from(
        "method,drop_mse,twist_mse,training_seconds,paper_drop_mse,paper_twist_mse,paper_seconds\n",
    );
    let mut rows = Vec::new();
    for r in &study.table3 {
        let p = paper::table3(&r.method);
        let (drop, twist) = (r.mse(BeamTest::Bend), r.mse(BeamTest::Twist));
        let _ = writeln!(
            md,
            "| {} | {} | {} | {:.1}{} | {} | {} | {} | {} |",
            r.method,
            score_or_why(drop, &study.fem, BeamTest::Bend),
            score_or_why(twist, &study.fem, BeamTest::Twist),
            r.training_seconds,
            if r.cached { " (cached)" } else { "" },
            r.loss
                .map_or("—".into(), |(a, b)| format!("{a:.2e} → {b:.2e}")),
            sci(p.map(|p| p.0)),
            sci(p.map(|p| p.1)),
            p.map_or("—".into(), |p| format!("{:.2}", p.2)),
        );
        let _ = writeln!(
            csv,
            "{},{},{},{},{},{},{}",
            r.method,
            drop.map_or(String::new(), |v| format!("{v:e}")),
            twist.map_or(String::new(), |v| format!("{v:e}")),
            r.training_seconds,
            p.map_or(String::new(), |p| format!("{:e}", p.0)),
            p.map_or(String::new(), |p| format!("{:e}", p.1)),
            p.map_or(String::new(), |p| p.2.to_string()),
        );
        rows.push(json!({
            "method": r.method,
            "drop_mse": drop,
            "twist_mse": twist,
            "scores": r.scores,
            "training_seconds": r.training_seconds,
            "cached": r.cached,
            "loss_first_last": r.loss,
            "paper_drop_mse": p.map(|p| p.0),
            "paper_twist_mse": p.map(|p| p.1),
            "paper_seconds": p.map(|p| p.2),
        }));
    }
    if !study.config.coefficient_ablations {
        md += "\nThe four coefficient-training rows were not run.\n";
    }
    RenderedTable {
        number: 3,
        markdown: md,
        json: json!({"table": 3, "m": m, "rows": rows,
            "settings": {"config": study.config, "fem": study.fem}}),
        csv,
    }
}

/// Table 4: each method simulated with grid and with random integration points.
pub fn table4(study: &AblationStudy) -> RenderedTable {
    let m = study.config.modes();
    let s = &study.config.base.settings;
    let mut md = format!(
        "## Table 4: grid vs random integration points at simulation time (beam, m = {m})\n\n"
    );
    md += &settings_lines(&study.config.base, &study.fem);
    let _ = writeln!(
        md,
        "Both methods' weights are built as in Table 1; only the simulation's ≈{} points change: \
         the grid (v = h³) or as many uniform random points in the beam (v = V/N, seed {}).",
        s.simulation_points, study.config.random_points_seed
    );
    md += "\n| method | test | grid MSE | random MSE | random/grid | paper grid | paper random |\n";
    md += "|---|---|---|---|---|---|---|\n";
    let mut csv = String::from("method,test,grid_mse,random_mse,paper_grid_mse,paper_random_mse\n");
    let mut rows = Vec::new();
    for r in &study.table4 {
        let p = paper::table4(&r.method, r.test.name());
        let label = match r.test {
            BeamTest::Bend => "Drop",
            BeamTest::Twist => "Twist",
        };
        let _ = writeln!(
            md,
            "| {} | {label} | {:.2e} | {:.2e} | {:.2} | {} | {} |",
            r.method,
            r.grid_mse,
            r.random_mse,
            r.random_mse / r.grid_mse,
            sci(p.map(|p| p.0)),
            sci(p.map(|p| p.1)),
        );
        let _ = writeln!(
            csv,
            "{},{},{:e},{:e},{},{}",
            r.method,
            r.test.name(),
            r.grid_mse,
            r.random_mse,
            p.map_or(String::new(), |p| format!("{:e}", p.0)),
            p.map_or(String::new(), |p| format!("{:e}", p.1)),
        );
        rows.push(json!({
            "method": r.method,
            "test": r.test.name(),
            "grid_mse": r.grid_mse,
            "random_mse": r.random_mse,
            "paper_grid_mse": p.map(|p| p.0),
            "paper_random_mse": p.map(|p| p.1),
        }));
    }
    if !study.config.sampling_ablation {
        md += "\nThe random-point simulations were not run.\n";
    }
    RenderedTable {
        number: 4,
        markdown: md,
        json: json!({"table": 4, "m": m, "rows": rows,
            "settings": {"config": study.config, "fem": study.fem}}),
        csv,
    }
}
