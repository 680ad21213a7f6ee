//! What the simulator simulates: integration points with volumes and materials, their
//! deformation map, and the constant reduced mass matrix (design §3.7).

use faer::{Accum, Mat, Par, Side};
use hyperelastic::MaterialSample;
use hyperelastic::{HyperelasticMaterial, LameParameters, MaterialParameterError};
use nalgebra::Vector3;
use rkpm_core::{Aabb, IntegrationPoints};
use thiserror::Error;

use crate::model::deformation_map::{DeformationMap, DeformationMapError};
use crate::model::elastic_quadrature::{ElasticQuadrature, QuadratureError};
use crate::model::projected_dilatation::{
    ProjectedDilatation, ProjectedDilatationError, ProjectedDilatationParams,
};
use crate::model::skinning_field::SkinningField;

/// The model could not be built.
#[derive(Debug, Error)]
pub enum ReducedModelError {
    /// The deformation map failed (basis evaluation, non-finite input).
    #[error(transparent)]
    DeformationMap(#[from] DeformationMapError),
    /// One material sample per integration point is required.
    #[error("{materials} material samples given for {points} integration points")]
    MaterialCount {
        /// Samples given.
        materials: usize,
        /// Integration points.
        points: usize,
    },
    /// A material sample is invalid.
    #[error("material at integration point {point}: {source}")]
    Material {
        /// Index of the point.
        point: usize,
        /// What is wrong with it.
        #[source]
        source: MaterialParameterError,
    },
    /// A density is not finite and positive.
    #[error(
        "density at integration point {point} must be finite and positive, got {density} kg/m³"
    )]
    Density {
        /// Index of the point.
        point: usize,
        /// The value.
        density: f64,
    },
    /// The reduced mass matrix is not positive definite: some skinning DoF moves no mass at
    /// these points (too few points for the basis, or weights that are linearly dependent
    /// there after multiplication by `[X; 1]`).
    #[error(
        "the reduced mass matrix ({size}×{size} block) is singular on these {points} points: \
         use more integration points or fewer modes"
    )]
    SingularMass {
        /// Block size 4(m + 1).
        size: usize,
        /// Number of integration points.
        points: usize,
    },
}

/// A reduced elastic object: N integration points (rest positions X_i in m, volumes v_i in m³,
/// densities ρ_i in kg/m³, Lamé parameters), a constitutive model, the deformation map of a
/// skinning basis at those points, and the reduced mass matrix
///
/// ```text
/// M_z = blockdiag(M, M, M),   M = Σ_i ρ_i v_i b_i b_iᵀ   (4(m+1) × 4(m+1), kg·m² / kg),
/// ```
///
/// constant in time and factored once (Cholesky; [`ReducedModel::new`] fails if it is not
/// positive definite).
///
/// Any integration points work: the points the basis was built on, a coarser grid, random
/// points. The elastic energy is integrated over all of them with their volumes unless an
/// [`ElasticQuadrature`] (a weighted subset, e.g. an optimized cubature) is set with
/// [`ReducedModel::with_elastic_quadrature`]; mass, gravity, pins and floor always use every
/// point.
pub struct ReducedModel<M: HyperelasticMaterial> {
    map: DeformationMap,
    /// The elastic quadrature when it is not every point with its volume.
    elastic: Option<ElasticSubset>,
    volumes: Vec<f64>,
    densities: Vec<f64>,
    lame: Vec<LameParameters>,
    material: M,
    mass_block: Mat<f64>,
    mass_factor: faer::linalg::solvers::Llt<f64>,
    total_mass: f64,
    bounds: Aabb,
    /// The projected volumetric term, when set.
    dilatation: Option<ProjectedDilatation>,
}

