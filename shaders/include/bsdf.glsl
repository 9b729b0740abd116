// The glTF metallic-roughness BSDF (spec Appendix B, with KHR_materials_ior, _specular, _transmission, _volume, and
// the _sheen and _clearcoat layers over it):
// eval, sample and pdf live together here, in the shading frame (z = normal on wo's side), so they cannot drift apart.
#ifndef BSDF_GLSL
#define BSDF_GLSL

#include "sampling.glsl"

// GGX alpha below this is a perfect mirror: the lobe becomes a delta (sampled, never evaluated).
const float DELTA_ALPHA = 1e-4;

struct Bsdf {
    vec3 base_color;
    float metallic;
    float roughness;      // perceptual, for the energy tables
    float alpha;          // GGX alpha = roughness^2
    float specular;       // KHR_materials_specular weight of the dielectric layer
    vec3 specular_f0;     // dielectric F0 = min(((ior - 1) / (ior + 1))^2 * specularColor, 1)
    bool compensate;      // add the metal's multiple scattering (Kulla-Conty)
    float transmission;   // fraction of the dielectric base that is a rough dielectric interface instead of diffuse
    bool thin;            // thin-walled: transmitted light passes straight through, unbent
    float eta;            // relative IOR across the surface, from wo's side to the other: n_other / n_this
    float clearcoat;      // KHR_materials_clearcoat weight (0: no coat, and nothing below is read)
    float coat_roughness; // perceptual, for the energy tables
    float coat_alpha;
    vec3 coat_n;          // the clear coat's normal in the shading frame, and its tangents (its own normal map)
    vec3 coat_t;
    vec3 coat_b;
    vec3 sheen_color;     // KHR_materials_sheen (black: no sheen)
    float sheen_roughness;
};

// KHR_materials_clearcoat fixes the coat's IOR at 1.5.
const float CLEARCOAT_F0 = 0.04;

// front: wo is on the front (counter-clockwise) side, outside the object.
Bsdf bsdf_from_material(Material m, bool front) {
    Bsdf b;
    b.base_color = m.base_color.rgb;
    // A lobe no material in the scene has is a constant zero, and the code for it folds away (see scene_has).
    b.metallic = scene_has(FEATURE_METAL) ? m.params.x : 0.0;
    b.roughness = m.params.y;
    b.alpha = m.params.y * m.params.y;
    float ior = m.params.z;
    float r = (ior - 1.0) / (ior + 1.0);
    b.specular = scene_has(FEATURE_COAT) ? m.params.w : 0.0;
    b.specular_f0 = min(vec3(r * r) * m.specular_color.rgb, vec3(1.0));
    b.compensate = (frame.flags & FLAG_ENERGY_COMPENSATION) != 0u;
    b.transmission = scene_has(FEATURE_TRANSMISSION) ? m.transmission.x : 0.0;
    b.thin = m.transmission.y > 0.5;
    b.eta = b.thin || front ? ior : 1.0 / ior;
    b.clearcoat = scene_has(FEATURE_CLEARCOAT) ? m.clearcoat.x : 0.0;
    b.coat_roughness = m.clearcoat.y;
    b.coat_alpha = m.clearcoat.y * m.clearcoat.y;
    b.coat_n = vec3(0.0, 0.0, 1.0);
    b.coat_t = vec3(1.0, 0.0, 0.0);
    b.coat_b = vec3(0.0, 1.0, 0.0);
    b.sheen_color = scene_has(FEATURE_SHEEN) ? m.sheen.rgb : vec3(0.0);
    b.sheen_roughness = m.sheen.w;
    return b;
}

// The clear coat's normal map, as a normal in the shading frame (z = the base's shading normal).
void bsdf_set_coat_normal(inout Bsdf b, vec3 n) {
    b.coat_n = n;
    basis(n, b.coat_t, b.coat_b);
}

bool bsdf_is_delta(Bsdf b) {
    return b.alpha < DELTA_ALPHA;
}

float schlick_weight(float c) {
    float m = clamp(1.0 - c, 0.0, 1.0);
    float m2 = m * m;
    return m2 * m2 * m;
}

float max3(vec3 v) {
    return max(v.x, max(v.y, v.z));
}

float luminance(vec3 c) {
    return dot(c, vec3(0.2126, 0.7152, 0.0722));
}

