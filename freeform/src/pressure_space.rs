//! The pressure space of the locking-free volumetric term
//! ([`reduced_sim::ReducedModel::with_projected_dilatation`]): the constant, the lowest Neumann
//! eigenmodes of the part of the object that deforms and, when asked for, the affine functions.
//!
//! ```text
//! Q = span{ 1, W^1 … W^P [, (X − c)/L] }   W^j: skinning eigenmodes with free boundaries (Eq. 15)
//! ```
//!
//! on the points outside the scene's held regions (values 0 inside them, so held points carry no
//! volumetric energy) for a weighted or exact hold, on every point for the penalty. c and L are
//! the centre and largest side of the basis points' bounding box.

use hyperelastic::LameParameters;
use nalgebra::{DMatrix, Vector3};
use rkpm_core::{IntegrationPoints, ShapeFunctionError};
use serde::{Deserialize, Serialize};
use skin_eigen::{
    BasisError, BasisParams, KernelShapeFunctions, SkinningBasis, build_basis_sharing,
};

use crate::pin_hold::PinHold;
use crate::scene::{Region, SceneSpec};

/// Options of [`PressureSpace::build`]; every field is optional in a file. The defaults are
/// the setting the convergence study (`freeform-paper convergence`) found non-increasing in m
/// from the stiff side on the beam's static Bend at ν = 0.3, 0.45 and 0.49 with no per-ν
/// change.
///
/// A richer space is not a safer one: each pressure function is a constraint on the few modes,
/// and one the modes cannot meet locks them again. The affine functions are the bending
/// pressure (linear across the thickness), which modes without the cross-section's Poisson
/// contraction cannot follow; they stiffen a bend at every m, and are off by default.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PressureSpaceParams {
    /// Neumann modes as a fraction of m + 1, rounded up (default 1).
    pub mode_fraction: f64,
    /// Whether the affine functions `(X − c)/L` are in the space (default false; the constant
    /// always is).
    pub affine: bool,
    /// c: the part `min(κ, c μ)` of the volumetric modulus kept pointwise
    /// ([`reduced_sim::ProjectedDilatationParams`]; default 0.5: enough to keep a point from
    /// flattening in a large twist, where the projected term alone lets it invert; each shear
    /// modulus kept pointwise stiffens a bend again).
    pub retained_shear_multiple: f64,
}

impl Default for PressureSpaceParams {
    fn default() -> Self {
        PressureSpaceParams {
            mode_fraction: 1.0,
            affine: false,
            retained_shear_multiple: 0.5,
        }
    }
}

impl PressureSpaceParams {
    /// Neumann modes for m displacement modes: `⌈mode_fraction · (m + 1)⌉`.
    pub fn neumann_modes(&self, modes: usize) -> usize {
        (self.mode_fraction * (modes + 1) as f64).ceil().max(0.0) as usize
    }
}

/// The pressure functions, evaluable at any rest points.
#[derive(Clone, Debug)]
pub struct PressureSpace {
    neumann: Option<SkinningBasis>,
    affine: bool,
    center: Vector3<f64>,
    scale: f64,
    held: Vec<Region>,
    retained_shear_multiple: f64,
    /// At most this many Neumann modes ([`PressureSpace::truncated`]).
    neumann_limit: Option<usize>,
}