impl<M: HyperelasticMaterial> ReducedModel<M> {
    /// Builds the model: evaluates the basis at the points and assembles and factors M.
    ///
    /// # Errors
    /// [`ReducedModelError`]: basis evaluation failed, a material or density is invalid, the
    /// counts differ, or the reduced mass matrix is singular.
    pub fn new<B: SkinningField + ?Sized>(
        basis: &B,
        points: &IntegrationPoints,
        materials: &[MaterialSample],
        material: M,
    ) -> Result<Self, ReducedModelError> {
        if materials.len() != points.len() {
            return Err(ReducedModelError::MaterialCount {
                materials: materials.len(),
                points: points.len(),
            });
        }
        let mut lame = Vec::with_capacity(points.len());
        let mut densities = Vec::with_capacity(points.len());
        for (point, s) in materials.iter().enumerate() {
            lame.push(
                s.lame_parameters()
                    .map_err(|source| ReducedModelError::Material { point, source })?,
            );
            if !(s.density > 0.0 && s.density.is_finite()) {
                return Err(ReducedModelError::Density {
                    point,
                    density: s.density,
                });
            }
            densities.push(s.density);
        }
        let map = DeformationMap::new(basis, points.positions())?;
        let n4 = map.layout().block_len();
        // M = B diag(ρv) Bᵀ as one product.
        let weighted: Vec<f64> = points
            .volumes()
            .iter()
            .zip(&densities)
            .enumerate()
            .flat_map(|(i, (v, rho))| map.position_row(i).iter().map(move |b| b * v * rho))
            .collect();
        let mut mass_block = Mat::<f64>::zeros(n4, n4);
        faer::linalg::matmul::matmul(
            mass_block.as_mut(),
            Accum::Replace,
            faer::MatRef::from_column_major_slice(&weighted, n4, points.len()),
            map.position_matrix().transpose(),
            1.0,
            Par::rayon(0),
        );
        symmetrize(&mut mass_block);
        let mass_factor =
            mass_block
                .llt(Side::Lower)
                .map_err(|_| ReducedModelError::SingularMass {
                    size: n4,
                    points: points.len(),
                })?;
        let total_mass = points
            .volumes()
            .iter()
            .zip(&densities)
            .map(|(v, rho)| v * rho)
            .sum();
        Ok(ReducedModel {
            elastic: None,
            volumes: points.volumes().to_vec(),
            bounds: points.bounding_box(),
            map,
            densities,
            lame,
            material,
            mass_block,
            mass_factor,
            total_mass,
            dilatation: None,
        })
    }

    /// The model with the material's volumetric term `½ κ (J − γ)²` replaced by its projection
    /// onto the pressure space whose values at the model's points are the columns of
    /// `pressure` (N × P; see [`crate::model::projected_dilatation`]; the part `min(κ, c μ)` of `params`
    /// stays pointwise): the locking-free volumetric term. Include the constant function; a point whose row is all zeros (a held region)
    /// carries no volumetric energy.
    ///
    /// # Errors
    /// [`ProjectedDilatationError`] for a material without a volumetric term, a row count other
    /// than N, no or non-finite values, or functions linearly dependent at the elastic points.
    pub fn with_projected_dilatation(
        mut self,
        pressure: nalgebra::DMatrix<f64>,
        params: ProjectedDilatationParams,
    ) -> Result<Self, ProjectedDilatationError> {
        if pressure.nrows() != self.map.len() {
            return Err(ProjectedDilatationError::RowCount {
                rows: pressure.nrows(),
                points: self.map.len(),
            });
        }
        self.dilatation = Some(self.dilatation_on_elastic_points(pressure, params)?);
        Ok(self)
    }

    /// The number P of pressure functions of the projected volumetric term, if it is set.
    pub fn pressure_functions(&self) -> Option<usize> {
        self.dilatation.as_ref().map(ProjectedDilatation::functions)
    }

    pub(crate) fn dilatation(&self) -> Option<&ProjectedDilatation> {
        self.dilatation.as_ref()
    }

    fn dilatation_on_elastic_points(
        &self,
        pressure: nalgebra::DMatrix<f64>,
        params: ProjectedDilatationParams,
    ) -> Result<ProjectedDilatation, ProjectedDilatationError> {
        ProjectedDilatation::new(
            &self.material,
            pressure,
            params,
            self.elastic.as_ref().map(|e| e.quadrature.points()),
            self.elastic_weights(),
            self.elastic_lame(),
        )
    }

