//! `freeform table`: the paper's tables.

use crate::plot_or_warn;
use std::path::{Path, PathBuf};

use anyhow::{Result, bail};
use baselines::mpm::MpmMaterial;
use baselines::sph::{RestVolume, SphParams};
use eval::ablation::study::{AblationStudyConfig, run_ablation_study};
use eval::ablation::tables::{table3, table4};
use eval::beam::BeamTest;
use eval::beam::mpm::MpmStudyConfig;
use eval::beam::sph::SphStudyConfig;
use eval::beam::study::{BeamStudyConfig, run_beam_study};
use eval::beam::tables::{table1, table5, table6, twist_error_plot};
use eval::progress::Progress;
use eval::report::table::{RenderedTable, write_table};
use eval::shapes::boundary::ShapeBoundary;
use eval::shapes::reference::{ReferenceFactorReuse, ShapeFemParams};
use eval::shapes::study::{ShapeStudy, ShapeStudyConfig, mesh_files, run_shape_study};
use eval::shapes::tables::{table2, table7};
use reduced_sim::{CubatureParams, HessianTangent, PinModulus, QuadratureRule};

/// Options of `freeform table`.
#[derive(clap::Args)]
pub(crate) struct TableOptions {
    /// Reduced configuration (minutes instead of tens of minutes).
    #[arg(long)]
    pub(crate) quick: bool,
    /// Print JSON instead of Markdown.
    #[arg(long)]
    json: bool,
    /// Leave out the Simplicits baseline (its training takes about 16 min per m on 2 cores
    /// the first time; networks are cached).
    #[arg(long)]
    skip_simplicits: bool,
    /// Only these modes (comma-separated), instead of the paper's 6, 9, 16, 32 (tables 3
    /// and 4: one m, default 16).
    #[arg(long, value_delimiter = ',')]
    modes: Option<Vec<usize>>,
    /// Tables 2 and 7: the folder of closed meshes (OBJ/STL/PLY), e.g. the shared
    /// `data/meshes`.
    #[arg(long)]
    meshes: Option<PathBuf>,
    /// Tables 2 and 7: only the mesh with this file name or stem.
    #[arg(long)]
    only: Option<String>,
    /// Tables 2 and 7: Young's modulus (Pa) of a mesh not in the shared-mesh catalog.
    #[arg(long, default_value_t = eval::shapes::catalog::DEFAULT_SHAPE_YOUNGS_MODULUS)]
    young: f64,
    /// Tables 2 and 7: shapes run at the same time.
    #[arg(long, default_value_t = 1)]
    jobs: usize,
    /// Tables 2 and 7: mesh the FEM reference on this lattice (cells across L) instead of
    /// refining from 10 up to 16 cells until the volume is within 5%.
    #[arg(long)]
    fem_cells: Option<usize>,
    /// Train Simplicits for this many Adam steps instead of the configuration's (the
    /// paper's 10 000 in a full run): networks are cached per step count.
    #[arg(long)]
    simplicits_steps: Option<usize>,
    /// Tables 1, 2, 5, 6, 7: integrate the elastic energy on every simulation point (`full`, the
    /// paper's setting) or on an optimized cubature (`cubature`, issue 18).
    #[arg(long, value_enum, default_value_t = QuadratureChoice::Full)]
    quadrature: QuadratureChoice,
    /// Tables 2 and 7: the quadrature Simplicits is simulated with, where it should differ
    /// from `--quadrature` (e.g. `full` beside FreeForm's cubature: Simplicits' own cubature is
    /// coarser and costs it accuracy on stiff shapes).
    #[arg(long, value_enum)]
    simplicits_quadrature: Option<QuadratureChoice>,
    /// With `--quadrature cubature`: the relative force error it is optimized to.
    #[arg(long, default_value_t = CubatureParams::DEFAULT.tolerance)]
    cubature_tolerance: f64,
    /// Tables 1, 2, 5, 6, 7: carry the Hessian factorization across steps while chord steps
    /// contract by 0.7 (the paper's setting assembles a fresh Hessian every iteration).
    #[arg(long)]
    hessian_reuse: bool,
    /// Tables 1, 2, 5, 6, 7: simulate on a grid of about this many points (default 5000, the
    /// paper's); 20000 is the basis's own grid, where the m = 32 Bend error is about 4× lower
    /// (issue 18). On the shapes the grid fills each surface, for both methods.
    #[arg(long)]
    simulation_points: Option<usize>,
    /// Pin penalty factor (default the library's, 3e3; tables 1, 2, 5, 6, 7).
    #[arg(long)]
    pin_factor: Option<f64>,
    /// The modulus the pin penalty scales with (default the library's, `young`; the first
    /// tables used `p-wave` with factor 1e3).
    #[arg(long, value_enum)]
    pin_modulus: Option<PinModulusChoice>,
    /// Tables 2 and 7: check each FEM reference's convergence by running it again on a 1.5×
    /// finer lattice (about 5× the FEM time); a row whose reference changes by a tenth of the
    /// smaller method error or more is not scored.
    #[arg(long)]
    check_convergence: bool,
    /// Tables 2 and 7: compute nothing, score what the cache holds; a row whose FEM reference
    /// or convergence check is not cached says so and is not scored, a shape whose Simplicits
    /// network is not cached is reported. For the tables of work spread over several runs.
    #[arg(long)]
    cached_only: bool,
    /// Tables 2 and 7: which conditions' FEM references carry the Cholesky factor across
    /// Newton iterations and steps at tolerance 1e-8 (`fem_ref::reusing_reference_newton`):
    /// `never`, `pulls` (Pull farthest and Pull boundary), `pulls-and-stiff-fix-side` (and Fix
    /// side on the stiff, 10⁸ Pa, shapes) or `every` (the value of a bare `--fem-reuse`);
    /// default the mesher choice's (`ShapeFemParams`). Cached apart.
    #[arg(long, value_enum, num_args = 0..=1, default_missing_value = "every")]
    fem_reuse: Option<FactorReuseChoice>,
    /// Tables 2 and 7: where Fix side's FEM reference is clamped: `plane` meshes it (and its
    /// convergence check) on the lattice shifted so that a vertex plane is the clamped slab's
    /// face, so the held nodes fill the slab; `lattice` keeps the shape's one mesh, whose held
    /// nodes stop at the last node plane inside the slab (0.031 L deep instead of 0.05 L at 16
    /// cells). Default: `plane` on graded lattices, `lattice` on uniform ones (the first
    /// tables' setting).
    #[arg(long, value_enum)]
    fem_clamp: Option<SlabFaceChoice>,
    /// Tables 2 and 7: where Pull boundary's FEM reference holds its two pulled slabs: `plane`
    /// meshes it (and its convergence check) on a lattice whose vertex planes are both slabs'
    /// faces (shifted, its spacing the faces' distance over a whole number of cells); `lattice`
    /// keeps the shape's one mesh. Default: `plane` on graded lattices, `lattice` on uniform
    /// ones.
    #[arg(long, value_enum)]
    fem_pull_slabs: Option<SlabFaceChoice>,
    /// Tables 2 and 7, graded lattices only: where Pull farthest's FEM reference pulls its
    /// patches: `refined` meshes it (and its convergence check) on the graded lattice refined
    /// to its finest level along every pulled ball's sphere, so the pulled nodes match the
    /// ball to a quarter cell; `lattice` keeps the shape's one mesh, whose pulled nodes match
    /// it to a cell. Default: the graded setting's.
    #[arg(long, value_enum)]
    fem_pull_patches: Option<RegionEdgeChoice>,
    /// Tables 2 and 7, graded lattices only: `refined` meshes Pull boundary's FEM reference
    /// (and its convergence check) on the graded lattice refined to its finest level along
    /// both pulled slabs' faces (where the held nodes end in an edge of singular stress);
    /// `lattice` does not. Default: the graded setting's.
    #[arg(long, value_enum)]
    fem_pull_slab_faces: Option<RegionEdgeChoice>,
    /// Tables 2 and 7: the boundary conditions run on every shape, comma-separated (default
    /// all three). The averages of a condition left out cover no shape.
    #[arg(long, value_enum, value_delimiter = ',')]
    boundaries: Option<Vec<BoundaryChoice>>,
    /// Tables 2 and 7: mesh the FEM references on uniform lattices (10 cells across ×1.5 up to
    /// 16 until the volume is within 5%, the first tables' setting) or on lattices graded near
    /// the surface (16 ×1.5 up to 36, two halvings near the surface, within 3%; issue 19;
    /// with --quick the quick lattice, graded).
    #[arg(long, value_enum, default_value_t = FemMesherChoice::Uniform)]
    fem_mesher: FemMesherChoice,
    /// Tables 2 and 7: the element tangent of the FEM references' Newton Hessian: PSD-projected
    /// or exact, projected only when the exact Hessian fails to factor (fewer iterations at
    /// large rotations; the same converged states, cached apart), or exact with the
    /// absolute-eigenvalue tangent as the fallback (exact-else-absolute). Default: projected on
    /// uniform lattices (the first tables' setting), exact-when-definite on graded ones.
    #[arg(long, value_enum)]
    fem_tangent: Option<FemTangentChoice>,
    /// Tables 2 and 7: how deep a FEM reference's step whose Newton solve does not converge
    /// within the iteration cap is split into backward-Euler half steps (0 keeps it
    /// unconverged, and its row is not scored). Default: 2 on graded lattices, 0 on uniform
    /// ones (the first tables' setting). References that converged whole are the same at
    /// every depth and stay cached.
    #[arg(long)]
    fem_step_halvings: Option<usize>,
    /// Leave out the exact-pin columns of Tables 1 and 2 (each row is run a second time with
    /// the pinned regions held exactly, on a basis built for them).
    #[arg(long)]
    skip_exact: bool,
    /// The exact pins of Tables 1 and 2: hold each region shrunk by this many median kernel
    /// radii (default 1.5 on the beam; 0 on the shapes, whose regions are thinner than that:
    /// the whole region is held).
    #[arg(long)]
    exact_inset_radii: Option<f64>,
    /// Leave out the MPM baseline of Tables 1 and 5 (its Bend run at Δx = 0.05 m takes more
    /// than 80 min on 2 cores the first time; trajectories are cached).
    #[arg(long)]
    skip_mpm: bool,
    /// The MPM grid spacings (m, comma-separated; default 0.1,0.05).
    #[arg(long, value_delimiter = ',')]
    mpm_spacings: Option<Vec<f64>>,
    /// The MPM particles' elastic model (default fixed corotated, warp-mpm's and the paper's
    /// run; `stable-neo-hookean` is the FEM's and ours).
    #[arg(long, value_enum)]
    mpm_material: Option<MpmMaterialChoice>,
    /// Leave out the SPH baseline of Tables 1 and 5 (spacing 0.05 m: about 4 min for Bend and
    /// Twist on 2 cores the first time; trajectories are cached).
    #[arg(long)]
    skip_sph: bool,
    /// The SPH particle spacings (m, comma-separated; default 0.1,0.05).
    #[arg(long, value_delimiter = ',')]
    sph_spacings: Option<Vec<f64>>,
    /// The SPH zero-energy-mode coefficient α (default 0.1, SPlisHSPlasH's beam scene; 0 turns
    /// the control off).
    #[arg(long)]
    sph_alpha: Option<f64>,
    /// SPH steps per 0.01 s frame (default 1: the paper's Δt = 0.01 s; SPlisHSPlasH's own beam
    /// scene takes Δt = 2 ms, i.e. 5).
    #[arg(long)]
    sph_substeps: Option<usize>,
    /// The volumes the SPH energies are integrated with (default sampled: the lattice's s³;
    /// `kernel-sum`: SPlisHSPlasH's m_i / Σ_j m_j W_ij, larger at the surface).
    #[arg(long, value_enum)]
    sph_rest_volume: Option<SphRestVolumeChoice>,
}

