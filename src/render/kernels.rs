//! The compute kernels: the `Stage` enum, each stage's compiled variants (`Kernel`), and the pipelines built for
//! them on demand, handed out as typed handles so a pass can only dispatch what it built.
use crate::constants::{FEATURES_ALL, FEATURE_DEEP_STACK, FEATURE_INSTANCES, FEATURE_MOTION, FEATURE_SPECTRAL};
use crate::error::Error;
use crate::layout::Frame;
use crate::variants::STAGE_VARIANTS;
use crate::vk::{Context, Pipelines};
use ash::vk;
use std::collections::HashMap;

/// Every compute stage, one per `shaders/{name}.comp`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Stage {
    Generate,
    QueueArgs,
    Extend,
    Shade,
    Connect,
    Accumulate,
    Follow,
    Survey,
    Plan,
    Tonemap,
    EnergyTables,
    SheenTable,
    AnisoTable,
    ProbeTrace,
    ProbeBsdf,
    ProbeEnv,
    ProbePhase,
    ProbeRand,
    ProbeLightPick,
    ProbeLightSelect,
    ProbeConstants,
}

impl Stage {
    pub const ALL: [Stage; 21] = [
        Stage::Generate,
        Stage::QueueArgs,
        Stage::Extend,
        Stage::Shade,
        Stage::Connect,
        Stage::Accumulate,
        Stage::Follow,
        Stage::Survey,
        Stage::Plan,
        Stage::Tonemap,
        Stage::EnergyTables,
        Stage::SheenTable,
        Stage::AnisoTable,
        Stage::ProbeTrace,
        Stage::ProbeBsdf,
        Stage::ProbeEnv,
        Stage::ProbePhase,
        Stage::ProbeRand,
        Stage::ProbeLightPick,
        Stage::ProbeLightSelect,
        Stage::ProbeConstants,
    ];

    /// The shader's file stem, and the label its GPU time is reported under.
    pub fn name(self) -> &'static str {
        match self {
            Stage::Generate => "generate",
            Stage::QueueArgs => "queue_args",
            Stage::Extend => "extend",
            Stage::Shade => "shade",
            Stage::Connect => "connect",
            Stage::Accumulate => "accumulate",
            Stage::Follow => "follow",
            Stage::Survey => "survey",
            Stage::Plan => "plan",
            Stage::Tonemap => "tonemap",
            Stage::EnergyTables => "energy_tables",
            Stage::SheenTable => "sheen_table",
            Stage::AnisoTable => "aniso_table",
            Stage::ProbeTrace => "probe_trace",
            Stage::ProbeBsdf => "probe_bsdf",
            Stage::ProbeEnv => "probe_env",
            Stage::ProbePhase => "probe_phase",
            Stage::ProbeRand => "probe_rand",
            Stage::ProbeLightPick => "probe_light_pick",
            Stage::ProbeLightSelect => "probe_light_select",
            Stage::ProbeConstants => "probe_constants",
        }
    }

    pub fn from_name(name: &str) -> Option<Stage> {
        Stage::ALL.into_iter().find(|s| s.name() == name)
    }

    /// Stages only the wavefront schedule runs: an edited one fixes that schedule, so the edit is what runs.
    pub fn wavefront_only(self) -> bool {
        matches!(
            self,
            Stage::Generate | Stage::QueueArgs | Stage::Extend | Stage::Shade | Stage::Connect
        )
    }

    /// Stages a pass dispatches: specialised for the scene's features and built when a pass first needs them
    /// (building every render variant up front cost start-up about a second on lavapipe).
    fn renders(self) -> bool {
        matches!(
            self,
            Stage::Generate
                | Stage::QueueArgs
                | Stage::Extend
                | Stage::Shade
                | Stage::Connect
                | Stage::Accumulate
                | Stage::Follow
                | Stage::Survey
                | Stage::Plan
        )
    }

    /// Stages built only when first run: the probes (tests and tools ask for them; probe_bsdf, with every lobe live,
    /// alone cost every renderer 1.2 s of start-up on lavapipe) and the tables a scene with a sheen or a stretched lobe
    /// asks for. The others that do not render are built with the renderer.
    fn on_demand(self) -> bool {
        matches!(
            self,
            Stage::ProbeTrace
                | Stage::ProbeBsdf
                | Stage::ProbeEnv
                | Stage::ProbePhase
                | Stage::ProbeRand
                | Stage::ProbeLightPick
                | Stage::ProbeLightSelect
                | Stage::ProbeConstants
                | Stage::SheenTable
                | Stage::AnisoTable
        )
    }

    /// Stages that keep every feature whatever the scene, but the BVH's own FEATURE_DEEP_STACK (so probe_trace
    /// traverses as the render stages do): probes test device functions with parameters of their own, and the
    /// energy tables integrate the full BSDF.
    fn scene_independent(self) -> bool {
        !self.renders() && self != Stage::Tonemap
    }
}

