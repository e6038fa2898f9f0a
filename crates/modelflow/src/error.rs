//! The library's one error type. Every error that comes from user input names the file and the
//! field (or line) at fault, or the option and its valid values, and says what was expected, so
//! that the CLI can print it as it is.

use std::path::{Path, PathBuf};

/// Errors of the modelflow library. New variants may be added: match with a `_` arm.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// A file or folder could not be read or written. (The OS error is part of the message and
    /// deliberately not a `source`, so that a printed chain does not repeat it.)
    #[error("{}: {error}", path.display())]
    Io {
        path: PathBuf,
        error: std::io::Error,
    },
    /// A file was read but its content is not what the format requires.
    #[error("{}: {field}: {message}", path.display())]
    Invalid {
        path: PathBuf,
        /// The field, key or line at fault (e.g. `cameras[1].K`, `line 12`).
        field: String,
        message: String,
    },
    /// An option (of a library call or a command) has a value outside its valid range.
    #[error("{option} {value}: expected {expected}")]
    Option {
        /// The option's name as the user knows it (e.g. `--cameras`, `run name`).
        option: String,
        /// The value given, as written.
        value: String,
        /// The valid values.
        expected: String,
    },
    /// Inputs that are each valid but do not fit together (e.g. three images for two cameras,
    /// a run whose meshes have another vertex count than the scene's).
    #[error("{what}: expected {expected}, found {found}")]
    Mismatch {
        what: String,
        expected: String,
        found: String,
    },
    /// A run folder cannot be used as asked: it holds other files, another run, or nothing to
    /// resume. `reason` says which and what to do.
    #[error("run folder {}: {reason}", dir.display())]
    RunFolder { dir: PathBuf, reason: String },
    /// Something went wrong with one run of several (in a report); the inner error is part of
    /// the message.
    #[error("run {name} ({}): {error}", dir.display())]
    InRun {
        name: String,
        dir: PathBuf,
        error: Box<Error>,
    },
    /// A frame's images could not be read in the middle of a run; every frame before it is
    /// complete (a run folder holding them can be resumed once the file is repaired).
    #[error("frame {frame}: {error}")]
    AtFrame { frame: u32, error: Box<Error> },
    /// The run was stopped on request (e.g. Ctrl-C); every frame up to `last_complete` is
    /// complete (a run folder holding them can be resumed).
    #[error("interrupted on request; every frame up to {last_complete} is complete")]
    Interrupted { last_complete: u32 },
    /// The GPU path (`--device gpu`) could not be used: no CUDA driver or NVRTC library, no
    /// device, a kernel that did not compile, or a call on the device that failed. The message
    /// says which and what to do.
    #[error("GPU: {0}")]
    Gpu(String),
}

impl Error {
    pub fn io(path: impl AsRef<Path>, error: std::io::Error) -> Self {
        Error::Io {
            path: path.as_ref().to_path_buf(),
            error,
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

    pub fn option(
        option: impl Into<String>,
        value: impl ToString,
        expected: impl Into<String>,
    ) -> Self {
        Error::Option {
            option: option.into(),
            value: value.to_string(),
            expected: expected.into(),
        }
    }

    pub fn mismatch(
        what: impl Into<String>,
        expected: impl ToString,
        found: impl ToString,
    ) -> Self {
        Error::Mismatch {
            what: what.into(),
            expected: expected.to_string(),
            found: found.to_string(),
        }
    }

    pub fn run_folder(dir: impl AsRef<Path>, reason: impl Into<String>) -> Self {
        Error::RunFolder {
            dir: dir.as_ref().to_path_buf(),
            reason: reason.into(),
        }
    }
}

pub type Result<T, E = Error> = std::result::Result<T, E>;
