//! The one vocabulary of a run's settings, shared by scene files (`[basis]`, `[simulation]`),
//! the paper's presets (`[config.settings]`, `eval::ReducedSettings`), the Python dictionaries
//! and the command line (`--set settings.KEY=…`):
//!
//! | key | meaning | scene file | presets |
//! |---|---|---|---|
//! | `modes` | skinning modes m | `[basis]` | `settings` |
//! | `kernels` | RKPM kernels K | `[basis]` | `settings` |
//! | `basis_points` | grid points the basis is built on | `[basis]` | `settings` |
//! | `simulation_points` | grid points the simulation integrates over | `[simulation]` | `settings` |
//! | `newton_tolerance` | Newton's RMS step over the object's largest side | `[simulation]` | `settings` |
//! | `hessian_reuse` | `"never"` or `{ while_contracting = { contraction } }` | `[simulation]` | `settings` |
//! | `quadrature` | `{ kind = "full" \| "cubature" \| "automatic" \| "random_subset", … }` | `[simulation]` | `settings` |
//! | `pins` | `"penalty"`, `{ exact = { inset } }`, `{ weighted = { … } }` | `[simulation]` | `settings` |
//! | `tangent` | `"projected_psd"`, `"exact_when_definite"`, `"exact"` | `[simulation]` | `settings` |
//! | `pressure` | `"pointwise"` or `{ mode_fraction, affine, retained_shear_multiple }` | `[simulation]` | `settings` |
//!
//! Earlier spellings stay readable: `points` in `[basis]` and `[simulation]`, `tolerance` in
//! presets, and `true` / `false` for `hessian_reuse` (the library's reuse and `"never"`).

use optimize::HessianReuse;
use reduced_sim::SimulationParams;
use serde::{Deserialize, Deserializer, Serialize, Serializer};

use crate::pressure_space::PressureSpaceParams;

/// Reads `hessian_reuse` as a [`HessianReuse`] or as a boolean: `true` is the library's
/// [`SimulationParams::HESSIAN_REUSE`], `false` is [`HessianReuse::Never`].
///
/// # Errors
/// The deserializer's error for a value that is neither.
pub fn hessian_reuse_or_bool<'de, D: Deserializer<'de>>(
    deserializer: D,
) -> Result<HessianReuse, D::Error> {
    #[derive(Deserialize)]
    #[serde(untagged)]
    enum Spelling {
        Bool(bool),
        Reuse(HessianReuse),
    }
    Ok(match Spelling::deserialize(deserializer)? {
        Spelling::Bool(true) => SimulationParams::HESSIAN_REUSE,
        Spelling::Bool(false) => HessianReuse::Never,
        Spelling::Reuse(reuse) => reuse,
    })
}

/// The spelling of the pointwise volumetric term, the paper's: `pressure = "pointwise"`.
#[derive(Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
enum Pointwise {
    Pointwise,
}

/// Reads `pressure` as `"pointwise"` (`None`: the material's own volumetric term at every
/// point) or as a table of [`PressureSpaceParams`] (`{}` for its defaults).
///
/// # Errors
/// The deserializer's error for a value that is neither.
pub fn pressure_or_pointwise<'de, D: Deserializer<'de>>(
    deserializer: D,
) -> Result<Option<PressureSpaceParams>, D::Error> {
    #[derive(Deserialize)]
    #[serde(untagged)]
    enum Spelling {
        Pointwise(Pointwise),
        Projected(PressureSpaceParams),
    }
    Ok(match Spelling::deserialize(deserializer)? {
        Spelling::Pointwise(Pointwise::Pointwise) => None,
        Spelling::Projected(params) => Some(params),
    })
}

/// Writes `pressure` as [`pressure_or_pointwise`] reads it.
///
/// # Errors
/// The serializer's.
pub fn serialize_pressure<S: Serializer>(
    pressure: &Option<PressureSpaceParams>,
    serializer: S,
) -> Result<S::Ok, S::Error> {
    match pressure {
        None => Pointwise::Pointwise.serialize(serializer),
        Some(params) => params.serialize(serializer),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::SimulationSpec;

    fn reuse_of(toml_value: &str) -> Result<HessianReuse, toml::de::Error> {
        toml::from_str::<SimulationSpec>(&format!("hessian_reuse = {toml_value}"))
            .map(|s| s.hessian_reuse)
    }

    #[test]
    fn hessian_reuse_reads_booleans_and_the_presets_spelling_alike() {
        assert_eq!(reuse_of("true").unwrap(), SimulationParams::HESSIAN_REUSE);
        assert_eq!(reuse_of("false").unwrap(), HessianReuse::Never);
        assert_eq!(reuse_of("\"never\"").unwrap(), HessianReuse::Never);
        assert_eq!(
            reuse_of("{ while_contracting = { contraction = 0.5 } }").unwrap(),
            HessianReuse::WhileContracting { contraction: 0.5 }
        );
        assert!(reuse_of("\"sometimes\"").is_err());
    }

    #[test]
    fn pressure_reads_pointwise_or_a_space_and_writes_what_it_reads() {
        let read = |text: &str| toml::from_str::<SimulationSpec>(text).map(|s| s.pressure);
        assert_eq!(read("").unwrap(), Some(PressureSpaceParams::default()));
        assert_eq!(read("pressure = \"pointwise\"").unwrap(), None);
        assert_eq!(
            read("pressure = {}").unwrap(),
            Some(PressureSpaceParams::default())
        );
        let affine = read("pressure = { affine = true }").unwrap().unwrap();
        assert!(affine.affine);
        assert!(read("pressure = \"none\"").is_err());
        for pressure in [None, Some(affine)] {
            let spec = SimulationSpec {
                pressure,
                ..SimulationSpec::default()
            };
            let text = toml::to_string(&spec).unwrap();
            assert_eq!(toml::from_str::<SimulationSpec>(&text).unwrap(), spec);
        }
    }

    #[test]
    fn the_papers_setting_is_spelled_by_the_keys_the_docs_give() {
        let paper: SimulationSpec = toml::from_str(
            "simulation_points = 5000\npins = \"penalty\"\npressure = \"pointwise\"\n\
             quadrature = { kind = \"full\" }\nhessian_reuse = \"never\"\n\
             tangent = \"projected_psd\"\n",
        )
        .unwrap();
        assert_eq!(paper, SimulationSpec::paper());
        assert_ne!(paper, SimulationSpec::default());
    }

    #[test]
    fn the_earlier_point_keys_read_as_the_shared_ones() {
        let old: crate::SceneFile = toml::from_str(
            "[geometry]\nbox = { min = [0, 0, 0], max = [1, 1, 1] }\n[material]\n\
             youngs_modulus = 1e5\npoisson_ratio = 0.3\ndensity = 1000\n\
             [basis]\npoints = 7000\n[simulation]\npoints = 3000\n",
        )
        .unwrap();
        let new: crate::SceneFile = toml::from_str(
            "[geometry]\nbox = { min = [0, 0, 0], max = [1, 1, 1] }\n[material]\n\
             youngs_modulus = 1e5\npoisson_ratio = 0.3\ndensity = 1000\n\
             [basis]\nbasis_points = 7000\n[simulation]\nsimulation_points = 3000\n",
        )
        .unwrap();
        assert_eq!(old, new);
        assert_eq!(new.basis.basis_points, 7000);
        assert_eq!(new.simulation.simulation_points, 3000);
    }
}