/// The feature bits scene-independent stages take from the scene rather than all set: the BVH's stack depth (so the
/// BVH tests check the traversal the render stages run), motion and instances (whose buffers only scenes with them
/// fill).
const SCENE_OWNED: u32 = FEATURE_DEEP_STACK | FEATURE_MOTION | FEATURE_INSTANCES;

/// The preprocessor defines a variant is compiled with (src/variants.rs), as bits.
const ALPHA_TEST: u8 = 1;
const TEXTURED: u8 = 2;
const TEXEL_READS: u8 = 4;
const RAY_QUERY: u8 = 8;

fn define_bits(defines: &str) -> u8 {
    defines
        .split_whitespace()
        .map(|d| match d {
            "ALPHA_TEST" => ALPHA_TEST,
            "TEXTURED" => TEXTURED,
            "TEXEL_READS" => TEXEL_READS,
            "RAY_QUERY" => RAY_QUERY,
            other => panic!("src/variants.rs names an unknown define {other}"),
        })
        .fold(0, |a, b| a | b)
}

/// What the scene asks of the stages that trace and shade.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SceneVariant {
    /// Some material is alpha-tested: traversal evaluates alpha at candidate hits.
    pub alpha: bool,
    /// Some material has a texture or alpha, or some mesh has COLOR_0.
    pub textured: bool,
    /// Traversal and shading read the scene through texel views (BvhReads::Texel).
    pub texel: bool,
    /// Traversal walks the device's acceleration structures (Traversal::RayQuery); its variants read storage
    /// buffers only, so `texel` is not asked of them.
    pub ray_query: bool,
}

/// One compiled variant of a stage: the stage as written (`variant` 0) or `{stage}_{suffix}` of STAGE_VARIANTS
/// entry `variant - 1`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Kernel {
    pub stage: Stage,
    variant: u8,
}

impl Kernel {
    /// The stage as written, with no variant define.
    pub fn of(stage: Stage) -> Kernel {
        Kernel { stage, variant: 0 }
    }

    /// The variant of `stage` a scene runs: the one compiled with exactly the defines the scene needs among those
    /// the stage has variants for (the variants with alpha testing and textures cost up to 4x in traversal, so only
    /// scenes that need them use them).
    pub fn for_scene(stage: Stage, scene: SceneVariant) -> Kernel {
        let variants = || STAGE_VARIANTS.iter().enumerate().filter(|(_, v)| v.0 == stage.name());
        let known = variants().fold(0, |a, (_, v)| a | define_bits(v.2));
        // Alpha testing implies textured shading (follow_alpha is ALPHA_TEST TEXTURED); defines the stage has no
        // variant for are not its business (extend never shades).
        let alpha = if scene.alpha { ALPHA_TEST | TEXTURED } else { 0 };
        let textured = if scene.textured { TEXTURED } else { 0 };
        let texel = if scene.texel && !scene.ray_query {
            TEXEL_READS
        } else {
            0
        };
        let ray_query = if scene.ray_query { RAY_QUERY } else { 0 };
        let wanted = (alpha | textured | texel | ray_query) & known;
        match variants().find(|(_, v)| define_bits(v.2) == wanted) {
            Some((i, _)) => Kernel {
                stage,
                variant: i as u8 + 1,
            },
            None => Kernel::of(stage),
        }
    }

    /// Compiled with ray queries: only a device that has them can build it.
    pub fn needs_ray_query(self) -> bool {
        self.variant > 0 && define_bits(STAGE_VARIANTS[self.variant as usize - 1].2) & RAY_QUERY != 0
    }

