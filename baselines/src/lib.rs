//! Baselines the method is compared against (DESIGN 3.9).
//!
//! Built so far:
//! - [`Mlp`], the network of the Simplicits baseline (3 → 64 → 6 × 64 → m, ELU, PyTorch-default
//!   initialization, f64, reverse-mode parameter gradients, forward-mode input derivatives,
//!   save/load), and [`Adam`];
//! - [`train_simplicits`]: the Simplicits losses and training loop of DESIGN 3.9, giving a
//!   [`SimplicitsField`] that the reduced simulator runs through `reduced_sim::SkinningField`;
//! - [`train_coefficients`]: the Table 3 optimization ablations, our RKPM coefficients c found
//!   by Adam on the Simplicits loss or on the penalized Hessian objective, on random or grid
//!   points, giving an ordinary `skin_eigen::SkinningBasis`.
//!
//! - [`mpm`]: the explicit APIC Material Point Method of Tables 1 and 5 (warp-mpm's scheme).
//!
//! - [`sph`]: the implicit corotated SPH solid of Tables 1 and 5 (Kugelstadt et al. 2021).

pub mod adam;
pub mod coefficient_training;
pub mod mlp;
pub mod model_file;
pub mod mpm;
pub mod particle_materials;
pub mod simplicits;
pub mod sph;

pub use adam::{Adam, AdamParams};
pub use coefficient_training::{
    COEFFICIENTS_FORMAT_VERSION, CoefficientLoss, CoefficientTrainingError,
    CoefficientTrainingParams, CoefficientTrainingReport, QuadratureBatch, TrainedCoefficients,
    TrainingPoints, random_handle_loss, sample_in_cells, train_coefficients, weight_hessian_loss,
};
pub use mlp::{MLP_FORMAT_VERSION, Mlp, MlpShape, Tape};
pub use model_file::ModelFileError;
pub use particle_materials::ParticleMaterials;
pub use simplicits::{
    SIMPLICITS_FORMAT_VERSION, SimplicitsError, SimplicitsField, SimplicitsParams, StepLosses,
    TrainedSimplicits, TrainingReport, ortho_loss, train_simplicits,
};
