// The buffers, structs and push constants every stage shares; mirrored by src/layout.rs and checked by tests/layout.rs.
#ifndef LAYOUT_GLSL
#define LAYOUT_GLSL

#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_control_flow_attributes : require
#include "shared_constants.glsl"

// 48 bytes (3 texels): an interior node, holding its BVH_WIDTH children's boxes quantised to 8 bits per bound on a grid
// of origin + q * 2^(e - 127) per axis (the builder rounds outwards, so a decoded box holds the true one), and where the
// children are. A child's kind (3 bits): 0 an unused slot, 1 .. BVH_MAX_LEAF_TRIS a leaf of that many triangles,
// BVH_CHILD_INTERIOR an interior node. A node's interior children are consecutive nodes from its first node index, its
// leaves' triangles consecutive from its first triangle, both in slot order (traverse.glsl's child_entries turns that into
// stack entries). Node 0 is the root. One texel less than spelling out each child's word: each texel read is a call on
// lavapipe, and one more per traversal step cost the Cornell box 4.5 %.
struct BvhNode {
    uvec4 origin;   // xyz: f32 bits of the grid origin, w: biased exponents of x, y, z in bytes 0, 1, 2, kinds of
                    // children 0 and 1 in bits 24 and 27
    uvec4 q0;       // byte c of each word belongs to child c: lo.x, lo.y, lo.z, hi.x
    uvec4 q1;       // byte c of x, y: hi.y, hi.z of child c; z: first interior child << STACK_COUNT_BITS | kind of
                    // child 2; w: first triangle << STACK_COUNT_BITS | kind of child 3
};

// 48 bytes: precomputed edges for Moller-Trumbore. v0.w = material index (uint bits); e1.w = 1 when the material
// is alpha-tested (traversal evaluates its alpha at each candidate hit), else 0.
struct TriVerts {
    vec4 v0;
    vec4 e1;
    vec4 e2;
};

// 48 bytes: vertex normals. n0.w = 1 + the triangle's entry in the light buffer (light selection's table, or its
// mesh's table when instanced) as a float, 0 if light selection never picks it; n1.w = triangle area; n2.w = the index of the scene instance that placed
// it (uint bits; the instance-id AOV).
struct TriShading {
    vec4 n0;
    vec4 n1;
    vec4 n2;
};

// 96 bytes: one key of a moving triangle (vertex 0, the two edges, the three shading normals; every w 0), or of the
// camera (origin in v0, right, up and forward in e1, e2 and n0). Key 0 of a triangle is its TriVerts and TriShading.
struct MotionKey {
    vec4 v0;
    vec4 e1;
    vec4 e2;
    vec4 n0;
    vec4 n1;
    vec4 n2;
};

// 128 bytes: an instance of a mesh kept in object space: object-to-world and world-to-object as three rows each of a
// 3x4 affine map; info = (its BLAS root node, 1 when it mirrors, its index among the scene's instances, the record of
// its key 0 when it moves over the shutter, else 0); light = (the first entry of its mesh's emitter table in the
// light buffer, their count, the instance's entry in light selection's table, the root of its mesh's light subtree),
// zero for a mesh that does not emit. Record 0 is the header: info = (the TLAS root node, the instance count, the first BLAS
// triangle, 0). A moving instance's keys 0 ..= MOTION_SEGMENTS are whole records after the instances' (see
// instance_at).
struct Instance {
    vec4 world0;
    vec4 world1;
    vec4 world2;
    vec4 object0;
    vec4 object1;
    vec4 object2;
    uvec4 info;
    uvec4 light;
};

// 32 bytes: a material's use of a texture. The texture is sampled at (dot(u.xyz, vec3(uv, 1)), dot(v.xyz, vec3(uv, 1)))
// (KHR_texture_transform as an affine map); u.w: texture index (uint bits, TEXTURE_NONE if unused), v.w: TEXCOORD set.
struct TextureSlot {
    vec4 u;
    vec4 v;
};

