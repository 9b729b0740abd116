// One bounce of a path: what the shade stage and the fused follow stage both run at a hit (or a miss).
#ifndef PATH_GLSL
#define PATH_GLSL

#include "rng.glsl"
#include "bsdf.glsl"
#include "camera.glsl"
#include "lights.glsl"
#include "media.glsl"

// Next-event estimation's ray: it adds `radiance` when nothing blocks origin -> origin + dir * origin.w.
struct ShadowRay {
    vec4 origin;
    vec3 dir;
    Spectrum radiance;
    bool wanted;
};

// Moves p off the surface along n by a few ulps, so the next ray cannot hit the surface it leaves (Waechter and
// Binder, Ray Tracing Gems ch. 6). Near the origin, where ulps vanish, they step a fixed distance instead, which
// assumes triangles of about unit size; `size` (a power of two, at most 1: see offset_size) scales that region and
// step with the triangle, so a scene modelled in micrometres renders as one in metres. Triangles of size 1/2 and
// more take the paper's constants exactly.
vec3 offset_ray(vec3 p, vec3 n, float size) {
    float origin = size * (1.0 / 32.0);
    float float_scale = size * (1.0 / 65536.0);
    const float int_scale = 256.0;
    ivec3 of_i = ivec3(int_scale * n);
    vec3 p_i = vec3(
        intBitsToFloat(floatBitsToInt(p.x) + (p.x < 0.0 ? -of_i.x : of_i.x)),
        intBitsToFloat(floatBitsToInt(p.y) + (p.y < 0.0 ? -of_i.y : of_i.y)),
        intBitsToFloat(floatBitsToInt(p.z) + (p.z < 0.0 ? -of_i.z : of_i.z)));
    return vec3(
        abs(p.x) < origin ? p.x + float_scale * n.x : p_i.x,
        abs(p.y) < origin ? p.y + float_scale * n.y : p_i.y,
        abs(p.z) < origin ? p.z + float_scale * n.z : p_i.z);
}

// The scale offset_ray works at for triangle tv: its largest coordinate or edge component, rounded up to a power of
// two (so the products stay exact), at most 1.
float offset_size(TriVerts tv) {
    vec3 m = max(abs(tv.v0.xyz), max(abs(tv.e1.xyz), abs(tv.e2.xyz)));
    float largest = max(m.x, max(m.y, m.z));
    return largest >= 0.5 ? 1.0 : exp2(ceil(log2(max(largest, 1e-30))));
}

// What shading needs of a hit, in world space: the triangle (moved by its instance), its material at the hit,
// the point, and its normals. The shade and follow stages and the survey (AOV) stage all see a hit through this.
struct Surface {
    TriVerts tv;
    TriShading ts;
    Material m;
    vec3 p;
    vec3 ng;     // geometric, from the winding (counter-clockwise faces front)
    bool front;  // the ray arrived on the front
    vec3 n_in;   // geometric normal on the side the ray arrived from
    vec3 n_mesh; // the interpolated vertex normal
    vec3 ns;     // shading normal (normal-mapped), on n_in's side
    vec2 lod;    // texture_footprint at p, which the material's textures were read at
};

