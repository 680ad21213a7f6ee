//! `freeform basis`: build and save a basis from a mesh or a point cloud.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use freeform::Geometry;
use freeform::terminal_progress::TerminalProgress;
use hyperelastic::LameParameters;
use skin_eigen::{BasisParams, build_basis};

/// The basis options of the command line.
pub(crate) struct BasisOptions {
    pub(crate) modes: usize,
    pub(crate) kernels: usize,
    pub(crate) basis_points: usize,
    pub(crate) young: f64,
    pub(crate) poisson: f64,
}

/// Builds the basis of `geometry` and saves it to `save`.
pub(crate) fn run(
    geometry: &Path,
    o: BasisOptions,
    save: PathBuf,
    progress: &TerminalProgress,
) -> Result<()> {
    let points = Geometry::read(geometry)?
        .normalized()
        .integration_points(o.basis_points)?;
    let lame = LameParameters::from_young_poisson(o.young, o.poisson)
        .with_context(|| format!("--young {} --poisson {}", o.young, o.poisson))?;
    progress.status(format!(
        "{}: {} integration points, K = {}, m = {}",
        geometry.display(),
        points.len(),
        o.kernels,
        o.modes
    ));
    let params = BasisParams::default()
        .with_modes(o.modes)
        .with_kernels(o.kernels);
    let (basis, report, _) = build_basis(&points, &vec![lame; points.len()], &params)?;
    if let Some(dir) = save.parent()
        && !dir.as_os_str().is_empty()
    {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    basis.save(&save)?;
    let t = &report.timings;
    let coverage = &report.coverage;
    if coverage.widened_kernels > 0 {
        println!(
            "{} points had too few kernels around them for exact linear reproduction (a thin \
             part?): {} kernels widened, \
             radii up to {:.2}× as placed, in {} rounds",
            coverage.singular_points,
            coverage.widened_kernels,
            coverage.max_radius_growth,
            coverage.rounds
        );
    }
    println!(
        "basis: m = {}, K = {}, N = {} points, {:.1} kernels/point\n\
         time: kernels {:.2} s, shape functions {:.2} s, assembly {:.2} s, eigen solve {:.2} s, total {:.2} s\n\
         eigenvalues (first 4): {:?}\nsaved to {}",
        basis.modes(),
        report.kernels,
        report.integration_points,
        report.mean_kernels_per_point,
        t.kernel_placement,
        t.shape_functions,
        t.assembly,
        t.eigen_solve,
        t.total(),
        &basis.eigenvalues()[..basis.eigenvalues().len().min(4)],
        save.display()
    );
    Ok(())
}
