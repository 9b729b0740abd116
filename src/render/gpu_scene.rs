//! Packs a host Scene into the device layout: BVH-ordered triangles, shading data, materials and the light table.
use crate::bvh::{self, Bvh};
use crate::constants::*;
use crate::layout::{
    GpuLight, GpuMaterial, GpuPunctual, GpuTexture, TextureSlot, TriColors, TriShading, TriTangents, TriTexcoords,
    TriVerts,
};
use crate::scene::{AlphaMode, Material, PunctualKind, Scene, TextureRef, TriangleSoup, Wrap};

/// Everything the device needs from a scene, in upload order.
pub struct PackedScene {
    pub bvh: Bvh,
    /// Wall time of the BVH build alone (the rest of packing is copying).
    pub bvh_build: std::time::Duration,
    pub tri_verts: Vec<TriVerts>,
    pub tri_shading: Vec<TriShading>,
    pub materials: Vec<GpuMaterial>,
    pub lights: Vec<GpuLight>,
    /// Sum of the lights' estimated power (W), what light selection is proportional to.
    pub total_light_power: f64,
    /// Probability that light selection picks the environment (0 without one).
    pub env_prob: f32,
    /// The environment's device buffer (see layout.glsl), empty without one.
    pub env_data: Vec<f32>,
    pub punctual: Vec<GpuPunctual>,
    pub textures: Vec<GpuTexture>,
    /// RGBA8 texels of every image, one u32 each (red in the low byte), as `TextureInfo.offset` indexes them.
    pub texels: Vec<u32>,
    /// Empty when no material has a texture (the shaders then never read them).
    pub tri_texcoords: Vec<TriTexcoords>,
    /// Empty when no material has a normal map.
    pub tri_tangents: Vec<TriTangents>,
    /// Empty when no mesh has COLOR_0.
    pub tri_colors: Vec<TriColors>,
}

impl PackedScene {
    /// The FEATURE_* bits of what the scene's materials and lights use, for SCENE_FEATURES: a cleared bit promises
    /// that the value it guards is zero for every material (or that no such light exists).
    pub fn features(&self) -> u32 {
        // Only materials some triangle uses (the loader always adds a default one).
        let mut used = vec![false; self.materials.len()];
        for t in &self.tri_verts {
            if let Some(u) = used.get_mut(t.v0[3].to_bits() as usize) {
                *u = true;
            }
        }
        let any = |f: fn(&GpuMaterial) -> bool| self.materials.iter().zip(&used).any(|(m, &u)| u && f(m));
        let mut bits = 0;
        if any(|m| m.params[3] != 0.0) {
            bits |= FEATURE_COAT;
        }
        if any(|m| m.params[0] != 0.0) {
            bits |= FEATURE_METAL;
        }
        if any(|m| m.transmission[0] != 0.0) {
            bits |= FEATURE_TRANSMISSION;
        }
        if !self.punctual.is_empty() {
            bits |= FEATURE_PUNCTUAL;
        }
        if !self.env_data.is_empty() {
            bits |= FEATURE_ENV;
        }
        if self.bvh.stats.max_waiting > REGISTER_STACK {
            bits |= FEATURE_DEEP_STACK;
        }
        bits
    }
}

fn v4(v: glam::Vec3, w: f32) -> [f32; 4] {
    [v.x, v.y, v.z, w]
}

/// Mean emitted radiance of a material: the factor times its emissive texture's average (decoded from sRGB).
pub fn mean_emission(scene: &Scene, m: &Material) -> glam::Vec3 {
    match m.emissive_texture {
        Some(r) => {
            m.emission
                * scene.images[scene.textures[r.texture].image]
                    .average_linear()
                    .truncate()
        }
        None => m.emission,
    }
}

/// Power a triangle emits: mean radiance over channels × area × pi (× 2 when both faces emit).
pub fn emitted_power(scene: &Scene, soup: &TriangleSoup, tri: usize) -> f64 {
    let m = &scene.materials[soup.material()[tri] as usize];
    let e = mean_emission(scene, m);
    let [a, b, c] = soup.positions()[tri];
    let area = 0.5 * (b - a).cross(c - a).length() as f64;
    let sides = if m.double_sided { 2.0 } else { 1.0 };
    (e.x + e.y + e.z) as f64 / 3.0 * area * std::f64::consts::PI * sides
}

