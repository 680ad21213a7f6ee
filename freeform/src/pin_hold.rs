//! How the reduced simulator holds a scene's constrained regions: by the penalty, or
//! exactly, with a basis built for the regions: modes in the null space of the kernels on the
//! (inset) regions ([`PinHold::Exact`]), or modes multiplied by a smooth distance to the regions
//! ([`PinHold::Weighted`], no band and no parameter; see [`skin_eigen::build_weighted_basis`]).
//!
//! Holding a region exactly makes the basis's modes vanish on it; RKPM weights do not
//! interpolate, so weights that vanish on a region stay small over a band about one kernel
//! support beyond it, and a beam clamped that way is stiffer than the FEM's (beam Bend, m = 32,
//! compact B-spline kernels: tip 7% / 29% short of the FEM at t = 0.5 / 1.0 s). Holding the
//! region shrunk by an inset of about 1.5 kernel radii puts the band back inside the region
//! (tip within 0.4% / 2.0%); the points between the inset and the region's boundary are then
//! kept by the penalty and drift by about as much as it lets them (1.4 cm on the 5 m beam).
//!
//! The default is the penalty: across the pin sweep (`freeform-paper pins`: beam Bend and Twist,
//! m = 16 and 32, ν = 0.3 / 0.45 / 0.49) exact holding with that inset is more accurate in 2 of
//! the 10 scored runs and less accurate in 8, by 1.46× in geometric mean; on the Twist the band
//! lags the rotating end (up to 0.17 m at the FEM's held vertices). The weighted basis holds
//! every region point exactly, but it exposes the subspace's volumetric locking at ν ≥ 0.45
//! (too stiff) that the penalty's softness partly cancels: `freeform-paper convergence` measures
//! both against the FEM.

use std::collections::HashSet;

use hyperelastic::LameParameters;
use nalgebra::Vector3;
use reduced_sim::{PinnedRegion, Scene};
use rkpm_core::{IntegrationPoints, KernelWindow, ShapeFunctionParams};
use serde::{Deserialize, Serialize};
use skin_eigen::{
    BasisError, BasisParams, BasisReport, HeldRegionShape, KernelShapeFunctions,
    RegionConstraintParams, RegionWeight, RegionWeightError, SkinningBasis,
    build_basis_keeping_shape_functions, build_basis_with_regions, build_weighted_basis_sharing,
};

use crate::scene::{REGION_TOLERANCE, Region, SceneSpec, SceneSpecError};

/// [`PinHold::build_basis`] failed.
#[derive(Debug, thiserror::Error)]
pub enum HeldBasisError {
    /// The held regions could not be selected (an inset that empties a region, an invalid
    /// scene).
    #[error(transparent)]
    Scene(#[from] SceneSpecError),
    /// The basis builder failed.
    #[error("building the basis failed")]
    Basis(#[from] BasisError),
}

/// How the reduced simulator holds the scene's constrained regions.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum PinHold {
    /// The penalty of [`reduced_sim::PenaltyParams`] on every point of each region (the
    /// paper's setting; the hold of a basis built without regions, as
    /// [`crate::Simulation::new`] assumes).
    Penalty,
    /// Exactly ([`Scene::held`]) on each region shrunk by `inset` (m), the rest of the region
    /// by the penalty; the basis must be built for the shrunk regions
    /// ([`PinHold::basis_regions`] and [`skin_eigen::build_basis_with_regions`]).
    Exact {
        /// How far inside each region's boundary the held points start (m, ≥ 0).
        inset: f64,
    },
    /// Exactly ([`Scene::held`]) on the whole of each region, with a weighted basis
    /// ([`skin_eigen::build_weighted_basis`]): the modes are multiplied by a smooth distance to
    /// the regions, so they vanish on them with no penalty, no band and no parameter to tune.
    /// A scene without constraints gets the plain basis of [`PinHold::Penalty`]. The default
    /// ([`PinHold::WEIGHTED`]).
    Weighted {
        /// The transition length δ of the weight ([`skin_eigen::RegionWeight`]) as a fraction
        /// of the smallest side of the basis points' bounding box (default 1: the weight reaches
        /// 1 one object thickness from the regions).
        transition_fraction: f64,
        /// What the weight's distance to a region measures (default: the material it holds).
        #[serde(default, skip_serializing_if = "WeightDistance::is_default")]
        distance: WeightDistance,
        /// Whether each simulation and basis point whose cell a region's boundary cuts is split
        /// into its held and free parts ([`PinHold::simulation_points`],
        /// [`PinHold::basis_points`]; default false: the point counts wholly as held or as free
        /// by where it lies, so the result depends on how the grids fall on the boundary).
        #[serde(default, skip_serializing_if = "is_false")]
        split_cut_cells: bool,
    },
}

/// Whether `value` is false (serde's `skip_serializing_if` for an option off by default).
fn is_false(value: &bool) -> bool {
    !*value
}

/// What a weighted basis's weight measures the distance to ([`PinHold::Weighted`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum WeightDistance {
    /// The part of the body the region holds, sampled by the basis's points
    /// ([`skin_eigen::HeldMaterial`]) (default): the shape's distance beside held material,
    /// larger away from it, so a slab that holds a flank and an ear's tip damps the modes near
    /// those two, not over the whole head beside its plane. Where the region's boundary crosses
    /// the body everywhere (a beam's clamped end) it is the shape's distance.
    #[default]
    HeldMaterial,
    /// The region's shape: a half-space's plane, a ball's sphere. The weight damps the modes
    /// near the plane even where the body crosses it nowhere near held material.
    RegionShape,
}