    /// The name build.rs and shader folders give its SPIR-V: "extend_alpha_texel".
    pub fn name(self) -> String {
        match self.variant {
            0 => self.stage.name().to_string(),
            v => format!("{}_{}", self.stage.name(), STAGE_VARIANTS[v as usize - 1].1),
        }
    }

    /// The kernel a SPIR-V name stands for, if any.
    pub fn from_name(name: &str) -> Option<Kernel> {
        if let Some(stage) = Stage::from_name(name) {
            return Some(Kernel::of(stage));
        }
        let (i, (stage, _, _)) = STAGE_VARIANTS.iter().enumerate().find(|(_, (stage, suffix, _))| {
            name.strip_prefix(stage).and_then(|r| r.strip_prefix('_')) == Some(suffix)
        })?;
        Some(Kernel {
            stage: Stage::from_name(stage)?,
            variant: i as u8 + 1,
        })
    }
}

/// A built pipeline of a kernel: only `Kernels::get` makes one, so a pass records only what it built.
#[derive(Clone, Copy, Debug)]
pub struct Built {
    pub stage: Stage,
    pipeline: vk::Pipeline,
}

/// The kernels a wavefront pass dispatches, named by stage.
pub struct WavefrontKernels {
    pub generate: Built,
    pub queue_args: Built,
    pub extend: Built,
    pub shade: Built,
    pub connect: Built,
    pub accumulate: Built,
}

/// The kernels a fused pass dispatches.
pub struct FusedKernels {
    pub follow: Built,
    pub accumulate: Built,
}

/// Every kernel's SPIR-V and the pipelines built from it so far, on the one shared descriptor set.
pub struct Kernels {
    pub pipelines: Pipelines,
    /// Pipelines by kernel and the FEATURE_* bits a render stage was specialised for (0 for the other stages, which
    /// keep the bits they were built with).
    built: HashMap<(Kernel, u32), vk::Pipeline>,
    spirv: HashMap<Kernel, Vec<u8>>,
    /// FEATURE_* bits the render stages are specialised for (SCENE_FEATURES in layout.glsl).
    features: u32,
    /// The feature sets whose render pipelines are kept, the latest last: a render that turns adaptive sampling, an
    /// exact film or a lens on and off (the bench, the viewer) finds its pipelines built, where rebuilding cost
    /// about 1.3 s on lavapipe every switch.
    kept: Vec<u32>,
}

/// Render-stage feature sets kept built at once (each about 7 pipelines).
const KEPT_FEATURE_SETS: usize = 4;

impl Kernels {
    /// Builds the energy tables' and the tone map's stages now; the render stages when a pass first needs them,
    /// specialised for `features`, and the probes and layer tables when first run (`Stage::on_demand`).
    pub fn new(ctx: &Context, spirv: &[(&str, &[u8])], features: u32) -> Result<Self, Error> {
        let mut me = Kernels {
            pipelines: Pipelines::new(ctx, std::mem::size_of::<Frame>() as u32)?,
            built: HashMap::new(),
            spirv: HashMap::new(),
            features,
            kept: vec![features],
        };
        for (name, spv) in spirv {
            let kernel = Kernel::from_name(name)
                .ok_or_else(|| Error::Vulkan(format!("built-in shader {name} is no known stage or variant")))?;
            me.spirv.insert(kernel, spv.to_vec());
            if !kernel.stage.renders() && !kernel.stage.on_demand() {
                me.build(ctx, kernel)?;
            }
        }
        Ok(me)
    }

    /// Specialises the render stages for `features` from now on. The pipelines of the last few feature sets stay
    /// built; older ones are dropped.
    pub fn set_features(&mut self, features: u32) {
        if features == self.features {
            return;
        }
        self.features = features;
        self.kept.retain(|&f| f != features);
        self.kept.push(features);
        if self.kept.len() > KEPT_FEATURE_SETS {
            let old = self.kept.remove(0);
            let stale: Vec<(Kernel, u32)> = self
                .built
                .keys()
                .copied()
                .filter(|&(k, f)| k.stage.renders() && f == old)
                .collect();
            for key in stale {
                if let Some(p) = self.built.remove(&key) {
                    self.pipelines.destroy(p);
                }
            }
        }
    }

    /// The key a kernel's pipeline is kept under for the current features.
    fn key(&self, kernel: Kernel) -> (Kernel, u32) {
        (kernel, if kernel.stage.renders() { self.features } else { 0 })
    }