    /// The model with its elastic energy integrated by `quadrature` instead of every point
    /// with its volume: `E_el(z) = Σ_q w_q Ψ(F_q(z))`, so its gradient and Hessian cost
    /// O(|Q|) instead of O(N). Mass, gravity, pins and floor are unchanged.
    ///
    /// # Errors
    /// [`QuadratureError::OutOfRange`] when a quadrature point is not a point of the model.
    pub fn with_elastic_quadrature(
        mut self,
        quadrature: ElasticQuadrature,
    ) -> Result<Self, QuadratureError> {
        self.set_elastic_quadrature(quadrature)?;
        Ok(self)
    }

    /// [`ReducedModel::with_elastic_quadrature`] in place: the elastic energy is integrated by
    /// `quadrature` from now on, whatever integrated it before.
    ///
    /// # Errors
    /// As [`ReducedModel::with_elastic_quadrature`]; the model is unchanged then.
    pub fn set_elastic_quadrature(
        &mut self,
        quadrature: ElasticQuadrature,
    ) -> Result<(), QuadratureError> {
        let (subset, dilatation) = self.elastic_subset(quadrature)?;
        self.elastic = Some(subset);
        if dilatation.is_some() {
            self.dilatation = dilatation;
        }
        Ok(())
    }

    /// The map, Lamé parameters and projected dilatation (if the model has one) of the
    /// model's points integrated by `quadrature`, without changing the model: what
    /// [`ReducedModel::set_elastic_quadrature`] installs, and what a force error of the
    /// quadrature against the full model reads.
    ///
    /// # Errors
    /// [`QuadratureError::OutOfRange`] for a quadrature point that is not a point of the model;
    /// [`QuadratureError::Dilatation`] when the pressure functions are dependent at the
    /// quadrature's points.
    pub(crate) fn elastic_subset(
        &self,
        quadrature: ElasticQuadrature,
    ) -> Result<(ElasticSubset, Option<ProjectedDilatation>), QuadratureError> {
        let n = self.map.len();
        if let Some(&point) = quadrature.points().iter().find(|&&p| p >= n) {
            return Err(QuadratureError::OutOfRange { point, points: n });
        }
        let subset = ElasticSubset {
            map: self.map.subset(quadrature.points()),
            lame: quadrature.points().iter().map(|&i| self.lame[i]).collect(),
            quadrature,
        };
        let dilatation = self
            .dilatation
            .as_ref()
            .map(|d| {
                ProjectedDilatation::new(
                    &self.material,
                    d.pressure().clone(),
                    d.params(),
                    Some(subset.quadrature.points()),
                    subset.quadrature.weights(),
                    &subset.lame,
                )
            })
            .transpose()
            .map_err(QuadratureError::Dilatation)?;
        Ok((subset, dilatation))
    }

    /// The elastic quadrature set by [`ReducedModel::with_elastic_quadrature`], or `None` when
    /// the elastic energy is integrated over every point with its volume.
    pub fn elastic_quadrature(&self) -> Option<&ElasticQuadrature> {
        self.elastic.as_ref().map(|e| &e.quadrature)
    }

    /// Number of points the elastic energy is evaluated at (N for the full quadrature).
    pub fn elastic_point_count(&self) -> usize {
        self.elastic_map().len()
    }

    /// The deformation map at the elastic quadrature points.
    pub(crate) fn elastic_map(&self) -> &DeformationMap {
        self.elastic.as_ref().map_or(&self.map, |e| &e.map)
    }

    /// The elastic quadrature weights (m³), one per point of [`Self::elastic_map`].
    pub(crate) fn elastic_weights(&self) -> &[f64] {
        self.elastic
            .as_ref()
            .map_or(&self.volumes, |e| e.quadrature.weights())
    }

