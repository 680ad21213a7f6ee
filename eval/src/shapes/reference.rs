//! The FEM reference of one shape: how it is meshed (a lattice refined until the volume is
//! within a tolerance, or the finest lattice allowed) and what the mesh kept.

use fem_ref::{
    ElementOrder, InteriorFeature, LatticeMesherError, LatticeMesherParams, LatticeMesherReport,
    LatticeRefinement, TetMesh, VolumeTarget, tetrahedralize, tetrahedralize_to_volume,
};
use hyperelastic::HessianTangent;
use optimize::NewtonParams;
use rkpm_core::TriangleMesh;
use serde::{Deserialize, Serialize};

use crate::EvalError;
use crate::shapes::boundary::ShapeBoundary;
use freeform::scene::{Region, SceneSpec};

/// How the FEM reference of a shape is meshed.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct ShapeFemParams {
    /// P1 or P2 (default P2: ν = 0.45 locks P1).
    pub order: ElementOrder,
    /// Lattice cells across L of the first try (default 10).
    pub first_cells_across: usize,
    /// Finest lattice tried (default 16). A shape whose volume is still off by more than
    /// `volume_tolerance` there is meshed at this lattice anyway, and its volume error is
    /// reported. Coarse on purpose: on 2 cores a P2 run of 50 steps takes 27-73 s on the
    /// bunny at 15 cells (26k DOFs, 2-4 Newton iterations per step), which over 72 runs is
    /// an hour.
    pub max_cells_across: usize,
    /// Accepted |relative volume error| of the tetrahedral mesh (default 0.05).
    pub volume_tolerance: f64,
    /// The references' Newton options (default [`NewtonParams::default`]: a fresh
    /// factorization every iteration, tolerance 1e-6), as [`ShapeFemParams::factor_reuse`]
    /// leaves them for a condition ([`ShapeFemParams::newton_for`]). Part of each cached
    /// trajectory's key.
    #[serde(default)]
    pub newton: NewtonParams,
    /// Uniform lattices (default) or lattices graded near the surface
    /// ([`ShapeFemParams::graded`]).
    #[serde(default)]
    pub refinement: LatticeRefinement,
    /// The element tangent of Newton's Hessian (default
    /// [`HessianTangent::ProjectedPsd`], the first tables' setting;
    /// [`HessianTangent::ExactWhenDefinite`] projects only when the exact Hessian fails to
    /// factor). Part of each cached trajectory's key.
    #[serde(default = "projected_tangent")]
    pub tangent: HessianTangent,
    /// Mesh Fix side's reference (and its convergence check) on the same lattice shifted so
    /// that a vertex plane is the clamped slab's face (default false: every condition on the
    /// shape's one mesh, the first tables' setting; [`ShapeFemParams::graded`] sets it). On the unshifted lattice the nodes with `x ≤ x_min + 0.05 L` fill
    /// the slab only to the last node plane inside it, which moves with the lattice: at 16
    /// cells across the clamped depth is 0.031 L, at 24 cells 0.042 L, against the 0.05 L the
    /// reduced methods hold.
    #[serde(default)]
    pub clamp_on_lattice_plane: bool,
    /// Mesh Pull boundary's reference (and its convergence check) on a lattice whose vertex
    /// planes are both pulled slabs' faces: shifted to put one face on a plane, its spacing
    /// the faces' distance over the nearest whole number of `L / cells` cells (default false,
    /// the first tables' setting; [`ShapeFemParams::graded`] sets it). The unshifted lattice
    /// pulls each end only to its last node plane inside the slab, as with Fix side above.
    #[serde(default)]
    pub pull_slabs_on_lattice_planes: bool,
    /// Mesh Pull farthest's reference (and its convergence check) on the graded lattice
    /// refined to its finest level wherever a tetrahedron meets the sphere that bounds a
    /// pulled patch ([`fem_ref::LatticeMesherParams::refine_across`]; default false, the
    /// first tables' setting; [`ShapeFemParams::graded`] sets it). The FEM pulls the nodes
    /// inside the patch, so on the shape's lattice the pulled region matches the patch only to
    /// a cell, and moves with the lattice: the finer reference pulls another node set.
    #[serde(default)]
    pub refine_pulled_patch_edges: bool,
    /// Mesh Pull boundary's reference (and its convergence check) on the graded lattice
    /// refined to its finest level along both pulled slabs' faces (default false, the first
    /// tables' setting; [`ShapeFemParams::graded`] sets it): where a face meets the surface,
    /// the held nodes end in an edge whose stress is singular.
    #[serde(default)]
    pub refine_pulled_slab_faces: bool,
    /// Which conditions' references carry the Cholesky factor across Newton iterations and
    /// steps ([`ShapeFemParams::newton_for`]; default [`ReferenceFactorReuse::Never`], the
    /// first tables' setting). Part of each cached trajectory's key.
    #[serde(default)]
    pub factor_reuse: ReferenceFactorReuse,
    /// How deep a reference's step whose Newton solve does not converge within
    /// `newton.max_iterations` is split into backward-Euler half steps
    /// ([`fem_ref::FemParams::failed_step_halvings`]; default 0, the first tables' setting:
    /// the step stays unconverged and the row is not scored; [`ShapeFemParams::graded`]
    /// sets 2). Cached references that converged whole stay valid.
    #[serde(default)]
    pub failed_step_halvings: usize,
}

