//! The wavefront integrator: generate, then extend / shade / connect per bounce, then accumulate, all on the device.
pub mod gpu_scene;

use crate::constants::*;
use crate::layout::{Counters, Frame, COUNTERS_DISPATCH_OFFSET};
use crate::scene::{Camera, Scene};
use crate::vk::{add_labelled, Buffer, Context, DeviceChoice, Pipelines, Timestamps, Validation};
use crate::Error;
use ash::vk;
use gpu_allocator::MemoryLocation;
use std::time::{Duration, Instant};

/// Which estimator shade uses; the three must agree in expectation (tests/estimators.rs).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum Estimator {
    /// Next-event estimation and BSDF sampling combined with the power heuristic.
    #[default]
    Mis,
    /// Light sampling only: emission found by BSDF-sampled rays is ignored after the camera ray.
    Light,
    /// BSDF sampling only: no next-event estimation.
    Bsdf,
}

impl Estimator {
    fn code(self) -> u32 {
        match self {
            Estimator::Mis => ESTIMATOR_MIS,
            Estimator::Light => ESTIMATOR_LIGHT,
            Estimator::Bsdf => ESTIMATOR_BSDF,
        }
    }
}

/// Bounces recorded when no `max_depth` is given: Russian roulette ends paths long before this.
pub const DEPTH_SAFETY_CAP: u32 = 64;

#[derive(Clone, Debug)]
pub struct RenderSettings {
    pub width: u32,
    pub height: u32,
    pub spp: u32,
    /// Longest path in bounces; None means unbounded (Russian roulette, with DEPTH_SAFETY_CAP).
    pub max_depth: Option<u32>,
    pub seed: u32,
    pub estimator: Estimator,
    /// Return the energy rough metals lose to single scattering (Kulla-Conty); on by default.
    pub energy_compensation: bool,
    /// Keep the environment out of camera rays (it still lights the scene).
    pub hide_environment: bool,
    /// Thin-lens aperture radius in scene units; 0 is a pinhole (everything sharp).
    pub aperture: f32,
    /// Distance from the camera to the plane in focus, along the view direction; None: the camera's distance to
    /// the scene's centre.
    pub focus_distance: Option<f32>,
}

impl Default for RenderSettings {
    fn default() -> Self {
        RenderSettings {
            width: 256,
            height: 256,
            spp: 16,
            max_depth: None,
            seed: 0,
            estimator: Estimator::Mis,
            energy_compensation: true,
            hide_environment: false,
            aperture: 0.0,
            focus_distance: None,
        }
    }
}

/// The accumulated image: per-pixel sums of samples and of their squares, so tests can bound the error.
#[derive(Clone, Debug)]
pub struct Film {
    pub width: u32,
    pub height: u32,
    pub spp: u32,
    pub sum: Vec<[f32; 4]>,
    pub sum_sq: Vec<[f32; 4]>,
}

impl Film {
    /// Per-pixel mean radiance (linear RGB), row 0 at the top.
    pub fn mean(&self) -> Vec<[f32; 3]> {
        let inv = 1.0 / self.spp.max(1) as f32;
        self.sum.iter().map(|s| [s[0] * inv, s[1] * inv, s[2] * inv]).collect()
    }

    /// Unbiased per-pixel variance of one sample, per channel.
    pub fn sample_variance(&self) -> Vec<[f32; 3]> {
        let n = self.spp as f64;
        self.sum
            .iter()
            .zip(&self.sum_sq)
            .map(|(s, q)| {
                std::array::from_fn(|c| {
                    if n < 2.0 {
                        return 0.0;
                    }
                    let m = s[c] as f64 / n;
                    ((q[c] as f64 / n - m * m) * n / (n - 1.0)).max(0.0) as f32
                })
            })
            .collect()
    }
}

#[derive(Clone, Debug, Default)]
pub struct RenderStats {
    pub wall: Duration,
    /// The first pass, which also pays for pipeline compilation on lavapipe.
    pub first_pass: Duration,
    pub passes: u32,
    pub samples: u64,
    pub extension_rays: u64,
    pub shadow_rays: u64,
    /// GPU time per stage in milliseconds, over all passes but the first (or the first, when it is the only one).
    pub stage_ms: Vec<(&'static str, f64)>,
    first_pass_stage_ms: Vec<(&'static str, f64)>,
}

impl RenderStats {
    /// Time over the passes after the first, so compile time does not count against throughput.
    fn steady(&self) -> Duration {
        self.wall.saturating_sub(self.first_pass)
    }
    pub fn samples_per_sec(&self) -> f64 {
        let (n, t) = self.steady_counts(self.samples);
        n / t
    }
    pub fn rays_per_sec(&self) -> f64 {
        let (n, t) = self.steady_counts(self.extension_rays + self.shadow_rays);
        n / t
    }
    /// Extension and shadow rays per second, apart.
    pub fn rays_per_sec_split(&self) -> (f64, f64) {
        let (e, t) = self.steady_counts(self.extension_rays);
        let (s, _) = self.steady_counts(self.shadow_rays);
        (e / t, s / t)
    }
    fn steady_counts(&self, total: u64) -> (f64, f64) {
        if self.passes > 1 && !self.steady().is_zero() {
            let per_pass = total as f64 / self.passes as f64;
            (per_pass * (self.passes - 1) as f64, self.steady().as_secs_f64())
        } else {
            (total as f64, self.wall.as_secs_f64().max(1e-9))
        }
    }
    /// The one-line summary every render ends with.
    pub fn summary(&self) -> String {
        let stages: Vec<String> = self.stage_ms.iter().map(|(n, ms)| format!("{n} {ms:.1}")).collect();
        format!(
            "{:.2} s (first pass {:.2} s), {:.0} samples/s, {:.2} Mrays/s ({} extension + {} shadow rays), GPU ms: {}",
            self.wall.as_secs_f64(),
            self.first_pass.as_secs_f64(),
            self.samples_per_sec(),
            self.rays_per_sec() / 1e6,
            self.extension_rays,
            self.shadow_rays,
            if stages.is_empty() {
                "n/a".to_string()
            } else {
                stages.join(", ")
            }
        )
    }
}

/// One BSDF query for `Renderer::probe_bsdf`, in the shading frame (z = normal).
#[derive(Clone, Copy, Debug)]
pub struct BsdfQuery {
    pub material: u32,
    pub wo: glam::Vec3,
    /// Three uniforms in [0, 1) when sampling; the direction wi when evaluating.
    pub x: glam::Vec3,
    /// wo is outside the object (its front face); inside, the relative IOR inverts.
    pub front: bool,
}

/// What the device BSDF answered for one query.
#[derive(Clone, Copy, Debug, Default)]
pub struct BsdfProbe {
    pub wi: glam::Vec3,
    /// f cos / pdf of the sample.
    pub weight: glam::Vec3,
    pub pdf: f32,
    pub delta: bool,
    /// Sampling produced a direction (false: absorbed or below the horizon).
    pub ok: bool,
    /// f(wo, wi), pdf(wo, wi) and f(wi, wo) evaluated at the returned or given direction.
    pub eval: glam::Vec3,
    pub pdf_wi: f32,
    pub eval_reverse: glam::Vec3,
}

/// The scene's device buffers, bound at the same bindings by every stage.
struct SceneBuffers {
    nodes: Buffer,
    tri_verts: Buffer,
    tri_shading: Buffer,
    materials: Buffer,
    lights: Buffer,
    env: Buffer,
    punctual: Buffer,
    textures: Buffer,
    texels: Buffer,
    tri_texcoords: Buffer,
    tri_tangents: Buffer,
    tri_colors: Buffer,
}

/// How traversal reads the BVH nodes and triangle vertices (the same bytes either way).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BvhReads {
    /// Storage-buffer loads: works everywhere.
    Storage,
    /// Uniform texel buffers (RGBA32UI): on lavapipe several times faster; used when the device's
    /// maxTexelBufferElements holds the scene. PATHWAVE_BVH_READS=storage forces the other path.
    Texel,
}

/// How a pass takes its paths through the stages. Both give the same bytes for a seed (tests/schedule.rs).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Schedule {
    /// generate, then extend, shade and connect once per bounce, with paths compacted through queues in between:
    /// the default on GPUs, where stages with full, coherent waves matter most.
    Wavefront,
    /// One `follow` dispatch: each invocation takes one pixel's samples from camera to end with the path state in
    /// registers, starting its next sample as soon as a path ends. No path state goes through memory (on lavapipe
    /// each path-state store is a loop of scalar stores), but a subgroup runs a shadow-ray traversal whenever any of
    /// its lanes has a shadow ray, where connect runs only compacted ones. On lavapipe the Cornell box renders 1.25x
    /// as many samples per second this way; scenes where fewer bounces cast shadow rays (glass, glossy and textured
    /// ones) run 1.2-1.45x slower.
    Fused,
}

