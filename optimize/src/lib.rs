#![doc = include_str!("../README.md")]

pub mod newton;
pub mod nnls;
mod subset_cholesky;

pub use newton::{
    CarriedFactor, HessianReuse, NewtonError, NewtonObjective, NewtonParams, NewtonReport,
    NewtonStop, NewtonTimings, minimize, minimize_reusing,
};
pub use nnls::{
    NnlsError, NnlsFactor, NnlsParams, NnlsSolution, NnlsWarmStart, nnls, nnls_normal,
    nnls_normal_carried,
};