/// `--sph-rest-volume`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub(crate) enum SphRestVolumeChoice {
    /// The sampling's own volume of each particle.
    Sampled,
    /// SPlisHSPlasH's kernel-sum volume.
    KernelSum,
}

/// `--mpm-material`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub(crate) enum MpmMaterialChoice {
    /// τ = 2μ(F − R)Fᵀ + λJ(J − 1)I.
    FixedCorotated,
    /// The project's stable Neo-Hookean.
    StableNeoHookean,
}

/// `--pin-modulus`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub(crate) enum PinModulusChoice {
    /// Young's modulus E.
    Young,
    /// The p-wave modulus λ + 2μ.
    PWave,
}

/// Where an FEM reference's held slabs end.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub(crate) enum SlabFaceChoice {
    /// On the shape's one lattice mesh: the nodes inside the slab.
    Lattice,
    /// On a lattice whose vertex planes are the slabs' faces, so the held nodes fill them
    /// (`ShapeFemParams::{clamp_on_lattice_plane, pull_slabs_on_lattice_planes}`).
    Plane,
}

/// A boundary condition of Tables 2 and 7.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub(crate) enum BoundaryChoice {
    /// The min-x side held, gravity.
    FixSide,
    /// Four farthest-point-sampled patches pulled outward.
    PullFarthest,
    /// Both ends of the longest axis pulled apart.
    PullBoundary,
}