/// How passes pick their schedule. PATHWAVE_SCHEDULE=wavefront|fused fixes it.
#[derive(Clone, Copy, Debug)]
enum ScheduleChoice {
    Fixed(Schedule),
    /// On CPU devices, where which is faster depends on the scene: passes 0 and 1 run the wavefront, 2 and 3 the
    /// fused schedule; the second of each pair (the first compiles) is timed, GPU time per path, and the faster is
    /// kept. Renders of one or two passes never build the fused pipelines. Both give the same bytes, so switching
    /// between passes changes nothing but speed.
    Trial {
        passes: u32,
        /// Wavefront, fused.
        ns_per_path: [f64; 2],
    },
}

impl ScheduleChoice {
    fn current(&self) -> Schedule {
        match *self {
            ScheduleChoice::Fixed(s) => s,
            ScheduleChoice::Trial { passes: 0..=1, .. } => Schedule::Wavefront,
            ScheduleChoice::Trial { passes: 2..=3, .. } => Schedule::Fused,
            ScheduleChoice::Trial {
                ns_per_path: [w, f], ..
            } if f < w => Schedule::Fused,
            ScheduleChoice::Trial { .. } => Schedule::Wavefront,
        }
    }

    /// Counts a pass that ran `current()` and took `ns` of GPU time for `paths` paths.
    fn record(&mut self, ns: f64, paths: u32) {
        if let ScheduleChoice::Trial { passes, ns_per_path } = self {
            match *passes {
                1 => ns_per_path[0] = ns / paths.max(1) as f64,
                3 => ns_per_path[1] = ns / paths.max(1) as f64,
                _ => {}
            }
            *passes = passes.saturating_add(1);
        }
    }
}

/// Which compiled variant of each stage a scene's passes dispatch.
struct StageVariants {
    extend: &'static str,
    shade: &'static str,
    connect: &'static str,
    follow: &'static str,
}

/// Records one pass's dispatches, each timed under its stage's name and followed by a barrier.
struct Recorder<'a> {
    ctx: &'a Context,
    p: &'a Pipelines,
    ts: &'a mut Timestamps,
    cmd: vk::CommandBuffer,
}

impl Recorder<'_> {
    fn dispatch(&mut self, name: &'static str, frame: &Frame, groups: u32) {
        let (p, cmd) = (self.p, self.cmd);
        self.ts
            .time(cmd, stage_label(name), || p.dispatch(cmd, name, frame, groups));
        self.ctx.barrier(cmd);
    }

    /// Sized by the queue counters queue_args turned into dispatch arguments.
    fn dispatch_indirect(&mut self, name: &'static str, frame: &Frame, counters: &Buffer) {
        let (p, cmd) = (self.p, self.cmd);
        self.ts.time(cmd, stage_label(name), || {
            p.dispatch_indirect(cmd, name, frame, counters, COUNTERS_DISPATCH_OFFSET)
        });
        self.ctx.barrier(cmd);
    }

    /// Camera rays into queue 0, then each bounce's stages over the paths still alive.
    fn wavefront(&mut self, stages: &StageVariants, frame: &Frame, counters: &Buffer) {
        self.dispatch("generate", frame, frame.path_count.div_ceil(WORKGROUP_SIZE));
        let mut f = *frame;
        for bounce in 0..=frame.max_depth {
            f.bounce = bounce;
            self.dispatch("queue_args", &f, 1);
            self.dispatch_indirect(stages.extend, &f, counters);
            self.dispatch_indirect(stages.shade, &f, counters);
            // Shade queues at most one shadow ray per path, so the extension dispatch size bounds connect's.
            self.dispatch_indirect(stages.connect, &f, counters);
        }
        // After the last bounce only the shadow-ray tally remains (queue_args.comp).
        f.bounce = NO_HIT;
        self.dispatch("queue_args", &f, 1);
    }
}

/// The stages only the wavefront runs: an edited one must be run (Renderer::load_shaders).
const WAVEFRONT_STAGES: [&str; 5] = ["generate", "queue_args", "extend", "shade", "connect"];

/// A variant's timings count under its stage: "extend_alpha_texel" is extend.
fn stage_label(name: &str) -> &str {
    crate::variants::STAGE_VARIANTS
        .iter()
        .find(|(stage, suffix, _)| name.strip_prefix(stage).and_then(|r| r.strip_prefix('_')) == Some(suffix))
        .map_or(name, |(stage, _, _)| stage)
}

/// Bytes for a message: MiB when large, bytes when not.
fn size_text(bytes: u64) -> String {
    if bytes >= 1 << 20 {
        format!("{:.1} MiB", bytes as f64 / (1u64 << 20) as f64)
    } else {
        format!("{bytes} bytes")
    }
}

/// Texel views of the BVH, per-triangle and image-texel buffers for BvhReads::Texel, by binding.
struct TexelViews {
    views: Vec<(u32, vk::BufferView)>,
    device: ash::Device,
}

impl TexelViews {
    /// Image texels are viewed as R32UI (one RGBA8 texel each), the path state as RGBA32F, everything else as
    /// RGBA32UI.
    fn new(ctx: &Context, buffers: &[(u32, &Buffer)]) -> Result<Self, Error> {
        let mut v = TexelViews {
            views: Vec::new(),
            device: ctx.device.clone(),
        };
        for (binding, b) in buffers {
            let info = vk::BufferViewCreateInfo::default()
                .buffer(b.raw)
                .format(match *binding {
                    BINDING_IMAGE_TEXELS => vk::Format::R32_UINT,
                    BINDING_PATH_TEXELS => vk::Format::R32G32B32A32_SFLOAT,
                    _ => vk::Format::R32G32B32A32_UINT,
                })
                .offset(0)
                .range(vk::WHOLE_SIZE);
            // On failure, Drop releases the views made so far.
            v.views
                .push((*binding, unsafe { ctx.device.create_buffer_view(&info, None) }?));
        }
        Ok(v)
    }
}

impl Drop for TexelViews {
    fn drop(&mut self) {
        for (_, view) in &self.views {
            unsafe { self.device.destroy_buffer_view(*view, None) };
        }
    }
}

/// A progressive render: the film and path state stay on the device between `Renderer::advance` calls, so a
/// viewer can add samples frame by frame and show the running mean.
pub struct Session {
    pub settings: RenderSettings,
    frame: Frame,
    pixels: u64,
    capacity: u32,
    /// The path state's texel views: dropped before it.
    path_views: TexelViews,
    paths: Buffer,
    queues: Buffer,
    counters: Buffer,
    film: Buffer,
    probe: Buffer,
    /// Samples per pixel accumulated so far.
    pub done: u32,
    /// Tallies since the last (re)start.
    pub stats: RenderStats,
    started: Instant,
}

impl Session {
    /// The session's buffers by binding, with `probe` in the probe slot (the tone map writes its pixels there).
    fn bindings<'a>(&'a self, probe: &'a Buffer) -> [(u32, &'a Buffer); 5] {
        [
            (BINDING_PATHS, &self.paths),
            (BINDING_QUEUES, &self.queues),
            (BINDING_COUNTERS, &self.counters),
            (BINDING_FILM, &self.film),
            (BINDING_PROBE, probe),
        ]
    }

    /// Samples (paths) per second since the session last (re)started.
    pub fn samples_per_sec(&self) -> f64 {
        self.stats.samples as f64 / self.started.elapsed().as_secs_f64().max(1e-9)
    }

    /// The film buffer on the device: running sums, then running sums of squares (see layout.glsl).
    pub fn film_buffer(&self) -> &Buffer {
        &self.film
    }
}