    /// Lamé parameters at the elastic quadrature points.
    pub(crate) fn elastic_lame(&self) -> &[LameParameters] {
        self.elastic.as_ref().map_or(&self.lame, |e| &e.lame)
    }

    /// The deformation map at the integration points.
    pub fn deformation_map(&self) -> &DeformationMap {
        &self.map
    }

    /// Rest positions of the integration points (m).
    pub fn rest_positions(&self) -> &[Vector3<f64>] {
        self.map.rest_positions()
    }

    /// Volumes v_i (m³).
    pub fn volumes(&self) -> &[f64] {
        &self.volumes
    }

    /// Densities ρ_i (kg/m³).
    pub fn densities(&self) -> &[f64] {
        &self.densities
    }

    /// Lamé parameters per point.
    pub fn lame_parameters(&self) -> &[LameParameters] {
        &self.lame
    }

    /// The constitutive model.
    pub fn material(&self) -> &M {
        &self.material
    }

    /// One diagonal block M of the reduced mass matrix (`4(m+1) × 4(m+1)`, kg·m²).
    pub fn mass_block(&self) -> &Mat<f64> {
        &self.mass_block
    }

    /// Total mass Σ ρ_i v_i (kg).
    pub fn total_mass(&self) -> f64 {
        self.total_mass
    }

    /// The rest bounding box of the integration points.
    pub fn bounds(&self) -> Aabb {
        self.bounds
    }

    /// The largest p-wave modulus λ + 2μ over the points (Pa): the stiffness scale used by the
    /// penalty rules.
    pub fn max_p_wave_modulus(&self) -> f64 {
        self.lame
            .iter()
            .map(|l| l.p_wave_modulus())
            .fold(0.0, f64::max)
    }

    /// The largest Young's modulus over the points (Pa): the stiffness scale of
    /// [`crate::PinModulus::Young`].
    pub fn max_youngs_modulus(&self) -> f64 {
        self.lame
            .iter()
            .map(|l| l.youngs_modulus())
            .fold(0.0, f64::max)
    }

    /// Indices of the integration points whose rest position satisfies `predicate`.
    pub fn points_where(&self, predicate: impl Fn(&Vector3<f64>) -> bool) -> Vec<usize> {
        (0..self.map.len())
            .filter(|&i| predicate(&self.map.rest_positions()[i]))
            .collect()
    }

    /// The mass-weighted least-squares fit of a per-point vector field: the ż (or z) minimizing
    /// `Σ_i ρ_i v_i |B_i ż - u(X_i)|²`, i.e. `M_z ż = Σ_i ρ_i v_i B_iᵀ u_i`. With u an initial
    /// velocity field (m/s) this is the reduced initial velocity; with u a displacement field
    /// (m) it is the best reduced displacement.
    ///
    /// # Panics
    /// If `field` does not have one vector per integration point.
    pub fn project_field(&self, field: &[Vector3<f64>]) -> Vec<f64> {
        self.project_fields(std::slice::from_ref(&field))
            .pop()
            .expect("one field in, one fit out")
    }

    /// [`Self::project_field`] of several fields at once: one pass over the points' `b_i` for
    /// all of them (`4(m+1) × N` times `N × 3F`), one solve with `M_z` for `3F` right-hand
    /// sides. Returns one z (length 12(m+1)) per field, in order.
    ///
    /// # Panics
    /// If a field does not have one vector per integration point.
    pub fn project_fields<F: AsRef<[Vector3<f64>]>>(&self, fields: &[F]) -> Vec<Vec<f64>> {
        let n = self.map.len();
        assert!(
            fields.iter().all(|f| f.as_ref().len() == n),
            "one vector per integration point"
        );
        let n4 = self.map.layout().block_len();
        // Σ_i ρ_i v_i B_iᵀ u_i as one product: the points' b_i side by side times the weighted
        // fields (N × 3F, field f's coordinate r in column 3f + r).
        let weighted = Mat::<f64>::from_fn(n, 3 * fields.len(), |i, j| {
            self.densities[i] * self.volumes[i] * fields[j / 3].as_ref()[i][j % 3]
        });
        let mut rhs = Mat::<f64>::zeros(n4, 3 * fields.len());
        faer::linalg::matmul::matmul(
            rhs.as_mut(),
            faer::Accum::Replace,
            self.map.position_matrix(),
            weighted.as_ref(),
            1.0,
            faer::Par::rayon(0),
        );
        use faer::linalg::solvers::Solve;
        self.mass_factor.solve_in_place(rhs.as_mut());
        (0..fields.len())
            .map(|f| {
                (0..3)
                    .flat_map(|r| (0..n4).map(move |k| (k, r)))
                    .map(|(k, r)| rhs[(k, 3 * f + r)])
                    .collect()
            })
            .collect()
    }
}

