//! The arguments `render`, `view` and `info` share: how far a scene's files may reach, the environment, the
//! scene and its camera, and the render settings built from them.
use super::info::instancing_rule;
use super::values::*;
use crate::vk::DeviceChoice;
use crate::{scene, LightSampler, RenderSettings, SpectralChoice, TextureFilter};
use anyhow::{bail, Result};
use std::path::PathBuf;

#[derive(clap::Args)]
pub struct LoadArgs {
    /// Let buffer and image URIs name files outside the scene's folder (absolute paths, `..`, `file:`, symlinks
    /// leading out). Only for scenes you trust.
    #[arg(long)]
    pub allow_outside_paths: bool,
    /// Largest image (texture or environment map) in pixels, checked from its header before it is decoded.
    #[arg(long, default_value_t = scene::DEFAULT_MAX_TEXTURE_PIXELS, value_parser = clap::value_parser!(u64).range(1..), allow_hyphen_values = true)]
    pub max_texture_pixels: u64,
    /// Host memory the scene may take once read, placed and packed, in bytes or with a suffix (512M, 8G); a scene
    /// that would need more is refused before it is built. Default: half of the available memory, at most 8 GiB.
    #[arg(long, value_parser = crate::memory::parse_size, allow_hyphen_values = true)]
    pub max_memory: Option<u64>,
    /// The KHR_materials_variants variant to render, by name (`pathwave info` lists them; the viewer cycles them
    /// with V). Default: the primitives' own materials.
    #[arg(long)]
    pub variant: Option<String>,
    /// Refuse a scene whose image files are missing, as a render farm may want, instead of rendering its materials
    /// without those textures (with a warning naming each image).
    #[arg(long)]
    pub strict: bool,
}

impl LoadArgs {
    pub fn options(&self, camera: Option<usize>) -> scene::LoadOptions {
        scene::LoadOptions {
            camera,
            allow_outside_paths: self.allow_outside_paths,
            max_texture_pixels: self.max_texture_pixels,
            max_memory: self.max_memory(),
            variant: self.variant.clone(),
            strict: self.strict,
        }
    }

    pub fn max_memory(&self) -> u64 {
        self.max_memory.unwrap_or_else(crate::memory::default_max_memory)
    }

    /// The scene, refused if reading it or placing its instances would not fit the host memory budget.
    pub fn load(&self, path: &std::path::Path, camera: Option<usize>) -> Result<scene::Scene> {
        let scene = scene::load_with(path, &self.options(camera))?;
        scene.check_host_memory(self.max_memory(), instancing_rule())?;
        Ok(scene)
    }
}

/// The environment options `render` and `view` share.
#[derive(clap::Args)]
pub struct EnvArgs {
    /// Environment map lighting the scene from infinitely far away: equirectangular .hdr or .exr.
    #[arg(long, conflicts_with = "env_color")]
    pub env: Option<PathBuf>,
    /// A uniform environment colour instead of a map: linear RGB radiance, e.g. 1,1,1.
    #[arg(long, value_parser = parse_rgb, allow_hyphen_values = true)]
    pub env_color: Option<[f32; 3]>,
    /// Multiplies the environment's radiance (0 to 1e10).
    #[arg(long, default_value = "1", value_parser = parse_intensity, allow_hyphen_values = true)]
    pub env_intensity: f32,
    /// Turns the environment about the up axis (+y), in degrees (-360 to 360).
    #[arg(long, default_value = "0", value_parser = parse_rotation, allow_hyphen_values = true)]
    pub env_rotation: f32,
    /// Keeps the environment out of camera rays; it still lights the scene.
    #[arg(long)]
    pub hide_env: bool,
}

impl EnvArgs {
    pub fn environment(&self, max_pixels: u64) -> Result<Option<scene::Environment>> {
        let mut environment = match (&self.env, self.env_color) {
            (Some(path), _) => Some(scene::Environment::load_limited(path, self.env_intensity, max_pixels)?),
            (None, Some(rgb)) => {
                let radiance = rgb.map(|c| c * self.env_intensity);
                if radiance.iter().any(|c| *c > scene::RADIANCE_MAX) {
                    bail!(
                        "--env-color times --env-intensity is {radiance:?}, above the radiance limit of {:e} per \
                         channel",
                        scene::RADIANCE_MAX
                    );
                }
                Some(scene::Environment::constant(radiance))
            }
            (None, None) => None,
        };
        if let Some(env) = &mut environment {
            env.rotation = self.env_rotation.to_radians();
        }
        Ok(environment)
    }
}

