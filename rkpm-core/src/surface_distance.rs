//! Closest points on a triangle surface: an axis-aligned bounding-volume hierarchy over the
//! triangles, queried with a distance bound.
//!
//! Method: the tree splits the triangles at the median centroid along the longest axis of their
//! box until a leaf holds at most [`LEAF_SIZE`] triangles; a query descends nearer child first and
//! prunes every box farther than the best distance found so far. The per-triangle closest point
//! is Ericson's Voronoi-region method (*Real-Time Collision Detection*, 5.1.5).

use nalgebra::Vector3;

use crate::aabb::Aabb;
use crate::triangle_mesh::TriangleMesh;

/// Most triangles a leaf holds.
pub const LEAF_SIZE: usize = 4;

/// The closest surface point to a query.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ClosestPoint {
    /// The point on the surface (same units as the mesh).
    pub point: Vector3<f64>,
    /// `|point - query|`.
    pub distance: f64,
    /// Index of the triangle it lies on.
    pub triangle: usize,
}

#[derive(Clone, Copy, Debug)]
struct Node {
    bbox: Aabb,
    /// Leaf: `triangles[start..start + count]`; inner: children at `start` and `start + 1`.
    start: u32,
    count: u32,
}

/// Closest-point queries on one triangle mesh. Build once (O(F log F)), query many times
/// (O(log F) for a query near the surface).
#[derive(Clone, Debug)]
pub struct SurfaceDistance {
    corners: Vec<[Vector3<f64>; 3]>,
    /// Triangle indices in leaf order.
    order: Vec<u32>,
    nodes: Vec<Node>,
}

impl SurfaceDistance {
    /// Builds the hierarchy over the mesh's triangles.
    pub fn new(mesh: &TriangleMesh) -> Self {
        let corners: Vec<[Vector3<f64>; 3]> = (0..mesh.triangles().len())
            .map(|t| mesh.triangle_corners(t))
            .collect();
        let centroids: Vec<Vector3<f64>> =
            corners.iter().map(|[a, b, c]| (a + b + c) / 3.0).collect();
        let mut order: Vec<u32> = (0..corners.len() as u32).collect();
        let mut nodes = Vec::with_capacity(2 * corners.len() / LEAF_SIZE + 1);
        nodes.push(Node {
            bbox: triangles_box(&corners, &order),
            start: 0,
            count: order.len() as u32,
        });
        // Breadth-first split; children of a node are stored next to each other.
        let mut next = 0;
        while next < nodes.len() {
            let Node { bbox, start, count } = nodes[next];
            if count as usize > LEAF_SIZE {
                let axis = bbox.extent().imax();
                let range = start as usize..(start + count) as usize;
                let half = count as usize / 2;
                order[range.clone()].select_nth_unstable_by(half, |&a, &b| {
                    centroids[a as usize][axis].total_cmp(&centroids[b as usize][axis])
                });
                let left = &order[range.start..range.start + half];
                let right = &order[range.start + half..range.end];
                let children = nodes.len() as u32;
                nodes.push(Node {
                    bbox: triangles_box(&corners, left),
                    start,
                    count: half as u32,
                });
                nodes.push(Node {
                    bbox: triangles_box(&corners, right),
                    start: start + half as u32,
                    count: count - half as u32,
                });
                // Mark as inner: count 0, start = first child.
                nodes[next] = Node {
                    bbox,
                    start: children,
                    count: 0,
                };
            }
            next += 1;
        }
        SurfaceDistance {
            corners,
            order,
            nodes,
        }
    }

    /// The closest surface point to `query` if one lies within `max_distance` (pass
    /// `f64::INFINITY` for no bound). `None` also for an empty mesh.
    pub fn closest_point(&self, query: &Vector3<f64>, max_distance: f64) -> Option<ClosestPoint> {
        let mut best: Option<ClosestPoint> = None;
        let mut best_squared = max_distance * max_distance;
        let mut stack: Vec<u32> = Vec::with_capacity(64);
        if !self.nodes.is_empty() {
            stack.push(0);
        }
        while let Some(n) = stack.pop() {
            let node = self.nodes[n as usize];
            if box_distance_squared(&node.bbox, query) > best_squared {
                continue;
            }
            if node.count > 0 {
                for &t in &self.order[node.start as usize..(node.start + node.count) as usize] {
                    let [a, b, c] = &self.corners[t as usize];
                    let p = closest_point_on_triangle(query, a, b, c);
                    let d2 = (p - query).norm_squared();
                    if d2 <= best_squared {
                        best_squared = d2;
                        best = Some(ClosestPoint {
                            point: p,
                            distance: d2.sqrt(),
                            triangle: t as usize,
                        });
                    }
                }
            } else {
                let (l, r) = (node.start, node.start + 1);
                let dl = box_distance_squared(&self.nodes[l as usize].bbox, query);
                let dr = box_distance_squared(&self.nodes[r as usize].bbox, query);
                // Push the farther child first so the nearer is searched first.
                if dl < dr {
                    stack.extend([r, l]);
                } else {
                    stack.extend([l, r]);
                }
            }
        }
        best
    }
}

