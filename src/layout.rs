//! Rust mirrors of the structs in `shaders/include/layout.glsl`; tests/layout.rs checks them against the SPIR-V.
use crate::constants::{BVH_CHILD_INTERIOR, STACK_COUNT_BITS};
use bytemuck::{Pod, Zeroable};

/// 48 bytes (three texels): one interior node, its BVH_WIDTH children's boxes quantised and where the children are.
/// See `BvhNode` in layout.glsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub struct BvhNode {
    /// xyz: f32 bits of the quantisation origin; w: the biased exponent of each axis's step (bytes 0, 1, 2), and the
    /// kinds (BVH_CHILD_INTERIOR, a leaf's triangle count, or 0 for unused) of children 0 and 1 in bits 24 and 27.
    pub origin: [u32; 4],
    /// Byte c of each word is child c's: lo.x, lo.y, lo.z, hi.x.
    pub q0: [u32; 4],
    /// Byte c of x and y is child c's hi.y, hi.z. z: the first interior child's node index << STACK_COUNT_BITS |
    /// child 2's kind; w: the first triangle of the leaf children << STACK_COUNT_BITS | child 3's kind.
    pub q1: [u32; 4],
}

impl BvhNode {
    /// The node moved into a node array and a triangle array that hold others before it: its interior children's
    /// index by `nodes`, its leaves' first triangle by `tris` (the kinds in the low bits are kept).
    pub fn offset(&mut self, nodes: u32, tris: u32) {
        use crate::constants::STACK_COUNT_BITS;
        self.q1[2] = self.q1[2].wrapping_add(nodes << STACK_COUNT_BITS);
        self.q1[3] = self.q1[3].wrapping_add(tris << STACK_COUNT_BITS);
    }

    /// Child `c`'s kind: 0 for an unused slot, a leaf's triangle count, or BVH_CHILD_INTERIOR.
    pub fn kind(&self, c: usize) -> u32 {
        let word = [self.origin[3] >> 24, self.origin[3] >> 27, self.q1[2], self.q1[3]][c];
        word & ((1 << STACK_COUNT_BITS) - 1)
    }

    /// Records child `c`'s kind (into a node whose kind bits are still 0).
    pub fn set_kind(&mut self, c: usize, kind: u32) {
        match c {
            0 => self.origin[3] |= kind << 24,
            1 => self.origin[3] |= kind << 27,
            2 => self.q1[2] |= kind,
            _ => self.q1[3] |= kind,
        }
    }

    /// Each child as a traversal stack entry holds it, `first << STACK_COUNT_BITS | count` (count 0 for an interior
    /// node), or 0 for an unused slot. A node's interior children are consecutive nodes from q1.z's index, and its
    /// leaves' triangles consecutive from q1.w's, both in slot order: the same arithmetic as traverse.glsl.
    pub fn child_entries(&self) -> [u32; 4] {
        let mut node = self.q1[2] >> STACK_COUNT_BITS;
        let mut tri = self.q1[3] >> STACK_COUNT_BITS;
        std::array::from_fn(|c| match self.kind(c) {
            0 => 0,
            BVH_CHILD_INTERIOR => {
                node += 1;
                (node - 1) << STACK_COUNT_BITS
            }
            count => {
                tri += count;
                (tri - count) << STACK_COUNT_BITS | count
            }
        })
    }

    /// The step of each axis's quantisation grid: 2^(exponent - 127), a normal power of two.
    pub fn scale(&self) -> [f32; 3] {
        std::array::from_fn(|a| f32::from_bits(((self.origin[3] >> (8 * a)) & 0xFF) << 23))
    }

    /// Grid point `q` on `axis`: origin + q * step. The product is exact (q < 256, the step a power of two), so the
    /// one rounding is the same with or without a fused multiply-add, on the device and here.
    pub fn bound(&self, axis: usize, q: u32) -> f32 {
        f32::from_bits(self.origin[axis]) + q as f32 * self.scale()[axis]
    }

