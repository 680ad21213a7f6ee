//! The pin sweep's tables: the penalty factors per ν with the best of each marked, and the
//! regions held exactly beside the best penalty.

use std::fmt::Write as _;

use reduced_sim::{PenaltyParams, PinModulus};

use crate::pins::{HeldSweepRow, PinSweep, PinSweepConfig};

/// The sweep as Markdown: one row per (test, m, modulus, factor), one MSE and pin-drift column
/// pair per ν, and the best factor of each (test, m, ν, modulus) marked.
pub fn pin_sweep_table(config: &PinSweepConfig, sweep: &PinSweep) -> String {
    let rows = &sweep.rows;
    let mut md = format!(
        "## Pin sweep: beam, MSE against the FEM ({}) and largest pin drift (m)\n\n\
         E = 5 MPa, ρ = 1000 kg/m³, K = {}, {} simulation points, every point with Hessian \
         reuse. κ_pin = factor · (λ + 2μ or E) / L². ★ = lowest MSE of its (test, m, ν, \
         modulus).\n\n",
        config.fem.label(),
        config.settings.kernels,
        config.settings.simulation_points
    );
    for why in &sweep.refused_references {
        let _ = writeln!(md, "Not scored: {why}.\n");
    }
    md += "| test | m | modulus | factor |";
    for nu in &config.poisson_ratios {
        let _ = write!(md, " MSE ν={nu} | drift ν={nu} |");
    }
    md += "\n|---|---|---|---|";
    md += &"---|---|".repeat(config.poisson_ratios.len());
    md += "\n";
    let find = |test, m, modulus, factor, nu| {
        rows.iter().find(|r| {
            r.test == test
                && r.m == m
                && r.modulus == modulus
                && r.factor == factor
                && r.poisson_ratio == nu
        })
    };
    let best = |test, m, modulus, nu| {
        rows.iter()
            .filter(|r| {
                r.test == test
                    && r.m == m
                    && r.modulus == modulus
                    && r.poisson_ratio == nu
                    && r.failure.is_none()
            })
            .min_by(|a, b| a.mse.total_cmp(&b.mse))
            .map(|r| r.factor)
    };
    for &test in &config.tests {
        for &m in &config.modes {
            for &modulus in &config.moduli {
                for &factor in &config.factors {
                    let _ = write!(
                        md,
                        "| {} | {m} | {} | {factor:e} |",
                        test.name(),
                        modulus_name(modulus)
                    );
                    for &nu in &config.poisson_ratios {
                        match find(test, m, modulus, factor, nu) {
                            Some(r) if r.failure.is_some() => md += " failed | — |",
                            Some(r) => {
                                let star = if best(test, m, modulus, nu) == Some(factor) {
                                    " ★"
                                } else {
                                    ""
                                };
                                let _ = write!(
                                    md,
                                    " {:.3e}{star} | {:.2e} |",
                                    r.mse, r.max_pin_deviation
                                );
                            }
                            None => md += " — | — |",
                        }
                    }
                    md += "\n";
                }
            }
        }
    }
    md
}

/// The regions held exactly (the exact pins and the parameter-free setting, those the sweep
/// ran) as Markdown beside the best penalty of each (test, m, ν) and the factor that reached
/// it: a penalty whose best factor moves with ν has to be tuned per material, a held row
/// has nothing to tune. Empty when the sweep ran neither.
pub fn held_sweep_table(config: &PinSweepConfig, sweep: &PinSweep) -> String {
    let mut held: Vec<(&str, &[HeldSweepRow])> = Vec::new();
    if config.exact_inset_radii.is_some() {
        held.push(("exact", &sweep.exact_rows));
    }
    if config.parameter_free.is_some() {
        held.push(("parameter-free", &sweep.parameter_free_rows));
    }
    if held.is_empty() {
        return String::new();
    }
    let mut md = String::from("\n## Regions held exactly beside the best penalty\n\n");
    if let Some(radii) = config.exact_inset_radii {
        let _ = writeln!(
            md,
            "Exact: the regions held exactly on the region shrunk by {radii} median kernel radii \
             (compact kernels, a basis per test), the band between kept by the penalty."
        );
    }
    if let Some(settings) = &config.parameter_free {
        let _ = writeln!(
            md,
            "Parameter-free: the same setting at every ν: {}{}; K = {}, {} basis and {} \
             simulation points, {}; Hessian {}.",
            settings.pin_rule_label(),
            settings.pressure_label(),
            settings.kernels,
            settings.basis_points,
            settings.simulation_points,
            settings.quadrature_label(),
            settings.hessian_reuse_label()
        );
    }
    let library = PenaltyParams::default();
    let _ = write!(
        md,
        "Drift: held points / FEM vertices of the whole region (m). Library penalty: the \
         library's factor, {:e} · {}, the same at every ν. Best penalty: the lowest MSE of the \
         sweep's factors and moduli at that (test, m, ν), with its factor.\n\n| test | m |",
        library.pin_factor,
        modulus_name(library.pin_modulus)
    );
    for nu in &config.poisson_ratios {
        for (name, _) in &held {
            let _ = write!(md, " {name} MSE ν={nu} | drift ν={nu} |");
        }
        let _ = write!(md, " library penalty ν={nu} | best penalty ν={nu} |");
    }
    md += "\n|---|---|";
    md += &format!("{}---|---|", "---|---|".repeat(held.len())).repeat(config.poisson_ratios.len());
    md += "\n";
    for &test in &config.tests {
        for &m in &config.modes {
            let _ = write!(md, "| {} | {m} |", test.name());
            for &nu in &config.poisson_ratios {
                for (_, rows) in &held {
                    let row = rows
                        .iter()
                        .find(|r| r.test == test && r.m == m && r.poisson_ratio == nu);
                    match row {
                        Some(r) if r.failure.is_some() => md += " failed | — |",
                        Some(r) => {
                            let _ = write!(
                                md,
                                " {:.3e} | {:.1e} / {:.2e} |",
                                r.mse, r.max_held_deviation, r.region_drift
                            );
                        }
                        None => md += " — | — |",
                    }
                }
                let penalty = sweep
                    .rows
                    .iter()
                    .filter(|r| r.test == test && r.m == m && r.poisson_ratio == nu);
                match penalty
                    .clone()
                    .find(|r| r.factor == library.pin_factor && r.modulus == library.pin_modulus)
                {
                    Some(r) if r.failure.is_some() => md += " failed |",
                    Some(r) => {
                        let _ = write!(md, " {:.3e} |", r.mse);
                    }
                    None => md += " — |",
                }
                let best = penalty
                    .filter(|r| r.failure.is_none())
                    .min_by(|a, b| a.mse.total_cmp(&b.mse));
                match best {
                    Some(r) => {
                        let _ = write!(
                            md,
                            " {:.3e} ({:e} · {}) |",
                            r.mse,
                            r.factor,
                            modulus_name(r.modulus)
                        );
                    }
                    None => md += " — |",
                }
            }
            md += "\n";
        }
    }
    md
}