// Triangle tri at barycentrics uv, reached along ray_d by sample s; inst is the hit's instance (NO_INSTANCE: world
// space).
Surface surface_at(uint tri, vec2 uv, uint inst, vec3 ray_d, uint s) {
    Surface sf;
    TriVerts tv = load_tri_verts(tri);
    TriShading ts = load_tri_shading(tri, tv);
    bool mirrored = false;
    if (scene_has(FEATURE_INSTANCES) && inst != NO_INSTANCE) {
        // An instanced triangle, in its mesh's space: into the world by the instance's transform, its normals by the
        // inverse transpose.
        Instance I = instance_at(inst);
        tv = tri_to_world(I, tv);
        ts.n0.xyz = instance_normal(I, ts.n0.xyz);
        ts.n1.xyz = instance_normal(I, ts.n1.xyz);
        ts.n2.xyz = instance_normal(I, ts.n2.xyz);
        mirrored = I.info.y != 0u;
        // Its area in the world now, which light sampling's density per unit area divides by (emitter_pdf_area).
        ts.n1.w = 0.5 * length(cross(tv.e1.xyz, tv.e2.xyz));
    }
    sf.p = tv.v0.xyz + uv.x * tv.e1.xyz + uv.y * tv.e2.xyz;
    sf.ng = normalize(cross(tv.e1.xyz, tv.e2.xyz));
#ifdef TEXTURED
    sf.lod = texture_footprint(tv.e1.xyz, tv.e2.xyz, sf.ng, sf.p, s);
#else
    sf.lod = NO_LOD;
#endif
    sf.m = material_at(load_material(floatBitsToUint(tv.v0.w)), tri, uv, sf.lod);
    // A mirroring instance turns the winding; its front is still the mesh's.
    if (mirrored) sf.ng = -sf.ng;
    sf.front = dot(sf.ng, ray_d) < 0.0;
    sf.n_in = sf.front ? sf.ng : -sf.ng;
    sf.n_mesh = normalize((1.0 - uv.x - uv.y) * ts.n0.xyz + uv.x * ts.n1.xyz + uv.y * ts.n2.xyz);
    sf.ns = normal_mapped(sf.m.textures[TEX_NORMAL], sf.m.alpha.z, tri, uv, sf.n_mesh, inst, sf.lod);
    if (dot(sf.ns, sf.n_in) < 0.0) sf.ns = -sf.ns;
    sf.tv = tv;
    sf.ts = ts;
    return sf;
}

// The shading frame at sf: z along the shading normal, x and y across it (the tangent frame for an anisotropic
// lobe); sets bsdf's clear-coat normal in that frame.
void shading_frame(Surface sf, uint tri, vec2 uv, uint inst, inout Bsdf bsdf, out vec3 tx, out vec3 ty) {
    basis(sf.ns, tx, ty);
    // An anisotropic lobe is stretched along a direction given in the mesh's tangent frame: the shading frame is that
    // frame (about the shading normal). Without tangents the lobe takes the arbitrary one.
    if (scene_has(FEATURE_ANISOTROPY) && bsdf.anisotropic) {
        vec3 t, bt;
        if (tangent_frame(tri, uv, sf.ns, inst, t, bt)) {
            tx = t;
            ty = bt;
        }
    }
    if (scene_has(FEATURE_CLEARCOAT) && bsdf.clearcoat > 0.0) {
        // The coat has its own normal map, or none: then it follows the mesh, not the base's map.
        vec3 nc = normal_mapped(sf.m.textures[TEX_CLEARCOAT_NORMAL], sf.m.clearcoat.z, tri, uv, sf.n_mesh, inst, sf.lod);
        if (dot(nc, sf.n_in) < 0.0) nc = -nc;
        vec3 nl = vec3(dot(nc, tx), dot(nc, ty), dot(nc, sf.ns));
        // A coat normal below the shading hemisphere (an extreme map) falls back to the shading normal.
        bsdf_set_coat_normal(bsdf, nl.z > 1e-4 ? normalize(nl) : vec3(0.0, 0.0, 1.0));
    }
}

// Russian roulette from bounce RR_START_BOUNCE on: the path survives with its throughput's largest component, at most
// `cap`, and the survivor's throughput is divided by that. Returns whether it survives.
bool roulette(uint pixel, uint s, uint bounce, float cap, inout Spectrum beta) {
    if (bounce < RR_START_BOUNCE) return true;
    float survive = min(spectrum_max(beta), cap);
    beta /= survive;
    return rand2(pixel, s, bounce, DIM_RR).x < survive;
}

