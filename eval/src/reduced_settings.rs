//! The settings of a reduced run that the experiments share (beam and shapes): modes, kernels,
//! point counts, Newton and pin options, where the simulation integrates, the tangent. Keys are
//! spelled as in scene files ([`freeform::settings_vocabulary`]).

use freeform::{PinHold, PressureSpaceParams, WeightDistance};
use optimize::{HessianReuse, NewtonParams};
use reduced_sim::{
    CubatureParams, HessianTangent, PenaltyParams, PinModulus, QuadratureRule, SimulationParams,
};
use rkpm_core::{
    IntegrationPoints, RandomSamplingParams, Reproduction, TriangleMesh, sample_box_grid,
    sample_random,
};
use serde::{Deserialize, Serialize};
use skin_eigen::BasisParams;

use crate::EvalError;
use crate::beam_scenario::{BEAM_MAX, BEAM_MIN, beam_grid_spacing};

/// The knobs of a reduced beam run.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct ReducedSettings {
    /// Skinning modes m (default 16).
    pub modes: usize,
    /// RKPM kernels K (default 1000).
    pub kernels: usize,
    /// Grid points the basis is built on (default 20 000).
    pub basis_points: usize,
    /// Grid points the simulation integrates over (default 5000).
    pub simulation_points: usize,
    /// Newton tolerance (default 1e-6, see `reduced_sim::NewtonParams`; `tolerance` is read
    /// as this).
    #[serde(alias = "tolerance")]
    pub newton_tolerance: f64,
    /// Pin penalty factor (default the library's, [`PenaltyParams::default`]: 3e3 with
    /// [`PinModulus::Young`], κ = factor · max E / L², chosen by `freeform-paper pins` against the
    /// FEM; the first tables used 1e3 with [`PinModulus::PWave`]).
    pub pin_factor: f64,
    /// Where the simulation integrates (default the grid; random points are Table 4's
    /// ablation).
    #[serde(default)]
    pub simulation_sampling: SimulationSampling,
    /// Whether Newton carries its Hessian factorization across steps (default
    /// [`HessianReuse::Never`], the paper's setting; the bench's "Hessian reuse" series runs
    /// [`reduced_sim::SimulationParams::HESSIAN_REUSE`]).
    #[serde(
        default,
        deserialize_with = "freeform::settings_vocabulary::hessian_reuse_or_bool"
    )]
    pub hessian_reuse: HessianReuse,
    /// Where the elastic energy is integrated (default [`QuadratureRule::PAPER`], every
    /// simulation point: the paper's setting; the bench's cubature series and
    /// [`ReducedSettings::library_step`] run [`QuadratureRule::Cubature`]).
    #[serde(default = "paper_quadrature")]
    pub quadrature: QuadratureRule,
    /// The modulus the pin penalty scales with (default the library's, [`PinModulus::Young`]:
    /// the same factor means the same drift at every ν).
    #[serde(default)]
    pub pin_modulus: PinModulus,
    /// How the pinned and twisted ends are held (default [`PinHold::Penalty`], the paper's
    /// treatment, where the library's default is [`PinHold::WEIGHTED`];
    /// [`crate::beam_protocol::reduced::exact_pin_hold`] gives the exact holding the tables run
    /// beside it).
    #[serde(default = "paper_pins")]
    pub pins: PinHold,
    /// The material tangent of Newton's Hessians (default [`HessianTangent::ProjectedPsd`],
    /// the paper's setting; [`ReducedSettings::library_step`] runs the library's,
    /// [`HessianTangent::ExactWhenDefinite`]).
    #[serde(default = "paper_tangent")]
    pub tangent: HessianTangent,
    /// A locking-free volumetric term over a pressure space (default none, also written
    /// `"pointwise"`: the material's own volumetric term at every point, the paper's setting,
    /// where the library's default is projected; `{}` for [`PressureSpaceParams`]' defaults), as
    /// scene files' `simulation.pressure`. The space is built per test on the basis grid
    /// ([`crate::beam_protocol::reduced::beam_pressure_space`]).
    #[serde(
        default,
        skip_serializing_if = "Option::is_none",
        deserialize_with = "freeform::settings_vocabulary::pressure_or_pointwise"
    )]
    pub pressure: Option<PressureSpaceParams>,
    /// The polynomials the basis's shape functions reproduce (default
    /// [`Reproduction::Linear`], the paper's Eq. 7; written only when quadratic).
    #[serde(default, skip_serializing_if = "Reproduction::is_linear")]
    pub reproduction: Reproduction,
}