// Both take the direction in the shading frame and use x^2 + y^2 for sin^2: 1 - cos^2 cancels catastrophically
// in f32 near the normal, exactly where a low-roughness lobe lives (D was off by percents at alpha 0.0025).
float ggx_d(float a2, vec3 h) {
    float d = h.z * h.z * a2 + (h.x * h.x + h.y * h.y);
    return a2 / (PI * d * d);
}

float smith_lambda(float a2, vec3 w) {
    float t2 = (w.x * w.x + w.y * w.y) / max(w.z * w.z, 1e-20);
    return 0.5 * (sqrt(1.0 + a2 * t2) - 1.0);
}

// Fresnel of the dielectric layer (per channel) and of the metal, at the cosine c between wo and the microfacet normal.
vec3 dielectric_fresnel(Bsdf b, float c) {
    return b.specular_f0 + (vec3(1.0) - b.specular_f0) * schlick_weight(c);
}

vec3 metal_fresnel(Bsdf b, float c) {
    return b.base_color + (vec3(1.0) - b.base_color) * schlick_weight(c);
}

// Bilinear lookup in one of the energy tables (table 0: E1, 1: E2, 2: Esheen) at (cos theta, roughness).
float energy_lookup(uint table, float mu, float roughness) {
    float x = clamp(mu, 0.0, 1.0) * float(ENERGY_RES - 1u);
    float y = clamp(roughness, 0.0, 1.0) * float(ENERGY_RES - 1u);
    uint x0 = min(uint(x), ENERGY_RES - 2u);
    uint y0 = min(uint(y), ENERGY_RES - 2u);
    float fx = x - float(x0);
    float fy = y - float(y0);
    uint base = table * ENERGY_RES * ENERGY_RES + y0 * ENERGY_RES + x0;
    float a = mix(energy[base], energy[base + 1u], fx);
    float c = mix(energy[base + ENERGY_RES], energy[base + ENERGY_RES + 1u], fx);
    return mix(a, c, fy);
}

// Hemispherical average 2 int E(mu) mu dmu of table 0 or 1, interpolated in roughness.
float energy_average(uint table, float roughness) {
    float y = clamp(roughness, 0.0, 1.0) * float(ENERGY_RES - 1u);
    uint y0 = min(uint(y), ENERGY_RES - 2u);
    uint base = ENERGY_GRIDS * ENERGY_RES * ENERGY_RES + table * ENERGY_RES + y0;
    return mix(energy[base], energy[base + 1u], y - float(y0));
}

// Directional albedo of the dielectric coat's single scattering, per channel (Schlick is linear in F0).
vec3 coat_albedo(Bsdf b, float mu) {
    if (bsdf_is_delta(b)) return b.specular * dielectric_fresnel(b, mu);
    return b.specular * (b.specular_f0 * energy_lookup(0u, mu, b.roughness) + (vec3(1.0) - b.specular_f0) * energy_lookup(1u, mu, b.roughness));
}

vec3 coat_average(Bsdf b) {
    // For a mirror, E1 = 1 and the average of (1 - mu)^5 over the projected hemisphere is 1/21.
    if (bsdf_is_delta(b)) return b.specular * (b.specular_f0 + (vec3(1.0) - b.specular_f0) / 21.0);
    return b.specular * (b.specular_f0 * energy_average(0u, b.roughness) + (vec3(1.0) - b.specular_f0) * energy_average(1u, b.roughness));
}

// The diffuse base under the coat: light enters through the coat at cos_i and leaves at cos_o, and is scaled so a white
// base returns exactly what the coat does not reflect. glTF's reference weights the base by 1 - F(VdotH), which can
// reflect more than arrives (1.025 for a white, nearly smooth plastic at 60 degrees); this form is reciprocal and
// conserves energy.
vec3 coat_transmittance(Bsdf b, float cos_o, float cos_i) {
    // No coat (KHR_materials_specular weight 0, as in a pure Lambertian): nothing to look up.
    if (b.specular == 0.0) return vec3(1.0);
    vec3 avg = coat_average(b);
    return (vec3(1.0) - coat_albedo(b, cos_o)) * (vec3(1.0) - coat_albedo(b, cos_i)) / max(vec3(1.0) - avg, vec3(1e-6));
}

