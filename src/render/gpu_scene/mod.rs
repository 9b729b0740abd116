//! A scene on the device: the one table of scene buffers (SCENE_BINDINGS), their upload, texel views and limits.
mod describe;
mod emission;
mod instances;
mod lights;
mod materials;
pub mod mipmaps;
mod pack;

pub use describe::{describe, Report};
pub use emission::Emission;
pub use pack::{pack, try_pack, try_pack_with, PackedScene};

use crate::constants::*;
use crate::error::Error;
use crate::vk::{Buffer, Context, TexelViews};
use ash::vk;

/// How traversal reads the BVH nodes and triangle vertices (the same bytes either way).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BvhReads {
    /// Storage-buffer loads: works everywhere.
    Storage,
    /// Uniform texel buffers (RGBA32UI): on lavapipe several times faster; used when the device's
    /// maxTexelBufferElements holds the scene. PATHWAVE_BVH_READS=storage forces the other path.
    Texel,
}

/// How the stages read one scene buffer, which decides its usage, its texel view and when it is refused.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Reads {
    /// Storage-buffer loads alone: it must fit the storage range.
    Storage,
    /// BVH and per-triangle data: also an RGBA32UI view when the device holds the scene that way, which lifts the
    /// storage range off it.
    Viewed,
    /// Read through an RGBA32UI view by the texel stages and from the storage buffer by the others (probe_bsdf, the
    /// storage variants), so it must fit the storage range either way.
    Both,
    /// The textures' RGBA8 texels, one u32 each, through an R32UI view.
    ImageTexels,
}

