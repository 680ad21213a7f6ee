//! Integration (quadrature) points inside a solid, each with the volume it stands for
//! (design §3.1).
//!
//! - [`sample_grid`]: cell centres of a uniform grid over the bounding box, kept where inside;
//!   `v_i` = cell volume. The per-axis spacing is fitted so the cells tile the box exactly.
//! - [`sample_random`]: uniform points in the box, rejected outside; `v_i = V / N` with V the
//!   mesh's divergence-theorem volume (Table 4 ablation).
//! - [`sample_point_cloud`]: the given points (randomly down-sampled when too many);
//!   `v_i = V_est / N`, see [`CloudVolume`].

use nalgebra::Vector3;
use rand::seq::index::sample;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::aabb::Aabb;
use crate::inside_test::InsideTest;
use crate::point_cloud::PointCloud;
use crate::spatial_index::SpatialIndex;
use crate::triangle_mesh::TriangleMesh;

/// Integration points: positions `X_i` (m) and volumes `v_i` (m³), `Σ v_i ≈ |Ω|`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct IntegrationPoints {
    positions: Vec<Vector3<f64>>,
    volumes: Vec<f64>,
}

impl IntegrationPoints {
    /// Points with their volumes.
    ///
    /// # Errors
    /// [`SamplingError::Empty`] for no points, [`SamplingError::InvalidInput`] when the lengths
    /// differ, a coordinate is not finite or a volume is not positive and finite.
    pub fn new(positions: Vec<Vector3<f64>>, volumes: Vec<f64>) -> Result<Self, SamplingError> {
        if positions.is_empty() {
            return Err(SamplingError::Empty);
        }
        if positions.len() != volumes.len() {
            return Err(SamplingError::InvalidInput(format!(
                "{} positions but {} volumes",
                positions.len(),
                volumes.len()
            )));
        }
        if let Some(i) = positions
            .iter()
            .position(|p| !p.iter().all(|c| c.is_finite()))
        {
            return Err(SamplingError::InvalidInput(format!(
                "point {i} is not finite"
            )));
        }
        if let Some(i) = volumes.iter().position(|v| !(v.is_finite() && *v > 0.0)) {
            return Err(SamplingError::InvalidInput(format!(
                "point {i} has volume {} (must be positive and finite)",
                volumes[i]
            )));
        }
        Ok(IntegrationPoints { positions, volumes })
    }

    /// Positions `X_i` (N).
    pub fn positions(&self) -> &[Vector3<f64>] {
        &self.positions
    }

    /// Volumes `v_i` (N).
    pub fn volumes(&self) -> &[f64] {
        &self.volumes
    }

    /// Number of points N.
    pub fn len(&self) -> usize {
        self.positions.len()
    }

    /// Whether there are no points (never true for a constructed value).
    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }

    /// Total volume `Σ v_i`.
    pub fn total_volume(&self) -> f64 {
        self.volumes.iter().sum()
    }

    /// Bounding box of the points.
    pub fn bounding_box(&self) -> Aabb {
        Aabb::from_points(&self.positions).expect("integration points are never empty")
    }

    /// Mean distance from each point to its nearest other point (the sampling spacing used by
    /// the kernel-radius clamp of design §3.2). Zero for a single point.
    pub fn mean_nearest_neighbor_distance(&self) -> f64 {
        mean_nearest_neighbor_distance(&self.positions)
    }
}

/// Mean nearest-other-point distance of a point set (0 for fewer than two points).
pub(crate) fn mean_nearest_neighbor_distance(points: &[Vector3<f64>]) -> f64 {
    if points.len() < 2 {
        return 0.0;
    }
    let index = SpatialIndex::new(points);
    // Distances in parallel, summed in index order (a parallel sum is not reproducible).
    let distances: Vec<f64> = points
        .par_iter()
        .map(|p| {
            index
                .nearest(p, 2)
                .iter()
                .map(|&(_, d)| d)
                .fold(0.0, f64::max)
        })
        .collect();
    let total: f64 = distances.iter().sum();
    total / points.len() as f64
}

/// Sampling could not produce usable integration points.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SamplingError {
    /// No point ended up inside the solid.
    #[error("no integration point fell inside the shape (asked for about {requested})")]
    NoPointsInside {
        /// The requested number of points.
        requested: usize,
    },
    /// Empty input.
    #[error("no integration points")]
    Empty,
    /// A parameter is out of range.
    #[error("invalid sampling parameter `{name}` = {value}: {reason}")]
    InvalidParameter {
        /// Parameter name.
        name: &'static str,
        /// The value given.
        value: f64,
        /// What it must satisfy.
        reason: &'static str,
    },
    /// Inconsistent or non-finite input data.
    #[error("invalid integration point data: {0}")]
    InvalidInput(String),
}