// Kulla-Conty multiple scattering of the metal lobe: the energy single scattering loses, returned in a diffuse-like
// lobe coloured by the average Fresnel. Zero for a mirror (it loses nothing).
vec3 metal_multiple_scattering(Bsdf b, float cos_o, float cos_i) {
    if (!b.compensate || bsdf_is_delta(b)) return vec3(0.0);
    float e_avg = energy_average(0u, b.roughness);
    if (e_avg >= 1.0) return vec3(0.0);
    vec3 f_avg = b.base_color + (vec3(1.0) - b.base_color) / 21.0;
    vec3 f_ms = f_avg * f_avg * e_avg / (vec3(1.0) - f_avg * (1.0 - e_avg));
    float lobe = (1.0 - energy_lookup(0u, cos_o, b.roughness)) * (1.0 - energy_lookup(0u, cos_i, b.roughness)) / (PI * (1.0 - e_avg));
    return f_ms * lobe;
}

// ---- The layers over the base: sheen (Estevez and Kulla 2017, as KHR_materials_sheen gives it) under a clear coat.
// Each layer scales what lies below by one minus its own directional albedo at wo (albedo scaling), so a layer over
// a base that keeps all energy keeps all energy too: total = coat + (1 - Ecoat(wo)) (sheen + (1 - Esheen(wo)) base).
// The scaling looks only at wo, so the layered BSDF is not reciprocal; the layers alone are.

bool coat_is_delta(Bsdf b) {
    return b.coat_alpha < DELTA_ALPHA;
}

vec3 to_coat(Bsdf b, vec3 w) {
    return vec3(dot(w, b.coat_t), dot(w, b.coat_b), dot(w, b.coat_n));
}

vec3 from_coat(Bsdf b, vec3 w) {
    return w.x * b.coat_t + w.y * b.coat_b + w.z * b.coat_n;
}

float coat_fresnel(float c) {
    return CLEARCOAT_F0 + (1.0 - CLEARCOAT_F0) * schlick_weight(c);
}

// The coat's directional albedo at cos theta mu (in its own frame): weight times Schlick F0 E1 + (1 - F0) E2.
float clearcoat_albedo(Bsdf b, float mu) {
    if (b.clearcoat == 0.0 || mu <= 0.0) return 0.0;
    if (coat_is_delta(b)) return b.clearcoat * coat_fresnel(mu);
    return b.clearcoat * (CLEARCOAT_F0 * energy_lookup(0u, mu, b.coat_roughness) + (1.0 - CLEARCOAT_F0) * energy_lookup(1u, mu, b.coat_roughness));
}

// Charlie sheen with alpha = roughness^2, kept above 1e-3 so 1 / alpha stays finite.
float sheen_alpha(float roughness) {
    return max(roughness * roughness, 1e-3);
}

float charlie_d(float alpha, vec3 h) {
    float inv = 1.0 / alpha;
    float sin2 = h.x * h.x + h.y * h.y;
    return (2.0 + inv) * pow(sin2, 0.5 * inv) / (2.0 * PI);
}

// The fitted exponent of the sheen's shadowing (Estevez and Kulla's l(x)), interpolated in (1 - alpha)^2.
float sheen_l(float x, float alpha) {
    float t = (1.0 - alpha) * (1.0 - alpha);
    float a = mix(21.5473, 25.3245, t);
    float b = mix(3.82987, 3.32435, t);
    float c = mix(0.19823, 0.16801, t);
    float d = mix(-1.97760, -1.27393, t);
    float e = mix(-4.32054, -4.85967, t);
    return a / (1.0 + b * pow(x, c)) + d * x + e;
}

float sheen_lambda(float mu, float alpha) {
    return mu < 0.5 ? exp(sheen_l(mu, alpha)) : exp(2.0 * sheen_l(0.5, alpha) - sheen_l(1.0 - mu, alpha));
}

// The sheen lobe for a white colour, both directions above the surface.
float sheen_lobe(float roughness, vec3 wo, vec3 wi) {
    float alpha = sheen_alpha(roughness);
    vec3 h = normalize(wo + wi);
    float v = 1.0 / ((1.0 + sheen_lambda(wo.z, alpha) + sheen_lambda(wi.z, alpha)) * 4.0 * wo.z * wi.z);
    return charlie_d(alpha, h) * v;
}

float sheen_albedo(Bsdf b, float mu) {
    if (max3(b.sheen_color) == 0.0) return 0.0;
    return max3(b.sheen_color) * energy_lookup(2u, mu, b.sheen_roughness);
}

