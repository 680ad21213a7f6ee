//! The cache keys of a FEM run ([`crate::FemSimulator::trajectory_key`]): a hash of what the
//! simulator is built from, computed without building it ([`crate::FemSimulator::load_cached`]).

use artifact::ContentKeyBuilder;
use hyperelastic::HyperelasticMaterial;

use crate::fem_model::FemModel;
use crate::fem_params::FemParams;
use crate::scene::{FemFloor, FemScene, NodeTarget};
use crate::trajectory_cache::{
    Trajectory, TrajectoryCache, TrajectoryCacheError, TrajectoryKey, trajectory_key_builder,
};

/// What a run's cache key hashes: [`crate::FemSimulator::new`]'s inputs, the floor's stiffness worked
/// out.
pub(crate) struct KeyInputs<'a, M: HyperelasticMaterial> {
    pub(crate) model: &'a FemModel<M>,
    pub(crate) scene: &'a FemScene,
    /// The floor with a unit normal and its penalty stiffness (Pa/m²).
    pub(crate) floor: Option<&'a (FemFloor, f64)>,
    pub(crate) params: &'a FemParams,
}

/// The keys a run is stored under: whole, and split when it may split.
pub(crate) struct RunKeys {
    pub(crate) whole: TrajectoryKey,
    pub(crate) split: Option<TrajectoryKey>,
}

impl RunKeys {
    /// The key a run's checkpoint is saved under: the one it may finish under (the split key,
    /// which holds the splitting depth, where the run may split steps).
    pub(crate) fn checkpoint(&self) -> TrajectoryKey {
        self.split.unwrap_or(self.whole)
    }

    /// The cached trajectory for these keys: under `whole` only if every step converged when the
    /// run may split (an unconverged one was run without splitting), else under `split`.
    pub(crate) fn load(
        &self,
        cache: &TrajectoryCache,
    ) -> Result<Option<Trajectory>, TrajectoryCacheError> {
        if let Some(t) = cache.load(self.whole)?
            && (self.split.is_none() || t.converged.iter().all(|&c| c))
        {
            return Ok(Some(t));
        }
        match self.split {
            Some(split) => cache.load(split),
            None => Ok(None),
        }
    }
}

impl<M: HyperelasticMaterial> KeyInputs<'_, M> {
    pub(crate) fn keys(&self, scene_label: &str, steps: usize) -> RunKeys {
        RunKeys {
            whole: self.builder(scene_label, steps).finish(),
            // Only a run that may split has a split key (each key hashes the whole mesh).
            split: (self.params.failed_step_halvings > 0)
                .then(|| self.split_key(scene_label, steps)),
        }
    }

    pub(crate) fn split_key(&self, scene_label: &str, steps: usize) -> TrajectoryKey {
        self.builder(scene_label, steps)
            .str("failed steps split in halves, at most this deep")
            .u64(self.params.failed_step_halvings as u64)
            .finish()
    }

    pub(crate) fn builder(&self, scene_label: &str, steps: usize) -> ContentKeyBuilder {
        let mut key = trajectory_key_builder();
        let mesh = self.model.mesh();
        let tets = mesh.tet_mesh();
        let vertices: Vec<f64> = tets
            .vertices()
            .iter()
            .flat_map(|v| [v.x, v.y, v.z])
            .collect();
        key.f64s(&vertices);
        key.u64(tets.tets().len() as u64);
        for t in tets.tets() {
            for &v in t {
                key.u64(v as u64);
            }
        }
        key.str(&format!("{:?} {:?}", mesh.order(), self.model.mass_kind()));
        key.str(self.model.material().name());
        let lame: Vec<f64> = self
            .model
            .lame_parameters()
            .iter()
            .flat_map(|l| [l.lambda(), l.mu()])
            .collect();
        key.f64s(&lame).f64s(self.model.densities());
        match self.scene.gravity {
            Some(g) => key.f64s(g.as_slice()),
            None => key.str("no gravity"),
        };
        for d in &self.scene.dirichlet {
            key.u64(d.nodes.len() as u64);
            for &n in &d.nodes {
                key.u64(n as u64);
            }
            key.str(match d.target {
                NodeTarget::Rest => "rest",
                NodeTarget::Moving(_) => "moving",
            });
        }
        match self.floor {
            Some((f, kappa)) => key.f64s(&[f.normal.x, f.normal.y, f.normal.z, f.offset, *kappa]),
            None => key.str("no floor"),
        };
        let n = &self.params.newton;
        key.f64s(&[self.params.time_step, n.tolerance, n.armijo])
            .u64(n.max_iterations as u64)
            .u64(n.max_line_search_cuts as u64)
            .str(&format!("{:?}", self.params.tangent))
            .str(scene_label)
            .u64(steps as u64);
        key
    }
}