// 880 bytes, the glTF material as the BSDF reads it; textures multiply the factors at each hit.
struct Material {
    vec4 base_color;     // rgb linear albedo / metal F0 / transmission tint, w: alpha (opacity under MASK and BLEND)
    vec4 emission;       // rgb radiance (W sr^-1 m^-2), w: 1 if double-sided
    vec4 params;         // x metallic, y roughness (perceptual: alpha = y^2), z IOR, w KHR_materials_specular weight
    vec4 specular_color; // rgb KHR_materials_specular colour factor, w KHR_materials_diffuse_roughness factor
    vec4 transmission;   // x KHR_materials_transmission factor, y 1 if thin-walled (no KHR_materials_volume), z
                         // KHR_materials_dispersion's 20 / Abbe number (0 when thin-walled), w KHR_materials_scatter's
                         // strength on a thin wall (0 in a volume)
    vec4 attenuation;    // rgb KHR_materials_volume absorption coefficient (1/m) inside the object, w unused
    vec4 alpha;          // x: ALPHA_* mode (uint bits), y: alphaCutoff, z: normalTexture scale, w: MATERIAL_* bits
    vec4 clearcoat;      // KHR_materials_clearcoat: x factor, y roughness (perceptual), z its normal map's scale, w unused
    vec4 sheen;          // KHR_materials_sheen: rgb colour, w roughness (perceptual)
    vec4 anisotropy;     // KHR_materials_anisotropy: x strength, yz its direction in tangent space (cos, sin), w unused
    vec4 iridescence;    // KHR_materials_iridescence: x factor, y the film's IOR, z and w its thickness range (nm); at
                         // a hit (material_at) w is the thickness there
    vec4 diffuse_transmission; // KHR_materials_diffuse_transmission: rgb colour, w factor
    TextureSlot textures[TEX_SLOTS]; // indexed by TEX_*
    vec4 medium;         // KHR_materials_scatter inside a volumetric object: rgb single-scattering albedo (the share of
                         // `attenuation` that scatters), w Henyey-Greenstein g (read by load_medium); on a thin wall,
                         // rgb its colour, w its g (read by load_material under FEATURE_THIN_SCATTER)
    vec4 base_color_spectrum; // spectral transport: xyz the RGB-to-spectrum coefficients of base_color.rgb, w 1 when
                              // it is not grey; material_at zeroes w where a texture or vertex colour changed it
    vec4 emission_spectrum;   // the same for emission.rgb over twice its largest component (w 1: neither zero nor grey)
};

// 16 bytes: a texture's texels[offset ..] (RGBA8, row 0 at the top), its size, and TEXTURE_* / WRAP_* flags.
struct TextureInfo {
    uint offset;
    uint width;
    uint height;
    uint flags;
};

// 48 bytes per triangle: per vertex, TEXCOORD_0 in xy and TEXCOORD_1 in zw.
struct TriTexcoords {
    vec4 t0;
    vec4 t1;
    vec4 t2;
};

// 48 bytes per triangle: per vertex, COLOR_0 as linear RGBA (only bound when FLAG_VERTEX_COLORS is set).
struct TriColors {
    vec4 c0;
    vec4 c1;
    vec4 c2;
};

// 48 bytes per triangle: per vertex, the tangent in xyz and the bitangent's sign in w (glTF: b = cross(n, t) * w).
struct TriTangents {
    vec4 t0;
    vec4 t1;
    vec4 t2;
};

// 16 bytes, one per light (emissive triangle or environment); cdf is the inclusive upper end. id: the kind in
// the top bits (LIGHT_KIND_*), the index below (the triangle for a triangle light). area is 0 for the environment.
struct Light {
    uint id;
    float cdf;
    float prob;
    float area;
};

// 64 bytes: a node of the light BVH (GpuLightNode in src/layout.rs says what each word holds). Record 0 is the
// header; the leaf of light-table entry j is record 1 + j.
struct LightNode {
    vec4 sphere;
    vec4 cone;
    vec4 angles;
    uvec4 link;
};

// 48 bytes, a KHR_lights_punctual light in world space. position.w: PUNCTUAL_* type (uint bits);
// direction: where it points (spot, directional), w: cos(outer cone); intensity: rgb radiant intensity (W/sr) for point
// and spot lights, irradiance (W/m^2) for directional ones, w: cos(inner cone).
struct PunctualLight {
    vec4 position;
    vec4 direction;
    vec4 intensity;
};