/// A scene uploaded to one device, ready to render any number of images.
pub struct Renderer {
    // Field order is drop order: everything device-owned goes before the context.
    timestamps: Timestamps,
    pipelines: Pipelines,
    /// Views of scene buffers: dropped before them.
    texel_views: Option<TexelViews>,
    /// A one-texel path-state view bound whenever no session's is: a set must not keep a destroyed view (lavapipe
    /// reads every binding of the set when it is bound, used or not).
    path_stand_in: (TexelViews, Buffer),
    /// Every BVH and per-triangle buffer fits the storage-buffer range (BvhReads::Storage can read the scene).
    storage_ok: bool,
    scene: SceneBuffers,
    /// Built once per device at start-up; None only while it is being built.
    energy: Option<Buffer>,
    light_count: u32,
    /// Some triangle's material is alpha-tested: traversal runs the *_alpha variants.
    alpha_tested: bool,
    /// How traversal reads the BVH; Texel needs `texel_views`.
    bvh_reads: BvhReads,
    /// Some material has a texture or alpha, or some mesh has COLOR_0: shading runs the textured variant.
    textured: bool,
    schedule: ScheduleChoice,
    /// Sample rows a follow dispatch takes, from FOLLOW_SAMPLES up to follow_rows_max: doubled after each fused pass,
    /// halved when lavapipe's loop budget cut one short (and follow_rows_max lowered to it).
    follow_rows: u32,
    follow_rows_max: u32,
    /// The scene's FEATURE_* bits; a pass adds FEATURE_LENS when its camera has an aperture.
    scene_features: u32,
    vertex_colors: bool,
    env_prob: f32,
    env_size: (u32, u32),
    env_rotation: f32,
    /// The camera's distance to the scene's centre along its view direction: the focus when none is given.
    default_focus: f32,
    camera: crate::scene::Camera,
    bvh_build: Duration,
    pub warnings: Vec<String>,
    ctx: Context,
}

/// The SPIR-V of a built-in stage, by name (e.g. "shade").
pub fn builtin_spirv(name: &str) -> Option<&'static [u8]> {
    crate::shaders::BUILTIN_SPIRV
        .iter()
        .find(|(n, _)| *n == name)
        .map(|(_, s)| *s)
}

pub fn builtin_stage_names() -> impl Iterator<Item = &'static str> {
    crate::shaders::BUILTIN_SPIRV.iter().map(|(n, _)| *n)
}

impl Renderer {
    pub fn new(scene: &Scene, device: &DeviceChoice) -> Result<Self, Error> {
        Self::with_validation(scene, device, Validation::from_env())
    }

    pub fn with_validation(scene: &Scene, device: &DeviceChoice, validation: Validation) -> Result<Self, Error> {
        Self::with_context(scene, Context::new(device, validation)?)
    }

    /// A renderer on a context made by the caller (e.g. one that can present to a window).
    pub fn with_context(scene: &Scene, ctx: Context) -> Result<Self, Error> {
        let packed = gpu_scene::pack(scene);
        let mut warnings = scene.warnings.clone();
        if packed.lights.is_empty() {
            warnings.push(
                "the scene has no emissive surface and no environment, so nothing lights it and the image is black"
                    .into(),
            );
        }
        // Traversal packs node and triangle indices with a leaf's count into one word (STACK_COUNT_BITS).
        if packed.bvh.nodes.len().max(packed.tri_verts.len()) as u64 >= MAX_SCENE_ITEMS as u64 {
            return Err(Error::Settings(format!(
                "the scene has {} triangles in {} BVH nodes; traversal handles fewer than {MAX_SCENE_ITEMS} of each",
                packed.tri_verts.len(),
                packed.bvh.nodes.len()
            )));
        }
        let range = ctx.properties.limits.max_storage_buffer_range as u64;
        // One storage buffer per kind of data. The BVH and per-triangle buffers are also readable as texels when
        // the device can hold them that way (BvhReads::Texel), which lifts the storage-buffer range off them: a
        // scene is refused, by buffer name, only when one of them outgrows every way the device can read it.
        let max_texels = ctx.properties.limits.max_texel_buffer_elements as u64;
        let uint4 = unsafe {
            ctx.instance
                .get_physical_device_format_properties(ctx.physical, vk::Format::R32G32B32A32_UINT)
        };
        let uint1 = unsafe {
            ctx.instance
                .get_physical_device_format_properties(ctx.physical, vk::Format::R32_UINT)
        };
        let texel_format = [uint4, uint1]
            .iter()
            .all(|f| f.buffer_features.contains(vk::FormatFeatureFlags::UNIFORM_TEXEL_BUFFER));
        // Every buffer read through an RGBA32UI view (all but the image texels).
        let viewed_bytes = [
            std::mem::size_of_val(&packed.materials[..]),
            std::mem::size_of_val(&packed.lights[..]),
            std::mem::size_of_val(&packed.bvh.nodes[..]),
            std::mem::size_of_val(&packed.tri_verts[..]),
            std::mem::size_of_val(&packed.tri_shading[..]),
            std::mem::size_of_val(&packed.tri_texcoords[..]),
            std::mem::size_of_val(&packed.tri_tangents[..]),
            std::mem::size_of_val(&packed.tri_colors[..]),
        ];
        let texel_ok = texel_format
            && viewed_bytes.iter().all(|b| *b as u64 <= 16 * max_texels)
            && packed.texels.len() as u64 <= max_texels;
        // `element`: the bytes per texel of the view the buffer is also read through, if any.
        let upload_as = |name: &str, data: &[u8], element: Option<u64>| -> Result<Buffer, Error> {
            let bytes = data.len() as u64;
            let texels = element.is_some();
            if bytes > range && !(texels && texel_ok) {
                return Err(Error::Settings(format!(
                    "the scene's {name} take {}, more than this device's storage-buffer range of {}{}",
                    size_text(bytes),
                    size_text(range),
                    if texels && texel_format {
                        format!(
                            " and its texel-buffer limit of {}",
                            size_text(element.unwrap_or(0) * max_texels)
                        )
                    } else {
                        String::new()
                    }
                )));
            }
            let usage = vk::BufferUsageFlags::STORAGE_BUFFER
                | if texels && texel_ok {
                    vk::BufferUsageFlags::UNIFORM_TEXEL_BUFFER
                } else {
                    vk::BufferUsageFlags::empty()
                };
            Buffer::with_data_usage(&ctx, name, data, usage)
        };
        let upload = |name: &str, data: &[u8]| upload_as(name, data, None);
        // Read through a view by the texel stages and from the storage buffer by the others (probe_bsdf, the storage
        // variants), so it must fit the storage range either way: past it, the storage-only upload refuses it by name.
        let upload_both = |name: &str, data: &[u8]| upload_as(name, data, (data.len() as u64 <= range).then_some(16));
        let per_tri = |name: &str, data: &[u8]| upload_as(name, data, Some(16));
        use bytemuck::cast_slice as bytes;
        let buffers = SceneBuffers {
            nodes: per_tri("bvh nodes", bytes(&packed.bvh.nodes))?,
            tri_verts: per_tri("triangle vertices", bytes(&packed.tri_verts))?,
            tri_shading: per_tri("triangle shading", bytes(&packed.tri_shading))?,
            tri_texcoords: per_tri("texture coordinates", bytes(&packed.tri_texcoords))?,
            tri_tangents: per_tri("tangents", bytes(&packed.tri_tangents))?,
            tri_colors: per_tri("vertex colours", bytes(&packed.tri_colors))?,
            materials: upload_both("materials", bytes(&packed.materials))?,
            lights: upload_both("lights", bytes(&packed.lights))?,
            env: upload("environment", bytes(&packed.env_data))?,
            punctual: upload("punctual lights", bytes(&packed.punctual))?,
            textures: upload("textures", bytes(&packed.textures))?,
            texels: upload_as("texture texels", bytes(&packed.texels), Some(4))?,
        };
        let b = &buffers;
        let texel_views = if texel_ok {
            Some(TexelViews::new(
                &ctx,
                &[
                    (BINDING_NODE_TEXELS, &b.nodes),
                    (BINDING_TRI_TEXELS, &b.tri_verts),
                    (BINDING_TRI_SHADING_TEXELS, &b.tri_shading),
                    (BINDING_TRI_TEXCOORD_TEXELS, &b.tri_texcoords),
                    (BINDING_TRI_TANGENT_TEXELS, &b.tri_tangents),
                    (BINDING_TRI_COLOR_TEXELS, &b.tri_colors),
                    (BINDING_IMAGE_TEXELS, &b.texels),
                    (BINDING_MATERIAL_TEXELS, &b.materials),
                    (BINDING_LIGHT_TEXELS, &b.lights),
                ],
            )?)
        } else {
            None
        };
        // Storage reads need every per-triangle buffer and the image texels within the storage range.
        let storage_ok = viewed_bytes.iter().all(|b| *b as u64 <= range) && b.texels.size <= range;
        let env = scene.environment.as_ref();
        let alpha_tested = packed.tri_verts.iter().any(|t| t.e1[3] != 0.0);
        let bvh_reads = match (&texel_views, std::env::var("PATHWAVE_BVH_READS").as_deref()) {
            (Some(_), Ok("storage")) if !storage_ok => {
                return Err(Error::Settings(
                    "PATHWAVE_BVH_READS=storage: the scene's BVH or per-triangle data outgrow this device's \
                     storage-buffer range"
                        .into(),
                ))
            }
            (_, Ok("storage")) | (None, _) => BvhReads::Storage,
            (Some(_), _) => BvhReads::Texel,
        };
        let schedule = match std::env::var("PATHWAVE_SCHEDULE").as_deref() {
            Ok("wavefront") => ScheduleChoice::Fixed(Schedule::Wavefront),
            Ok("fused") => ScheduleChoice::Fixed(Schedule::Fused),
            Ok(other) => {
                return Err(Error::Settings(format!(
                    "PATHWAVE_SCHEDULE={other}: expected wavefront or fused"
                )))
            }
            // On GPUs the wavefront's compacted, coherent stages are the design; a CPU device is measured.
            Err(_) if ctx.properties.device_type == vk::PhysicalDeviceType::CPU => ScheduleChoice::Trial {
                passes: 0,
                ns_per_path: [0.0; 2],
            },
            Err(_) => ScheduleChoice::Fixed(Schedule::Wavefront),
        };
        let scene_features = packed.features();
        let pipelines = Pipelines::new(&ctx, crate::shaders::BUILTIN_SPIRV, scene_features)?;
        if let Some(v) = &texel_views {
            pipelines.bind_texel_views(&ctx, &v.views);
        }
        let timestamps = Timestamps::new(&ctx, 2048)?;
        let stand_in = Buffer::new(
            &ctx,
            "path state stand-in",
            16,
            vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::UNIFORM_TEXEL_BUFFER,
            MemoryLocation::GpuOnly,
        )?;
        let path_stand_in = (TexelViews::new(&ctx, &[(BINDING_PATH_TEXELS, &stand_in)])?, stand_in);
        pipelines.bind_texel_views(&ctx, &path_stand_in.0.views);
        let mut r = Renderer {
            timestamps,
            pipelines,
            scene: buffers,
            energy: None,
            light_count: packed.lights.len() as u32,
            alpha_tested,
            bvh_reads,
            storage_ok,
            texel_views,
            path_stand_in,
            textured: alpha_tested || !packed.tri_texcoords.is_empty() || !packed.tri_colors.is_empty(),
            schedule,
            follow_rows: FOLLOW_SAMPLES,
            follow_rows_max: FOLLOW_ROWS_MAX,
            scene_features,
            vertex_colors: !packed.tri_colors.is_empty(),
            env_prob: packed.env_prob,
            env_size: env.map(|e| (e.width, e.height)).unwrap_or((0, 0)),
            env_rotation: env.map(|e| e.rotation).unwrap_or(0.0),
            default_focus: {
                let cam = scene.camera_or_default();
                let (lo, hi) = if scene.is_empty() {
                    (glam::Vec3::ZERO, glam::Vec3::ZERO)
                } else {
                    scene.bounds()
                };
                ((lo + hi) * 0.5 - cam.origin()).dot(cam.basis().2).max(1e-3)
            },
            camera: scene.camera_or_default(),
            bvh_build: packed.bvh_build,
            warnings,
            ctx,
        };
        r.energy = Some(r.build_energy_tables()?);
        Ok(r)
    }