fn paper_tangent() -> HessianTangent {
    HessianTangent::ProjectedPsd
}

fn paper_pins() -> PinHold {
    PinHold::Penalty
}

/// The inset of exactly held regions, in kernel radii (the median radius of the basis's
/// kernels): [`crate::beam_protocol::reduced::exact_pin_hold`]'s rule.
///
/// Chosen against the converged FEM on the beam Bend (`results/RESULTS.md`, "The exact pins'
/// inset").
pub const EXACT_INSET_KERNEL_RADII: f64 = 1.5;

/// How the simulation's integration points are placed.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SimulationSampling {
    /// A uniform grid of about `simulation_points` cells, `v_i = h³` (default).
    #[default]
    #[serde(alias = "Grid")]
    Grid,
    /// As many uniform random points in the beam as the grid has, `v_i = V / N`, seeded
    /// (design §3.1, Table 4).
    #[serde(alias = "Random")]
    Random {
        /// The random seed.
        seed: u64,
    },
}

impl SimulationSampling {
    /// "grid" or "random".
    pub fn name(&self) -> &'static str {
        match self {
            SimulationSampling::Grid => "grid",
            SimulationSampling::Random { .. } => "random",
        }
    }

    /// The beam's integration points for about `points` points.
    ///
    /// # Errors
    /// [`EvalError::Sampling`] for a count the samplers reject.
    pub fn beam_points(&self, points: usize) -> Result<IntegrationPoints, EvalError> {
        let grid =
            sample_box_grid(BEAM_MIN, BEAM_MAX, beam_grid_spacing(points)).map_err(|source| {
                EvalError::Sampling {
                    what: "simulation points",
                    source,
                }
            })?;
        match *self {
            SimulationSampling::Grid => Ok(grid),
            SimulationSampling::Random { seed } => sample_random(
                &TriangleMesh::cuboid(BEAM_MIN, BEAM_MAX),
                &RandomSamplingParams {
                    points: grid.len(),
                    seed,
                },
            )
            .map_err(|source| EvalError::Sampling {
                what: "simulation points",
                source,
            }),
        }
    }
}

fn paper_quadrature() -> QuadratureRule {
    QuadratureRule::PAPER
}

/// A quadrature rule in words, for table preambles: "every simulation point (the paper's
/// setting)", a random subset, or an optimized cubature.
pub fn quadrature_rule_label(rule: QuadratureRule) -> String {
    match rule {
        QuadratureRule::Full => "every simulation point (the paper's setting)".to_string(),
        QuadratureRule::RandomSubset { points, seed } => {
            format!("{points} random simulation points (seed {seed}), volumes rescaled")
        }
        QuadratureRule::Cubature(p) => format!(
            "optimized cubature (An et al. 2008) to relative force error {} on the basis's \
             training poses, at most {} points",
            p.tolerance, p.max_points
        ),
        QuadratureRule::Automatic(p) => format!(
            "optimized cubature (An et al. 2008) to relative force error {}, at most {} points, \
             when it pays for itself over the run, otherwise every simulation point",
            p.tolerance, p.max_points
        ),
    }
}

impl ReducedSettings {
    /// The elastic quadrature in words, for table preambles: "every simulation point (the
    /// paper's setting)", a random subset, or an optimized cubature.
    pub fn quadrature_label(&self) -> String {
        quadrature_rule_label(self.quadrature)
    }

