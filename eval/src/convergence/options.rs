//! What the convergence study varies besides m, K and ν: the test, the boundary treatment and
//! the volumetric term.

use freeform::PinHold;
use serde::{Deserialize, Serialize};

use crate::EvalError;
use crate::beam_protocol::reduced::exact_pin_hold;
use crate::beam_scenario::BeamTest;
use crate::reduced_settings::{EXACT_INSET_KERNEL_RADII, ReducedSettings};

/// A test of the study.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ConvergenceTest {
    /// The Bend's clamp and gravity scaled by [`crate::convergence::ConvergenceConfig::static_gravity_scale`],
    /// solved for static equilibrium: a linear problem whose Galerkin solution obeys the Ritz
    /// bounds.
    StaticBend,
    /// Table 1's dynamic Bend.
    Bend,
    /// Table 1's Twist.
    Twist,
}

impl ConvergenceTest {
    /// "static_bend", "bend" or "twist".
    pub fn name(self) -> &'static str {
        match self {
            ConvergenceTest::StaticBend => "static_bend",
            ConvergenceTest::Bend => "bend",
            ConvergenceTest::Twist => "twist",
        }
    }

    /// The beam test whose scene it runs.
    pub fn beam_test(self) -> BeamTest {
        match self {
            ConvergenceTest::StaticBend | ConvergenceTest::Bend => BeamTest::Bend,
            ConvergenceTest::Twist => BeamTest::Twist,
        }
    }
}

/// How the pinned and twisted ends are held.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum BoundaryTreatment {
    /// The penalty with the settings' factor ([`PinHold::Penalty`]; the paper's treatment).
    Penalty,
    /// Exact on the regions shrunk by [`EXACT_INSET_KERNEL_RADII`], penalty on the band
    /// ([`PinHold::Exact`]).
    ExactInset,
    /// The weighted basis: exact on the whole regions, no parameter; the settings' transition
    /// when their hold is weighted, else [`PinHold::WEIGHTED`]'s.
    Weighted,
    /// Symmetric Nitsche ([`reduced_sim::NitscheInterface`]): the held region left out of the
    /// body, the basis built on the free part alone, the interface held weakly with β from the
    /// reduced trace bound ([`crate::convergence::ConvergenceConfig::nitsche_stabilization_factor`]).
    /// Built for the beam's half-space regions (the clamp and the Twist's turning end).
    Nitsche,
}

impl BoundaryTreatment {
    /// "penalty", "exact_inset", "weighted" or "nitsche".
    pub fn name(self) -> &'static str {
        match self {
            BoundaryTreatment::Penalty => "penalty",
            BoundaryTreatment::ExactInset => "exact_inset",
            BoundaryTreatment::Weighted => "weighted",
            BoundaryTreatment::Nitsche => "nitsche",
        }
    }

    /// `base` with this treatment's hold (Nitsche's body has no held region: the penalty's,
    /// with nothing to penalize).
    ///
    /// # Errors
    /// [`EvalError`] when the exact inset's kernels cannot be placed.
    pub fn settings(self, base: &ReducedSettings) -> Result<ReducedSettings, EvalError> {
        let pins = match self {
            BoundaryTreatment::Penalty | BoundaryTreatment::Nitsche => PinHold::Penalty,
            BoundaryTreatment::ExactInset => exact_pin_hold(base, EXACT_INSET_KERNEL_RADII)?,
            BoundaryTreatment::Weighted => match base.pins {
                weighted @ PinHold::Weighted { .. } => weighted,
                _ => PinHold::WEIGHTED,
            },
        };
        Ok(ReducedSettings { pins, ..*base })
    }

    /// Whether this is the library's default hold ([`PinHold::default`]).
    pub fn is_library_default(self) -> bool {
        matches!(
            (self, PinHold::default()),
            (BoundaryTreatment::Penalty, PinHold::Penalty)
                | (BoundaryTreatment::Weighted, PinHold::Weighted { .. })
                | (BoundaryTreatment::ExactInset, PinHold::Exact { .. })
        )
    }
}

/// How the volumetric term of the material is integrated.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum VolumetricTerm {
    /// At every quadrature point, as the material defines it (the paper's setting).
    Pointwise,
    /// Projected onto a pressure space ([`freeform::PressureSpace`],
    /// [`crate::convergence::ConvergenceConfig::pressure`]): the locking-free term.
    Projected,
}

impl VolumetricTerm {
    /// Whether this is the library's default volumetric term (a scene file's
    /// [`freeform::SimulationSpec::default`]).
    pub fn is_library_default(self) -> bool {
        let projected = freeform::SimulationSpec::default().pressure.is_some();
        (self == VolumetricTerm::Projected) == projected
    }

    /// "pointwise" or "projected".
    pub fn name(self) -> &'static str {
        match self {
            VolumetricTerm::Pointwise => "pointwise",
            VolumetricTerm::Projected => "projected",
        }
    }
}
