//! Checks any [`StepTerm`] (a user's own included) against central differences before it is
//! simulated, as `hyperelastic::check_material` checks a material.

use faer::Mat;
use hyperelastic::Tangent;
use thiserror::Error;

use crate::terms::step_term::{StepTerm, TermPoint};

/// Options of [`check_term`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TermCheckParams {
    /// Central-difference step on every entry of z (default 1e-6).
    pub step: f64,
    /// Largest accepted relative error of every check (default 1e-5).
    pub tolerance: f64,
}

impl Default for TermCheckParams {
    fn default() -> Self {
        TermCheckParams {
            step: 1e-6,
            tolerance: 1e-5,
        }
    }
}

/// The largest relative error of each check, `max_k |a_k − b_k| / max_k max(|a_k|, |b_k|)`
/// (0 when both are zero).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TermCheckReport {
    /// The gradient against central differences of the energy.
    pub gradient_error: f64,
    /// The exact Hessian ([`Tangent::Exact`]) against central differences of the gradient.
    pub hessian_error: f64,
    /// The exact Hessian against its transpose.
    pub symmetry_error: f64,
    /// The gradient added without a Hessian against the one added with it.
    pub consistency_error: f64,
}

/// A check failed: the term is not what the simulator assumes.
#[derive(Clone, Debug, Error, PartialEq)]
pub enum TermCheckError {
    /// The energy, the gradient or the Hessian at z is not finite.
    #[error("term {term}: its {what} at z is not finite")]
    NonFinite {
        /// The term's [`StepTerm::name`].
        term: String,
        /// "energy", "gradient" or "Hessian".
        what: &'static str,
    },
    /// One of the checks exceeded the tolerance.
    #[error("term {term}: {check} error {error:.3e} exceeds {tolerance:.1e}")]
    Failed {
        /// The term's name.
        term: String,
        /// "gradient vs FD of the energy", "Hessian vs FD of the gradient", "Hessian symmetry"
        /// or "gradient with and without the Hessian".
        check: &'static str,
        /// The error measured.
        error: f64,
        /// The tolerance.
        tolerance: f64,
        /// All measured errors.
        report: Box<TermCheckReport>,
    },
}

/// Checks `term` at `at`: its gradient against central differences of its energy, its exact
/// Hessian against central differences of its gradient and against its transpose, and the
/// gradient it adds alone against the one it adds with the Hessian. Costs `2·len(z)` energies
/// and `2·len(z)` gradients; choose a z away from the term's kinks (a contact's edge).
///
/// # Errors
/// [`TermCheckError`] naming the first check that fails.
pub fn check_term(
    term: &dyn StepTerm,
    at: &TermPoint<'_>,
    params: &TermCheckParams,
) -> Result<TermCheckReport, TermCheckError> {
    let name = || term.name().to_owned();
    let len = at.z.len();
    let h = params.step;
    let energy = term.energy(at);
    if !energy.is_finite() {
        return Err(TermCheckError::NonFinite {
            term: name(),
            what: "energy",
        });
    }
    let gradient_at = |z: &[f64]| {
        let mut gradient = vec![0.0; len];
        term.add_derivatives(&at.at(z), Tangent::Exact, &mut gradient, None);
        gradient
    };
    let gradient = gradient_at(at.z);
    let mut with_hessian = vec![0.0; len];
    let mut hessian = Mat::<f64>::zeros(len, len);
    term.add_derivatives(at, Tangent::Exact, &mut with_hessian, Some(&mut hessian));
    if !gradient.iter().all(|g| g.is_finite()) {
        return Err(TermCheckError::NonFinite {
            term: name(),
            what: "gradient",
        });
    }
    let hessian_entries: Vec<f64> = (0..len)
        .flat_map(|j| (0..len).map(move |i| (i, j)))
        .map(|(i, j)| hessian[(i, j)])
        .collect();
    if !hessian_entries.iter().all(|h| h.is_finite()) {
        return Err(TermCheckError::NonFinite {
            term: name(),
            what: "Hessian",
        });
    }

    let mut z = at.z.to_vec();
    let mut fd_gradient = vec![0.0; len];
    let mut fd_hessian = vec![0.0; len * len];
    for k in 0..len {
        let centre = z[k];
        z[k] = centre + h;
        let (e_plus, g_plus) = (term.energy(&at.at(&z)), gradient_at(&z));
        z[k] = centre - h;
        let (e_minus, g_minus) = (term.energy(&at.at(&z)), gradient_at(&z));
        z[k] = centre;
        fd_gradient[k] = (e_plus - e_minus) / (2.0 * h);
        for i in 0..len {
            fd_hessian[k * len + i] = (g_plus[i] - g_minus[i]) / (2.0 * h);
        }
    }
    let transpose: Vec<f64> = (0..len)
        .flat_map(|j| (0..len).map(move |i| (j, i)))
        .map(|(i, j)| hessian[(i, j)])
        .collect();
    let report = TermCheckReport {
        gradient_error: relative_error(&gradient, &fd_gradient),
        hessian_error: relative_error(&hessian_entries, &fd_hessian),
        symmetry_error: relative_error(&hessian_entries, &transpose),
        consistency_error: relative_error(&gradient, &with_hessian),
    };
    let checks = [
        ("gradient vs FD of the energy", report.gradient_error),
        ("Hessian vs FD of the gradient", report.hessian_error),
        ("Hessian symmetry", report.symmetry_error),
        (
            "gradient with and without the Hessian",
            report.consistency_error,
        ),
    ];
    match checks.iter().find(|(_, e)| !(*e <= params.tolerance)) {
        Some(&(check, error)) => Err(TermCheckError::Failed {
            term: name(),
            check,
            error,
            tolerance: params.tolerance,
            report: Box::new(report),
        }),
        None => Ok(report),
    }
}