    /// The microfacet energy tables: the grid from the device (the BSDF's own sampling), the averages from the host.
    fn build_energy_tables(&mut self) -> Result<Buffer, Error> {
        let n = ENERGY_RES as usize;
        let floats = ENERGY_TABLE_FLOATS as usize;
        let storage = vk::BufferUsageFlags::STORAGE_BUFFER;
        let mut energy = Buffer::new(
            &self.ctx,
            "energy tables",
            floats as u64 * 4,
            storage,
            MemoryLocation::GpuOnly,
        )?;
        let cells = ENERGY_RES * ENERGY_RES;
        self.run_kernel(
            "energy_tables",
            &[(BINDING_ENERGY, &energy)],
            Frame {
                path_count: cells,
                ..Default::default()
            },
            1,
        )?;
        let mut table: Vec<f32> = energy.download(&self.ctx)?;
        table.truncate(floats);
        let h = 1.0 / (n - 1) as f64;
        for t in 0..2 {
            for j in 0..n {
                // 2 * int_0^1 E(mu) mu dmu by the trapezoid rule on the grid the table was made on.
                let row = &table[t * n * n + j * n..t * n * n + (j + 1) * n];
                let integral: f64 = (0..n - 1)
                    .map(|i| 0.5 * h * (row[i] as f64 * i as f64 * h + row[i + 1] as f64 * (i + 1) as f64 * h))
                    .sum();
                table[2 * n * n + t * n + j] = (2.0 * integral) as f32;
            }
        }
        energy.upload(&self.ctx, bytemuck::cast_slice(&table))?;
        Ok(energy)
    }

    /// The energy tables as the device uses them: E1 and E2 grids, then their averages (see ENERGY_* constants).
    pub fn energy_tables(&self) -> Result<Vec<f32>, Error> {
        let energy = self.energy.as_ref().expect("built in Renderer::new");
        let mut t: Vec<f32> = energy.download(&self.ctx)?;
        t.truncate(ENERGY_TABLE_FLOATS as usize);
        Ok(t)
    }

    /// Rebuilds the pipelines of `stages` (every stage the folder overrides when None) from a shader folder. All
    /// compile before any is replaced, so a compile error leaves the renderer exactly as it was. Returns the stages
    /// rebuilt. An edited stage must be the one that runs: a wavefront stage among them fixes the wavefront schedule,
    /// follow alone the fused one (an edit to path.glsl rebuilds both, and both then give the same image).
    pub fn load_shaders(
        &mut self,
        dir: &crate::shaders::ShaderDir,
        stages: Option<&[String]>,
    ) -> Result<Vec<String>, Error> {
        let names = stages.map(<[String]>::to_vec).unwrap_or_else(|| dir.stages());
        let mut compiled = Vec::with_capacity(names.len());
        for name in &names {
            compiled.push(dir.compile(name)?);
        }
        for (name, spv) in names.iter().zip(&compiled) {
            self.pipelines.replace(&self.ctx, name, spv)?;
        }
        if names.iter().any(|n| WAVEFRONT_STAGES.contains(&stage_label(n))) {
            self.schedule = ScheduleChoice::Fixed(Schedule::Wavefront);
        } else if names.iter().any(|n| stage_label(n) == "follow") {
            self.schedule = ScheduleChoice::Fixed(Schedule::Fused);
        }
        Ok(names)
    }

    /// How long building the scene's BVH took.
    pub fn bvh_build_time(&self) -> Duration {
        self.bvh_build
    }

    /// Device bytes of what traversal and shading read per triangle: BVH nodes, vertices and shading normals.
    pub fn traversal_bytes(&self) -> u64 {
        self.scene.nodes.size + self.scene.tri_verts.size + self.scene.tri_shading.size
    }

    pub fn context(&self) -> &Context {
        &self.ctx
    }

    fn check_validation(&self) -> Result<(), Error> {
        let errors = self.ctx.validation_errors();
        match errors.first() {
            None => Ok(()),
            Some(first) => Err(Error::Validation {
                count: errors.len(),
                first: first.clone(),
            }),
        }
    }

