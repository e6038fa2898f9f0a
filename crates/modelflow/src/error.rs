//! The library's one error type. Every error that comes from user input names the file and the
//! field (or line) at fault and says what was expected, so that the CLI can print it as is.

use std::path::{Path, PathBuf};

/// Errors of the modelflow library.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A file could not be read or written.
    #[error("{}: {source}", path.display())]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// A file was read but its content is not what the format requires.
    #[error("{}: {field}: {message}", path.display())]
    Invalid {
        path: PathBuf,
        /// The field, key or line at fault (e.g. `cameras[1].K`, `line 12`).
        field: String,
        message: String,
    },
    /// Inconsistent options or arguments given to a library call.
    #[error("{0}")]
    Usage(String),
}

impl Error {
    pub fn io(path: impl AsRef<Path>, source: std::io::Error) -> Self {
        Error::Io {
            path: path.as_ref().to_path_buf(),
            source,
        }
    }

    pub fn invalid(
        path: impl AsRef<Path>,
        field: impl Into<String>,
        message: impl Into<String>,
    ) -> Self {
        Error::Invalid {
            path: path.as_ref().to_path_buf(),
            field: field.into(),
            message: message.into(),
        }
    }
}

pub type Result<T, E = Error> = std::result::Result<T, E>;
