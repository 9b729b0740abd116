// Reads of the scene's buffers (layout.glsl declares them): per-triangle data, BVH nodes, materials, lights and
// image texels through texel views (TEXEL_READS variants) or storage buffers, the same bytes either way; and where
// things are at the ray's time in the shutter (triangles' motion keys, instances' transforms).
#ifndef SCENE_READS_GLSL
#define SCENE_READS_GLSL

#include "layout.glsl"

#ifdef TEXEL_READS
#define FETCH(view, k) uintBitsToFloat(texelFetch(view, int(k)))
#define FETCH3(view, i) FETCH(view, 3u * (i)), FETCH(view, 3u * (i) + 1u), FETCH(view, 3u * (i) + 2u)
Light load_light(uint i) {
    uvec4 t = texelFetch(light_texels, int(i));
    return Light(t.x, uintBitsToFloat(t.y), uintBitsToFloat(t.z), uintBitsToFloat(t.w));
}
Material load_material(uint i) {
    uint b = MATERIAL_TEXELS * i;
    Material m;
    m.base_color = FETCH(material_texels, b);
    m.emission = FETCH(material_texels, b + 1u);
    m.params = FETCH(material_texels, b + 2u);
    m.specular_color = FETCH(material_texels, b + 3u);
    m.transmission = FETCH(material_texels, b + 4u);
    m.attenuation = FETCH(material_texels, b + 5u);
    m.alpha = FETCH(material_texels, b + 6u);
    m.clearcoat = FETCH(material_texels, b + 7u);
    m.sheen = FETCH(material_texels, b + 8u);
    m.anisotropy = FETCH(material_texels, b + 9u);
    m.iridescence = FETCH(material_texels, b + 10u);
    m.diffuse_transmission = FETCH(material_texels, b + 11u);
    // The thin wall's scattering slots come last and are read only where a material has it.
    uint slots = scene_has(FEATURE_THIN_SCATTER) ? TEX_SLOTS : TEX_SCATTER_STRENGTH;
    for (uint k = 0u; k < slots; ++k) {
        m.textures[k] = TextureSlot(FETCH(material_texels, b + 12u + 2u * k), FETCH(material_texels, b + 13u + 2u * k));
    }
    // Shading at a surface never needs the medium behind it: one texel read fewer per hit, but for a thin wall's
    // scattering.
    m.medium = scene_has(FEATURE_THIN_SCATTER) ? FETCH(material_texels, b + MATERIAL_TEXEL_MEDIUM) : vec4(0.0);
    m.base_color_spectrum = scene_has(FEATURE_SPECTRAL) ? FETCH(material_texels, b + MATERIAL_TEXEL_SPECTRA) : vec4(0.0);
    m.emission_spectrum = scene_has(FEATURE_SPECTRAL) ? FETCH(material_texels, b + MATERIAL_TEXEL_SPECTRA + 1u) : vec4(0.0);
    return m;
}
// The medium inside material i (KHR_materials_volume, with KHR_materials_scatter): its extinction (1/m) and, in
// albedo_g, the single-scattering albedo and Henyey-Greenstein g.
void load_medium(uint i, out vec3 sigma_t, out vec4 albedo_g) {
    uint b = MATERIAL_TEXELS * i;
    sigma_t = FETCH(material_texels, b + 5u).rgb;
    albedo_g = FETCH(material_texels, b + MATERIAL_TEXEL_MEDIUM);
}
BvhNode load_node(uint i) {
    return BvhNode(texelFetch(node_texels, int(3u * i)), texelFetch(node_texels, int(3u * i + 1u)),
                   texelFetch(node_texels, int(3u * i + 2u)));
}
TriVerts fetch_tri_verts(uint i) { return TriVerts(FETCH3(tri_texels, i)); }
MotionKey fetch_motion_key(uint i) {
    uint b = MOTION_KEY_TEXELS * i;
    return MotionKey(FETCH(motion_texels, b), FETCH(motion_texels, b + 1u), FETCH(motion_texels, b + 2u),
                     FETCH(motion_texels, b + 3u), FETCH(motion_texels, b + 4u), FETCH(motion_texels, b + 5u));
}
TriShading fetch_tri_shading(uint i) { return TriShading(FETCH3(tri_shading_texels, i)); }
TriTexcoords load_tri_texcoords(uint i) { return TriTexcoords(FETCH3(tri_texcoord_texels, i)); }
TriTangents load_tri_tangents(uint i) { return TriTangents(FETCH3(tri_tangent_texels, i)); }
TriColors load_tri_colors(uint i) { return TriColors(FETCH3(tri_color_texels, i)); }
uint load_image_texel(uint i) { return texelFetch(image_texels, int(i)).x; }
vec4 light_node_sphere(uint i) { return FETCH(light_tree_texels, 4u * i); }
vec4 light_node_cone(uint i) { return FETCH(light_tree_texels, 4u * i + 1u); }
vec4 light_node_angles(uint i) { return FETCH(light_tree_texels, 4u * i + 2u); }
uvec4 light_node_link(uint i) { return texelFetch(light_tree_texels, int(4u * i + 3u)); }
#else
vec4 light_node_sphere(uint i) { return light_nodes[i].sphere; }
vec4 light_node_cone(uint i) { return light_nodes[i].cone; }
vec4 light_node_angles(uint i) { return light_nodes[i].angles; }
uvec4 light_node_link(uint i) { return light_nodes[i].link; }
Light load_light(uint i) { return lights[i]; }
Material load_material(uint i) { return materials[i]; }
void load_medium(uint i, out vec3 sigma_t, out vec4 albedo_g) {
    sigma_t = materials[i].attenuation.rgb;
    albedo_g = materials[i].medium;
}
BvhNode load_node(uint i) { return nodes[i]; }
TriVerts fetch_tri_verts(uint i) { return tri_verts[i]; }
MotionKey fetch_motion_key(uint i) { return motion_keys[i]; }
TriShading fetch_tri_shading(uint i) { return tri_shading[i]; }
TriTexcoords load_tri_texcoords(uint i) { return tri_texcoords[i]; }
TriTangents load_tri_tangents(uint i) { return tri_tangents[i]; }
TriColors load_tri_colors(uint i) { return tri_colors[i]; }
uint load_image_texel(uint i) { return texels[i]; }
#endif