impl WeightDistance {
    /// Whether this is the default, [`WeightDistance::HeldMaterial`].
    pub fn is_default(&self) -> bool {
        *self == WeightDistance::default()
    }
}

impl Default for PinHold {
    /// [`PinHold::WEIGHTED`]: the hold whose error falls monotonically in m with no parameter
    /// (`docs/defaults.md`).
    fn default() -> Self {
        PinHold::WEIGHTED
    }
}

impl PinHold {
    /// How it holds a region, in a few words for status lines: "held by a pin penalty",
    /// "held exactly inside an inset of 0.05 m", "held exactly by a weighted basis".
    pub fn summary(&self) -> String {
        match self {
            PinHold::Penalty => "held by a pin penalty".to_string(),
            PinHold::Exact { inset } => format!("held exactly inside an inset of {inset} m"),
            PinHold::Weighted { .. } => "held exactly by a weighted basis".to_string(),
        }
    }

    /// [`PinHold::Weighted`] with its defaults: a transition of one object thickness, distances
    /// to the held material.
    pub const WEIGHTED: PinHold = PinHold::Weighted {
        transition_fraction: 1.0,
        distance: WeightDistance::HeldMaterial,
        split_cut_cells: false,
    };

    /// The weight of [`PinHold::Weighted`] for `scene`'s constraint regions, in order, on an
    /// object whose basis points span `bounding_box_sides` (m); `None` for the other holds.
    ///
    /// # Errors
    /// [`RegionWeightError`] for a scene without constraints or a transition that is not
    /// positive.
    pub fn region_weight(
        &self,
        scene: &SceneSpec,
        bounding_box_sides: Vector3<f64>,
    ) -> Result<Option<RegionWeight>, RegionWeightError> {
        let PinHold::Weighted {
            transition_fraction,
            ..
        } = *self
        else {
            return Ok(None);
        };
        let regions = scene
            .constraints
            .iter()
            .map(|c| c.region.held_region_shape())
            .collect();
        RegionWeight::new(regions, transition_fraction * bounding_box_sides.min()).map(Some)
    }

    /// The basis options for this hold: `params` as given for the penalty; for exact holding,
    /// with compact kernels ([`KernelWindow::CubicBSpline`], zero beyond two radii), since the
    /// Gaussian's tails reach every kernel within four radii into the region and widen the band
    /// where the modes vanish.
    pub fn basis_params(&self, params: BasisParams) -> BasisParams {
        match self {
            PinHold::Penalty | PinHold::Weighted { .. } => params,
            PinHold::Exact { .. } => BasisParams {
                shape_functions: ShapeFunctionParams {
                    window: KernelWindow::CubicBSpline,
                    ..params.shape_functions
                },
                ..params
            },
        }
    }

