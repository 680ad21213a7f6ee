//! Jacobi-preconditioned conjugate gradients over particle vectors with some particles held,
//! the SPH solid's matrix-free solver (its volume step and its small-strain static solve).

use nalgebra::Vector3;

/// A solve that stopped at its iteration cap.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct NotConverged {
    /// Iterations taken.
    pub(crate) iterations: usize,
    /// ‖b − A x‖ / ‖b‖ reached.
    pub(crate) residual: f64,
}

/// Solves A x = b on the particles flagged in `free` (the others keep their entries of `x`,
/// their equations are dropped) for symmetric positive definite A given by `apply`, from the
/// start `x`, preconditioned by `diagonal` (A's diagonal per coordinate; `None`: none), until
/// ‖b − A x‖ ≤ `tolerance` ‖b‖ over the free particles. Returns x and the iterations.
///
/// # Errors
/// [`NotConverged`] after `max_iterations` iterations.
pub(crate) fn conjugate_gradients(
    apply: impl Fn(&[Vector3<f64>]) -> Vec<Vector3<f64>>,
    b: &[Vector3<f64>],
    mut x: Vec<Vector3<f64>>,
    diagonal: Option<&[Vector3<f64>]>,
    free: &[bool],
    tolerance: f64,
    max_iterations: usize,
) -> Result<(Vec<Vector3<f64>>, usize), NotConverged> {
    let n = x.len();
    let mask = |mut u: Vec<Vector3<f64>>| {
        for (u, &f) in u.iter_mut().zip(free) {
            if !f {
                *u = Vector3::zeros();
            }
        }
        u
    };
    let precondition = |r: &[Vector3<f64>]| -> Vec<Vector3<f64>> {
        match diagonal {
            Some(d) => r.iter().zip(d).map(|(r, d)| r.component_div(d)).collect(),
            None => r.to_vec(),
        }
    };
    let b_norm = norm(&mask(b.to_vec())).max(f64::MIN_POSITIVE);
    let ax = apply(&x);
    let mut r = mask((0..n).map(|i| b[i] - ax[i]).collect());
    let mut z = precondition(&r);
    let mut p = z.clone();
    let mut rz = dot(&r, &z);
    let mut iterations = 0;
    let mut residual = norm(&r) / b_norm;
    while residual > tolerance {
        if iterations == max_iterations {
            return Err(NotConverged {
                iterations,
                residual,
            });
        }
        let ap = mask(apply(&p));
        let alpha = rz / dot(&p, &ap);
        for i in 0..n {
            x[i] += alpha * p[i];
            r[i] -= alpha * ap[i];
        }
        z = precondition(&r);
        let rz_next = dot(&r, &z);
        let beta = rz_next / rz;
        rz = rz_next;
        for i in 0..n {
            p[i] = z[i] + beta * p[i];
        }
        iterations += 1;
        residual = norm(&r) / b_norm;
    }
    Ok((x, iterations))
}

fn dot(a: &[Vector3<f64>], b: &[Vector3<f64>]) -> f64 {
    a.iter().zip(b).map(|(a, b)| a.dot(b)).sum()
}

fn norm(a: &[Vector3<f64>]) -> f64 {
    dot(a, a).sqrt()
}
