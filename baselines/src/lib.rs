//! Baselines the method is compared against (DESIGN 3.9).
//!
//! Built so far: [`Mlp`], the network of the Simplicits baseline (3 → 64 → 6 × 64 → m, ELU,
//! PyTorch-default initialization, f64, reverse-mode gradients, save/load), and [`Adam`].
//! Still to come (the baselines issue): the Simplicits losses and training loop as a
//! `reduced_sim::SkinningField`, and the Table 3 optimization ablations; later MPM and SPH.

pub mod adam;
pub mod mlp;

pub use adam::{Adam, AdamParams};
pub use mlp::{MLP_FORMAT_VERSION, Mlp, MlpFileError, MlpShape, Tape};
