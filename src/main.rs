//! The pathwave command line: render, view, bench, info, export-shaders.
use anyhow::{bail, Context as _, Result};
use clap::{Parser, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};
use pathwave::output::Aov;
use pathwave::vk::DeviceChoice;
use pathwave::{output, scene, Estimator, LightSampler, RenderSettings, Renderer};
use std::path::PathBuf;

mod cli_values;
mod film_cli;
mod interrupt;
use cli_values::*;
use std::time::Instant;

#[derive(Parser)]
#[command(
    name = "pathwave",
    version,
    about = "A physically based wavefront path tracer on Vulkan compute"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Render a glTF scene to an EXR (linear) or PNG (sRGB) file.
    Render(RenderArgs),
    /// Show a scene in a window, rendering progressively; see README for the controls.
    View(ViewArgs),
    /// Describe a scene (triangles, materials, lights, BVH), take a census of a folder of scenes, or list the
    /// Vulkan devices.
    Info {
        /// The glTF (.gltf or .glb) scene, or a folder: every .gltf and .glb under it, each loaded as `render` would,
        /// one line each, then the extensions they use and how many files use each.
        scene: Option<PathBuf>,
        /// List the Vulkan devices instead (their index is what --device takes).
        #[arg(long)]
        devices: bool,
        #[command(flatten)]
        limits: LoadArgs,
    },
    /// Merge film files of disjoint sample ranges of one render (`render --samples` or `--part`) into one film
    /// file, bit-identical to rendering their union at once.
    Merge(film_cli::MergeArgs),
    /// Compare a render with a reference: a per-pixel statistical test when either carries film statistics, else
    /// relMSE and FLIP against thresholds. Exit 0: consistent; 1: they differ; 2: an error.
    Diff(film_cli::DiffArgs),
    /// Measure a fixed set of renders (Cornell box, glass, a 1M-triangle terrain): a table, and JSON with --json.
    Bench(BenchArgs),
    /// Write the built-in GLSL stages (and include/) into a folder, to edit and use with --shader-dir.
    ExportShaders {
        /// The folder to write into (created if missing).
        dir: PathBuf,
    },
}

/// How far a scene's files may reach, and how large its images may be: `render`, `view` and `info` share them.
#[derive(clap::Args)]
struct LoadArgs {
    /// Let buffer and image URIs name files outside the scene's folder (absolute paths, `..`, `file:`, symlinks
    /// leading out). Only for scenes you trust.
    #[arg(long)]
    allow_outside_paths: bool,
    /// Largest image (texture or environment map) in pixels, checked from its header before it is decoded.
    #[arg(long, default_value_t = scene::DEFAULT_MAX_TEXTURE_PIXELS, value_parser = clap::value_parser!(u64).range(1..), allow_hyphen_values = true)]
    max_texture_pixels: u64,
    /// Host memory the scene may take once read, placed and packed, in bytes or with a suffix (512M, 8G); a scene
    /// that would need more is refused before it is built. Default: half of the available memory, at most 8 GiB.
    #[arg(long, value_parser = pathwave::memory::parse_size, allow_hyphen_values = true)]
    max_memory: Option<u64>,
    /// The KHR_materials_variants variant to render, by name (`pathwave info` lists them; the viewer cycles them
    /// with V). Default: the primitives' own materials.
    #[arg(long)]
    variant: Option<String>,
    /// Refuse a scene whose image files are missing, as a render farm may want, instead of rendering its materials
    /// without those textures (with a warning naming each image).
    #[arg(long)]
    strict: bool,
}

impl LoadArgs {
    fn options(&self, camera: Option<usize>) -> scene::LoadOptions {
        scene::LoadOptions {
            camera,
            allow_outside_paths: self.allow_outside_paths,
            max_texture_pixels: self.max_texture_pixels,
            max_memory: self.max_memory(),
            variant: self.variant.clone(),
            strict: self.strict,
        }
    }

    fn max_memory(&self) -> u64 {
        self.max_memory.unwrap_or_else(pathwave::memory::default_max_memory)
    }

    /// The scene, refused if reading it or placing its instances would not fit the host memory budget.
    fn load(&self, path: &std::path::Path, camera: Option<usize>) -> Result<scene::Scene> {
        let scene = scene::load_with(path, &self.options(camera))?;
        scene.check_host_memory(self.max_memory(), instancing_rule())?;
        Ok(scene)
    }
}

/// The environment options `render` and `view` share.
#[derive(clap::Args)]
struct EnvArgs {
    /// Environment map lighting the scene from infinitely far away: equirectangular .hdr or .exr.
    #[arg(long, conflicts_with = "env_color")]
    env: Option<PathBuf>,
    /// A uniform environment colour instead of a map: linear RGB radiance, e.g. 1,1,1.
    #[arg(long, value_parser = parse_rgb, allow_hyphen_values = true)]
    env_color: Option<[f32; 3]>,
    /// Multiplies the environment's radiance (0 to 1e10).
    #[arg(long, default_value = "1", value_parser = parse_intensity, allow_hyphen_values = true)]
    env_intensity: f32,
    /// Turns the environment about the up axis (+y), in degrees (-360 to 360).
    #[arg(long, default_value = "0", value_parser = parse_rotation, allow_hyphen_values = true)]
    env_rotation: f32,
    /// Keeps the environment out of camera rays; it still lights the scene.
    #[arg(long)]
    hide_env: bool,
}

