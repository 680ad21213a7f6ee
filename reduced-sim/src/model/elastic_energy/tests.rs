//! The elastic energy's assembly against its point-by-point definitions.

use faer::Mat;
use hyperelastic::{HyperelasticMaterial, StableNeoHookean, Tangent};
use nalgebra::Matrix3;

use crate::model::analytic_field::analytic_model_with_spacing;
use crate::model::reduced_model::ReducedModel;

/// `Σ_i Σ_{s,t} G_i[a, s] v_i ∂²Ψ/∂F_rs∂F_qt G_i[b, t]` in entry `(r·n4 + a, q·n4 + b)`,
/// one point and one entry at a time (the definition, without chunks, parts or products).
fn hessian_point_by_point(
    model: &ReducedModel<StableNeoHookean>,
    z: &[f64],
    tangent: Tangent,
) -> Mat<f64> {
    let map = model.elastic_map();
    let n4 = map.layout().block_len();
    let f = map.deformation_gradients(z);
    let mut h = Mat::zeros(3 * n4, 3 * n4);
    for (i, f) in f.iter().enumerate() {
        let lame = &model.elastic_lame()[i];
        let d = model.material().tangent_stress_derivative(lame, f, tangent)
            * model.elastic_weights()[i];
        let g = map.gradient_block(i);
        for (r, q, s, t) in every_index_quadruple() {
            let a_rq = d[(3 * s + r, 3 * t + q)];
            for b in 0..n4 {
                let right = a_rq * g[t * n4 + b];
                for a in 0..n4 {
                    h[(r * n4 + a, q * n4 + b)] += g[s * n4 + a] * right;
                }
            }
        }
    }
    h
}

/// Every (r, q, s, t) in 0..3⁴.
fn every_index_quadruple() -> impl Iterator<Item = (usize, usize, usize, usize)> {
    (0..81).map(|k| (k / 27, (k / 9) % 3, (k / 3) % 3, k % 3))
}

#[test]
fn the_chunked_hessian_is_the_point_by_point_sum_on_any_number_of_threads() {
    // 0.15 m spacing: several hundred points, so several chunks, uneven parts and a
    // partial last chunk.
    let (model, _) = analytic_model_with_spacing(0.15);
    assert!(model.elastic_weights().len() > 5 * super::POINTS_PER_CHUNK);
    let len = model.deformation_map().layout().len();
    // A pose with large strains, some of them inverted (the projection acts).
    let z: Vec<f64> = (0..len)
        .map(|i| 0.5 * ((i as f64 * 1.37).sin() + 0.3 * (i as f64 * 0.71).cos()))
        .collect();
    for tangent in [Tangent::Exact, Tangent::ProjectedPsd] {
        let reference = hessian_point_by_point(&model, &z, tangent);
        let scale = (0..len)
            .flat_map(|i| (0..len).map(move |j| (i, j)))
            .map(|(i, j)| reference[(i, j)].abs())
            .fold(0.0, f64::max);
        for threads in [1, 2, 3, 7] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .expect("a thread pool");
            let h = pool.install(|| model.elastic_hessian(&z, tangent));
            for i in 0..len {
                for j in 0..len {
                    let error = (h[(i, j)] - reference[(i, j)]).abs();
                    assert!(
                        error <= 1e-12 * scale,
                        "{tangent:?}, {threads} threads: entry ({i}, {j}) is {} against \
                         {} point by point",
                        h[(i, j)],
                        reference[(i, j)]
                    );
                }
            }
        }
    }
}

#[test]
fn the_one_pass_energy_gradient_and_f_are_the_point_by_point_definitions_and_do_not_depend_on_threads()
 {
    let (model, _) = analytic_model_with_spacing(0.15);
    let map = model.elastic_map();
    assert!(
        map.len() > 2 * crate::model::deformation_map::POINTS_PER_PART,
        "{} points",
        map.len()
    );
    let n4 = map.layout().block_len();
    let len = 3 * n4;
    let z: Vec<f64> = (0..len)
        .map(|i| 0.3 * ((i as f64 * 1.37).sin() + 0.3 * (i as f64 * 0.71).cos()))
        .collect();
    // The definitions, one point at a time: F_i = I + Zᵀ G_i, Σ_i v_i Ψ(F_i) and
    // Σ_i v_i G_i P_iᵀ.
    let f: Vec<Matrix3<f64>> = (0..map.len())
        .map(|i| {
            let g = map.gradient_block(i);
            Matrix3::from_fn(|r, s| {
                let dot: f64 = (0..n4).map(|a| z[r * n4 + a] * g[s * n4 + a]).sum();
                f64::from(u8::from(r == s)) + dot
            })
        })
        .collect();
    let (material, lame, weights) = (
        model.material(),
        model.elastic_lame(),
        model.elastic_weights(),
    );
    let mut energy = 0.0;
    let mut gradient = vec![0.0; len];
    for (i, f) in f.iter().enumerate() {
        energy += weights[i] * material.energy_density(&lame[i], f);
        let p = material.first_piola_kirchhoff(&lame[i], f) * weights[i];
        let g = map.gradient_block(i);
        for (r, s, a) in
            (0..3).flat_map(|r| (0..3).flat_map(move |s| (0..n4).map(move |a| (r, s, a))))
        {
            gradient[r * n4 + a] += g[s * n4 + a] * p[(r, s)];
        }
    }
    let scale = gradient.iter().fold(0.0f64, |m, g| m.max(g.abs()));
    let mut first = None;
    for threads in [1, 2, 3] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("a thread pool");
        let (e, g, formed) = pool.install(|| {
            (
                model.elastic_energy(&z),
                model.elastic_gradient(&z),
                map.deformation_gradients(&z),
            )
        });
        for (i, (x, y)) in formed.iter().zip(&f).enumerate() {
            assert!((x - y).amax() <= 1e-13, "F of point {i}: {x} against {y}");
        }
        // The Newton iterations take the gradient at F formed once for it and the Hessian:
        // the same bits as the one-pass gradient.
        assert_eq!(
            model.elastic_gradient_at(&model.elastic_deformation_of(formed.clone())),
            g,
            "{threads} threads"
        );
        assert!(
            (e - energy).abs() <= 1e-12 * energy.abs(),
            "{e} against {energy}"
        );
        for (a, (x, y)) in g.iter().zip(&gradient).enumerate() {
            assert!((x - y).abs() <= 1e-12 * scale, "entry {a}: {x} against {y}");
        }
        // Parts of a fixed size summed in order: the same bits on any number of threads.
        let first = first.get_or_insert((e, g.clone()));
        assert_eq!((first.0, &first.1), (e, &g), "{threads} threads");
    }
}