fn slot(r: Option<TextureRef>) -> TextureSlot {
    match r {
        Some(r) => TextureSlot {
            u: [
                r.transform[0][0],
                r.transform[0][1],
                r.transform[0][2],
                f32::from_bits(r.texture as u32),
            ],
            v: [
                r.transform[1][0],
                r.transform[1][1],
                r.transform[1][2],
                f32::from_bits(r.tex_coord),
            ],
        },
        None => TextureSlot {
            u: [1.0, 0.0, 0.0, f32::from_bits(TEXTURE_NONE)],
            v: [0.0, 1.0, 0.0, f32::from_bits(0)],
        },
    }
}

fn gpu_material(m: &Material) -> GpuMaterial {
    let (mode, cutoff) = match m.alpha_mode {
        AlphaMode::Opaque => (ALPHA_OPAQUE, 0.0),
        AlphaMode::Mask(c) => (ALPHA_MASK, c),
        AlphaMode::Blend => (ALPHA_BLEND, 0.0),
    };
    GpuMaterial {
        base_color: v4(m.base_color, m.alpha),
        emission: v4(m.emission, if m.double_sided { 1.0 } else { 0.0 }),
        params: [m.metallic, m.roughness, m.ior, m.specular],
        specular_color: v4(m.specular_color, 0.0),
        transmission: [m.transmission, if m.thin_walled { 1.0 } else { 0.0 }, 0.0, 0.0],
        attenuation: v4(m.attenuation, 0.0),
        alpha: [f32::from_bits(mode), cutoff, m.normal_scale, 0.0],
        textures: m.texture_refs().map(slot),
    }
}

/// The texture table and every image's texels, each image once however many textures share it.
fn pack_textures(scene: &Scene) -> (Vec<GpuTexture>, Vec<u32>) {
    let mut offsets = Vec::with_capacity(scene.images.len());
    let mut texels = Vec::new();
    for image in &scene.images {
        offsets.push(texels.len() as u32);
        texels.extend(image.texels.iter().map(|t| u32::from_le_bytes(*t)));
    }
    let wrap = |w: Wrap| match w {
        Wrap::Repeat => WRAP_REPEAT,
        Wrap::ClampToEdge => WRAP_CLAMP,
        Wrap::MirroredRepeat => WRAP_MIRROR,
    };
    let textures = scene
        .textures
        .iter()
        .map(|t| {
            let image = &scene.images[t.image];
            GpuTexture {
                offset: offsets[t.image],
                width: image.width,
                height: image.height,
                flags: wrap(t.wrap_s)
                    | wrap(t.wrap_t) << TEXTURE_WRAP_T_SHIFT
                    | if t.nearest { TEXTURE_NEAREST } else { 0 },
            }
        })
        .collect();
    (textures, texels)
}