/// One scene buffer: its name in messages, its storage binding, its texel binding, how it is read.
struct SceneBinding(&'static str, u32, Option<u32>, Reads);

/// The storage and texel bindings the scene fills (render/mod.rs checks every binding has exactly one filler).
#[cfg(test)]
pub(super) fn filled_bindings() -> (Vec<u32>, Vec<u32>) {
    let storage = SCENE_BINDINGS.iter().map(|b| b.1).collect();
    let texel = SCENE_BINDINGS.iter().filter_map(|b| b.2).collect();
    (storage, texel)
}

/// Every scene buffer, in upload order: the one list binding, upload, views and limits come from.
const SCENE_BINDINGS: [SceneBinding; 15] = [
    SceneBinding("bvh nodes", BINDING_NODES, Some(BINDING_NODE_TEXELS), Reads::Viewed),
    SceneBinding(
        "triangle vertices",
        BINDING_TRI_VERTS,
        Some(BINDING_TRI_TEXELS),
        Reads::Viewed,
    ),
    SceneBinding(
        "triangle shading",
        BINDING_TRI_SHADING,
        Some(BINDING_TRI_SHADING_TEXELS),
        Reads::Viewed,
    ),
    SceneBinding(
        "texture coordinates",
        BINDING_TRI_TEXCOORDS,
        Some(BINDING_TRI_TEXCOORD_TEXELS),
        Reads::Viewed,
    ),
    SceneBinding(
        "tangents",
        BINDING_TRI_TANGENTS,
        Some(BINDING_TRI_TANGENT_TEXELS),
        Reads::Viewed,
    ),
    SceneBinding(
        "vertex colours",
        BINDING_TRI_COLORS,
        Some(BINDING_TRI_COLOR_TEXELS),
        Reads::Viewed,
    ),
    SceneBinding(
        "materials",
        BINDING_MATERIALS,
        Some(BINDING_MATERIAL_TEXELS),
        Reads::Both,
    ),
    SceneBinding("lights", BINDING_LIGHTS, Some(BINDING_LIGHT_TEXELS), Reads::Both),
    SceneBinding(
        "light tree",
        BINDING_LIGHT_TREE,
        Some(BINDING_LIGHT_TREE_TEXELS),
        Reads::Both,
    ),
    SceneBinding("environment", BINDING_ENV, None, Reads::Storage),
    SceneBinding("punctual lights", BINDING_PUNCTUAL, None, Reads::Storage),
    SceneBinding("textures", BINDING_TEXTURES, None, Reads::Storage),
    SceneBinding("instances", BINDING_INSTANCES, None, Reads::Storage),
    SceneBinding(
        "motion keys",
        BINDING_MOTION,
        Some(BINDING_MOTION_TEXELS),
        Reads::Viewed,
    ),
    SceneBinding(
        "texture texels",
        BINDING_TEXELS,
        Some(BINDING_IMAGE_TEXELS),
        Reads::ImageTexels,
    ),
];

impl PackedScene {
    /// The bytes uploaded to a scene binding.
    fn bytes(&self, binding: u32) -> &[u8] {
        use bytemuck::cast_slice as bytes;
        match binding {
            BINDING_NODES => bytes(&self.bvh.nodes),
            BINDING_TRI_VERTS => bytes(&self.tri_verts),
            BINDING_TRI_SHADING => bytes(&self.tri_shading),
            BINDING_TRI_TEXCOORDS => bytes(&self.tri_texcoords),
            BINDING_TRI_TANGENTS => bytes(&self.tri_tangents),
            BINDING_TRI_COLORS => bytes(&self.tri_colors),
            BINDING_MATERIALS => bytes(&self.materials),
            BINDING_LIGHTS => bytes(&self.lights),
            BINDING_LIGHT_TREE => bytes(&self.light_tree.nodes),
            BINDING_ENV => bytes(&self.env_data),
            BINDING_PUNCTUAL => bytes(&self.punctual),
            BINDING_TEXTURES => bytes(&self.textures),
            BINDING_TEXELS => bytes(&self.texels),
            BINDING_MOTION => bytes(&self.motion),
            BINDING_INSTANCES => bytes(&self.instances),
            _ => unreachable!("binding {binding} is no scene buffer"),
        }
    }
}

impl PackedScene {
    /// BLAKE3 of every buffer the device gets, by binding: what a film file names its scene by. Equal scenes pack to
    /// equal bytes (packing is deterministic), whatever file layout or compression they were read from.
    pub fn fingerprint(&self) -> String {
        let mut hasher = blake3::Hasher::new();
        for b in &SCENE_BINDINGS {
            let bytes = self.bytes(b.1);
            hasher.update(&b.1.to_le_bytes());
            hasher.update(&(bytes.len() as u64).to_le_bytes());
            hasher.update(bytes);
        }
        hasher.update(&self.env_prob.to_le_bytes());
        hasher.update(&self.env_prob_tree.to_le_bytes());
        hasher.finalize().to_hex().to_string()
    }
}

/// Bytes for a message: MiB when large, bytes when not.
pub(super) fn size_text(bytes: u64) -> String {
    if bytes >= 1 << 20 {
        format!("{:.1} MiB", bytes as f64 / (1u64 << 20) as f64)
    } else {
        format!("{bytes} bytes")
    }
}

/// Refuses a scene whose buffers would take more than `budget` bytes of device memory, before any is allocated.
fn check_device_memory(packed: &PackedScene, budget: u64) -> Result<(), Error> {
    // Every buffer is at least 16 bytes (Buffer::new).
    let size = |b: &SceneBinding| (packed.bytes(b.1).len() as u64).max(16);
    let total: u64 = SCENE_BINDINGS.iter().map(size).fold(0, u64::saturating_add);
    if total <= budget {
        return Ok(());
    }
    let largest = SCENE_BINDINGS
        .iter()
        .max_by_key(|b| size(b))
        .expect("SCENE_BINDINGS is not empty");
    Err(Error::Limit(format!(
        "the scene's buffers take {} of device memory (the largest, its {}, {}), more than the {} it may use",
        size_text(total),
        largest.0,
        size_text(size(largest)),
        size_text(budget)
    )))
}

/// Every scene buffer on the device at its binding, with a texel view's usage when `texel_ok` lets it be read
/// through one; an error naming the first buffer this device can read neither way (within the storage range
/// `range`, nor through `max_texels` texels when `texel_format`).
fn upload_buffers(
    ctx: &Context,
    packed: &PackedScene,
    range: u64,
    max_texels: u64,
    texel_format: bool,
    texel_ok: bool,
) -> Result<Vec<(u32, Buffer)>, Error> {
    let mut buffers = Vec::with_capacity(SCENE_BINDINGS.len());
    for b in &SCENE_BINDINGS {
        let data = packed.bytes(b.1);
        let bytes = data.len() as u64;
        // The bytes per texel of the view the buffer is also read through, if any.
        let element = match b.3 {
            Reads::Storage => None,
            Reads::Viewed => Some(16),
            Reads::Both => (bytes <= range).then_some(16),
            Reads::ImageTexels => Some(4),
        };
        let viewed = element.is_some() && texel_ok;
        if bytes > range && !viewed {
            let limit = match element {
                Some(e) if texel_format => format!(" and its texel-buffer limit of {}", size_text(e * max_texels)),
                _ => String::new(),
            };
            return Err(Error::Settings(format!(
                "the scene's {} take {}, more than this device's storage-buffer range of {}{limit}",
                b.0,
                size_text(bytes),
                size_text(range),
            )));
        }
        let usage = vk::BufferUsageFlags::STORAGE_BUFFER
            | if viewed {
                vk::BufferUsageFlags::UNIFORM_TEXEL_BUFFER
            } else {
                vk::BufferUsageFlags::empty()
            };
        buffers.push((b.1, Buffer::with_data_usage(ctx, b.0, data, usage)?));
    }
    Ok(buffers)
}

/// The texel views of `buffers` (uploaded in SCENE_BINDINGS' order) at their texel bindings: RGBA32UI, R32UI for
/// the image texels.
fn create_texel_views(ctx: &Context, buffers: &[(u32, Buffer)]) -> Result<TexelViews, Error> {
    let list: Vec<(u32, &Buffer, vk::Format)> = SCENE_BINDINGS
        .iter()
        .zip(buffers)
        .filter_map(|(b, (_, buffer))| {
            let format = match b.3 {
                Reads::ImageTexels => vk::Format::R32_UINT,
                _ => vk::Format::R32G32B32A32_UINT,
            };
            b.2.map(|view| (view, buffer, format))
        })
        .collect();
    TexelViews::new(ctx, &list)
}

/// A scene on the device: its buffers at their bindings, their texel views, and what its passes need to know of it.
pub struct GpuScene {
    /// Dropped before the buffers they view.
    views: Option<TexelViews>,
    buffers: Vec<(u32, Buffer)>,
    /// Every BVH and per-triangle buffer fits the storage-buffer range (BvhReads::Storage can read the scene).
    pub storage_ok: bool,
    pub light_count: u32,
    pub env_prob: f32,
    /// The environment's probability when light selection descends the light BVH.
    pub env_prob_tree: f32,
    /// What the light BVH holds (emitters, nodes, depth, build time) and its device bytes.
    pub light_tree: crate::bvh::lights::LightTreeStats,
    pub light_tree_bytes: usize,
    /// The FEATURE_* bits of what the scene's materials and lights use.
    pub features: u32,
    /// Some triangle's material is alpha-tested: traversal runs the *_alpha variants.
    pub alpha_tested: bool,
    /// Some material has a texture or alpha, or some mesh has COLOR_0: shading runs the textured variant.
    pub textured: bool,
    pub vertex_colors: bool,
    /// The scene's own camera moves over the shutter (FLAG_CAMERA_MOTION, when the renders use that camera).
    pub camera_moves: bool,
    /// How long building the BVH took.
    pub bvh_build: std::time::Duration,
    /// `PackedScene::fingerprint`, when the renderer was asked to keep it (`RendererOptions::fingerprint`).
    pub fingerprint: Option<String>,
    /// The device's acceleration structures, when rays are traced with ray queries (render::accel).
    pub accel: Option<crate::render::accel::AccelStructures>,
}

impl GpuScene {
    /// Uploads `packed`, refusing it by buffer name when one outgrows every way this device can read it.
    pub fn upload(ctx: &Context, packed: &PackedScene, device_budget: u64) -> Result<Self, Error> {
        check_device_memory(packed, device_budget)?;
        let range = ctx.properties.limits.max_storage_buffer_range as u64;
        let max_texels = ctx.properties.limits.max_texel_buffer_elements as u64;
        let format_ok = |f| {
            let p = unsafe { ctx.instance.get_physical_device_format_properties(ctx.physical, f) };
            p.buffer_features.contains(vk::FormatFeatureFlags::UNIFORM_TEXEL_BUFFER)
        };
        let texel_format = format_ok(vk::Format::R32G32B32A32_UINT) && format_ok(vk::Format::R32_UINT);
        let len = |b: &SceneBinding| packed.bytes(b.1).len() as u64;
        // Every buffer read through an RGBA32UI view (all viewed but the image texels).
        let viewed = || {
            SCENE_BINDINGS
                .iter()
                .filter(|b| matches!(b.3, Reads::Viewed | Reads::Both))
        };
        let image_texels = packed.texels.len() as u64;
        let texel_ok = texel_format && viewed().all(|b| len(b) <= 16 * max_texels) && image_texels <= max_texels;
        let buffers = upload_buffers(ctx, packed, range, max_texels, texel_format, texel_ok)?;
        let views = if texel_ok {
            Some(create_texel_views(ctx, &buffers)?)
        } else {
            None
        };
        // Storage reads need every viewed buffer and the image texels within the storage range.
        let storage_ok = viewed().all(|b| len(b) <= range) && (4 * image_texels).max(16) <= range;
        let alpha_tested = packed.tri_verts.iter().any(|t| t.e1[3] != 0.0);
        Ok(GpuScene {
            views,
            buffers,
            storage_ok,
            light_count: packed.light_count,
            env_prob: packed.env_prob,
            env_prob_tree: packed.env_prob_tree,
            light_tree: packed.light_tree.stats.clone(),
            light_tree_bytes: packed.light_tree.bytes(),
            features: packed.features(),
            alpha_tested,
            textured: alpha_tested || !packed.tri_texcoords.is_empty() || !packed.tri_colors.is_empty(),
            vertex_colors: !packed.tri_colors.is_empty(),
            camera_moves: packed.camera_moves,
            bvh_build: packed.bvh_build,
            fingerprint: None,
            accel: None,
        })
    }

    /// Every scene buffer at its binding.
    pub fn bindings(&self) -> impl Iterator<Item = (u32, &Buffer)> {
        self.buffers.iter().map(|(b, buffer)| (*b, buffer))
    }

    /// The texel views by binding, when the device holds the scene that way.
    /// Device bytes of the scene's buffers.
    pub fn bytes(&self) -> u64 {
        self.buffers.iter().map(|(_, b)| b.size).sum()
    }

    pub fn texel_views(&self) -> Option<&[(u32, vk::BufferView)]> {
        self.views.as_ref().map(|v| &v.views[..])
    }

    fn buffer(&self, binding: u32) -> &Buffer {
        &self
            .buffers
            .iter()
            .find(|(b, _)| *b == binding)
            .expect("every scene binding is uploaded")
            .1
    }

    /// Device bytes of what traversal and shading read per triangle: BVH nodes, vertices and shading normals.
    pub fn traversal_bytes(&self) -> u64 {
        let instances = match self.features & FEATURE_INSTANCES {
            0 => 0,
            _ => self.buffer(BINDING_INSTANCES).size,
        };
        [BINDING_NODES, BINDING_TRI_VERTS, BINDING_TRI_SHADING]
            .map(|b| self.buffer(b).size)
            .iter()
            .sum::<u64>()
            + instances
    }
}