impl BoundaryChoice {
    fn boundary(self) -> ShapeBoundary {
        match self {
            BoundaryChoice::FixSide => ShapeBoundary::FixSide,
            BoundaryChoice::PullFarthest => ShapeBoundary::PullFarthest,
            BoundaryChoice::PullBoundary => ShapeBoundary::PullBoundary,
        }
    }
}

/// How finely an FEM reference's lattice resolves the edge of a pulled region.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub(crate) enum RegionEdgeChoice {
    /// As the rest of the lattice: the region's nodes match it to a cell.
    Lattice,
    /// Refined to the graded lattice's finest level along the edge
    /// (`ShapeFemParams::{refine_pulled_patch_edges, refine_pulled_slab_faces}`).
    Refined,
}

/// Which conditions' FEM references reuse the Cholesky factor.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub(crate) enum FactorReuseChoice {
    /// A fresh factorization every Newton iteration.
    Never,
    /// Pull farthest's and Pull boundary's.
    Pulls,
    /// The Pulls', and Fix side's of the stiff (manufactured, 10⁸ Pa) shapes.
    PullsAndStiffFixSide,
    /// Every condition's.
    Every,
}

/// How the shapes' FEM references are meshed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub(crate) enum FemMesherChoice {
    /// Uniform lattices (`ShapeFemParams::default`).
    Uniform,
    /// Lattices graded near the surface (`ShapeFemParams::graded`).
    Graded,
}