pub fn pack(scene: &Scene) -> PackedScene {
    let soup = scene.flatten();
    let start = std::time::Instant::now();
    let bvh = bvh::build(soup.positions());
    let bvh_build = start.elapsed();
    let n = soup.len();
    let mut tri_verts = Vec::with_capacity(n);
    let mut tri_shading = Vec::with_capacity(n);
    let textured = scene
        .materials
        .iter()
        .any(|m| m.texture_refs().iter().any(Option::is_some));
    let normal_mapped = scene.materials.iter().any(|m| m.normal_texture.is_some());
    let mut tri_texcoords = Vec::with_capacity(if textured { n } else { 0 });
    let mut tri_tangents = Vec::with_capacity(if normal_mapped { n } else { 0 });
    let mut tri_colors = Vec::with_capacity(soup.colors().len());
    // (light id, power, area)
    let mut powers: Vec<(u32, f64, f32)> = Vec::new();
    for (slot, &orig) in bvh.order.iter().enumerate() {
        let orig = orig as usize;
        let [a, b, c] = soup.positions()[orig];
        let [na, nb, nc] = soup.normals()[orig];
        let material = soup.material()[orig];
        let alpha_tested = scene.materials[material as usize].alpha_tested();
        tri_verts.push(TriVerts {
            v0: v4(a, f32::from_bits(material)),
            e1: v4(b - a, if alpha_tested { 1.0 } else { 0.0 }),
            e2: v4(c - a, 0.0),
        });
        if textured {
            let [t0, t1, t2] = soup.texcoords()[orig].map(|t| t.to_array());
            tri_texcoords.push(TriTexcoords { t0, t1, t2 });
        }
        if normal_mapped {
            let [t0, t1, t2] = soup.tangents()[orig].map(|t| t.to_array());
            tri_tangents.push(TriTangents { t0, t1, t2 });
        }
        if let Some(c) = soup.colors().get(orig) {
            let [c0, c1, c2] = c.map(|v| v.to_array());
            tri_colors.push(TriColors { c0, c1, c2 });
        }
        let area = 0.5 * (b - a).cross(c - a).length();
        tri_shading.push(TriShading {
            n0: v4(na, 0.0),
            n1: v4(nb, area),
            n2: v4(nc, 0.0),
        });
        let p = emitted_power(scene, &soup, orig);
        if p > 0.0 {
            powers.push((slot as u32, p, area));
        }
    }
    let (lo, hi) = soup.bounds();
    let radius = if soup.is_empty() {
        1.0
    } else {
        ((hi - lo).length() * 0.5).max(1e-3)
    };
    // Punctual lights by their emitted power; a directional one by what crosses the scene's bounding disk.
    let mut punctual = Vec::with_capacity(scene.punctual.len());
    for (i, l) in scene.punctual.iter().enumerate() {
        let mean = (l.intensity.x + l.intensity.y + l.intensity.z) as f64 / 3.0;
        let pi = std::f64::consts::PI;
        let (kind, cos_outer, cos_inner, p) = match l.kind {
            PunctualKind::Point => (PUNCTUAL_POINT, -1.0, -1.0, 4.0 * pi * mean),
            PunctualKind::Spot { inner, outer } => {
                let (ci, co) = (inner.cos(), outer.cos());
                (PUNCTUAL_SPOT, co, ci, 2.0 * pi * (1.0 - 0.5 * (ci + co) as f64) * mean)
            }
            PunctualKind::Directional => (PUNCTUAL_DIRECTIONAL, 1.0, 1.0, pi * (radius as f64).powi(2) * mean),
        };
        punctual.push(GpuPunctual {
            position: v4(l.position, f32::from_bits(kind)),
            direction: v4(l.direction, cos_outer),
            intensity: v4(l.intensity, cos_inner),
        });
        if p > 0.0 {
            powers.push((LIGHT_KIND_PUNCTUAL << LIGHT_KIND_SHIFT | i as u32, p, 0.0));
        }
    }
    // The environment competes with the emitters by the power it sends into the scene's bounding sphere.
    if let Some(env) = &scene.environment {
        let p = env.power(radius);
        if p > 0.0 {
            powers.push((LIGHT_KIND_ENV << LIGHT_KIND_SHIFT, p, 0.0));
        }
    }
    let total: f64 = powers.iter().map(|p| p.1).sum();
    let mut lights = Vec::with_capacity(powers.len());
    let mut acc = 0.0f64;
    let mut env_prob = 0.0;
    let mut previous_cdf = 0.0f32;
    for (i, &(id, p, area)) in powers.iter().enumerate() {
        acc += p;
        // The last cdf is exactly 1 so every u in [0, 1) finds a light.
        let cdf = if i + 1 == powers.len() {
            1.0
        } else {
            (acc / total) as f32
        };
        // The probability the device actually picks with is the gap between stored f32 cdfs, not p / total: for tiny
        // lights late in the table they differ.
        let prob = cdf - previous_cdf;
        previous_cdf = cdf;
        lights.push(GpuLight { id, cdf, prob, area });
        match id >> LIGHT_KIND_SHIFT {
            LIGHT_KIND_ENV => env_prob = prob,
            LIGHT_KIND_TRIANGLE => tri_shading[id as usize].n0[3] = if prob > 0.0 { prob / area } else { 0.0 },
            _ => {} // punctual lights are never hit, so MIS never asks for their probability
        }
    }
    let materials = scene.materials.iter().map(gpu_material).collect();
    let (textures, texels) = pack_textures(scene);
    let env_data = scene.environment.as_ref().map(|e| e.device_data()).unwrap_or_default();
    PackedScene {
        bvh_build,
        bvh,
        tri_verts,
        tri_shading,
        materials,
        lights,
        total_light_power: total,
        env_prob,
        env_data,
        punctual,
        textures,
        texels,
        tri_texcoords,
        tri_tangents,
        tri_colors,
    }
}

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

