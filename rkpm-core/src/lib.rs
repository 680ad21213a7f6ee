#![doc = include_str!("../README.md")]

pub mod aabb;
pub mod geometry_io;
pub mod grid_bins;
pub mod inside_test;
pub mod integration_points;
pub mod kernel_coverage;
pub mod kernels;
pub mod point_cloud;
pub mod reproduction;
pub mod shape_functions;
pub mod spatial_index;
pub mod surface_distance;
pub mod triangle_mesh;

pub use aabb::Aabb;
pub use geometry_io::{
    GeometryFormat, GeometryReadError, parse_point_cloud, parse_triangle_mesh, read_point_cloud,
    read_triangle_mesh,
};
pub use grid_bins::GridBins;
pub use inside_test::InsideTest;
pub use integration_points::{
    CloudVolume, GridSamplingParams, IntegrationPoints, PointCloudSamplingParams,
    RandomSamplingParams, SamplingError, sample_box_grid, sample_grid, sample_point_cloud,
    sample_random,
};
pub use kernel_coverage::{CoverageParams, CoverageReport, cover_queries};
pub use kernels::{
    KernelError, KernelParams, KernelWindow, Kernels, farthest_point_sampling, place_kernels,
};
pub use point_cloud::{GaussianSplatAttributes, PointCloud};
pub use reproduction::Reproduction;
pub use shape_functions::{
    ReproducingErrors, ShapeFunctionError, ShapeFunctionParams, ShapeFunctions,
    evaluate_shape_functions, shape_function_values_unshifted, singular_queries,
};
pub use spatial_index::SpatialIndex;
pub use surface_distance::{ClosestPoint, SurfaceDistance};
pub use triangle_mesh::{MeshValidationError, Normalization, TriangleMesh};