// A scattering in medium md at p, reached along d_in with throughput beta (the free flight's weight in it): next-event
// estimation towards a light through the medium, MIS-weighted against the phase function, and the continuation drawn
// from the phase function. A shadow ray that meets the volume's boundary is blocked (as in Mitsuba 3 and pbrt-v4: a
// refracting boundary has no straight path through it); light from outside arrives by phase sampling through the
// boundary's refraction instead. Returns whether the path goes on.
bool scatter_path(uint pixel, uint s, uint bounce, vec3 p, vec3 d_in, Medium md, Spectrum beta, inout PathVertex v,
                  inout ShadowRay shadow) {
    bool alive = bounce < frame.max_depth;
    if (frame.light_count > 0u) {
        vec2 u_pick = light_tree_on() ? rand2(pixel, s, bounce, DIM_LIGHT_PICK) : vec2(0.0);
        // No normal: the light BVH weighs its nodes without a receiver cosine, and its pdf twin at an emitter the
        // continuation hits sees the same (LIGHT_NORMAL_NONE).
        LightSample ls = sample_light(p, vec3(0.0), rand2(pixel, s, bounce, DIM_LIGHT), u_pick);
        bool wanted = frame_estimator() != ESTIMATOR_BSDF || ls.delta;
        if (alive && wanted && ls.pdf > 0.0) {
            float phase = hg_phase(dot(d_in, ls.wi), md.g);
            bool mis = frame_estimator() == ESTIMATOR_MIS && !ls.delta;
            float w = mis ? power_heuristic(ls.pdf, phase) : 1.0;
            // The run to the light stays in this medium, or the shadow ray meets a surface and is blocked.
            Spectrum contribution = beta * phase * medium_transmittance(md, ls.dist) * ls.radiance * (w / ls.pdf);
            shadow.wanted = spectrum_positive(contribution);
            shadow.origin = vec4(p, ls.dist * (1.0 - 1e-4));
            shadow.dir = ls.wi;
            shadow.radiance = contribution;
        }
    }
    vec3 wi = hg_sample(d_in, md.g, rand2(pixel, s, bounce, DIM_PHASE));
    // The phase function is sampled exactly: its weight is 1, the throughput only the free flight's. Roulette
    // only takes what the throughput has lost (pbrt-v4's rule, without the surfaces' 0.95 cap): light diffusing
    // through a dense, bright medium scatters hundreds of times, and a 5 % loss at each left almost none to leave it
    // (the marble of scenes/subsurface.gltf rendered black, with fireflies).
    alive = roulette(pixel, s, bounce, 1.0, beta) && alive;
    v.origin = vec4(p, hg_phase(dot(d_in, wi), md.g));
    v.dir = wi;
    v.beta = beta;
    if (light_tree_on()) v.light_normal = LIGHT_NORMAL_NONE;
    return alive;
}

