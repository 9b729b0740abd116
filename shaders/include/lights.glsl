// Next-event estimation's lights: light selection (by the light BVH's importance at the point, by power, or uniformly,
// over one table of emissive triangles, emissive instances, punctual lights and the environment) and sampling.
#ifndef LIGHTS_GLSL
#define LIGHTS_GLSL

#include "environment.glsl"
#include "surface.glsl"
#include "spectrum.glsl"
#include "light_tree.glsl"

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

// Which light selection runs (--light-sampler): the tree, uniform, or (neither flag) by power.
bool light_tree_on() { return scene_has(FEATURE_LIGHT_TREE) && (frame.flags & FLAG_LIGHT_TREE) != 0u; }
bool light_uniform() { return (frame.flags & FLAG_LIGHT_UNIFORM) != 0u; }

// p and n in instance inst's mesh space (at the path's time), where its mesh's light subtree judges importance; the
// pick and its pdf twin both take them from here, so both see the same floats.
void light_into_instance(uint inst, vec3 p, vec3 n, out vec3 po, out vec3 no) {
    Instance I = instance_at(inst);
    po = vec3(dot(I.object0.xyz, p) + I.object0.w, dot(I.object1.xyz, p) + I.object1.w, dot(I.object2.xyz, p) + I.object2.w);
    // A normal goes by the transpose of the forward map.
    vec3 m = I.world0.xyz * n.x + I.world1.xyz * n.y + I.world2.xyz * n.z;
    no = dot(m, m) > 0.0 ? normalize(m) : vec3(0.0);
}

// Light selection: an entry of the light buffer (of the table, or of the tree's infinite lights), for an instance
// the emitter of its mesh picked within it when the tree picks (sub; else LIGHT_NONE, and sample_light picks by
// power in the mesh's table), and the probability of both, from the point p with normal n. By power and uniformly,
// u_point.x picks and is rescaled to the pick's share, so one stratified 2D sample spreads over the lights together
// (on the Cornell box's two light triangles that lowered relMSE at equal samples by 2.4 % against a separate
// dimension). The tree takes u_pick: its descent would leave u_point.x too few bits. The tree's share of the picks
// is the header's; the rest goes to the infinite lights (environment, directional lights) by their power, as in the
// power table. An instance the tree reaches continues the same descent into its mesh's subtree, stored once for
// every instance of the mesh, with p and n taken into the mesh's space.
bool select_light(vec3 p, vec3 n, vec2 u_pick, inout vec2 u_point, out uint j, out uint sub, out float prob) {
    sub = LIGHT_NONE;
    if (light_tree_on()) {
        float share = light_node_sphere(0u).x;
        if (u_pick.x < share) {
            LightWalk w = light_walk(vec2(u_pick.x / share, u_pick.y));
            bool ok = tree_descend(light_node_link(0u).x, p, n, w, j, prob);
            prob *= share;
            if (ok && scene_has(FEATURE_INSTANCES) && (load_light(j).id >> LIGHT_KIND_SHIFT) == LIGHT_KIND_INSTANCE) {
                uint inst = load_light(j).id & LIGHT_INDEX_MASK;
                vec3 po, no;
                light_into_instance(inst, p, n, po, no);
                float q;
                ok = tree_descend(instances[inst].light.w, po, no, w, sub, q);
                prob *= q;
            }
            return ok;
        }
        uvec4 h = light_node_link(0u);
        j = pick_light_in(h.y, max(h.z, 1u), min((u_pick.x - share) / (1.0 - share), 0.99999994));
        prob = h.z > 0u ? load_light(j).prob : 0.0;
        return h.z > 0u;
    }
    if (light_uniform()) {
        float count = float(frame.light_count);
        j = min(uint(u_point.x * count), frame.light_count - 1u);
        prob = 1.0 / count;
        u_point.x = min(u_point.x * count - float(j), 0.99999994);
        return true;
    }
    j = pick_light(u_point.x);
    Light l = load_light(j);
    prob = l.prob;
    u_point.x = rescale_pick(0u, j, l, u_point.x);
    return true;
}

// The probability light selection picks table entry j from (p, n) (a triangle or an instance: never infinite).
float light_pick_prob(uint j, vec3 p, vec3 n) {
    if (light_tree_on()) return light_node_sphere(0u).x * tree_pmf(j, p, n);
    if (light_uniform()) return 1.0 / float(frame.light_count);
    return load_light(j).prob;
}