    /// Child `c`'s box in grid steps from the origin: (lo, hi) per axis.
    pub fn child_q(&self, c: usize) -> ([u32; 3], [u32; 3]) {
        let byte = |w: u32| (w >> (8 * c)) & 0xFF;
        (
            [byte(self.q0[0]), byte(self.q0[1]), byte(self.q0[2])],
            [byte(self.q0[3]), byte(self.q1[0]), byte(self.q1[1])],
        )
    }

    /// The grid origin.
    pub fn grid_origin(&self) -> [f32; 3] {
        std::array::from_fn(|a| f32::from_bits(self.origin[a]))
    }

    /// Child `c`'s box as the builder decodes it, or None for an unused slot.
    pub fn child_box(&self, c: usize) -> Option<([f32; 3], [f32; 3])> {
        if self.kind(c) == 0 {
            return None;
        }
        let (lo_q, hi_q) = self.child_q(c);
        let lo = std::array::from_fn(|a| self.bound(a, lo_q[a]));
        let hi = std::array::from_fn(|a| self.bound(a, hi_q[a]));
        Some((lo, hi))
    }
}

/// 48 bytes: vertex 0 and two edges; `v0[3]` holds the material index bits, `e1[3]` is 1 when the material is
/// alpha-tested (rays may pass through).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub struct TriVerts {
    pub v0: [f32; 4],
    pub e1: [f32; 4],
    pub e2: [f32; 4],
}

/// 96 bytes: one key of a moving triangle, as TriVerts and TriShading hold key 0: vertex 0, the two edges and the
/// three shading normals (every w 0). A camera key uses the same record: origin in v0, right, up and forward in e1,
/// e2 and n0. See `MotionKey` in layout.glsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub struct MotionKey {
    pub v0: [f32; 4],
    pub e1: [f32; 4],
    pub e2: [f32; 4],
    pub n0: [f32; 4],
    pub n1: [f32; 4],
    pub n2: [f32; 4],
}

/// 128 bytes: one instance of a mesh kept in object space: its object-to-world and world-to-object transforms as
/// three rows each (x, y, z of a 3x4 affine map), `info` = (its BLAS root node, 1 when the transform mirrors, its
/// index in `Scene::instances`, the record of its key 0 when it moves over the shutter, else 0), and `light` = (where
/// its mesh's emitters' table starts in the light buffer, how many it holds, this instance's entry in light
/// selection's table, the root of its mesh's light subtree in the light tree); all 0 for a mesh that does not emit. Record 0 is the header: `info` =
/// (the TLAS root node, the instance count, the first BLAS triangle, 0). The instances' records follow in the TLAS's
/// order, then each moving instance's keys 0 ..= MOTION_SEGMENTS, whole records at those times whose object rows
/// hold the key's decomposition instead of its inverse (object0 = translation and 1, object1 = the rotation's
/// quaternion, object2 = scale; object0.w = 0 when the keys do not decompose). 128 bytes a still instance, 768 a
/// moving one. See `Instance` in layout.glsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub struct GpuInstance {
    pub world0: [f32; 4],
    pub world1: [f32; 4],
    pub world2: [f32; 4],
    pub object0: [f32; 4],
    pub object1: [f32; 4],
    pub object2: [f32; 4],
    pub info: [u32; 4],
    pub light: [u32; 4],
}

/// 48 bytes: vertex normals; `n0[3]` = the triangle's entry in the light buffer + 1 (0 if light selection never
/// picks it), `n1[3]` = area, `n2[3]` = the
/// placing instance's index in `Scene::instances` (u32 bits).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub struct TriShading {
    pub n0: [f32; 4],
    pub n1: [f32; 4],
    pub n2: [f32; 4],
}