// 64 bytes. queue_count: 0/1 ray queues (ping-pong), 2 shadow queue, 3 unused.
// dispatch xyz is a VkDispatchIndirectCommand for the current bounce's stages. follow_cut: nonzero when a follow
// dispatch's loops were cut short (follow.comp), and accumulate then leaves the film alone. nonfinite: samples
// film_add dropped this pass (not finite, or beyond SAMPLE_RADIANCE_MAX).
struct Counters {
    uint queue_count[4];
    uint dispatch[4];
    uint extension_rays;
    uint shadow_rays;
    uint follow_cut;
    uint nonfinite;
    uint stage_cut; // wavefront stage invocations whose loops lavapipe's loop budget cut (check_loop_budget)
    uint budget_max; // the largest budget plan.comp set (adaptive sampling)
    uint pad1;
    uint pad2;
};

// 128 bytes, the guaranteed push-constant budget. The camera basis vectors are in world space.
struct Frame {
    vec4 cam_origin;   // w: tan(yfov / 2)
    vec4 cam_right;    // w: aspect (width / height)
    vec4 cam_up;       // w: thin-lens aperture radius (0: a pinhole)
    vec4 cam_forward;  // w: focus distance along the view direction
    uint width;
    uint height;
    uint sample_index;
    uint seed;
    uint bounce;
    uint max_depth;
    uint pass_pixels;  // pixels per sample in this pass: path i is pixel pixel_offset + i % pass_pixels,
                       // sample sample_index + i / pass_pixels
    uint pixel_offset;
    uint path_count;
    uint path_capacity;
    uint light_count;
    uint flags;        // FLAG_* bits
    float env_prob;    // probability that light selection picks the environment (0 without one)
    float env_rotation; // radians about +y
    uint env_width;    // environment map size; 0 means no environment
    uint env_height;
};

layout(push_constant) uniform PushConstants { Frame frame; };
// The camera's scalars ride in the basis vectors' w (Frame::with_camera in src/layout.rs writes them).
float frame_half_height() { return frame.cam_origin.w; }
float frame_aspect() { return frame.cam_right.w; }
float frame_aperture() { return frame.cam_up.w; }
float frame_focus_distance() { return frame.cam_forward.w; }

// FEATURE_* bits of what the scene uses (see src/constants.rs): a specialisation constant, so code behind a cleared bit
// is folded away when the pipeline is built. Every bit is set unless the host says otherwise.
layout(constant_id = SPEC_SCENE_FEATURES) const uint SCENE_FEATURES = FEATURES_ALL;
bool scene_has(uint features) { return (SCENE_FEATURES & features) != 0u; }

