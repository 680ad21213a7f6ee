//! The three boundary conditions of the shapes experiment (design §4.2, paper Sec. 4 "Thingi10K
//! and SimReady"), as solver-independent [`SceneSpec`]s of a surface. Every size, speed and
//! step count is a field of [`ShapeBoundaryParams`] and printed with the tables.
//!
//! With L the largest side of the surface's bounding box (1 m after normalization) and the
//! extremes `x_min`, `x_max` taken over candidate points of the solid (the shapes study passes
//! its FEM mesh's vertices: a coarse tetrahedral mesh cuts off thin tips, and slabs measured
//! from the surface's own extremes then hold no FEM node; the reduced model's points in the
//! cut-off tip lie in the slab and are held too):
//! - **Fix side**: the slab `x ≤ x_min + side_fraction · L` held at rest; gravity `g` along −y.
//! - **Pull farthest**: `pull_points` points chosen by farthest point sampling among candidate
//!   points (the first is the candidate farthest from the bounding-box centre c); the points
//!   within `pull_radius · L` of each chosen p move with constant velocity `pull_speed · L/s`
//!   along `(p − c)/|p − c|`; no gravity. The shapes study samples among the FEM mesh's
//!   vertices, whose extreme points lie on the surface: sampling the surface's own vertices
//!   picks tips (a bunny's ear) that a coarse tetrahedral mesh has cut off, and the patch then
//!   holds no FEM node.
//! - **Pull boundary**: along the surface box's longest axis a, the slabs
//!   `x_a ≤ min + side_fraction · L` and `x_a ≥ max − side_fraction · L` move apart, each at
//!   `pull_speed · L/s`; no gravity.

use nalgebra::Vector3;
use rkpm_core::{Aabb, TriangleMesh};
use serde::{Deserialize, Serialize};

use freeform::scene::{Constraint, Motion, Region, SceneSpec};

/// One of the three boundary conditions.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ShapeBoundary {
    /// The min-x side held, gravity.
    FixSide,
    /// Four farthest-point-sampled surface patches pulled outward.
    PullFarthest,
    /// Both ends of the longest axis pulled apart.
    PullBoundary,
}

/// Sizes, speeds and durations of the boundary conditions (the defaults are the tables').
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct ShapeBoundaryParams {
    /// Thickness of a held or pulled end slab as a fraction of L (default 0.05).
    pub side_fraction: f64,
    /// Gravitational acceleration of Fix side (m/s², along −y; default 9.8).
    pub gravity: f64,
    /// Pulled patches of Pull farthest (default 4).
    pub pull_points: usize,
    /// Radius of each pulled patch as a fraction of L (default 0.1).
    pub pull_radius: f64,
    /// Speed of every pulled region in L per second (default 0.2; 0.08 L over the default run).
    pub pull_speed: f64,
    /// Backward Euler step (s, default 0.01).
    pub time_step: f64,
    /// Steps of every run (default 40, i.e. 0.4 s).
    pub steps: usize,
}

impl Default for ShapeBoundaryParams {
    fn default() -> Self {
        ShapeBoundaryParams {
            side_fraction: 0.05,
            gravity: 9.8,
            pull_points: 4,
            pull_radius: 0.1,
            pull_speed: 0.2,
            time_step: 0.01,
            steps: 40,
        }
    }
}

impl ShapeBoundaryParams {
    /// One line with every value, for table preambles.
    pub fn describe(&self) -> String {
        format!(
            "Fix side: x ≤ x_min + {s}·L held, gravity {g} m/s² along −y. Pull farthest: {n} \
             points chosen by farthest point sampling, the points within {r}·L of each moved \
             outward (away from the bounding-box centre) at {v}·L/s, no gravity. Pull boundary: \
             the end slabs of thickness {s}·L along the longest axis moved apart at {v}·L/s each, \
             no gravity. Extremes and sampled points are the FEM mesh's vertices. h = {h} s, \
             {steps} steps ({t:.2} s).",
            s = self.side_fraction,
            g = self.gravity,
            n = self.pull_points,
            r = self.pull_radius,
            v = self.pull_speed,
            h = self.time_step,
            steps = self.steps,
            t = self.time_step * self.steps as f64,
        )
    }
}

impl ShapeBoundary {
    /// The three, in the paper's column order.
    pub const ALL: [ShapeBoundary; 3] = [
        ShapeBoundary::FixSide,
        ShapeBoundary::PullFarthest,
        ShapeBoundary::PullBoundary,
    ];