/// 880 bytes. See `Material` in layout.glsl: base colour (w: alpha), emission (w: double-sided),
/// params (metallic, roughness, IOR, specular weight), specular colour (w: diffuse roughness), transmission (factor, thin), absorption,
/// alpha (mode bits, cutoff, normal scale, MATERIAL_* bits), clear coat (factor, roughness, normal scale), sheen
/// (colour, roughness), anisotropy (strength, cos and sin of the rotation), iridescence (factor, film IOR, thickness
/// minimum and maximum in nm), diffuse transmission (colour, factor), one texture slot per TEX_*, then the medium
/// inside (single-scattering albedo, Henyey-Greenstein g), and for spectral transport the base colour's and the
/// emission's RGB-to-spectrum coefficients.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub struct GpuMaterial {
    pub base_color: [f32; 4],
    pub emission: [f32; 4],
    pub params: [f32; 4],
    pub specular_color: [f32; 4],
    /// x factor, y 1 if thin-walled, z KHR_materials_dispersion (20 / Abbe number; 0 for thin walls), w
    /// KHR_materials_scatter's strength on a thin wall (0 in a volume).
    pub transmission: [f32; 4],
    pub attenuation: [f32; 4],
    pub alpha: [f32; 4],
    pub clearcoat: [f32; 4],
    pub sheen: [f32; 4],
    pub anisotropy: [f32; 4],
    pub iridescence: [f32; 4],
    pub diffuse_transmission: [f32; 4],
    pub textures: [TextureSlot; crate::constants::TEX_SLOTS as usize],
    /// KHR_materials_scatter: in a volume, rgb the medium's single-scattering albedo (0: absorption alone); on a thin
    /// wall, rgb the scattering's colour; w g.
    pub medium: [f32; 4],
    /// The sigmoid-of-quadratic coefficients (`spectrum::Tables::coefficients`) of the base colour factor, w 1 when
    /// it is not grey (a grey's spectrum is constant and needs none), so that a hit on an untextured colour reads
    /// three numbers instead of interpolating the table (spectrum.glsl's spectrum_reflectance_known).
    pub base_color_spectrum: [f32; 4],
    /// The same for the emission's colour over twice its largest component (spectrum_unbounded's normalisation, so
    /// that any strength keeps them), w 1 when the emission is neither zero nor grey.
    pub emission_spectrum: [f32; 4],
}

/// 32 bytes: a material's use of a texture. uv' = (u . (uv, 1), v . (uv, 1)); `u[3]` holds the texture index bits
/// (TEXTURE_NONE: unused slot), `v[3]` the TEXCOORD set bits.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub struct TextureSlot {
    pub u: [f32; 4],
    pub v: [f32; 4],
}

/// 16 bytes: where a texture's RGBA8 texels start in the texel buffer, its size, and TEXTURE_*/WRAP_* flags.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub struct GpuTexture {
    pub offset: u32,
    pub width: u32,
    pub height: u32,
    pub flags: u32,
}

/// 48 bytes per triangle: each vertex's TEXCOORD_0 (xy) and TEXCOORD_1 (zw).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub struct TriTexcoords {
    pub t0: [f32; 4],
    pub t1: [f32; 4],
    pub t2: [f32; 4],
}

/// 48 bytes per triangle: each vertex's COLOR_0 (linear RGBA).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub struct TriColors {
    pub c0: [f32; 4],
    pub c1: [f32; 4],
    pub c2: [f32; 4],
}

/// 48 bytes per triangle: each vertex's tangent (xyz) and bitangent sign (w).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub struct TriTangents {
    pub t0: [f32; 4],
    pub t1: [f32; 4],
    pub t2: [f32; 4],
}

/// 16 bytes, one per entry of light selection's table: an emissive triangle (world space), the environment, a
/// punctual light, or an instance of an emissive mesh; then each emissive instanced mesh's table of its triangles
/// (cdf and prob within the mesh, area in its space).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub struct GpuLight {
    pub id: u32,
    pub cdf: f32,
    pub prob: f32,
    pub area: f32,
}

/// 64 bytes: a node of the light BVH (`bvh::lights`; `LightNode` in layout.glsl), what importance reads of it.
/// `sphere`: the centre and radius of the sphere around the bounds; `cone`: the normal cone's axis and the power (W)
/// below the node; `angles`: cos and sin of the cone's half angle, cos of how far emission reaches past it, 0;
/// `link`: (first child, second child | LIGHT_NODE_TWO_SIDED, 0, 0) for an interior node, (LIGHT_NODE_LEAF,
/// LIGHT_NODE_TWO_SIDED or 0, the trail's low and high 32 bits) for a leaf. Record 0 is the header: `sphere.x` the
/// probability light selection descends the tree, `link` = (the root, the infinite lights' table's first entry in
/// the light buffer, its length, the emitters in the tree); the leaf of table entry j is record 1 + j. About 128
/// bytes per emitter.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub struct GpuLightNode {
    pub sphere: [f32; 4],
    pub cone: [f32; 4],
    pub angles: [f32; 4],
    pub link: [u32; 4],
}