layout(std430, set = 0, binding = BINDING_NODES) readonly buffer Nodes { BvhNode nodes[]; };
layout(std430, set = 0, binding = BINDING_TRI_VERTS) readonly buffer TriVertsBuf { TriVerts tri_verts[]; };
layout(std430, set = 0, binding = BINDING_TRI_SHADING) readonly buffer TriShadingBuf { TriShading tri_shading[]; };
layout(std430, set = 0, binding = BINDING_MATERIALS) readonly buffer Materials { Material materials[]; };
layout(std430, set = 0, binding = BINDING_LIGHTS) readonly buffer Lights { Light lights[]; };
layout(std430, set = 0, binding = BINDING_LIGHT_TREE) readonly buffer LightTree { LightNode light_nodes[]; };
layout(std430, set = 0, binding = BINDING_PATHS) buffer Paths { vec4 paths[]; };
layout(std430, set = 0, binding = BINDING_QUEUES) buffer Queues { uint queues[]; };
layout(std430, set = 0, binding = BINDING_COUNTERS) buffer CountersBuf { Counters counters; };
// Film: [0, pixels) running sum of samples, [pixels, 2 * pixels) running sum of squares.
layout(std430, set = 0, binding = BINDING_FILM) buffer Film { vec4 film[]; };
// Adds sample radiance l to a pixel's running film sums (rgb sum and sample count in w; sum of squares). accumulate
// and follow both add through here, in sample order, which is what makes their film bytes the same.
// A sample that is not finite, or so large its square could overflow the sums, would spoil the pixel for good: it
// is counted and added as a sample of zero. Zero, not skipped, so the count in w stays the spp every pixel is
// divided by, and both schedules (which both add here) agree on it. The test is on the bits (|l| above the limit,
// which Inf and NaN are too), so no float arithmetic changes and finite samples give the same bytes as before.
// Returns 1 for a dropped sample, which the caller tallies into counters.nonfinite once per invocation: an atomic
// per sample, under lavapipe's mask, would run in follow's innermost loop.
uint film_add(inout vec4 sum, inout vec4 sum_sq, vec3 l) {
    uint dropped = 0u;
    if (any(greaterThan(floatBitsToUint(l) & 0x7fffffffu, uvec3(floatBitsToUint(SAMPLE_RADIANCE_MAX))))) {
        dropped = 1u;
        l = vec3(0.0);
    }
    sum += vec4(l, 1.0);
    sum_sq += vec4(l * l, 0.0);
    return dropped;
}
// The probe kernels' records (one per invocation, inputs then outputs) live at BINDING_PROBE, each kernel declaring
// the buffer with its own record type; the records are here so tests/layout.rs checks them against src/layout.rs.

// 64 bytes: probe_trace's ray (with its time in the shutter, for moving scenes) and the hit traversal found (t, tri
// NO_HIT on a miss, barycentrics).
struct TraceRecord {
    vec3 origin;
    float tmin;
    vec3 dir;
    float tmax;
    float time;
    uint inst;     // out: the instance hit (NO_INSTANCE for a world-space triangle)
    uint key;      // the ray's key for stochastic transparency, in the _alpha variants
    uint pad2;
    float t;
    uint tri;
    vec2 uv;
};

// 96 bytes: probe_bsdf's query (material, wo, the three uniforms or wi, whether wo is outside) and what the BSDF
// answered: the sampled (or given) wi with the pdf of sampling it, f cos / pdf with PROBE_DELTA | PROBE_OK, f(wo, wi)
// with pdf(wo, wi), and f(wi, wo).
struct BsdfRecord {
    vec3 wo;
    uint material;
    vec3 x;
    uint front;
    vec3 wi;
    float pdf;
    vec3 weight;
    uint flags;
    vec3 eval;
    float pdf_wi;
    vec3 eval_reverse;
    uint pad0;
};

// 48 bytes: probe_env's uniforms (xy) or direction, and the sampled or given direction with the pdf of sampling it,
// the pdf of the direction, and the radiance from it.
struct EnvRecord {
    vec3 x;
    float pdf;
    vec3 dir;
    float pdf_dir;
    vec3 radiance;
    uint pad0;
};

// 48 bytes: probe_phase's query (the propagation direction before scattering, g, and in x the uniforms (xy) to sample
// with or the direction to evaluate) and Henyey-Greenstein's answer: the direction and the phase function there.
struct PhaseRecord {
    vec3 d_in;
    float g;
    vec3 x;
    float pdf;
    vec3 wi;
    uint pad0;
};

// 64 bytes: probe_light_select's point, receiver normal and uniforms, the table entry whose pdf it asks for (and
// for an instance, sub_entry: its mesh's emitter, or LIGHT_NONE for the instance's pick alone), and what light
// selection answered: the entry picked (LIGHT_NONE: nothing can light p) and the emitter picked within it for an
// instance (sub_picked, else LIGHT_NONE), their probability, the entry's (and sub-entry's) pmf.
struct LightSelectRecord {
    vec3 p;
    uint entry;
    vec3 n;
    float u;
    float v;
    uint picked;
    float prob;
    float pmf;
    uint sub_entry;
    uint sub_picked;
    uint pad0;
    uint pad1;
};