    fn bind_scene(&self, extra: &[(u32, &Buffer)]) {
        let b = &self.scene;
        let mut all = vec![
            (BINDING_NODES, &b.nodes),
            (BINDING_TRI_VERTS, &b.tri_verts),
            (BINDING_TRI_SHADING, &b.tri_shading),
            (BINDING_MATERIALS, &b.materials),
            (BINDING_LIGHTS, &b.lights),
            (BINDING_ENV, &b.env),
            (BINDING_PUNCTUAL, &b.punctual),
            (BINDING_TEXTURES, &b.textures),
            (BINDING_TEXELS, &b.texels),
            (BINDING_TRI_TEXCOORDS, &b.tri_texcoords),
            (BINDING_TRI_TANGENTS, &b.tri_tangents),
            (BINDING_TRI_COLORS, &b.tri_colors),
        ];
        // While the energy tables are being built, the caller binds them.
        if let Some(energy) = &self.energy {
            all.push((BINDING_ENERGY, energy));
        }
        all.extend_from_slice(extra);
        self.pipelines.bind_buffers(&self.ctx, &all);
    }

    fn frame(&self, s: &RenderSettings) -> Frame {
        let (right, up, forward) = self.camera.basis();
        let o = self.camera.origin();
        Frame {
            cam_origin: [o.x, o.y, o.z, (self.camera.yfov * 0.5).tan()],
            cam_right: [right.x, right.y, right.z, s.width as f32 / s.height as f32],
            cam_up: [up.x, up.y, up.z, s.aperture],
            cam_forward: [
                forward.x,
                forward.y,
                forward.z,
                s.focus_distance.unwrap_or(self.default_focus),
            ],
            width: s.width,
            height: s.height,
            seed: s.seed,
            // The cap applies to unbounded paths only; an explicit depth is taken as given.
            max_depth: s.max_depth.unwrap_or(DEPTH_SAFETY_CAP),

            light_count: self.light_count,
            flags: s.estimator.code() << ESTIMATOR_SHIFT
                | if s.energy_compensation {
                    FLAG_ENERGY_COMPENSATION
                } else {
                    0
                }
                | if s.hide_environment { FLAG_HIDE_ENV } else { 0 }
                | if self.vertex_colors { FLAG_VERTEX_COLORS } else { 0 },
            env_prob: self.env_prob,
            env_rotation: self.env_rotation,
            env_width: self.env_size.0,
            env_height: self.env_size.1,
            ..Default::default()
        }
    }

    /// Renders `settings.spp` samples per pixel; `progress` hears the samples per pixel done so far.
    pub fn render(
        &mut self,
        settings: &RenderSettings,
        progress: &mut dyn FnMut(u32),
    ) -> Result<(Film, RenderStats), Error> {
        let mut session = self.begin(settings)?;
        while session.done < settings.spp {
            let remaining = settings.spp - session.done;
            self.advance(&mut session, remaining)?;
            progress(session.done);
        }
        let film = self.film(&session)?;
        let mut stats = std::mem::take(&mut session.stats);
        stats.wall = session.started.elapsed();
        if stats.passes == 1 {
            stats.stage_ms = std::mem::take(&mut stats.first_pass_stage_ms);
        }
        Ok((film, stats))
    }

    /// Starts a progressive render: allocates the film and path state and clears the film. `settings.spp` is not
    /// used; `advance` adds samples until the caller stops.
    pub fn begin(&mut self, settings: &RenderSettings) -> Result<Session, Error> {
        let s = settings;
        if s.width == 0 || s.height == 0 {
            return Err(Error::Settings(format!(
                "image size {}x{} has no pixels",
                s.width, s.height
            )));
        }
        if s.spp == 0 {
            return Err(Error::Settings("samples per pixel must be at least 1".into()));
        }
        if !(s.aperture.is_finite() && s.aperture >= 0.0)
            || s.focus_distance.is_some_and(|f| !(f.is_finite() && f > 0.0))
        {
            return Err(Error::Settings(
                "the aperture must be >= 0 and the focus distance > 0".into(),
            ));
        }
        let pixels = s.width as u64 * s.height as u64;
        let range = self.ctx.properties.limits.max_storage_buffer_range as u64;
        let film_bytes = pixels * 32;
        if film_bytes > range || pixels > u32::MAX as u64 / 2 {
            return Err(Error::Settings(format!(
                "{}x{} needs a {film_bytes}-byte film but this device's storage buffers hold at most {range} bytes",
                s.width, s.height
            )));
        }
        let per_path = PATH_FIELDS as u64 * 16;
        // Paths in flight: every pixel times as many samples as fit, or chunks of pixels when one sample of the image
        // alone is larger. The budget is a sixteenth of the largest device-local heap, within one storage buffer's
        // range: on lavapipe that is 2^20 paths (128 MiB), 6 % faster on the Cornell box than the 2^18 used before.
        let memory = unsafe {
            self.ctx
                .instance
                .get_physical_device_memory_properties(self.ctx.physical)
        };
        let heap = memory.memory_heaps[..memory.memory_heap_count as usize]
            .iter()
            .filter(|h| h.flags.contains(vk::MemoryHeapFlags::DEVICE_LOCAL))
            .map(|h| h.size)
            .max()
            .unwrap_or(256 << 20);
        let budget = (heap / 16).max(per_path * 1024);
        // The TEXEL_READS stages read the path state through one texel view, which must see all of it.
        let view_paths = self.ctx.properties.limits.max_texel_buffer_elements as u64 / PATH_FIELDS as u64;
        let capacity = (pixels * s.spp as u64)
            .min(range / per_path)
            .min(view_paths)
            .min(budget / per_path)
            .min(u32::MAX as u64 / 4) as u32;
        let ctx = &self.ctx;
        let storage = vk::BufferUsageFlags::STORAGE_BUFFER;
        let paths = Buffer::new(
            ctx,
            "path state",
            capacity as u64 * per_path,
            storage | vk::BufferUsageFlags::UNIFORM_TEXEL_BUFFER,
            MemoryLocation::GpuOnly,
        )?;
        let path_views = TexelViews::new(ctx, &[(BINDING_PATH_TEXELS, &paths)])?;
        let queues = Buffer::new(ctx, "queues", capacity as u64 * 4 * 3, storage, MemoryLocation::GpuOnly)?;
        let counters = Buffer::new(
            ctx,
            "counters",
            std::mem::size_of::<Counters>() as u64,
            storage | vk::BufferUsageFlags::INDIRECT_BUFFER,
            MemoryLocation::GpuToCpu,
        )?;
        let film = Buffer::new(ctx, "film", film_bytes, storage, MemoryLocation::GpuOnly)?;
        let probe = Buffer::new(ctx, "probe (unused)", 16, storage, MemoryLocation::GpuOnly)?;
        let mut session = Session {
            settings: s.clone(),
            frame: Frame::default(),
            pixels,
            capacity,
            path_views,
            paths,
            queues,
            counters,
            film,
            probe,
            done: 0,
            stats: RenderStats::default(),
            started: Instant::now(),
        };
        self.restart(&mut session)?;
        Ok(session)
    }

    /// Clears a session's film and starts again from sample 0 with the renderer's current camera and the session's
    /// settings (the image size must stay the same).
    pub fn restart(&mut self, session: &mut Session) -> Result<(), Error> {
        let mut frame = self.frame(&session.settings);
        frame.path_capacity = session.capacity;
        session.frame = frame;
        session.done = 0;
        session.stats = RenderStats::default();
        session.started = Instant::now();
        let (ctx, film) = (&self.ctx, &session.film);
        ctx.submit_and_wait(|cmd| unsafe { ctx.device.cmd_fill_buffer(cmd, film.raw, 0, vk::WHOLE_SIZE, 0) })
    }