// The clear coat's albedo at wo (0 in scenes without one).
float coat_albedo_at(Bsdf b, vec3 wo) {
    return scene_has(FEATURE_CLEARCOAT) ? clearcoat_albedo(b, dot(wo, b.coat_n)) : 0.0;
}

// How much of the base (everything but the layers) is left at wo, given the coat's albedo there: the scale the layers
// put on it.
float base_weight_under(Bsdf b, vec3 wo, float coat) {
    float w = 1.0;
    if (scene_has(FEATURE_CLEARCOAT)) w *= 1.0 - coat;
    if (scene_has(FEATURE_SHEEN)) w *= 1.0 - sheen_albedo(b, wo.z);
    return w;
}

float base_weight(Bsdf b, vec3 wo) {
    return base_weight_under(b, wo, coat_albedo_at(b, wo));
}

// The coat lobe's f, for the integrator's cosine about the shading normal: the coat's own cosine replaces it, so the
// lobe keeps exactly the albedo its table gives even under its own normal map.
float clearcoat_eval(Bsdf b, vec3 wo, vec3 wi) {
    if (b.clearcoat == 0.0 || coat_is_delta(b) || wi.z <= 0.0) return 0.0;
    vec3 o = to_coat(b, wo);
    vec3 i = to_coat(b, wi);
    if (o.z <= 0.0 || i.z <= 0.0) return 0.0;
    float a2 = b.coat_alpha * b.coat_alpha;
    vec3 h = normalize(o + i);
    float g = 1.0 / (1.0 + smith_lambda(a2, o) + smith_lambda(a2, i));
    return b.clearcoat * coat_fresnel(dot(o, h)) * ggx_d(a2, h) * g / (4.0 * o.z * wi.z);
}

float clearcoat_pdf(Bsdf b, vec3 wo, vec3 wi) {
    if (coat_is_delta(b)) return 0.0;
    vec3 o = to_coat(b, wo);
    vec3 i = to_coat(b, wi);
    if (o.z <= 0.0 || i.z <= 0.0) return 0.0;
    float a2 = b.coat_alpha * b.coat_alpha;
    vec3 h = normalize(o + i);
    return ggx_d(a2, h) / (4.0 * (1.0 + smith_lambda(a2, o)) * o.z);
}

// Exact Fresnel reflectance of a dielectric interface; eta = n_t / n_i, cos_i > 0. 1 under total internal reflection.
float fresnel_dielectric(float cos_i, float eta) {
    float sin2_t = max(0.0, 1.0 - cos_i * cos_i) / (eta * eta);
    if (sin2_t >= 1.0) return 1.0;
    float cos_t = sqrt(1.0 - sin2_t);
    float r_parl = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    float r_perp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    return 0.5 * (r_parl * r_parl + r_perp * r_perp);
}

// Refracts wo (pointing away, on n's side) through a surface with normal n; false under total internal reflection.
bool refract_dir(vec3 wo, vec3 n, float eta, out vec3 wt) {
    float cos_i = dot(n, wo);
    float sin2_t = max(0.0, 1.0 - cos_i * cos_i) / (eta * eta);
    wt = vec3(0.0);
    if (sin2_t >= 1.0) return false;
    float cos_t = sqrt(1.0 - sin2_t);
    wt = -wo / eta + (cos_i / eta - cos_t) * n;
    return true;
}

// Lobe selection: the probability of the glass lobe (rough dielectric interface), of the specular reflections
// (coat and metal) and of the clear coat; the rest goes to the cosine lobe that samples everything diffuse-like,
// sheen included.
vec3 lobe_probabilities(Bsdf b, vec3 wo) {
    vec3 fd = dielectric_fresnel(b, wo.z);
    float opaque = (1.0 - b.metallic) * (1.0 - b.transmission);
    float spec = opaque * b.specular * luminance(fd) + b.metallic * luminance(metal_fresnel(b, wo.z));
    float diff = opaque * (1.0 - b.specular * max3(fd)) * luminance(b.base_color);
    if (b.compensate && !bsdf_is_delta(b) && b.metallic > 0.0) {
        diff += b.metallic * (1.0 - energy_lookup(0u, wo.z, b.roughness)) * luminance(b.base_color);
    }
    float glass = (1.0 - b.metallic) * b.transmission;
    float coat = 0.0;
    if (scene_has(FEATURE_CLEARCOAT | FEATURE_SHEEN)) {
        float cc = coat_albedo_at(b, wo);
        float w = base_weight_under(b, wo, cc);
        spec *= w;
        diff *= w;
        glass *= w;
        if (scene_has(FEATURE_SHEEN)) diff += (1.0 - cc) * luminance(b.sheen_color) * energy_lookup(2u, wo.z, b.sheen_roughness);
        coat = cc;
    }
    float total = spec + diff + glass + coat;
    if (total <= 0.0) return vec3(0.0, 1.0, 0.0);
    // Without a clear coat its share is a constant zero, which the lobe choice and the pdf then fold away.
    return vec3(glass / total, spec / total, scene_has(FEATURE_CLEARCOAT) ? coat / total : 0.0);
}