/// Which conditions' FEM references reuse the Cholesky factor
/// ([`fem_ref::reusing_reference_newton`]'s chord steps while each is at most half the last,
/// to its tolerance of 1e-8 instead of 1e-6).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ReferenceFactorReuse {
    /// A fresh factorization every Newton iteration (default, the first tables' setting).
    #[default]
    #[serde(alias = "Never")]
    Never,
    /// Pull farthest's and Pull boundary's references (and their convergence checks); Fix
    /// side's, where the soft shapes sag far and Newton needs many iterations, fresh.
    #[serde(alias = "Pulls")]
    Pulls,
    /// The Pulls' references, and Fix side's of a stiff shape: Young's modulus at least
    /// [`STIFF_YOUNGS_MODULUS`] (the manufactured class, 10⁸ Pa), where the shape's own weight
    /// strains it by about ρ g L / E ≈ 10⁻⁴ (ρ = 1000 kg/m³, L = 1 m after normalization) and
    /// each step is nearly linear. A soft shape's Fix side (10⁵ Pa, strain ≈ 0.1) stays fresh.
    #[serde(alias = "PullsAndStiffFixSide")]
    PullsAndStiffFixSide,
    /// Every condition's.
    #[serde(alias = "Every")]
    Every,
}

/// The least Young's modulus (Pa) whose Fix side reference
/// [`ReferenceFactorReuse::PullsAndStiffFixSide`] reuses the factor for: between the
/// catalogue's organic (10⁵ Pa) and manufactured (10⁸ Pa) classes, above the measured
/// crossover (reused against fresh on Fix side, 53k–65k DOFs: the koala 1.4× slower at 10⁵ Pa,
/// 1.6× faster at 10⁶, 4.4× at 10⁷; the skull about even at 10⁶; README).
pub const STIFF_YOUNGS_MODULUS: f64 = 1e7;

impl ReferenceFactorReuse {
    /// Whether `boundary`'s reference (and its convergence check) on a shape of Young's
    /// modulus `youngs_modulus` (Pa) reuses the factor.
    pub fn covers(self, boundary: ShapeBoundary, youngs_modulus: f64) -> bool {
        match self {
            ReferenceFactorReuse::Never => false,
            ReferenceFactorReuse::Pulls => boundary != ShapeBoundary::FixSide,
            ReferenceFactorReuse::PullsAndStiffFixSide => {
                boundary != ShapeBoundary::FixSide || youngs_modulus >= STIFF_YOUNGS_MODULUS
            }
            ReferenceFactorReuse::Every => true,
        }
    }
}

/// The faces of a condition's held slabs that its reference's lattice puts on vertex planes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SlabFaces {
    /// The axis the slabs are cut across (0 = x).
    pub axis: usize,
    /// One face's coordinate on `axis` (m): a vertex plane passes through it exactly.
    pub first: f64,
    /// The other slab's face, when there are two (m): on a vertex plane up to round-off, the
    /// spacing adjusted to divide the faces' distance.
    pub second: Option<f64>,
}

/// The references' tangent before it could be chosen (for settings stored without one).
fn projected_tangent() -> HessianTangent {
    HessianTangent::ProjectedPsd
}

/// How one condition's reference lattice departs from the shape's: slab faces on vertex planes
/// and region edges refined to the finest level. Plain (the shape's one mesh) when neither.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ConditionLattice {
    /// Held or pulled slabs' faces on vertex planes ([`ShapeFemParams::slab_faces`]).
    pub faces: Option<SlabFaces>,
    /// Surfaces inside the solid refined to the finest level
    /// ([`ShapeFemParams::refined_edges`]).
    pub refine_across: Vec<InteriorFeature>,
}