/// Options for [`sample_grid`].
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct GridSamplingParams {
    /// Approximate number of points inside the solid (default 30 000). The grid spacing is
    /// `h = (V / target_points)^(1/3)`, V the enclosed volume.
    pub target_points: usize,
}

impl Default for GridSamplingParams {
    fn default() -> Self {
        GridSamplingParams {
            target_points: 30_000,
        }
    }
}

/// Uniform-grid integration points inside a closed mesh (design §3.1).
///
/// The bounding box is split into `n_x × n_y × n_z` equal cells, `n_d = max(1, round(L_d/h))`,
/// `h = (V/target)^(1/3)`; each cell centre inside the mesh becomes a point with volume
/// `h_x h_y h_z`. For a box the points tile it exactly (`Σ v_i = V`).
///
/// # Errors
/// [`SamplingError::InvalidParameter`] for `target_points == 0`,
/// [`SamplingError::NoPointsInside`] when no cell centre is inside (a shape thinner than a cell).
pub fn sample_grid(
    mesh: &TriangleMesh,
    params: &GridSamplingParams,
) -> Result<IntegrationPoints, SamplingError> {
    if params.target_points == 0 {
        return Err(SamplingError::InvalidParameter {
            name: "target_points",
            value: 0.0,
            reason: "must be at least 1",
        });
    }
    let bbox = mesh.bounding_box();
    let h = (mesh.volume() / params.target_points as f64).cbrt();
    let ext = bbox.extent();
    let n = ext.map(|l| ((l / h).round() as usize).max(1));
    let cell = Vector3::new(ext.x / n.x as f64, ext.y / n.y as f64, ext.z / n.z as f64);
    let inside = InsideTest::new(mesh);
    let candidates: Vec<Vector3<f64>> = (0..n.x * n.y * n.z)
        .map(|c| {
            let (i, j, k) = (c / (n.y * n.z), (c / n.z) % n.y, c % n.z);
            bbox.min
                + Vector3::new(
                    (i as f64 + 0.5) * cell.x,
                    (j as f64 + 0.5) * cell.y,
                    (k as f64 + 0.5) * cell.z,
                )
        })
        .collect();
    let keep = inside.contains_all(&candidates);
    let positions: Vec<_> = candidates
        .into_iter()
        .zip(keep)
        .filter_map(|(p, k)| k.then_some(p))
        .collect();
    if positions.is_empty() {
        return Err(SamplingError::NoPointsInside {
            requested: params.target_points,
        });
    }
    let volumes = vec![cell.product(); positions.len()];
    Ok(IntegrationPoints { positions, volumes })
}

/// Options for [`sample_random`].
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct RandomSamplingParams {
    /// Number of points inside the solid (default 30 000).
    pub points: usize,
    /// Random seed (default 0); the same seed gives the same points.
    pub seed: u64,
}

impl Default for RandomSamplingParams {
    fn default() -> Self {
        RandomSamplingParams {
            points: 30_000,
            seed: 0,
        }
    }
}

/// Uniform random integration points inside a closed mesh, each with volume `V / N`.
///
/// # Errors
/// [`SamplingError::InvalidParameter`] for `points == 0`; [`SamplingError::NoPointsInside`]
/// when rejection sampling finds nothing inside after `1000 · N` tries.
pub fn sample_random(
    mesh: &TriangleMesh,
    params: &RandomSamplingParams,
) -> Result<IntegrationPoints, SamplingError> {
    if params.points == 0 {
        return Err(SamplingError::InvalidParameter {
            name: "points",
            value: 0.0,
            reason: "must be at least 1",
        });
    }
    let bbox = mesh.bounding_box();
    let inside = InsideTest::new(mesh);
    let mut rng = ChaCha8Rng::seed_from_u64(params.seed);
    let mut positions = Vec::with_capacity(params.points);
    let mut tries = 0usize;
    // Batches keep the inside test parallel while the random stream stays sequential.
    while positions.len() < params.points {
        if tries > 1000 * params.points {
            return Err(SamplingError::NoPointsInside {
                requested: params.points,
            });
        }
        let batch: Vec<Vector3<f64>> = (0..params.points.clamp(1024, 65_536))
            .map(|_| bbox.min + bbox.extent().map(|l| l * rng.random::<f64>()))
            .collect();
        tries += batch.len();
        let keep = inside.contains_all(&batch);
        positions.extend(
            batch
                .into_iter()
                .zip(keep)
                .filter_map(|(p, k)| k.then_some(p))
                .take(params.points - positions.len()),
        );
    }
    let volumes = vec![mesh.volume() / positions.len() as f64; positions.len()];
    Ok(IntegrationPoints { positions, volumes })
}

