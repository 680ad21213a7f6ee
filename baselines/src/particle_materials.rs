//! Per-particle Lamé parameters and masses of the particle baselines (MPM, SPH) from the
//! materials a caller gives, checked once for both.

use hyperelastic::{LameParameters, MaterialSample};

/// Lamé parameters and masses m_i = ρ_i V_i (kg) of particles with volumes V_i (m³).
#[derive(Clone, Debug, PartialEq)]
pub struct ParticleMaterials {
    /// One per particle.
    pub lame: Vec<LameParameters>,
    /// One per particle (kg).
    pub masses: Vec<f64>,
}

impl ParticleMaterials {
    /// The parameters of particles with `volumes` (m³) of `materials` (one per particle, or one
    /// for all).
    ///
    /// # Errors
    /// A message naming the problem: a count of materials that is neither 1 nor one per
    /// particle, invalid elastic parameters, or a density that is not positive and finite
    /// (the first offending particle).
    pub fn new(volumes: &[f64], materials: &[MaterialSample]) -> Result<Self, String> {
        let n = volumes.len();
        if materials.len() != n && materials.len() != 1 {
            return Err(format!(
                "{} materials for {n} particles (give one per particle or one for all)",
                materials.len()
            ));
        }
        let material = |i: usize| &materials[if materials.len() == 1 { 0 } else { i }];
        let mut lame = Vec::with_capacity(n);
        let mut masses = Vec::with_capacity(n);
        for (i, v) in volumes.iter().enumerate() {
            let m = material(i);
            lame.push(
                m.lame_parameters()
                    .map_err(|e| format!("particle {i}: {e}"))?,
            );
            if !(m.density > 0.0 && m.density.is_finite()) {
                return Err(format!(
                    "particle {i}: density {} must be positive and finite",
                    m.density
                ));
            }
            masses.push(m.density * v);
        }
        Ok(ParticleMaterials { lame, masses })
    }
}
