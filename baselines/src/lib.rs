#![doc = include_str!("../README.md")]

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