/// 64 bytes: probe_light_select's query and answer (see `LightSelectRecord` in layout.glsl).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub struct LightSelectRecord {
    pub p: [f32; 3],
    pub entry: u32,
    pub n: [f32; 3],
    pub u: f32,
    pub v: f32,
    pub picked: u32,
    pub prob: f32,
    pub pmf: f32,
    pub sub_entry: u32,
    pub sub_picked: u32,
    pub pad0: u32,
    pub pad1: u32,
}

/// 48 bytes: a KHR_lights_punctual light (see `PunctualLight` in layout.glsl).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub struct GpuPunctual {
    pub position: [f32; 4],
    pub direction: [f32; 4],
    pub intensity: [f32; 4],
}

/// 64 bytes: queue counters, the indirect dispatch of the current bounce, ray tallies, whether a follow dispatch was
/// cut short (its pass is then run again by the wavefront), the samples film_add dropped as not finite, and the
/// wavefront stage invocations lavapipe's loop budget cut short (an error: their results are wrong).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub struct Counters {
    pub queue_count: [u32; 4],
    pub dispatch: [u32; 4],
    pub extension_rays: u32,
    pub shadow_rays: u32,
    pub follow_cut: u32,
    pub nonfinite: u32,
    pub stage_cut: u32,
    /// The largest budget plan.comp set (adaptive sampling): where the render can end.
    pub budget_max: u32,
    pub pad1: u32,
    pub pad2: u32,
}

/// 128 bytes: the push constants of every stage.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub struct Frame {
    pub cam_origin: [f32; 4],
    pub cam_right: [f32; 4],
    pub cam_up: [f32; 4],
    pub cam_forward: [f32; 4],
    pub width: u32,
    pub height: u32,
    pub sample_index: u32,
    pub seed: u32,
    pub bounce: u32,
    pub max_depth: u32,
    pub pass_pixels: u32,
    pub pixel_offset: u32,
    pub path_count: u32,
    pub path_capacity: u32,
    pub light_count: u32,
    pub flags: u32,
    pub env_prob: f32,
    pub env_rotation: f32,
    pub env_width: u32,
    pub env_height: u32,
}

/// 32 bytes: the tone-map stage's push constants (its own block inside the shared 128-byte range).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub struct ToneMap {
    pub film_width: u32,
    pub film_height: u32,
    pub out_width: u32,
    pub out_height: u32,
    /// Samples per pixel in the film (its sums are divided by this).
    pub samples: u32,
    /// TONEMAP_* curve, | TONEMAP_BGRA for BGRA byte order.
    pub op: u32,
    /// Linear scale before the curve: 2^stops.
    pub exposure: f32,
    pub pad: u32,
}

const _: () = assert!(std::mem::size_of::<ToneMap>() == 32);
const _: () = assert!(std::mem::size_of::<BvhNode>() == 48);
const _: () = assert!(std::mem::size_of::<TriVerts>() == 48);
const _: () = assert!(std::mem::size_of::<TriShading>() == 48);
const _: () = assert!(std::mem::size_of::<MotionKey>() == 96);
const _: () = assert!(std::mem::size_of::<GpuInstance>() == 128);
const _: () = assert!(std::mem::size_of::<GpuLightNode>() == 64);
const _: () = assert!(std::mem::size_of::<LightSelectRecord>() == 64);

/// 64 bytes: a pixel's AOV sums (survey.comp): albedo rgb and the samples added; the normal and the samples whose
/// camera ray hit; the first hit's position and its distance along the camera ray (summed over hits); the instance
/// and material of the first sample's first hit (AOV_NONE on a miss). See `AovSums` in layout.glsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub struct AovSums {
    pub albedo: [f32; 4],
    pub normal: [f32; 4],
    pub position: [f32; 4],
    pub ids: [u32; 4],
}
const _: () = assert!(std::mem::size_of::<AovSums>() == 64);

