//! The committed presets (`eval/presets/*.toml`) are the configurations the code builds: each
//! parses into its study's typed configuration and equals what the constructors give (and,
//! for the paper's binary, what its flags gave before presets), so a preset run reproduces the
//! earlier tables bit for bit. `FREEFORM_WRITE_PRESETS=1 cargo test -p eval --test presets`
//! writes the files from the constructors.

use std::path::{Path, PathBuf};

use eval::ablation::study::AblationStudyConfig;
use eval::beam_protocol::study_config::BeamStudyConfig;
use eval::bench::BenchConfig;
use eval::convergence::ConvergenceConfig;
use eval::pins::PinSweepConfig;
use eval::presets::{PRESETS, Preset, StudyKind, render_preset, set_folder};
use eval::reduced_settings::ReducedSettings;
use eval::shapes::config::ShapeStudyConfig;
use eval::shapes::reference::ShapeFemParams;
use eval::stress::StressConfig;
use serde::Serialize;
use serde::de::DeserializeOwned;

const CACHE: &str = "CACHE";

fn cache() -> PathBuf {
    PathBuf::from(CACHE)
}

/// The beam study the paper's binary ran for `table 1 5 6` before presets (the SPH time step
/// set from its substeps, as the flags did).
fn beam_full() -> BeamStudyConfig {
    let full = BeamStudyConfig::full(cache());
    BeamStudyConfig {
        sph: full.sph.clone().map(|sph| {
            let substeps = sph.substeps;
            sph.with_substeps(substeps)
        }),
        ..full
    }
}

/// The trusted shapes study: graded references with the convergence check.
fn shapes_trusted() -> ShapeStudyConfig {
    ShapeStudyConfig {
        fem: ShapeFemParams::graded(),
        check_convergence: true,
        ..ShapeStudyConfig::full(Vec::new(), cache())
    }
}

/// Checks (or with `FREEFORM_WRITE_PRESETS` writes) preset `name` against `expected`.
fn check<T: Serialize + DeserializeOwned + PartialEq + std::fmt::Debug>(
    name: &str,
    study: StudyKind,
    description: &str,
    expected: T,
    folders: &[&str],
) {
    if std::env::var_os("FREEFORM_WRITE_PRESETS").is_some() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("presets/{name}.toml"));
        std::fs::write(&path, render_preset(study, description, &expected).unwrap()).unwrap();
        // The binary holds the presets it was built with: check them on the next build.
        return;
    }
    let preset = Preset::named(name).unwrap_or_else(|e| panic!("{e}"));
    let config: T = preset
        .config(study, |table| {
            for key in folders {
                set_folder(table, key, Path::new(CACHE));
            }
            if study == StudyKind::Shapes {
                table.insert("meshes".into(), toml::Value::Array(Vec::new()));
            }
        })
        .unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(config, expected, "preset {name}");
}

#[test]
fn every_committed_preset_equals_the_configuration_the_code_builds() {
    beam_and_ablation_presets();
    shapes_presets();
    bench_pins_convergence_and_stress_presets();
    assert_eq!(PRESETS.len(), 19, "every committed preset is checked above");
}

fn beam_and_ablation_presets() {
    check(
        "beam",
        StudyKind::Beam,
        "Tables 1, 5 and 6 as the paper ran them: the beam Bend (300 steps) and Twist (30 steps) at\nm = 6, 9, 16, 32, K = 1000 on 20 000 points, 5000 simulation points, every point and a\nfresh PSD-projected Hessian every Newton iteration (the paper's step), the library's pin\npenalty, FEM P2 res 6; Simplicits, MPM, SPH and exact pins beside.",
        beam_full(),
        &["cache_dir"],
    );
    check(
        "beam-quick",
        StudyKind::Beam,
        "Tables 1, 5 and 6 in minutes: m = 6 and 16, K = 500 on 10 000 points, 100 Bend steps,\nFEM P2 res 4, Simplicits trained for 500 steps, no MPM or SPH.",
        BeamStudyConfig::quick(cache()),
        &["cache_dir"],
    );
    check(
        "beam-library",
        StudyKind::Beam,
        "Tables 1, 5 and 6 on the paper's discretization (pin penalty, pointwise volumetric term,\n5000 points) with the library's step: the optimized cubature, the Hessian carried across\nsteps, the exact tangent where the step's system factors; everything else as `beam`.",
        BeamStudyConfig {
            settings: ReducedSettings::library_step(),
            ..beam_full()
        },
        &["cache_dir"],
    );
    check(
        "beam-converging",
        StudyKind::Beam,
        "Tables 1 and 5 with the library's defaults, whose error falls monotonically in m: the regions\nheld by the weighted basis, the projected volumetric term, 40 000 basis and simulation\npoints, the library's step (docs/defaults.md); FreeForm against the FEM only, no baselines.",
        BeamStudyConfig {
            settings: ReducedSettings::default().converging(),
            simplicits: None,
            mpm: None,
            sph: None,
            exact_pins: None,
            ..beam_full()
        },
        &["cache_dir"],
    );
    check(
        "ablation",
        StudyKind::Ablation,
        "Tables 3 and 4 as the paper ran them, at m = 16: Simplicits, our coefficients trained by\nAdam (random-handle or Hessian loss, random or grid points), our eigen solve; grid against\nrandom simulation points.",
        AblationStudyConfig::full(BeamStudyConfig::full(cache())),
        &["base.cache_dir"],
    );
    check(
        "ablation-quick",
        StudyKind::Ablation,
        "Tables 3 and 4 on the `beam-quick` settings (m = 16).",
        AblationStudyConfig::full(BeamStudyConfig::quick(cache())),
        &["base.cache_dir"],
    );
}

