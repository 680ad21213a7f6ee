//! The layout of the reduced coordinates z (design §3.7).
//!
//! The deformation map is `x(X, z) = X + Σ_{j=0..m} W^j(X) Z_j X̄`, `X̄ = [X; 1]`, with one 3×4
//! affine matrix `Z_j` per handle. Row r of every `Z_j` only moves coordinate r of x, so z is
//! stored row-block by row-block: `z = [z_0; z_1; z_2]`, `z_r[4j + c] = Z_j[r, c]`, each block
//! of length `4(m + 1)`. Seen as a column-major `4(m+1) × 3` matrix, column r of z is `z_r`;
//! the simulator uses that view for its dense products.

use nalgebra::{Matrix3, Vector3};

/// Index arithmetic for the reduced coordinates of a basis with `handles = m + 1` handles.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ReducedLayout {
    handles: usize,
}

impl ReducedLayout {
    /// The layout for `handles` handles (m + 1, the constant handle included).
    pub fn new(handles: usize) -> Self {
        ReducedLayout { handles }
    }

    /// Number of handles m + 1.
    pub fn handles(&self) -> usize {
        self.handles
    }

    /// Length `4(m + 1)` of one row block `z_r`.
    pub fn block_len(&self) -> usize {
        4 * self.handles
    }

    /// Length `12(m + 1)` of z.
    pub fn len(&self) -> usize {
        12 * self.handles
    }

    /// True for a layout of zero handles (no basis); any basis has at least the constant one.
    pub fn is_empty(&self) -> bool {
        self.handles == 0
    }

    /// Index of `Z_j[r, c]` in z (`r < 3`, `c < 4`, `j ≤ m`).
    pub fn index(&self, handle: usize, row: usize, col: usize) -> usize {
        debug_assert!(handle < self.handles && row < 3 && col < 4);
        row * self.block_len() + 4 * handle + col
    }

    /// z of the rest state: all zeros (x = X).
    pub fn rest(&self) -> Vec<f64> {
        vec![0.0; self.len()]
    }

    /// z of the rigid motion `x = R X + t` carried by the constant handle:
    /// `Z_0 = [R - I | t]`, every other `Z_j = 0`. `rotation` (orthonormal), `translation` (m).
    pub fn rigid_motion(&self, rotation: &Matrix3<f64>, translation: &Vector3<f64>) -> Vec<f64> {
        self.affine_motion(rotation, translation)
    }

    /// z of the affine motion `x = A X + t` carried by the constant handle (F = A at every
    /// point): `Z_0 = [A - I | t]`, every other `Z_j = 0`. `translation` in m.
    pub fn affine_motion(&self, matrix: &Matrix3<f64>, translation: &Vector3<f64>) -> Vec<f64> {
        let rotation = matrix;
        let mut z = self.rest();
        for r in 0..3 {
            for c in 0..3 {
                z[self.index(0, r, c)] = rotation[(r, c)] - if r == c { 1.0 } else { 0.0 };
            }
            z[self.index(0, r, 3)] = translation[r];
        }
        z
    }

    /// Velocity ż of a uniform translation at `velocity` (m/s): the constant handle's translation
    /// column, every other entry zero.
    pub fn uniform_velocity(&self, velocity: &Vector3<f64>) -> Vec<f64> {
        let mut zdot = self.rest();
        for r in 0..3 {
            zdot[self.index(0, r, 3)] = velocity[r];
        }
        zdot
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn indices_cover_z_exactly_once() {
        let layout = ReducedLayout::new(3);
        let mut seen = vec![false; layout.len()];
        for j in 0..3 {
            for r in 0..3 {
                for c in 0..4 {
                    let i = layout.index(j, r, c);
                    assert!(!seen[i], "index {i} used twice");
                    seen[i] = true;
                }
            }
        }
        assert!(seen.iter().all(|&s| s));
    }
}
