//! The renderer: a scene on one device and the passes that render it. `Renderer` is a thin facade; each job lives in
//! the module that owns it (see docs/ARCHITECTURE.md).
pub mod accel;
pub mod aovs;
mod energy;
pub mod film;
mod fingerprint;
pub mod gpu_scene;
mod integrator;
pub mod kernels;
mod probes;
pub mod schedule;
pub mod session;
pub mod settings;
mod sizing;
mod tonemap;

pub use aovs::Aovs;
pub use film::{Film, RenderStats};
pub use gpu_scene::BvhReads;
pub use probes::{BsdfProbe, BsdfQuery};
pub use schedule::Schedule;
pub use session::Session;
pub use settings::{
    Adaptive, Estimator, LightSampler, RenderSettings, RendererOptions, SpectralChoice, TextureFilter, Traversal,
    DEPTH_SAFETY_CAP,
};

use crate::constants::*;
use crate::error::Error;
use crate::layout::Frame;
use crate::scene::{Camera, Scene};
use crate::vk::{Buffer, Context, DeviceChoice, TexelViews, Validation};
use ash::vk;
use energy::EnergyTables;
use gpu_allocator::MemoryLocation;
use gpu_scene::GpuScene;
use integrator::Integrator;
use kernels::{Kernel, Kernels, SceneVariant};
use schedule::ScheduleChoice;

/// Renderer-owned 16-byte buffers bound wherever no session or probe binds a buffer, and a one-texel path-state view:
/// lavapipe reads every binding of a bound set, used or not, so a set must never keep a destroyed buffer or view.
struct StandIns {
    /// Dropped before the buffer it views, which is held only for it.
    path_view: TexelViews,
    _path: Buffer,
    buffers: Vec<(u32, Buffer)>,
}

impl StandIns {
    /// The bindings a session, a probe or the tone map fills in.
    const BINDINGS: [u32; 9] = [
        BINDING_PATHS,
        BINDING_QUEUES,
        BINDING_COUNTERS,
        BINDING_FILM,
        BINDING_PROBE,
        BINDING_TONEMAP_OUT,
        BINDING_AOVS,
        BINDING_BUDGET,
        BINDING_DEBUG_AOVS,
    ];

    fn new(ctx: &Context) -> Result<Self, Error> {
        let storage = vk::BufferUsageFlags::STORAGE_BUFFER;
        let path = Buffer::new(
            ctx,
            "path state stand-in",
            16,
            storage | vk::BufferUsageFlags::UNIFORM_TEXEL_BUFFER,
            MemoryLocation::GpuOnly,
        )?;
        let path_view = TexelViews::new(ctx, &[(BINDING_PATH_TEXELS, &path, vk::Format::R32G32B32A32_SFLOAT)])?;
        let buffers = Self::BINDINGS
            .iter()
            .map(|&b| {
                let name = format!("stand-in {b}");
                Ok((b, Buffer::new(ctx, &name, 16, storage, MemoryLocation::GpuOnly)?))
            })
            .collect::<Result<_, Error>>()?;
        Ok(StandIns {
            path_view,
            _path: path,
            buffers,
        })
    }
}