/// How the volume of a point-cloud solid is obtained.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CloudVolume {
    /// The caller knows the volume (m³).
    #[serde(alias = "Given")]
    Given(f64),
    /// `V_est` = (number of occupied cells) × `c³` on a grid of spacing
    /// `c = cell_factor × mean nearest-neighbour distance`. For a solid, well-sampled cloud it
    /// approaches the true volume as the sampling refines; for a surface-like cloud (most 3DGS
    /// files) it measures a shell about one cell thick, so pass [`CloudVolume::Given`] when the
    /// volume matters (it scales mass and stiffness together, not the mode shapes).
    #[serde(alias = "VoxelEstimate")]
    VoxelEstimate {
        /// Cell size in units of the mean nearest-neighbour distance (default 1.0).
        cell_factor: f64,
    },
    /// The volume the cloud encloses, right for a solid whether the cloud samples its surface
    /// (most 3DGS files) or its inside (the default): on a grid of spacing
    /// `c = cell_factor × mean nearest-neighbour distance` the cells holding a point are
    /// occupied; a morphological closing (dilate by 2 cells, flood the outside through faces,
    /// erode by 2 cells) fills the inside and the sampling's gaps up to about 4 cells across;
    /// then
    ///
    /// ```text
    /// V_est = (solid inner cells + ½ · solid boundary cells) · c³
    /// ```
    ///
    /// (a boundary cell has a face-neighbour outside the solid; the surface runs through it,
    /// about half of it inside). Concavities narrower than about 4 cells are filled too.
    #[serde(alias = "FilledVoxels")]
    FilledVoxels {
        /// Cell size in units of the mean nearest-neighbour distance (default 2.0).
        cell_factor: f64,
    },
}

/// Options for [`sample_point_cloud`].
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct PointCloudSamplingParams {
    /// Keep at most this many points (random subset, default 100 000).
    pub max_points: usize,
    /// Seed of the down-sampling (default 0).
    pub seed: u64,
    /// Volume rule (default `FilledVoxels { cell_factor: 2.0 }`).
    pub volume: CloudVolume,
    /// With [`CloudVolume::FilledVoxels`]: add integration points inside, one per block of the
    /// closing's empty inner cells (blocks about `(V / max_points)^⅓` across, the point at the
    /// mean of the block's cell centres, volume the cells' total), the cloud's points sharing
    /// the rest (default false). A cloud on a surface (a 3DGS file) then carries mass and
    /// elastic energy inside as well, not only on its shell.
    pub fill_interior: bool,
}

impl Default for PointCloudSamplingParams {
    fn default() -> Self {
        PointCloudSamplingParams {
            max_points: 100_000,
            seed: 0,
            volume: CloudVolume::FilledVoxels { cell_factor: 2.0 },
            fill_interior: false,
        }
    }
}

/// Integration points from a point cloud or 3DGS object: the points themselves (down-sampled
/// to `max_points`, a seeded random subset), each with volume `V / N` (design §3.1); with
/// [`PointCloudSamplingParams::fill_interior`], also the empty inner cells of the voxel closing.
///
/// # Errors
/// [`SamplingError::Empty`] for an empty cloud, [`SamplingError::InvalidParameter`] for
/// `max_points == 0`, a non-positive given volume or cell factor, or an estimated volume of 0
/// (all points coincide).
pub fn sample_point_cloud(
    cloud: &PointCloud,
    params: &PointCloudSamplingParams,
) -> Result<IntegrationPoints, SamplingError> {
    if cloud.is_empty() {
        return Err(SamplingError::Empty);
    }
    if params.max_points == 0 {
        return Err(SamplingError::InvalidParameter {
            name: "max_points",
            value: 0.0,
            reason: "must be at least 1",
        });
    }
    let positions: Vec<Vector3<f64>> = if cloud.len() > params.max_points {
        let mut rng = ChaCha8Rng::seed_from_u64(params.seed);
        let mut chosen = sample(&mut rng, cloud.len(), params.max_points).into_vec();
        chosen.sort_unstable();
        chosen.into_iter().map(|i| cloud.positions()[i]).collect()
    } else {
        cloud.positions().to_vec()
    };
    let volume = match params.volume {
        CloudVolume::Given(v) if v > 0.0 && v.is_finite() => v,
        CloudVolume::Given(v) => {
            return Err(SamplingError::InvalidParameter {
                name: "volume",
                value: v,
                reason: "must be positive and finite",
            });
        }
        CloudVolume::VoxelEstimate { cell_factor } => {
            let c = cloud_cell_size(&positions, cell_factor)?;
            let bbox = Aabb::from_points(&positions).expect("non-empty");
            let mut cells: Vec<[i64; 3]> = positions
                .iter()
                .map(|p| ((p - bbox.min) / c).map(|x| x.floor() as i64).into())
                .collect();
            cells.sort_unstable();
            cells.dedup();
            cells.len() as f64 * c * c * c
        }
        CloudVolume::FilledVoxels { cell_factor } => {
            let c = cloud_cell_size(&positions, cell_factor)?;
            let closing = VoxelClosing::new(&positions, c);
            if params.fill_interior {
                // Inner points about as far apart as `max_points` points filling the volume;
                // the cloud's points share what they do not hold.
                let volume = closing.volume();
                let spacing = (volume / params.max_points as f64).cbrt();
                let stride = (spacing / c).round().max(1.0) as usize;
                let inner = closing.empty_inner_blocks(stride);
                let held: f64 = inner.iter().map(|(_, v)| v).sum();
                let share = (volume - held) / positions.len() as f64;
                let mut volumes = vec![share; positions.len()];
                let mut all = positions;
                for (x, v) in inner {
                    all.push(x);
                    volumes.push(v);
                }
                return IntegrationPoints::new(all, volumes);
            }
            closing.volume()
        }
    };
    let volumes = vec![volume / positions.len() as f64; positions.len()];
    IntegrationPoints::new(positions, volumes)
}

