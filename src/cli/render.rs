//! `pathwave render`: its arguments, the shots (frames and outputs) they ask for, and the render loop that writes
//! them.
use super::args::*;
use super::values::*;
use crate::output::Aov;
use crate::{output, scene, Estimator, RenderSettings, Renderer};
use anyhow::{bail, Context as _, Result};
use indicatif::{ProgressBar, ProgressStyle};
use std::path::PathBuf;
use std::time::Instant;

#[derive(clap::Args)]
pub struct RenderArgs {
    /// Output image; the extension picks the format (.exr or .png). Repeat to write several from one render.
    #[arg(short, long, required = true)]
    pub output: Vec<PathBuf>,
    /// Samples per pixel, at most 2^24.
    #[arg(long, default_value = "64", value_parser = parse_spp, allow_hyphen_values = true)]
    pub spp: u32,
    /// Image size as WIDTHxHEIGHT.
    #[arg(long, default_value = "512x512", value_parser = parse_size, allow_hyphen_values = true)]
    pub size: (u32, u32),
    #[command(flatten)]
    pub common: SceneArgs,
    /// Exposure in stops applied to PNG output, -64 to 64.
    #[arg(long, default_value = "0", value_parser = parse_exposure, allow_hyphen_values = true)]
    pub exposure: f32,
    /// Write the fraction of each pixel's camera samples that hit the scene as alpha: an A channel in EXR (the
    /// colour as rendered: premultiplied with --hide-env), RGBA in PNG (straight: divided by alpha with --hide-env).
    #[arg(long)]
    pub alpha: bool,
    /// Tone curve of PNG output after --exposure: none (linear, clipped at 1), aces (Narkowicz's fit), agx
    /// (Sobotka's AgX) or pbr-neutral (Khronos PBR Neutral). EXR output stays linear.
    #[arg(long, value_enum, default_value = "none")]
    pub tonemap: output::ToneCurve,
    /// Estimator, for experiments and tests: mis (default), light (NEE only) or bsdf (BSDF sampling only).
    #[arg(long, value_enum, default_value = "mis", hide = true)]
    pub estimator: Estimator,
    /// Turn off the energy compensation of rough metals (on by default; off shows single scattering alone).
    #[arg(long)]
    pub no_energy_compensation: bool,
    /// A folder of GLSL stages (as written by `export-shaders`) replacing the built-in ones of the same name.
    #[arg(long)]
    pub shader_dir: Option<PathBuf>,
    /// With --shader-dir: after writing the image, watch the folder and render again whenever a stage or an
    /// include changes. A stage that fails to compile is reported and the last image is kept. Stop with Ctrl-C.
    #[arg(long, requires = "shader_dir")]
    pub watch: bool,
    /// Render frames FIRST..LAST (inclusive) of the animation, frame k at time k / --fps, one file per frame: the
    /// last run of # in each -o name becomes the zero-padded frame number (-o out.####.exr).
    #[arg(long, value_parser = parse_frames, conflicts_with_all = ["time", "watch"])]
    pub frames: Option<(u32, u32)>,
    /// Frames per second of --frames.
    #[arg(long, default_value = "24", value_parser = parse_fps, requires = "frames")]
    pub fps: f32,
    /// With --frames: skip the frames whose every output file exists already.
    #[arg(long, requires = "frames")]
    pub resume: bool,
    /// Render only sample indices A to B-1 of every pixel (the samples a full render takes there) into a film file
    /// (EXR with film statistics); `pathwave merge` joins parts of disjoint ranges. Instead of --spp.
    #[arg(long, value_parser = parse_samples, conflicts_with_all = ["spp", "part"], allow_hyphen_values = true)]
    pub samples: Option<(u32, u32)>,
    /// Render the I-th (from 0) of N contiguous shares of --spp's samples into a film file, or with --frames the I-th
    /// of N shares of the frames. `auto/N` takes I from the job array: SLURM_ARRAY_TASK_ID, JOB_COMPLETION_INDEX
    /// (Kubernetes Indexed Jobs) or AWS_BATCH_JOB_ARRAY_INDEX.
    #[arg(long, value_parser = parse_part, allow_hyphen_values = true)]
    pub part: Option<Part>,
    /// Write film statistics into every EXR output: exact per-pixel sums of the samples and their squares, the
    /// sample count, and what rendered it, so `pathwave merge` and `pathwave diff` can use it. Implied by
    /// --samples, and by --part without --frames.
    #[arg(long)]
    pub film_stats: bool,
    /// Auxiliary images to write beside the image, comma-separated: albedo, normal (world space), depth (distance
    /// along the camera ray), position, variance (of each pixel's mean), sample-count, instance-id, material-id,
    /// with --denoise beauty-noisy, and the debug views geometric-normal, shading-normal, uv, bvh-cost and
    /// light-pick. An EXR output holds them as layers (albedo.R, normal.X, depth.Z, ...); a PNG
    /// output gets a file of each beside it (out.albedo.png).
    #[arg(long, value_parser = parse_aovs, allow_hyphen_values = true)]
    pub aov: Option<AovList>,
    /// Write each AOV to a file of its own beside every output (out.albedo.exr), EXR outputs too.
    #[arg(long, requires = "aov")]
    pub aov_files: bool,
    /// Denoise the image with Intel Open Image Denoise (its RT filter, guided by the albedo and normal AOVs, which
    /// are prefiltered first). OIDN is loaded at run time: from PATHWAVE_OIDN (its path), else the pyoidn Python
    /// package (`pip install pyoidn`). --aov beauty-noisy keeps the image before denoising.
    #[arg(long, conflicts_with_all = ["film_stats", "samples", "part"])]
    pub denoise: bool,
    /// Adaptive sampling: after --min-spp samples of every pixel, each pixel takes only the samples its mean needs for
    /// a relative standard error of --noise-threshold (as its neighbours' first samples estimate it), at most --spp.
    /// The image stays unbiased (docs/guide/aovs.md, "Adaptive sampling"); --aov sample-count shows where the samples went.
    #[arg(long)]
    pub adaptive: bool,
    /// With --adaptive: the relative standard error of a pixel's mean to reach, in (0, 1].
    #[arg(long, default_value = "0.01", value_parser = parse_noise_threshold, requires = "adaptive", allow_hyphen_values = true)]
    pub noise_threshold: f32,
    /// With --adaptive: the samples every pixel takes first (the pilot its neighbours' budgets are planned from).
    #[arg(long, default_value = "16", value_parser = parse_min_spp, requires = "adaptive", allow_hyphen_values = true)]
    pub min_spp: u32,
}

