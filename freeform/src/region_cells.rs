//! Integration points whose cells a region's boundary cuts, split into one point per part.
//!
//! A weighted hold ([`crate::PinHold::Weighted`]) holds a region rigidly and lets the body
//! strain from its boundary on: the energy density jumps there, from zero inside to its
//! largest value (a clamp's root). A grid point's cell that the boundary cuts is integrated by
//! the point alone, so the whole cell counts as held or as free by where its centre lies: an
//! error of the order of one cell at the place of largest strain, which makes the result
//! depend on how the grid happens to fall on the boundary (a cantilever's static tip moved by
//! 2% between grids of 40 000 and 80 000 points). Splitting each cut cell into its part inside
//! and its part outside, each a point at its part's centroid with its part's volume, integrates
//! the jump where it is. The basis grid has the same cells: a weighted basis's free part is
//! its points outside every region, and an unsplit cut cell puts too much or too little material
//! in it, so the modes depend on how the basis grid falls on the boundary.
//! [`PinHold::simulation_points`] and [`PinHold::basis_points`] split both when the hold asks.
//!
//! ```text
//! cell of x_i: the cube of side ∛v_i centred at x_i, sampled by s³ sub-cells (s = 8)
//! parts:       the sub-cells grouped by the first region containing them (or none)
//! new points:  one per part, at the part's centroid, volume v_i · (sub-cells in it) / s³
//! ```

use std::borrow::Cow;

use hyperelastic::LameParameters;
use nalgebra::Vector3;
use rkpm_core::IntegrationPoints;

use crate::PinHold;
use crate::scene::{Region, SceneSpec};

/// Sub-cells per side a cut cell is sampled with (s).
pub const CELL_SPLIT_SUBDIVISIONS: usize = 8;

/// What [`split_cells_at_regions`] changed.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct CellSplitReport {
    /// Points whose cells a region's boundary cut.
    pub cut_cells: usize,
    /// Points added (each cut cell becomes two or more).
    pub added_points: usize,
}

/// `points` with every point whose cell (the cube of its volume centred at it) is cut by the
/// boundary of one of `regions` replaced by one point per part (inside each region it meets,
/// and outside all of them), at the part's centroid with the part's volume.
///
/// The total volume is kept to round-off; a point whose cell no boundary cuts is kept as it
/// is, in order, so points far from every region and their volumes are unchanged. A part's
/// point lies in the part: where a part's centroid does not (the outside of a ball), the part's
/// sub-cell nearest the centroid stands for it.
pub fn split_cells_at_regions(
    points: &IntegrationPoints,
    regions: &[Region],
) -> (IntegrationPoints, CellSplitReport) {
    let (split, _, report) = split_cells_at_regions_with_origins(points, regions);
    (split, report)
}

/// [`split_cells_at_regions`], also returning, for each new point, the index in `points` of
/// the point whose cell it is a part of (N' entries, non-decreasing): what carries a per-point
/// quantity, such as a material, over to the parts.
pub fn split_cells_at_regions_with_origins(
    points: &IntegrationPoints,
    regions: &[Region],
) -> (IntegrationPoints, Vec<usize>, CellSplitReport) {
    let mut positions = Vec::with_capacity(points.len());
    let mut volumes = Vec::with_capacity(points.len());
    let mut origins = Vec::with_capacity(points.len());
    let mut report = CellSplitReport::default();
    for (i, (x, &volume)) in points.positions().iter().zip(points.volumes()).enumerate() {
        let side = volume.cbrt();
        let parts = if regions.iter().any(|r| boundary_may_cut(r, x, side)) {
            cell_parts(regions, x, side)
        } else {
            Vec::new()
        };
        if parts.len() < 2 {
            positions.push(*x);
            volumes.push(volume);
            origins.push(i);
            continue;
        }
        report.cut_cells += 1;
        report.added_points += parts.len() - 1;
        let total = CELL_SPLIT_SUBDIVISIONS.pow(3) as f64;
        for part in parts {
            positions.push(part.position);
            volumes.push(volume * part.sub_cells as f64 / total);
            origins.push(i);
        }
    }
    let split = IntegrationPoints::new(positions, volumes)
        .expect("the parts of valid points are finite with positive volumes");
    (split, origins, report)
}