/// The cell size `cell_factor × mean nearest-neighbour distance` of a cloud's voxel estimate.
fn cloud_cell_size(positions: &[Vector3<f64>], cell_factor: f64) -> Result<f64, SamplingError> {
    if !(cell_factor > 0.0 && cell_factor.is_finite()) {
        return Err(SamplingError::InvalidParameter {
            name: "cell_factor",
            value: cell_factor,
            reason: "must be positive and finite",
        });
    }
    let c = cell_factor * mean_nearest_neighbor_distance(positions);
    if !(c > 0.0) {
        return Err(SamplingError::InvalidParameter {
            name: "volume",
            value: 0.0,
            reason: "the points coincide, so the cloud has no volume estimate",
        });
    }
    Ok(c)
}

/// Cells of [`CloudVolume::FilledVoxels`]' closing (dilation and erosion radius, in cells).
const CLOSING_RADIUS: usize = 2;

/// The voxel closing of [`CloudVolume::FilledVoxels`] on cells of size `c`: which cells are
/// solid, which of those are on the boundary, and which hold a point of the cloud.
struct VoxelClosing {
    grid: VoxelGrid,
    /// Centre of cell (0, 0, 0) (m).
    origin: Vector3<f64>,
    c: f64,
    solid: Vec<bool>,
    boundary: Vec<bool>,
    occupied: Vec<bool>,
}

impl VoxelClosing {
    fn new(positions: &[Vector3<f64>], c: f64) -> VoxelClosing {
        let bbox = Aabb::from_points(positions).expect("non-empty");
        let r = CLOSING_RADIUS;
        // Cells centred on the bounding box's faces (half a cell of offset), padded by r + 1
        // empty cells on every side so the outside is connected after the dilation.
        let pad = r + 1;
        let grid = VoxelGrid {
            dims: std::array::from_fn(|d| {
                (bbox.extent()[d] / c + 0.5).floor() as usize + 1 + 2 * pad
            }),
        };
        let mut occupied = vec![false; grid.len()];
        for p in positions {
            let cell: [usize; 3] =
                std::array::from_fn(|d| ((p[d] - bbox.min[d]) / c + 0.5).floor() as usize + pad);
            occupied[grid.index(cell)] = true;
        }
        // Closing: dilate, flood the outside through face-neighbours, erode what is not outside.
        let dilated = grid.dilate(&occupied, r);
        let mut outside = vec![false; grid.len()];
        let mut stack = vec![[0usize; 3]];
        outside[0] = true;
        while let Some(cell) = stack.pop() {
            for next in grid.face_neighbours(cell) {
                let n = grid.index(next);
                if !outside[n] && !dilated[n] {
                    outside[n] = true;
                    stack.push(next);
                }
            }
        }
        let solid: Vec<bool> = grid
            .dilate(&outside, r)
            .into_iter()
            .map(|near_outside| !near_outside)
            .collect();
        let boundary = (0..grid.len())
            .map(|n| {
                solid[n]
                    && grid
                        .face_neighbours(grid.cell(n))
                        .into_iter()
                        .any(|m| !solid[grid.index(m)])
            })
            .collect();
        VoxelClosing {
            origin: bbox.min - Vector3::repeat(pad as f64 * c),
            grid,
            c,
            solid,
            boundary,
            occupied,
        }
    }