// What Frame.bounce means to a probe kernel: PROBE_SAMPLE or PROBE_EVALUATE (PROBE_ANY_HIT for probe_trace).
uint probe_mode() { return frame.bounce; }
// probe_rand's dimension rides in Frame.max_depth.
uint probe_dimension() { return frame.max_depth; }
// A follow dispatch's first sample row rides in Frame.bounce (Frame::follow_rows).
uint follow_first_row() { return frame.bounce; }
// survey's sample row (Frame::survey_row).
uint survey_row() { return frame.bounce; }
// plan's parameters (Frame::plan): the pilot's samples per pixel, the noise threshold, the render's sample end.
uint plan_pilot() { return frame.bounce; }
float plan_threshold() { return frame.env_prob; }
uint plan_end() { return frame.path_count; }
// Microfacet energy tables (see ENERGY_* in src/constants.rs); written once at start-up by energy_tables.comp.
layout(std430, set = 0, binding = BINDING_ENERGY) buffer Energy { float energy[]; };
// Environment: rgba texels (w unused) row by row from the top (+y), then the marginal cdf over rows
// (env_height + 1 values), then each row's conditional cdf (env_width + 1 values), all inclusive-start at 0.
layout(std430, set = 0, binding = BINDING_ENV) readonly buffer Env { float env[]; };
layout(std430, set = 0, binding = BINDING_PUNCTUAL) readonly buffer Punctuals { PunctualLight punctuals[]; };
// Textures are texels in one storage buffer, not images: lavapipe has no descriptor indexing, and a buffer works
// for any number and size of textures on every Vulkan device (filtering and wrapping are done in textures.glsl).
layout(std430, set = 0, binding = BINDING_TEXTURES) readonly buffer Textures { TextureInfo textures[]; };
layout(std430, set = 0, binding = BINDING_TEXELS) readonly buffer Texels { uint texels[]; };
layout(std430, set = 0, binding = BINDING_TRI_TEXCOORDS) readonly buffer TriTexcoordsBuf { TriTexcoords tri_texcoords[]; };
layout(std430, set = 0, binding = BINDING_TRI_TANGENTS) readonly buffer TriTangentsBuf { TriTangents tri_tangents[]; };
layout(std430, set = 0, binding = BINDING_TRI_COLORS) readonly buffer TriColorsBuf { TriColors tri_colors[]; };
layout(std430, set = 0, binding = BINDING_MOTION) readonly buffer MotionBuf { MotionKey motion_keys[]; };
layout(std430, set = 0, binding = BINDING_INSTANCES) readonly buffer InstancesBuf { Instance instances[]; };
// 64 bytes: a pixel's AOV sums over the samples survey has added, in sample order. albedo: rgb, and w the samples
// added; normal: xyz (zero where a sample saw no surface), w the samples whose camera ray hit something; position:
// the first hit's xyz, w its distance along the camera ray (both over hitting samples); ids: the instance and the
// material of the first sample's first hit (AOV_NONE on a miss), zw unused.
struct AovSums {
    vec4 albedo;
    vec4 normal;
    vec4 position;
    uvec4 ids;
};
layout(std430, set = 0, binding = BINDING_AOVS) buffer AovBuf { AovSums aovs[]; };
// 48 bytes: a pixel's debug views, summed over the samples survey added (FLAG_DEBUG_AOVS) at each camera ray's first
// hit: geometric: the geometric normal (xyz, facing the ray) and the child boxes traversal tested for the camera ray
// (w, misses too); shading: the shading normal (xyz) and the chance next-event estimation picks the light the ray
// found (w: an emitter's or the environment's share of the light table); uv: TEXCOORD_0 (xy; zero where the scene
// keeps no texture coordinates), zw unused.
struct DebugSums {
    vec4 geometric;
    vec4 shading;
    vec4 uv;
};
layout(std430, set = 0, binding = BINDING_DEBUG_AOVS) buffer DebugBuf { DebugSums debug_aovs[]; };
// Adaptive sampling's budgets: per pixel the sample index it samples below.
layout(std430, set = 0, binding = BINDING_BUDGET) buffer BudgetBuf { uint budget[]; };
// Whether pixel takes sample s: always, unless the render is adaptive and s is past the pixel's budget.
bool sample_taken(uint pixel, uint s) {
    return !scene_has(FEATURE_ADAPTIVE) || s < budget[pixel];
}
// A budget's bucket (render::order_bucket's twin): the budget itself below 8, then eight buckets per octave.
uint order_bucket(uint n) {
    if (n < 8u) return n;
    int m = findMSB(n);
    return 8u * uint(m - 2) + ((n >> uint(m - 3)) & 7u);
}