// The visible-normal density of the microfacet normal m seen from wo: G1(wo) D(m) max(0, wo.m) / wo.z.
float vndf_pdf(float a2, vec3 wo, vec3 m) {
    return ggx_d(a2, m) * max(0.0, dot(wo, m)) / ((1.0 + smith_lambda(a2, wo)) * wo.z);
}

// Thin-walled transmission mirrors the reflected direction through the surface plane.
vec3 flip_z(vec3 w) {
    return vec3(w.x, w.y, -w.z);
}

// An interface between equal indices changes nothing, however rough: light passes straight through (a delta).
// Treating it as a microfacet refraction would divide by a vanishing half vector.
bool glass_passes_through(Bsdf b) {
    return !b.thin && abs(b.eta - 1.0) < 1e-4;
}

// The glass lobe without its weight or tint: f and the density of sampling wi within the lobe.
// Reflection and transmission are chosen by Fresnel at the sampled microfacet (pbrt-v4's DielectricBxDF).
void glass_eval_pdf(Bsdf b, vec3 wo, vec3 wi, out vec3 f, out float pdf) {
    f = vec3(0.0);
    pdf = 0.0;
    if (bsdf_is_delta(b) || glass_passes_through(b) || wi.z == 0.0) return;
    float a2 = b.alpha * b.alpha;
    bool reflect_side = wi.z > 0.0;
    if (b.thin || reflect_side) {
        vec3 w = reflect_side ? wi : flip_z(wi);
        vec3 m = normalize(wo + w);
        float F = fresnel_dielectric(dot(wo, m), b.eta);
        float weight = reflect_side ? F : 1.0 - F;
        float g = 1.0 / (1.0 + smith_lambda(a2, wo) + smith_lambda(a2, w));
        f = vec3(ggx_d(a2, m) * g * weight / (4.0 * wo.z * w.z));
        pdf = vndf_pdf(a2, wo, m) / (4.0 * dot(wo, m)) * weight;
        if (!reflect_side) f *= b.base_color;
        return;
    }
    // Refraction: the generalised half vector, facing wo's side.
    vec3 m = normalize(wi * b.eta + wo);
    if (m.z < 0.0) m = -m;
    float wo_m = dot(wo, m);
    float wi_m = dot(wi, m);
    if (wo_m <= 0.0 || wi_m >= 0.0) return; // the microfacet must face wo and be crossed by wi
    float F = fresnel_dielectric(wo_m, b.eta);
    float denom = wi_m + wo_m / b.eta;
    float g = 1.0 / (1.0 + smith_lambda(a2, wo) + smith_lambda(a2, wi));
    float ft = ggx_d(a2, m) * (1.0 - F) * g * abs(wi_m * wo_m / (denom * denom * wi.z * wo.z));
    // Radiance is compressed by eta^2 entering a denser medium (and expanded leaving it).
    f = b.base_color * ft / (b.eta * b.eta);
    pdf = vndf_pdf(a2, wo, m) * abs(wi_m) / (denom * denom) * (1.0 - F);
}