impl PressureSpace {
    /// The pressure space for a model of `basis.eigen.modes` modes held by `hold` in `scene`,
    /// its Neumann modes built on `basis_points` (those outside the held regions, unless the
    /// hold is the penalty; split as [`PinHold::basis_points`] says) with `materials` and the
    /// kernel options of `basis` (its mode count replaced by
    /// [`PressureSpaceParams::neumann_modes`]). `shared`: the kernels and shape functions a
    /// weighted basis of the same points evaluated on their free part
    /// ([`PinHold::build_basis_sharing`]); the Neumann modes are built on them when they are
    /// those a build would place and evaluate ([`skin_eigen::build_basis_sharing`]: the same
    /// modes, set up once).
    ///
    /// # Errors
    /// [`BasisError`] when the Neumann basis cannot be built (too few free points for its
    /// kernels, more modes than kernels).
    pub fn build(
        scene: &SceneSpec,
        hold: PinHold,
        basis_points: &IntegrationPoints,
        materials: &[LameParameters],
        basis: BasisParams,
        params: &PressureSpaceParams,
        shared: Option<&KernelShapeFunctions>,
    ) -> Result<PressureSpace, BasisError> {
        let (basis_points, materials) = hold.basis_points(scene, basis_points, materials);
        let (basis_points, materials) = (basis_points.as_ref(), materials.as_ref());
        let modes = basis.eigen.modes;
        let held: Vec<Region> = match hold {
            PinHold::Penalty => Vec::new(),
            PinHold::Exact { .. } | PinHold::Weighted { .. } => {
                scene.constraints.iter().map(|c| c.region.clone()).collect()
            }
        };
        let bounds = basis_points.bounding_box();
        let count = params.neumann_modes(modes);
        let neumann = if count == 0 {
            None
        } else {
            let free: Vec<usize> = (0..basis_points.len())
                .filter(|&i| {
                    !held
                        .iter()
                        .any(|r| r.contains(&basis_points.positions()[i]))
                })
                .collect();
            let points = IntegrationPoints::new(
                free.iter().map(|&i| basis_points.positions()[i]).collect(),
                free.iter().map(|&i| basis_points.volumes()[i]).collect(),
            )
            .map_err(|_| BasisError::Regions(skin_eigen::RegionError::NoFreePoints))?;
            let lame: Vec<LameParameters> = free.iter().map(|&i| materials[i]).collect();
            let kernels = basis.kernels.count.min(points.len());
            let params = basis.with_modes(count).with_kernels(kernels);
            Some(build_basis_sharing(&points, &lame, &params, shared)?.0)
        };
        Ok(PressureSpace {
            neumann,
            affine: params.affine,
            center: 0.5 * (bounds.min + bounds.max),
            scale: (bounds.max - bounds.min).max(),
            held,
            retained_shear_multiple: params.retained_shear_multiple,
            neumann_limit: None,
        })
    }

    /// The options of the projected term over this space.
    pub fn dilatation_params(&self) -> reduced_sim::ProjectedDilatationParams {
        reduced_sim::ProjectedDilatationParams {
            retained_shear_multiple: self.retained_shear_multiple,
        }
    }

    /// Number P of pressure functions.
    pub fn functions(&self) -> usize {
        1 + if self.affine { 3 } else { 0 } + self.neumann_modes()
    }

    /// The same space with its first `neumann_modes` Neumann modes only (all when fewer).
    pub fn truncated(&self, neumann_modes: usize) -> PressureSpace {
        let mut space = self.clone();
        space.neumann_limit = Some(neumann_modes);
        space
    }

    /// Number of Neumann modes in the space.
    pub fn neumann_modes(&self) -> usize {
        let available = self.neumann.as_ref().map_or(0, SkinningBasis::modes);
        self.neumann_limit.map_or(available, |n| n.min(available))
    }

    /// The functions' values at `points` (N × P; rows of held points are 0).
    ///
    /// # Errors
    /// [`ShapeFunctionError`] when the Neumann modes cannot be evaluated at a free point.
    pub fn values(&self, points: &[Vector3<f64>]) -> Result<DMatrix<f64>, ShapeFunctionError> {
        let free: Vec<usize> = (0..points.len())
            .filter(|&i| !self.held.iter().any(|r| r.contains(&points[i])))
            .collect();
        let free_points: Vec<Vector3<f64>> = free.iter().map(|&i| points[i]).collect();
        let modes = match &self.neumann {
            Some(basis) => Some(
                basis
                    .evaluate(&free_points)
                    .map_err(|e| e.renumbered(|p| free[p]))?
                    .weights,
            ),
            None => None,
        };
        let mut values = DMatrix::zeros(points.len(), self.functions());
        for (row, &i) in free.iter().enumerate() {
            values[(i, 0)] = 1.0;
            let mut column = 1;
            if self.affine {
                let x = (points[i] - self.center) / self.scale;
                for d in 0..3 {
                    values[(i, column + d)] = x[d];
                }
                column += 3;
            }
            if let Some(modes) = &modes {
                // Column 0 of the Neumann basis is its constant handle, already in column 0.
                for j in 1..=self.neumann_modes() {
                    values[(i, column + j - 1)] = modes[(row, j)];
                }
            }
        }
        Ok(values)
    }
}
