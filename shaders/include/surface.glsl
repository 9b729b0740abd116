// A material at a hit point: glTF's factors times its textures at the hit's texture coordinates, and alpha testing.
// Textures and alpha apply only with TEXTURED defined (the shade_textured variant, used for scenes that have either):
// without it the factors alone are used, and the texture code is not compiled into the stage at all.
#ifndef SURFACE_GLSL
#define SURFACE_GLSL

#include "rng.glsl"
#include "textures.glsl"

bool slot_used(TextureSlot s) {
    return floatBitsToUint(s.u.w) != TEXTURE_NONE;
}

// log2 of the side of a pixel's footprint at p on a triangle of world-space edges e1, e2 (unit normal ng), per unit
// of the square root of the triangle's area: sample_slot turns it into texels with the triangle's area in the
// texture. The footprint is the camera's (pbrt-v4's approximation at every bounce): a pixel's angle times the
// distance from the camera (its width, orthographic), spread by the surface's slant (area-preserving: the side of a
// square of the ellipse's area, so a grazing floor blurs less than along its long axis), and divided by the sample
// index plus one: a pixel's first sample is prefiltered over the pixel (no shimmer at one sample), and over N
// samples the blur falls as log(N) / N, below the noise's 1 / sqrt(N), so converged images keep point sampling's
// expectation (a floor of an eighth of a pixel, as pbrt-v4 keeps, left a bias the statistical diff found at 256
// spp). It depends on the point and the sample index alone, so both schedules, every pass split and every bounce
// choose the same level. y: the number that picks between mip levels (texture_sample), a hash of the point and the sample
// index for the same reason. NO_LOD without FEATURE_TEXTURE_LOD.
vec2 texture_footprint(vec3 e1, vec3 e2, vec3 ng, vec3 p, uint s) {
    if (!scene_has(FEATURE_TEXTURE_LOD)) return NO_LOD;
    vec3 to = p - frame.cam_origin.xyz;
    float dist = length(to);
    float pixel = 2.0 * frame_half_height() / float(frame.height);
    float width = (frame.flags & FLAG_ORTHOGRAPHIC) != 0u ? pixel : pixel * dist;
    float slant = abs(dot(ng, to)) / max(dist, 1e-30);
    width *= inversesqrt(max(slant, 1e-4)) / (float(s) + 1.0);
    float area = 0.5 * length(cross(e1, e2));
    float f = log2(width) - 0.5 * log2(area);
    float u = float(pcg4d(uvec4(floatBitsToUint(p), s)).x >> 8u) * (1.0 / 16777216.0);
    // A degenerate triangle or a point at the camera: level 0.
    return abs(f) < 1e30 ? vec2(f, u) : NO_LOD;
}

// The slot's texture at barycentrics b (of vertices 1 and 2) of triangle tri, after KHR_texture_transform, at the
// hit's footprint (texture_footprint; NO_LOD: level 0).
vec4 sample_slot(TextureSlot s, uint tri, vec2 b, bool srgb, vec2 lod) {
    TriTexcoords tc = load_tri_texcoords(tri);
    vec4 w = (1.0 - b.x - b.y) * tc.t0 + b.x * tc.t1 + b.y * tc.t2;
    bool first = floatBitsToUint(s.v.w) == 0u;
    vec2 uv = first ? w.xy : w.zw;
    vec2 st = vec2(dot(s.u.xyz, vec3(uv, 1.0)), dot(s.v.xyz, vec3(uv, 1.0)));
    if (scene_has(FEATURE_TEXTURE_LOD) && lod.x > NO_FOOTPRINT) {
        // The triangle's area in the texture's uv units, after the transform (which scales areas by its determinant).
        vec2 d1 = first ? tc.t1.xy - tc.t0.xy : tc.t1.zw - tc.t0.zw;
        vec2 d2 = first ? tc.t2.xy - tc.t0.xy : tc.t2.zw - tc.t0.zw;
        float area = 0.5 * abs((d1.x * d2.y - d1.y * d2.x) * (s.u.x * s.v.y - s.u.y * s.v.x));
        lod.x += 0.5 * log2(area);
    }
    return texture_sample(floatBitsToUint(s.u.w), st, srgb, lod);
}

// COLOR_0 at the hit, white without vertex colours. Its alpha multiplies the material's under MASK and BLEND, as
// the base colour's does (glTF: COLOR_0 multiplies baseColorFactor, alpha included).
vec4 vertex_color(uint tri, vec2 b) {
    if ((frame.flags & FLAG_VERTEX_COLORS) == 0u) return vec4(1.0);
    TriColors c = load_tri_colors(tri);
    return (1.0 - b.x - b.y) * c.c0 + b.x * c.c1 + b.y * c.c2;
}