    /// The reduced simulator's scene on integration points `points`: every constraint held by
    /// the penalty ([`SceneSpec::reduced_scene`]); or, for exact holding, each constraint's
    /// inset region in [`Scene::held`] and the band between the inset and the region's boundary
    /// kept by the penalty in [`Scene::pins`] (bands without points left out).
    ///
    /// # Errors
    /// As [`PinHold::held_scene`] and [`SceneSpec::select`]; a held region the inset left without
    /// integration points is [`SceneSpecError::Invalid`] naming the inset.
    pub fn reduced_scene(
        &self,
        scene: &SceneSpec,
        points: &[Vector3<f64>],
    ) -> Result<Scene, SceneSpecError> {
        let full = scene.reduced_scene(points)?;
        match self {
            PinHold::Penalty => return Ok(full),
            PinHold::Weighted { .. } => {
                return Ok(Scene {
                    held: full.pins,
                    pins: Vec::new(),
                    ..full
                });
            }
            PinHold::Exact { .. } => {}
        }
        let held = self
            .held_scene(scene)?
            .reduced_scene(points)
            .map_err(|e| self.explain(e))?
            .pins;
        let band = full
            .pins
            .into_iter()
            .zip(&held)
            .filter_map(|(region, inner)| {
                let held: HashSet<usize> = inner.points.iter().copied().collect();
                let points: Vec<usize> = region
                    .points
                    .into_iter()
                    .filter(|p| !held.contains(p))
                    .collect();
                (!points.is_empty()).then_some(PinnedRegion {
                    points,
                    target: region.target,
                })
            })
            .collect();
        Ok(Scene {
            pins: band,
            held,
            ..full
        })
    }

    /// The scene whose constrained regions the simulator holds: `scene` itself for the penalty,
    /// its regions shrunk by the inset for exact holding ([`Region::inset`]).
    ///
    /// # Errors
    /// [`SceneSpecError::Invalid`] for a negative or non-finite inset, or one that swallows a
    /// ball.
    pub fn held_scene(&self, scene: &SceneSpec) -> Result<SceneSpec, SceneSpecError> {
        match *self {
            PinHold::Penalty | PinHold::Weighted { .. } => Ok(scene.clone()),
            PinHold::Exact { inset } => {
                if !(inset >= 0.0 && inset.is_finite()) {
                    return Err(SceneSpecError::Invalid(format!(
                        "the exact pins' inset must be finite and non-negative, got {inset} m"
                    )));
                }
                let mut held = scene.clone();
                for (i, c) in held.constraints.iter_mut().enumerate() {
                    c.region = c.region.inset(inset).ok_or_else(|| {
                        SceneSpecError::Invalid(format!(
                            "constraints[{i}]: an inset of {inset} m leaves nothing of {:?}",
                            c.region
                        ))
                    })?;
                }
                Ok(held)
            }
        }
    }

    /// For exact holding: the rest points (m) of `point_sets` in each held region, the regions
    /// [`skin_eigen::build_basis_with_regions`] needs (pass the basis's own points and the
    /// simulation's integration points). Empty for the penalty.
    ///
    /// # Errors
    /// As [`PinHold::held_scene`], and [`SceneSpecError::Invalid`] naming the inset for a held
    /// region that holds none of the points.
    pub fn basis_regions(
        &self,
        scene: &SceneSpec,
        point_sets: &[&[Vector3<f64>]],
    ) -> Result<Vec<Vec<Vector3<f64>>>, SceneSpecError> {
        if *self == PinHold::Penalty {
            return Ok(Vec::new());
        }
        let held = self.held_scene(scene)?;
        let all: Vec<Vector3<f64>> = point_sets.iter().flat_map(|s| s.iter().copied()).collect();
        let selected = held
            .select(&all, "basis and integration points")
            .map_err(|e| self.explain(e))?;
        Ok(selected
            .into_iter()
            .map(|indices| indices.into_iter().map(|i| all[i]).collect())
            .collect())
    }

    /// The basis of `basis_points` (with Lamé parameters `materials` and options `params`) for
    /// this hold: [`skin_eigen::build_basis`] for the penalty; for exact holding,
    /// [`skin_eigen::build_basis_with_regions`] on the hold's compact kernels
    /// ([`PinHold::basis_params`]) for `scene`'s regions shrunk by the inset, held at the basis
    /// points and at `simulation_points` (the integration points the simulator will check), with
    /// the kernels widened where the compact ones leave no shape functions at a basis, simulation
    /// or `output_points` point (the vertices frames are written at; a thin part,
    /// [`skin_eigen::BasisParams::coverage`]). The penalty's Gaussian kernels reach 4 r_k and are
    /// widened only where they leave a basis point uncovered.
    ///
    /// # Errors
    /// [`HeldBasisError::Scene`] as [`PinHold::basis_regions`]; [`HeldBasisError::Basis`] from
    /// the builder.
    pub fn build_basis(
        &self,
        scene: &SceneSpec,
        basis_points: &IntegrationPoints,
        materials: &[LameParameters],
        simulation_points: &[Vector3<f64>],
        output_points: &[Vector3<f64>],
        params: BasisParams,
    ) -> Result<(SkinningBasis, BasisReport), HeldBasisError> {
        self.build_basis_sharing(
            scene,
            basis_points,
            materials,
            simulation_points,
            output_points,
            params,
        )
        .map(|(basis, report, _)| (basis, report))
    }