/// An elastic quadrature with the deformation map and materials restricted to its points.
pub(crate) struct ElasticSubset {
    /// The points and their weights (m³).
    pub(crate) quadrature: ElasticQuadrature,
    /// The deformation map at the quadrature's points.
    pub(crate) map: DeformationMap,
    /// The Lamé parameters at the quadrature's points.
    pub(crate) lame: Vec<LameParameters>,
}

/// `y ← y + s · blockdiag(A, A, A) x` for a small dense square A (`n × n`; x and y of length
/// 3n in z's layout): one product `Y ← Y + s A X` with X and Y viewed as column-major `n × 3`
/// matrices (the three coordinate blocks of z), so the three blocks share one SIMD kernel.
///
/// # Panics
/// If `x.len()` or `y.len()` is not `3 · A.nrows()`.
pub(crate) fn add_block_diagonal_product(y: &mut [f64], a: &Mat<f64>, x: &[f64], s: f64) {
    let n = a.nrows();
    faer::linalg::matmul::matmul(
        faer::MatMut::from_column_major_slice_mut(y, n, 3),
        faer::Accum::Add,
        a.as_ref(),
        faer::MatRef::from_column_major_slice(x, n, 3),
        s,
        faer::Par::Seq,
    );
}

/// Copies the lower triangle's mirror over round-off asymmetry: `A ← (A + Aᵀ)/2`.
pub(crate) fn symmetrize(a: &mut Mat<f64>) {
    for j in 0..a.ncols() {
        for i in 0..j {
            let v = 0.5 * (a[(i, j)] + a[(j, i)]);
            a[(i, j)] = v;
            a[(j, i)] = v;
        }
    }
}

#[cfg(test)]
mod tests {
    use crate::model::analytic_field::analytic_model;

    /// A pose of every coordinate nonzero, of size about `scale`.
    fn pose(len: usize, scale: f64) -> Vec<f64> {
        (0..len)
            .map(|k| scale * (1.0 + ((7 * k) % 11) as f64) / 11.0)
            .collect()
    }

    #[test]
    fn projecting_a_field_of_the_subspace_returns_its_coordinates() {
        let (model, _) = analytic_model();
        let len = model.deformation_map().layout().len();
        let z = pose(len, 0.05);
        let field = model.deformation_map().displacements(&z);
        let fitted = model.project_field(&field);
        for (k, (got, want)) in fitted.iter().zip(&z).enumerate() {
            assert!((got - want).abs() <= 1e-9, "{k}: {got} vs {want}");
        }
    }

    #[test]
    fn projecting_fields_together_equals_projecting_each() {
        let (model, _) = analytic_model();
        let len = model.deformation_map().layout().len();
        let fields: Vec<_> = [0.01, -0.03, 0.2]
            .iter()
            .map(|&s| model.deformation_map().displacements(&pose(len, s)))
            .collect();
        let together = model.project_fields(&fields);
        assert_eq!(together.len(), fields.len());
        for (field, fit) in fields.iter().zip(&together) {
            let alone = model.project_field(field);
            for (a, b) in alone.iter().zip(fit) {
                assert!((a - b).abs() <= 1e-12 * (1.0 + a.abs()), "{a} vs {b}");
            }
        }
    }
}
