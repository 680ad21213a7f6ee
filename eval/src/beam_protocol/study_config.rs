//! The beam protocol's settings (design §4.1), shared by the experiments on the beam: which m,
//! tests and steps, the reduced settings, the FEM reference, the baselines.

use optimize::NewtonParams;
use std::path::PathBuf;

use baselines::SimplicitsParams;
use serde::{Deserialize, Serialize};

use crate::beam_scenario::BeamTest;
use crate::fem_reference::FemResolution;
use crate::particle_baselines::mpm::MpmStudyConfig;
use crate::particle_baselines::sph::SphStudyConfig;
use crate::reduced_settings::{EXACT_INSET_KERNEL_RADII, ReducedSettings};

/// What a beam study runs.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BeamStudyConfig {
    /// Modes m to run.
    pub modes: Vec<usize>,
    /// Tests to run.
    pub tests: Vec<BeamTest>,
    /// Everything but m.
    pub settings: ReducedSettings,
    /// Steps per test; `None` for design §4.1's (300 Bend, 30 Twist).
    pub steps: Option<usize>,
    /// The FEM ground truth.
    pub fem: FemResolution,
    /// The FEM's Newton options (default: 20 iterations, tolerance 1e-6). A reference any of
    /// whose steps stops unconverged is not scored.
    #[serde(default = "NewtonParams::default")]
    pub fem_newton: NewtonParams,
    /// The Simplicits baseline's training options (its `modes` is set per m), or `None` to
    /// leave it out.
    pub simplicits: Option<SimplicitsParams>,
    /// Cache folder (FEM trajectories under `fem/`, networks under `simplicits/`).
    pub cache_dir: PathBuf,
    /// Also run every (test, m) with the pinned regions held exactly, shrunk by this many
    /// median kernel radii ([`crate::beam_protocol::reduced::exact_pin_hold`], a basis per test), beside the penalty (issue
    /// 25); `None` to leave it out.
    #[serde(default)]
    pub exact_pins: Option<f64>,
    /// The MPM baseline at each of its grid spacings on every test, or `None` to
    /// leave it out.
    #[serde(default)]
    pub mpm: Option<MpmStudyConfig>,
    /// The SPH baseline at each of its particle spacings on every test, or `None` to
    /// leave it out.
    #[serde(default)]
    pub sph: Option<SphStudyConfig>,
}

impl BeamStudyConfig {
    /// The paper's configuration: m ∈ {6, 9, 16, 32}, both tests, K = 1000, design §4.1's steps,
    /// FEM P2 res 6.
    pub fn full(cache_dir: PathBuf) -> Self {
        BeamStudyConfig {
            modes: vec![6, 9, 16, 32],
            tests: BeamTest::ALL.to_vec(),
            settings: ReducedSettings::default(),
            steps: None,
            fem: FemResolution::GROUND_TRUTH,
            fem_newton: NewtonParams::default(),
            simplicits: Some(SimplicitsParams::default()),
            cache_dir,
            exact_pins: Some(EXACT_INSET_KERNEL_RADII),
            mpm: Some(MpmStudyConfig::default()),
            sph: Some(SphStudyConfig::default()),
        }
    }

    /// A few-minute version: m ∈ {6, 16}, K = 500 on 10k basis points, 100 Bend steps (Twist
    /// keeps its 30), FEM P2 res 4, Simplicits trained for 500 steps instead of 10 000, no MPM
    /// or SPH.
    pub fn quick(cache_dir: PathBuf) -> Self {
        BeamStudyConfig {
            modes: vec![6, 16],
            settings: ReducedSettings {
                kernels: 500,
                basis_points: 10_000,
                ..ReducedSettings::default()
            },
            steps: Some(100),
            fem: FemResolution {
                cells_per_metre: 4,
                ..FemResolution::GROUND_TRUTH
            },
            simplicits: Some(SimplicitsParams {
                steps: 500,
                ..SimplicitsParams::default()
            }),
            mpm: None,
            sph: None,
            ..BeamStudyConfig::full(cache_dir)
        }
    }

    /// Steps of `test` in this configuration (Twist never runs past its 30 steps).
    pub fn steps_of(&self, test: BeamTest) -> usize {
        self.steps.unwrap_or(test.steps()).min(test.steps())
    }
}