/// The element tangent of the shapes' FEM references.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub(crate) enum FemTangentChoice {
    /// `HessianTangent::ProjectedPsd`.
    Projected,
    /// `HessianTangent::ExactWhenDefinite`.
    ExactWhenDefinite,
    /// `HessianTangent::ExactElseAbsolute`.
    ExactElseAbsolute,
}

/// Where the reduced runs integrate the elastic energy.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub(crate) enum QuadratureChoice {
    /// Every simulation point with its volume.
    Full,
    /// An optimized cubature.
    Cubature,
}

impl QuadratureChoice {
    /// The rule chosen; a cubature optimized to relative force error `cubature_tolerance`.
    fn rule(self, cubature_tolerance: f64) -> QuadratureRule {
        match self {
            QuadratureChoice::Full => QuadratureRule::Full,
            QuadratureChoice::Cubature => QuadratureRule::Cubature(CubatureParams {
                tolerance: cubature_tolerance,
                ..CubatureParams::DEFAULT
            }),
        }
    }
}

pub(crate) fn run(
    numbers: &[u32],
    TableOptions {
        quick,
        json,
        skip_simplicits,
        modes,
        meshes,
        only,
        young,
        jobs,
        fem_cells,
        simplicits_steps,
        quadrature,
        simplicits_quadrature,
        cubature_tolerance,
        hessian_reuse,
        simulation_points,
        pin_factor,
        pin_modulus,
        skip_exact,
        exact_inset_radii,
        check_convergence,
        cached_only,
        fem_reuse,
        fem_clamp,
        fem_pull_slabs,
        fem_pull_patches,
        fem_pull_slab_faces,
        boundaries,
        fem_mesher,
        fem_tangent,
        fem_step_halvings,
        skip_mpm,
        mpm_spacings,
        mpm_material,
        skip_sph,
        sph_spacings,
        sph_alpha,
        sph_substeps,
        sph_rest_volume,
    }: TableOptions,
    out: &Path,
    cache: &Path,
    progress: &Progress,
) -> Result<()> {
    if let Some(n) = numbers.iter().find(|n| !matches!(n, 1..=7)) {
        bail!("there is no table {n}: the paper's tables are 1 to 7");
    }
    if simplicits_steps == Some(0) {
        bail!("--simplicits-steps must be at least 1");
    }
    let mut config = if quick {
        BeamStudyConfig::quick(cache.to_path_buf())
    } else {
        BeamStudyConfig::full(cache.to_path_buf())
    };
    if numbers.iter().all(|&n| n == 5) {
        // Timing only needs the Bend.
        config.tests = vec![BeamTest::Bend];
    }
    // Only Table 1 prints the exact-pin columns.
    if let Some(radii) = exact_inset_radii
        && !(radii >= 0.0 && radii.is_finite())
    {
        bail!("--exact-inset-radii must be a non-negative number, got {radii}");
    }
    config.exact_pins = (!skip_exact && numbers.contains(&1))
        .then_some(exact_inset_radii.unwrap_or(eval::beam::reduced::EXACT_INSET_KERNEL_RADII));
    check_spacings("--mpm-spacings", mpm_spacings.as_deref())?;
    // Only Tables 1 and 5 print the MPM baseline.
    config.mpm = if skip_mpm || !numbers.iter().any(|&n| n == 1 || n == 5) {
        None
    } else {
        // `--quick` leaves MPM out unless spacings are given.
        let mpm = match (config.mpm.take(), mpm_spacings) {
            (mpm, Some(spacings)) => Some(MpmStudyConfig {
                spacings,
                ..mpm.unwrap_or_default()
            }),
            (mpm, None) => mpm,
        };
        mpm.map(|mpm| MpmStudyConfig {
            material: match mpm_material {
                Some(MpmMaterialChoice::FixedCorotated) => MpmMaterial::FixedCorotated,
                Some(MpmMaterialChoice::StableNeoHookean) => MpmMaterial::StableNeoHookean,
                None => mpm.material,
            },
            ..mpm
        })
    };
    check_spacings("--sph-spacings", sph_spacings.as_deref())?;
    if sph_substeps == Some(0) {
        bail!("--sph-substeps must be at least 1");
    }
    let refined =
        [fem_pull_patches, fem_pull_slab_faces].contains(&Some(RegionEdgeChoice::Refined));
    if refined && fem_mesher != FemMesherChoice::Graded {
        bail!(
            "--fem-pull-patches refined and --fem-pull-slab-faces refined need --fem-mesher graded \
             (they refine a graded lattice)"
        );
    }
    if let Some(alpha) = sph_alpha
        && !(alpha >= 0.0 && alpha.is_finite())
    {
        bail!("--sph-alpha must be a non-negative number, got {alpha}");
    }
    // Only Tables 1 and 5 print the SPH baseline; `--quick` leaves it out unless spacings are
    // given.
    config.sph = if skip_sph || !numbers.iter().any(|&n| n == 1 || n == 5) {
        None
    } else {
        match (config.sph.take(), sph_spacings) {
            (sph, Some(spacings)) => Some(SphStudyConfig {
                spacings,
                ..sph.unwrap_or_default()
            }),
            (sph, None) => sph,
        }
        .map(|sph| {
            let substeps = sph_substeps.unwrap_or(sph.substeps);
            SphStudyConfig {
                params: SphParams {
                    zero_energy_alpha: sph_alpha.unwrap_or(sph.params.zero_energy_alpha),
                    rest_volume: match sph_rest_volume {
                        Some(SphRestVolumeChoice::Sampled) => RestVolume::Sampled,
                        Some(SphRestVolumeChoice::KernelSum) => RestVolume::KernelSum,
                        None => sph.params.rest_volume,
                    },
                    ..sph.params
                },
                ..sph
            }
            .with_substeps(substeps)
        })
    };
    if let Some(modes) = &modes {
        if modes.contains(&0) {
            bail!("--modes: every m must be at least 1");
        }
        config.modes = modes.clone();
    }
    if !(cubature_tolerance > 0.0 && cubature_tolerance.is_finite()) {
        bail!("--cubature-tolerance must be a positive number, got {cubature_tolerance}");
    }
    config.settings.quadrature = quadrature.rule(cubature_tolerance);
    if hessian_reuse {
        config.settings.hessian_reuse = reduced_sim::SimulationParams::HESSIAN_REUSE;
    }
    if let Some(points) = simulation_points {
        if points == 0 {
            bail!("--simulation-points must be at least 1");
        }
        config.settings.simulation_points = points;
    }
    if let Some(factor) = pin_factor {
        if !(factor > 0.0 && factor.is_finite()) {
            bail!("--pin-factor must be a positive number, got {factor}");
        }
        config.settings.pin_factor = factor;
    }
    match pin_modulus {
        None => {}
        Some(PinModulusChoice::Young) => config.settings.pin_modulus = PinModulus::Young,
        Some(PinModulusChoice::PWave) => config.settings.pin_modulus = PinModulus::PWave,
    }
    let wants = |group: &[u32]| numbers.iter().any(|n| group.contains(n));
    if let Some(steps) = simplicits_steps
        && let Some(params) = &mut config.simplicits
    {
        params.steps = steps;
    }
    let mut rendered = Vec::new();
    if wants(&[2, 7]) {
        let Some(dir) = &meshes else {
            bail!("tables 2 and 7 need --meshes DIR (e.g. the shared data/meshes folder)");
        };
        if !(young > 0.0 && young.is_finite()) {
            bail!("--young must be a positive number of pascals, got {young}");
        }
        let files = mesh_files(dir, only.as_deref())?;
        let mut shapes = if quick {
            ShapeStudyConfig::quick(files, cache.to_path_buf())
        } else {
            ShapeStudyConfig::full(files, cache.to_path_buf())
        };
        shapes.default_youngs_modulus = young;
        shapes.check_convergence = check_convergence;
        shapes.cached_only = cached_only;
        if fem_mesher == FemMesherChoice::Graded {
            let graded = ShapeFemParams::graded();
            // A quick run keeps its coarse base lattice and grades it.
            shapes.fem = if quick {
                ShapeFemParams {
                    refinement: graded.refinement,
                    newton: graded.newton,
                    tangent: graded.tangent,
                    clamp_on_lattice_plane: graded.clamp_on_lattice_plane,
                    pull_slabs_on_lattice_planes: graded.pull_slabs_on_lattice_planes,
                    refine_pulled_patch_edges: graded.refine_pulled_patch_edges,
                    refine_pulled_slab_faces: graded.refine_pulled_slab_faces,
                    factor_reuse: graded.factor_reuse,
                    failed_step_halvings: graded.failed_step_halvings,
                    ..shapes.fem
                }
            } else {
                graded
            };
        }
        if let Some(choice) = fem_reuse {
            shapes.fem.factor_reuse = match choice {
                FactorReuseChoice::Never => ReferenceFactorReuse::Never,
                FactorReuseChoice::Pulls => ReferenceFactorReuse::Pulls,
                FactorReuseChoice::PullsAndStiffFixSide => {
                    ReferenceFactorReuse::PullsAndStiffFixSide
                }
                FactorReuseChoice::Every => ReferenceFactorReuse::Every,
            };
        }
        if let Some(choice) = fem_clamp {
            shapes.fem.clamp_on_lattice_plane = choice == SlabFaceChoice::Plane;
        }
        if let Some(choice) = fem_pull_slabs {
            shapes.fem.pull_slabs_on_lattice_planes = choice == SlabFaceChoice::Plane;
        }
        if let Some(choice) = fem_pull_patches {
            shapes.fem.refine_pulled_patch_edges = choice == RegionEdgeChoice::Refined;
        }
        if let Some(choice) = fem_pull_slab_faces {
            shapes.fem.refine_pulled_slab_faces = choice == RegionEdgeChoice::Refined;
        }
        if let Some(halvings) = fem_step_halvings {
            shapes.fem.failed_step_halvings = halvings;
        }
        if let Some(choice) = fem_tangent {
            shapes.fem.tangent = match choice {
                FemTangentChoice::Projected => HessianTangent::ProjectedPsd,
                FemTangentChoice::ExactWhenDefinite => HessianTangent::ExactWhenDefinite,
                FemTangentChoice::ExactElseAbsolute => HessianTangent::ExactElseAbsolute,
            };
        }
        if skip_exact {
            shapes.exact_pins = None;
        } else if let Some(radii) = exact_inset_radii {
            shapes.exact_pins = Some(radii);
        }
        shapes.jobs = jobs;
        shapes.settings.pin_factor = config.settings.pin_factor;
        shapes.settings.pin_modulus = config.settings.pin_modulus;
        if let Some(points) = simulation_points {
            shapes.settings.simulation_points = points;
        }
        shapes.settings.quadrature = config.settings.quadrature;
        if let Some(choices) = &boundaries {
            // In the paper's column order, each once.
            shapes.boundaries = ShapeBoundary::ALL
                .into_iter()
                .filter(|b| choices.iter().any(|c| c.boundary() == *b))
                .collect();
        }
        shapes.simplicits_quadrature =
            simplicits_quadrature.map(|choice| choice.rule(cubature_tolerance));
        shapes.settings.hessian_reuse = config.settings.hessian_reuse;
        if let Some(cells) = fem_cells {
            if cells == 0 {
                bail!("--fem-cells must be at least 1");
            }
            shapes.fem.first_cells_across = cells;
            shapes.fem.max_cells_across = cells;
        }
        if let Some(modes) = &modes {
            match modes.as_slice() {
                [m] => shapes.settings.modes = *m,
                _ => bail!("tables 2 and 7 use one m: give --modes a single value"),
            }
        }
        match (skip_simplicits, &mut shapes.simplicits, simplicits_steps) {
            (true, simplicits, _) => *simplicits = None,
            (false, Some(params), Some(steps)) => params.steps = steps,
            _ => {}
        }
        let total = shapes.meshes.len();
        let study = run_shape_study(&shapes, progress, |shape, so_far| {
            let mut line = format!(
                "[{}/{total} shapes] {} finished",
                so_far.shapes.len(),
                shape.name
            );
            // A long run leaves the tables of the shapes it finished, should it be stopped (or
            // should a later table fail).
            let written = shape_tables(numbers, so_far)
                .iter()
                .map(|table| write_table(table, out))
                .collect::<Result<Vec<_>, _>>();
            line += &match written {
                Ok(_) => format!("; the tables so far are in {}", out.display()),
                Err(e) => format!("; the tables so far could not be written: {e}"),
            };
            progress.status(line);
        })?;
        progress.status(format!(
            "shape study: {total} shape(s) in {:.0} s",
            study.seconds
        ));
        rendered.extend(shape_tables(numbers, &study));
    }
    if wants(&[3, 4]) {
        if skip_simplicits {
            bail!("tables 3 and 4 compare against Simplicits; drop --skip-simplicits for them");
        }
        let m = match modes.as_deref() {
            None => 16,
            Some([m]) => *m,
            Some(_) => bail!("tables 3 and 4 study one m: give --modes a single value"),
        };
        let ablation = AblationStudyConfig {
            coefficient_ablations: wants(&[3]),
            sampling_ablation: wants(&[4]),
            ..AblationStudyConfig::full(BeamStudyConfig {
                modes: vec![m],
                ..config.clone()
            })
        };
        let study = run_ablation_study(&ablation, progress)?;
        for &number in numbers.iter().filter(|n| matches!(n, 3 | 4)) {
            rendered.push(if number == 3 {
                table3(&study)
            } else {
                table4(&study)
            });
        }
    }
    if wants(&[1, 5, 6]) {
        if skip_simplicits {
            config.simplicits = None;
        }
        let study = run_beam_study(&config, progress)?;
        if wants(&[1])
            && let Some(spec) = twist_error_plot(&study)
        {
            for f in plot_or_warn(&spec, &out.join("twist_error_per_frame")) {
                progress.status(format!("wrote {}", f.display()));
            }
        }
        for &number in numbers.iter().filter(|n| matches!(n, 1 | 5 | 6)) {
            rendered.push(match number {
                1 => table1(&study),
                5 => table5(&study),
                _ => table6(&study),
            });
        }
    }
    let mut rendered_json = Vec::new();
    for table in rendered {
        let files = write_table(&table, out)?;
        if json {
            rendered_json.push(table.json);
        } else {
            println!("{}", table.markdown);
            for f in files {
                println!("wrote {}", f.display());
            }
            println!();
        }
    }
    if json {
        let value = if rendered_json.len() == 1 {
            rendered_json.remove(0)
        } else {
            serde_json::Value::Array(rendered_json)
        };
        println!("{}", serde_json::to_string_pretty(&value)?);
    }
    Ok(())
}

/// Tables 2 and 7 of `study`, those of them `numbers` asks for, in its order.
fn shape_tables(numbers: &[u32], study: &ShapeStudy) -> Vec<RenderedTable> {
    numbers
        .iter()
        .filter_map(|n| match n {
            2 => Some(table2(study)),
            7 => Some(table7(study)),
            _ => None,
        })
        .collect()
}

/// Every spacing of a `--…-spacings` flag must be a positive, finite number of metres.
fn check_spacings(flag: &str, spacings: Option<&[f64]>) -> Result<()> {
    if let Some(bad) = spacings
        .unwrap_or_default()
        .iter()
        .find(|h| !(**h > 0.0 && h.is_finite()))
    {
        bail!("{flag}: every spacing must be a positive number of metres, got {bad}");
    }
    Ok(())
}