// The base's f(wo, wi), below the layers.
vec3 base_eval(Bsdf b, vec3 wo, vec3 wi) {
    float glass_w = (1.0 - b.metallic) * b.transmission;
    vec3 glass_f = vec3(0.0);
    float glass_pdf;
    if (glass_w > 0.0) glass_eval_pdf(b, wo, wi, glass_f, glass_pdf);
    if (wi.z < 0.0) return glass_w * glass_f;
    float opaque = (1.0 - b.metallic) * (1.0 - b.transmission);
    vec3 h = normalize(wo + wi);
    float c = dot(wo, h);
    vec3 fd = dielectric_fresnel(b, c);
    vec3 diffuse = opaque * coat_transmittance(b, wo.z, wi.z) * b.base_color / PI;
    if (b.metallic > 0.0) diffuse += b.metallic * metal_multiple_scattering(b, wo.z, wi.z);
    // No specular lobe at all (a mirror's is a delta; a pure Lambertian has neither coat nor metal).
    if (bsdf_is_delta(b) || (opaque * b.specular == 0.0 && b.metallic == 0.0)) return diffuse + glass_w * glass_f;
    float a2 = b.alpha * b.alpha;
    float g = 1.0 / (1.0 + smith_lambda(a2, wo) + smith_lambda(a2, wi));
    float spec = ggx_d(a2, h) * g / (4.0 * wo.z * wi.z);
    return diffuse + spec * (opaque * b.specular * fd + b.metallic * metal_fresnel(b, c)) + glass_w * glass_f;
}

// f(wo, wi) without the cosine; zero for delta lobes.
vec3 bsdf_eval(Bsdf b, vec3 wo, vec3 wi) {
    if (wo.z <= 0.0 || wi.z == 0.0) return vec3(0.0);
    vec3 f = base_eval(b, wo, wi);
    if (scene_has(FEATURE_CLEARCOAT | FEATURE_SHEEN)) {
        float cc = coat_albedo_at(b, wo);
        vec3 under = f * base_weight_under(b, wo, cc);
        if (scene_has(FEATURE_SHEEN) && wi.z > 0.0 && max3(b.sheen_color) > 0.0) {
            under += (1.0 - cc) * b.sheen_color * sheen_lobe(b.sheen_roughness, wo, wi);
        }
        f = under;
        if (scene_has(FEATURE_CLEARCOAT)) f += vec3(clearcoat_eval(b, wo, wi));
    }
    return f;
}

// Solid-angle density with which bsdf_sample returns wi (delta lobes have none).
float bsdf_pdf(Bsdf b, vec3 wo, vec3 wi) {
    if (wo.z <= 0.0 || wi.z == 0.0) return 0.0;
    vec3 p = lobe_probabilities(b, wo);
    float pdf = 0.0;
    if (p.x > 0.0) {
        vec3 f;
        float glass_pdf;
        glass_eval_pdf(b, wo, wi, f, glass_pdf);
        pdf += p.x * glass_pdf;
    }
    if (wi.z < 0.0) return pdf;
    pdf += (1.0 - p.x - p.y - p.z) * wi.z / PI;
    if (scene_has(FEATURE_CLEARCOAT) && p.z > 0.0) pdf += p.z * clearcoat_pdf(b, wo, wi);
    if (scene_has(FEATURE_COAT | FEATURE_METAL) && !bsdf_is_delta(b)) {
        // Visible-normal sampling then reflection: D_wo(h) / (4 wo.h) = G1(wo) D(h) / (4 wo.z).
        float a2 = b.alpha * b.alpha;
        vec3 h = normalize(wo + wi);
        pdf += p.y * ggx_d(a2, h) / (4.0 * (1.0 + smith_lambda(a2, wo)) * wo.z);
    }
    return pdf;
}

// Heitz 2018, "Sampling the GGX distribution of visible normals".
vec3 sample_ggx_vndf(vec3 wo, float alpha, vec2 u) {
    vec3 vh = normalize(vec3(alpha * wo.x, alpha * wo.y, wo.z));
    float lensq = vh.x * vh.x + vh.y * vh.y;
    vec3 t1 = lensq > 0.0 ? vec3(-vh.y, vh.x, 0.0) * inversesqrt(lensq) : vec3(1.0, 0.0, 0.0);
    vec3 t2 = cross(vh, t1);
    float r = sqrt(u.x);
    float phi = 2.0 * PI * u.y;
    float p1 = r * cos(phi);
    float p2 = r * sin(phi);
    float s = 0.5 * (1.0 + vh.z);
    p2 = (1.0 - s) * sqrt(max(0.0, 1.0 - p1 * p1)) + s * p2;
    vec3 nh = p1 * t1 + p2 * t2 + sqrt(max(0.0, 1.0 - p1 * p1 - p2 * p2)) * vh;
    return normalize(vec3(alpha * nh.x, alpha * nh.y, max(1e-6, nh.z)));
}