/// "λ+2μ" or "E".
pub(crate) fn modulus_name(modulus: PinModulus) -> &'static str {
    match modulus {
        PinModulus::PWave => "λ+2μ",
        PinModulus::Young => "E",
    }
}

#[cfg(test)]
mod tests {
    use std::path::PathBuf;

    use super::*;
    use crate::beam_scenario::BeamTest;
    use crate::pins::PinSweepRow;

    fn row(nu: f64, modulus: PinModulus, factor: f64, mse: f64) -> PinSweepRow {
        PinSweepRow {
            poisson_ratio: nu,
            test: BeamTest::Bend,
            m: 16,
            modulus,
            factor,
            mse,
            max: 0.1,
            max_pin_deviation: 0.01,
            unconverged_steps: 0,
            failure: None,
        }
    }

    #[test]
    fn the_tables_star_each_best_factor_name_failures_and_set_held_rows_beside_the_best_penalty() {
        let config = PinSweepConfig {
            poisson_ratios: vec![0.3, 0.49],
            modes: vec![16],
            tests: vec![BeamTest::Bend],
            factors: vec![1e2, 1e3],
            moduli: vec![PinModulus::Young],
            ..PinSweepConfig::quick(PathBuf::from("unused"))
        };
        let mut failed = row(0.49, PinModulus::Young, 1e3, f64::NAN);
        failed.failure = Some("step 3 failed".into());
        let rows = vec![
            row(0.3, PinModulus::Young, 1e2, 2e-4),
            row(0.3, PinModulus::Young, 1e3, 1e-4),
            row(0.49, PinModulus::Young, 1e2, 3e-4),
            failed,
            // The library's factor, outside the first table's factors.
            row(0.3, PinModulus::Young, 3e3, 1.5e-4),
        ];
        let held = |mse: f64, drift: f64| HeldSweepRow {
            poisson_ratio: 0.3,
            test: BeamTest::Bend,
            m: 16,
            mse,
            max: 1e-2,
            max_held_deviation: drift,
            region_drift: 2e-2,
            unconverged_steps: 0,
            failure: None,
        };
        let sweep = PinSweep {
            rows,
            exact_rows: vec![held(5e-5, 1e-12)],
            parameter_free_rows: vec![held(4e-5, 0.0)],
            refused_references: vec!["ν = 0.3, twist: not converged".into()],
        };
        let md = pin_sweep_table(&config, &sweep);
        assert!(
            md.contains("Not scored: ν = 0.3, twist: not converged."),
            "{md}"
        );
        let lines: Vec<&str> = md.lines().filter(|l| l.starts_with("| bend")).collect();
        assert_eq!(lines.len(), 2, "{md}");
        // ν = 0.3: 1e3 is best; ν = 0.49: 1e2 is the only one that ran.
        assert!(
            lines[0].contains("2.000e-4 |") && lines[0].contains("3.000e-4 ★"),
            "{md}"
        );
        assert!(
            lines[1].contains("1.000e-4 ★") && lines[1].contains("failed"),
            "{md}"
        );
        // The held rows sit beside the library's penalty and the best penalty of their
        // (test, m, ν) with its factor; at ν = 0.49 the held rows and the library's factor did
        // not run, and the best penalty is the one factor that did.
        let table = held_sweep_table(&config, &sweep);
        let line = table
            .lines()
            .find(|l| l.starts_with("| bend | 16 |"))
            .expect("a held row");
        assert!(
            line.contains(
                "| bend | 16 | 5.000e-5 | 1.0e-12 / 2.00e-2 | 4.000e-5 | 0.0e0 / 2.00e-2 | \
                 1.500e-4 | 1.000e-4 (1e3 · E) | — | — | — | — | — | 3.000e-4 (1e2 · E) |"
            ),
            "{table}"
        );
        let header = table.lines().find(|l| l.starts_with("| test")).unwrap();
        let rule = table.lines().find(|l| l.starts_with("|---")).unwrap();
        assert_eq!(
            header.matches('|').count(),
            rule.matches('|').count(),
            "{table}"
        );
        assert_eq!(
            header.matches('|').count(),
            line.matches('|').count(),
            "{table}"
        );
    }
}