float material_alpha(Material m, uint tri, vec2 b) {
    float a = m.base_color.w * vertex_color(tri, b).a;
    if (slot_used(m.textures[TEX_BASE_COLOR])) a *= sample_slot(m.textures[TEX_BASE_COLOR], tri, b, true, NO_LOD).a;
    return a;
}

// How much of the surface is there: 1 or 0 under MASK, alpha under BLEND (which rays realise stochastically).
float material_coverage(Material m, uint tri, vec2 b) {
    uint mode = floatBitsToUint(m.alpha.x);
    if (mode == ALPHA_OPAQUE) return 1.0;
    float a = material_alpha(m, tri, b);
    if (mode == ALPHA_MASK) return a >= m.alpha.y ? 1.0 : 0.0;
    return clamp(a, 0.0, 1.0);
}

// Whether a ray stops at this candidate hit on an alpha-tested triangle. BLEND stops with probability alpha, decided
// by a hash of the ray's key and the triangle, so revisiting the triangle in one traversal gives the same answer.
bool alpha_stops(uint tri, vec2 b, uint key) {
    Material m = load_material(floatBitsToUint(load_tri_verts(tri).v0.w));
    float c = material_coverage(m, tri, b);
    if (c >= 1.0) return true;
    if (c <= 0.0) return false;
    uint h = pcg4d(uvec4(key, tri, 0x2545F491u, frame.seed)).x;
    return float(h >> 8u) * (1.0 / 16777216.0) < c;
}

// The material with its textures applied at the hit: base colour and alpha, metallic and roughness, emission; at
// the hit's footprint (texture_footprint), but emission always at level 0: light selection weighs each emitter by
// the level-0 texels its lookups can reach (emission.rs), and a light sample reads level 0 too.
Material material_at(Material m, uint tri, vec2 b, vec2 lod) {
#ifdef TEXTURED
    vec3 base_factor = m.base_color.rgb;
    vec3 emission_factor = m.emission.rgb;
    m.base_color.rgb *= vertex_color(tri, b).rgb;
    if (slot_used(m.textures[TEX_BASE_COLOR])) m.base_color *= sample_slot(m.textures[TEX_BASE_COLOR], tri, b, true, lod);
    if (slot_used(m.textures[TEX_METALLIC_ROUGHNESS])) {
        vec4 mr = sample_slot(m.textures[TEX_METALLIC_ROUGHNESS], tri, b, false, lod);
        m.params.x *= mr.b;
        m.params.y *= mr.g;
    }
    if (slot_used(m.textures[TEX_EMISSIVE])) m.emission.rgb *= sample_slot(m.textures[TEX_EMISSIVE], tri, b, true, NO_LOD).rgb;
    if (scene_has(FEATURE_COAT)) {
        if (slot_used(m.textures[TEX_SPECULAR])) m.params.w *= sample_slot(m.textures[TEX_SPECULAR], tri, b, false, lod).a;
        if (slot_used(m.textures[TEX_SPECULAR_COLOR])) {
            m.specular_color.rgb *= sample_slot(m.textures[TEX_SPECULAR_COLOR], tri, b, true, lod).rgb;
        }
    }
    if (scene_has(FEATURE_TRANSMISSION) && slot_used(m.textures[TEX_TRANSMISSION])) {
        m.transmission.x *= sample_slot(m.textures[TEX_TRANSMISSION], tri, b, false, lod).r;
    }
    if (scene_has(FEATURE_CLEARCOAT)) {
        if (slot_used(m.textures[TEX_CLEARCOAT])) m.clearcoat.x *= sample_slot(m.textures[TEX_CLEARCOAT], tri, b, false, lod).r;
        if (slot_used(m.textures[TEX_CLEARCOAT_ROUGHNESS])) {
            m.clearcoat.y *= sample_slot(m.textures[TEX_CLEARCOAT_ROUGHNESS], tri, b, false, lod).g;
        }
    }
    if (scene_has(FEATURE_SHEEN)) {
        if (slot_used(m.textures[TEX_SHEEN_COLOR])) m.sheen.rgb *= sample_slot(m.textures[TEX_SHEEN_COLOR], tri, b, true, lod).rgb;
        if (slot_used(m.textures[TEX_SHEEN_ROUGHNESS])) m.sheen.w *= sample_slot(m.textures[TEX_SHEEN_ROUGHNESS], tri, b, false, lod).a;
    }
    if (scene_has(FEATURE_ANISOTROPY) && slot_used(m.textures[TEX_ANISOTROPY])) {
        // The texel's direction (RG) turned by the material's rotation (yz); a zero direction keeps the rotation's.
        vec3 a = sample_slot(m.textures[TEX_ANISOTROPY], tri, b, false, lod).rgb;
        vec2 d = a.rg * 2.0 - 1.0;
        vec2 r = m.anisotropy.yz;
        d = vec2(r.x * d.x - r.y * d.y, r.y * d.x + r.x * d.y);
        m.anisotropy.x *= a.b;
        if (dot(d, d) > 1e-12) m.anisotropy.yz = normalize(d);
    }
    if (scene_has(FEATURE_DIFFUSE_ROUGHNESS) && slot_used(m.textures[TEX_DIFFUSE_ROUGHNESS])) {
        m.specular_color.w *= sample_slot(m.textures[TEX_DIFFUSE_ROUGHNESS], tri, b, false, lod).r;
    }
    if (scene_has(FEATURE_DIFFUSE_TRANSMISSION)) {
        if (slot_used(m.textures[TEX_DIFFUSE_TRANSMISSION])) {
            m.diffuse_transmission.w *= sample_slot(m.textures[TEX_DIFFUSE_TRANSMISSION], tri, b, false, lod).a;
        }
        if (slot_used(m.textures[TEX_DIFFUSE_TRANSMISSION_COLOR])) {
            m.diffuse_transmission.rgb *= sample_slot(m.textures[TEX_DIFFUSE_TRANSMISSION_COLOR], tri, b, true, lod).rgb;
        }
    }
    if (scene_has(FEATURE_THIN_SCATTER)) {
        if (slot_used(m.textures[TEX_SCATTER_STRENGTH])) {
            m.transmission.w *= sample_slot(m.textures[TEX_SCATTER_STRENGTH], tri, b, false, lod).a;
        }
        if (slot_used(m.textures[TEX_SCATTER_COLOR])) {
            m.medium.rgb *= sample_slot(m.textures[TEX_SCATTER_COLOR], tri, b, true, lod).rgb;
        }
    }
    if (scene_has(FEATURE_IRIDESCENCE)) {
        if (slot_used(m.textures[TEX_IRIDESCENCE])) m.iridescence.x *= sample_slot(m.textures[TEX_IRIDESCENCE], tri, b, false, lod).r;
        if (slot_used(m.textures[TEX_IRIDESCENCE_THICKNESS])) {
            float g = sample_slot(m.textures[TEX_IRIDESCENCE_THICKNESS], tri, b, false, lod).g;
            m.iridescence.w = mix(m.iridescence.z, m.iridescence.w, g);
        }
    }
    // The host's spectral coefficients are the factors'; a colour a texture or the vertices changed has its own.
    if (m.base_color.rgb != base_factor) m.base_color_spectrum.w = 0.0;
    if (m.emission.rgb != emission_factor) m.emission_spectrum.w = 0.0;
#endif
    return m;
}