// The ray's time in the shutter, in [0, 1): one per camera sample (motion_begin in rng.glsl), for every ray of its
// path; 0 where nothing moves.
float motion_time = 0.0;

// The segment of the shutter holding motion_time, and how far into it the time is.
void motion_segment(out uint k, out float f) {
    float x = motion_time * float(MOTION_SEGMENTS);
    k = min(uint(x), MOTION_SEGMENTS - 1u);
    f = x - float(k);
}

MotionKey motion_key(uint tri, uint k) { return fetch_motion_key(MOTION_CAMERA_KEYS + tri * MOTION_SEGMENTS + k - 1u); }

// a + (b - a) f: exactly a where a key repeats (a static triangle in a moving scene), unlike mix.
vec3 toward(vec3 a, vec3 b, float f) { return a + (b - a) * f; }

// The keys of triangle i on either side of motion_time (b after it, a before it unless that is key 0, which the
// triangle buffers hold: then false) and how far between them the time is.
bool motion_span(uint i, out MotionKey a, out MotionKey b, out float f) {
    uint k;
    motion_segment(k, f);
    b = motion_key(i, k + 1u);
    if (k > 0u) a = motion_key(i, k);
    return k > 0u;
}

// Whether triangle i is a world triangle with keys of its own (an instanced mesh's triangles, from the header's first
// BLAS triangle on, move only with their instances).
bool tri_moves(uint i) {
    return !scene_has(FEATURE_INSTANCES) || i < instances[0].info.z;
}

// Triangle i at motion_time: its keys on either side, linearly between them (its w's, which do not move, from key 0).
TriVerts load_tri_verts(uint i) {
    TriVerts tv = fetch_tri_verts(i);
    if (scene_has(FEATURE_MOTION) && tri_moves(i)) {
        MotionKey a, b;
        float f;
        vec3 v0 = tv.v0.xyz, e1 = tv.e1.xyz, e2 = tv.e2.xyz;
        if (motion_span(i, a, b, f)) {
            v0 = a.v0.xyz;
            e1 = a.e1.xyz;
            e2 = a.e2.xyz;
        }
        tv.v0.xyz = toward(v0, b.v0.xyz, f);
        tv.e1.xyz = toward(e1, b.e1.xyz, f);
        tv.e2.xyz = toward(e2, b.e2.xyz, f);
    }
    return tv;
}

// Triangle i's shading data at motion_time, given its vertices then (tv, from load_tri_verts): normals between its
// keys and its area then (which light sampling's density per unit area divides by).
TriShading load_tri_shading(uint i, TriVerts tv) {
    TriShading ts = fetch_tri_shading(i);
    if (scene_has(FEATURE_MOTION) && tri_moves(i)) {
        MotionKey a, b;
        float f;
        vec3 n0 = ts.n0.xyz, n1 = ts.n1.xyz, n2 = ts.n2.xyz;
        if (motion_span(i, a, b, f)) {
            n0 = a.n0.xyz;
            n1 = a.n1.xyz;
            n2 = a.n2.xyz;
        }
        float area = 0.5 * length(cross(tv.e1.xyz, tv.e2.xyz));
        ts.n0.xyz = toward(n0, b.n0.xyz, f);
        ts.n1 = vec4(toward(n1, b.n1.xyz, f), area);
        ts.n2.xyz = toward(n2, b.n2.xyz, f);
    }
    return ts;
}