/// `max_k |a_k − b_k| / max_k max(|a_k|, |b_k|)`, 0 when both are zero.
fn relative_error(a: &[f64], b: &[f64]) -> f64 {
    let scale = a.iter().chain(b).fold(0.0_f64, |m, v| m.max(v.abs()));
    let difference = a
        .iter()
        .zip(b)
        .fold(0.0_f64, |m, (x, y)| m.max((x - y).abs()));
    if scale == 0.0 {
        0.0
    } else {
        difference / scale
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::analytic_field::{analytic_model, probe_z};
    use crate::terms::scene_terms::term_point;

    /// `E = Σ_k z_k⁴` with a gradient scaled by `gradient_scale` and a Hessian by
    /// `hessian_scale`: exact at 1, wrong otherwise.
    struct Quartic {
        gradient_scale: f64,
        hessian_scale: f64,
    }

    impl StepTerm for Quartic {
        fn name(&self) -> &str {
            "quartic"
        }

        fn add_energy(&self, at: &TermPoint<'_>, energy: &mut f64) {
            *energy += at.z.iter().map(|z| z.powi(4)).sum::<f64>();
        }

        fn add_derivatives(
            &self,
            at: &TermPoint<'_>,
            _tangent: Tangent,
            gradient: &mut [f64],
            hessian: Option<&mut Mat<f64>>,
        ) {
            for (g, z) in gradient.iter_mut().zip(at.z) {
                *g += self.gradient_scale * 4.0 * z.powi(3);
            }
            if let Some(hessian) = hessian {
                for (k, z) in at.z.iter().enumerate() {
                    hessian[(k, k)] += self.hessian_scale * 12.0 * z * z;
                }
            }
        }
    }

    #[test]
    fn the_check_passes_an_exact_term_and_names_what_is_wrong_in_a_broken_one() {
        let (model, _) = analytic_model();
        let z = probe_z(model.deformation_map().layout().len(), 0.5);
        let at = term_point(&model, &z, 0.0);
        let check = |gradient_scale, hessian_scale| {
            let term = Quartic {
                gradient_scale,
                hessian_scale,
            };
            check_term(&term, &at, &TermCheckParams::default())
        };
        let report = check(1.0, 1.0).unwrap();
        assert!(
            report.gradient_error < 1e-8 && report.hessian_error < 1e-6,
            "{report:?}"
        );
        let failed = |result: Result<TermCheckReport, TermCheckError>| match result {
            Err(TermCheckError::Failed { check, .. }) => check,
            other => panic!("expected a failed check, got {other:?}"),
        };
        assert_eq!(failed(check(1.001, 1.001)), "gradient vs FD of the energy");
        assert_eq!(failed(check(1.0, 1.01)), "Hessian vs FD of the gradient");
    }

    #[test]
    fn a_term_with_an_infinite_energy_is_refused() {
        struct Wall;
        impl StepTerm for Wall {
            fn name(&self) -> &str {
                "wall"
            }
            fn add_energy(&self, _at: &TermPoint<'_>, energy: &mut f64) {
                *energy += f64::INFINITY;
            }
            fn add_derivatives(
                &self,
                _at: &TermPoint<'_>,
                _tangent: Tangent,
                _gradient: &mut [f64],
                _hessian: Option<&mut Mat<f64>>,
            ) {
            }
        }
        let (model, _) = analytic_model();
        let z = vec![0.0; model.deformation_map().layout().len()];
        let error = check_term(
            &Wall,
            &term_point(&model, &z, 0.0),
            &TermCheckParams::default(),
        );
        assert!(matches!(
            error,
            Err(TermCheckError::NonFinite { what: "energy", .. })
        ));
    }
}