impl EnvArgs {
    fn environment(&self, max_pixels: u64) -> Result<Option<scene::Environment>> {
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
struct SceneArgs {
    /// The glTF (.gltf or .glb) scene.
    scene: PathBuf,
    /// Which camera of the file to use (to start from, in the viewer), counting from 0.
    #[arg(long, allow_hyphen_values = true)]
    camera: Option<usize>,
    /// Vulkan device by index or by part of its name (see `pathwave info --devices`).
    #[arg(long)]
    device: Option<DeviceChoice>,
    /// How rays find surfaces: `compute` (pathwave's BVH, every device), `ray-query` (the device's acceleration
    /// structures, where `info --devices` says it has ray queries) or `auto` (ray queries on GPUs that have them).
    /// Default: PATHWAVE_TRAVERSAL, else auto.
    #[arg(long, value_enum)]
    traversal: Option<pathwave::render::Traversal>,
    /// Longest path in bounces (default: unbounded, ended by Russian roulette).
    #[arg(long, value_parser = parse_max_depth, allow_hyphen_values = true)]
    max_depth: Option<u32>,
    /// Seed of the random sequences; the same seed gives the same bytes.
    #[arg(long, default_value = "0", allow_hyphen_values = true)]
    seed: u32,
    /// Thin-lens aperture radius in scene units (metres for glTF); 0, the default, is a pinhole. In the viewer, F
    /// toggles depth of field and a right click focuses.
    #[arg(long, default_value = "0", value_parser = parse_aperture, allow_hyphen_values = true)]
    aperture: f32,
    /// Distance to the plane in focus along the view direction (default: the camera's distance to the scene's centre).
    #[arg(long, value_parser = parse_focus_distance, allow_hyphen_values = true)]
    focus_distance: Option<f32>,
    /// Render the scene as its animations place it at this time, in seconds (default 0); keys outside an
    /// animation's range hold its first or last values.
    #[arg(long, value_parser = parse_time, allow_hyphen_values = true)]
    time: Option<f32>,
    /// The animation that plays, by index or by name (default: every channel of the file, as viewers play them).
    #[arg(long)]
    animation: Option<String>,
    /// Seconds the shutter stays open from --time (or each frame's time): what moves meanwhile (the camera, nodes,
    /// skinned and morphed vertices) is blurred. 0, the default, is an instant and costs nothing.
    #[arg(long, default_value = "0", value_parser = parse_shutter, allow_hyphen_values = true)]
    shutter: f32,
    /// Spectral transport: every path carries four wavelengths and colours become spectra at them (README,
    /// "Spectral rendering"). Scenes with dispersion (KHR_materials_dispersion) render spectrally without it.
    #[arg(long, conflicts_with = "rgb")]
    spectral: bool,
    /// RGB transport even for a scene with dispersion, which is then ignored (with a warning).
    #[arg(long)]
    rgb: bool,
    /// How next-event estimation picks a light: bvh (by importance at the shading point, from a light BVH over the
    /// emitters), power (in proportion to power, the same everywhere) or uniform. README, "Light selection".
    #[arg(long, value_enum, default_value = "bvh")]
    light_sampler: LightSampler,
    #[command(flatten)]
    view: CameraArgs,
    #[command(flatten)]
    env: EnvArgs,
    #[command(flatten)]
    limits: LoadArgs,
}

/// A camera given on the command line (README, "Cameras"), replacing or changing the file's.
#[derive(clap::Args)]
struct CameraArgs {
    /// Where the camera stands, X,Y,Z in scene units; with --target.
    #[arg(long, value_parser = parse_point, requires = "target", conflicts_with = "orbit", allow_hyphen_values = true)]
    eye: Option<[f32; 3]>,
    /// The point the camera looks at, X,Y,Z; alone, the file's camera turns to it; with --orbit, the orbit's centre
    /// (default: the centre of the scene's bounds).
    #[arg(long, value_parser = parse_point, allow_hyphen_values = true)]
    target: Option<[f32; 3]>,
    /// The image's up direction, X,Y,Z (default 0,1,0).
    #[arg(long, value_parser = parse_up, allow_hyphen_values = true)]
    up: Option<[f32; 3]>,
    /// Vertical field of view in degrees, (0, 180); alone, it changes only the field of view of the file's camera.
    #[arg(long, value_parser = parse_yfov, allow_hyphen_values = true)]
    yfov: Option<f64>,
    /// AZIMUTH,ELEVATION,DISTANCE: a camera looking at --target (default: the bounds' centre) from this direction
    /// (azimuth in degrees from +z towards +x, elevation in degrees up) and distance.
    #[arg(long, value_parser = parse_orbit, allow_hyphen_values = true)]
    orbit: Option<[f32; 3]>,
}

impl CameraArgs {
    fn spec(&self) -> scene::CameraSpec {
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
    fn load(&self) -> Result<scene::Scene> {
        self.load_at(self.time.unwrap_or(0.0))
    }

    /// `load`, at `time` rather than --time's.
    fn load_at(&self, time: f32) -> Result<scene::Scene> {
        let mut scene = self.limits.load(&self.scene, self.camera)?;
        self.aim(&mut scene)?;
        self.pose(&mut scene, time)?;
        scene.environment = self.env.environment(self.limits.max_texture_pixels)?;
        Ok(scene)
    }

    /// Gives `scene` the camera --eye, --target, --up, --yfov and --orbit ask for, if any (before posing, so that
    /// an orbit's default centre is the bounds' centre of the file's own pose).
    fn aim(&self, scene: &mut scene::Scene) -> Result<()> {
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
    fn pose(&self, scene: &mut scene::Scene, time: f32) -> Result<()> {
        let pose = self.pose_time(scene, time)?;
        if scene.rig.animated() && (pose != scene.rig.posed || self.shutter > 0.0) {
            scene.pose_shutter(pose, self.shutter)?;
            scene.check_host_memory(self.limits.max_memory(), instancing_rule())?;
        }
        Ok(())
    }

    /// The pose `--animation` and `time` ask for; a time on a file without animations is warned about.
    fn pose_time(&self, scene: &scene::Scene, time: f32) -> Result<scene::PoseTime> {
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
    fn spectral(&self, scene: &scene::Scene) -> bool {
        let dispersive = scene.wants_spectral();
        if dispersive && self.rgb {
            eprintln!(
                "warning: {}: --rgb renders without dispersion (KHR_materials_dispersion needs spectral transport)",
                self.scene.display()
            );
        } else if dispersive && !self.spectral {
            eprintln!(
                "{}: dispersion (KHR_materials_dispersion): rendering spectrally (--rgb to force RGB)",
                self.scene.display()
            );
        }
        self.spectral || (dispersive && !self.rgb)
    }

    fn settings(&self) -> RenderSettings {
        RenderSettings {
            max_depth: self.max_depth,
            seed: self.seed,
            hide_environment: self.env.hide_env,
            aperture: self.aperture,
            focus_distance: self.focus_distance,
            light_sampler: self.light_sampler,
            ..Default::default()
        }
    }
}

#[derive(clap::Args)]
struct ViewArgs {
    /// Window size as WIDTHxHEIGHT.
    #[arg(long, default_value = "640x480", value_parser = parse_size, allow_hyphen_values = true)]
    size: (u32, u32),
    #[command(flatten)]
    common: SceneArgs,
    /// Exposure in stops (+ and - change it in the window), -64 to 64.
    #[arg(long, default_value = "0", value_parser = parse_exposure, allow_hyphen_values = true)]
    exposure: f32,
    /// Tone curve after --exposure (T cycles through them in the window; P's PNG uses the one shown): none
    /// (linear, clipped), aces (Narkowicz's fit), agx (Sobotka's AgX) or pbr-neutral (Khronos PBR Neutral).
    #[arg(long, value_enum, default_value = "aces")]
    tonemap: output::ToneCurve,
    /// Shader folder to use and watch: edited stages are rebuilt while the window stays open.
    #[arg(long)]
    shader_dir: Option<PathBuf>,
    /// Close after this many frames (for scripts and tests).
    #[arg(long, value_parser = positive)]
    frames: Option<u32>,
    /// Where P saves (default pathwave.exr and pathwave.png), and what --frames writes before closing.
    #[arg(long)]
    screenshot: Option<PathBuf>,
    /// Milliseconds per frame the adaptive sampler aims at.
    #[arg(long, default_value = "33", value_parser = positive)]
    frame_budget_ms: u32,
    /// Start with the animation playing (space toggles it).
    #[arg(long)]
    play: bool,
    /// Start showing an AOV or debug view (G cycles them): albedo, normal, depth, geometric-normal, shading-normal,
    /// uv, bvh-cost, light-pick.
    #[arg(long, value_parser = parse_view_aov)]
    show: Option<Aov>,
    /// Start denoising the still image (Shift+D toggles it); Open Image Denoise as for `render --denoise`.
    #[arg(long)]
    denoise: bool,
}

#[derive(clap::Args)]
struct RenderArgs {
    /// Output image; the extension picks the format (.exr or .png). Repeat to write several from one render.
    #[arg(short, long, required = true)]
    output: Vec<PathBuf>,
    /// Samples per pixel, at most 2^24.
    #[arg(long, default_value = "64", value_parser = parse_spp, allow_hyphen_values = true)]
    spp: u32,
    /// Image size as WIDTHxHEIGHT.
    #[arg(long, default_value = "512x512", value_parser = parse_size, allow_hyphen_values = true)]
    size: (u32, u32),
    #[command(flatten)]
    common: SceneArgs,
    /// Exposure in stops applied to PNG output, -64 to 64.
    #[arg(long, default_value = "0", value_parser = parse_exposure, allow_hyphen_values = true)]
    exposure: f32,
    /// Write the fraction of each pixel's camera samples that hit the scene as alpha: an A channel in EXR (the
    /// colour as rendered: premultiplied with --hide-env), RGBA in PNG (straight: divided by alpha with --hide-env).
    #[arg(long)]
    alpha: bool,
    /// Tone curve of PNG output after --exposure: none (linear, clipped at 1), aces (Narkowicz's fit), agx
    /// (Sobotka's AgX) or pbr-neutral (Khronos PBR Neutral). EXR output stays linear.
    #[arg(long, value_enum, default_value = "none")]
    tonemap: output::ToneCurve,
    /// Estimator, for experiments and tests: mis (default), light (NEE only) or bsdf (BSDF sampling only).
    #[arg(long, value_enum, default_value = "mis", hide = true)]
    estimator: Estimator,
    /// Turn off the energy compensation of rough metals (on by default; off shows single scattering alone).
    #[arg(long)]
    no_energy_compensation: bool,
    /// A folder of GLSL stages (as written by `export-shaders`) replacing the built-in ones of the same name.
    #[arg(long)]
    shader_dir: Option<PathBuf>,
    /// With --shader-dir: after writing the image, watch the folder and render again whenever a stage or an
    /// include changes. A stage that fails to compile is reported and the last image is kept. Stop with Ctrl-C.
    #[arg(long, requires = "shader_dir")]
    watch: bool,
    /// Render frames FIRST..LAST (inclusive) of the animation, frame k at time k / --fps, one file per frame: the
    /// last run of # in each -o name becomes the zero-padded frame number (-o out.####.exr).
    #[arg(long, value_parser = parse_frames, conflicts_with_all = ["time", "watch"])]
    frames: Option<(u32, u32)>,
    /// Frames per second of --frames.
    #[arg(long, default_value = "24", value_parser = parse_fps, requires = "frames")]
    fps: f32,
    /// With --frames: skip the frames whose every output file exists already.
    #[arg(long, requires = "frames")]
    resume: bool,
    /// Render only sample indices A to B-1 of every pixel (the samples a full render takes there) into a film file
    /// (EXR with film statistics); `pathwave merge` joins parts of disjoint ranges. Instead of --spp.
    #[arg(long, value_parser = parse_samples, conflicts_with_all = ["spp", "part"], allow_hyphen_values = true)]
    samples: Option<(u32, u32)>,
    /// Render the I-th (from 0) of N contiguous shares of --spp's samples into a film file, or with --frames the I-th
    /// of N shares of the frames. `auto/N` takes I from the job array: SLURM_ARRAY_TASK_ID, JOB_COMPLETION_INDEX
    /// (Kubernetes Indexed Jobs) or AWS_BATCH_JOB_ARRAY_INDEX.
    #[arg(long, value_parser = parse_part, allow_hyphen_values = true)]
    part: Option<Part>,
    /// Write film statistics into every EXR output: exact per-pixel sums of the samples and their squares, the
    /// sample count, and what rendered it, so `pathwave merge` and `pathwave diff` can use it. Implied by
    /// --samples, and by --part without --frames.
    #[arg(long)]
    film_stats: bool,
    /// Auxiliary images to write beside the image, comma-separated: albedo, normal (world space), depth (distance
    /// along the camera ray), position, variance (of each pixel's mean), sample-count, instance-id, material-id,
    /// with --denoise beauty-noisy, and the debug views geometric-normal, shading-normal, uv, bvh-cost and
    /// light-pick. An EXR output holds them as layers (albedo.R, normal.X, depth.Z, ...); a PNG
    /// output gets a file of each beside it (out.albedo.png).
    #[arg(long, value_parser = parse_aovs, allow_hyphen_values = true)]
    aov: Option<AovList>,
    /// Write each AOV to a file of its own beside every output (out.albedo.exr), EXR outputs too.
    #[arg(long, requires = "aov")]
    aov_files: bool,
    /// Denoise the image with Intel Open Image Denoise (its RT filter, guided by the albedo and normal AOVs, which
    /// are prefiltered first). OIDN is loaded at run time: from PATHWAVE_OIDN (its path), else the pyoidn Python
    /// package (`pip install pyoidn`). --aov beauty-noisy keeps the image before denoising.
    #[arg(long, conflicts_with_all = ["film_stats", "samples", "part"])]
    denoise: bool,
    /// Adaptive sampling: after --min-spp samples of every pixel, each pixel takes only the samples its mean needs for
    /// a relative standard error of --noise-threshold (as its neighbours' first samples estimate it), at most --spp.
    /// The image stays unbiased (README, "Adaptive sampling"); --aov sample-count shows where the samples went.
    #[arg(long)]
    adaptive: bool,
    /// With --adaptive: the relative standard error of a pixel's mean to reach, in (0, 1].
    #[arg(long, default_value = "0.01", value_parser = parse_noise_threshold, requires = "adaptive", allow_hyphen_values = true)]
    noise_threshold: f32,
    /// With --adaptive: the samples every pixel takes first (the pilot its neighbours' budgets are planned from).
    #[arg(long, default_value = "16", value_parser = parse_min_spp, requires = "adaptive", allow_hyphen_values = true)]
    min_spp: u32,
}

/// One image a render writes: which frame (None: not a sequence), at what time, into which files.
struct Shot {
    frame: Option<u32>,
    time: f32,
    outputs: Vec<PathBuf>,
}

impl RenderArgs {
    /// The AOVs asked for.
    fn aovs(&self) -> &[Aov] {
        self.aov.as_ref().map_or(&[], |l| &l.0)
    }

    /// Whether the render keeps the exact film and writes film files.
    fn film_stats(&self) -> bool {
        self.film_stats || self.samples.is_some() || (self.part.is_some() && self.frames.is_none())
    }

    /// The first sample index and the samples per pixel: --samples, this part's share of --spp, or all of --spp.
    fn sample_range(&self) -> Result<(u32, u32)> {
        match (self.samples, self.part) {
            (Some((a, b)), _) => Ok((a, b - a)),
            (None, Some(part)) if self.frames.is_none() => {
                let index = part.index().map_err(|e| anyhow::anyhow!(e))?;
                let r = Part::range(index, part.count, self.spp as u64);
                if r.is_empty() {
                    bail!(
                        "--part {index}/{}: {} samples per pixel give part {index} none; use at most {} parts",
                        part.count,
                        self.spp,
                        self.spp
                    );
                }
                Ok((r.start as u32, (r.end - r.start) as u32))
            }
            _ => Ok((0, self.spp)),
        }
    }

    /// `--part`'s share, for a render of a share of the samples.
    fn part_of(&self) -> Result<Option<output::PartOf>> {
        match (self.part, self.frames) {
            (Some(part), None) => Ok(Some(output::PartOf {
                index: part.index().map_err(|e| anyhow::anyhow!(e))?,
                count: part.count,
                spp: self.spp,
            })),
            _ => Ok(None),
        }
    }

    /// The options that change the image, as given, for a film file's metadata (its fingerprints hold the rest):
    /// they name what differs when parts are refused. Nothing machine-specific: parts render on many machines.
    fn film_settings(&self) -> Vec<(String, String)> {
        let c = &self.common;
        let opt = |v: Option<String>| v.unwrap_or_else(|| "default".into());
        let triple = |v: [f32; 3]| format!("{},{},{}", v[0], v[1], v[2]);
        [
            ("size", format!("{}x{}", self.size.0, self.size.1)),
            ("max-depth", opt(c.max_depth.map(|d| d.to_string()))),
            ("estimator", format!("{:?}", self.estimator).to_lowercase()),
            ("light-sampler", c.light_sampler.name().to_string()),
            ("energy-compensation", (!self.no_energy_compensation).to_string()),
            ("camera", opt(c.camera.map(|n| n.to_string()))),
            ("eye", opt(c.view.eye.map(triple))),
            ("target", opt(c.view.target.map(triple))),
            ("up", opt(c.view.up.map(triple))),
            ("yfov", opt(c.view.yfov.map(|d| d.to_string()))),
            ("orbit", opt(c.view.orbit.map(triple))),
            ("aperture", c.aperture.to_string()),
            ("focus-distance", opt(c.focus_distance.map(|f| f.to_string()))),
            ("time", opt(c.time.map(|t| t.to_string()))),
            ("shutter", c.shutter.to_string()),
            ("animation", opt(c.animation.clone())),
            ("variant", opt(c.limits.variant.clone())),
            (
                "env-color",
                opt(c.env.env_color.map(|rgb| format!("{},{},{}", rgb[0], rgb[1], rgb[2]))),
            ),
            ("env-intensity", c.env.env_intensity.to_string()),
            ("env-rotation", c.env.env_rotation.to_string()),
            ("hide-env", c.env.hide_env.to_string()),
            (
                "adaptive",
                match self.adaptive {
                    true => format!("threshold {} after {} spp", self.noise_threshold, self.min_spp),
                    false => "off".into(),
                },
            ),
        ]
        .into_iter()
        .map(|(k, v)| (k.to_string(), v))
        .collect()
    }

    /// The images to render: one at --time, or one per frame of --frames (this part's share of them, with --part)
    /// with its numbered file names.
    fn shots(&self) -> Result<Vec<Shot>> {
        let mut shots = self.all_shots()?;
        if let (Some(part), Some(_)) = (self.part, self.frames) {
            let index = part.index().map_err(|e| anyhow::anyhow!(e))?;
            let r = Part::range(index, part.count, shots.len() as u64);
            if r.is_empty() {
                bail!(
                    "--part {index}/{}: {} frames give part {index} none; use at most {} parts",
                    part.count,
                    shots.len(),
                    shots.len()
                );
            }
            shots = shots.drain(r.start as usize..r.end as usize).collect();
        }
        Ok(shots)
    }

    fn all_shots(&self) -> Result<Vec<Shot>> {
        let Some((first, last)) = self.frames else {
            return Ok(vec![Shot {
                frame: None,
                time: self.common.time.unwrap_or(0.0),
                outputs: self.output.clone(),
            }]);
        };
        (first..=last)
            .map(|k| {
                let outputs = (self.output.iter())
                    .map(|o| match output::frame_path(o, k) {
                        Some(p) => Ok(p),
                        None if first == last => Ok(o.clone()),
                        None => bail!(
                            "-o {}: with --frames {first}..{last}, every output name needs a run of # for the frame \
                             number (e.g. out.####.exr)",
                            o.display()
                        ),
                    })
                    .collect::<Result<Vec<_>>>()?;
                Ok(Shot {
                    frame: Some(k),
                    time: k as f32 / self.fps,
                    outputs,
                })
            })
            .collect()
    }
}

fn main() {
    let cli = Cli::parse();
    // diff's exit codes are cmp's: 1 means the images differ, so its errors exit 2.
    let error_code = if matches!(cli.command, Command::Diff(_)) { 2 } else { 1 };
    let result = match cli.command {
        Command::Render(args) => render(args),
        Command::View(args) => view(args),
        Command::Info { scene, devices, limits } => info(scene, devices, &limits),
        Command::ExportShaders { dir } => export_shaders(dir),
        Command::Bench(args) => bench(args),
        Command::Merge(args) => film_cli::merge(args),
        Command::Diff(args) => film_cli::diff(args),
    };
    if let Err(e) = result {
        eprintln!("error: {e:#}");
        std::process::exit(error_code);
    }
}

fn render(args: RenderArgs) -> Result<()> {
    if args.aovs().contains(&Aov::BeautyNoisy) && !args.denoise {
        bail!("--aov beauty-noisy is the image before denoising: it needs --denoise");
    }
    // Found before rendering, so a missing library costs no render.
    let denoiser = match args.denoise {
        true => Some(pathwave::denoise::Denoiser::from_env()?),
        false => None,
    };
    let shots = args.shots()?;
    // Refuse a bad output path before spending time on the render.
    let mut inputs = vec![("scene", args.common.scene.as_path())];
    if let Some(env) = &args.common.env.env {
        inputs.push(("environment map", env.as_path()));
    }
    for shot in &shots {
        for out in &shot.outputs {
            output::check_writable(out)?;
            output::check_not_input(out, &inputs)?;
            for &aov in args.aovs() {
                output::check_not_input(&output::aov_path(out, aov), &inputs)?;
            }
        }
    }
    let (first_sample, spp) = args.sample_range()?;
    interrupt::install()?;
    let start = Instant::now();
    let mut scene = args.common.load_at(shots[0].time)?;
    let from_env = pathwave::render::RendererOptions::from_env()?;
    let options = pathwave::render::RendererOptions {
        fingerprint: args.film_stats(),
        traversal: args.common.traversal.unwrap_or(from_env.traversal),
        ..from_env
    };
    let device = args.common.device.clone().unwrap_or_default();
    let ctx = pathwave::vk::Context::new(&device, pathwave::vk::Validation::from_env()?)?;
    // What the device could not build (the BVH past its limits, the ray-query structures past the budget) names
    // the scene it was built for.
    let mut renderer =
        Renderer::with_options(&scene, ctx, options).with_context(|| args.common.scene.display().to_string())?;
    for w in &renderer.warnings {
        eprintln!("warning: {}: {w}", args.common.scene.display());
    }
    let shader_dir = match &args.shader_dir {
        Some(dir) => {
            let dir = pathwave::shaders::ShaderDir::open(dir)?;
            for unknown in dir.unknown_stages() {
                eprintln!(
                    "warning: {}: {unknown}.comp is not a pathwave stage and is not used",
                    dir.root().display()
                );
            }
            let used = renderer.load_shaders(&dir, None)?;
            eprintln!("using {} from {}", used.join(", "), dir.root().display());
            Some(dir)
        }
        None => None,
    };
    let settings = RenderSettings {
        width: args.size.0,
        height: args.size.1,
        spp,
        first_sample,
        exact_film: args.film_stats(),
        aovs: args.denoise || args.alpha || args.aovs().iter().any(|a| a.surveyed()),
        debug_aovs: args.aovs().iter().any(|a| a.debug()),
        adaptive: args.adaptive.then_some(pathwave::Adaptive {
            threshold: args.noise_threshold,
            pilot: args.min_spp,
        }),
        estimator: args.estimator,
        energy_compensation: !args.no_energy_compensation,
        spectral: args.common.spectral(&scene),
        ..args.common.settings()
    };
    let denoiser = denoiser.as_ref();
    if args.frames.is_some() {
        return render_frames(&args, &shots, &mut scene, &mut renderer, &settings, denoiser, start);
    }
    render_and_write(&mut renderer, &settings, &args, &shots[0], denoiser, start)?;
    let Some(dir) = shader_dir.filter(|_| args.watch) else {
        return Ok(());
    };
    let watcher = pathwave::shaders::ShaderWatcher::new(&dir)?;
    eprintln!("watching {} for changes (Ctrl-C to stop)", dir.root().display());
    loop {
        let changed = watcher.changed(std::time::Duration::from_secs(3600));
        let stale = dir.affected(&changed);
        if stale.is_empty() {
            continue;
        }
        // A stage that does not compile keeps its last good pipeline, and the last image stays on disk.
        match renderer.load_shaders(&dir, Some(&stale)) {
            Ok(rebuilt) => {
                eprintln!("rebuilt {}", rebuilt.join(", "));
                match render_and_write(&mut renderer, &settings, &args, &shots[0], denoiser, Instant::now()) {
                    Err(e) if interrupt::STOP.load(std::sync::atomic::Ordering::SeqCst) => return Err(e),
                    Err(e) => eprintln!("error: {e:#}"),
                    Ok(()) => {}
                }
            }
            Err(e) => eprintln!("error: {e}\nkeeping the previous pipelines; watching for the next change"),
        }
    }
}

/// Every frame of --frames in turn: the scene posed at the frame's time and uploaded again on the same device, the
/// pipelines kept. An interrupted frame is not written (so --resume renders it again); the run then fails.
fn render_frames(
    args: &RenderArgs,
    shots: &[Shot],
    scene: &mut scene::Scene,
    renderer: &mut Renderer,
    settings: &RenderSettings,
    denoiser: Option<&pathwave::denoise::Denoiser>,
    start: Instant,
) -> Result<()> {
    let (mut rendered, mut skipped) = (0, 0);
    if !scene.rig.animated() {
        eprintln!(
            "warning: {}: the file has no animations, so every frame is the same image",
            args.common.scene.display()
        );
    }
    // The scene came posed at the first frame's time.
    let mut posed_at = shots[0].time;
    for (i, shot) in shots.iter().enumerate() {
        if args.resume && shot.outputs.iter().all(|o| o.exists()) {
            skipped += 1;
            continue;
        }
        if scene.rig.animated() && shot.time != posed_at {
            args.common.pose(scene, shot.time)?;
            renderer.set_scene(scene)?;
            posed_at = shot.time;
        }
        let label = format!("frame {} ({}/{})", shot.frame.unwrap_or(0), i + 1, shots.len());
        let written = render_and_write(renderer, settings, args, shot, denoiser, Instant::now());
        match written {
            Ok(()) => rendered += 1,
            Err(e) => return Err(e.context(format!("{label}, at {} s", shot.time))),
        }
    }
    let (first, last) = args.frames.unwrap_or((0, 0));
    eprintln!(
        "frames {first}..{last} at {} fps: {rendered} rendered, {skipped} already there (--resume); wall {:.2} s",
        args.fps,
        start.elapsed().as_secs_f64()
    );
    Ok(())
}

fn render_and_write(
    renderer: &mut Renderer,
    settings: &RenderSettings,
    args: &RenderArgs,
    shot: &Shot,
    denoiser: Option<&pathwave::denoise::Denoiser>,
    start: Instant,
) -> Result<()> {
    let bar = ProgressBar::new(settings.spp as u64);
    let prefix = match shot.frame {
        Some(k) => format!("frame {k} "),
        None => String::new(),
    };
    bar.set_style(
        ProgressStyle::with_template(&format!(
            "{prefix}{{bar:40}} {{pos}}/{{len}} spp  {{per_sec}}  eta {{eta}}"
        ))
        .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    let device = match renderer.traversal() {
        pathwave::render::Traversal::RayQuery => format!("{} (ray queries)", renderer.context().device_name()),
        _ => renderer.context().device_name(),
    };
    let warned = renderer.warnings.len();
    // Until the files are in place, a signal stops the render after its pass rather than the process.
    let _busy = interrupt::Busy::begin();
    let (film, stats) = renderer.render_until(settings, &mut |done| bar.set_position(done as u64), &interrupt::STOP)?;
    bar.finish_and_clear();
    // What the renderer learned while rendering (e.g. falling back to the wavefront schedule).
    for w in &renderer.warnings[warned..] {
        eprintln!("warning: {}: {w}", args.common.scene.display());
    }
    if film.spp == 0 && stats.interrupted {
        bail!("interrupted before the first pass ended: no samples, nothing written");
    }
    if stats.interrupted && shot.frame.is_some() {
        bail!(
            "interrupted with {} of {} samples per pixel; the frame is not written, so --resume renders it again",
            film.spp,
            settings.spp
        );
    }
    let noisy = film.mean();
    let (pixels, denoise_s) = match denoiser {
        Some(d) => {
            let aovs = film
                .aovs
                .as_ref()
                .context("the render has no AOVs to guide the denoiser")?;
            let (albedo, normal) = (aovs.albedo(), aovs.normal());
            let t = Instant::now();
            let guides = pathwave::denoise::Guides {
                albedo: Some(&albedo),
                normal: Some(&normal),
                clean: false,
            };
            let denoised = d.denoise(film.width, film.height, &noisy, guides)?;
            (denoised, Some(t.elapsed().as_secs_f64()))
        }
        None => (noisy.clone(), None),
    };
    let meta = match &film.exact {
        Some(exact) => Some(film_cli::film_meta(
            renderer,
            settings,
            exact,
            args.film_settings(),
            args.part_of()?,
        )?),
        None => None,
    };
    let film_stats = (film.exact.as_ref().zip(meta.as_ref())).map(|(film, meta)| output::Stats { film, meta });
    let written = write_outputs(args, shot, &film, &pixels, &noisy, film_stats)?;
    let names: Vec<String> = written.iter().map(|p| p.display().to_string()).collect();
    let denoised = denoise_s.map_or(String::new(), |s| format!(", denoised in {s:.2} s"));
    eprintln!(
        "{} {}x{} {} spp on {device}: wall {:.2} s, render {}{denoised}",
        names.join(", "),
        film.width,
        film.height,
        film.spp,
        start.elapsed().as_secs_f64(),
        stats.summary()
    );
    if stats.interrupted {
        let (a, done, b) = (
            settings.first_sample,
            settings.first_sample + film.spp,
            settings.first_sample + settings.spp,
        );
        let rest = match film.exact {
            Some(_) => format!(" (samples {a}..{done}; render --samples {done}..{b} and merge them to finish)"),
            None => String::new(),
        };
        bail!(
            "interrupted: wrote {} with {} of {} samples per pixel{rest}",
            names.join(", "),
            film.spp,
            settings.spp
        );
    }
    Ok(())
}

/// The shot's outputs and, for the AOVs asked for, their layers in each EXR and their files of their own (beside
/// every PNG output, and every output with --aov-files), all or nothing. Returns every path written.
fn write_outputs(
    args: &RenderArgs,
    shot: &Shot,
    film: &pathwave::Film,
    pixels: &[[f32; 3]],
    noisy: &[[f32; 3]],
    stats: Option<output::Stats>,
) -> Result<Vec<PathBuf>> {
    use output::{Content, OutFile};
    let source = output::AovSource {
        film,
        noisy: Some(noisy),
    };
    let missing = |a: Aov| anyhow::anyhow!("the render has no {} AOV", a.name());
    let aovs = args.aovs();
    let mut layers = Vec::new();
    let coverage = match args.alpha {
        true => Some(
            film.aovs
                .as_ref()
                .context("the render has no coverage for --alpha")?
                .coverage(),
        ),
        false => None,
    };
    if let Some(c) = &coverage {
        layers.push(output::Channel {
            name: "A".into(),
            samples: output::Samples::F32(c.clone()),
        });
    }
    let mut own = Vec::new();
    for &a in aovs {
        layers.extend(source.channels(a, true).ok_or_else(|| missing(a))?);
        own.push(source.channels(a, false).ok_or_else(|| missing(a))?);
    }
    let png = shot
        .outputs
        .iter()
        .any(|o| output::format_of(o).ok() == Some(output::Format::Png));
    let pictures = match png {
        true => (aovs.iter())
            .map(|&a| source.picture(a, args.exposure).ok_or_else(|| missing(a)))
            .collect::<Result<Vec<_>>>()?,
        false => Vec::new(),
    };
    let mut paths: Vec<(PathBuf, Option<usize>)> = Vec::new();
    for out in &shot.outputs {
        paths.push((out.clone(), None));
        let is_png = output::format_of(out)? == output::Format::Png;
        if is_png || args.aov_files {
            paths.extend((0..aovs.len()).map(|k| (output::aov_path(out, aovs[k]), Some(k))));
        }
    }
    let files: Vec<OutFile> = (paths.iter())
        .map(|(path, aov)| -> Result<OutFile> {
            let png = output::format_of(path)? == output::Format::Png;
            let content = match (aov, png) {
                (None, _) => Content::Image {
                    rgb: pixels,
                    display: output::Display {
                        exposure: args.exposure,
                        curve: args.tonemap,
                    },
                    stats,
                    layers: &layers,
                    alpha: coverage.as_deref().map(|coverage| output::Alpha {
                        coverage,
                        // glTF holds no environment: only these options give one.
                        over_black: args.common.env.hide_env
                            || (args.common.env.env.is_none() && args.common.env.env_color.is_none()),
                    }),
                },
                (Some(k), false) => Content::Channels(&own[*k]),
                (Some(k), true) => Content::Srgb8(&pictures[*k]),
            };
            Ok(OutFile { path, content })
        })
        .collect::<Result<_>>()?;
    output::write_files(film.width, film.height, &files)?;
    Ok(paths.into_iter().map(|(p, _)| p).collect())
}

fn view(args: ViewArgs) -> Result<()> {
    if let Some(out) = &args.screenshot {
        output::check_writable(out)?;
        output::check_not_input(out, &[("scene", args.common.scene.as_path())])?;
    }
    let scene = args.common.load()?;
    let animation = match &args.common.animation {
        Some(a) => Some(scene.rig.find_animation(a).map_err(|e| anyhow::anyhow!(e))?),
        None => None,
    };
    let options = pathwave::viewer::ViewOptions {
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
    pathwave::viewer::run(scene, options)?;
    Ok(())
}

#[derive(Clone, Copy, Debug, clap::ValueEnum)]
enum CompareWith {
    Mitsuba,
    Embree,
    /// The lamp grid, the city block and the emissive panel against Mitsuba 3, once per light sampler (bvh, power,
    /// uniform).
    Lights,
}

#[derive(clap::Args)]
struct BenchArgs {
    /// Also write the figures as JSON to this file.
    #[arg(long)]
    json: Option<PathBuf>,
    /// Fewer samples and a smaller terrain, for a quick look.
    #[arg(long)]
    quick: bool,
    /// Folder holding cornell-box.gltf and glass.gltf (default: ./scenes, else the source tree's).
    #[arg(long)]
    scenes: Option<PathBuf>,
    #[arg(long)]
    device: Option<DeviceChoice>,
    /// Also measure against another renderer in the same run: `mitsuba` (Mitsuba 3 llvm_ad_rgb, equal-time
    /// relMSE on the Cornell box), `embree` (embreex, random-ray traversal on the terrain) or `lights` (Mitsuba 3 on
    /// the lamp grid, the city block and the emissive panel, once per light sampler). Repeatable.
    #[arg(long, value_enum)]
    compare: Vec<CompareWith>,
    /// The Python interpreter that has `mitsuba` and `embreex` installed.
    #[arg(long, default_value = "python3")]
    python: PathBuf,
    /// Run only the comparisons, not the fixed cases.
    #[arg(long, requires = "compare")]
    only_compare: bool,
    /// Light selection for the fixed cases and the Cornell box comparisons (`--compare lights` runs all three):
    /// bvh (default), power or uniform.
    #[arg(long, value_enum, default_value = "bvh")]
    light_sampler: LightSampler,
    /// Which traversals the cases and the Embree comparison measure: `auto` (default) both side by side where the
    /// device has ray queries, else the compute BVH; `compute` or `ray-query` that one alone.
    #[arg(long, value_enum, default_value = "auto")]
    traversal: pathwave::render::Traversal,
}

fn bench(a: BenchArgs) -> Result<()> {
    let scenes = a.scenes.unwrap_or_else(|| {
        let here = PathBuf::from("scenes");
        if here.join("cornell-box.gltf").exists() {
            here
        } else {
            PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenes")
        }
    });
    let options = pathwave::bench::BenchOptions {
        device: a.device.unwrap_or_default(),
        scenes,
        exe: std::env::current_exe()?,
        quick: a.quick,
        compare: (a.compare.iter())
            .map(|c| match c {
                CompareWith::Mitsuba => pathwave::bench::Compare::Mitsuba,
                CompareWith::Embree => pathwave::bench::Compare::Embree,
                CompareWith::Lights => pathwave::bench::Compare::Lights,
            })
            .collect(),
        python: a.python,
        only_compare: a.only_compare,
        light_sampler: a.light_sampler,
        traversal: a.traversal,
    };
    let report = pathwave::bench::run(&options, &mut |case| eprintln!("bench: {case}"))?;
    print!("{}", report.table());
    if let Some(path) = a.json {
        std::fs::write(&path, report.json() + "\n").with_context(|| format!("cannot write {}", path.display()))?;
    }
    Ok(())
}

fn export_shaders(dir: PathBuf) -> Result<()> {
    let written = pathwave::shaders::export_builtin(&dir)?;
    eprintln!(
        "wrote {} files into {}; use them with --shader-dir {}",
        written.len(),
        dir.display(),
        dir.display()
    );
    Ok(())
}

/// Most files a census looks at: a folder's listing is read before anything loads.
const CENSUS_FILES: usize = 100_000;

/// `info FOLDER`: every .gltf and .glb under `dir` (sorted, depth first, symbolic links not followed) loaded with
/// `limits` as `render` loads it; a line per file (what it holds, or why it is refused), then each extension the
/// loaded files use, with how many use it and whether pathwave renders it, then one summary line.
fn census(dir: &std::path::Path, limits: &LoadArgs) -> Result<()> {
    fn walk(dir: &std::path::Path, out: &mut Vec<PathBuf>) -> Result<()> {
        let mut entries: Vec<PathBuf> = std::fs::read_dir(dir)
            .with_context(|| format!("cannot list {}", dir.display()))?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .collect();
        entries.sort();
        for p in entries {
            let Ok(meta) = std::fs::symlink_metadata(&p) else {
                continue;
            };
            if meta.is_dir() {
                walk(&p, out)?;
            } else if !meta.is_symlink() && {
                // A FIFO or device named .gltf is listed so that its refusal is reported, not silently skipped;
                // the loader refuses it from its metadata without opening it.
                let ext = p.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
                matches!(ext.as_deref(), Some("gltf" | "glb"))
            } {
                out.push(p);
            }
            if out.len() > CENSUS_FILES {
                bail!(
                    "{}: more than {CENSUS_FILES} glTF files; take a census of a smaller folder",
                    dir.display()
                );
            }
        }
        Ok(())
    }
    let mut files = Vec::new();
    walk(dir, &mut files)?;
    if files.is_empty() {
        bail!("{}: no .gltf or .glb file under it", dir.display());
    }
    let bar = ProgressBar::new(files.len() as u64);
    let mut used: std::collections::BTreeMap<String, usize> = Default::default();
    let (mut loaded, mut warned) = (0usize, 0usize);
    for f in &files {
        let name = f.strip_prefix(dir).unwrap_or(f).display().to_string();
        let line = match limits.load(f, None) {
            Ok(scene) => {
                loaded += 1;
                warned += !scene.warnings.is_empty() as usize;
                for e in &scene.extensions_used {
                    *used.entry(e.clone()).or_default() += 1;
                }
                format!(
                    "loads    {name}: {} triangles, {} materials, {} warnings",
                    scene.triangle_count(),
                    scene.materials.len(),
                    scene.warnings.len()
                )
            }
            Err(e) => format!("refused  {name}: {}", format!("{e:#}").replace('\n', " ")),
        };
        bar.suspend(|| println!("{line}"));
        bar.inc(1);
    }
    bar.finish_and_clear();
    for (ext, n) in &used {
        let supported = pathwave::scene::SUPPORTED_EXTENSIONS.contains(&ext.as_str());
        let how = if supported {
            "supported"
        } else {
            "not supported, ignored"
        };
        println!("extension   {ext}: {n} of the files that load, {how}");
    }
    println!(
        "census: {loaded} of {} files load ({warned} with warnings), {} refused",
        files.len(),
        files.len() - loaded
    );
    Ok(())
}

fn info(path: Option<PathBuf>, devices: bool, limits: &LoadArgs) -> Result<()> {
    if devices {
        for d in pathwave::vk::list_devices()? {
            println!(
                "{}: {} ({}, Vulkan {}, {}, maxStorageBufferRange {} MiB, ray queries: {})",
                d.index,
                d.name,
                d.kind,
                d.api_version,
                d.driver,
                d.max_storage_buffer_range >> 20,
                if d.ray_query { "yes" } else { "no" }
            );
        }
        return Ok(());
    }
    let Some(path) = path else {
        bail!("name a scene, or pass --devices")
    };
    if path.is_dir() {
        return census(&path, limits);
    }
    let scene = limits.load(&path, None).with_context(|| "cannot describe the scene")?;
    for w in &scene.warnings {
        eprintln!("warning: {}: {w}", path.display());
    }
    let start = Instant::now();
    let packed = pathwave::render::gpu_scene::try_pack_with(&scene, instancing_rule())?;
    let build = start.elapsed();
    let st = &packed.bvh.stats;
    println!("scene       {}", path.display());
    let placed = scene.flattened_triangle_bound();
    println!("triangles   {} stored, {placed} placed", packed.tri_verts.len());
    let file_meshes = &scene.meshes[..scene.rig.file_meshes.min(scene.meshes.len())];
    println!(
        "meshes      {} unique ({} triangles), placed by {} instances",
        file_meshes.len(),
        file_meshes.iter().map(|m| m.triangle_count()).sum::<usize>(),
        scene.instances.len()
    );
    if scene.extensions_used.is_empty() {
        println!("extensions  none");
    }
    if !scene.variants.is_empty() {
        println!(
            "variants    {} (--variant NAME): '{}'",
            scene.variants.len(),
            scene.variants.join("', '")
        );
    }
    for ext in &scene.extensions_used {
        let supported = pathwave::scene::SUPPORTED_EXTENSIONS.contains(&ext.as_str());
        println!(
            "extension   {ext}: {}",
            if supported {
                "supported"
            } else {
                "not supported, ignored"
            }
        );
    }
    let (morphed, skinned) = pathwave::scene::rig::deformation_counts(&scene);
    println!(
        "deforming   {} skins, {skinned} skinned meshes, {morphed} meshes with morph targets",
        scene.rig.skins.len()
    );
    if scene.rig.animations.is_empty() {
        println!("animations  none");
    }
    for (i, a) in scene.rig.animations.iter().enumerate() {
        let (lo, hi) = a.range();
        let name = if a.name.is_empty() {
            String::new()
        } else {
            format!(" '{}'", a.name)
        };
        println!(
            "animation   {i}{name}: {} channels, keys from {lo} s to {hi} s ({:.3} s)",
            a.channels.len(),
            hi - lo
        );
    }
    let instanced = scene.instanced_meshes(instancing_rule());
    let kept = instanced.iter().filter(|&&i| i).count();
    if kept > 0 {
        println!(
            "instancing  {kept} of {} meshes kept once in object space under a two-level BVH, placed by {} instances \
             ({:.2} MiB of instance records)",
            file_meshes.len(),
            packed.instances.first().map_or(0, |header| header.info[1]),
            std::mem::size_of_val(&packed.instances[..]) as f64 / (1 << 20) as f64
        );
    } else {
        println!("instancing  none (every instance is placed into the world BVH)");
    }
    println!("materials   {}", scene.materials.len() - 1);
    let instanced_lights = (packed.lights.iter().take(packed.light_count as usize))
        .filter(|l| l.id >> pathwave::constants::LIGHT_KIND_SHIFT == pathwave::constants::LIGHT_KIND_INSTANCE)
        .count();
    let triangles = packed
        .lights
        .iter()
        .filter(|l| l.id >> pathwave::constants::LIGHT_KIND_SHIFT == 0)
        .count();
    println!(
        "lights      {triangles} emissive triangles{}, {:.4} W in total",
        match instanced_lights {
            0 => String::new(),
            n => format!(" (instanced meshes' counted once) and {n} emissive instances"),
        },
        packed.total_light_power + 0.0
    );
    let tree = &packed.light_tree;
    println!(
        "light tree  {} emitters, {} interior nodes, depth {}, {} bytes, built in {:.1} ms{}",
        tree.stats.emitters,
        tree.stats.interior,
        tree.stats.depth,
        tree.bytes(),
        tree.stats.build.as_secs_f64() * 1e3,
        match tree.share() {
            s if s < 1.0 && tree.stats.emitters > 0 =>
                format!("; infinite lights take {:.1} % of the picks", 100.0 * (1.0 - s)),
            _ => String::new(),
        }
    );
    println!(
        "textures    {} ({} images, {:.2} MiB of texels)",
        scene.textures.len(),
        scene.images.len(),
        (packed.texels.len() * 4) as f64 / (1 << 20) as f64
    );
    println!("cameras     {}", scene.camera_count);
    println!(
        "bvh         {} node records ({} leaves), {} children per node, binary depth {}, at most {} entries on the \
         traversal stack, at most {} triangles per leaf, SAH cost {:.2}, {} bytes, built in {:.1} ms",
        st.nodes,
        st.leaves,
        pathwave::constants::BVH_WIDTH,
        st.depth,
        st.max_waiting,
        st.max_leaf_tris,
        st.sah_cost,
        st.nodes * std::mem::size_of::<pathwave::layout::BvhNode>(),
        build.as_secs_f64() * 1e3
    );
    Ok(())
}

/// The instancing rule the renderer will use (PATHWAVE_INSTANCING; a bad value is refused when the renderer reads it).
fn instancing_rule() -> scene::Instancing {
    pathwave::RendererOptions::from_env().map_or(scene::Instancing::Auto, |o| o.instancing)
}
