//! Every file format agentstar reads or writes: captures (capture/v1), `pose.json`, mesh
//! files (OBJ, STL, PLY, GLB), URDF models, GLB and URDF export, images and masks.
//!
//! This is the only library crate that touches the file system. Every writer goes through
//! [`atomic::write_atomic`] (temporary file, then rename), so a failure never leaves a
//! half-written file behind. Bad input is reported with the file and what is wrong.

pub mod animation;
pub mod arctic;
pub mod atomic;
pub mod bop;
pub mod cameras;
pub mod capture;
pub mod capture_writer;
pub mod export;
pub mod gt;
pub mod hot3d;
pub mod images;
mod import_common;
pub mod ledger;
pub mod meshio;
pub mod npz;
pub mod posefile;
pub mod scenefile;
pub mod urdf;
pub mod video;

use std::path::{Path, PathBuf};

/// A data error names the file and what is wrong with it.
#[derive(Debug, thiserror::Error)]
pub enum DataError {
    #[error("{path}: {message}")]
    Invalid { path: PathBuf, message: String },
    /// The message already holds the I/O error, so it is not also reported as a source
    /// (which would print it twice in an error chain).
    #[error("{path}: {error}")]
    Io {
        path: PathBuf,
        error: std::io::Error,
    },
    #[error("{0}")]
    Scene(#[from] agentstar_scene::SceneError),
}

impl DataError {
    pub fn invalid(path: impl AsRef<Path>, message: impl Into<String>) -> Self {
        DataError::Invalid {
            path: path.as_ref().to_path_buf(),
            message: message.into(),
        }
    }
    pub fn io(path: impl AsRef<Path>, error: std::io::Error) -> Self {
        DataError::Io {
            path: path.as_ref().to_path_buf(),
            error,
        }
    }
}

pub type Result<T, E = DataError> = std::result::Result<T, E>;

/// Reads a whole file, naming it in the error.
pub fn read_bytes(path: &Path) -> Result<Vec<u8>> {
    std::fs::read(path).map_err(|e| DataError::io(path, e))
}

pub fn read_text(path: &Path) -> Result<String> {
    std::fs::read_to_string(path).map_err(|e| DataError::io(path, e))
}