// An instance's affine maps as three rows (x, y, z): a point, and a vector (the translation left out).
vec3 rows_point(vec4 r0, vec4 r1, vec4 r2, vec3 p) {
    return vec3(dot(r0.xyz, p) + r0.w, dot(r1.xyz, p) + r1.w, dot(r2.xyz, p) + r2.w);
}
vec3 rows_vector(vec4 r0, vec4 r1, vec4 r2, vec3 v) { return vec3(dot(r0.xyz, v), dot(r1.xyz, v), dot(r2.xyz, v)); }
// A normal into the world: by the inverse transpose, the world-to-object rows transposed.
vec3 instance_normal(Instance inst, vec3 n) {
    return inst.object0.xyz * n.x + inst.object1.xyz * n.y + inst.object2.xyz * n.z;
}

// The inverse of the affine map with rows r (o, as rows): the inverse's columns are the rows' cross products over
// the determinant (written out: naga's SPIR-V reader, which tests/layout.rs uses, has no matrix inverse).
void inverse_rows(vec4 r0, vec4 r1, vec4 r2, out vec4 o0, out vec4 o1, out vec4 o2) {
    vec3 c0 = cross(r1.xyz, r2.xyz), c1 = cross(r2.xyz, r0.xyz), c2 = cross(r0.xyz, r1.xyz);
    float inv_det = 1.0 / dot(r0.xyz, c0);
    vec3 a0 = vec3(c0.x, c1.x, c2.x) * inv_det;
    vec3 a1 = vec3(c0.y, c1.y, c2.y) * inv_det;
    vec3 a2 = vec3(c0.z, c1.z, c2.z) * inv_det;
    vec3 t = vec3(r0.w, r1.w, r2.w);
    o0 = vec4(a0, -dot(a0, t));
    o1 = vec4(a1, -dot(a1, t));
    o2 = vec4(a2, -dot(a2, t));
}

// An instanced triangle (in its mesh's space) in the world, as instance I places it (w's kept).
TriVerts tri_to_world(Instance I, TriVerts tv) {
    tv.v0.xyz = rows_point(I.world0, I.world1, I.world2, tv.v0.xyz);
    tv.e1.xyz = rows_vector(I.world0, I.world1, I.world2, tv.e1.xyz);
    tv.e2.xyz = rows_vector(I.world0, I.world1, I.world2, tv.e2.xyz);
    return tv;
}

// Spherical linear interpolation from a to b (dot(a, b) >= 0, as the host stores consecutive keys): a turn about one
// axis at a constant rate; the normalised blend where the angle is too small for 1/sin (src/bvh/motion.rs's slerp).
const float SLERP_LINEAR = 0.9995;
vec4 slerp(vec4 a, vec4 b, float f) {
    float c = min(dot(a, b), 1.0);
    if (c > SLERP_LINEAR) return normalize(mix(a, b, f));
    float theta = acos(c);
    return (a * sin((1.0 - f) * theta) + b * sin(f * theta)) / sin(theta);
}

// Instance record i placed at motion_time: a moving one's keys on either side (records info.w + k and + k + 1)
// interpolated. Keys that decompose (object0.w = 1: translation in object0, the rotation's quaternion (x, y, z, w)
// in object1, scale in object2) go as pbrt-v4's and Cycles' do, translation and scale linearly and rotation by
// slerp, so a turning instance keeps its size; other keys (shear) have their object-to-world rows interpolated,
// which moves each point linearly between its places at the keys. World-to-object is the inverse of the map so
// made (interpolating the keys' inverses would not undo it).
Instance instance_at(uint i) {
    Instance I = instances[i];
    if (scene_has(FEATURE_MOTION) && I.info.w != 0u) {
        uint k;
        float f;
        motion_segment(k, f);
        Instance a = instances[I.info.w + k];
        Instance b = instances[I.info.w + k + 1u];
        if (a.object0.w != 0.0) {
            vec3 t = toward(a.object0.xyz, b.object0.xyz, f);
            vec4 q = slerp(a.object1, b.object1, f);
            vec3 s = toward(a.object2.xyz, b.object2.xyz, f);
            // Rows of T R S: the rotation matrix's rows with each column scaled by s.
            float xx = q.x * q.x, yy = q.y * q.y, zz = q.z * q.z;
            float xy = q.x * q.y, xz = q.x * q.z, yz = q.y * q.z;
            float wx = q.w * q.x, wy = q.w * q.y, wz = q.w * q.z;
            I.world0 = vec4(vec3(1.0 - 2.0 * (yy + zz), 2.0 * (xy - wz), 2.0 * (xz + wy)) * s, t.x);
            I.world1 = vec4(vec3(2.0 * (xy + wz), 1.0 - 2.0 * (xx + zz), 2.0 * (yz - wx)) * s, t.y);
            I.world2 = vec4(vec3(2.0 * (xz - wy), 2.0 * (yz + wx), 1.0 - 2.0 * (xx + yy)) * s, t.z);
        } else {
            I.world0 = a.world0 + (b.world0 - a.world0) * f;
            I.world1 = a.world1 + (b.world1 - a.world1) * f;
            I.world2 = a.world2 + (b.world2 - a.world2) * f;
        }
        inverse_rows(I.world0, I.world1, I.world2, I.object0, I.object1, I.object2);
    }
    return I;
}

#endif