impl ConditionLattice {
    /// Whether the condition runs on the shape's one mesh.
    pub fn is_plain(&self) -> bool {
        self.faces.is_none() && self.refine_across.is_empty()
    }
}

impl ShapeFemParams {
    /// References on graded lattices: 16 cells across refined up to two halvings near the
    /// surface where the signed distance is not linear (tolerance 0.05), the base lattice ×1.5 up
    /// to 36 until the volume is within 3%; Newton up to 60 iterations a step with the exact
    /// element tangent, projected only where the exact Hessian fails to factor; Fix side clamped
    /// and Pull boundary's slabs pulled on lattice planes
    /// ([`ShapeFemParams::clamp_on_lattice_plane`],
    /// [`ShapeFemParams::pull_slabs_on_lattice_planes`]); both Pulls' region edges refined
    /// ([`ShapeFemParams::refine_pulled_patch_edges`],
    /// [`ShapeFemParams::refine_pulled_slab_faces`]); the Cholesky factor carried across
    /// iterations and steps for the Pulls and the stiff shapes' Fix side
    /// ([`ReferenceFactorReuse::PullsAndStiffFixSide`]). Each choice and its measurements:
    /// `results/RESULTS.md` ("The graded references").
    pub fn graded() -> Self {
        ShapeFemParams {
            first_cells_across: 16,
            max_cells_across: 36,
            volume_tolerance: 0.03,
            refinement: LatticeRefinement::Graded {
                max_halvings: 2,
                linearity_tolerance: 0.05,
            },
            newton: NewtonParams {
                max_iterations: 60,
                ..NewtonParams::default()
            },
            tangent: HessianTangent::ExactWhenDefinite,
            clamp_on_lattice_plane: true,
            pull_slabs_on_lattice_planes: true,
            refine_pulled_patch_edges: true,
            refine_pulled_slab_faces: true,
            factor_reuse: ReferenceFactorReuse::PullsAndStiffFixSide,
            failed_step_halvings: 2,
            ..ShapeFemParams::default()
        }
    }

    /// The volume ladder from a lattice of `first_cells_across`: ×1.5 up to
    /// `max_cells_across` (or `first_cells_across` when that is finer) until the volume is
    /// within `volume_tolerance`.
    pub fn volume_target(&self, first_cells_across: usize) -> VolumeTarget {
        VolumeTarget {
            max_relative_error: self.volume_tolerance,
            max_cells_across: self.max_cells_across.max(first_cells_across),
            growth: 1.5,
        }
    }

    /// The mesher options at `cells_across`.
    pub fn lattice(&self, cells_across: usize) -> LatticeMesherParams {
        LatticeMesherParams {
            cells_across,
            refinement: self.refinement,
            ..LatticeMesherParams::default()
        }
    }

    /// The slab faces `boundary`'s reference puts on lattice vertex planes in `scene` (its
    /// scene on the shape): with [`ShapeFemParams::clamp_on_lattice_plane`], Fix side's
    /// clamped face `x = x_min + 0.05 L`; with
    /// [`ShapeFemParams::pull_slabs_on_lattice_planes`], Pull boundary's two faces
    /// `x_a = min + 0.05 L` and `x_a = max − 0.05 L`; otherwise none, and the condition shares
    /// the shape's mesh.
    pub fn slab_faces(&self, boundary: ShapeBoundary, scene: &SceneSpec) -> Option<SlabFaces> {
        match (boundary, &scene.constraints[..]) {
            (ShapeBoundary::FixSide, [clamp]) if self.clamp_on_lattice_plane => {
                match clamp.region {
                    Region::Below { axis, value } => Some(SlabFaces {
                        axis,
                        first: value,
                        second: None,
                    }),
                    _ => None,
                }
            }
            (ShapeBoundary::PullBoundary, [low, high]) if self.pull_slabs_on_lattice_planes => {
                match (&low.region, &high.region) {
                    (
                        &Region::Below { axis, value: first },
                        &Region::Above {
                            axis: high_axis,
                            value: second,
                        },
                    ) if axis == high_axis && first < second => Some(SlabFaces {
                        axis,
                        first,
                        second: Some(second),
                    }),
                    _ => None,
                }
            }
            _ => None,
        }
    }

