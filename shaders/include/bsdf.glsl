// The glTF metallic-roughness BSDF (spec Appendix B, with KHR_materials_ior and KHR_materials_specular):
// eval, sample and pdf live together here, in the shading frame (z = normal), so they cannot drift apart.
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
};

Bsdf bsdf_from_material(Material m) {
    Bsdf b;
    b.base_color = m.base_color.rgb;
    b.metallic = m.params.x;
    b.roughness = m.params.y;
    b.alpha = m.params.y * m.params.y;
    float ior = m.params.z;
    float r = (ior - 1.0) / (ior + 1.0);
    b.specular = m.params.w;
    b.specular_f0 = min(vec3(r * r) * m.specular_color.rgb, vec3(1.0));
    b.compensate = (frame.flags & FLAG_ENERGY_COMPENSATION) != 0u;
    return b;
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

// Bilinear lookup in one of the energy tables (table 0: E1, 1: E2) at (cos theta, roughness).
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
    uint base = 2u * ENERGY_RES * ENERGY_RES + table * ENERGY_RES + y0;
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

// The weight of the specular lobe against the diffuse one, as the probability of sampling it.
float specular_probability(Bsdf b, vec3 wo) {
    vec3 fd = dielectric_fresnel(b, wo.z);
    float spec = (1.0 - b.metallic) * b.specular * luminance(fd) + b.metallic * luminance(metal_fresnel(b, wo.z));
    // Everything diffuse-like (the base under the coat, the metal's multiple scattering) is sampled by the cosine lobe.
    float diff = (1.0 - b.metallic) * (1.0 - b.specular * max3(fd)) * luminance(b.base_color);
    if (b.compensate && !bsdf_is_delta(b)) diff += b.metallic * (1.0 - energy_lookup(0u, wo.z, b.roughness)) * luminance(b.base_color);
    if (spec + diff <= 0.0) return 1.0;
    return spec / (spec + diff);
}

// f(wo, wi) without the cosine; zero for the delta part of a mirror.
vec3 bsdf_eval(Bsdf b, vec3 wo, vec3 wi) {
    if (wo.z <= 0.0 || wi.z <= 0.0) return vec3(0.0);
    vec3 h = normalize(wo + wi);
    float c = dot(wo, h);
    vec3 fd = dielectric_fresnel(b, c);
    vec3 diffuse = (1.0 - b.metallic) * coat_transmittance(b, wo.z, wi.z) * b.base_color / PI
        + b.metallic * metal_multiple_scattering(b, wo.z, wi.z);
    if (bsdf_is_delta(b)) return diffuse;
    float a2 = b.alpha * b.alpha;
    float g = 1.0 / (1.0 + smith_lambda(a2, wo) + smith_lambda(a2, wi));
    float spec = ggx_d(a2, h) * g / (4.0 * wo.z * wi.z);
    return diffuse + spec * ((1.0 - b.metallic) * b.specular * fd + b.metallic * metal_fresnel(b, c));
}

// Solid-angle density with which bsdf_sample returns wi (the delta part of a mirror has none).
float bsdf_pdf(Bsdf b, vec3 wo, vec3 wi) {
    if (wo.z <= 0.0 || wi.z <= 0.0) return 0.0;
    float ps = specular_probability(b, wo);
    float pdf = (1.0 - ps) * wi.z / PI;
    if (!bsdf_is_delta(b)) {
        // Visible-normal sampling then reflection: D_wo(h) / (4 wo.h) = G1(wo) D(h) / (4 wo.z).
        float a2 = b.alpha * b.alpha;
        vec3 h = normalize(wo + wi);
        pdf += ps * ggx_d(a2, h) / (4.0 * (1.0 + smith_lambda(a2, wo)) * wo.z);
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
    vec3 weight;  // f * cos / pdf (for a delta lobe: its reflectance over the lobe's probability)
    float pdf;    // 0 for a delta lobe
    bool delta;
};

// u.z picks the lobe, u.xy the direction. Returns false when the sample carries no energy.
bool bsdf_sample(Bsdf b, vec3 wo, vec3 u, out BsdfSample s) {
    s.wi = vec3(0.0, 0.0, 1.0);
    s.weight = vec3(0.0);
    s.pdf = 0.0;
    s.delta = false;
    if (wo.z <= 0.0) return false;
    float ps = specular_probability(b, wo);
    if (u.z < ps) {
        if (bsdf_is_delta(b)) {
            s.wi = vec3(-wo.x, -wo.y, wo.z);
            s.delta = true;
            vec3 f = (1.0 - b.metallic) * b.specular * dielectric_fresnel(b, wo.z) + b.metallic * metal_fresnel(b, wo.z);
            s.weight = f / ps;
            return true;
        }
        vec3 h = sample_ggx_vndf(wo, b.alpha, u.xy);
        s.wi = reflect(-wo, h);
        if (s.wi.z <= 0.0) return false;
    } else {
        s.wi = sample_cosine_hemisphere(vec3(0.0, 0.0, 1.0), u.xy);
    }
    s.pdf = bsdf_pdf(b, wo, s.wi);
    if (!(s.pdf > 0.0)) return false;
    s.weight = bsdf_eval(b, wo, s.wi) * (s.wi.z / s.pdf);
    return true;
}

#endif