/// A scene uploaded to one device, ready to render any number of images.
pub struct Renderer {
    // Field order is drop order: everything device-owned goes before the context.
    integrator: Integrator,
    kernels: Kernels,
    scene: GpuScene,
    stand_ins: StandIns,
    energy: EnergyTables,
    /// How traversal reads the BVH; Texel needs the scene's texel views.
    bvh_reads: BvhReads,
    options: RendererOptions,
    env_size: (u32, u32),
    env_rotation: f32,
    /// The camera's distance to the scene's centre along its view direction: the focus when none is given.
    default_focus: f32,
    camera: Camera,
    /// The scene's own camera at the shutter's opening: while renders use it, a moving one follows its keys.
    scene_camera: Option<Camera>,
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
        Self::with_validation(scene, device, Validation::from_env()?)
    }

    pub fn with_validation(scene: &Scene, device: &DeviceChoice, validation: Validation) -> Result<Self, Error> {
        Self::with_context(scene, Context::new(device, validation)?)
    }

    /// A renderer on a context made by the caller (e.g. one that can present to a window), with the options the
    /// environment gives (RendererOptions::from_env).
    pub fn with_context(scene: &Scene, ctx: Context) -> Result<Self, Error> {
        Self::with_options(scene, ctx, RendererOptions::from_env()?)
    }

    pub fn with_options(scene: &Scene, ctx: Context, options: RendererOptions) -> Result<Self, Error> {
        let uploaded = Uploaded::new(&ctx, scene, &options)?;
        let schedule = match options.schedule {
            Some(s) => ScheduleChoice::Fixed(s),
            // On GPUs the wavefront's compacted, coherent stages are the design; a CPU device is measured.
            None if ctx.properties.device_type == vk::PhysicalDeviceType::CPU => ScheduleChoice::trial(),
            None => ScheduleChoice::Fixed(Schedule::Wavefront),
        };
        let kernels = Kernels::new(&ctx, crate::shaders::BUILTIN_SPIRV, uploaded.gpu.features)?;
        let stand_ins = StandIns::new(&ctx)?;
        let env = scene.environment.as_ref();
        let mut r = Renderer {
            integrator: Integrator::new(&ctx, schedule)?,
            kernels,
            scene: uploaded.gpu,
            stand_ins,
            energy: EnergyTables::upload(&ctx)?,
            bvh_reads: uploaded.bvh_reads,
            options,
            env_size: env.map(|e| (e.width, e.height)).unwrap_or((0, 0)),
            env_rotation: env.map(|e| e.rotation).unwrap_or(0.0),
            default_focus: uploaded.default_focus,
            camera: uploaded.camera,
            scene_camera: scene.camera,
            warnings: uploaded.warnings,
            ctx,
        };
        r.bind_scene_views();
        r.build_grids(
            kernels::Stage::EnergyTables,
            ENERGY_RES * ENERGY_RES,
            energy::grid_averages,
        )?;
        r.ensure_layer_tables(scene)?;
        Ok(r)
    }

    /// Replaces the scene, e.g. with the next frame's pose of it: packs and uploads it, keeping the device, the
    /// energy tables, the schedule and every pipeline the new scene's features do not change. The camera becomes
    /// the new scene's. Warnings the new scene brings are added to `warnings`.
    pub fn set_scene(&mut self, scene: &Scene) -> Result<(), Error> {
        // Uploaded before the old scene goes, so that a scene refused leaves the renderer as it was. No pass is in
        // flight between calls, and every pass binds the scene's buffers again.
        let uploaded = Uploaded::new(&self.ctx, scene, &self.options)?;
        self.ensure_layer_tables(scene)?;
        self.scene = uploaded.gpu;
        self.bvh_reads = uploaded.bvh_reads;
        let env = scene.environment.as_ref();
        self.env_size = env.map(|e| (e.width, e.height)).unwrap_or((0, 0));
        self.env_rotation = env.map(|e| e.rotation).unwrap_or(0.0);
        self.default_focus = uploaded.default_focus;
        self.camera = uploaded.camera;
        self.scene_camera = scene.camera;
        for w in uploaded.warnings {
            if !self.warnings.contains(&w) {
                self.warnings.push(w);
            }
        }
        self.bind_scene_views();
        Ok(())
    }

    /// Whether scenes uploaded from now on (`set_scene`) keep their fingerprint for film files.
    pub fn set_fingerprint(&mut self, on: bool) {
        self.options.fingerprint = on;
    }

    /// The scene's texel views where it has them, the path-state stand-in's otherwise, and the CIE rows'.
    fn bind_scene_views(&self) {
        self.kernels
            .pipelines
            .bind_texel_views(&self.ctx, self.energy.texel_views());
        if let Some(views) = self.scene.texel_views() {
            self.kernels.pipelines.bind_texel_views(&self.ctx, views);
        }
        if let Some(accel) = &self.scene.accel {
            self.kernels.pipelines.bind_tlas(&self.ctx, accel.tlas);
        }
        self.kernels
            .pipelines
            .bind_texel_views(&self.ctx, &self.stand_ins.path_view.views);
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
        let mut names = stages.map(<[String]>::to_vec).unwrap_or_else(|| dir.stages());
        let mut kernels = Vec::with_capacity(names.len());
        for name in &names {
            kernels.push(
                Kernel::from_name(name)
                    .ok_or_else(|| Error::Shader(format!("{name}: no built-in stage or variant has this name")))?,
            );
        }
        // Ray-query variants can neither be built nor run on a device without ray queries.
        let usable = |k: &Kernel| self.ctx.accel.is_some() || !k.needs_ray_query();
        names.retain(|n| Kernel::from_name(n).is_some_and(|k| usable(&k)));
        kernels.retain(usable);
        let mut compiled = Vec::with_capacity(names.len());
        for (name, kernel) in names.iter().zip(kernels) {
            compiled.push((kernel, dir.compile(name)?));
        }
        for (kernel, spv) in &compiled {
            self.kernels.replace(&self.ctx, *kernel, spv)?;
        }
        if compiled.iter().any(|(k, _)| k.stage.wavefront_only()) {
            self.integrator.fix(Schedule::Wavefront);
        } else if compiled.iter().any(|(k, _)| k.stage == kernels::Stage::Follow) {
            self.integrator.fix(Schedule::Fused);
        }
        Ok(names)
    }

    /// How long building the scene's BVH took.
    pub fn bvh_build_time(&self) -> std::time::Duration {
        self.scene.bvh_build
    }

    /// Device bytes of what traversal and shading read: BVH nodes, vertices, shading normals and instance records.
    pub fn traversal_bytes(&self) -> u64 {
        self.scene.traversal_bytes()
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

    /// Binds the scene, the energy tables, `extra` buffers and `views`, and stand-ins for every other binding.
    fn bind(&self, extra: &[(u32, &Buffer)], views: &[(u32, vk::BufferView)]) {
        let mut all: Vec<(u32, &Buffer)> = self.scene.bindings().collect();
        all.push(self.energy.binding());
        all.extend_from_slice(extra);
        let missing: Vec<(u32, &Buffer)> = self
            .stand_ins
            .buffers
            .iter()
            .filter(|(b, _)| !all.iter().any(|(bound, _)| bound == b))
            .map(|(b, buffer)| (*b, buffer))
            .collect();
        all.extend(missing);
        self.kernels.pipelines.bind_buffers(&self.ctx, &all);
        let views = if views.is_empty() {
            &self.stand_ins.path_view.views[..]
        } else {
            views
        };
        self.kernels.pipelines.bind_texel_views(&self.ctx, views);
    }

    /// `frame` with the scene's light table and environment, and the light selection its flags ask for: the light
    /// BVH only where the scene has LIGHT_TREE_MIN_EMITTERS emitters for it or more.
    fn lit(&self, frame: Frame) -> Frame {
        let mut flags = frame.flags;
        let tree = &self.scene.light_tree;
        if ((tree.emitters + tree.instanced) as u32) < LIGHT_TREE_MIN_EMITTERS {
            flags &= !FLAG_LIGHT_TREE;
        }
        let env_prob = if flags & FLAG_LIGHT_TREE != 0 {
            self.scene.env_prob_tree
        } else if flags & FLAG_LIGHT_UNIFORM != 0 && self.scene.env_prob > 0.0 {
            1.0 / self.scene.light_count as f32
        } else {
            self.scene.env_prob
        };
        Frame {
            flags,
            light_count: self.scene.light_count,
            env_prob,
            env_rotation: self.env_rotation,
            env_width: self.env_size.0,
            env_height: self.env_size.1,
            ..frame
        }
    }

    /// Which variants of the tracing and shading stages this scene's passes run.
    fn scene_variant(&self) -> SceneVariant {
        SceneVariant {
            alpha: self.scene.alpha_tested,
            textured: self.scene.textured,
            texel: self.bvh_reads == BvhReads::Texel,
            ray_query: self.scene.accel.is_some(),
        }
    }

    /// Whether rays are traced with the device's ray queries (else the compute BVH).
    pub fn traversal(&self) -> Traversal {
        match self.scene.accel {
            Some(_) => Traversal::RayQuery,
            None => Traversal::Compute,
        }
    }

    /// The ray-query structures, when rays are traced with them: compacted bytes, bytes before compaction, and the
    /// build's time.
    pub fn acceleration_structures(&self) -> Option<(u64, u64, std::time::Duration)> {
        (self.scene.accel.as_ref()).map(|a| (a.bytes, a.uncompacted_bytes, a.build_time))
    }

    /// The distance along the view direction to the first surface under image position (x, y) in [0, 1]^2 (0, 0 at
    /// the top left), for click-to-focus; None when the ray escapes.
    pub fn focus_distance_at(&mut self, x: f32, y: f32, aspect: f32) -> Result<Option<f32>, Error> {
        let (_, _, forward) = self.camera.basis();
        let (origin, dir) = self.camera.ray(x, y, aspect);
        let ray = crate::bvh::Ray {
            origin,
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
        if reads == BvhReads::Texel && self.scene.texel_views().is_none() {
            return Err(Error::Settings(
                "this device cannot read the scene's BVH through texel buffers".into(),
            ));
        }
        if reads == BvhReads::Storage && !self.scene.storage_ok {
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
        self.integrator.schedule()
    }

    /// Sample rows the next follow dispatch takes (see FOLLOW_SAMPLES).
    pub fn follow_rows(&self) -> u32 {
        self.integrator.follow_rows()
    }

    /// Fixes how passes run; both schedules work on every device and give the same bytes.
    pub fn set_schedule(&mut self, schedule: Schedule) {
        self.integrator.fix(schedule);
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
}

/// A scene packed and on the device, with what the renderer takes from it.
struct Uploaded {
    gpu: GpuScene,
    bvh_reads: BvhReads,
    camera: Camera,
    default_focus: f32,
    warnings: Vec<String>,
}

impl Uploaded {
    fn new(ctx: &Context, scene: &Scene, options: &RendererOptions) -> Result<Self, Error> {
        if let Some(env) = &scene.environment {
            env.check()
                .map_err(|why| Error::Settings(format!("the environment: {why}")))?;
        }
        let packed = gpu_scene::try_pack_with(scene, options.instancing)?;
        let mut warnings = scene.warnings.clone();
        if packed.lights.is_empty() {
            warnings.push(
                "the scene has no emissive surface and no environment, so nothing lights it and the image is black"
                    .into(),
            );
        }
        // Traversal packs node and triangle indices with a leaf's count into one word (STACK_COUNT_BITS).
        if packed.bvh.nodes.len().max(packed.tri_verts.len()) as u64 >= MAX_SCENE_ITEMS as u64 {
            return Err(Error::Limit(format!(
                "the scene has {} triangles in {} BVH nodes; traversal handles fewer than {MAX_SCENE_ITEMS} of each",
                packed.tri_verts.len(),
                packed.bvh.nodes.len()
            )));
        }
        let device_budget = options.max_device_memory.unwrap_or_else(|| ctx.device_local_heap());
        let mut gpu = GpuScene::upload(ctx, &packed, device_budget)?;
        gpu.fingerprint = options.fingerprint.then(|| packed.fingerprint());
        let bvh_reads = options.bvh_reads(gpu.texel_views().is_some(), gpu.storage_ok)?;
        gpu.accel = ray_query_structures(ctx, &packed, options.traversal, &gpu, device_budget, &mut warnings)?;
        // From the packed bounds: the scene's own walk would place every instance again.
        let camera = scene.camera.unwrap_or_else(|| scene.default_camera(packed.bounds));
        Ok(Uploaded {
            gpu,
            bvh_reads,
            camera,
            default_focus: default_focus(packed.bounds, &camera),
            warnings,
        })
    }
}

/// The acceleration structures for ray-query traversal when `traversal` asks for it and the device and scene allow
/// it; otherwise None (the compute BVH), with a warning when ray queries were asked for by name.
fn ray_query_structures(
    ctx: &Context,
    packed: &gpu_scene::PackedScene,
    traversal: Traversal,
    gpu: &GpuScene,
    device_budget: u64,
    warnings: &mut Vec<String>,
) -> Result<Option<accel::AccelStructures>, Error> {
    let gpu_device = matches!(
        ctx.properties.device_type,
        vk::PhysicalDeviceType::DISCRETE_GPU | vk::PhysicalDeviceType::INTEGRATED_GPU
    );
    let wanted = match traversal {
        Traversal::Compute => false,
        Traversal::RayQuery => true,
        // On lavapipe the compute BVH is the faster (docs/guide/traversal.md).
        Traversal::Auto => gpu_device && ctx.accel.is_some(),
    };
    if !wanted {
        return Ok(None);
    }
    let why = accel::unsupported(ctx, packed).or_else(|| {
        (!gpu.storage_ok)
            .then(|| "the scene outgrows this device's storage-buffer range, which ray queries' stages read".into())
    });
    if let Some(why) = why {
        if traversal == Traversal::RayQuery {
            warnings.push(format!(
                "ray queries asked for, but {why}: tracing with the compute BVH"
            ));
        }
        return Ok(None);
    }
    let left = device_budget.saturating_sub(gpu.bytes());
    accel::AccelStructures::build(ctx, packed, left).map(Some)
}

/// The camera's distance to the scene's centre along its view direction, at least 1 mm.
fn default_focus(bounds: Option<(glam::Vec3, glam::Vec3)>, cam: &Camera) -> f32 {
    let (lo, hi) = bounds.unwrap_or((glam::Vec3::ZERO, glam::Vec3::ZERO));
    ((lo + hi) * 0.5 - cam.origin()).dot(cam.basis().2).max(1e-3)
}

#[cfg(test)]
mod tests {
    use super::StandIns;
    use crate::constants::*;

    /// Every binding of the one descriptor set has exactly one filler: the scene (SCENE_BINDINGS), the energy tables,
    /// or a session, probe or tone map (with a stand-in when none is bound), the path state's texel view and the CIE
    /// rows' (the energy tables'). A binding
    /// nobody fills would keep a destroyed buffer on lavapipe, which reads every binding of a bound set; one filled
    /// twice would be bound to whichever comes last.
    #[test]
    fn every_binding_has_exactly_one_filler() {
        let (scene_storage, scene_texel) = super::gpu_scene::filled_bindings();
        let mut storage: Vec<u32> = scene_storage;
        storage.push(BINDING_ENERGY);
        storage.extend(StandIns::BINDINGS);
        storage.sort_unstable();
        assert_eq!(storage, (0..BINDING_FIRST_TEXEL).collect::<Vec<_>>());
        let mut texel = scene_texel;
        texel.push(BINDING_PATH_TEXELS);
        texel.push(BINDING_CIE_TEXELS);
        texel.sort_unstable();
        assert_eq!(texel, (BINDING_FIRST_TEXEL..BINDING_COUNT).collect::<Vec<_>>());
    }
}
