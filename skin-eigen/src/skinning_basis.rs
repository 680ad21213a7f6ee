//! The skinning basis: RKPM kernels plus eigenvector coefficients, evaluable anywhere and
//! saved to disk with a versioned header.

use std::path::Path;

use artifact::{ArtifactError, FrameError, decode_framed, encode_framed};
use nalgebra::{DMatrix, Vector3};
use rkpm_core::{Kernels, ShapeFunctionError, ShapeFunctionParams, evaluate_shape_functions};
use serde::{Deserialize, Serialize};

/// File magic of a saved basis.
const MAGIC: [u8; 8] = *b"FFBASIS\0";
/// Format version; bump on any change of [`SkinningBasis`]'s serialized layout (2: the
/// shape-function options carry the kernel window).
pub const BASIS_FORMAT_VERSION: u32 = 2;

/// Saving or loading a basis failed.
#[derive(Debug, thiserror::Error)]
pub enum BasisFileError {
    /// I/O failure.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// The underlying error.
        source: std::io::Error,
    },
    /// Not a basis file.
    #[error("{path}: not a FreeForm basis file (bad magic bytes)")]
    NotABasisFile {
        /// The file.
        path: String,
    },
    /// Written by an incompatible version.
    #[error(
        "{path}: basis format version {found}, this build reads version {expected}; rebuild the basis"
    )]
    IncompatibleVersion {
        /// The file.
        path: String,
        /// Version in the file.
        found: u32,
        /// Version this build understands.
        expected: u32,
    },
    /// Corrupt payload.
    #[error("{path}: corrupt basis data: {message}")]
    Corrupt {
        /// The file.
        path: String,
        /// Decoder message.
        message: String,
    },
}

/// How the basis was made, kept with it for reports and reproducibility.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BasisMetadata {
    /// The material model whose rest Hessian defined H_w (e.g. "stable Neo-Hookean").
    pub material: String,
    /// Number of integration points used for assembly.
    pub integration_points: usize,
    /// `λ_max(𝓜)/λ_min(𝓜)`.
    pub mass_condition_number: f64,
    /// Near-null mass directions discarded before the solve.
    pub discarded_mass_directions: usize,
    /// The dropped constant-mode eigenvalue.
    pub constant_eigenvalue: f64,
}

/// m skinning weight fields `W^j(X) = Σ_k ϕ_k(X) c_kj` (Sec. 3.2), plus the constant handle.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SkinningBasis {
    kernels: Kernels,
    shape_params: ShapeFunctionParams,
    /// c, K × m.
    coefficients: DMatrix<f64>,
    eigenvalues: Vec<f64>,
    metadata: BasisMetadata,
}

/// Weights and weight gradients at a set of points, with the constant handle first:
/// column 0 is W⁰ ≡ 1 (∇W⁰ = 0), columns 1..=m the eigen-weights.
#[derive(Clone, Debug, PartialEq)]
pub struct SkinningWeights {
    /// W, N × (m + 1) (dimensionless).
    pub weights: DMatrix<f64>,
    /// ∇W, one N × (m + 1) matrix per axis x, y, z (1/m).
    pub gradients: [DMatrix<f64>; 3],
}

impl SkinningBasis {
    /// A basis from its parts.
    ///
    /// # Panics
    /// If `coefficients` does not have one row per kernel and one column per eigenvalue.
    pub fn new(
        kernels: Kernels,
        shape_params: ShapeFunctionParams,
        coefficients: DMatrix<f64>,
        eigenvalues: Vec<f64>,
        metadata: BasisMetadata,
    ) -> Self {
        assert_eq!(
            coefficients.nrows(),
            kernels.len(),
            "one coefficient row per kernel"
        );
        assert_eq!(
            coefficients.ncols(),
            eigenvalues.len(),
            "one coefficient column per mode"
        );
        SkinningBasis {
            kernels,
            shape_params,
            coefficients,
            eigenvalues,
            metadata,
        }
    }

    /// Number m of eigen-weights (the constant handle not counted, as in the paper).
    pub fn modes(&self) -> usize {
        self.eigenvalues.len()
    }