    /// `(solid inner cells + ½ · solid boundary cells) · c³` (m³).
    fn volume(&self) -> f64 {
        let cells: f64 = (0..self.grid.len())
            .filter(|&n| self.solid[n])
            .map(|n| if self.boundary[n] { 0.5 } else { 1.0 })
            .sum();
        cells * self.c.powi(3)
    }

    /// The solid inner cells that hold no point of the cloud, gathered in blocks of
    /// `stride³` cells: per block with any, the mean of their centres (m) and their volume
    /// `count · c³` (m³).
    fn empty_inner_blocks(&self, stride: usize) -> Vec<(Vector3<f64>, f64)> {
        let stride = stride.max(1);
        let mut blocks: std::collections::BTreeMap<[usize; 3], (Vector3<f64>, usize)> =
            std::collections::BTreeMap::new();
        for n in 0..self.grid.len() {
            if self.solid[n] && !self.boundary[n] && !self.occupied[n] {
                let cell = self.grid.cell(n);
                let centre = self.origin + Vector3::from_fn(|d, _| cell[d] as f64 * self.c);
                let entry = blocks
                    .entry(cell.map(|i| i / stride))
                    .or_insert((Vector3::zeros(), 0));
                entry.0 += centre;
                entry.1 += 1;
            }
        }
        blocks
            .into_values()
            .map(|(sum, count)| (sum / count as f64, count as f64 * self.c.powi(3)))
            .collect()
    }
}

/// A box of voxels, x fastest.
struct VoxelGrid {
    dims: [usize; 3],
}

impl VoxelGrid {
    fn len(&self) -> usize {
        self.dims.iter().product()
    }

    fn index(&self, [i, j, k]: [usize; 3]) -> usize {
        (k * self.dims[1] + j) * self.dims[0] + i
    }

    fn cell(&self, n: usize) -> [usize; 3] {
        let (i, rest) = (n % self.dims[0], n / self.dims[0]);
        [i, rest % self.dims[1], rest / self.dims[1]]
    }

    fn face_neighbours(&self, cell: [usize; 3]) -> Vec<[usize; 3]> {
        let mut out = Vec::with_capacity(6);
        for d in 0..3 {
            if cell[d] > 0 {
                let mut lower = cell;
                lower[d] -= 1;
                out.push(lower);
            }
            if cell[d] + 1 < self.dims[d] {
                let mut upper = cell;
                upper[d] += 1;
                out.push(upper);
            }
        }
        out
    }

    /// Cells within Chebyshev distance `r` of a set cell (three separable passes).
    fn dilate(&self, set: &[bool], r: usize) -> Vec<bool> {
        let mut current = set.to_vec();
        for d in 0..3 {
            let mut next = vec![false; current.len()];
            for (n, value) in next.iter_mut().enumerate() {
                let cell = self.cell(n);
                let lo = cell[d].saturating_sub(r);
                let hi = (cell[d] + r).min(self.dims[d] - 1);
                *value = (lo..=hi).any(|x| {
                    let mut other = cell;
                    other[d] = x;
                    current[self.index(other)]
                });
            }
            current = next;
        }
        current
    }
}

/// Uniform-grid integration points filling the box `[min, max]` exactly: `n_d` cells per
/// axis, `n_d = max(1, round(L_d / spacing))`, cell centres as points, `v_i = h_x h_y h_z`.
/// Used for procedural boxes such as the 5 × 1 × 1 beam.
///
/// # Errors
/// [`SamplingError::InvalidParameter`] for a non-positive spacing or an empty box.
pub fn sample_box_grid(
    min: Vector3<f64>,
    max: Vector3<f64>,
    spacing: f64,
) -> Result<IntegrationPoints, SamplingError> {
    if !(spacing > 0.0 && spacing.is_finite()) {
        return Err(SamplingError::InvalidParameter {
            name: "spacing",
            value: spacing,
            reason: "must be positive and finite",
        });
    }
    let ext = max - min;
    if !(ext.min() > 0.0) {
        return Err(SamplingError::InvalidParameter {
            name: "box extent",
            value: ext.min(),
            reason: "every side must be positive",
        });
    }
    let mesh = TriangleMesh::cuboid(min, max);
    let target = (mesh.volume() / spacing.powi(3)).round().max(1.0) as usize;
    sample_grid(
        &mesh,
        &GridSamplingParams {
            target_points: target,
        },
    )
}
