//! The static Bend's FEM reference and the two best approximations of its field in a basis's
//! subspace (L2 and energy projections), with the field errors the study reports.

use fem_ref::{FemSimulator, PointInterpolation, TetMesh};
use freeform::fem_reference::FemProblem;
use freeform::scene::SceneSpec;
use hyperelastic::{HessianTangent, MaterialSample, StableNeoHookean, Tangent};
use nalgebra::{DMatrix, DVector, Vector3};
use optimize::NewtonParams;
use reduced_sim::DeformationMap;
use skin_eigen::SkinningBasis;

use crate::EvalError;
use crate::beam_scenario::{BEAM_MAX, BEAM_MIN, BEAM_TIME_STEP, BeamTest, beam_length_scale};
use crate::fem_reference::FemResolution;

/// A static FEM solution with what the projections need.
pub(crate) struct StaticReference {
    /// The FEM nodes (m).
    pub(crate) nodes: Vec<Vector3<f64>>,
    /// Their static displacements (m).
    pub(crate) displacements: Vec<Vector3<f64>>,
    /// Per element: its nodes and its rest stiffness (row-major, node-major DOFs).
    elements: Vec<(Vec<usize>, Vec<f64>)>,
    /// Which nodes the held region holds (their displacement is zero).
    pub(crate) held: Vec<bool>,
    /// The node nearest the tip ([`tip_index`]).
    pub(crate) tip: usize,
}

/// Index of the point nearest the beam's tip corner (5, 1, 1): off the Twist's axis, so that
/// the Twist moves it too.
pub(crate) fn tip_index(points: &[Vector3<f64>]) -> usize {
    let tip = BEAM_MAX;
    (0..points.len())
        .min_by(|&a, &b| {
            (points[a] - tip)
                .norm()
                .total_cmp(&(points[b] - tip).norm())
        })
        .unwrap_or(0)
}

/// The static Bend's scene: the Bend with gravity scaled by `scale`.
pub(crate) fn static_scene(scale: f64) -> SceneSpec {
    let mut scene = BeamTest::Bend.scene();
    scene.gravity = scene.gravity.map(|g| g * scale);
    scene
}

/// The static FEM solution of `scene` at `resolution` for `material`, converged.
fn solved(
    scene: &SceneSpec,
    resolution: FemResolution,
    material: MaterialSample,
) -> Result<FemSimulator<StableNeoHookean>, EvalError> {
    let r = resolution.cells_per_metre;
    let tets = TetMesh::cuboid(BEAM_MIN, BEAM_MAX, [5 * r, r, r]).map_err(EvalError::FemBox)?;
    let problem = FemProblem {
        tets,
        order: resolution.order,
        material,
        scene,
        time_step: BEAM_TIME_STEP,
        newton: NewtonParams::default(),
        tangent: HessianTangent::ProjectedPsd,
        ordering: Default::default(),
        failed_step_halvings: 0,
        steps: 0,
    };
    let (mut sim, _) = problem.simulator()?;
    let report = sim
        .solve_static(0.0)
        .map_err(|source| EvalError::Fem(fem_ref::FemRunError::Step { step: 0, source }))?;
    if !report.converged() {
        return Err(EvalError::StaticReferenceNotConverged {
            iterations: report.iterations,
        });
    }
    Ok(sim)
}

/// The static reference's own discretization error, measured against a finer FEM.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct ReferenceError {
    /// Normalized MSE of the reference against the finer solution interpolated at its nodes
    /// ([`field_errors`]).
    pub(crate) mse: f64,
    /// `u_tip,y / u'_tip,y − 1` at the reference's tip node (− the reference is stiffer).
    pub(crate) tip_change: f64,
}

/// Solves the static problem of `reference` again at `finer` and measures how far the
/// reference is from it at the reference's nodes.
///
/// # Errors
/// [`EvalError`] when the finer FEM cannot be built or does not converge, or a node of the
/// reference lies outside its mesh.
pub(crate) fn reference_error(
    reference: &StaticReference,
    scene: &SceneSpec,
    finer: FemResolution,
    material: MaterialSample,
) -> Result<ReferenceError, EvalError> {
    let sim = solved(scene, finer, material)?;
    let mesh = sim.model().mesh();
    let interpolation = PointInterpolation::new(mesh, &reference.nodes)?;
    let finer_positions = interpolation.interpolate(&sim.positions());
    let finer_displacements: Vec<Vector3<f64>> = finer_positions
        .iter()
        .zip(&reference.nodes)
        .map(|(x, rest)| x - rest)
        .collect();
    let (mse, _) = field_errors(&reference.displacements, &finer_displacements);
    let tip = reference.tip;
    Ok(ReferenceError {
        mse,
        tip_change: reference.displacements[tip].y / finer_displacements[tip].y - 1.0,
    })
}

/// Solves the static FEM reference at `resolution` for `material`.
pub(crate) fn static_reference(
    scene: &SceneSpec,
    resolution: FemResolution,
    material: MaterialSample,
) -> Result<StaticReference, EvalError> {
    let sim = solved(scene, resolution, material)?;
    let model = sim.model();
    let nodes = model.mesh().nodes().to_vec();
    let displacements: Vec<Vector3<f64>> = sim
        .positions()
        .iter()
        .zip(&nodes)
        .map(|(x, rest)| x - rest)
        .collect();
    let rest: Vec<f64> = nodes.iter().flat_map(|x| x.iter().copied()).collect();
    let elements = (0..model.mesh().element_count())
        .map(|e| {
            (
                model.mesh().element(e).to_vec(),
                model.element_hessian(e, &rest, Tangent::Exact, 0.0),
            )
        })
        .collect();
    let held = scene
        .fem_scene(&nodes, 1e4)?
        .held_nodes(nodes.len())
        .map_err(EvalError::FemSetup)?;
    let tip = tip_index(&nodes);
    Ok(StaticReference {
        nodes,
        displacements,
        elements,
        held,
        tip,
    })
}

