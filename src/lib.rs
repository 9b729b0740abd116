//! pathwave: a physically based wavefront path tracer on Vulkan compute. This is the API a Rust program embeds.
pub mod bench;
pub mod bvh;
pub mod constants;
pub mod layout;
pub mod output;
pub mod render;
pub mod scene;
pub mod shaders;
pub mod variants;
pub mod viewer;
pub mod vk;

pub use render::{BvhReads, Estimator, Film, RenderSettings, RenderStats, Renderer, Schedule, Session};
pub use scene::Scene;

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
    /// A user shader that does not compile (glslang's report, with file:line) or a shader folder that cannot be read.
    #[error("{0}")]
    Shader(String),
    #[error("the validation layer reported {count} error(s); the first: {first}")]
    Validation { count: usize, first: String },
}
