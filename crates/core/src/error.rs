//! The one error type of wgslam: every way a user's input or machine can make a run fail.
//!
//! Panics are reserved for broken internal contracts; anything a user can cause is a
//! variant here, with enough context (file, line, numbers) to fix it without a debugger.

use std::path::PathBuf;

/// Everything that can go wrong in a wgslam run that is not a bug in wgslam.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A file or directory the run needs does not exist or cannot be read.
    #[error("cannot read {path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// An output file or directory cannot be created, written or renamed into place.
    #[error("cannot write {path}: {source}")]
    Write {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// A report (JSON) could not be encoded; names what was being encoded.
    #[error("cannot encode {what}: {why}")]
    Encode { what: String, why: String },
    /// A file exists but its contents are not what the format requires.
    #[error("{path}: {what}")]
    Format { path: PathBuf, what: String },
    /// A text file has a line that does not parse (1-based line number).
    #[error("{path}:{line}: {what}")]
    Parse {
        path: PathBuf,
        line: usize,
        what: String,
    },
    /// An image decodes but has the wrong pixel format or size for its role.
    #[error("{path}: {what}")]
    Image { path: PathBuf, what: String },
    /// A command-line value or option combination that cannot be honoured.
    #[error("invalid argument: {0}")]
    Argument(String),
    /// No usable GPU adapter (Vulkan, Metal or DX12) was found.
    #[error("no GPU adapter found ({0}); install a Vulkan driver (on Debian/Ubuntu: apt-get install mesa-vulkan-drivers) or run with --backend cpu")]
    NoAdapter(String),
    /// The GPU device could not be created, was lost, or reported a validation error.
    #[error("GPU error: {0}")]
    Gpu(String),
    /// The surfel map would exceed a buffer or device limit.
    #[error("map capacity exceeded: {0}")]
    Capacity(String),
    /// A numerical step could not produce a trustworthy answer (e.g. a singular system).
    #[error("numerical failure: {0}")]
    Numerical(String),
    /// A batch finished with failed jobs, or two batches' numbers differ.
    #[error("batch: {0}")]
    Batch(String),
    /// Ctrl-C or SIGTERM stopped the work; what it says was left unfinished.
    #[error("interrupted: {0}")]
    Interrupted(String),
}

/// Result with the wgslam [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;

impl Error {
    /// A write error on `path` (creating, writing, syncing or renaming an output).
    pub fn write(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Error::Write {
            path: path.into(),
            source,
        }
    }
    /// An encoding failure of `what` (a report or result file).
    pub fn encode(what: impl Into<String>, why: impl std::fmt::Display) -> Self {
        Error::Encode {
            what: what.into(),
            why: why.to_string(),
        }
    }
    /// A read error on `path` (opening, reading or listing an input).
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Error::Io {
            path: path.into(),
            source,
        }
    }
    /// A format error in `path`.
    pub fn format(path: impl Into<PathBuf>, what: impl Into<String>) -> Self {
        Error::Format {
            path: path.into(),
            what: what.into(),
        }
    }
    /// A parse error at 1-based `line` of `path`.
    pub fn parse(path: impl Into<PathBuf>, line: usize, what: impl Into<String>) -> Self {
        Error::Parse {
            path: path.into(),
            line,
            what: what.into(),
        }
    }
}
