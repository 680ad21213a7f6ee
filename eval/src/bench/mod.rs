//! The error-vs-time study (design §5) on the beam Bend: sweep the knobs that trade time for
//! error — modes m, kernels K, simulation points, Newton tolerance, and coarser FEM as its own
//! method — and mark the Pareto front (no other configuration is both faster and more accurate).

//!
//! Files: `config.rs` (what the bench sweeps), `run.rs` (each method's run, scored), `report.rs`
//! (results, Pareto front, CSV, Markdown and the plot).

mod config;
mod report;
mod run;

pub use config::{BenchConfig, BenchMethod, CUBATURE};
pub use report::{BenchResult, bench_plot, pareto_front, write_bench};
pub use run::{quadrature_label, run_bench};
