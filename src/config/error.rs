//! Why a configuration could not be used: [`ConfigError`].

use std::path::PathBuf;

/// Why a configuration could not be used.
#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    /// The file could not be read.
    #[error("{path}: {source}")]
    Io {
        /// The configuration file.
        path: PathBuf,
        /// The underlying I/O error.
        #[source]
        source: std::io::Error,
    },
    /// The file is not valid TOML, or holds a key or table that is not known; `message` says where.
    #[error("{path}: {message}")]
    Parse {
        /// The configuration file.
        path: PathBuf,
        /// The parser's message: the line, the column and what was expected.
        message: String,
    },
    /// A key's value is out of range or inconsistent with another key.
    #[error("{path}: key `{key}` = {value}: {allowed}")]
    Invalid {
        /// The configuration file.
        path: PathBuf,
        /// The key, in dotted form (`detect.background_frames`).
        key: String,
        /// The value as given.
        value: String,
        /// What is allowed instead.
        allowed: String,
    },
}
