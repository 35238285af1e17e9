//! Small hand-written neural networks: dense layers, MLPs, Gaussian heads, Adam.
//!
//! Conventions shared by every type here:
//! - `f32` throughout; parameters, gradients and activations live in `DMatrix<f32>`.
//! - A batch is a matrix with one **column per sample** (features × batch, column-major), so a
//!   sample's features are contiguous and copying observations in and out is a slice copy.
//! - Matrix products go through [`gemm::gemm`] (matrixmultiply's `sgemm` with explicit
//!   strides, or [`gemm_unpacked`] with the same bits), never nalgebra's own `gemm` on views
//!   (dimforge/nalgebra#1616).
//! - Forward and backward passes write into caller-owned workspaces sized for the batch, so
//!   the training hot path does not allocate.
//! - Backward passes overwrite gradients (they do not accumulate).

pub mod adam;
pub mod codec;
pub mod dense;
pub mod gaussian;
#[allow(unsafe_code)]
pub mod gemm;
#[allow(unsafe_code)]
pub mod gemm_unpacked;
pub mod mlp;

pub use adam::{Adam, AdamConfig};
pub use codec::{ByteReader, ByteWriter, CodecError, FileError};
pub use dense::Dense;
pub use mlp::{BackwardMode, Mlp, MlpArch, MlpWorkspace};

/// Errors of the neural-network layer (loading parameters, mismatched shapes).
#[derive(Debug, thiserror::Error)]
pub enum NnError {
    #[error(transparent)]
    File(#[from] FileError),
    #[error("{path}: network architecture {found} does not match the expected {expected}")]
    ArchitectureMismatch {
        path: String,
        found: String,
        expected: String,
    },
}