struct BsdfSample {
    vec3 wi;
    vec3 weight;  // f * |cos| / pdf (for a delta lobe: its throughput over the lobe's probability)
    float pdf;    // 0 for a delta lobe
    bool delta;
};

// u.z picks the lobe (and, rescaled, reflection or transmission in the glass lobe), u.xy the direction.
// Returns false when the sample carries no energy.
bool bsdf_sample(Bsdf b, vec3 wo, vec3 u, out BsdfSample s) {
    s.wi = vec3(0.0, 0.0, 1.0);
    s.weight = vec3(0.0);
    s.pdf = 0.0;
    s.delta = false;
    if (wo.z <= 0.0) return false;
    vec3 p = lobe_probabilities(b, wo);
    // What the layers leave of the base, for the base's delta lobes (whose weights are not evaluated).
    float under = base_weight(b, wo);
    if (scene_has(FEATURE_TRANSMISSION) && u.z < p.x) {
        // The glass lobe. u_rt reuses u.z, rescaled to [0, 1), to choose reflection or transmission.
        float u_rt = u.z / p.x;
        float glass_w = (1.0 - b.metallic) * b.transmission;
        if (glass_passes_through(b)) {
            s.wi = -wo;
            s.delta = true;
            s.weight = b.base_color * (glass_w * under / p.x);
            return true;
        }
        if (bsdf_is_delta(b)) {
            float F = fresnel_dielectric(wo.z, b.eta);
            s.delta = true;
            if (u_rt < F) {
                s.wi = vec3(-wo.x, -wo.y, wo.z);
                s.weight = vec3(glass_w * under / p.x);
            } else if (b.thin) {
                s.wi = -wo;
                s.weight = b.base_color * (glass_w * under / p.x);
            } else {
                if (!refract_dir(wo, vec3(0.0, 0.0, 1.0), b.eta, s.wi)) return false;
                s.weight = b.base_color * (glass_w * under / (p.x * b.eta * b.eta));
            }
            return true;
        }
        vec3 m = sample_ggx_vndf(wo, b.alpha, u.xy);
        float F = fresnel_dielectric(dot(wo, m), b.eta);
        if (u_rt < F) {
            s.wi = reflect(-wo, m);
            if (s.wi.z <= 0.0) return false;
        } else if (b.thin) {
            s.wi = flip_z(reflect(-wo, m));
            if (s.wi.z >= 0.0) return false;
        } else {
            if (!refract_dir(wo, m, b.eta, s.wi) || s.wi.z >= 0.0) return false;
        }
    } else if (scene_has(FEATURE_COAT | FEATURE_METAL) && u.z < p.x + p.y) {
        if (bsdf_is_delta(b)) {
            s.wi = vec3(-wo.x, -wo.y, wo.z);
            s.delta = true;
            float opaque = (1.0 - b.metallic) * (1.0 - b.transmission);
            vec3 f = opaque * b.specular * dielectric_fresnel(b, wo.z) + b.metallic * metal_fresnel(b, wo.z);
            s.weight = f * under / p.y;
            return true;
        }
        vec3 h = sample_ggx_vndf(wo, b.alpha, u.xy);
        s.wi = reflect(-wo, h);
        if (s.wi.z <= 0.0) return false;
    } else if (scene_has(FEATURE_CLEARCOAT) && u.z < p.x + p.y + p.z) {
        // The clear coat, sampled in its own frame; a direction its normal map sends below the surface is lost.
        vec3 o = to_coat(b, wo);
        if (coat_is_delta(b)) {
            s.wi = from_coat(b, vec3(-o.x, -o.y, o.z));
            if (s.wi.z <= 0.0) return false;
            s.delta = true;
            s.weight = vec3(b.clearcoat * coat_fresnel(o.z) / p.z);
            return true;
        }
        s.wi = from_coat(b, reflect(-o, sample_ggx_vndf(o, b.coat_alpha, u.xy)));
        if (s.wi.z <= 0.0 || dot(s.wi, b.coat_n) <= 0.0) return false;
    } else {
        s.wi = sample_cosine_hemisphere(vec3(0.0, 0.0, 1.0), u.xy);
    }
    s.pdf = bsdf_pdf(b, wo, s.wi);
    if (!(s.pdf > 0.0)) return false;
    s.weight = bsdf_eval(b, wo, s.wi) * (abs(s.wi.z) / s.pdf);
    return true;
}

#endif