    /// [`PinHold::build_basis`], also returning the kernels it placed and their plain shape
    /// functions: at the basis points for the plain basis (the penalty, or a weighted hold with
    /// no constraint; [`skin_eigen::build_basis_keeping_shape_functions`]), on the points outside
    /// the regions for a weighted basis ([`skin_eigen::build_weighted_basis_sharing`]; the grid's
    /// cut cells split first when the hold asks, [`PinHold::basis_points`]), `None`
    /// for exact holding. The pressure space's Neumann modes on the same points are built on
    /// them ([`crate::PressureSpace::build`]).
    ///
    /// # Errors
    /// As [`PinHold::build_basis`].
    pub fn build_basis_sharing(
        &self,
        scene: &SceneSpec,
        basis_points: &IntegrationPoints,
        materials: &[LameParameters],
        simulation_points: &[Vector3<f64>],
        output_points: &[Vector3<f64>],
        params: BasisParams,
    ) -> Result<(SkinningBasis, BasisReport, Option<KernelShapeFunctions>), HeldBasisError> {
        let params = self.basis_params(params);
        match self {
            PinHold::Weighted { distance, .. } if !scene.constraints.is_empty() => {
                let (basis_points, materials) = self.basis_points(scene, basis_points, materials);
                let (basis_points, materials) = (basis_points.as_ref(), materials.as_ref());
                let bounds = basis_points.bounding_box();
                let invalid = |e| SceneSpecError::Invalid(format!("weighted holding: {e}"));
                let mut weight = self
                    .region_weight(scene, bounds.max - bounds.min)
                    .map_err(invalid)?
                    .expect("a weighted hold has a weight");
                if *distance == WeightDistance::HeldMaterial {
                    weight = weight.with_held_material(basis_points).map_err(invalid)?;
                }
                let (basis, report, _, shared) = build_weighted_basis_sharing(
                    basis_points,
                    materials,
                    &params,
                    &weight,
                    &[simulation_points, output_points],
                )?;
                Ok((basis, report, Some(shared)))
            }
            PinHold::Exact { .. } => {
                let regions =
                    self.basis_regions(scene, &[basis_points.positions(), simulation_points])?;
                let (basis, report, _) = build_basis_with_regions(
                    basis_points,
                    materials,
                    &params,
                    &regions,
                    &RegionConstraintParams::default(),
                    &[simulation_points, output_points],
                )?;
                Ok((basis, report, None))
            }
            // The penalty, or nothing to hold for a weighted basis: the plain basis.
            PinHold::Penalty | PinHold::Weighted { .. } => {
                let (basis, report, _, shared) =
                    build_basis_keeping_shape_functions(basis_points, materials, &params)?;
                Ok((basis, report, Some(shared)))
            }
        }
    }

    /// `error` with a hint when it is an exact hold's inset that emptied a region.
    fn explain(&self, error: SceneSpecError) -> SceneSpecError {
        match (self, error) {
            (
                PinHold::Exact { inset },
                SceneSpecError::EmptyRegion {
                    index,
                    region,
                    what,
                    available,
                },
            ) => SceneSpecError::Invalid(format!(
                "constraints[{index}] shrunk by the exact pins' inset of {inset} m ({region:?}) holds \
                 none of the {available} {what}: use a smaller inset (0 holds the whole region)"
            )),
            (_, error) => error,
        }
    }
}

impl Region {
    /// The region as a [`HeldRegionShape`] with an analytic distance, grown by
    /// [`REGION_TOLERANCE`] as [`Region::contains`] is.
    pub fn held_region_shape(&self) -> HeldRegionShape {
        let axis_vector = |axis: usize| Vector3::from_fn(|d, _| f64::from(u8::from(d == axis)));
        match *self {
            Region::Below { axis, value } => HeldRegionShape::HalfSpace {
                normal: axis_vector(axis),
                offset: value + REGION_TOLERANCE,
            },
            Region::Above { axis, value } => HeldRegionShape::HalfSpace {
                normal: -axis_vector(axis),
                offset: -(value - REGION_TOLERANCE),
            },
            Region::Ball { center, radius } => HeldRegionShape::Ball {
                center,
                radius: radius + REGION_TOLERANCE,
            },
        }
    }

