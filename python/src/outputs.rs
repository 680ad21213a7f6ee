//! What a state gives at points: the stress, deformed splats.

use freeform::StressField;
use freeform::reduced_sim::DeformationMap;
use hyperelastic::{MaterialField, StableNeoHookean};
use nalgebra::{Matrix3, Vector3};
use numpy::ndarray::{Array1, Array2, Array3};
use numpy::{IntoPyArray, PyArray1, PyArray2, PyArray3};
use pyo3::prelude::*;
use skin_eigen::SkinningBasis;

use crate::errors::{self, value_error};
use crate::material::lame_of;
use crate::splats::PySplats;

/// `splats` (rest centres, m) deformed by `basis` at coordinates `z`, and the number of splats
/// with det F ≤ 0.
pub(crate) fn deform_splats(
    py: Python<'_>,
    basis: &SkinningBasis,
    z: &[f64],
    splats: &PySplats,
) -> PyResult<(PySplats, usize)> {
    let table = &splats.inner;
    let (deformed, inverted) = py
        .detach(|| -> Result<_, Box<dyn std::error::Error + Send + Sync>> {
            let map = DeformationMap::new(basis, &table.positions())?;
            Ok(table.deformed(&map.positions(z), &map.deformation_gradients(z))?)
        })
        .map_err(|e| errors::raise::<errors::BasisError>(e.as_ref()))?;
    Ok((PySplats { inner: deformed }, inverted))
}

/// The stress of `material` with deformation gradients `f` at rest positions `rest`: Cauchy σ
/// `(n, 3, 3)`, principal stresses `(n, 3)`, von Mises `(n,)` (Pa), inverted points.
#[allow(clippy::type_complexity)]
pub(crate) fn stress_arrays<'py>(
    py: Python<'py>,
    material: &MaterialField,
    rest: &[Vector3<f64>],
    f: &[Matrix3<f64>],
) -> PyResult<(
    Bound<'py, PyArray3<f64>>,
    Bound<'py, PyArray2<f64>>,
    Bound<'py, PyArray1<f64>>,
    Vec<usize>,
)> {
    let lame = lame_of(material, rest)?;
    let field = StressField::new(&StableNeoHookean, &lame, f).map_err(|e| value_error(&e))?;
    let samples = &field.samples;
    let n = samples.len();
    let cauchy = Array3::from_shape_fn((n, 3, 3), |(i, r, c)| samples[i].cauchy[(r, c)]);
    let principal = Array2::from_shape_fn((n, 3), |(i, k)| samples[i].principal[k]);
    let von_mises = Array1::from_iter(samples.iter().map(|s| s.von_mises));
    Ok((
        cauchy.into_pyarray(py),
        principal.into_pyarray(py),
        von_mises.into_pyarray(py),
        field.inverted,
    ))
}

/// `n` 3 × 3 matrices as an `(n, 3, 3)` array.
pub(crate) fn matrices_array<'py>(
    py: Python<'py>,
    m: &[Matrix3<f64>],
) -> Bound<'py, PyArray3<f64>> {
    Array3::from_shape_fn((m.len(), 3, 3), |(i, r, c)| m[i][(r, c)]).into_pyarray(py)
}
