//! Cubatures cached by content, so one optimization serves every later run of the same model.

use std::path::{Path, PathBuf};

use artifact::{ContentKeyBuilder, load_framed, save_framed};
use hyperelastic::HyperelasticMaterial;
use serde::{Deserialize, Serialize};

use crate::model::elastic_quadrature::ElasticQuadrature;
use crate::model::reduced_model::ReducedModel;

use super::{CubatureError, CubatureParams, CubatureReport, optimize_cubature};

/// File kind and format version of cached cubatures. The version is part of the cache key:
/// bump it whenever the optimization changes its result (2: zero-weight candidates leave the
/// greedy set; 3: the targets from the one-pass elastic gradient and the residual as one
/// product, which round differently; 4: the approximations' F from the targets' SIMD kernel
/// and the Gram columns from per-point factors, which round differently again; 5: on a model
/// with a projected dilatation, the candidates' stresses shifted by the full model's pressure
/// and the pressure space in the key; 6: batches spread out by `batch_spacing`).
const CUBATURE_MAGIC: &[u8] = b"FREEFORM-CUBATURE";
const CUBATURE_FORMAT_VERSION: u32 = 6;

/// A cached cubature: its points, weights and the report of its optimization.
#[derive(Serialize, Deserialize)]
struct CachedCubature {
    points: Vec<usize>,
    weights: Vec<f64>,
    report: CubatureReport,
}

/// Where [`optimize_cubature_cached`] keeps the cubature of `model` and `params`:
/// `<cache_dir>/cubature/cubature-<hash>.bin`, the hash of everything that determines it (the
/// deformation map's G at every point, volumes, densities, Lamé parameters, the material's
/// name, the projected dilatation's pressure values and options when it has one, every
/// option).
pub fn cubature_cache_path<M: HyperelasticMaterial>(
    model: &ReducedModel<M>,
    params: &CubatureParams,
    cache_dir: &Path,
) -> PathBuf {
    let mut key = ContentKeyBuilder::new(CUBATURE_MAGIC, u64::from(CUBATURE_FORMAT_VERSION));
    let map = model.deformation_map();
    key.u64(map.layout().handles() as u64)
        .f64s(map.gradient_matrix_slice())
        .f64s(model.volumes())
        .f64s(model.densities())
        .str(model.material().name())
        .str(&format!("{params:?}"));
    for l in model.lame_parameters() {
        key.f64s(&[l.lambda(), l.mu()]);
    }
    match model.dilatation() {
        None => key.str("pointwise volumetric term"),
        Some(d) => key
            .str(&format!("projected dilatation {:?}", d.params()))
            .f64s(d.pressure().as_slice()),
    };
    cache_dir
        .join("cubature")
        .join(format!("cubature-{}.bin", key.finish().hex()))
}

/// The cache file of one model's cubature under one set of options: its path
/// ([`cubature_cache_path`]) hashed once, so that looking for a cached cubature, saving a new
/// one and the automatic rule's over-budget note beside it do not hash the model again (the
/// hash reads the deformation map's G at every point: about 0.1 s at 40 000 points).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct CubatureCacheFile {
    path: PathBuf,
    point_count: usize,
}

impl CubatureCacheFile {
    /// The file of `model`'s cubature under `params` in `cache_dir`.
    pub fn new<M: HyperelasticMaterial>(
        model: &ReducedModel<M>,
        params: &CubatureParams,
        cache_dir: &Path,
    ) -> Self {
        CubatureCacheFile {
            path: cubature_cache_path(model, params, cache_dir),
            point_count: model.volumes().len(),
        }
    }

    /// The file's path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The cached cubature, if the file holds a readable one that fits the model (its report
    /// says `cached`).
    pub fn load(&self) -> Option<(ElasticQuadrature, CubatureReport)> {
        let cached =
            load_framed::<CachedCubature>(&self.path, CUBATURE_MAGIC, CUBATURE_FORMAT_VERSION)
                .ok()
                .flatten()
                .filter(|cached| cached.points.iter().all(|&p| p < self.point_count))?;
        let quadrature = ElasticQuadrature::new(cached.points, cached.weights).ok()?;
        let report = CubatureReport {
            cached: true,
            ..cached.report
        };
        Some((quadrature, report))
    }

    /// Saves a freshly optimized cubature and returns it; when it cannot be saved, the reason
    /// goes into the report's `cache_warning`.
    pub fn save(
        &self,
        quadrature: ElasticQuadrature,
        mut report: CubatureReport,
    ) -> (ElasticQuadrature, CubatureReport) {
        let entry = CachedCubature {
            points: quadrature.points().to_vec(),
            weights: quadrature.weights().to_vec(),
            report: report.clone(),
        };
        let saved = self
            .path
            .parent()
            .map_or(Ok(()), std::fs::create_dir_all)
            .map_err(|e| e.to_string())
            .and_then(|()| {
                save_framed(&self.path, CUBATURE_MAGIC, CUBATURE_FORMAT_VERSION, &entry)
                    .map_err(|e| e.to_string())
            });
        if let Err(why) = saved {
            report.cache_warning = Some(format!("{}: {why}", self.path.display()));
        }
        (quadrature, report)
    }
}

/// [`optimize_cubature`], cached under `cache_dir` by content ([`cubature_cache_path`]): a
/// cached cubature is loaded (its report says `cached`), a missing or unreadable one is
/// optimized and saved. A cubature that cannot be saved is still returned, with the reason in
/// its report's `cache_warning`.
///
/// # Errors
/// As [`optimize_cubature`].
pub fn optimize_cubature_cached<M: HyperelasticMaterial>(
    model: &ReducedModel<M>,
    params: &CubatureParams,
    cache_dir: &Path,
) -> Result<(ElasticQuadrature, CubatureReport), CubatureError> {
    let file = CubatureCacheFile::new(model, params, cache_dir);
    if let Some(cached) = file.load() {
        return Ok(cached);
    }
    let (quadrature, report) = optimize_cubature(model, params)?;
    Ok(file.save(quadrature, report))
}

/// The cubature of `model` and `params` cached under `cache_dir`, if there is a readable one
/// that fits the model (its report says `cached`); [`CubatureCacheFile::load`].
pub fn load_cached_cubature<M: HyperelasticMaterial>(
    model: &ReducedModel<M>,
    params: &CubatureParams,
    cache_dir: &Path,
) -> Option<(ElasticQuadrature, CubatureReport)> {
    CubatureCacheFile::new(model, params, cache_dir).load()
}

/// Saves a freshly optimized cubature of `model` and `params` under `cache_dir` and returns
/// it; [`CubatureCacheFile::save`].
pub fn save_cached_cubature<M: HyperelasticMaterial>(
    model: &ReducedModel<M>,
    params: &CubatureParams,
    cache_dir: &Path,
    quadrature: ElasticQuadrature,
    report: CubatureReport,
) -> (ElasticQuadrature, CubatureReport) {
    CubatureCacheFile::new(model, params, cache_dir).save(quadrature, report)
}