    /// The kernel's pipeline, built first if it is not yet.
    pub fn get(&mut self, ctx: &Context, kernel: Kernel) -> Result<Built, Error> {
        let pipeline = match self.built.get(&self.key(kernel)) {
            Some(&p) => p,
            None => self.build(ctx, kernel)?,
        };
        Ok(Built {
            stage: kernel.stage,
            pipeline,
        })
    }

    /// BLAKE3 of the SPIR-V of every render stage and variant, as this renderer would build them (built-in or
    /// loaded from a shader folder): part of what a film file names its render by.
    pub fn render_fingerprint(&self) -> String {
        let mut kernels: Vec<(String, &Vec<u8>)> = (self.spirv.iter())
            .filter(|(k, _)| k.stage.renders())
            .map(|(k, spv)| (k.name(), spv))
            .collect();
        kernels.sort();
        let mut hasher = blake3::Hasher::new();
        for (name, spv) in kernels {
            hasher.update(name.as_bytes());
            hasher.update(&(spv.len() as u64).to_le_bytes());
            hasher.update(spv);
        }
        hasher.finalize().to_hex().to_string()
    }

    /// The kernel's pipeline if it is built.
    pub fn built(&self, kernel: Kernel) -> Option<Built> {
        self.built.get(&self.key(kernel)).map(|&pipeline| Built {
            stage: kernel.stage,
            pipeline,
        })
    }

    /// The kernels a wavefront pass runs for this scene.
    pub fn wavefront(&mut self, ctx: &Context, scene: SceneVariant) -> Result<WavefrontKernels, Error> {
        let mut get = |stage| self.get(ctx, Kernel::for_scene(stage, scene));
        Ok(WavefrontKernels {
            generate: get(Stage::Generate)?,
            queue_args: get(Stage::QueueArgs)?,
            extend: get(Stage::Extend)?,
            shade: get(Stage::Shade)?,
            connect: get(Stage::Connect)?,
            accumulate: get(Stage::Accumulate)?,
        })
    }

    /// The kernels a fused pass runs for this scene.
    pub fn fused(&mut self, ctx: &Context, scene: SceneVariant) -> Result<FusedKernels, Error> {
        Ok(FusedKernels {
            follow: self.get(ctx, Kernel::for_scene(Stage::Follow, scene))?,
            accumulate: self.get(ctx, Kernel::of(Stage::Accumulate))?,
        })
    }

    /// The AOV stage for this scene.
    pub fn survey(&mut self, ctx: &Context, scene: SceneVariant) -> Result<Built, Error> {
        self.get(ctx, Kernel::for_scene(Stage::Survey, scene))
    }

    /// Adaptive sampling's planning stage.
    pub fn plan(&mut self, ctx: &Context) -> Result<Built, Error> {
        self.get(ctx, Kernel::of(Stage::Plan))
    }

    /// Replaces a kernel's SPIR-V (a user's shader) and builds it now, so a bad one fails here. Its pipelines for
    /// other feature sets are dropped, to be built from the new SPIR-V when used.
    pub fn replace(&mut self, ctx: &Context, kernel: Kernel, spv: &[u8]) -> Result<(), Error> {
        self.spirv.insert(kernel, spv.to_vec());
        let current = self.key(kernel);
        let stale: Vec<(Kernel, u32)> = self
            .built
            .keys()
            .copied()
            .filter(|&(k, f)| k == kernel && (k, f) != current)
            .collect();
        for key in stale {
            if let Some(p) = self.built.remove(&key) {
                self.pipelines.destroy(p);
            }
        }
        self.build(ctx, kernel).map(|_| ())
    }

    fn build(&mut self, ctx: &Context, kernel: Kernel) -> Result<vk::Pipeline, Error> {
        let spv = self
            .spirv
            .get(&kernel)
            .ok_or_else(|| Error::Vulkan(format!("no SPIR-V for kernel {}", kernel.name())))?;
        let features = if kernel.stage.scene_independent() {
            (FEATURES_ALL & !SCENE_OWNED & !FEATURE_SPECTRAL) | (self.features & SCENE_OWNED)
        } else if kernel.stage == Stage::Survey {
            // The AOVs are RGB whatever the beauty is: an albedo is a colour, not a spectrum at four wavelengths.
            self.features & !FEATURE_SPECTRAL
        } else {
            self.features
        };
        let pipeline = self.pipelines.create(ctx, &kernel.name(), spv, features)?;
        if let Some(old) = self.built.insert(self.key(kernel), pipeline) {
            self.pipelines.destroy(old);
        }
        Ok(pipeline)
    }