/// Normalized MSE (over L²) and relative L2 error of `ours` against `reference`.
pub(crate) fn field_errors(ours: &[Vector3<f64>], reference: &[Vector3<f64>]) -> (f64, f64) {
    let (mut error, mut size) = (0.0, 0.0);
    for (a, b) in ours.iter().zip(reference) {
        error += (a - b).norm_squared();
        size += b.norm_squared();
    }
    let length = beam_length_scale();
    (
        error / ours.len().max(1) as f64 / (length * length),
        (error / size).sqrt(),
    )
}

/// The L2 and the energy projection of a field, as displacement fields at the same points.
type Projections = (Vec<Vector3<f64>>, Vec<Vector3<f64>>);

/// The L2 and energy projections of the reference onto the LBS span of `basis` at the nodes
/// (module docs), as displacement fields.
pub(crate) fn projections(
    basis: &SkinningBasis,
    reference: &StaticReference,
) -> Result<Projections, EvalError> {
    let map = DeformationMap::new(basis, &reference.nodes).map_err(EvalError::OutputMap)?;
    let positions = map.position_matrix();
    let (width, n) = (positions.nrows(), positions.ncols());
    // B: N × 4h, row i = b_iᵀ.
    let b = DMatrix::from_fn(n, width, |i, k| positions[(k, i)]);
    let gram = b.transpose() * &b;
    let cholesky = gram.clone().cholesky().ok_or_else(|| {
        EvalError::Projection("the basis's LBS Gram matrix at the FEM nodes is singular")
    })?;
    let u =
        |axis: usize| DVector::from_iterator(n, reference.displacements.iter().map(|d| d[axis]));
    let coefficients: Vec<DVector<f64>> = (0..3)
        .map(|axis| cholesky.solve(&(b.transpose() * u(axis))))
        .collect();
    let field = |c: &[DVector<f64>]| -> Vec<Vector3<f64>> {
        let per_axis: Vec<DVector<f64>> = c.iter().map(|c| &b * c).collect();
        (0..n)
            .map(|i| Vector3::new(per_axis[0][i], per_axis[1][i], per_axis[2][i]))
            .collect()
    };
    let best_l2 = field(&coefficients);

    // KP: 3N × 3w, column block r for axis r.
    let d = 3 * width;
    let mut kp = DMatrix::<f64>::zeros(3 * n, d);
    for (nodes, hessian) in &reference.elements {
        let size = 3 * nodes.len();
        for (a, &node_a) in nodes.iter().enumerate() {
            for i in 0..3 {
                let row = 3 * node_a + i;
                for (bi, &node_b) in nodes.iter().enumerate() {
                    for r in 0..3 {
                        let h = hessian[(3 * a + i) * size + 3 * bi + r];
                        if h == 0.0 {
                            continue;
                        }
                        for k in 0..width {
                            kp[(row, r * width + k)] += h * b[(node_b, k)];
                        }
                    }
                }
            }
        }
    }
    let mut system = DMatrix::<f64>::zeros(d, d);
    let mut rhs = DVector::<f64>::zeros(d);
    let flat_u = DVector::from_iterator(
        3 * n,
        reference
            .displacements
            .iter()
            .flat_map(|v| v.iter().copied()),
    );
    let kp_u = kp.transpose() * &flat_u;
    for r in 0..3 {
        let rows = DMatrix::from_fn(n, d, |i, c| kp[(3 * i + r, c)]);
        let block = b.transpose() * rows;
        system.rows_mut(r * width, width).copy_from(&block);
    }
    rhs += &kp_u;
    let trace_k = system.trace();
    let tie = 1e-8 * trace_k / (3.0 * gram.trace());
    // The held nodes tied to their (zero) displacement, 1e4 times as stiff per node as K is
    // on average: the projection stays in the subspace's fields that hold the region, as the
    // Galerkin solution does, instead of adding the rigid motion that fits the field best.
    let held_rows: Vec<usize> = (0..n).filter(|&i| reference.held[i]).collect();
    let held_b = DMatrix::from_fn(held_rows.len(), width, |i, k| b[(held_rows[i], k)]);
    let held_gram = held_b.transpose() * &held_b;
    let held_tie = if held_rows.is_empty() {
        0.0
    } else {
        1e4 * trace_k / (3.0 * gram.trace())
    };
    for r in 0..3 {
        let held_u = DVector::from_iterator(
            held_rows.len(),
            held_rows.iter().map(|&i| reference.displacements[i][r]),
        );
        let mut diagonal = system.view_mut((r * width, r * width), (width, width));
        diagonal += &gram * tie + &held_gram * held_tie;
        let mut part = rhs.rows_mut(r * width, width);
        part += b.transpose() * u(r) * tie + held_b.transpose() * held_u * held_tie;
    }
    let system = (&system + system.transpose()) * 0.5;
    let solution = system
        .cholesky()
        .ok_or_else(|| EvalError::Projection("the energy projection's system is not definite"))?
        .solve(&rhs);
    let energy: Vec<DVector<f64>> = (0..3)
        .map(|r| solution.rows(r * width, width).into_owned())
        .collect();
    Ok((best_l2, field(&energy)))
}