    /// Runs one pass: up to `samples` more samples per pixel (as many as fit in flight; one when the image must be
    /// covered in chunks). Returns how many were added.
    pub fn advance(&mut self, session: &mut Session, samples: u32) -> Result<u32, Error> {
        self.bind_scene(&session.bindings(&session.probe));
        self.pipelines.bind_texel_views(&self.ctx, &session.path_views.views);
        let (pixels, capacity) = (session.pixels, session.capacity);
        let mut frame = session.frame;
        frame.sample_index = session.done;
        let mut stats = std::mem::take(&mut session.stats);
        let added = if pixels <= capacity as u64 {
            // Whole samples of every pixel, as many as fit.
            // A fused pass keeps only a pixel's running sums in the path state, so it may take more samples than
            // fit there (FOLLOW_ROWS_MAX: a dispatch takes up to that many, and the more, the less lanes wait for
            // the last paths); a wavefront pass as many as fit.
            let fit = (capacity as u64 / pixels) as u32;
            let k = match self.schedule.current() {
                // path_count must stay within u32, as the path state's capacity does.
                Schedule::Fused => fit.max(FOLLOW_ROWS_MAX).min((u32::MAX as u64 / 4 / pixels) as u32),
                Schedule::Wavefront => fit,
            }
            .min(samples.max(1));
            frame.pixel_offset = 0;
            frame.pass_pixels = pixels as u32;
            frame.path_count = pixels as u32 * k;
            let r = self.run_pass(&frame, &session.counters, &mut stats);
            session.stats = stats;
            r?;
            k
        } else {
            // One sample, the image in chunks of `capacity` pixels.
            for chunk in 0..pixels.div_ceil(capacity as u64) as u32 {
                frame.pixel_offset = chunk * capacity;
                frame.pass_pixels = (pixels - frame.pixel_offset as u64).min(capacity as u64) as u32;
                frame.path_count = frame.pass_pixels;
                if let Err(e) = self.run_pass(&frame, &session.counters, &mut stats) {
                    session.stats = stats;
                    return Err(e);
                }
            }
            session.stats = stats;
            1
        };
        session.done += added;
        self.check_validation()?;
        Ok(added)
    }

    /// The session's film so far (running sums over `done` samples per pixel).
    pub fn film(&self, session: &Session) -> Result<Film, Error> {
        let raw: Vec<[f32; 4]> = session.film.download(&self.ctx)?;
        self.check_validation()?;
        let pixels = session.pixels as usize;
        let (sum, sum_sq) = raw.split_at(pixels);
        Ok(Film {
            width: session.settings.width,
            height: session.settings.height,
            spp: session.done,
            sum: sum.to_vec(),
            sum_sq: sum_sq[..pixels].to_vec(),
        })
    }

    /// Writes the session's running mean into `out` as packed 8-bit sRGB pixels of `out_size` (nearest-scaled from
    /// the film), through `op`'s tone curve after scaling by `exposure` (linear). Recorded into `cmd`, which the
    /// caller submits; a barrier after it makes the pixels ready for transfers.
    pub fn record_tonemap(
        &self,
        cmd: vk::CommandBuffer,
        session: &Session,
        out: &Buffer,
        out_size: [u32; 2],
        op: u32,
        exposure: f32,
    ) {
        self.bind_scene(&session.bindings(out));
        let tone = crate::layout::ToneMap {
            film_width: session.settings.width,
            film_height: session.settings.height,
            out_width: out_size[0],
            out_height: out_size[1],
            samples: session.done,
            op,
            exposure,
            pad: 0,
        };
        let groups = [out_size[0].div_ceil(TONEMAP_TILE), out_size[1].div_ceil(TONEMAP_TILE)];
        self.pipelines
            .dispatch_2d(cmd, "tonemap", bytemuck::bytes_of(&tone), groups);
        let barrier = vk::MemoryBarrier::default()
            .src_access_mask(vk::AccessFlags::SHADER_WRITE)
            .dst_access_mask(vk::AccessFlags::TRANSFER_READ);
        unsafe {
            self.ctx.device.cmd_pipeline_barrier(
                cmd,
                vk::PipelineStageFlags::COMPUTE_SHADER,
                vk::PipelineStageFlags::TRANSFER,
                vk::DependencyFlags::empty(),
                &[barrier],
                &[],
                &[],
            )
        };
    }

    /// The distance along the view direction to the first surface under image position (x, y) in [0, 1]^2 (0, 0 at
    /// the top left), for click-to-focus; None when the ray escapes.
    pub fn focus_distance_at(&mut self, x: f32, y: f32, aspect: f32) -> Result<Option<f32>, Error> {
        let (right, up, forward) = self.camera.basis();
        let t = (self.camera.yfov * 0.5).tan();
        let dir = (forward + right * ((2.0 * x - 1.0) * t * aspect) + up * ((1.0 - 2.0 * y) * t)).normalize();
        let ray = crate::bvh::Ray {
            origin: self.camera.origin(),
            dir,
            tmin: 0.0,
            tmax: f32::INFINITY,
        };
        let hit = self.probe_trace(&[ray], false)?[0];
        Ok((hit.tri != NO_HIT).then(|| hit.t * dir.dot(forward)))
    }

    /// How traversal reads the BVH.
    pub fn bvh_reads(&self) -> BvhReads {
        self.bvh_reads
    }

    /// Chooses how traversal reads the BVH; Texel fails on a device (or scene size) without texel-buffer support.
    pub fn set_bvh_reads(&mut self, reads: BvhReads) -> Result<(), Error> {
        if reads == BvhReads::Texel && self.texel_views.is_none() {
            return Err(Error::Settings(
                "this device cannot read the scene's BVH through texel buffers".into(),
            ));
        }
        if reads == BvhReads::Storage && !self.storage_ok {
            return Err(Error::Settings(
                "the scene's BVH or per-triangle data outgrow this device's storage-buffer range; only texel reads \
                 hold them"
                    .into(),
            ));
        }
        self.bvh_reads = reads;
        Ok(())
    }

    /// How the next pass takes paths through the stages (on a CPU device, the one timed faster after four passes).
    pub fn schedule(&self) -> Schedule {
        self.schedule.current()
    }

    /// Sample rows the next follow dispatch takes (see FOLLOW_SAMPLES).
    pub fn follow_rows(&self) -> u32 {
        self.follow_rows
    }

    /// Fixes how passes run; both schedules work on every device and give the same bytes.
    pub fn set_schedule(&mut self, schedule: Schedule) {
        self.schedule = ScheduleChoice::Fixed(schedule);
    }

    /// The camera renders use; `set_camera` changes it for the next `begin` or `restart`.
    pub fn camera(&self) -> Camera {
        self.camera
    }

    pub fn set_camera(&mut self, camera: Camera) {
        self.camera = camera;
    }

    /// The focus distance used when the settings give none: the camera's distance to the scene's centre.
    pub fn default_focus(&self) -> f32 {
        self.default_focus
    }

    /// Runs one pass and adds its ray tallies and (after the first pass, which also compiles) GPU stage times.
    fn run_pass(&mut self, frame: &Frame, counters: &Buffer, stats: &mut RenderStats) -> Result<(), Error> {
        let pass_start = Instant::now();
        let schedule = self.schedule.current();
        let mut times = Vec::new();
        let mut tally = self.tallied_pass(frame, counters, schedule, &mut times)?;
        while tally.follow_cut != 0 {
            // lavapipe cut follow's loops short (follow.comp), and accumulate skipped the pass. With fewer rows per
            // dispatch the pass runs fused again, and never with as many again; at the fewest, it runs again as a
            // wavefront, whose invocations each trace one ray, and the renderer stays with the wavefront.
            times.clear();
            // The rows the cut dispatch took: a pass may hold fewer than follow_rows.
            let taken = self.follow_rows.min(frame.path_count / frame.pass_pixels.max(1));
            if taken > FOLLOW_SAMPLES {
                self.follow_rows = (taken / 2).max(FOLLOW_SAMPLES);
                self.follow_rows_max = self.follow_rows;
                tally = self.tallied_pass(frame, counters, Schedule::Fused, &mut times)?;
            } else {
                self.warnings.push(
                    "the fused schedule ran past lavapipe's loop budget on this scene; using the wavefront".into(),
                );
                self.schedule = ScheduleChoice::Fixed(Schedule::Wavefront);
                tally = self.wavefront_in_chunks(frame, counters, &mut times)?;
            }
        }
        if schedule == Schedule::Fused && self.schedule.current() == Schedule::Fused {
            self.follow_rows = (2 * self.follow_rows).min(self.follow_rows_max);
        }
        stats.extension_rays += tally.extension_rays as u64;
        stats.shadow_rays += tally.shadow_rays as u64;
        stats.samples += frame.path_count as u64;
        // Without timestamps (some devices), the pass's wall time, which also holds the tally's download.
        let gpu_ns: f64 = times.iter().map(|(_, ns)| ns).sum();
        let ns = if gpu_ns > 0.0 {
            gpu_ns
        } else {
            pass_start.elapsed().as_nanos() as f64
        };
        self.schedule.record(ns, frame.path_count);
        if stats.passes == 0 {
            stats.first_pass = pass_start.elapsed();
            // Kept apart (it includes compilation) and reported only if no other pass follows.
            stats.first_pass_stage_ms = times.iter().map(|(l, ns)| (*l, ns * 1e-6)).collect();
        } else {
            for (label, ns) in times {
                add_labelled(&mut stats.stage_ms, label, ns * 1e-6);
            }
        }
        stats.passes += 1;
        Ok(())
    }