// Per-triangle data, BVH nodes and image texels as texel views (TEXEL_READS variants), the same bytes as the storage
// buffers above: scene_reads.glsl reads both, and every stage reads the scene through its functions.
#ifdef TEXEL_READS
layout(set = 0, binding = BINDING_NODE_TEXELS) uniform usamplerBuffer node_texels;
layout(set = 0, binding = BINDING_TRI_TEXELS) uniform usamplerBuffer tri_texels;
layout(set = 0, binding = BINDING_TRI_SHADING_TEXELS) uniform usamplerBuffer tri_shading_texels;
layout(set = 0, binding = BINDING_TRI_TEXCOORD_TEXELS) uniform usamplerBuffer tri_texcoord_texels;
layout(set = 0, binding = BINDING_TRI_TANGENT_TEXELS) uniform usamplerBuffer tri_tangent_texels;
layout(set = 0, binding = BINDING_TRI_COLOR_TEXELS) uniform usamplerBuffer tri_color_texels;
layout(set = 0, binding = BINDING_IMAGE_TEXELS) uniform usamplerBuffer image_texels;
layout(set = 0, binding = BINDING_MATERIAL_TEXELS) uniform usamplerBuffer material_texels;
layout(set = 0, binding = BINDING_LIGHT_TEXELS) uniform usamplerBuffer light_texels;
layout(set = 0, binding = BINDING_LIGHT_TREE_TEXELS) uniform usamplerBuffer light_tree_texels;
layout(set = 0, binding = BINDING_MOTION_TEXELS) uniform usamplerBuffer motion_texels;
layout(set = 0, binding = BINDING_CIE_TEXELS) uniform samplerBuffer cie_texels;
#endif

// The pass's i-th pixel: in image order, or after adaptive sampling's plan in the order of their budgets
// (FLAG_PIXEL_ORDER).
// In the order, workgroups alternate between the ends of the ranking (the first takes the largest budgets, the second
// the smallest, and so on), so that a device handing each thread a contiguous run of workgroups (lavapipe) gives
// each about as much work; invocations of one workgroup keep neighbouring ranks, so a subgroup's budgets stay alike.
// A bijection on the pass's pixels: the last partial workgroup keeps its place.
uint pass_pixel(uint i) {
    if (scene_has(FEATURE_ADAPTIVE) && (frame.flags & FLAG_PIXEL_ORDER) != 0u) {
        uint full = frame.pass_pixels / WORKGROUP_SIZE;
        uint group = i / WORKGROUP_SIZE;
        if (group < full) {
            group = (group & 1u) == 0u ? group / 2u : full - 1u - group / 2u;
            i = group * WORKGROUP_SIZE + i % WORKGROUP_SIZE;
        }
        return budget[frame.width * frame.height + frame.pixel_offset + i];
    }
    return frame.pixel_offset + i;
}
uint path_pixel(uint path) { return pass_pixel(path % frame.pass_pixels); }
uint path_sample(uint path) { return frame.sample_index + path / frame.pass_pixels; }
uint frame_estimator() { return (frame.flags >> ESTIMATOR_SHIFT) & 3u; }

// A stage reads a path's field before it writes it, never after: the texel view need not see the stage's own writes.
#ifdef TEXEL_READS
layout(set = 0, binding = BINDING_PATH_TEXELS) uniform samplerBuffer path_texels;
vec4 path_get(uint field, uint path) { return texelFetch(path_texels, int(field * frame.path_capacity + path)); }
#else
vec4 path_get(uint field, uint path) { return paths[field * frame.path_capacity + path]; }
#endif
void path_set(uint field, uint path, vec4 v) { paths[field * frame.path_capacity + path] = v; }

#endif