// The probability that instance inst, once picked from (p, n), gives the emitter at entry e of its mesh's table:
// through its mesh's subtree under the tree, else by power in the table.
float instanced_pick_prob(uint inst, uint e, vec3 p, vec3 n) {
    if (light_tree_on()) {
        vec3 po, no;
        light_into_instance(inst, p, n, po, no);
        return tree_pmf_below(instances[inst].light.w, e, po, no);
    }
    return load_light(e).prob;
}

// The table entry of emissive triangle ts (its light-buffer entry + 1 in n0.w, 0 when light selection never picks
// it), hit through instance inst: its probability of being picked from (p, n), over its area now (n1.w), which is
// light sampling's density per unit area there; MIS weighs a BSDF sample's hit by it.
float emitter_pdf_area(TriShading ts, uint inst, vec3 p, vec3 n) {
    if (!(ts.n0.w > 0.0) || !(ts.n1.w > 0.0)) return 0.0;
    uint e = uint(ts.n0.w) - 1u;
    float prob;
    if (scene_has(FEATURE_INSTANCES) && inst != NO_INSTANCE) {
        prob = light_pick_prob(instances[inst].light.z, p, n) * instanced_pick_prob(inst, e, p, n);
    } else {
        prob = light_pick_prob(e, p, n);
    }
    return prob / ts.n1.w;
}

// The emitter's share of the power table (the light-pick debug view).
float emitter_power_share(TriShading ts, uint inst) {
    if (!(ts.n0.w > 0.0)) return 0.0;
    float prob = load_light(uint(ts.n0.w) - 1u).prob;
    if (scene_has(FEATURE_INSTANCES) && inst != NO_INSTANCE) prob *= load_light(instances[inst].light.z).prob;
    return prob;
}

struct LightSample {
    vec3 wi;        // towards the light
    float dist;     // to the light's point; effectively infinite for the environment
    Spectrum radiance; // arriving along -wi
    float pdf;      // solid-angle density including the selection probability; 0 when the light cannot reach p
    bool delta;     // a punctual light: pdf is only the selection probability, and no BSDF sample can find it
};

// Picks a light as seen from p on a surface with normal n (select_light, with u and u_pick) and a point or direction
// on it with u.
LightSample sample_light(vec3 p, vec3 n, vec2 u, vec2 u_pick) {
    LightSample ls;
    ls.pdf = 0.0;
    ls.radiance = Spectrum(0.0);
    ls.wi = vec3(0.0, 0.0, 1.0);
    ls.dist = 0.0;
    ls.delta = false;
    uint picked, sub;
    float prob;
    vec2 u_point = u;
    if (!select_light(p, n, u_pick, u_point, picked, sub, prob)) return ls;
    Light l = load_light(picked);
    if (scene_has(FEATURE_PUNCTUAL) && (l.id >> LIGHT_KIND_SHIFT) == LIGHT_KIND_PUNCTUAL) {
        PunctualLight pl = punctuals[l.id & LIGHT_INDEX_MASK];
        uint kind = floatBitsToUint(pl.position.w);
        ls.delta = true;
        ls.pdf = prob;
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
        ls.pdf = prob * pdf_dir;
        return ls;
    }
    uint tri = l.id & LIGHT_INDEX_MASK;
    uint inst = NO_INSTANCE;
    if (scene_has(FEATURE_INSTANCES) && (l.id >> LIGHT_KIND_SHIFT) == LIGHT_KIND_INSTANCE) {
        // An instance of an emissive mesh: the triangle the tree picked in its subtree, or one from the mesh's own
        // table by power, u_point.x rescaled again to that triangle's share.
        inst = tri;
        if (sub != LIGHT_NONE) {
            tri = load_light(sub).id & LIGHT_INDEX_MASK;
        } else {
            uvec4 table = instances[inst].light;
            uint j = pick_light_in(table.x, table.y, u_point.x);
            Light t = load_light(j);
            u_point.x = rescale_pick(table.x, j, t, u_point.x);
            tri = t.id & LIGHT_INDEX_MASK;
            prob *= t.prob;
        }
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
    Material hit = material_at(lm, tri, b, NO_LOD);
    ls.radiance = spectrum_illuminant_known(hit.emission.rgb, hit.emission_spectrum) * (lv.e1.w != 0.0 ? material_coverage(lm, tri, b) : 1.0);
#else
    ls.radiance = spectrum_illuminant_known(lm.emission.rgb, lm.emission_spectrum);
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