// Bounce `bounce` of sample s of pixel: v's ray found `hit` (t, triangle bits, barycentrics). Adds the emission the
// ray sees (MIS-weighted), asks for a shadow ray towards a light in `shadow`, and turns v into the continuation.
// Returns whether the path goes on. Randomness depends only on (pixel, s, bounce, dimension), so the wavefront and
// follow give the same bytes.
bool shade_path(uint pixel, uint s, uint bounce, vec4 hit, uint inst, inout PathVertex v, out ShadowRay shadow) {
    uint tri = floatBitsToUint(hit.y);
    vec4 ray_o = v.origin;
    vec3 ray_d = v.dir;
    Spectrum beta = v.beta;
    shadow.wanted = false;
    shadow.origin = vec4(0.0);
    shadow.dir = vec3(0.0);
    shadow.radiance = Spectrum(0.0);
    // After the camera or a delta bounce, nothing else could have found this light: it counts in full.
    bool camera_or_delta = bounce == 0u || ray_o.w == 0.0;

    // Inside a scattering volume the ray may scatter before it reaches the surface (or, having left the scene through
    // an open volume, anywhere): then the surface is not seen at all.
    if (scene_has(FEATURE_MEDIA) && v.media.x != 0u) {
        Medium md = medium_at(v.media.x);
        float t;
        float t_max = tri != NO_HIT ? hit.x : 1.0e30;
        float u = rand2(pixel, s, bounce, DIM_MEDIUM).y;
        if (medium_sample(md, t_max, medium_channel(pixel, s), u, beta, v.media_ratios, t)) {
            return scatter_path(pixel, s, bounce, ray_o.xyz + t * ray_d, ray_d, md, beta, v, shadow);
        }
    }

    // No early exit: lavapipe runs every line for every lane anyway, so an early return only adds stores. A lane stops
    // being `alive` where its path ends; what follows still runs for it but changes nothing it returns.
    bool alive = tri != NO_HIT;
    if (!alive) {
        bool hidden = bounce == 0u && (frame.flags & FLAG_HIDE_ENV) != 0u;
        if (scene_has(FEATURE_ENV) && frame.env_width > 0u && !hidden) {
            float w = 1.0;
            if (!camera_or_delta) {
                if (frame_estimator() == ESTIMATOR_LIGHT) {
                    w = 0.0;
                } else if (frame_estimator() == ESTIMATOR_MIS) {
                    w = power_heuristic(ray_o.w, frame.env_prob * env_pdf(ray_d));
                }
            }
            v.radiance += beta * spectrum_illuminant(env_radiance(ray_d)) * w;
        }
    }

    Surface sf = surface_at(tri, hit.zw, inst, ray_d, s);
    TriVerts tv = sf.tv;
    TriShading ts = sf.ts;
    vec2 uv = hit.zw;
    Material m = sf.m;
    vec3 p = sf.p;
    vec3 ng = sf.ng;
    bool front = sf.front;
    vec3 n_in = sf.n_in;
    vec3 ns = sf.ns;
    // To look at any quantity while editing (docs/guide/shaders.md), e.g. the shading normals in an RGB render:
    // `v.radiance = Spectrum(ns * 0.5 + 0.5, 0.0); return false;` here.

    // Emission seen by this ray, weighted against the chance NEE would have found the same point.
    bool emits = (front || m.emission.w > 0.5) && any(greaterThan(m.emission.rgb, vec3(0.0)));
    if (alive && emits) {
        float w = 1.0;
        if (!camera_or_delta) {
            if (frame_estimator() == ESTIMATOR_LIGHT) {
                w = 0.0;
            } else if (frame_estimator() == ESTIMATOR_MIS) {
                // Light selection's probability from the vertex the ray left (its origin and normal, as NEE there
                // picked with them).
                float cos_l = abs(dot(ng, ray_d));
                vec3 n_from = light_tree_on() ? unpack_light_normal(v.light_normal) : vec3(0.0);
                float pdf_area = emitter_pdf_area(ts, inst, ray_o.xyz, n_from);
                float pdf_light = cos_l > 0.0 ? pdf_area * hit.x * hit.x / cos_l : 0.0;
                w = power_heuristic(ray_o.w, pdf_light);
            }
        }
        v.radiance += beta * spectrum_illuminant_known(m.emission.rgb, m.emission_spectrum) * w;
    }
    // An unlit surface shows its colour to whatever ray reaches it and ends the path. No light sampling aims at it, so
    // the colour counts in full after every kind of bounce.
    if (scene_has(FEATURE_UNLIT) && (floatBitsToUint(m.alpha.w) & MATERIAL_UNLIT) != 0u) {
        if (alive) v.radiance += beta * spectrum_illuminant(m.base_color.rgb);
        alive = false;
    }
    alive = alive && bounce < frame.max_depth;

    // A ray leaving a volumetric object has crossed its inside: absorption over that segment (Beer-Lambert), whether
    // it entered by refraction or diffusely.
    bool enters = (scene_has(FEATURE_TRANSMISSION) && m.transmission.x > 0.0) ||
                  (scene_has(FEATURE_DIFFUSE_TRANSMISSION) && m.diffuse_transmission.w > 0.0);
    // With media, the path's medium stack has done that already, for every volume it is inside.
    bool volumetric = enters && m.transmission.y < 0.5;
    // This surface's volume as the medium stack names it.
    uint medium_id = floatBitsToUint(tv.v0.w) + 1u;
    if (!scene_has(FEATURE_MEDIA) && volumetric && !front) {
        beta *= exp(-spectrum_unbounded(m.attenuation.rgb) * hit.x);
    }
    // Dispersion (KHR_materials_dispersion): the surface bends each wavelength its own way, so the direction sampled
    // here serves the hero alone and the path drops the others (pbrt-v4's rule). The hero then stands for all of the
    // film's mean over WAVELENGTHS wavelengths, so its throughput is multiplied by WAVELENGTHS; what the path gathered
    // before this hit keeps every wavelength, which stays unbiased (each wavelength's share before, the hero's after)
    // and keeps more colour than pbrt's dropping of the whole path's others.
    if (spectral() && m.transmission.z > 0.0 && m.transmission.x > 0.0 && !v.hero_only) {
        beta = Spectrum(beta.x * float(WAVELENGTHS), 0.0, 0.0, 0.0);
        v.hero_only = true;
    }
    Bsdf bsdf = bsdf_from_material(m, front);
    float size = offset_size(tv);
    vec3 p_back = offset_ray(p, -n_in, size); // origin for rays that go through the surface
    vec3 p_off = offset_ray(p, n_in, size);
    vec3 tx, ty;
    shading_frame(sf, tri, uv, inst, bsdf, tx, ty);
    bsdf_at(bsdf, vec3(dot(-ray_d, tx), dot(-ray_d, ty), dot(-ray_d, ns)));

    vec2 u_dir = rand2(pixel, s, bounce, DIM_BSDF);
    BsdfSample bs;
    bool ok = bsdf_sample(bsdf, vec3(u_dir, rand2(pixel, s, bounce, DIM_BSDF_LOBE).x), bs);
    vec3 wi = bs.wi.x * tx + bs.wi.y * ty + bs.wi.z * ns;
    // The light BVH's receiver normal at this vertex (the geometric one: its side does not matter to importance).
    if (light_tree_on()) v.light_normal = pack_light_normal(ng);

    // BSDF-only sampling still takes punctual lights by next-event estimation: no BSDF sample can find a delta light.
    if (frame.light_count > 0u) {
        // The light BVH picks from where the continuation starts and by the surface's normal (packed, as the path
        // state keeps it), so the pdf twin at the emitter the continuation may hit sees the same point and normal.
        vec3 n_pick = vec3(0.0);
        vec2 u_pick = vec2(0.0);
        if (light_tree_on()) {
            n_pick = unpack_light_normal(v.light_normal);
            u_pick = rand2(pixel, s, bounce, DIM_LIGHT_PICK);
        }
        vec3 p_pick = p;
        if (light_tree_on()) p_pick = bs.wi.z > 0.0 ? p_off : p_back;
        LightSample ls = sample_light(p_pick, n_pick, rand2(pixel, s, bounce, DIM_LIGHT), u_pick);
        vec3 wi_local = vec3(dot(ls.wi, tx), dot(ls.wi, ty), dot(ls.wi, ns));
        // The shading and true normals must agree on which side the light is (reflection or transmission).
        float side = dot(n_in, ls.wi);
        bool wanted = frame_estimator() != ESTIMATOR_BSDF || ls.delta;
        if (alive && wanted && ls.pdf > 0.0 && wi_local.z * side > 0.0) {
            Spectrum f = bsdf_eval(bsdf, wi_local);
            bool mis = frame_estimator() == ESTIMATOR_MIS && !ls.delta;
            float w = mis ? power_heuristic(ls.pdf, bsdf_pdf(bsdf, wi_local)) : 1.0;
            Spectrum contribution = beta * f * abs(wi_local.z) * ls.radiance * (w / ls.pdf);
            if (scene_has(FEATURE_MEDIA)) {
                // The run to the light crosses the medium on the side it leaves by, if any.
                uint id = side > 0.0 ? v.media.x : media_beyond(v.media, medium_id, volumetric, front);
                if (id != 0u) contribution *= medium_transmittance(medium_at(id), ls.dist);
            }
            shadow.wanted = spectrum_positive(contribution);
            // The shadow ray starts off the surface but ends at the light's point itself, just short of it so it
            // cannot hit the emitter it aims at. Its length measured from p_pick instead would overshoot by the
            // offset, through that emitter wherever the offset leans towards its back: facades facing each other
            // across a street lost up to 6 % of their direct light to it under the power and uniform selections.
            vec3 o = side > 0.0 ? p_off : p_back;
            vec3 to_light = ls.wi;
            float dist = ls.dist;
            if (ls.dist < 1e29) {
                vec3 d = p_pick + ls.wi * ls.dist - o;
                dist = length(d);
                to_light = d / dist;
            }
            shadow.origin = vec4(o, dist * (1.0 - 1e-4));
            shadow.dir = to_light;
            shadow.radiance = contribution;
        }
    }

    // A direction the shading normal puts on one side and the true surface on the other carries no light.
    alive = alive && ok && dot(n_in, wi) * bs.wi.z > 0.0;
    // Through a volume's boundary, the path enters or leaves its medium.
    if (scene_has(FEATURE_MEDIA) && volumetric && bs.wi.z < 0.0) {
        v.media = front ? media_enter(v.media, medium_id) : media_leave(v.media, medium_id);
    }
    beta *= bs.weight;
    alive = roulette(pixel, s, bounce, 0.95, beta) && alive;
    // w = 0 marks a delta bounce: the next emission hit is not weighted against light sampling.
    v.origin = vec4(bs.wi.z > 0.0 ? p_off : p_back, bs.delta ? 0.0 : bs.pdf);
    v.dir = wi;
    v.beta = beta;
    return alive;
}

#endif