    /// The region edges `boundary`'s reference refines across in `scene` on a graded
    /// lattice: with [`ShapeFemParams::refine_pulled_patch_edges`], the sphere of every ball
    /// Pull farthest pulls; with [`ShapeFemParams::refine_pulled_slab_faces`], the face of
    /// both slabs Pull boundary pulls; otherwise none.
    pub fn refined_edges(
        &self,
        boundary: ShapeBoundary,
        scene: &SceneSpec,
    ) -> Vec<InteriorFeature> {
        if !self.refines_region_edges(boundary) {
            return Vec::new();
        }
        scene
            .constraints
            .iter()
            .map(|c| match c.region {
                Region::Ball { center, radius } => InteriorFeature::Sphere { center, radius },
                Region::Below { axis, value } | Region::Above { axis, value } => {
                    InteriorFeature::Plane { axis, value }
                }
            })
            .collect()
    }

    /// The Newton options of `boundary`'s reference and its convergence check on a shape of
    /// Young's modulus `youngs_modulus` (Pa): [`ShapeFemParams::newton`], with
    /// [`fem_ref::reusing_reference_newton`]'s factor reuse and tolerance where
    /// [`ShapeFemParams::factor_reuse`] covers them ([`ReferenceFactorReuse::covers`]; the
    /// iteration cap and line search stay `newton`'s).
    pub fn newton_for(&self, boundary: ShapeBoundary, youngs_modulus: f64) -> NewtonParams {
        if self.factor_reuse.covers(boundary, youngs_modulus) {
            let reusing = fem_ref::reusing_reference_newton();
            NewtonParams {
                tolerance: reusing.tolerance,
                hessian_reuse: reusing.hessian_reuse,
                ..self.newton
            }
        } else {
            self.newton
        }
    }

    /// Whether `boundary`'s reference lattice is refined along its regions' edges: on graded
    /// lattices only, Pull farthest's with [`ShapeFemParams::refine_pulled_patch_edges`],
    /// Pull boundary's with [`ShapeFemParams::refine_pulled_slab_faces`], never Fix side's.
    pub fn refines_region_edges(&self, boundary: ShapeBoundary) -> bool {
        matches!(self.refinement, LatticeRefinement::Graded { .. })
            && match boundary {
                ShapeBoundary::FixSide => false,
                ShapeBoundary::PullFarthest => self.refine_pulled_patch_edges,
                ShapeBoundary::PullBoundary => self.refine_pulled_slab_faces,
            }
    }

    /// `boundary`'s own lattice in `scene`: [`ShapeFemParams::slab_faces`] and
    /// [`ShapeFemParams::refined_edges`].
    pub fn condition_lattice(
        &self,
        boundary: ShapeBoundary,
        scene: &SceneSpec,
    ) -> ConditionLattice {
        ConditionLattice {
            faces: self.slab_faces(boundary, scene),
            refine_across: self.refined_edges(boundary, scene),
        }
    }

    /// [`ShapeFemParams::lattice`] at `cells_across` along `length` (the surface's largest
    /// side, m), refined across `condition.refine_across`, with `condition.faces` on vertex
    /// planes: a plane through `first`, and with a `second` face the spacing `d / k`, `d` the
    /// faces' distance and `k ≥ 1` the whole number of cells nearest `d / (length / cells_across)` (the lattice then differs from the
    /// unaligned one's by under half a cell over `d`).
    pub fn lattice_through(
        &self,
        cells_across: usize,
        length: f64,
        condition: &ConditionLattice,
    ) -> LatticeMesherParams {
        let mut params = self.lattice(cells_across);
        params.refine_across.clone_from(&condition.refine_across);
        if let Some(faces) = condition.faces {
            params.vertex_planes[faces.axis] = Some(faces.first);
            if let Some(second) = faces.second {
                let distance = (second - faces.first).abs();
                let cells = (distance * cells_across as f64 / length).round().max(1.0);
                params.cell_size = Some(distance / cells);
            }
        }
        params
    }
}

impl Default for ShapeFemParams {
    fn default() -> Self {
        ShapeFemParams {
            order: ElementOrder::Quadratic,
            first_cells_across: 10,
            max_cells_across: 16,
            volume_tolerance: 0.05,
            newton: NewtonParams::default(),
            refinement: LatticeRefinement::Uniform,
            tangent: HessianTangent::ProjectedPsd,
            clamp_on_lattice_plane: false,
            pull_slabs_on_lattice_planes: false,
            refine_pulled_patch_edges: false,
            refine_pulled_slab_faces: false,
            factor_reuse: ReferenceFactorReuse::Never,
            failed_step_halvings: 0,
        }
    }
}