fn shapes_presets() {
    check(
        "shapes",
        StudyKind::Shapes,
        "Tables 2 and 7 as committed (results/current-default/): m = 32 on every shape, FEM\nreferences on graded lattices with a 1.5x finer convergence check; a reference failing its\ngate (volume within 3%, converged, finer change under a tenth of the smaller error) is not\nscored.",
        shapes_trusted(),
        &["cache_dir"],
    );
    check(
        "shapes-quick",
        StudyKind::Shapes,
        "Tables 2 and 7 in seconds per shape, for trying the pipeline: m = 6, K = 120, 10 steps,\nFEM P2 on a coarse uniform 6-cell lattice, no convergence check. Not the trusted setting.",
        ShapeStudyConfig::quick(Vec::new(), cache()),
        &["cache_dir"],
    );
    check(
        "shapes-converging",
        StudyKind::Shapes,
        "Table 2 on the trusted references (the `shapes` preset) with the library's defaults, whose\nerror falls monotonically in m on the beam (the `beam-converging` preset's): FreeForm\nagainst the FEM only, no Simplicits, to set beside the committed rows.",
        ShapeStudyConfig {
            settings: shapes_trusted().settings.converging(),
            simplicits: None,
            exact_pins: None,
            ..shapes_trusted()
        },
        &["cache_dir"],
    );
    let quick = ShapeStudyConfig::quick(Vec::new(), cache());
    let graded = ShapeFemParams::graded();
    check(
        "shapes-quick-graded",
        StudyKind::Shapes,
        "The `shapes-quick` study on its coarse base lattice graded as the trusted setting grades\nits own (refined near the surface, regions on lattice planes, edges refined, the factor\ncarried), with the convergence check: the trusted pipeline in seconds per shape.",
        ShapeStudyConfig {
            fem: ShapeFemParams {
                refinement: graded.refinement,
                newton: graded.newton,
                tangent: graded.tangent,
                clamp_on_lattice_plane: graded.clamp_on_lattice_plane,
                pull_slabs_on_lattice_planes: graded.pull_slabs_on_lattice_planes,
                refine_pulled_patch_edges: graded.refine_pulled_patch_edges,
                refine_pulled_slab_faces: graded.refine_pulled_slab_faces,
                factor_reuse: graded.factor_reuse,
                failed_step_halvings: graded.failed_step_halvings,
                ..quick.fem
            },
            check_convergence: true,
            ..quick.clone()
        },
        &["cache_dir"],
    );
    check(
        "shapes-uniform",
        StudyKind::Shapes,
        "Tables 2 and 7 on the first study's uniform lattices (results/shape-study/), without the\nconvergence check: kept for comparison, not the trusted setting.",
        ShapeStudyConfig::full(Vec::new(), cache()),
        &["cache_dir"],
    );
}

fn bench_pins_convergence_and_stress_presets() {
    check(
        "bench",
        StudyKind::Bench,
        "The error-vs-time sweep on the beam Bend: every knob around the default, Simplicits at\nfour m, MPM, SPH and coarser FEM.",
        BenchConfig::full(cache()),
        &["cache_dir"],
    );
    check(
        "bench-quick",
        StudyKind::Bench,
        "The error-vs-time sweep in about a minute.",
        BenchConfig::quick(cache()),
        &["cache_dir"],
    );
    check(
        "pins",
        StudyKind::Pins,
        "The pin sweep: the beam Bend and Twist at nu = 0.3, 0.45, 0.49 and m = 16, 32, pin\nfactors 1e2 to 3e4 under both moduli, the exact pins and the parameter-free converging\nsetting, each against the FEM.",
        PinSweepConfig::full(cache()),
        &["cache_dir"],
    );
    check(
        "pins-quick",
        StudyKind::Pins,
        "The pin sweep in minutes: nu = 0.3 and 0.49, m = 16, 100 Bend steps, FEM P2 res 4, the\nparameter-free rows on K = 500 and 10 000 / 5000 points.",
        PinSweepConfig::quick(cache()),
        &["cache_dir"],
    );
    check(
        "convergence",
        StudyKind::Convergence,
        "The convergence study: static Bend, Bend and Twist at nu = 0.3, 0.45, 0.49, m = 8 to 64,\nK = 1000 and 2000, each boundary treatment, against the FEM (the static Bend against P2\nres 10, checked against res 12), with the subspace's best approximations.",
        ConvergenceConfig::full(cache()),
        &["cache_dir"],
    );
    check(
        "convergence-quick",
        StudyKind::Convergence,
        "The convergence study in minutes: the static Bend at nu = 0.45, m = 8, 16, 32, K = 1000,\neach boundary treatment, against P2 res 8 (checked against P2 res 10).",
        ConvergenceConfig::quick(cache()),
        &["cache_dir"],
    );
    check(
        "stress",
        StudyKind::Stress,
        "The numerical stress suite: extreme nu, stiffness contrast, large steps, fast twists, an\nimpact, extreme m and K, degenerate sampling.",
        StressConfig::full(),
        &[],
    );
    check(
        "stress-quick",
        StudyKind::Stress,
        "A subset of the stress suite that runs in about a minute.",
        StressConfig::quick(),
        &[],
    );
}
