//! Where the elastic energy is integrated: the rules (every point, a random subset, an
//! optimized cubature, or the automatic choice between them), the cubature's training, and
//! the predicted cost the automatic choice weighs. The quadrature a model carries is
//! [`crate::model::elastic_quadrature`].

pub mod automatic_quadrature;
pub mod cubature;
pub mod elastic_cost;
pub mod rule;