    /// `groups` workgroups of a built kernel with `frame` as push constants.
    pub fn dispatch(&self, cmd: vk::CommandBuffer, k: Built, frame: &Frame, groups: u32) {
        self.pipelines
            .dispatch(cmd, k.pipeline, bytemuck::bytes_of(frame), [groups, 1, 1]);
    }

    /// A dispatch sized by the indirect command at `offset` in `args`.
    pub fn dispatch_indirect(
        &self,
        cmd: vk::CommandBuffer,
        k: Built,
        frame: &Frame,
        args: &crate::vk::Buffer,
        offset: u64,
    ) {
        self.pipelines
            .dispatch_indirect(cmd, k.pipeline, bytemuck::bytes_of(frame), args, offset);
    }

    /// A 2D dispatch with a stage's own push block (within the shared range), e.g. the tone map.
    pub fn dispatch_2d(&self, cmd: vk::CommandBuffer, k: Built, push: &[u8], groups: [u32; 2]) {
        self.pipelines
            .dispatch(cmd, k.pipeline, push, [groups[0], groups[1], 1]);
    }
}

impl Drop for Kernels {
    fn drop(&mut self) {
        if crate::vk::device_lost() {
            return;
        }
        for (_, p) in self.built.drain() {
            self.pipelines.destroy(p);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every built-in SPIR-V is a known kernel, and names round-trip.
    #[test]
    fn every_builtin_stage_is_a_kernel() {
        for (name, _) in crate::shaders::BUILTIN_SPIRV {
            let k = Kernel::from_name(name).unwrap_or_else(|| panic!("{name} is no kernel"));
            assert_eq!(k.name(), *name);
        }
        for s in Stage::ALL {
            assert!(
                crate::shaders::BUILTIN_SPIRV.iter().any(|(n, _)| *n == s.name()),
                "{s:?} has no shader"
            );
        }
    }

    /// The variant choice the renderer made by hand before it was derived from src/variants.rs.
    #[test]
    fn scenes_pick_the_variants_they_need() {
        let pick = |stage, alpha, textured, texel| {
            Kernel::for_scene(
                stage,
                SceneVariant {
                    alpha,
                    textured: textured || alpha,
                    texel,
                    ray_query: false,
                },
            )
            .name()
        };
        for texel in [false, true] {
            let t = if texel { "_texel" } else { "" };
            assert_eq!(pick(Stage::Extend, false, false, texel), format!("extend{t}"));
            assert_eq!(pick(Stage::Extend, false, true, texel), format!("extend{t}"));
            assert_eq!(pick(Stage::Extend, true, true, texel), format!("extend_alpha{t}"));
            assert_eq!(pick(Stage::Connect, true, true, texel), format!("connect_alpha{t}"));
            assert_eq!(pick(Stage::Shade, false, false, texel), format!("shade{t}"));
            assert_eq!(pick(Stage::Shade, false, true, texel), format!("shade_textured{t}"));
            assert_eq!(pick(Stage::Shade, true, true, texel), format!("shade_textured{t}"));
            assert_eq!(pick(Stage::Follow, false, false, texel), format!("follow{t}"));
            assert_eq!(pick(Stage::Follow, false, true, texel), format!("follow_textured{t}"));
            assert_eq!(pick(Stage::Follow, true, true, texel), format!("follow_alpha{t}"));
            // The probe tests alpha only when asked (probe_trace_alpha): an alpha-tested scene's plain probe sees
            // every triangle opaque.
            assert_eq!(pick(Stage::ProbeTrace, false, true, texel), format!("probe_trace{t}"));
            assert_eq!(
                pick(Stage::ProbeTrace, true, true, texel),
                format!("probe_trace_alpha{t}")
            );
            assert_eq!(pick(Stage::Generate, true, true, texel), "generate");
            assert_eq!(pick(Stage::Accumulate, true, true, texel), format!("accumulate{t}"));
        }
    }
}