/// 48 bytes: a pixel's debug-view sums (survey.comp, FLAG_DEBUG_AOVS): the first hit's geometric normal and the
/// camera ray's traversal cost (child boxes tested), its shading normal and the chance next-event estimation picks
/// the light it found, and its TEXCOORD_0. See `DebugSums` in layout.glsl.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub struct DebugSums {
    pub geometric: [f32; 4],
    pub shading: [f32; 4],
    pub uv: [f32; 4],
}
const _: () = assert!(std::mem::size_of::<DebugSums>() == 48);
const _: () = assert!(std::mem::size_of::<MotionKey>() == 16 * crate::constants::MOTION_KEY_TEXELS as usize);
const _: () = assert!(crate::constants::MOTION_CAMERA_KEYS == crate::constants::MOTION_SEGMENTS + 1);
const _: () = assert!(std::mem::size_of::<GpuMaterial>() == 880);
const _: () =
    assert!(std::mem::offset_of!(GpuMaterial, medium) == 16 * crate::constants::MATERIAL_TEXEL_MEDIUM as usize);
const _: () = assert!(
    std::mem::offset_of!(GpuMaterial, base_color_spectrum) == 16 * crate::constants::MATERIAL_TEXEL_SPECTRA as usize
);
const _: () = assert!(std::mem::size_of::<GpuMaterial>() == 16 * crate::constants::MATERIAL_TEXELS as usize);
const _: () = assert!(std::mem::size_of::<TextureSlot>() == 32);
const _: () = assert!(std::mem::size_of::<GpuTexture>() == 16);
const _: () = assert!(std::mem::size_of::<TriTexcoords>() == 48);
const _: () = assert!(std::mem::size_of::<TriTangents>() == 48);
const _: () = assert!(std::mem::size_of::<TriColors>() == 48);
const _: () = assert!(std::mem::size_of::<GpuLight>() == 16);
const _: () = assert!(std::mem::size_of::<Counters>() == 64);
const _: () = assert!(std::mem::size_of::<GpuPunctual>() == 48);
const _: () = assert!(std::mem::size_of::<Frame>() == 128);

/// Byte offset of the indirect dispatch command inside `Counters`.
pub const COUNTERS_DISPATCH_OFFSET: u64 = std::mem::offset_of!(Counters, dispatch) as u64;

/// What the stages need of the camera: a world-space basis and its scalars.
#[derive(Clone, Copy, Debug)]
pub struct FrameCamera {
    pub origin: glam::Vec3,
    pub right: glam::Vec3,
    pub up: glam::Vec3,
    pub forward: glam::Vec3,
    /// Half the image plane's height (`Projection::half_height`): tan(yfov / 2) at distance 1, or an orthographic
    /// camera's ymag.
    pub half_height: f32,
    /// Width / height of the image.
    pub aspect: f32,
    /// Thin-lens radius; 0 is a pinhole.
    pub aperture: f32,
    /// Distance to the plane in focus along `forward`.
    pub focus_distance: f32,
}

/// Frame's fields mean one thing in the render stages; a few carry another meaning per stage, and these name each
/// use so no caller sets a field for what it is not (layout.glsl's accessors read them by the same names).
impl Frame {
    /// The camera's basis and scalars, which ride in the basis vectors' w (frame_aperture() and the others in
    /// layout.glsl read them back).
    pub fn with_camera(self, c: &FrameCamera) -> Frame {
        let v = |v: glam::Vec3, w: f32| [v.x, v.y, v.z, w];
        Frame {
            cam_origin: v(c.origin, c.half_height),
            cam_right: v(c.right, c.aspect),
            cam_up: v(c.up, c.aperture),
            cam_forward: v(c.forward, c.focus_distance),
            ..self
        }
    }

    /// The thin lens's aperture radius (cam_up.w); 0 is a pinhole.
    pub fn aperture(&self) -> f32 {
        self.cam_up[3]
    }

    /// The wavefront stages of `bounce`.
    pub fn at_bounce(&self, bounce: u32) -> Frame {
        Frame { bounce, ..*self }
    }

