// survey: the AOVs of one sample row of the pass. Each pixel's camera ray of that sample (the beauty's own: the same
// jitter, lens point and time), its first hit (distance, position, instance, material), and through specular and
// near-specular bounces the first rough surface (the albedo and normal Open Image Denoise asks for), added to the
// pixel's AovSums. One dispatch per sample row, in sample order, so the sums are the same bytes however samples are
// grouped into passes.
#version 460
#extension GL_GOOGLE_include_directive : require
#include "stage.glsl"
#include "path.glsl"
// The traversal-cost debug view counts the child boxes the camera ray tests.
#define TRAVERSE_COUNT_NODES
#include "traverse.glsl"

// Whether the lobe bsdf_sample chose with lobe-choice number u_lobe is a specular one (the glass, the coat and metal,
// or the clear coat) with a GGX alpha below AOV_SPECULAR_ALPHA: the AOVs look through it like through a mirror.
bool near_specular(Bsdf b, float u_lobe) {
    vec4 p = b.lobe_p;
    if (u_lobe < p.x + p.y) return b.alpha < AOV_SPECULAR_ALPHA;
    if (u_lobe < p.x + p.y + p.z) return b.coat_alpha < AOV_SPECULAR_ALPHA;
    return false;
}

void main() {
    uint i = gl_GlobalInvocationID.x;
    // A follow dispatch cut short: the host runs the pass again, survey included (Integrator::run).
    if (i >= frame.pass_pixels || counters.follow_cut != 0u) return;
    uint path = i + survey_row() * frame.pass_pixels;
    uint pixel = path_pixel(path);
    uint s = path_sample(path);
    if (!sample_taken(pixel, s)) return;
    PathVertex v = start_path(pixel_xy(pixel), pixel, s);
    vec3 through = vec3(1.0); // what the specular bounces so far pass on
    vec3 albedo = vec3(0.0);
    vec3 normal = vec3(0.0);
    vec4 first = vec4(0.0); // the first hit's position and distance
    uvec2 ids = uvec2(AOV_NONE);
    DebugSums debug = DebugSums(vec4(0.0), vec4(0.0), vec4(0.0));
    bool open = true;       // still looking for a rough surface
    for (uint bounce = 0u; bounce < AOV_MAX_BOUNCES && open; bounce++) {
        Hit h = trace(v.origin.xyz, v.dir, 0.0, 3.0e38, false, ray_key(pixel, s, bounce, DIM_ALPHA));
        if (bounce == 0u) debug.geometric.w = float(traverse_node_visits);
        if (h.tri == NO_HIT) {
            if (bounce == 0u && scene_has(FEATURE_ENV) && frame.env_width > 0u) debug.shading.w = frame.env_prob;
            // The environment seen, within [0, 1], stands for the albedo of what is not there (the normal stays zero,
            // Open Image Denoise's "no surface").
            bool hidden = bounce == 0u && (frame.flags & FLAG_HIDE_ENV) != 0u;
            if (scene_has(FEATURE_ENV) && frame.env_width > 0u && !hidden) {
                albedo = through * clamp(env_radiance(v.dir), vec3(0.0), vec3(1.0));
            }
            normal = vec3(0.0);
            open = false;
            break;
        }
        Surface sf = surface_at(h.tri, h.uv, h.inst, v.dir, s);
        if (bounce == 0u) {
            first = vec4(sf.p, h.t);
            uint instance = floatBitsToUint(sf.ts.n2.w);
            if (scene_has(FEATURE_INSTANCES) && h.inst != NO_INSTANCE) instance = instances[h.inst].info.z;
            ids = uvec2(instance, floatBitsToUint(sf.tv.v0.w));
            debug.geometric.xyz = sf.n_in;
            debug.shading.xyz = sf.ns;
            // An emitter's share of the power table.
            debug.shading.w = emitter_power_share(sf.ts, h.inst);
#ifdef TEXTURED
            TriTexcoords tc = load_tri_texcoords(h.tri);
            debug.uv.xy = ((1.0 - h.uv.x - h.uv.y) * tc.t0 + h.uv.x * tc.t1 + h.uv.y * tc.t2).xy;
#endif
        }
        normal = sf.ns;
        if (scene_has(FEATURE_UNLIT) && (floatBitsToUint(sf.m.alpha.w) & MATERIAL_UNLIT) != 0u) {
            albedo = through * sf.m.base_color.rgb;
            open = false;
            break;
        }
        Bsdf bsdf = bsdf_from_material(sf.m, sf.front);
        vec3 tx, ty;
        shading_frame(sf, h.tri, h.uv, h.inst, bsdf, tx, ty);
        bsdf_at(bsdf, vec3(dot(-v.dir, tx), dot(-v.dir, ty), dot(-v.dir, sf.ns)));
        // The beauty path's own choice at this bounce: the AOVs follow the prefix of the path the image adds.
        vec3 u = vec3(rand2(pixel, s, bounce, DIM_BSDF), rand2(pixel, s, bounce, DIM_BSDF_LOBE).x);
        BsdfSample bs;
        bool ok = bsdf_sample(bsdf, u, bs);
        bool specular = ok && (bs.delta || near_specular(bsdf, u.z));
        bool emits = (sf.front || sf.m.emission.w > 0.5) && any(greaterThan(sf.m.emission.rgb, vec3(0.0)));
        if (emits) {
            // A light shows what it emits, within [0, 1], like the environment: its edge is then an edge of the
            // guide, which keeps the denoiser from spreading it.
            albedo = through * clamp(sf.m.emission.rgb, vec3(0.0), vec3(1.0));
            open = false;
        } else if (!specular || bounce + 1u == AOV_MAX_BOUNCES) {
            // f cos / pdf of a BSDF sample has the directional albedo as its mean: the AOV converges to the whole
            // BSDF's albedo at wo (every lobe and layer), and is exact at once for a Lambertian surface.
            albedo = ok ? through * bs.weight.rgb : vec3(0.0);
            open = false;
        } else {
            through *= bs.weight.rgb;
            float size = offset_size(sf.tv);
            vec3 wi = bs.wi.x * tx + bs.wi.y * ty + bs.wi.z * sf.ns;
            v.origin = vec4(offset_ray(sf.p, bs.wi.z > 0.0 ? sf.n_in : -sf.n_in, size), 0.0);
            v.dir = wi;
        }
    }
    uint at = pixel;
    AovSums a = aovs[at];
    // The first sample a film adds names the pixel's ids.
    if (a.albedo.w == 0.0) a.ids = uvec4(ids, 0u, 0u);
    a.albedo += vec4(albedo, 1.0);
    bool hit = ids.x != AOV_NONE;
    a.normal += vec4(normal, hit ? 1.0 : 0.0);
    a.position += first;
    aovs[at] = a;
    if ((frame.flags & FLAG_DEBUG_AOVS) != 0u) {
        DebugSums d = debug_aovs[at];
        d.geometric += debug.geometric;
        d.shading += debug.shading;
        d.uv += debug.uv;
        debug_aovs[at] = d;
    }
    check_loop_budget();
}
