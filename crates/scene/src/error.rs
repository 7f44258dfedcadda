//! Import errors: every one names the file and the place in it.

use std::path::PathBuf;

/// An error while importing a scene.
#[derive(Debug, thiserror::Error)]
pub enum ImportError {
    /// The file could not be read.
    #[error("{path}: {cause}")]
    Io {
        /// File.
        path: PathBuf,
        /// Cause (in the message, so not also a `source()`: a chain printed whole, as
        /// `anyhow`'s `{:#}` does, said it twice).
        cause: std::io::Error,
    },
    /// Bad content at a line.
    #[error("{path}:{line}: {msg}")]
    Parse {
        /// File.
        path: PathBuf,
        /// Line number (1-based).
        line: usize,
        /// What is wrong.
        msg: String,
    },
    /// Bad content at a line and column (XML).
    #[error("{path}:{line}:{column}: {msg}")]
    At {
        /// File.
        path: PathBuf,
        /// Line (1-based).
        line: u32,
        /// Column (1-based).
        column: u32,
        /// What is wrong.
        msg: String,
    },
    /// Bad content somewhere without a line (binary formats, glTF paths).
    #[error("{path}: {at}: {msg}")]
    Invalid {
        /// File.
        path: PathBuf,
        /// Where: a glTF JSON path, "header", a byte offset.
        at: String,
        /// What is wrong.
        msg: String,
    },
    /// The file type is not known.
    #[error("{0}: unknown scene format (expected .obj, .obj.gz, .ply, .ply.gz, .gltf, .glb or Mitsuba .xml)")]
    UnknownFormat(PathBuf),
}