/// Every scene buffer, in upload order: the one list binding, upload, views and limits come from.
const SCENE_BINDINGS: [SceneBinding; 12] = [
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
    SceneBinding("environment", BINDING_ENV, None, Reads::Storage),
    SceneBinding("punctual lights", BINDING_PUNCTUAL, None, Reads::Storage),
    SceneBinding("textures", BINDING_TEXTURES, None, Reads::Storage),
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
            BINDING_ENV => bytes(&self.env_data),
            BINDING_PUNCTUAL => bytes(&self.punctual),
            BINDING_TEXTURES => bytes(&self.textures),
            BINDING_TEXELS => bytes(&self.texels),
            _ => unreachable!("binding {binding} is no scene buffer"),
        }
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

/// A scene on the device: its buffers at their bindings, their texel views, and what its passes need to know of it.
pub struct GpuScene {
    /// Dropped before the buffers they view.
    views: Option<TexelViews>,
    buffers: Vec<(u32, Buffer)>,
    /// Every BVH and per-triangle buffer fits the storage-buffer range (BvhReads::Storage can read the scene).
    pub storage_ok: bool,
    pub light_count: u32,
    pub env_prob: f32,
    /// The FEATURE_* bits of what the scene's materials and lights use.
    pub features: u32,
    /// Some triangle's material is alpha-tested: traversal runs the *_alpha variants.
    pub alpha_tested: bool,
    /// Some material has a texture or alpha, or some mesh has COLOR_0: shading runs the textured variant.
    pub textured: bool,
    pub vertex_colors: bool,
    /// How long building the BVH took.
    pub bvh_build: std::time::Duration,
}

impl GpuScene {
    /// Uploads `packed`, refusing it by buffer name when one outgrows every way this device can read it.
    pub fn upload(ctx: &Context, packed: &PackedScene) -> Result<Self, Error> {
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
        let views = if texel_ok {
            let list: Vec<(u32, &Buffer, vk::Format)> = SCENE_BINDINGS
                .iter()
                .zip(&buffers)
                .filter_map(|(b, (_, buffer))| {
                    let format = match b.3 {
                        Reads::ImageTexels => vk::Format::R32_UINT,
                        _ => vk::Format::R32G32B32A32_UINT,
                    };
                    b.2.map(|view| (view, buffer, format))
                })
                .collect();
            Some(TexelViews::new(ctx, &list)?)
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
            light_count: packed.lights.len() as u32,
            env_prob: packed.env_prob,
            features: packed.features(),
            alpha_tested,
            textured: alpha_tested || !packed.tri_texcoords.is_empty() || !packed.tri_colors.is_empty(),
            vertex_colors: !packed.tri_colors.is_empty(),
            bvh_build: packed.bvh_build,
        })
    }

    /// Every scene buffer at its binding.
    pub fn bindings(&self) -> impl Iterator<Item = (u32, &Buffer)> {
        self.buffers.iter().map(|(b, buffer)| (*b, buffer))
    }

    /// The texel views by binding, when the device holds the scene that way.
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
        [BINDING_NODES, BINDING_TRI_VERTS, BINDING_TRI_SHADING]
            .map(|b| self.buffer(b).size)
            .iter()
            .sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn features_of(name: &str) -> u32 {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("scenes")
            .join(name);
        pack(&crate::scene::load(&path, None).unwrap()).features()
    }

    // A bit cleared by mistake folds a lobe or light away while the scene uses it; one set by mistake only costs time.
    #[test]
    fn scene_features_name_what_materials_and_lights_use() {
        assert_eq!(features_of("cornell-box.gltf"), 0);
        assert_eq!(
            features_of("glass.gltf"),
            FEATURE_COAT | FEATURE_TRANSMISSION | FEATURE_DEEP_STACK
        );
        assert_eq!(features_of("punctual-lights.gltf") & FEATURE_PUNCTUAL, FEATURE_PUNCTUAL);
        let grid = features_of("material-grid.gltf");
        assert_eq!(grid & (FEATURE_COAT | FEATURE_METAL), FEATURE_COAT | FEATURE_METAL);
    }
}