/// The scene, camera, device and path options `render` and `view` share.
#[derive(clap::Args)]
pub struct SceneArgs {
    /// The glTF (.gltf or .glb) scene.
    pub scene: PathBuf,
    /// Which camera of the file to use (to start from, in the viewer), counting from 0.
    #[arg(long, allow_hyphen_values = true)]
    pub camera: Option<usize>,
    /// Vulkan device by index or by part of its name (see `pathwave info --devices`).
    #[arg(long)]
    pub device: Option<DeviceChoice>,
    /// How rays find surfaces: `compute` (pathwave's BVH, every device), `ray-query` (the device's acceleration
    /// structures, where `info --devices` says it has ray queries) or `auto` (ray queries on GPUs that have them).
    /// Default: PATHWAVE_TRAVERSAL, else auto.
    #[arg(long, value_enum)]
    pub traversal: Option<crate::render::Traversal>,
    /// Longest path in bounces (default: unbounded, ended by Russian roulette).
    #[arg(long, value_parser = parse_max_depth, allow_hyphen_values = true)]
    pub max_depth: Option<u32>,
    /// Seed of the random sequences; the same seed gives the same bytes.
    #[arg(long, default_value = "0", allow_hyphen_values = true)]
    pub seed: u32,
    /// Thin-lens aperture radius in scene units (metres for glTF); 0, the default, is a pinhole. In the viewer, F
    /// toggles depth of field and a right click focuses.
    #[arg(long, default_value = "0", value_parser = parse_aperture, allow_hyphen_values = true)]
    pub aperture: f32,
    /// Distance to the plane in focus along the view direction (default: the camera's distance to the scene's centre).
    #[arg(long, value_parser = parse_focus_distance, allow_hyphen_values = true)]
    pub focus_distance: Option<f32>,
    /// Render the scene as its animations place it at this time, in seconds (default 0); keys outside an
    /// animation's range hold its first or last values.
    #[arg(long, value_parser = parse_time, allow_hyphen_values = true)]
    pub time: Option<f32>,
    /// The animation that plays, by index or by name (default: every channel of the file, as viewers play them).
    #[arg(long)]
    pub animation: Option<String>,
    /// Seconds the shutter stays open from --time (or each frame's time): what moves meanwhile (the camera, nodes,
    /// skinned and morphed vertices) is blurred. 0, the default, is an instant and costs nothing.
    #[arg(long, default_value = "0", value_parser = parse_shutter, allow_hyphen_values = true)]
    pub shutter: f32,
    /// Spectral transport: every path carries four wavelengths and colours become spectra at them
    /// (docs/guide/spectral.md). Scenes with dispersion (KHR_materials_dispersion) render spectrally without it.
    #[arg(long, conflicts_with = "rgb")]
    pub spectral: bool,
    /// RGB transport even for a scene with dispersion, which is then ignored (with a warning).
    #[arg(long)]
    pub rgb: bool,
    /// How next-event estimation picks a light: bvh (by importance at the shading point, from a light BVH over the
    /// emitters), power (in proportion to power, the same everywhere) or uniform. docs/guide/light-selection.md.
    #[arg(long, value_enum, default_value = "bvh")]
    pub light_sampler: LightSampler,
    /// How minified textures are read: trilinear (from mip levels at the pixel's footprint, prefiltered) or
    /// bilinear (from the full-resolution image at any distance, as point sampling converges to).
    /// docs/guide/materials.md.
    #[arg(long, value_enum, default_value = "trilinear")]
    pub texture_filter: TextureFilter,
    #[command(flatten)]
    pub view: CameraArgs,
    #[command(flatten)]
    pub env: EnvArgs,
    #[command(flatten)]
    pub limits: LoadArgs,
}

/// A camera given on the command line (docs/guide/rendering.md, "Cameras"), replacing or changing the file's.
#[derive(clap::Args)]
pub struct CameraArgs {
    /// Where the camera stands, X,Y,Z in scene units; with --target.
    #[arg(long, value_parser = parse_point, requires = "target", conflicts_with = "orbit", allow_hyphen_values = true)]
    pub eye: Option<[f32; 3]>,
    /// The point the camera looks at, X,Y,Z; alone, the file's camera turns to it; with --orbit, the orbit's centre
    /// (default: the centre of the scene's bounds).
    #[arg(long, value_parser = parse_point, allow_hyphen_values = true)]
    pub target: Option<[f32; 3]>,
    /// The image's up direction, X,Y,Z (default 0,1,0).
    #[arg(long, value_parser = parse_up, allow_hyphen_values = true)]
    pub up: Option<[f32; 3]>,
    /// Vertical field of view in degrees, (0, 180); alone, it changes only the field of view of the file's camera.
    #[arg(long, value_parser = parse_yfov, allow_hyphen_values = true)]
    pub yfov: Option<f64>,
    /// AZIMUTH,ELEVATION,DISTANCE: a camera looking at --target (default: the bounds' centre) from this direction
    /// (azimuth in degrees from +z towards +x, elevation in degrees up) and distance.
    #[arg(long, value_parser = parse_orbit, allow_hyphen_values = true)]
    pub orbit: Option<[f32; 3]>,
}