// The mesh's tangent frame at the hit, orthonormal about ns (unit, in the world): false where the triangle has no
// usable tangent. An instanced triangle's tangents are its mesh's: the instance takes them into the world, and a
// mirroring one flips the bitangent relative to cross(normal, tangent), as placing a mirrored mesh does.
bool tangent_frame(uint tri, vec2 b, vec3 ns, uint inst, out vec3 t, out vec3 bt) {
    t = vec3(0.0);
    bt = vec3(0.0);
#ifdef TEXTURED
    TriTangents tt = load_tri_tangents(tri);
    vec4 t4 = (1.0 - b.x - b.y) * tt.t0 + b.x * tt.t1 + b.y * tt.t2;
    if (scene_has(FEATURE_INSTANCES) && inst != NO_INSTANCE) {
        Instance I = instance_at(inst);
        t4.xyz = rows_vector(I.world0, I.world1, I.world2, t4.xyz);
        if (I.info.y != 0u) t4.w = -t4.w;
    }
    t = t4.xyz - ns * dot(ns, t4.xyz);
    if (!(dot(t, t) > 1e-12)) return false;
    t = normalize(t);
    bt = cross(ns, t) * (t4.w < 0.0 ? -1.0 : 1.0);
    return true;
#else
    return false;
#endif
}

// The shading normal with the normal map in `slot` applied (x and y scaled by `scale`); ns is the interpolated vertex
// normal (unit length, in the world).
vec3 normal_mapped(TextureSlot slot, float scale, uint tri, vec2 b, vec3 ns, uint inst, vec2 lod) {
#ifdef TEXTURED
    if (!slot_used(slot)) return ns;
    vec3 t, bt;
    if (!tangent_frame(tri, b, ns, inst, t, bt)) return ns;
    vec3 c = sample_slot(slot, tri, b, false, lod).xyz * 2.0 - 1.0;
    c.xy *= scale;
    vec3 n = c.x * t + c.y * bt + c.z * ns;
    return dot(n, n) > 1e-12 ? normalize(n) : ns;
#else
    return ns;
#endif
}

#endif
