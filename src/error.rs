//! The library's error type: every failure names what went wrong, and for files, which file.
use std::path::PathBuf;

#[derive(Debug, thiserror::Error)]
pub enum Error {
    #[error("{}: {message}", path.display())]
    Scene { path: PathBuf, message: String },
    #[error("{}: {message}", path.display())]
    Output { path: PathBuf, message: String },
    #[error("Vulkan: {0}")]
    Vulkan(String),
    #[error("{0}")]
    Settings(String),
    /// Work or memory past a limit (the host budget of --max-memory, the device's memory, traversal's index range):
    /// refused before it is allocated.
    #[error("{0}")]
    Limit(String),
    /// A user shader that does not compile (glslang's report, with file:line) or a shader folder that cannot be read.
    #[error("{0}")]
    Shader(String),
    #[error("the validation layer reported {count} error(s); the first: {first}")]
    Validation { count: usize, first: String },
}