    /// `pass`, then its tallies; its GPU stage times are added to `times`.
    fn tallied_pass(
        &mut self,
        frame: &Frame,
        counters: &Buffer,
        schedule: Schedule,
        times: &mut Vec<(&'static str, f64)>,
    ) -> Result<Counters, Error> {
        self.pass(frame, counters, schedule)?;
        let tally: Counters = counters.download(&self.ctx)?[0];
        for (label, ns) in self.timestamps.read()? {
            add_labelled(times, label, ns);
        }
        Ok(tally)
    }

    /// A pass as wavefront passes of as many sample rows as the path state holds (a fused pass may have more), with
    /// their tallies summed.
    fn wavefront_in_chunks(
        &mut self,
        frame: &Frame,
        counters: &Buffer,
        times: &mut Vec<(&'static str, f64)>,
    ) -> Result<Counters, Error> {
        let rows = frame.path_count / frame.pass_pixels.max(1);
        let fit = (frame.path_capacity / frame.pass_pixels.max(1)).max(1);
        let mut total = Counters::default();
        for first in (0..rows).step_by(fit as usize) {
            let mut f = *frame;
            f.sample_index = frame.sample_index + first;
            f.path_count = fit.min(rows - first) * frame.pass_pixels;
            let t = self.tallied_pass(&f, counters, Schedule::Wavefront, times)?;
            // The device's tallies are u32 and wrap; so do these.
            total.extension_rays = total.extension_rays.wrapping_add(t.extension_rays);
            total.shadow_rays = total.shadow_rays.wrapping_add(t.shadow_rays);
        }
        Ok(total)
    }

    /// One pass: `frame.path_count` paths (pixels x samples), the whole path, every bounce, in one submission.
    fn pass(&mut self, frame: &Frame, counters: &Buffer, schedule: Schedule) -> Result<(), Error> {
        let stages = self.stage_variants();
        let names: &[&str] = match schedule {
            Schedule::Wavefront => &[
                "generate",
                "queue_args",
                stages.extend,
                stages.shade,
                stages.connect,
                "accumulate",
            ],
            Schedule::Fused => &[stages.follow, "accumulate"],
        };
        let lens = if frame.cam_up[3] > 0.0 { FEATURE_LENS } else { 0 };
        self.pipelines.set_features(self.scene_features | lens);
        self.pipelines.ensure(&self.ctx, names)?;
        let follow_rows = self.follow_rows;
        let Renderer {
            ctx,
            pipelines,
            timestamps,
            ..
        } = self;
        let mut rec = Recorder {
            ctx,
            p: pipelines,
            ts: timestamps,
            cmd: vk::CommandBuffer::null(),
        };
        ctx.submit_and_wait(|cmd| {
            rec.cmd = cmd;
            rec.ts.reset(cmd);
            unsafe { ctx.device.cmd_fill_buffer(cmd, counters.raw, 0, vk::WHOLE_SIZE, 0) };
            ctx.barrier(cmd);
            let mut f = *frame;
            match schedule {
                Schedule::Wavefront => rec.wavefront(&stages, frame, counters),
                Schedule::Fused => {
                    // follow_rows sample rows per dispatch, from frame.bounce to path_count / pass_pixels, each
                    // invocation one pixel, which keeps its running film sums itself.
                    f.flags |= FLAG_FUSED_SUMS;
                    let rows = frame.path_count / frame.pass_pixels;
                    for first in (0..rows).step_by(follow_rows as usize) {
                        f.bounce = first;
                        f.path_count = (first + follow_rows).min(rows) * frame.pass_pixels;
                        rec.dispatch(stages.follow, &f, frame.pass_pixels.div_ceil(WORKGROUP_SIZE));
                    }
                }
            }
            rec.dispatch("accumulate", &f, frame.pass_pixels.div_ceil(WORKGROUP_SIZE));
        })
    }

    /// The pipelines this scene's passes run: the variants with alpha testing and textures cost up to 4x in
    /// traversal, so only scenes that need them use them.
    fn stage_variants(&self) -> StageVariants {
        let texel = self.bvh_reads == BvhReads::Texel;
        let pick = |names: [&'static str; 2]| names[texel as usize];
        let (extend, connect) = if self.alpha_tested {
            (
                pick(["extend_alpha", "extend_alpha_texel"]),
                pick(["connect_alpha", "connect_alpha_texel"]),
            )
        } else {
            (pick(["extend", "extend_texel"]), pick(["connect", "connect_texel"]))
        };
        let shade = match self.textured {
            false => pick(["shade", "shade_texel"]),
            true => pick(["shade_textured", "shade_textured_texel"]),
        };
        let follow = match (self.alpha_tested, self.textured) {
            (true, _) => pick(["follow_alpha", "follow_alpha_texel"]),
            (false, true) => pick(["follow_textured", "follow_textured_texel"]),
            (false, false) => pick(["follow", "follow_texel"]),
        };
        StageVariants {
            extend,
            shade,
            connect,
            follow,
        }
    }

    /// Runs the device traversal on `rays` (closest or any hit): the BVH tests' window onto traverse.glsl.
    pub fn probe_trace(&mut self, rays: &[crate::bvh::Ray], any_hit: bool) -> Result<Vec<crate::bvh::TraceHit>, Error> {
        Ok(self.trace_timed(rays, any_hit, 1)?.0)
    }

    /// Traces `rays` `repeats` times after one upload; returns the hits and each dispatch's wall time. The bench's
    /// traversal figure: the same kernel the tests check, with nothing of the wavefront around it.
    pub fn trace_timed(
        &mut self,
        rays: &[crate::bvh::Ray],
        any_hit: bool,
        repeats: u32,
    ) -> Result<(Vec<crate::bvh::TraceHit>, Vec<Duration>), Error> {
        let n = rays.len() as u32;
        let mut words: Vec<u32> = Vec::with_capacity(rays.len() * 12);
        for r in rays {
            words.extend(
                [
                    r.origin.x, r.origin.y, r.origin.z, r.tmin, r.dir.x, r.dir.y, r.dir.z, r.tmax,
                ]
                .map(f32::to_bits),
            );
        }
        words.resize(rays.len() * 12, 0);
        let stage = match self.bvh_reads {
            BvhReads::Storage => "probe_trace",
            BvhReads::Texel => "probe_trace_texel",
        };
        let frame = Frame {
            path_count: n,
            bounce: any_hit as u32,
            ..Default::default()
        };
        let (out, times) = self.run_probe(stage, &words, frame, repeats)?;
        let hits = (0..rays.len())
            .map(|k| {
                let b = 8 * rays.len() + 4 * k;
                crate::bvh::TraceHit {
                    t: f32::from_bits(out[b]),
                    tri: out[b + 1],
                    uv: glam::Vec2::new(f32::from_bits(out[b + 2]), f32::from_bits(out[b + 3])),
                }
            })
            .collect();
        Ok((hits, times))
    }

    /// The light shade would pick for each of `n` samples (first bounce, sample index `sample`).
    pub fn probe_light_pick(&mut self, n: u32, sample: u32, seed: u32) -> Result<Vec<u32>, Error> {
        let words = vec![0u32; n as usize];
        let (mut out, _) = self.run_probe(
            "probe_light_pick",
            &words,
            Frame {
                path_count: n,
                sample_index: sample,
                seed,
                ..Default::default()
            },
            1,
        )?;
        out.truncate(n as usize);
        Ok(out)
    }

    /// The sampler's uniforms (as 24-bit integers) at `bounce` and dimension `dim` (see rand2 in rng.glsl) for
    /// every pixel of `pixels` and sample of `samples`, pixel-minor as paths are numbered.
    pub fn probe_rand(
        &mut self,
        pixels: std::ops::Range<u32>,
        samples: std::ops::Range<u32>,
        (bounce, dim): (u32, u32),
        seed: u32,
    ) -> Result<Vec<[u32; 2]>, Error> {
        let n = pixels.len() as u32 * samples.len() as u32;
        let words = vec![0u32; 2 * n as usize];
        let frame = Frame {
            path_count: n,
            pass_pixels: pixels.len() as u32,
            pixel_offset: pixels.start,
            sample_index: samples.start,
            bounce,
            max_depth: dim,
            seed,
            ..Default::default()
        };
        let (out, _) = self.run_probe("probe_rand", &words, frame, 1)?;
        Ok(out.chunks_exact(2).map(|c| [c[0], c[1]]).collect())
    }

    /// Runs the device BSDF on `queries`: sampling (x = three uniforms) or evaluation (x = wi).
    pub fn probe_bsdf(
        &mut self,
        queries: &[BsdfQuery],
        evaluate: bool,
        energy_compensation: bool,
    ) -> Result<Vec<BsdfProbe>, Error> {
        let n = queries.len();
        let mut words: Vec<u32> = Vec::with_capacity(24 * n);
        for q in queries {
            words.push(q.material);
            words.extend([q.wo.x, q.wo.y, q.wo.z, q.x.x, q.x.y, q.x.z].map(f32::to_bits));
            words.push(q.front as u32);
        }
        words.resize(24 * n, 0);
        let frame = Frame {
            path_count: n as u32,
            bounce: evaluate as u32,
            flags: if energy_compensation {
                FLAG_ENERGY_COMPENSATION
            } else {
                0
            },
            ..Default::default()
        };
        let (out, _) = self.run_probe("probe_bsdf", &words, frame, 1)?;
        let f = |i: usize| f32::from_bits(out[i]);
        let v = |i: usize| glam::Vec3::new(f(i), f(i + 1), f(i + 2));
        Ok((0..n)
            .map(|k| {
                let o = 8 * n + 16 * k;
                BsdfProbe {
                    wi: v(o),
                    weight: v(o + 3),
                    pdf: f(o + 6),
                    delta: out[o + 7] & 1 != 0,
                    ok: out[o + 7] & 2 != 0,
                    eval: v(o + 8),
                    pdf_wi: f(o + 11),
                    eval_reverse: v(o + 12),
                }
            })
            .collect())
    }

    /// Runs environment sampling on the device: `x` holds uniforms (sampling) or directions (`evaluate`).
    /// Returns (direction, pdf from sampling, pdf of the direction, radiance) per query.
    pub fn probe_env(
        &mut self,
        x: &[glam::Vec3],
        evaluate: bool,
    ) -> Result<Vec<(glam::Vec3, f32, f32, glam::Vec3)>, Error> {
        let n = x.len();
        let mut words: Vec<u32> = x.iter().flat_map(|v| [v.x, v.y, v.z, 0.0].map(f32::to_bits)).collect();
        words.resize(12 * n, 0);
        let (out, _) = self.run_probe(
            "probe_env",
            &words,
            Frame {
                path_count: n as u32,
                bounce: evaluate as u32,
                ..Default::default()
            },
            1,
        )?;
        let f = |i: usize| f32::from_bits(out[i]);
        Ok((0..n)
            .map(|k| {
                let o = 4 * n + 8 * k;
                (
                    glam::Vec3::new(f(o), f(o + 1), f(o + 2)),
                    f(o + 3),
                    f(o + 4),
                    glam::Vec3::new(f(o + 5), f(o + 6), f(o + 7)),
                )
            })
            .collect())
    }

    /// Runs `stage` `repeats` times over the probe buffer holding `words`; returns the buffer and each run's time.
    fn run_probe(
        &mut self,
        stage: &str,
        words: &[u32],
        frame: Frame,
        repeats: u32,
    ) -> Result<(Vec<u32>, Vec<Duration>), Error> {
        let storage = vk::BufferUsageFlags::STORAGE_BUFFER;
        let mut probe = Buffer::new(
            &self.ctx,
            "probe",
            words.len() as u64 * 4,
            storage,
            MemoryLocation::CpuToGpu,
        )?;
        probe.upload(&self.ctx, bytemuck::cast_slice(words))?;
        let times = self.run_kernel(stage, &[(BINDING_PROBE, &probe)], frame, repeats)?;
        Ok((probe.download(&self.ctx)?, times))
    }

    /// Runs one kernel `repeats` times over `frame.path_count` invocations with the scene bound, `extra` bindings,
    /// and stand-ins for the rest; fails on any validation error, else returns each submission's wall time.
    fn run_kernel(
        &mut self,
        stage: &str,
        extra: &[(u32, &Buffer)],
        frame: Frame,
        repeats: u32,
    ) -> Result<Vec<Duration>, Error> {
        let ctx = &self.ctx;
        let storage = vk::BufferUsageFlags::STORAGE_BUFFER;
        let bound: Vec<u32> = extra.iter().map(|(b, _)| *b).collect();
        let mut wanted = vec![
            BINDING_PATHS,
            BINDING_QUEUES,
            BINDING_COUNTERS,
            BINDING_FILM,
            BINDING_PROBE,
        ];
        if self.energy.is_none() {
            wanted.push(BINDING_ENERGY);
        }
        let stand_ins: Vec<(u32, Buffer)> = wanted
            .iter()
            .filter(|b| !bound.contains(b))
            .map(|&b| {
                Ok((
                    b,
                    Buffer::new(ctx, &format!("stand-in {b}"), 16, storage, MemoryLocation::GpuOnly)?,
                ))
            })
            .collect::<Result<_, Error>>()?;
        let mut all: Vec<(u32, &Buffer)> = extra.to_vec();
        all.extend(stand_ins.iter().map(|(b, buf)| (*b, buf)));
        self.bind_scene(&all);
        self.pipelines.bind_texel_views(ctx, &self.path_stand_in.0.views);
        let frame = Frame {
            light_count: self.light_count,
            env_prob: self.env_prob,
            env_rotation: self.env_rotation,
            env_width: self.env_size.0,
            env_height: self.env_size.1,
            ..frame
        };
        let n = frame.path_count;
        let p = &self.pipelines;
        let mut times = Vec::with_capacity(repeats as usize);
        for _ in 0..repeats.max(1) {
            let start = Instant::now();
            ctx.submit_and_wait(|cmd| {
                p.dispatch(cmd, stage, &frame, n.div_ceil(WORKGROUP_SIZE));
            })?;
            times.push(start.elapsed());
        }
        self.check_validation()?;
        Ok(times)
    }
}

#[cfg(test)]
mod tests {
    use super::{Schedule, ScheduleChoice};

    /// The trial runs each schedule twice, times the second run of each, and keeps the faster per path.
    #[test]
    fn the_schedule_trial_keeps_the_faster_per_path() {
        for (wave_ns, fused_ns, want) in [(2.0e6, 1.0e6, Schedule::Fused), (1.0e6, 2.0e6, Schedule::Wavefront)] {
            let mut c = ScheduleChoice::Trial {
                passes: 0,
                ns_per_path: [0.0; 2],
            };
            let mut ran = Vec::new();
            for pass in 0..6 {
                let s = c.current();
                ran.push(s);
                // The first pass of each schedule compiles: its time must not count.
                let ns = match (s, pass) {
                    (_, 0) | (_, 2) => 1e12,
                    (Schedule::Wavefront, _) => wave_ns,
                    (Schedule::Fused, _) => fused_ns,
                };
                c.record(ns, 1000);
            }
            assert_eq!(
                ran[..4],
                [
                    Schedule::Wavefront,
                    Schedule::Wavefront,
                    Schedule::Fused,
                    Schedule::Fused
                ]
            );
            assert_eq!(ran[4..], [want, want]);
        }
        let mut fixed = ScheduleChoice::Fixed(Schedule::Fused);
        fixed.record(1.0, 1);
        assert_eq!(fixed.current(), Schedule::Fused);
    }
}
