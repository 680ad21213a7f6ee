//! `freeform mesh`: tetrahedralize a surface.

use std::path::Path;

use anyhow::Result;
use artifact::write_atomically;
use fem_ref::{
    ElementOrder, FemMesh, LatticeMesherParams, LatticeRefinement, VolumeTarget, tetrahedralize,
    tetrahedralize_to_volume,
};
use freeform::frames::unstructured_grid_vtk;
use rkpm_core::read_triangle_mesh;

/// What `freeform mesh` was asked for.
pub(crate) struct MeshOptions {
    /// Lattice cells across the largest side (the first try with a volume target).
    pub cells: usize,
    /// Refine (×1.5, up to 128 cells) until the volume is within this fraction.
    pub volume_target: Option<f64>,
    /// Halvings of a lattice graded near the surface (none: uniform).
    pub graded: Option<usize>,
    /// Keep the file's units instead of scaling the largest side to 1.
    pub keep_units: bool,
}

/// Meshes `path` and writes the tet mesh as VTK under `out`.
pub(crate) fn run(
    path: &Path,
    &MeshOptions {
        cells,
        volume_target,
        graded,
        keep_units,
    }: &MeshOptions,
    out: &Path,
) -> Result<()> {
    let surface = read_triangle_mesh(path)?;
    let surface = if keep_units {
        surface
    } else {
        surface.normalized().0
    };
    let params = LatticeMesherParams {
        cells_across: cells,
        refinement: match graded {
            None => LatticeRefinement::Uniform,
            Some(max_halvings) => LatticeRefinement::Graded {
                max_halvings,
                linearity_tolerance: 0.05,
            },
        },
        ..Default::default()
    };
    let (tets, report) = match volume_target {
        None => tetrahedralize(&surface, &params)?,
        Some(max_relative_error) => tetrahedralize_to_volume(
            &surface,
            &params,
            &VolumeTarget {
                max_relative_error,
                ..Default::default()
            },
        )?,
    };
    let stem = path.file_stem().unwrap_or_default().to_string_lossy();
    let file = out.join(format!("{stem}.vtk"));
    write_atomically(
        &file,
        unstructured_grid_vtk(tets.vertices(), tets.vertices(), tets.tets(), 0.0, None).as_bytes(),
    )?;
    // What a FEM reference on it solves for: the P2 nodes (vertices and edge midpoints).
    let quadratic_nodes = FemMesh::new(tets, ElementOrder::Quadratic).nodes().len();
    let q = &report.quality;
    println!(
        "{}: {} cells across (h = {:.4}; shortest lattice edge {:.4}), {} vertices, {} \
         tetrahedra; P2: {} nodes, {} DOFs before any are held\n\
         volume {:.6} vs surface {:.6} ({:+.3}%)\n\
         dihedral angles {:.1}°–{:.1}°; boundary vertices {} ({} moved part way, {} kept off \
         the surface to protect quality)\n\
         {:.2} s; wrote {}",
        path.display(),
        (1.0 / report.cell_size * surface.bounding_box().largest_side()).round(),
        report.cell_size,
        report.shortest_lattice_edge,
        report.vertices,
        report.tets,
        quadratic_nodes,
        3 * quadratic_nodes,
        report.mesh_volume,
        report.surface_volume,
        100.0 * report.relative_volume_error,
        q.min_dihedral_degrees,
        q.max_dihedral_degrees,
        report.boundary_vertices,
        report.boundary_vertices_held_back[0],
        report.boundary_vertices_held_back[1],
        report.seconds,
        file.display()
    );
    Ok(())
}