/// The tetrahedral mesh of the FEM reference.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct FemMeshSummary {
    /// Lattice cells across L.
    pub cells_across: usize,
    /// Tetrahedral mesh vertices (where methods are scored).
    pub vertices: usize,
    /// Tetrahedra.
    pub tets: usize,
    /// (mesh volume − surface volume) / surface volume, after dropping the islands.
    pub relative_volume_error: f64,
    /// Pieces of the lattice mesh not face-connected to the largest one, dropped.
    pub dropped_pieces: usize,
    /// Their volume over the surface's.
    pub dropped_volume_fraction: f64,
}

impl FemMeshSummary {
    /// The largest face-connected piece of the lattice mesh `mesh` (made by the mesher that
    /// wrote `report`, of a surface whose largest side is `length`) and its summary. The
    /// dropped islands count against the volume: `relative_volume_error` is that of the piece.
    pub fn largest_piece(
        mesh: &TetMesh,
        report: &LatticeMesherReport,
        length: f64,
    ) -> (TetMesh, FemMeshSummary) {
        let pieces = mesh.face_connected_components().len();
        let (piece, dropped) = mesh.largest_component();
        let summary = FemMeshSummary {
            cells_across: (length / report.cell_size).round() as usize,
            vertices: piece.vertices().len(),
            tets: piece.tets().len(),
            relative_volume_error: (piece.volume() - report.surface_volume) / report.surface_volume,
            dropped_pieces: pieces.saturating_sub(1),
            dropped_volume_fraction: dropped / report.surface_volume,
        };
        (piece, summary)
    }
}

/// The FEM mesh of `surface` (largest bounding-box side `length`) on `condition`'s lattice
/// ([`ShapeFemParams::lattice_through`]): the largest piece of the lattice at `cells_across`
/// and, while that piece's volume is off the surface's by more than
/// [`ShapeFemParams::volume_tolerance`], of the lattice at 1.5× the cells, up to
/// [`ShapeFemParams::max_cells_across`] ([`mesh_for_fem`]'s ladder for the shape's mesh: a
/// shifted or stretched lattice cuts the surface elsewhere, which can cost a thin shape the
/// last percent of its volume). Returns the piece, its summary and the cells across it was
/// made at.
///
/// # Errors
/// [`EvalError::FemMesh`] when the surface cannot be tetrahedralized.
pub fn mesh_through(
    surface: &TriangleMesh,
    params: &ShapeFemParams,
    cells_across: usize,
    length: f64,
    condition: &ConditionLattice,
) -> Result<(TetMesh, FemMeshSummary, usize), EvalError> {
    let target = params.volume_target(cells_across);
    let mut cells = cells_across;
    loop {
        let lattice = params.lattice_through(cells, length, condition);
        let (mesh, report) = tetrahedralize(surface, &lattice).map_err(EvalError::FemMesh)?;
        let (piece, summary) = FemMeshSummary::largest_piece(&mesh, &report, length);
        match target.next_cells_across(cells) {
            Some(next) if summary.relative_volume_error.abs() > target.max_relative_error => {
                cells = next;
            }
            _ => return Ok((piece, summary, cells)),
        }
    }
}

/// The FEM mesh of `surface`: the first lattice from `first_cells_across` up (×1.5) whose
/// volume is within the tolerance, else the `max_cells_across` lattice as it is (islands
/// included; the caller drops them).
///
/// # Errors
/// [`EvalError::FemMesh`] when the surface cannot be tetrahedralized.
pub fn mesh_for_fem(
    surface: &TriangleMesh,
    params: &ShapeFemParams,
) -> Result<(TetMesh, LatticeMesherReport), EvalError> {
    let lattice = params.lattice(params.first_cells_across);
    let target = params.volume_target(params.first_cells_across);
    match tetrahedralize_to_volume(surface, &lattice, &target) {
        Ok(mesh) => Ok(mesh),
        Err(LatticeMesherError::VolumeNotReached { cells_across, .. }) => {
            tetrahedralize(surface, &params.lattice(cells_across))
        }
        Err(e) => Err(e),
    }
    .map_err(EvalError::FemMesh)
}

#[cfg(test)]
mod tests {
    use nalgebra::{Rotation3, Vector3};

    use super::*;

    /// A 1 × 0.5 × `thickness` plate tilted off the lattice planes.
    fn tilted_plate(thickness: f64) -> TriangleMesh {
        let box_ = TriangleMesh::cuboid(Vector3::zeros(), Vector3::new(1.0, 0.5, thickness));
        let rotation = Rotation3::new(Vector3::new(0.2, -0.3, 0.1));
        TriangleMesh::new(
            box_.vertices().iter().map(|p| rotation * p).collect(),
            box_.triangles().to_vec(),
        )
        .unwrap()
    }

