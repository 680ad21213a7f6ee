//! The real spherical harmonics of 3D Gaussian Splatting's view-dependent colour (degrees 1 to
//! 3, in the order and signs of 3DGS's `eval_sh`) and their rotation: a splat turned by R shows
//! from direction d what it showed from `Rᵀ d`, so its coefficients become `c' = T(R) c` with
//!
//! ```text
//! Σ_k c'_k Y_k(d) = Σ_k c_k Y_k(Rᵀ d)   for every unit d,
//! ```
//!
//! one `(2l + 1) × (2l + 1)` block per degree l (rotations do not mix degrees). Each block is
//! found by least squares on fixed sample directions, exact up to rounding because the
//! degree-l functions span a rotation-invariant space.

use nalgebra::{DMatrix, Matrix3, Vector3};

/// Coefficients per colour channel beyond the DC term for `degree` (3, 8 or 15).
pub fn rest_coefficients(degree: usize) -> usize {
    (degree + 1) * (degree + 1) - 1
}

/// The degree whose `3 · rest_coefficients(degree)` is `f_rest` columns, if any (1 to 3).
pub fn degree_of_rest_columns(columns: usize) -> Option<usize> {
    (1..=3).find(|&d| 3 * rest_coefficients(d) == columns)
}

/// The real SH functions of degrees 1 to `degree` (at most 3) at the unit direction `d`, in
/// 3DGS's order and normalization (`sh[1..16]` of `eval_sh`).
pub fn real_sh_basis(degree: usize, d: &Vector3<f64>) -> Vec<f64> {
    const C1: f64 = 0.488_602_511_902_919_9;
    const C2: [f64; 5] = [
        1.092_548_430_592_079_2,
        -1.092_548_430_592_079_2,
        0.315_391_565_252_520_05,
        -1.092_548_430_592_079_2,
        0.546_274_215_296_039_6,
    ];
    const C3: [f64; 7] = [
        -0.590_043_589_926_643_5,
        2.890_611_442_640_554,
        -0.457_045_799_464_465_8,
        0.373_176_332_590_115_4,
        -0.457_045_799_464_465_8,
        1.445_305_721_320_277,
        -0.590_043_589_926_643_5,
    ];
    let (x, y, z) = (d.x, d.y, d.z);
    let mut out = Vec::with_capacity(rest_coefficients(degree.min(3)));
    if degree >= 1 {
        out.extend([-C1 * y, C1 * z, -C1 * x]);
    }
    if degree >= 2 {
        let (xx, yy, zz) = (x * x, y * y, z * z);
        out.extend([
            C2[0] * x * y,
            C2[1] * y * z,
            C2[2] * (2.0 * zz - xx - yy),
            C2[3] * x * z,
            C2[4] * (xx - yy),
        ]);
    }
    if degree >= 3 {
        let (xx, yy, zz) = (x * x, y * y, z * z);
        out.extend([
            C3[0] * y * (3.0 * xx - yy),
            C3[1] * x * y * z,
            C3[2] * y * (4.0 * zz - xx - yy),
            C3[3] * z * (2.0 * zz - 3.0 * xx - 3.0 * yy),
            C3[4] * x * (4.0 * zz - xx - yy),
            C3[5] * z * (xx - yy),
            C3[6] * x * (xx - 3.0 * yy),
        ]);
    }
    out
}

/// Rotations of SH coefficients up to one degree, with the sample directions' pseudo-inverse
/// computed once.
pub struct ShRotation {
    degree: usize,
    directions: Vec<Vector3<f64>>,
    /// Per degree l: the pseudo-inverse of `[Y_l(d_1) … Y_l(d_K)]` (`K × (2l + 1)`).
    pseudo_inverses: Vec<DMatrix<f64>>,
}