    /// queue_args after the last bounce: only the shadow-ray tally remains.
    pub fn after_last_bounce(&self) -> Frame {
        self.at_bounce(crate::constants::NO_HIT)
    }

    /// A follow dispatch over sample rows `first..end` (slots row * pass_pixels + pixel): `bounce` holds the first
    /// row, `path_count` the end.
    pub fn follow_rows(&self, first: u32, end: u32) -> Frame {
        Frame {
            bounce: first,
            path_count: end * self.pass_pixels,
            ..*self
        }
    }

    /// survey over sample row `row` of the pass (slots row * pass_pixels + pixel): `bounce` holds the row.
    pub fn survey_row(&self, row: u32) -> Frame {
        Frame { bounce: row, ..*self }
    }

    /// plan after a pilot of `pilot` samples per pixel: the relative standard error to reach, and the sample index
    /// the render ends at (`bounce`, `env_prob` and `path_count` hold them).
    pub fn plan(&self, pilot: u32, threshold: f32, end: u32) -> Frame {
        Frame {
            bounce: pilot,
            env_prob: threshold,
            path_count: end,
            ..*self
        }
    }

    /// A fused pass: follow keeps each pixel's running film sums, which accumulate copies (FLAG_FUSED_SUMS).
    pub fn with_fused_sums(&self) -> Frame {
        Frame {
            flags: self.flags | crate::constants::FLAG_FUSED_SUMS,
            ..*self
        }
    }

    /// A probe kernel over `count` records; `mode` (PROBE_SAMPLE, PROBE_EVALUATE, PROBE_ANY_HIT, ...) is in
    /// `bounce` (probe_mode() in layout.glsl).
    pub fn probe(count: u32, mode: u32) -> Frame {
        Frame {
            path_count: count,
            bounce: mode,
            ..Default::default()
        }
    }
}

/// 64 bytes: probe_trace's ray, with its time in the shutter, and the hit traversal found, with its instance (see
/// `TraceRecord` in layout.glsl).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub struct TraceRecord {
    pub origin: [f32; 3],
    pub tmin: f32,
    pub dir: [f32; 3],
    pub tmax: f32,
    pub time: f32,
    /// Out: the instance hit (NO_INSTANCE for a world-space triangle).
    pub inst: u32,
    /// The ray's key for stochastic transparency (alphaMode BLEND), in the probe_trace_alpha variants.
    pub key: u32,
    pub pad2: u32,
    pub t: f32,
    pub tri: u32,
    pub uv: [f32; 2],
}

/// 96 bytes: probe_bsdf's query and the BSDF's answer (see `BsdfRecord` in layout.glsl).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub struct BsdfRecord {
    pub wo: [f32; 3],
    pub material: u32,
    pub x: [f32; 3],
    pub front: u32,
    pub wi: [f32; 3],
    pub pdf: f32,
    pub weight: [f32; 3],
    /// PROBE_DELTA | PROBE_OK.
    pub flags: u32,
    pub eval: [f32; 3],
    pub pdf_wi: f32,
    pub eval_reverse: [f32; 3],
    pub pad0: u32,
}

/// 48 bytes: probe_env's query and the environment's answer (see `EnvRecord` in layout.glsl).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub struct EnvRecord {
    pub x: [f32; 3],
    pub pdf: f32,
    pub dir: [f32; 3],
    pub pdf_dir: f32,
    pub radiance: [f32; 3],
    pub pad0: u32,
}

const _: () = assert!(std::mem::size_of::<TraceRecord>() == 64);
const _: () = assert!(std::mem::size_of::<BsdfRecord>() == 96);
const _: () = assert!(std::mem::size_of::<EnvRecord>() == 48);

/// 48 bytes: probe_phase's query and Henyey-Greenstein's answer (see `PhaseRecord` in layout.glsl).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable, PartialEq)]
pub struct PhaseRecord {
    pub d_in: [f32; 3],
    pub g: f32,
    pub x: [f32; 3],
    pub pdf: f32,
    pub wi: [f32; 3],
    pub pad0: u32,
}

const _: () = assert!(std::mem::size_of::<PhaseRecord>() == 48);