    /// When the Newton Hessian is rebuilt, in words, for table preambles.
    pub fn hessian_reuse_label(&self) -> String {
        match self.hessian_reuse {
            HessianReuse::Never => "fresh every Newton iteration (the paper's setting)".to_string(),
            HessianReuse::WhileContracting { contraction } => {
                format!("reused across steps while chord steps contract by {contraction}")
            }
        }
    }

    /// The volumetric term in words, for table preambles: "" for the material's own at every
    /// point (the paper's setting), else "; volumetric term projected onto …".
    pub fn pressure_label(&self) -> String {
        self.pressure.map_or(String::new(), |p| {
            format!(
                "; volumetric term projected onto a pressure space of the constant{}, the \
                 free part's first ⌈{} (m + 1)⌉ Neumann modes, min(λ, {} μ) kept pointwise",
                if p.affine {
                    ", the affine functions"
                } else {
                    ""
                },
                p.mode_fraction,
                p.retained_shear_multiple
            )
        })
    }

    /// How the held regions are held, in words, for table preambles: "pin penalty κ_pin = 3e3 ·
    /// max E / L² (the library default, chosen against the FEM by `freeform-paper pins`)", or
    /// the exact holds.
    pub fn pin_rule_label(&self) -> String {
        let modulus = match self.pin_modulus {
            PinModulus::Young => "max E",
            PinModulus::PWave => "max (λ + 2μ)",
        };
        let default = PenaltyParams::default();
        let origin =
            if self.pin_factor == default.pin_factor && self.pin_modulus == default.pin_modulus {
                " (the library default, chosen against the FEM by `freeform-paper pins`)"
            } else {
                ""
            };
        match self.pins {
            PinHold::Penalty => {
                format!(
                    "pin penalty κ_pin = {:e} · {modulus} / L²{origin}",
                    self.pin_factor
                )
            }
            PinHold::Exact { inset } => {
                format!(
                    "pins exact (held regions shrunk by {inset:.3} m, compact kernels, the band \
                     between by the penalty)"
                )
            }
            PinHold::Weighted {
                transition_fraction,
                distance,
                split_cut_cells,
            } => format!(
                "regions held exactly by a weighted basis (transition {transition_fraction} × \
                 the object's thickness, the smallest side of its bounding box{}{})",
                match distance {
                    WeightDistance::HeldMaterial => ", distances to the held material",
                    WeightDistance::RegionShape => ", distances to the regions' shapes",
                },
                if split_cut_cells {
                    ", cells the regions cut split"
                } else {
                    ""
                }
            ),
        }
    }

    /// The defaults (the paper's discretization: penalty pins, the pointwise volumetric term,
    /// 20 000 / 5000 points) with the library's fast step instead of the paper's: the elastic
    /// energy on an optimized cubature ([`QuadratureRule::default`]), the Hessian carried
    /// across steps ([`reduced_sim::SimulationParams::HESSIAN_REUSE`]) and the exact tangent
    /// wherever the step's system factors ([`HessianTangent::ExactWhenDefinite`]).
    pub fn library_step() -> Self {
        ReducedSettings {
            quadrature: QuadratureRule::default(),
            hessian_reuse: SimulationParams::HESSIAN_REUSE,
            tangent: HessianTangent::default(),
            ..ReducedSettings::default()
        }
    }