impl ShRotation {
    /// For degrees 1 to `degree` (clamped to 1..=3).
    pub fn new(degree: usize) -> ShRotation {
        let degree = degree.clamp(1, 3);
        // 32 points of a Fibonacci sphere: well spread, enough for the 7 functions of l = 3.
        let k = 32;
        let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
        let directions: Vec<Vector3<f64>> = (0..k)
            .map(|i| {
                let z = 1.0 - 2.0 * (i as f64 + 0.5) / k as f64;
                let r = (1.0 - z * z).sqrt();
                let phi = golden * i as f64;
                Vector3::new(r * phi.cos(), r * phi.sin(), z)
            })
            .collect();
        let pseudo_inverses = (1..=degree)
            .map(|l| {
                let a = Self::samples(l, &directions, &Matrix3::identity());
                a.pseudo_inverse(1e-12)
                    .expect("the sample matrix has an SVD")
            })
            .collect();
        ShRotation {
            degree,
            directions,
            pseudo_inverses,
        }
    }

    /// `[Y_l(Rᵀ d_1) … Y_l(Rᵀ d_K)]`, the degree-l functions only (`(2l + 1) × K`).
    fn samples(l: usize, directions: &[Vector3<f64>], rotation: &Matrix3<f64>) -> DMatrix<f64> {
        let offset = rest_coefficients(l - 1);
        let width = 2 * l + 1;
        DMatrix::from_fn(width, directions.len(), |row, k| {
            real_sh_basis(l, &(rotation.transpose() * directions[k]))[offset + row]
        })
    }

    /// The coefficient map `T(R)` of degrees 1 to the degree given at construction,
    /// block-diagonal, `rest_coefficients(degree)` square: `c' = T c`.
    pub fn matrix(&self, rotation: &Matrix3<f64>) -> DMatrix<f64> {
        let n = rest_coefficients(self.degree);
        let mut t = DMatrix::zeros(n, n);
        for l in 1..=self.degree {
            // c'ᵀ A = cᵀ A'  ⇒  c' = (A' A⁺)ᵀ c.
            let rotated = Self::samples(l, &self.directions, rotation);
            let block = (rotated * &self.pseudo_inverses[l - 1]).transpose();
            let offset = rest_coefficients(l - 1);
            t.view_mut((offset, offset), (2 * l + 1, 2 * l + 1))
                .copy_from(&block);
        }
        t
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use hyperelastic::polar_rotation;
    use nalgebra::{Rotation3, Unit};

    #[test]
    fn rotated_coefficients_show_from_d_what_the_original_showed_from_r_transpose_d() {
        let rotation =
            Rotation3::from_axis_angle(&Unit::new_normalize(Vector3::new(0.3, -1.0, 0.5)), 2.1)
                .into_inner();
        let t = ShRotation::new(3).matrix(&rotation);
        let c: Vec<f64> = (0..15)
            .map(|k| ((k * 7 + 3) % 11) as f64 / 5.0 - 1.0)
            .collect();
        let rotated = &t * DMatrix::from_column_slice(15, 1, &c);
        for d in [
            Vector3::new(1.0, 0.2, -0.3),
            Vector3::new(-0.4, 0.9, 0.1),
            Vector3::new(0.1, -0.2, -1.0),
        ] {
            let d = d.normalize();
            let now: f64 = real_sh_basis(3, &d)
                .iter()
                .zip(rotated.iter())
                .map(|(y, c)| y * c)
                .sum();
            let before: f64 = real_sh_basis(3, &(rotation.transpose() * d))
                .iter()
                .zip(&c)
                .map(|(y, c)| y * c)
                .sum();
            assert!((now - before).abs() < 1e-10, "{now} vs {before}");
        }
        // The identity leaves the coefficients as they are.
        let identity = ShRotation::new(3).matrix(&Matrix3::identity());
        assert!((identity - DMatrix::<f64>::identity(15, 15)).norm() < 1e-10);
    }

    #[test]
    fn the_polar_rotation_of_a_stretched_rotation_is_the_rotation() {
        let r = Rotation3::from_euler_angles(0.4, -1.2, 2.0).into_inner();
        let s = Matrix3::new(1.5, 0.2, 0.0, 0.2, 0.7, 0.1, 0.0, 0.1, 1.1);
        assert!((polar_rotation(&(r * s)) - r).norm() < 1e-10);
        // An inverted F still gives a proper rotation.
        let flip = Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, -0.5));
        assert!((polar_rotation(&(r * flip)).determinant() - 1.0).abs() < 1e-10);
    }
}
