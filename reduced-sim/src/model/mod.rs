//! The reduced model: the skinning field W(X) and the layout of the reduced coordinates z, the
//! deformation map x(X, z) it defines at any points, the model of the integration points (per
//! point G_i, volumes, materials) with its elastic energy, gradient and Hessian on the
//! quadrature it carries, and the projected dilatation that keeps the volumetric term from locking.

#[cfg(test)]
pub(crate) mod analytic_field;
pub mod deformation_map;
pub(crate) mod elastic_deformation;
pub mod elastic_energy;
pub mod elastic_quadrature;
pub mod projected_dilatation;
pub mod reduced_coordinates;
pub mod reduced_model;
pub mod skinning_field;
