//! Baselines the method is compared against (DESIGN 3.9).
//!
//! Built so far:
//! - [`Mlp`], the network of the Simplicits baseline (3 → 64 → 6 × 64 → m, ELU, PyTorch-default
//!   initialization, f64, reverse-mode parameter gradients, forward-mode input derivatives,
//!   save/load), and [`Adam`];
//! - [`train_simplicits`]: the Simplicits losses and training loop of DESIGN 3.9, giving a
//!   [`SimplicitsField`] that the reduced simulator runs through `reduced_sim::SkinningField`.
//!
//! Still to come (the baselines issue): caching trained networks, the Table 3 optimization
//! ablations on the RKPM coefficients, and the eval tables; later MPM and SPH.

pub mod adam;
pub mod mlp;
pub mod model_file;
pub mod simplicits;

pub use adam::{Adam, AdamParams};
pub use mlp::{MLP_FORMAT_VERSION, Mlp, MlpShape, Tape};
pub use model_file::ModelFileError;
pub use simplicits::{
    SIMPLICITS_FORMAT_VERSION, SimplicitsError, SimplicitsField, SimplicitsParams, StepLosses,
    TrainedSimplicits, TrainingReport, ortho_loss, train_simplicits,
};
