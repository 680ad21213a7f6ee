//! One stress case on the FEM reference.

use crate::beam_scenario::{BEAM_MAX, BEAM_MIN, beam_material};
use hyperelastic::StableNeoHookean;

use super::reduced_case::{case_object, material};
use super::{CaseStatus, StressCase, StressOutcome, StressScene};

/// Runs one case on the FEM reference (P2, 2 cells per metre): finiteness, Newton convergence
/// and min det F at every quadrature point; no energy balance.
pub(super) fn run_fem_case(case: &StressCase) -> StressOutcome {
    use fem_ref::{ElementOrder, FemMesh, FemModel, FemParams, FemSimulator, MassKind, TetMesh};

    let mut outcome = StressOutcome {
        min_det_f: f64::INFINITY,
        ..StressOutcome::not_run(case)
    };
    let object = match case_object(case) {
        Ok(object) => object,
        Err(e) => {
            return StressOutcome {
                status: CaseStatus::Error(format!("scene: {e}")),
                ..outcome
            };
        }
    };
    let setup = || -> Result<FemSimulator<StableNeoHookean>, String> {
        if !matches!(
            case.scene,
            StressScene::BeamBend | StressScene::BeamTwist { .. }
        ) {
            return Err("the FEM stress cases are beam scenes".into());
        }
        let tets = TetMesh::cuboid(BEAM_MIN, BEAM_MAX, [10, 2, 2]).map_err(|e| e.to_string())?;
        let elements = tets.tets().len();
        let model = FemModel::new(
            FemMesh::new(tets, ElementOrder::Quadratic),
            &vec![material(beam_material().youngs_modulus, case.poisson_ratio); elements],
            StableNeoHookean,
            MassKind::Consistent,
        )
        .map_err(|e| e.to_string())?;
        let scene = object
            .scene
            .fem_scene(model.mesh().nodes(), 1e4)
            .map_err(|e| e.to_string())?;
        let params = FemParams {
            time_step: case.time_step,
            ..Default::default()
        };
        FemSimulator::new(model, scene, params).map_err(|e| e.to_string())
    };
    let mut sim = match setup() {
        Ok(sim) => sim,
        Err(e) => {
            outcome.status = CaseStatus::Error(format!("FEM setup: {e}"));
            return outcome;
        }
    };
    for step in 1..=case.steps {
        match sim.step() {
            Ok(report) => {
                outcome.steps_run = step;
                outcome.unconverged_steps += usize::from(!report.converged());
            }
            Err(e) => {
                outcome.status = CaseStatus::Error(format!("FEM step {step}: {e}"));
                break;
            }
        }
        let x: Vec<f64> = sim
            .positions()
            .iter()
            .flat_map(|p| [p.x, p.y, p.z])
            .collect();
        if !x.iter().all(|v| v.is_finite()) {
            outcome.all_finite = false;
            break;
        }
        for f in sim.model().deformation_gradients(&x) {
            outcome.min_det_f = outcome.min_det_f.min(f.determinant());
        }
    }
    outcome
}