    /// The region shrunk by `distance` (m): the points at least that far inside its boundary
    /// (planes moved inwards, a ball's radius reduced); `None` when nothing is left of a ball.
    pub fn inset(&self, distance: f64) -> Option<Region> {
        match *self {
            Region::Below { axis, value } => Some(Region::Below {
                axis,
                value: value - distance,
            }),
            Region::Above { axis, value } => Some(Region::Above {
                axis,
                value: value + distance,
            }),
            Region::Ball { center, radius } => (radius > distance).then_some(Region::Ball {
                center,
                radius: radius - distance,
            }),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{Constraint, Motion};

    fn clamp() -> SceneSpec {
        SceneSpec {
            constraints: vec![Constraint {
                region: Region::Below {
                    axis: 0,
                    value: 0.5,
                },
                motion: Motion::Rest,
            }],
            ..SceneSpec::default()
        }
    }

    #[test]
    fn an_inset_moves_planes_inwards_and_shrinks_balls() {
        let below = Region::Below {
            axis: 0,
            value: 0.5,
        };
        assert!(below.contains(&Vector3::new(0.45, 0.0, 0.0)));
        assert!(
            !below
                .inset(0.1)
                .unwrap()
                .contains(&Vector3::new(0.45, 0.0, 0.0))
        );
        let above = Region::Above {
            axis: 1,
            value: 1.0,
        };
        assert!(
            !above
                .inset(0.2)
                .unwrap()
                .contains(&Vector3::new(0.0, 1.1, 0.0))
        );
        let ball = Region::Ball {
            center: Vector3::zeros(),
            radius: 0.3,
        };
        assert_eq!(
            ball.inset(0.1),
            Some(Region::Ball {
                center: Vector3::zeros(),
                radius: 0.3 - 0.1
            })
        );
        assert_eq!(ball.inset(0.3), None);
    }

    #[test]
    fn exact_holding_splits_each_region_into_a_held_core_and_a_penalized_band() {
        let points = [
            Vector3::new(0.1, 0.0, 0.0),
            Vector3::new(0.45, 0.0, 0.0),
            Vector3::new(2.0, 0.0, 0.0),
        ];
        let penalty = PinHold::Penalty.reduced_scene(&clamp(), &points).unwrap();
        assert_eq!(penalty.pins[0].points, vec![0, 1]);
        assert!(penalty.held.is_empty());
        let exact = PinHold::Exact { inset: 0.1 }
            .reduced_scene(&clamp(), &points)
            .unwrap();
        assert_eq!(exact.held.len(), 1);
        assert_eq!(exact.held[0].points, vec![0]);
        assert_eq!(exact.pins.len(), 1);
        assert_eq!(exact.pins[0].points, vec![1]);
        // No band left: no penalized region at all.
        let whole = PinHold::Exact { inset: 0.0 }
            .reduced_scene(&clamp(), &points)
            .unwrap();
        assert_eq!(whole.held[0].points, vec![0, 1]);
        assert!(whole.pins.is_empty());
    }

    #[test]
    fn basis_regions_gather_the_held_points_of_every_set() {
        let a = [Vector3::new(0.1, 0.0, 0.0), Vector3::new(0.45, 0.0, 0.0)];
        let b = [Vector3::new(0.2, 0.0, 0.0), Vector3::new(2.0, 0.0, 0.0)];
        let hold = PinHold::Exact { inset: 0.1 };
        let regions = hold.basis_regions(&clamp(), &[&a, &b]).unwrap();
        assert_eq!(regions, vec![vec![a[0], b[0]]]);
        assert!(
            PinHold::Penalty
                .basis_regions(&clamp(), &[&a])
                .unwrap()
                .is_empty()
        );
        assert!(matches!(
            PinHold::Exact { inset: -1.0 }.held_scene(&clamp()),
            Err(SceneSpecError::Invalid(_))
        ));
        let emptied = PinHold::Exact { inset: 0.45 }.basis_regions(&clamp(), &[&a]);
        match emptied {
            Err(SceneSpecError::Invalid(message)) => {
                assert!(message.contains("use a smaller inset"), "{message}");
            }
            other => panic!("expected the inset to be named, got {other:?}"),
        }
    }
}