/// One image a render writes: which frame (None: not a sequence), at what time, into which files.
pub struct Shot {
    pub frame: Option<u32>,
    pub time: f32,
    pub outputs: Vec<PathBuf>,
}

impl RenderArgs {
    /// The AOVs asked for.
    pub fn aovs(&self) -> &[Aov] {
        self.aov.as_ref().map_or(&[], |l| &l.0)
    }

    /// Whether the render keeps the exact film and writes film files.
    pub fn film_stats(&self) -> bool {
        self.film_stats || self.samples.is_some() || (self.part.is_some() && self.frames.is_none())
    }

    /// The first sample index and the samples per pixel: --samples, this part's share of --spp, or all of --spp.
    pub fn sample_range(&self) -> Result<(u32, u32)> {
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
    pub fn part_of(&self) -> Result<Option<output::PartOf>> {
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
    pub fn film_settings(&self) -> Vec<(String, String)> {
        let c = &self.common;
        let opt = |v: Option<String>| v.unwrap_or_else(|| "default".into());
        let triple = |v: [f32; 3]| format!("{},{},{}", v[0], v[1], v[2]);
        [
            ("size", format!("{}x{}", self.size.0, self.size.1)),
            ("max-depth", opt(c.max_depth.map(|d| d.to_string()))),
            ("estimator", format!("{:?}", self.estimator).to_lowercase()),
            ("light-sampler", c.light_sampler.name().to_string()),
            ("texture-filter", c.texture_filter.name().to_string()),
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
    pub fn shots(&self) -> Result<Vec<Shot>> {
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

    pub fn all_shots(&self) -> Result<Vec<Shot>> {
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

pub fn render(args: RenderArgs) -> Result<()> {
    // Found before rendering, so a missing library costs no render.
    let denoiser = args.denoiser()?;
    let shots = args.shots()?;
    check_outputs(&args, &shots)?;
    // Refused before the scene loads, as the outputs are.
    args.sample_range()?;
    super::interrupt::install()?;
    let start = Instant::now();
    let mut scene = args.common.load_at(shots[0].time)?;
    let mut renderer = renderer_for(&args, &scene)?;
    let shader_dir = match &args.shader_dir {
        Some(dir) => Some(load_shader_dir(dir, &mut renderer)?),
        None => None,
    };
    let settings = args.render_settings(&scene)?;
    let denoiser = denoiser.as_ref();
    if args.frames.is_some() {
        return render_frames(&args, &shots, &mut scene, &mut renderer, &settings, denoiser, start);
    }
    render_and_write(&mut renderer, &settings, &args, &shots[0], denoiser, start)?;
    match shader_dir.filter(|_| args.watch) {
        Some(dir) => watch(&dir, &mut renderer, &settings, &args, &shots[0], denoiser),
        None => Ok(()),
    }
}

impl RenderArgs {
    /// Parses `render`'s arguments (without the command's name) as the command line does, with its checks and
    /// messages; the outputs may be left out, for a caller that names them when it saves (the Python module).
    pub fn parse_from<I, T>(args: I) -> Result<RenderArgs, clap::Error>
    where
        I: IntoIterator<Item = T>,
        T: Into<std::ffi::OsString> + Clone,
    {
        use clap::{Args as _, FromArgMatches as _};
        let command = RenderArgs::augment_args(clap::Command::new("render")).mut_arg("output", |a| a.required(false));
        let matches =
            command.try_get_matches_from(std::iter::once("render".into()).chain(args.into_iter().map(Into::into)))?;
        RenderArgs::from_arg_matches(&matches)
    }

    /// The denoiser --denoise asks for (None without it), refusing --aov beauty-noisy without it.
    pub fn denoiser(&self) -> Result<Option<crate::denoise::Denoiser>> {
        if self.aovs().contains(&Aov::BeautyNoisy) && !self.denoise {
            bail!("--aov beauty-noisy is the image before denoising: it needs --denoise");
        }
        Ok(match self.denoise {
            true => Some(crate::denoise::Denoiser::from_env()?),
            false => None,
        })
    }

    /// The render settings these options give for `scene` (loaded and posed by `common`).
    pub fn render_settings(&self, scene: &scene::Scene) -> Result<RenderSettings> {
        let (first_sample, spp) = self.sample_range()?;
        Ok(RenderSettings {
            width: self.size.0,
            height: self.size.1,
            spp,
            first_sample,
            exact_film: self.film_stats(),
            aovs: self.denoise || self.alpha || self.aovs().iter().any(|a| a.surveyed()),
            debug_aovs: self.aovs().iter().any(|a| a.debug()),
            adaptive: self.adaptive.then_some(crate::Adaptive {
                threshold: self.noise_threshold,
                pilot: self.min_spp,
            }),
            estimator: self.estimator,
            energy_compensation: !self.no_energy_compensation,
            spectral: self.common.spectral(scene),
            ..self.common.settings()
        })
    }
}

/// Refuses a bad output path (unwritable, or one of the inputs, AOV files included) before any time goes to the render.
pub fn check_outputs(args: &RenderArgs, shots: &[Shot]) -> Result<()> {
    let mut inputs = vec![("scene", args.common.scene.as_path())];
    if let Some(env) = &args.common.env.env {
        inputs.push(("environment map", env.as_path()));
    }
    for shot in shots {
        for out in &shot.outputs {
            output::check_writable(out)?;
            output::check_not_input(out, &inputs)?;
            for &aov in args.aovs() {
                output::check_not_input(&output::aov_path(out, aov), &inputs)?;
            }
        }
    }
    Ok(())
}

/// The renderer on the device asked for, with the environment's options and the command line's traversal; its
/// warnings are printed.
pub fn renderer_for(args: &RenderArgs, scene: &scene::Scene) -> Result<Renderer> {
    let from_env = crate::render::RendererOptions::from_env()?;
    let options = crate::render::RendererOptions {
        fingerprint: args.film_stats(),
        traversal: args.common.traversal.unwrap_or(from_env.traversal),
        ..from_env
    };
    let device = args.common.device.clone().unwrap_or_default();
    let ctx = crate::vk::Context::new(&device, crate::vk::Validation::from_env()?)?;
    // What the device could not build (the BVH past its limits, the ray-query structures past the budget) names
    // the scene it was built for.
    let renderer =
        Renderer::with_options(scene, ctx, options).with_context(|| args.common.scene.display().to_string())?;
    for w in &renderer.warnings {
        eprintln!("warning: {}: {w}", args.common.scene.display());
    }
    Ok(renderer)
}

/// --shader-dir: the folder's stages replace the built-in ones.
fn load_shader_dir(dir: &std::path::Path, renderer: &mut Renderer) -> Result<crate::shaders::ShaderDir> {
    let dir = crate::shaders::ShaderDir::open(dir)?;
    for unknown in dir.unknown_stages() {
        eprintln!(
            "warning: {}: {unknown}.comp is not a pathwave stage and is not used",
            dir.root().display()
        );
    }
    let used = renderer.load_shaders(&dir, None)?;
    eprintln!("using {} from {}", used.join(", "), dir.root().display());
    Ok(dir)
}

/// --watch: renders again whenever a stage the folder holds changes, until interrupted.
fn watch(
    dir: &crate::shaders::ShaderDir,
    renderer: &mut Renderer,
    settings: &RenderSettings,
    args: &RenderArgs,
    shot: &Shot,
    denoiser: Option<&crate::denoise::Denoiser>,
) -> Result<()> {
    let watcher = crate::shaders::ShaderWatcher::new(dir)?;
    eprintln!("watching {} for changes (Ctrl-C to stop)", dir.root().display());
    loop {
        let changed = watcher.changed(std::time::Duration::from_secs(3600));
        let stale = dir.affected(&changed);
        if stale.is_empty() {
            continue;
        }
        // A stage that does not compile keeps its last good pipeline, and the last image stays on disk.
        match renderer.load_shaders(dir, Some(&stale)) {
            Ok(rebuilt) => {
                eprintln!("rebuilt {}", rebuilt.join(", "));
                match render_and_write(renderer, settings, args, shot, denoiser, Instant::now()) {
                    Err(e) if super::interrupt::STOP.load(std::sync::atomic::Ordering::SeqCst) => return Err(e),
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
pub fn render_frames(
    args: &RenderArgs,
    shots: &[Shot],
    scene: &mut scene::Scene,
    renderer: &mut Renderer,
    settings: &RenderSettings,
    denoiser: Option<&crate::denoise::Denoiser>,
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

pub fn render_and_write(
    renderer: &mut Renderer,
    settings: &RenderSettings,
    args: &RenderArgs,
    shot: &Shot,
    denoiser: Option<&crate::denoise::Denoiser>,
    start: Instant,
) -> Result<()> {
    let bar = progress_bar(shot, settings.spp);
    // Until the files are in place, a signal stops the render after its pass rather than the process.
    let _busy = super::interrupt::Busy::begin();
    let rendered = super::shot::render_shot(
        renderer,
        settings,
        args,
        denoiser,
        &mut |done| bar.set_position(done as u64),
        &super::interrupt::STOP,
    )?;
    bar.finish_and_clear();
    for w in &rendered.warnings {
        eprintln!("warning: {}: {w}", args.common.scene.display());
    }
    let (film, stats) = (&rendered.film, &rendered.stats);
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
    let written = rendered.write(args, shot)?;
    let names: Vec<String> = written.iter().map(|p| p.display().to_string()).collect();
    let denoised = rendered
        .denoise_s
        .map_or(String::new(), |s| format!(", denoised in {s:.2} s"));
    eprintln!(
        "{} {}x{} {} spp on {}: wall {:.2} s, render {}{denoised}",
        names.join(", "),
        film.width,
        film.height,
        film.spp,
        rendered.device,
        start.elapsed().as_secs_f64(),
        stats.summary()
    );
    match stats.interrupted {
        true => Err(interrupted(settings, film, &names)),
        false => Ok(()),
    }
}

fn progress_bar(shot: &Shot, spp: u32) -> ProgressBar {
    let bar = ProgressBar::new(spp as u64);
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
    bar
}

/// A render stopped before its samples, its files written: what it holds, and how to finish it when it can be.
fn interrupted(settings: &RenderSettings, film: &crate::Film, names: &[String]) -> anyhow::Error {
    let (a, done, b) = (
        settings.first_sample,
        settings.first_sample + film.spp,
        settings.first_sample + settings.spp,
    );
    let rest = match film.exact {
        Some(_) => format!(" (samples {a}..{done}; render --samples {done}..{b} and merge them to finish)"),
        None => String::new(),
    };
    anyhow::anyhow!(
        "interrupted: wrote {} with {} of {} samples per pixel{rest}",
        names.join(", "),
        film.spp,
        settings.spp
    )
}
