//! `pathwave view`: the window's arguments, handed to the viewer.
use super::args::*;
use super::values::*;
use crate::output::Aov;
use crate::{output, RenderSettings};
use anyhow::Result;
use std::path::PathBuf;

#[derive(clap::Args)]
pub struct ViewArgs {
    /// Window size as WIDTHxHEIGHT.
    #[arg(long, default_value = "640x480", value_parser = parse_size, allow_hyphen_values = true)]
    pub size: (u32, u32),
    #[command(flatten)]
    pub common: SceneArgs,
    /// Exposure in stops (+ and - change it in the window), -64 to 64.
    #[arg(long, default_value = "0", value_parser = parse_exposure, allow_hyphen_values = true)]
    pub exposure: f32,
    /// Tone curve after --exposure (T cycles through them in the window; P's PNG uses the one shown): none
    /// (linear, clipped), aces (Narkowicz's fit), agx (Sobotka's AgX) or pbr-neutral (Khronos PBR Neutral).
    #[arg(long, value_enum, default_value = "aces")]
    pub tonemap: output::ToneCurve,
    /// Shader folder to use and watch: edited stages are rebuilt while the window stays open.
    #[arg(long)]
    pub shader_dir: Option<PathBuf>,
    /// Close after this many frames (for scripts and tests).
    #[arg(long, value_parser = positive)]
    pub frames: Option<u32>,
    /// Where P saves (default pathwave.exr and pathwave.png), and what --frames writes before closing.
    #[arg(long)]
    pub screenshot: Option<PathBuf>,
    /// Milliseconds per frame the adaptive sampler aims at.
    #[arg(long, default_value = "33", value_parser = positive)]
    pub frame_budget_ms: u32,
    /// Start with the animation playing (space toggles it).
    #[arg(long)]
    pub play: bool,
    /// Start showing an AOV or debug view (G cycles them): albedo, normal, depth, geometric-normal, shading-normal,
    /// uv, bvh-cost, light-pick.
    #[arg(long, value_parser = parse_view_aov)]
    pub show: Option<Aov>,
    /// Start denoising the still image (Shift+D toggles it); Open Image Denoise as for `render --denoise`.
    #[arg(long)]
    pub denoise: bool,
}

pub fn view(args: ViewArgs) -> Result<()> {
    if let Some(out) = &args.screenshot {
        output::check_writable(out)?;
        output::check_not_input(out, &[("scene", args.common.scene.as_path())])?;
    }
    let scene = args.common.load()?;
    let animation = match &args.common.animation {
        Some(a) => Some(scene.rig.find_animation(a).map_err(|e| anyhow::anyhow!(e))?),
        None => None,
    };
    let options = crate::viewer::ViewOptions {
        time: args.common.time.unwrap_or(0.0),
        animation,
        shutter: args.common.shutter,
        play: args.play,
        device: args.common.device.clone().unwrap_or_default(),
        settings: RenderSettings {
            width: args.size.0,
            height: args.size.1,
            // Only sizes the paths in flight: up to this many samples per pixel share a pass.
            spp: 256,
            spectral: args.common.spectral,
            ..args.common.settings()
        },
        rgb: args.common.rgb,
        exposure: args.exposure,
        tonemap: args.tonemap,
        shader_dir: args.shader_dir,
        traversal: args.common.traversal,
        frames: args.frames,
        screenshot: args.screenshot,
        budget: std::time::Duration::from_millis(args.frame_budget_ms as u64),
        load: args.common.limits.options(args.common.camera),
        show: args.show,
        denoise: args.denoise,
    };
    crate::viewer::run(scene, options)?;
    Ok(())
}