    /// Number of handles the simulator uses, m + 1.
    pub fn handles(&self) -> usize {
        self.modes() + 1
    }

    /// The kernels.
    pub fn kernels(&self) -> &Kernels {
        &self.kernels
    }

    /// Coefficients c (K × m), `cᵀ𝓜c = I`.
    pub fn coefficients(&self) -> &DMatrix<f64> {
        &self.coefficients
    }

    /// Eigenvalues λ_1..λ_m of `H_w c = λ𝓜c`, ascending.
    pub fn eigenvalues(&self) -> &[f64] {
        &self.eigenvalues
    }

    /// How the basis was made.
    pub fn metadata(&self) -> &BasisMetadata {
        &self.metadata
    }

    /// W and ∇W at arbitrary points, constant handle first.
    ///
    /// # Errors
    /// [`ShapeFunctionError`] when a point is not reached by enough kernels (far outside the
    /// object) or is not finite.
    pub fn evaluate(&self, points: &[Vector3<f64>]) -> Result<SkinningWeights, ShapeFunctionError> {
        let shape = evaluate_shape_functions(&self.kernels, points, &self.shape_params)?;
        let (n, m) = (points.len(), self.modes());
        let mut weights = DMatrix::zeros(n, m + 1);
        let mut gradients = [
            DMatrix::zeros(n, m + 1),
            DMatrix::zeros(n, m + 1),
            DMatrix::zeros(n, m + 1),
        ];
        for i in 0..n {
            weights[(i, 0)] = 1.0;
            for ((&k, &phi), grad) in shape
                .kernels(i)
                .iter()
                .zip(shape.values(i))
                .zip(shape.gradients(i))
            {
                let row = self.coefficients.row(k as usize);
                for j in 0..m {
                    let c = row[j];
                    weights[(i, j + 1)] += phi * c;
                    for (d, g) in gradients.iter_mut().enumerate() {
                        g[(i, j + 1)] += grad[d] * c;
                    }
                }
            }
        }
        Ok(SkinningWeights { weights, gradients })
    }

    /// Writes the basis (magic, format version, bincode payload) atomically
    /// ([`artifact::write_atomically`]).
    ///
    /// # Errors
    /// [`BasisFileError::Io`].
    pub fn save(&self, path: impl AsRef<Path>) -> Result<(), BasisFileError> {
        let path = path.as_ref();
        artifact::write_atomically(path, &encode_framed(&MAGIC, BASIS_FORMAT_VERSION, self))
            .map_err(|e| match e {
                ArtifactError::Io { path, source } => BasisFileError::Io {
                    path: path.display().to_string(),
                    source,
                },
                ArtifactError::Format { path, source } => BasisFileError::Corrupt {
                    path: path.display().to_string(),
                    message: source.to_string(),
                },
            })
    }

    /// Reads a basis written by [`SkinningBasis::save`].
    ///
    /// # Errors
    /// [`BasisFileError`] for unreadable files, wrong magic, another format version, or a
    /// corrupt payload.
    pub fn load(path: impl AsRef<Path>) -> Result<Self, BasisFileError> {
        let path = path.as_ref();
        let name = path.display().to_string();
        let bytes = std::fs::read(path).map_err(|source| BasisFileError::Io {
            path: name.clone(),
            source,
        })?;
        let basis: SkinningBasis =
            decode_framed(&bytes, &MAGIC, BASIS_FORMAT_VERSION).map_err(|e| match e {
                FrameError::WrongMagic { .. } => {
                    BasisFileError::NotABasisFile { path: name.clone() }
                }
                FrameError::WrongVersion { found, expected } => {
                    BasisFileError::IncompatibleVersion {
                        path: name.clone(),
                        found,
                        expected,
                    }
                }
                FrameError::Corrupt(message) => BasisFileError::Corrupt {
                    path: name.clone(),
                    message,
                },
            })?;
        if basis.coefficients.nrows() != basis.kernels.len()
            || basis.coefficients.ncols() != basis.eigenvalues.len()
        {
            return Err(BasisFileError::Corrupt {
                path: name,
                message: "inconsistent sizes".into(),
            });
        }
        Ok(basis)
    }
}