    /// "fix_side", "pull_farthest", "pull_boundary".
    pub fn name(self) -> &'static str {
        match self {
            ShapeBoundary::FixSide => "fix_side",
            ShapeBoundary::PullFarthest => "pull_farthest",
            ShapeBoundary::PullBoundary => "pull_boundary",
        }
    }

    /// "Fix side", "Pull farthest", "Pull boundary".
    pub fn title(self) -> &'static str {
        match self {
            ShapeBoundary::FixSide => "Fix side",
            ShapeBoundary::PullFarthest => "Pull farthest",
            ShapeBoundary::PullBoundary => "Pull boundary",
        }
    }

    /// The scene of this condition on the solid bounded by `surface` (any units; sizes scale
    /// with its largest bounding-box side L, speeds are in L per second), with the slabs
    /// measured from the extremes of `candidates` and Pull farthest's patches centred on
    /// points of `candidates` (points of the solid, e.g. its FEM mesh's vertices; the
    /// surface's vertices if empty).
    pub fn scene(
        self,
        surface: &TriangleMesh,
        candidates: &[Vector3<f64>],
        params: &ShapeBoundaryParams,
    ) -> SceneSpec {
        let bbox = surface.bounding_box();
        let candidates = if candidates.is_empty() {
            surface.vertices()
        } else {
            candidates
        };
        let extremes = Aabb::from_points(candidates).unwrap_or(bbox);
        let length = bbox.largest_side();
        let slab = params.side_fraction * length;
        let speed = params.pull_speed * length;
        match self {
            ShapeBoundary::FixSide => SceneSpec {
                gravity: Some(Vector3::new(0.0, -params.gravity, 0.0)),
                constraints: vec![Constraint {
                    region: Region::Below {
                        axis: 0,
                        value: extremes.min.x + slab,
                    },
                    motion: Motion::Rest,
                }],
                floor: None,
                colliders: Vec::new(),
            },
            ShapeBoundary::PullFarthest => {
                let center = bbox.center();
                let constraints = farthest_points(candidates, center, params.pull_points)
                    .into_iter()
                    .map(|p| {
                        let outward = (p - center)
                            .try_normalize(f64::EPSILON)
                            .unwrap_or_else(Vector3::x);
                        Constraint {
                            region: Region::Ball {
                                center: p,
                                radius: params.pull_radius * length,
                            },
                            motion: Motion::Translate {
                                velocity: outward * speed,
                            },
                        }
                    })
                    .collect();
                SceneSpec {
                    gravity: None,
                    constraints,
                    floor: None,
                    colliders: Vec::new(),
                }
            }
            ShapeBoundary::PullBoundary => {
                let extent = bbox.extent();
                let axis = extent.imax();
                let direction = Vector3::ith(axis, 1.0);
                SceneSpec {
                    gravity: None,
                    constraints: vec![
                        Constraint {
                            region: Region::Below {
                                axis,
                                value: extremes.min[axis] + slab,
                            },
                            motion: Motion::Translate {
                                velocity: -direction * speed,
                            },
                        },
                        Constraint {
                            region: Region::Above {
                                axis,
                                value: extremes.max[axis] - slab,
                            },
                            motion: Motion::Translate {
                                velocity: direction * speed,
                            },
                        },
                    ],
                    floor: None,
                    colliders: Vec::new(),
                }
            }
        }
    }
}

/// `count` of `points` by farthest point sampling: the first is the point farthest from
/// `center`, each next one the point farthest from those already chosen (ties to the lowest
/// index, so the choice is deterministic). Fewer if there are fewer distinct points.
pub fn farthest_points(
    points: &[Vector3<f64>],
    center: Vector3<f64>,
    count: usize,
) -> Vec<Vector3<f64>> {
    let mut distance: Vec<f64> = points.iter().map(|v| (v - center).norm()).collect();
    let mut chosen = Vec::new();
    while chosen.len() < count {
        let Some((best, &d)) = distance
            .iter()
            .enumerate()
            .max_by(|(i, a), (j, b)| a.total_cmp(b).then(j.cmp(i)))
        else {
            break;
        };
        if !chosen.is_empty() && d <= 0.0 {
            break;
        }
        let p = points[best];
        // Distances to the chosen set only: the centre just picks the first point.
        let first = chosen.is_empty();
        chosen.push(p);
        for (v, d) in points.iter().zip(&mut distance) {
            let to_p = (v - p).norm();
            *d = if first { to_p } else { d.min(to_p) };
        }
    }
    chosen
}