impl CameraArgs {
    pub fn spec(&self) -> scene::CameraSpec {
        let v = |p: Option<[f32; 3]>| p.map(glam::Vec3::from);
        scene::CameraSpec {
            eye: v(self.eye),
            target: v(self.target),
            up: v(self.up),
            yfov: self.yfov,
            orbit: self.orbit,
        }
    }
}

impl SceneArgs {
    /// The scene posed at --time with --animation and lit by the environment the options ask for, refused if it
    /// would not fit the host budget.
    pub fn load(&self) -> Result<scene::Scene> {
        self.load_at(self.time.unwrap_or(0.0))
    }

    /// `load`, at `time` rather than --time's.
    pub fn load_at(&self, time: f32) -> Result<scene::Scene> {
        let mut scene = self.limits.load(&self.scene, self.camera)?;
        self.aim(&mut scene)?;
        self.pose(&mut scene, time)?;
        scene.environment = self.env.environment(self.limits.max_texture_pixels)?;
        Ok(scene)
    }

    /// Gives `scene` the camera --eye, --target, --up, --yfov and --orbit ask for, if any (before posing, so that
    /// an orbit's default centre is the bounds' centre of the file's own pose).
    pub fn aim(&self, scene: &mut scene::Scene) -> Result<()> {
        let spec = self.view.spec();
        let o = spec
            .resolve(scene)
            .map_err(|e| anyhow::anyhow!("{}: the command line's camera: {e}", self.scene.display()))?;
        if let Some(o) = o {
            scene.override_camera(o);
        }
        Ok(())
    }

    /// Poses `scene` at `time` with --animation and --shutter, if that changes it; refused if the pose would not
    /// fit the host budget.
    pub fn pose(&self, scene: &mut scene::Scene, time: f32) -> Result<()> {
        let pose = self.pose_time(scene, time)?;
        if scene.rig.animated() && (pose != scene.rig.posed || self.shutter > 0.0) {
            scene.pose_shutter(pose, self.shutter)?;
            scene.check_host_memory(self.limits.max_memory(), instancing_rule())?;
        }
        Ok(())
    }

    /// The pose `--animation` and `time` ask for; a time on a file without animations is warned about.
    pub fn pose_time(&self, scene: &scene::Scene, time: f32) -> Result<scene::PoseTime> {
        let animation = match &self.animation {
            Some(a) => Some(
                scene
                    .rig
                    .find_animation(a)
                    .map_err(|e| anyhow::anyhow!("{}: {e}", self.scene.display()))?,
            ),
            None => None,
        };
        if (self.time.is_some() || self.shutter > 0.0) && !scene.rig.animated() {
            eprintln!(
                "warning: {}: the file has no animations, so --time and --shutter change nothing",
                self.scene.display()
            );
        }
        Ok(scene::PoseTime { time, animation })
    }

    /// Render settings from these options; the caller sets the size and samples.
    /// Whether the render is spectral: --spectral, or a scene with dispersion unless --rgb. Says which, on stderr, when
    /// the scene decided.
    pub fn spectral(&self, scene: &scene::Scene) -> bool {
        let choice = SpectralChoice::new(self.spectral, self.rgb, scene.wants_spectral());
        match choice {
            SpectralChoice::RgbOverDispersion => eprintln!(
                "warning: {}: --rgb renders without dispersion (KHR_materials_dispersion needs spectral transport)",
                self.scene.display()
            ),
            SpectralChoice::Dispersion => eprintln!(
                "{}: dispersion (KHR_materials_dispersion): rendering spectrally (--rgb to force RGB)",
                self.scene.display()
            ),
            SpectralChoice::Asked | SpectralChoice::Rgb => {}
        }
        choice.spectral()
    }

    pub fn settings(&self) -> RenderSettings {
        RenderSettings {
            max_depth: self.max_depth,
            seed: self.seed,
            hide_environment: self.env.hide_env,
            aperture: self.aperture,
            focus_distance: self.focus_distance,
            light_sampler: self.light_sampler,
            texture_filter: self.texture_filter,
            ..Default::default()
        }
    }
}