fn triangles_box(corners: &[[Vector3<f64>; 3]], triangles: &[u32]) -> Aabb {
    Aabb::from_points(triangles.iter().flat_map(|&t| corners[t as usize].iter())).unwrap_or(Aabb {
        min: Vector3::zeros(),
        max: Vector3::zeros(),
    })
}

fn box_distance_squared(bbox: &Aabb, p: &Vector3<f64>) -> f64 {
    (0..3)
        .map(|d| {
            let gap = (bbox.min[d] - p[d]).max(p[d] - bbox.max[d]).max(0.0);
            gap * gap
        })
        .sum()
}

/// The point of triangle `abc` closest to `p` (Ericson 5.1.5).
pub fn closest_point_on_triangle(
    p: &Vector3<f64>,
    a: &Vector3<f64>,
    b: &Vector3<f64>,
    c: &Vector3<f64>,
) -> Vector3<f64> {
    let ab = b - a;
    let ac = c - a;
    let ap = p - a;
    let d1 = ab.dot(&ap);
    let d2 = ac.dot(&ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return *a;
    }
    let bp = p - b;
    let d3 = ab.dot(&bp);
    let d4 = ac.dot(&bp);
    if d3 >= 0.0 && d4 <= d3 {
        return *b;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return a + ab * (d1 / (d1 - d3));
    }
    let cp = p - c;
    let d5 = ab.dot(&cp);
    let d6 = ac.dot(&cp);
    if d6 >= 0.0 && d5 <= d6 {
        return *c;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return a + ac * (d2 / (d2 - d6));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
    }
    let denom = va + vb + vc;
    if denom.abs() < f64::MIN_POSITIVE {
        // Degenerate (zero-area) triangle: the nearest of its three edges' points.
        return [
            a + ab * (d1 / ab.norm_squared().max(f64::MIN_POSITIVE)).clamp(0.0, 1.0),
            *b,
            *c,
        ]
        .into_iter()
        .min_by(|x, y| (x - p).norm_squared().total_cmp(&(y - p).norm_squared()))
        .unwrap_or(*a);
    }
    let v = vb / denom;
    let w = vc / denom;
    a + ab * v + ac * w
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// Brute force over all triangles, densely sampled: the reference for the tree and for
    /// Ericson's region logic.
    fn sampled_distance(p: &Vector3<f64>, [a, b, c]: &[Vector3<f64>; 3]) -> f64 {
        let n = 60;
        let mut best = f64::INFINITY;
        for i in 0..=n {
            for j in 0..=n - i {
                let (u, v) = (i as f64 / n as f64, j as f64 / n as f64);
                let q = a + (b - a) * u + (c - a) * v;
                best = best.min((q - p).norm());
            }
        }
        best
    }

    #[test]
    fn closest_point_on_triangle_is_never_farther_than_any_sample_and_lies_on_the_triangle() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        for _ in 0..200 {
            let mut r = || Vector3::new(rng.random(), rng.random(), rng.random()) * 2.0;
            let (a, b, c, p) = (r(), r(), r(), r());
            let q = closest_point_on_triangle(&p, &a, &b, &c);
            let d = (q - p).norm();
            let sampled = sampled_distance(&p, &[a, b, c]);
            assert!(d <= sampled + 1e-12, "{d} > sampled {sampled}");
            // Sampling resolution bounds how much the samples can overshoot.
            assert!(sampled - d < 0.1, "{d} vs sampled {sampled}");
            // q is in the plane of abc.
            let n = (b - a).cross(&(c - a)).normalize();
            assert!((q - a).dot(&n).abs() < 1e-12);
        }
    }

    #[test]
    fn tree_query_equals_brute_force_over_all_triangles() {
        let mesh = TriangleMesh::cuboid(Vector3::zeros(), Vector3::new(2.0, 1.0, 0.5));
        let tree = SurfaceDistance::new(&mesh);
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        for _ in 0..500 {
            let p = Vector3::new(
                rng.random_range(-1.0..3.0),
                rng.random_range(-1.0..2.0),
                rng.random_range(-1.0..1.5),
            );
            let brute = (0..mesh.triangles().len())
                .map(|t| {
                    let [a, b, c] = mesh.triangle_corners(t);
                    (closest_point_on_triangle(&p, &a, &b, &c) - p).norm()
                })
                .fold(f64::INFINITY, f64::min);
            let found = tree.closest_point(&p, f64::INFINITY).unwrap();
            assert!((found.distance - brute).abs() < 1e-14);
            // A bound below the distance finds nothing; one above finds the same point.
            assert!(tree.closest_point(&p, brute * 0.99).is_none());
            assert_eq!(
                tree.closest_point(&p, brute * 1.01 + 1e-12)
                    .unwrap()
                    .distance,
                found.distance
            );
        }
    }
}