/// Whether the boundary of `region` may pass through the cube of side `side` centred at `x`.
fn boundary_may_cut(region: &Region, x: &Vector3<f64>, side: f64) -> bool {
    match *region {
        Region::Below { axis, value } | Region::Above { axis, value } => {
            (x[axis] - value).abs() < 0.5 * side
        }
        Region::Ball { center, radius } => {
            ((x - center).norm() - radius).abs() < 0.5 * 3f64.sqrt() * side
        }
    }
}

impl PinHold {
    /// The simulation's integration points for this hold: for [`PinHold::Weighted`] with
    /// `split_cut_cells`, `points` with each cell a constraint region's boundary cuts split
    /// into its held and free parts ([`split_cells_at_regions`]: the strain jumps at a weighted
    /// region's boundary, and an unsplit cut cell counts wholly as held or free); `points`
    /// unchanged otherwise (the penalty's pins are the points inside the regions, the paper's
    /// setting) and for a scene without constraints.
    pub fn simulation_points(
        &self,
        scene: &SceneSpec,
        points: IntegrationPoints,
    ) -> (IntegrationPoints, CellSplitReport) {
        match self.regions_splitting_cells(scene) {
            Some(regions) => split_cells_at_regions(&points, &regions),
            None => (points, CellSplitReport::default()),
        }
    }

    /// The basis grid for this hold, with its points' Lamé parameters (one per point): for
    /// [`PinHold::Weighted`] with `split_cut_cells`, `points` with their cut cells split as
    /// [`PinHold::simulation_points`] splits the simulation's, each part with its cell's
    /// `materials` (a weighted basis's free part, the points outside every region, then has the
    /// free material's exact volume, wherever the grid falls on the regions); `points` and
    /// `materials` unchanged otherwise, and when `materials` is not one per point (the basis
    /// builder then names the mismatch). [`PinHold::build_basis`] and
    /// [`crate::PressureSpace::build`] call it on the grid they are given.
    pub fn basis_points<'a>(
        &self,
        scene: &SceneSpec,
        points: &'a IntegrationPoints,
        materials: &'a [LameParameters],
    ) -> (Cow<'a, IntegrationPoints>, Cow<'a, [LameParameters]>) {
        let regions = self
            .regions_splitting_cells(scene)
            .filter(|_| materials.len() == points.len());
        let Some(regions) = regions else {
            return (Cow::Borrowed(points), Cow::Borrowed(materials));
        };
        let (split, origins, report) = split_cells_at_regions_with_origins(points, &regions);
        if report.cut_cells == 0 {
            return (Cow::Borrowed(points), Cow::Borrowed(materials));
        }
        let materials = origins.iter().map(|&i| materials[i]).collect();
        (Cow::Owned(split), Cow::Owned(materials))
    }

    /// The regions whose cut cells this hold splits: the scene's constraint regions for a
    /// weighted hold with `split_cut_cells` and at least one constraint, `None` otherwise.
    fn regions_splitting_cells(&self, scene: &SceneSpec) -> Option<Vec<Region>> {
        match self {
            PinHold::Weighted {
                split_cut_cells: true,
                ..
            } if !scene.constraints.is_empty() => {
                Some(scene.constraints.iter().map(|c| c.region.clone()).collect())
            }
            _ => None,
        }
    }
}

/// One part of a cut cell.
struct CellPart {
    /// The region containing it (`None`: outside every region).
    region: Option<usize>,
    position: Vector3<f64>,
    sub_cells: usize,
}

