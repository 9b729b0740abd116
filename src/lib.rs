//! pathwave: a physically based wavefront path tracer on Vulkan compute. This is the API a Rust program embeds.
pub mod bench;
pub mod bvh;
/// The command line's arguments and command bodies: the binary's `main` and the Python module both drive them.
pub mod cli;
pub mod constants;
pub mod denoise;
pub mod diff;
pub mod error;
pub mod layout;
pub mod memory;
pub mod microsurface;
pub mod output;
pub mod render;
pub mod scene;
pub mod shaders;
pub mod spectrum;
pub mod variants;
pub mod viewer;
pub mod vk;

pub use error::Error;
pub use render::{
    Adaptive, BvhReads, Estimator, Film, LightSampler, RenderSettings, RenderStats, Renderer, RendererOptions,
    Schedule, Session, SpectralChoice, TextureFilter,
};
pub use scene::Scene;