    /// These settings with the library's defaults for everything but m and K (a scene file's
    /// [`freeform::SimulationSpec::default`] and [`freeform::BasisSpec::default`]): the regions
    /// held by the weighted basis ([`PinHold::WEIGHTED`]), the volumetric term projected onto
    /// the default pressure space ([`PressureSpaceParams::default`]), 40 000 basis and
    /// simulation points (an integration pool that `freeform-paper convergence`'s pool check
    /// finds converged for K ≤ 2000), the elastic energy on an optimized cubature trained on
    /// them ([`CubatureParams::DEFAULT`], 10 000 candidates), the Hessian carried across steps
    /// and the exact tangent where the step's system factors: the setting under which the
    /// beam's error falls monotonically in m, with no pin factor and nothing chosen per ν.
    pub fn converging(self) -> Self {
        ReducedSettings {
            pins: PinHold::WEIGHTED,
            pressure: Some(PressureSpaceParams::default()),
            basis_points: freeform::BasisSpec::DEFAULT_POINTS,
            simulation_points: freeform::SimulationSpec::DEFAULT_POINTS,
            quadrature: QuadratureRule::Cubature(CubatureParams::DEFAULT),
            hessian_reuse: SimulationParams::HESSIAN_REUSE,
            tangent: HessianTangent::default(),
            ..self
        }
    }

    /// The basis builder's options for these settings: `modes`, `kernels` and the shape
    /// functions' `reproduction`, the rest default.
    pub fn basis_params(&self) -> BasisParams {
        let mut params = BasisParams::default()
            .with_modes(self.modes)
            .with_kernels(self.kernels);
        params.shape_functions.reproduction = self.reproduction;
        params
    }

    /// The simulator's options for these settings at time step `time_step` (s): Newton
    /// tolerance and pin penalty from here, everything else default.
    pub fn simulation_params(&self, time_step: f64) -> SimulationParams {
        SimulationParams {
            time_step,
            newton: NewtonParams {
                tolerance: self.newton_tolerance,
                hessian_reuse: self.hessian_reuse,
                ..Default::default()
            },
            penalty: PenaltyParams {
                pin_factor: self.pin_factor,
                pin_modulus: self.pin_modulus,
                ..Default::default()
            },
            tangent: self.tangent,
            ..SimulationParams::default()
        }
    }
}

impl Default for ReducedSettings {
    fn default() -> Self {
        ReducedSettings {
            modes: 16,
            kernels: 1000,
            basis_points: 20_000,
            simulation_points: 5000,
            newton_tolerance: NewtonParams::default().tolerance,
            pin_factor: PenaltyParams::default().pin_factor,
            simulation_sampling: SimulationSampling::Grid,
            hessian_reuse: HessianReuse::Never,
            quadrature: QuadratureRule::PAPER,
            pin_modulus: PenaltyParams::default().pin_modulus,
            pins: PinHold::Penalty,
            tangent: paper_tangent(),
            pressure: None,
            reproduction: Reproduction::Linear,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_pressure_key_is_written_only_when_set_and_reads_its_defaults_from_an_empty_table() {
        let paper = ReducedSettings::default();
        let value = serde_json::to_value(paper).unwrap();
        assert!(value.get("pressure").is_none(), "{value}");
        let mut table = toml::Table::try_from(paper).unwrap();
        table.insert("pressure".into(), toml::Value::Table(toml::Table::new()));
        let projected: ReducedSettings = table.try_into().unwrap();
        assert_eq!(projected.pressure, Some(PressureSpaceParams::default()));
        assert_eq!(paper.pressure_label(), "");
        assert!(
            projected
                .pressure_label()
                .contains("first ⌈1 (m + 1)⌉ Neumann modes, min(λ, 0.5 μ) kept pointwise")
        );
    }

    #[test]
    fn the_reproduction_key_is_written_only_when_quadratic_and_reaches_the_basis() {
        let paper = ReducedSettings::default();
        let value = serde_json::to_value(paper).unwrap();
        assert!(value.get("reproduction").is_none(), "{value}");
        assert_eq!(
            paper.basis_params().shape_functions.reproduction,
            Reproduction::Linear
        );
        let mut table = toml::Table::try_from(paper).unwrap();
        table.insert("reproduction".into(), "quadratic".into());
        let quadratic: ReducedSettings = table.try_into().unwrap();
        assert_eq!(
            quadratic.basis_params().shape_functions.reproduction,
            Reproduction::Quadratic
        );
        let value = serde_json::to_value(quadratic).unwrap();
        assert_eq!(value["reproduction"], "quadratic");
    }
}