/// The parts of the cube of side `side` centred at `x`, by the first region containing each
/// sub-cell centre.
fn cell_parts(regions: &[Region], x: &Vector3<f64>, side: f64) -> Vec<CellPart> {
    let s = CELL_SPLIT_SUBDIVISIONS;
    let label = |p: &Vector3<f64>| regions.iter().position(|r| r.contains(p));
    let sub_cells: Vec<(Option<usize>, Vector3<f64>)> = (0..s * s * s)
        .map(|c| {
            let offset = |i: usize| ((i as f64 + 0.5) / s as f64 - 0.5) * side;
            let p = x + Vector3::new(offset(c / (s * s)), offset((c / s) % s), offset(c % s));
            (label(&p), p)
        })
        .collect();
    let mut parts: Vec<CellPart> = Vec::new();
    for &(region, p) in &sub_cells {
        match parts.iter_mut().find(|part| part.region == region) {
            Some(part) => {
                part.position += p;
                part.sub_cells += 1;
            }
            None => parts.push(CellPart {
                region,
                position: p,
                sub_cells: 1,
            }),
        }
    }
    for part in &mut parts {
        let centroid = part.position / part.sub_cells as f64;
        part.position = if label(&centroid) == part.region {
            centroid
        } else {
            sub_cells
                .iter()
                .filter(|(region, _)| *region == part.region)
                .map(|(_, p)| *p)
                .min_by(|a, b| (a - centroid).norm().total_cmp(&(b - centroid).norm()))
                .expect("a part has a sub-cell")
        };
    }
    parts
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{Constraint, Motion};
    use rkpm_core::sample_box_grid;

    /// The beam's clamp: x ≤ 0.5 m.
    const CLAMP: Region = Region::Below {
        axis: 0,
        value: 0.5,
    };

    fn beam(spacing: f64) -> IntegrationPoints {
        sample_box_grid(Vector3::zeros(), Vector3::new(5.0, 1.0, 1.0), spacing).unwrap()
    }

    fn held_volume(points: &IntegrationPoints, region: &Region) -> f64 {
        points
            .positions()
            .iter()
            .zip(points.volumes())
            .filter(|(p, _)| region.contains(p))
            .map(|(_, v)| v)
            .sum()
    }

    #[test]
    fn a_plane_through_the_cells_holds_its_exact_volume_once_they_are_split() {
        // 126 × 25 × 25 cells: x = 0.5 cuts the thirteenth layer at 60% of its width.
        let points = beam((5.0f64 / 80_000.0).cbrt());
        let before = held_volume(&points, &CLAMP);
        assert!((before - 0.5).abs() > 0.01, "{before}");
        let (split, report) = split_cells_at_regions(&points, &[CLAMP]);
        assert_eq!(report.cut_cells, 25 * 25);
        assert_eq!(report.added_points, 25 * 25);
        let after = held_volume(&split, &CLAMP);
        // Sub-cells resolve the cut to 1/8 of a cell width (0.005 m of the 1 m² section).
        assert!((after - 0.5).abs() < 0.005, "held volume {after}");
        let total: f64 = split.volumes().iter().sum();
        assert!((total - 5.0).abs() < 1e-9, "{total}");
    }

    #[test]
    fn cells_a_plane_passes_between_are_kept_as_they_are() {
        // 100 × 20 × 20 cells: x = 0.5 lies on the faces between the tenth and eleventh layers.
        let points = beam(0.05);
        let (split, report) = split_cells_at_regions(&points, &[CLAMP]);
        assert_eq!(report, CellSplitReport::default());
        assert_eq!(split, points);
    }

    #[test]
    fn a_ball_through_the_cells_holds_nearly_its_exact_volume_once_they_are_split() {
        let points = beam(0.1);
        let ball = Region::Ball {
            center: Vector3::new(2.5, 0.5, 0.5),
            radius: 0.33,
        };
        let (split, report) = split_cells_at_regions(&points, std::slice::from_ref(&ball));
        assert!(report.cut_cells > 0);
        let exact = 4.0 / 3.0 * std::f64::consts::PI * 0.33f64.powi(3);
        let before = held_volume(&points, &ball);
        let after = held_volume(&split, &ball);
        assert!(
            (after - exact).abs() < 0.25 * (before - exact).abs(),
            "ball volume {exact}: {before} unsplit, {after} split"
        );
        let total: f64 = split.volumes().iter().sum();
        assert!((total - 5.0).abs() < 1e-9, "{total}");
    }

    #[test]
    fn a_split_basis_grid_gives_the_free_part_its_exact_volume_and_each_part_its_cells_material() {
        // 126 × 25 × 25 cells: the clamp's plane x = 0.5 cuts the thirteenth layer.
        let points = beam((5.0f64 / 80_000.0).cbrt());
        let side = points.volumes()[0].cbrt();
        // Point i's material has μ = i + 1: a part's material names the cell it came from.
        let materials: Vec<LameParameters> = (0..points.len())
            .map(|i| LameParameters::new(1.0, i as f64 + 1.0).unwrap())
            .collect();
        let clamp = SceneSpec {
            constraints: vec![Constraint {
                region: CLAMP,
                motion: Motion::Rest,
            }],
            ..SceneSpec::default()
        };
        let free_volume = |points: &IntegrationPoints| {
            let all: f64 = points.volumes().iter().sum();
            all - held_volume(points, &CLAMP)
        };
        assert!((free_volume(&points) - 4.5).abs() > 0.01);
        let hold = PinHold::Weighted {
            transition_fraction: 1.0,
            distance: crate::WeightDistance::HeldMaterial,
            split_cut_cells: true,
        };
        let (split, split_materials) = hold.basis_points(&clamp, &points, &materials);
        assert_eq!(split.len(), points.len() + 625);
        assert_eq!(split_materials.len(), split.len());
        assert!(
            (free_volume(&split) - 4.5).abs() < 0.005,
            "free volume {}",
            free_volume(&split)
        );
        for (x, lame) in split.positions().iter().zip(split_materials.iter()) {
            let cell = points.positions()[lame.mu() as usize - 1];
            assert!(
                (x - cell).amax() <= 0.5 * side,
                "{x} is not in the cell of {cell}"
            );
        }
        // The default hold leaves the grid and its materials as they are, and so does a split
        // given too few materials (the basis builder names the mismatch).
        let (kept, kept_materials) = PinHold::WEIGHTED.basis_points(&clamp, &points, &materials);
        assert!(matches!(kept, Cow::Borrowed(_)) && matches!(kept_materials, Cow::Borrowed(_)));
        let (kept, kept_materials) = hold.basis_points(&clamp, &points, &materials[..10]);
        assert_eq!((kept.len(), kept_materials.len()), (points.len(), 10));
    }

    #[test]
    fn only_a_weighted_hold_asked_to_splits_the_cells_its_regions_cut() {
        // 126 × 25 × 25 cells: the clamp's plane x = 0.5 cuts one layer of 625.
        let spacing = (5.0f64 / 80_000.0).cbrt();
        let points =
            sample_box_grid(Vector3::zeros(), Vector3::new(5.0, 1.0, 1.0), spacing).unwrap();
        let clamp = SceneSpec {
            constraints: vec![Constraint {
                region: CLAMP,
                motion: Motion::Rest,
            }],
            ..SceneSpec::default()
        };
        #[derive(serde::Deserialize)]
        struct File {
            pins: PinHold,
        }
        let file: File = toml::from_str(
            "pins = { weighted = { transition_fraction = 1.0, split_cut_cells = true } }",
        )
        .unwrap();
        let (split, report) = file.pins.simulation_points(&clamp, points.clone());
        assert_eq!(report.cut_cells, 625);
        assert_eq!(split.len(), points.len() + 625);
        let unconstrained = SceneSpec::default();
        assert_eq!(
            file.pins
                .simulation_points(&unconstrained, points.clone())
                .0,
            points
        );
        for hold in [
            PinHold::WEIGHTED,
            PinHold::Penalty,
            PinHold::Exact { inset: 0.05 },
        ] {
            let (kept, report) = hold.simulation_points(&clamp, points.clone());
            assert_eq!(kept, points, "{hold:?}");
            assert_eq!(report, CellSplitReport::default());
        }
    }
}