    #[test]
    fn factor_reuse_changes_only_the_covered_conditions_tolerance_and_reuse_not_the_cap() {
        use optimize::HessianReuse;
        let reusing = fem_ref::reusing_reference_newton();
        let mut params = ShapeFemParams::graded();
        // Which of Fix side, Pull farthest and Pull boundary reuse, on an organic (10⁵ Pa) and
        // a manufactured (10⁸ Pa) shape.
        for (reuse, soft, stiff) in [
            (
                ReferenceFactorReuse::Never,
                [false, false, false],
                [false, false, false],
            ),
            (
                ReferenceFactorReuse::Pulls,
                [false, true, true],
                [false, true, true],
            ),
            (
                ReferenceFactorReuse::PullsAndStiffFixSide,
                [false, true, true],
                [true, true, true],
            ),
            (
                ReferenceFactorReuse::Every,
                [true, true, true],
                [true, true, true],
            ),
        ] {
            params.factor_reuse = reuse;
            for (youngs_modulus, reused) in [(1e5, soft), (1e8, stiff)] {
                for (boundary, reused) in ShapeBoundary::ALL.into_iter().zip(reused) {
                    let newton = params.newton_for(boundary, youngs_modulus);
                    let case = format!("{reuse:?} {boundary:?} E = {youngs_modulus:e}");
                    assert_eq!(reuse.covers(boundary, youngs_modulus), reused, "{case}");
                    assert_eq!(newton.max_iterations, 60, "{case}");
                    if reused {
                        assert_eq!(newton.tolerance, reusing.tolerance, "{case}");
                        assert_eq!(newton.hessian_reuse, reusing.hessian_reuse, "{case}");
                        assert_ne!(newton.hessian_reuse, HessianReuse::Never, "{case}");
                    } else {
                        assert_eq!(newton, params.newton, "{case}");
                    }
                }
            }
        }
    }

    #[test]
    fn a_rows_own_mesh_climbs_the_lattice_ladder_until_its_volume_is_within_tolerance() {
        // A tilted 1 × 0.5 × 0.1 plate, Fix side's face on a vertex plane: at 6 cells across the
        // uniform lattice loses more than 3% of the volume; the ladder refines until it keeps it,
        // and stops at the largest lattice allowed (its error then reported, not hidden).
        let plate = tilted_plate(0.1);
        let bbox = plate.bounding_box();
        let condition = ConditionLattice {
            faces: Some(SlabFaces {
                axis: 0,
                first: bbox.min.x + 0.05 * bbox.largest_side(),
                second: None,
            }),
            refine_across: Vec::new(),
        };
        let params = ShapeFemParams {
            volume_tolerance: 0.03,
            max_cells_across: 36,
            ..ShapeFemParams::default()
        };
        let length = bbox.largest_side();
        let capped = ShapeFemParams {
            max_cells_across: 6,
            ..params
        };
        let (mesh, first, cells) = mesh_through(&plate, &capped, 6, length, &condition).unwrap();
        assert_eq!(cells, 6);
        assert_eq!(mesh.tets().len(), first.tets);
        assert!(first.relative_volume_error.abs() > 0.03, "{first:?}");
        let (_, summary, cells) = mesh_through(&plate, &params, 6, length, &condition).unwrap();
        assert!(cells > 6 && cells <= 36, "{cells}");
        assert!(summary.relative_volume_error.abs() <= 0.03, "{summary:?}");
    }

    #[test]
    fn graded_references_keep_a_thin_plate_the_default_lattice_loses() {
        // 1 × 0.5 × 0.03, tilted off the lattice planes: thinner than the default's 16-cell
        // spacing.
        let plate = tilted_plate(0.03);
        let lost = |params: &ShapeFemParams| match mesh_for_fem(&plate, params) {
            Ok((_, report)) => report.relative_volume_error,
            Err(EvalError::FemMesh(LatticeMesherError::NothingInside { .. })) => -1.0,
            Err(e) => panic!("{e}"),
        };
        let uniform = lost(&ShapeFemParams::default());
        let graded = lost(&ShapeFemParams::graded());
        assert!(uniform < -0.05, "the uniform lattice keeps {uniform:+.3}");
        assert!(
            graded.abs() <= 0.03,
            "the graded lattice keeps {graded:+.3}"
        );
    }
}
