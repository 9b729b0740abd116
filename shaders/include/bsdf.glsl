// The glTF metallic-roughness BSDF (spec Appendix B, with KHR_materials_ior, _specular, _transmission, _volume, and
// _anisotropy, _iridescence, _diffuse_transmission, _diffuse_roughness, and the _sheen and _clearcoat layers over it):
// eval, sample and pdf live together here, in the shading frame (z = normal on wo's side), so they cannot drift apart.
#ifndef BSDF_GLSL
#define BSDF_GLSL

#include "sampling.glsl"
#include "spectrum.glsl"

// GGX alpha below this is a perfect mirror: the lobe becomes a delta (sampled, never evaluated).
const float DELTA_ALPHA = 1e-4;

// Colours are Spectrum (spectrum.glsl): RGB, or the path's wavelengths under FEATURE_SPECTRAL.
struct Bsdf {
    Spectrum base_color;
    Spectrum diffuse_color; // the diffuse lobe's albedo: base_color, but where a thin wall scatters (thin_scatter)
    float metallic;
    float roughness;      // perceptual, for the energy tables
    float alpha;          // GGX alpha = roughness^2
    float specular;       // KHR_materials_specular weight of the dielectric layer
    Spectrum specular_f0; // dielectric F0 = min(((ior - 1) / (ior + 1))^2 * specularColor, 1)
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
    Spectrum sheen_color; // KHR_materials_sheen (black: no sheen)
    float sheen_roughness;
    bool anisotropic;     // KHR_materials_anisotropy: the base's GGX lobes have alpha_xy along aniso_dir and across it
    vec2 aniso_alpha;
    vec2 aniso_dir;       // unit, in the shading frame's xy (the tangent frame)
    float iridescence;    // KHR_materials_iridescence: how much of the base's Fresnel is the thin film's
    float film_ior;
    float film_thickness; // nm
    float outside_ior;    // above the film: air, or the clear coat's 1.5
    float diffuse_transmission; // KHR_materials_diffuse_transmission: the share of the diffuse lobe that passes
    Spectrum dt_color;
    float diffuse_roughness; // KHR_materials_diffuse_roughness: EON's r (0: the Lambertian lobe)
    // Hemispherical averages a stretched lobe or a film needs on every evaluation, computed once per hit (see
    // bsdf_averages): inlined at each evaluation they made every stage's pipeline several times larger before
    // specialisation folded them away.
    Spectrum coat_avg;
    float metal_e_avg;
    Spectrum metal_f_avg;
    // What every evaluation at the hit's wo shares, computed once by bsdf_at: eval, pdf and sample all see from wo,
    // and lavapipe runs each table lookup for every lane wherever it stands in the code, taken or not (the dielectric
    // layer's multiple scattering, read up to fourteen times a hit, made layers.gltf's shade stage 2.4x slower).
    vec3 wo;
    vec4 lobe_p;          // lobe_probabilities at wo
    float under;          // base_weight_under at wo: what the sheen and clear coat leave of the base
    Spectrum coat_albedo_o; // the dielectric layer's directional albedo at wo
    Spectrum coat_ms_o;   // its multiple scattering at wo, and the hemispherical average of that
    Spectrum coat_ms_avg;
    float metal_e_o;      // the metal lobe's single-scattering albedo at wo
    float clearcoat_o;    // the clear coat's albedo at wo
};

Spectrum coat_average(Bsdf b);
float spec_energy_average(Bsdf b, uint table);
Spectrum film_average(Bsdf b, Spectrum f0, bool albedo);
float film_weight(Bsdf b);

// Only where a lobe is stretched or filmed: the isotropic averages are two table reads, cheaper at their use.
bool bsdf_needs_averages() {
    return scene_has(FEATURE_ANISOTROPY | FEATURE_IRIDESCENCE);
}

// The layer's average is kept in the Bsdf where a stretched lobe or a film needs it, or where the multiple scattering
// adds a trilinear lookup to it (read by every evaluation of a diffuse lobe, twice a hit).
bool coat_average_kept() {
    return bsdf_needs_averages() || scene_has(FEATURE_DIELECTRIC_MS);
}

void bsdf_averages(inout Bsdf b) {
    b.coat_avg = Spectrum(0.0);
    b.metal_e_avg = 0.0;
    b.metal_f_avg = Spectrum(0.0);
    if (coat_average_kept() && b.specular > 0.0) b.coat_avg = coat_average(b);
    if (!bsdf_needs_averages()) return;
    if (b.metallic > 0.0) {
        b.metal_e_avg = spec_energy_average(b, 0u);
        b.metal_f_avg = b.base_color + (Spectrum(1.0) - b.base_color) / 21.0;
        if (film_weight(b) > 0.0) b.metal_f_avg = mix(b.metal_f_avg, film_average(b, b.base_color, false), film_weight(b));
    }
}

// The smallest alpha across an anisotropic lobe: a line-shaped distribution has no finite density.
const float ANISO_MIN_ALPHA = 1e-3;

// KHR_materials_clearcoat fixes the coat's IOR at 1.5.
const float CLEARCOAT_F0 = 0.04;

// KHR_materials_scatter's thin-walled mode (FEATURE_THIN_SCATTER): strength S of the transmission lobe becomes the
// draft's scatter_bsdf, Lambertian both ways in colour C, (1 + g) / 2 of it through the surface and (1 - g) / 2 back.
// Its base is mix(diffuse(baseColor), mix(btdf baseColor, scatter_bsdf, S), T) under fresnel_mix's dielectric layer,
// so the scattering joins the diffuse lobe under the layer: the glass keeps T (1 - S), and the diffuse lobe (the
// share W = 1 - T (1 - S) of the base) reflects (1 - T) baseColor + T S (1 - g) / 2 C and sends T S (1 + g) / 2 C
// through, as diffuse transmission does. Its reflection's albedo stays within 1: W - T S (1 + g) / 2 bounds it.
void thin_scatter(inout Bsdf b, Material m) {
    float t = b.transmission;
    float s = clamp(m.transmission.w, 0.0, 1.0);
    float g = m.medium.w;
    Spectrum c = spectrum_reflectance(m.medium.rgb);
    float w = 1.0 - t * (1.0 - s);
    float through = t * s * 0.5 * (1.0 + g);
    float back = t * s * 0.5 * (1.0 - g);
    b.transmission = t * (1.0 - s);
    b.diffuse_transmission = through / w;
    b.dt_color = c;
    b.diffuse_color = ((1.0 - t) * b.base_color + back * c) / max(w - through, 1e-7);
}

// front: wo is on the front (counter-clockwise) side, outside the object.
Bsdf bsdf_from_material(Material m, bool front) {
    Bsdf b;
    b.base_color = spectrum_reflectance_known(m.base_color.rgb, m.base_color_spectrum);
    // A lobe no material in the scene has is a constant zero, and the code for it folds away (see scene_has).
    b.metallic = scene_has(FEATURE_METAL) ? m.params.x : 0.0;
    b.roughness = m.params.y;
    b.alpha = m.params.y * m.params.y;
    float ior = m.params.z;
    // A dispersive volume's IOR at the hero wavelength, the only one its paths keep (shade_path).
    if (spectral() && m.transmission.z > 0.0) ior = dispersive_ior(ior, m.transmission.z, path_lambda.x);
    float r = (ior - 1.0) / (ior + 1.0);
    b.specular = scene_has(FEATURE_COAT) ? m.params.w : 0.0;
    b.specular_f0 = min(Spectrum(r * r) * spectrum_unbounded(m.specular_color.rgb), Spectrum(1.0));
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
    b.sheen_color = scene_has(FEATURE_SHEEN) ? spectrum_reflectance(m.sheen.rgb) : Spectrum(0.0);
    b.sheen_roughness = m.sheen.w;
    b.anisotropic = scene_has(FEATURE_ANISOTROPY) && m.anisotropy.x > 0.0;
    b.aniso_dir = m.anisotropy.yz;
    b.aniso_alpha = vec2(b.alpha);
    b.iridescence = scene_has(FEATURE_IRIDESCENCE) ? m.iridescence.x : 0.0;
    b.film_ior = m.iridescence.y;
    b.film_thickness = m.iridescence.w;
    b.outside_ior = b.clearcoat > 0.0 ? 1.5 : 1.0;
    b.diffuse_transmission = scene_has(FEATURE_DIFFUSE_TRANSMISSION) ? m.diffuse_transmission.w : 0.0;
    b.dt_color = scene_has(FEATURE_DIFFUSE_TRANSMISSION) ? spectrum_reflectance(m.diffuse_transmission.rgb) : Spectrum(0.0);
    b.diffuse_roughness = scene_has(FEATURE_DIFFUSE_ROUGHNESS) ? clamp(m.specular_color.w, 0.0, 1.0) : 0.0;
    b.diffuse_color = b.base_color;
    if (scene_has(FEATURE_THIN_SCATTER) && b.thin && m.transmission.w > 0.0 && b.transmission > 0.0) thin_scatter(b, m);
    if (b.anisotropic) {
        float s = m.anisotropy.x;
        b.aniso_alpha = vec2(mix(b.alpha, 1.0, s * s), max(b.alpha, ANISO_MIN_ALPHA));
        // A stretched lobe is a mirror only when both of its axes are; its energy has tables of its own.
        b.alpha = b.aniso_alpha.x;
    }
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

// The base's microfacet distribution, masking and visible normals, isotropic or stretched along aniso_dir. The
// stretched forms rotate the direction into the lobe's axes and are the isotropic ones with alpha per axis.
vec3 to_aniso(Bsdf b, vec3 w) {
    return vec3(b.aniso_dir.x * w.x + b.aniso_dir.y * w.y, b.aniso_dir.x * w.y - b.aniso_dir.y * w.x, w.z);
}

vec3 from_aniso(Bsdf b, vec3 w) {
    return vec3(b.aniso_dir.x * w.x - b.aniso_dir.y * w.y, b.aniso_dir.y * w.x + b.aniso_dir.x * w.y, w.z);
}

float spec_d(Bsdf b, vec3 h) {
    if (scene_has(FEATURE_ANISOTROPY) && b.anisotropic) {
        vec3 a = to_aniso(b, h);
        float x = a.x / b.aniso_alpha.x;
        float y = a.y / b.aniso_alpha.y;
        float d = x * x + y * y + a.z * a.z;
        return 1.0 / (PI * b.aniso_alpha.x * b.aniso_alpha.y * d * d);
    }
    return ggx_d(b.alpha * b.alpha, h);
}

// Smith's Lambda of the lobe with alphas `alpha` along x and y, for w in the lobe's axes.
float stretched_lambda(vec2 alpha, vec3 w) {
    float x = alpha.x * w.x;
    float y = alpha.y * w.y;
    return 0.5 * (sqrt(1.0 + (x * x + y * y) / max(w.z * w.z, 1e-20)) - 1.0);
}

float spec_lambda(Bsdf b, vec3 w) {
    if (scene_has(FEATURE_ANISOTROPY) && b.anisotropic) return stretched_lambda(b.aniso_alpha, to_aniso(b, w));
    return smith_lambda(b.alpha * b.alpha, w);
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

// ---- The thin film of KHR_materials_iridescence (Belcour and Barla 2017, "A Practical Extension to Microfacet
// Theory for the Modeling of Varying Iridescence", with the extension's simplifications: no polarisation, a metal's
// IOR taken from its F0 as if it were real. The interfaces reflect by the exact dielectric Fresnel, not the
// extension's Schlick: Schlick reflects (1 - cos)^5 off an interface between equal indices, which is no interface,
// and the film then kept 0.89 of a white plastic's energy at 85 degrees).

// The CIE 1931 matching functions' Fourier transform at the phase `phase` (the paper's Gaussian fit, per X, Y, Z),
// shifted by `shift`, normalised by Y's integral and taken to linear Rec. 709: the response of each RGB channel to one
// cosine term of the film's reflectance spectrum.
vec3 film_sensitivity(float opd_nm, vec3 shift) {
    float phase = 2.0 * PI * opd_nm * 1e-9;
    const vec3 amplitude = vec3(5.4856e-13, 4.4201e-13, 5.2481e-13);
    const vec3 centre = vec3(1.6810e+06, 1.7953e+06, 2.2084e+06);
    const vec3 spread = vec3(4.3278e+09, 9.3046e+09, 6.6121e+09);
    vec3 xyz = amplitude * sqrt(2.0 * PI * spread) * cos(centre * phase + shift) * exp(-phase * phase * spread);
    // X has a second lobe (the blue hump of x-bar).
    xyz.x += 9.7470e-14 * sqrt(2.0 * PI * 4.5282e+09) * cos(2.2399e+06 * phase + shift.x) * exp(-4.5282e+09 * phase * phase);
    xyz /= 1.0685e-7;
    const mat3 xyz_to_rec709 = mat3(3.2404542, -0.9692660, 0.0556434, -1.5371385, 1.8760108, -0.2040259, -0.4985314,
                                    0.0415560, 1.0572252);
    return xyz_to_rec709 * xyz;
}

// Reflectance of a film of IOR film_ior and thickness_nm over a base of normal-incidence reflectance base_f0, seen at
// cos1 from a medium of IOR outside_ior, per channel: the first reflection, plus the light that crosses the film and
// returns after any number of bounces inside it, summed with the phases their paths pick up (the Airy series, its
// first two interference orders integrated against the eye's response in closed form).
Spectrum thin_film_fresnel(float outside_ior, float film_ior, float thickness_nm, Spectrum base_f0, float cos1) {
    float n2 = film_ior;
    float sin2_sq = (outside_ior / n2) * (outside_ior / n2) * (1.0 - cos1 * cos1);
    if (sin2_sq >= 1.0) return Spectrum(1.0); // total internal reflection at the film
    float cos2 = sqrt(1.0 - sin2_sq);
    // Outside -> film.
    float R12 = fresnel_dielectric(cos1, n2 / outside_ior);
    float T121 = 1.0 - R12;
    float phi12 = n2 < outside_ior ? PI : 0.0;
    float phi21 = PI - phi12;
    // Film -> base, the base's IOR from its F0 (kept below 1 so the IOR stays finite).
    Spectrum s = sqrt(min(base_f0, Spectrum(0.9999)));
    Spectrum n3 = (Spectrum(1.0) + s) / (Spectrum(1.0) - s);
    Spectrum R23 = Spectrum(fresnel_dielectric(cos2, n3.x / n2), fresnel_dielectric(cos2, n3.y / n2),
                            fresnel_dielectric(cos2, n3.z / n2), spectral() ? fresnel_dielectric(cos2, n3.w / n2) : 0.0);
    Spectrum phi23 = mix(Spectrum(0.0), Spectrum(PI), lessThan(n3, Spectrum(n2)));
    // The optical path difference of one round trip through the film.
    float opd = 2.0 * n2 * thickness_nm * cos2;
    Spectrum phi = Spectrum(phi21) + phi23;
    // (No floor above 0: a film matching the medium above it must leave the base's Fresnel exactly.)
    Spectrum R123 = clamp(R12 * R23, Spectrum(0.0), Spectrum(0.9999));
    Spectrum r123 = sqrt(R123);
    Spectrum Rs = T121 * T121 * R23 / (Spectrum(1.0) - R123);
    // The incoherent sum (the series' mean), then its interference terms, which fall off with r123^m. At one
    // wavelength a term is the cosine of its phase; in RGB it is that cosine integrated against each channel.
    Spectrum I = R12 + Rs;
    Spectrum Cm = Rs - T121;
    for (int k = 1; k <= 2; ++k) {
        Cm *= r123;
        Spectrum term = spectral() ? cos(float(k) * (2.0 * PI * opd / path_lambda + phi))
                                   : Spectrum(film_sensitivity(float(k) * opd, float(k) * phi.xyz), 0.0);
        I += Cm * 2.0 * term;
    }
    return clamp(I, Spectrum(0.0), Spectrum(1.0));
}

// How much of the base's Fresnel is the film's: the material's factor, faded out below a few tens of nanometres, as
// light cannot resolve so thin a film (the extension fades the film's IOR instead, which leaves Schlick's reflection
// off the first interface: at 85 degrees a film of no thickness then lost 9 % of a white plastic's energy).
float film_weight(Bsdf b) {
    return scene_has(FEATURE_IRIDESCENCE) ? b.iridescence * smoothstep(0.0, 30.0, b.film_thickness) : 0.0;
}

// The film over F0 at c, blended in by film_weight.
Spectrum with_film(Bsdf b, Spectrum schlick, Spectrum f0, float c) {
    float w = film_weight(b);
    if (w == 0.0) return schlick;
    return mix(schlick, thin_film_fresnel(b.outside_ior, b.film_ior, b.film_thickness, f0, c), w);
}

// Fresnel of the dielectric layer (per channel) and of the metal, at the cosine c between wo and the microfacet normal.
Spectrum dielectric_fresnel(Bsdf b, float c) {
    return with_film(b, b.specular_f0 + (Spectrum(1.0) - b.specular_f0) * schlick_weight(c), b.specular_f0, c);
}

Spectrum metal_fresnel(Bsdf b, float c) {
    return with_film(b, b.base_color + (Spectrum(1.0) - b.base_color) * schlick_weight(c), b.base_color, c);
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

// Table 0 (E1) or 1 (E2) of the base's lobe seen from w, as bilinear energy_lookup reads the isotropic ones; a
// stretched lobe reads its own grids, quadrilinearly in (cos theta, azimuth against the stretch, both roughnesses).
float aniso_lookup(uint table, float mu, float phi, vec2 rough) {
    float x = clamp(mu, 0.0, 1.0) * float(ANISO_RES_MU - 1u);
    float y = clamp(phi * (2.0 / PI), 0.0, 1.0) * float(ANISO_RES_PHI - 1u);
    vec2 z = clamp(rough, vec2(0.0), vec2(1.0)) * float(ANISO_RES_ROUGH - 1u);
    uint x0 = min(uint(x), ANISO_RES_MU - 2u);
    uint y0 = min(uint(y), ANISO_RES_PHI - 2u);
    uvec2 z0 = min(uvec2(z), uvec2(ANISO_RES_ROUGH - 2u));
    vec4 f = vec4(x - float(x0), y - float(y0), z - vec2(z0));
    uint base = ENERGY_TABLE_FLOATS + table * ANISO_CELLS;
    float result = 0.0;
    // Kept a loop: unrolled at each of its uses it was most of a pipeline's size.
    [[dont_unroll]] for (uint c = 0u; c < 16u; ++c) {
        uvec4 d = uvec4(c & 1u, (c >> 1u) & 1u, (c >> 2u) & 1u, (c >> 3u) & 1u);
        vec4 w = mix(vec4(1.0) - f, f, vec4(d));
        uint k = x0 + d.x + ANISO_RES_MU * (y0 + d.y + ANISO_RES_PHI * (z0.x + d.z + ANISO_RES_ROUGH * (z0.y + d.w)));
        result += w.x * w.y * w.z * w.w * energy[base + k];
    }
    return result;
}

// The stretched lobe's perceptual roughnesses along and across its direction, as its tables index them.
vec2 aniso_roughness(Bsdf b) {
    return sqrt(b.aniso_alpha);
}

float spec_energy(Bsdf b, uint table, vec3 w) {
    if (scene_has(FEATURE_ANISOTROPY) && b.anisotropic) {
        vec3 a = to_aniso(b, w);
        // The albedo is even in both axes: a quarter turn of azimuths covers every direction.
        return aniso_lookup(table, a.z, atan(abs(a.y), max(abs(a.x), 1e-20)), aniso_roughness(b));
    }
    return energy_lookup(table, w.z, b.roughness);
}

// The hemispherical average of spec_energy's table 0 or 1.
float spec_energy_average(Bsdf b, uint table) {
    if (scene_has(FEATURE_ANISOTROPY) && b.anisotropic) {
        vec2 z = clamp(aniso_roughness(b), vec2(0.0), vec2(1.0)) * float(ANISO_RES_ROUGH - 1u);
        uvec2 z0 = min(uvec2(z), uvec2(ANISO_RES_ROUGH - 2u));
        vec2 f = z - vec2(z0);
        uint base = ENERGY_TABLE_FLOATS + 2u * ANISO_CELLS + table * ANISO_RES_ROUGH * ANISO_RES_ROUGH;
        uint k = base + z0.y * ANISO_RES_ROUGH + z0.x;
        float a = mix(energy[k], energy[k + 1u], f.x);
        float c = mix(energy[k + ANISO_RES_ROUGH], energy[k + ANISO_RES_ROUGH + 1u], f.x);
        return mix(a, c, f.y);
    }
    return energy_average(table, b.roughness);
}

// Directional albedo of the dielectric coat's single scattering seen from w, per channel (Schlick is linear in F0).
// The thin film's albedo for the base's lobe seen from w: E1 times the film's reflectance at the cosine where
// Schlick's weight equals the lobe's mean one (E2 / E1). Exact for a mirror (the cosine is then w's own) and for a
// film that is no film; for rough lobes an approximation (tests/bsdf/ measures it: a white plastic under a strong
// film returns 0.98 to 1.02 of what arrives; the film's reflectance at w's own cosine was off by 8 % at grazing).
Spectrum film_albedo(Bsdf b, Spectrum f0, vec3 w) {
    float e1 = bsdf_is_delta(b) ? 1.0 : spec_energy(b, 0u, w);
    float e2 = bsdf_is_delta(b) ? schlick_weight(w.z) : spec_energy(b, 1u, w);
    float c = 1.0 - pow(clamp(e2 / max(e1, 1e-6), 0.0, 1.0), 0.2);
    return e1 * thin_film_fresnel(b.outside_ior, b.film_ior, b.film_thickness, f0, c);
}

// 2 int film_albedo mu dmu over the hemisphere, by four-point Gauss-Legendre in mu (the film's colour changes slowly
// with angle next to the lobe's own falloff); `albedo` false averages the film's reflectance alone (E1 = 1).
Spectrum film_average(Bsdf b, Spectrum f0, bool albedo) {
    const vec4 x = vec4(0.0694318, 0.3300095, 0.6699905, 0.9305682);
    const vec4 w = vec4(0.1739274, 0.3260726, 0.3260726, 0.1739274);
    Spectrum sum = Spectrum(0.0);
    [[dont_unroll]] for (uint k = 0u; k < 4u; ++k) {
        float mu = x[k];
        Spectrum f = albedo ? film_albedo(b, f0, vec3(sqrt(1.0 - mu * mu), 0.0, mu))
                        : thin_film_fresnel(b.outside_ior, b.film_ior, b.film_thickness, f0, mu);
        sum += w[k] * 2.0 * mu * f;
    }
    return sum;
}

// ---- The dielectric layer's multiple scattering: what bounces between its microfacets more than once, which single-
// scattering GGX loses (4 to 13 % of a dark plastic's reflection at roughness 0.5 to 1, most of it at grazing angles).
// Its albedo E_ms comes from the random walk on the microsurface (microsurface.rs), tabulated over (cos theta,
// roughness, F0) since a dielectric's bounces meet Fresnel at angles no average stands for: Kulla and Conty's
// F_avg^2 E_avg / (1 - F_avg (1 - E_avg)) (1 - E(mu)), right for metals, returns a twentieth of it at grazing angles
// for F0 0.04. It is returned in the reciprocal lobe E_ms(mu_o) E_ms(mu_i) / (pi E_ms_avg), whose albedo is E_ms
// exactly; its directions are the cosine lobe's to sample.

// The table (DIELECTRIC_MS) at (cos theta, perceptual roughness, F0), trilinear with F0 on its square-root axis.
float dielectric_ms_lookup(float mu, float roughness, float f0) {
    float x = clamp(mu, 0.0, 1.0) * float(MS_RES_MU - 1u);
    float y = clamp(roughness, 0.0, 1.0) * float(MS_RES_ROUGH - 1u);
    float z = sqrt(clamp(f0, 0.0, 1.0)) * float(MS_RES_F0 - 1u);
    uint x0 = min(uint(x), MS_RES_MU - 2u);
    uint y0 = min(uint(y), MS_RES_ROUGH - 2u);
    uint z0 = min(uint(z), MS_RES_F0 - 2u);
    float fx = x - float(x0);
    float fy = y - float(y0);
    uint k = DIELECTRIC_MS + (z0 * MS_RES_ROUGH + y0) * MS_RES_MU + x0;
    const uint slice = MS_RES_ROUGH * MS_RES_MU;
    float lo = mix(mix(energy[k], energy[k + 1u], fx), mix(energy[k + MS_RES_MU], energy[k + MS_RES_MU + 1u], fx), fy);
    k += slice;
    float hi = mix(mix(energy[k], energy[k + 1u], fx), mix(energy[k + MS_RES_MU], energy[k + MS_RES_MU + 1u], fx), fy);
    return mix(lo, hi, z - float(z0));
}

// The table's hemispherical average 2 int E_ms mu dmu at (roughness, F0), bilinear.
float dielectric_ms_average(float roughness, float f0) {
    float y = clamp(roughness, 0.0, 1.0) * float(MS_RES_ROUGH - 1u);
    float z = sqrt(clamp(f0, 0.0, 1.0)) * float(MS_RES_F0 - 1u);
    uint y0 = min(uint(y), MS_RES_ROUGH - 2u);
    uint z0 = min(uint(z), MS_RES_F0 - 2u);
    uint k = DIELECTRIC_MS + MS_RES_MU * MS_RES_ROUGH * MS_RES_F0 + z0 * MS_RES_ROUGH + y0;
    float fy = y - float(y0);
    return mix(mix(energy[k], energy[k + 1u], fy), mix(energy[k + MS_RES_ROUGH], energy[k + MS_RES_ROUGH + 1u], fy),
               z - float(z0));
}

// The table is isotropic: a stretched lobe reads it at the roughness of its alphas' geometric mean.
float ms_roughness(Bsdf b) {
    if (scene_has(FEATURE_ANISOTROPY) && b.anisotropic) return sqrt(sqrt(b.aniso_alpha.x * b.aniso_alpha.y));
    return b.roughness;
}

// Only a layer over an opaque base has it (glass and metals have no base under a layer); FEATURE_DIELECTRIC_MS folds
// it out of scenes with none.
bool coat_ms_on(Bsdf b) {
    return scene_has(FEATURE_DIELECTRIC_MS) && b.compensate && !bsdf_is_delta(b) && b.specular > 0.0 &&
           b.metallic < 1.0 && b.transmission < 1.0;
}

// F0 differs across the channels (a tinted KHR_materials_specular): each channel reads the table; a grey F0, the
// common case, reads it once.
bool coat_ms_tinted(Bsdf b) {
    Spectrum f0 = b.specular_f0;
    return f0.y != f0.x || f0.z != f0.x || (spectral() && f0.w != f0.x);
}

// E_ms per channel at cos theta mu, times the layer's weight. The thin film tints single scattering only: the walk's
// F0 is the layer's own.
Spectrum coat_ms(Bsdf b, float mu) {
    if (!coat_ms_on(b)) return Spectrum(0.0);
    float r = ms_roughness(b);
    Spectrum e = Spectrum(dielectric_ms_lookup(mu, r, b.specular_f0.x));
    if (coat_ms_tinted(b)) {
        for (int c = 1; c < (spectral() ? 4 : 3); ++c) e[c] = dielectric_ms_lookup(mu, r, b.specular_f0[c]);
    }
    if (!spectral()) e.w = 0.0;
    return b.specular * e;
}

// coat_ms's hemispherical average 2 int E_ms mu dmu.
Spectrum coat_ms_average(Bsdf b) {
    if (!coat_ms_on(b)) return Spectrum(0.0);
    float r = ms_roughness(b);
    Spectrum e = Spectrum(dielectric_ms_average(r, b.specular_f0.x));
    if (coat_ms_tinted(b)) {
        for (int c = 1; c < (spectral() ? 4 : 3); ++c) e[c] = dielectric_ms_average(r, b.specular_f0[c]);
    }
    if (!spectral()) e.w = 0.0;
    return b.specular * e;
}

// The layer's multiple-scattering lobe from wo to wi, reciprocal, with albedo coat_ms(mu_o); ms_i = coat_ms at wi.
Spectrum coat_ms_eval(Bsdf b, Spectrum ms_i) {
    if (!coat_ms_on(b)) return Spectrum(0.0);
    return b.coat_ms_o * ms_i / max(PI * b.coat_ms_avg, Spectrum(1e-12));
}

// The layer's directional albedo seen from w: single scattering, then ms = coat_ms at w, what its microsurface returns
// after more bounces.
Spectrum coat_albedo(Bsdf b, vec3 w, Spectrum ms) {
    if (bsdf_is_delta(b)) return b.specular * dielectric_fresnel(b, w.z);
    Spectrum a = b.specular_f0 * spec_energy(b, 0u, w) + (Spectrum(1.0) - b.specular_f0) * spec_energy(b, 1u, w);
    if (film_weight(b) > 0.0) a = mix(a, film_albedo(b, b.specular_f0, w), film_weight(b));
    return b.specular * a + ms;
}

Spectrum coat_average(Bsdf b) {
    Spectrum a;
    if (bsdf_is_delta(b)) {
        // For a mirror, E1 = 1 and the average of (1 - mu)^5 over the projected hemisphere is 1/21.
        a = b.specular_f0 + (Spectrum(1.0) - b.specular_f0) / 21.0;
    } else {
        a = b.specular_f0 * spec_energy_average(b, 0u) + (Spectrum(1.0) - b.specular_f0) * spec_energy_average(b, 1u);
    }
    if (film_weight(b) > 0.0) a = mix(a, film_average(b, b.specular_f0, true), film_weight(b));
    return b.specular * a + b.coat_ms_avg;
}

// The diffuse base under the coat: light enters through the coat along wi and leaves along wo, and is scaled so a white
// base returns exactly what the coat does not reflect. glTF's reference weights the base by 1 - F(VdotH), which can
// reflect more than arrives (1.025 for a white, nearly smooth plastic at 60 degrees); this form is reciprocal and
// conserves energy.
Spectrum coat_transmittance(Bsdf b, vec3 wi, Spectrum ms_i) {
    // No coat (KHR_materials_specular weight 0, as in a pure Lambertian): nothing to look up.
    if (b.specular == 0.0) return Spectrum(1.0);
    Spectrum avg = coat_average_kept() ? b.coat_avg : coat_average(b);
    return (Spectrum(1.0) - b.coat_albedo_o) * (Spectrum(1.0) - coat_albedo(b, wi, ms_i)) / max(Spectrum(1.0) - avg, Spectrum(1e-6));
}

// Kulla-Conty multiple scattering of the metal lobe: the energy single scattering loses, returned in a diffuse-like
// lobe coloured by the average Fresnel. Zero for a mirror (it loses nothing).
Spectrum metal_multiple_scattering(Bsdf b, vec3 wi) {
    if (!b.compensate || bsdf_is_delta(b)) return Spectrum(0.0);
    float e_avg = bsdf_needs_averages() ? b.metal_e_avg : spec_energy_average(b, 0u);
    if (e_avg >= 1.0) return Spectrum(0.0);
    Spectrum f_avg = bsdf_needs_averages() ? b.metal_f_avg : b.base_color + (Spectrum(1.0) - b.base_color) / 21.0;
    Spectrum f_ms = f_avg * f_avg * e_avg / (Spectrum(1.0) - f_avg * (1.0 - e_avg));
    float lobe = (1.0 - b.metal_e_o) * (1.0 - spec_energy(b, 0u, wi)) / (PI * (1.0 - e_avg));
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
    if (spectrum_max(b.sheen_color) == 0.0) return 0.0;
    return spectrum_max(b.sheen_color) * energy_lookup(2u, mu, b.sheen_roughness);
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
// (coat and metal), of the clear coat and of the sheen; the rest goes to the cosine lobe that samples everything
// diffuse-like. The sheen is sampled uniformly over the hemisphere: its lobe peaks at grazing wi, where the cosine
// lobe's samples are rare. Estimating its albedo at grazing wo (cos 0.05), a uniform sample's standard deviation is
// 2.8, 2.3, 2.6 and 3.4 times smaller than a cosine sample's at roughness 0.1, 0.3, 0.6 and 1 (1.1 to 4.1 times over
// cos 0.2 to 0.9).
vec4 lobe_probabilities(Bsdf b, vec3 wo) {
    Spectrum fd = dielectric_fresnel(b, wo.z);
    float opaque = (1.0 - b.metallic) * (1.0 - b.transmission);
    float spec = opaque * b.specular * spectrum_luminance(fd) + b.metallic * spectrum_luminance(metal_fresnel(b, wo.z));
    Spectrum tint = b.diffuse_color;
    if (scene_has(FEATURE_DIFFUSE_TRANSMISSION)) tint = mix(b.diffuse_color, b.dt_color, b.diffuse_transmission);
    float diff = opaque * (1.0 - b.specular * spectrum_max(fd)) * spectrum_luminance(tint);
    if (scene_has(FEATURE_COAT)) diff += opaque * spectrum_luminance(b.coat_ms_o);
    if (b.compensate && !bsdf_is_delta(b) && b.metallic > 0.0) {
        diff += b.metallic * (1.0 - b.metal_e_o) * spectrum_luminance(b.base_color);
    }
    float glass = (1.0 - b.metallic) * b.transmission;
    float coat = 0.0;
    float sheen = 0.0;
    if (scene_has(FEATURE_CLEARCOAT | FEATURE_SHEEN)) {
        float cc = b.clearcoat_o;
        float w = b.under;
        spec *= w;
        diff *= w;
        glass *= w;
        if (scene_has(FEATURE_SHEEN)) sheen = (1.0 - cc) * spectrum_luminance(b.sheen_color) * energy_lookup(2u, wo.z, b.sheen_roughness);
        coat = cc;
    }
    float total = spec + diff + glass + coat + sheen;
    if (total <= 0.0) return vec4(0.0, 1.0, 0.0, 0.0);
    // Without a clear coat or a sheen its share is a constant zero, which the lobe choice and the pdf then fold away.
    return vec4(glass / total, spec / total, scene_has(FEATURE_CLEARCOAT) ? coat / total : 0.0,
                scene_has(FEATURE_SHEEN) ? sheen / total : 0.0);
}

// The cosine lobe's share of the samples: what the other lobes leave.
float cosine_share(vec4 p) {
    return 1.0 - p.x - p.y - p.z - p.w;
}

// The visible-normal density of the base's microfacet normal m seen from wo: G1(wo) D(m) max(0, wo.m) / wo.z.
float vndf_pdf(Bsdf b, vec3 wo, vec3 m) {
    return spec_d(b, m) * max(0.0, dot(wo, m)) / ((1.0 + spec_lambda(b, wo)) * wo.z);
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
void glass_eval_pdf(Bsdf b, vec3 wo, vec3 wi, out Spectrum f, out float pdf) {
    f = Spectrum(0.0);
    pdf = 0.0;
    if (bsdf_is_delta(b) || glass_passes_through(b) || wi.z == 0.0) return;
    bool reflect_side = wi.z > 0.0;
    if (b.thin || reflect_side) {
        vec3 w = reflect_side ? wi : flip_z(wi);
        vec3 m = normalize(wo + w);
        float F = fresnel_dielectric(dot(wo, m), b.eta);
        float weight = reflect_side ? F : 1.0 - F;
        float g = 1.0 / (1.0 + spec_lambda(b, wo) + spec_lambda(b, w));
        f = Spectrum(spec_d(b, m) * g * weight / (4.0 * wo.z * w.z));
        pdf = vndf_pdf(b, wo, m) / (4.0 * dot(wo, m)) * weight;
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
    float g = 1.0 / (1.0 + spec_lambda(b, wo) + spec_lambda(b, wi));
    float ft = spec_d(b, m) * (1.0 - F) * g * abs(wi_m * wo_m / (denom * denom * wi.z * wo.z));
    // Radiance is compressed by eta^2 entering a denser medium (and expanded leaving it).
    f = b.base_color * ft / (b.eta * b.eta);
    pdf = vndf_pdf(b, wo, m) * abs(wi_m) / (denom * denom) * (1.0 - F);
}

// KHR_materials_diffuse_roughness's lobe: the energy-preserving Oren-Nayar BRDF (EON: Portsmouth, Kutz and Hill 2024,
// OpenPBR's glossy-diffuse base), Fujii's single-scattering Oren-Nayar with roughness r in [0, 1] plus the multiple
// scattering it loses, so that a white surface reflects everything it receives at every angle. The glTF extension
// names it (the factor is r as it is, as OpenPBR's base_diffuse_roughness and Babylon.js take it). Sampled as the
// Lambertian lobe is, by the cosine (as Cycles samples its Oren-Nayar): the weights stay bounded except where wo
// and wi both graze.
const float EON_C1 = 0.5 - 2.0 / (3.0 * PI);
const float EON_C2 = 2.0 / 3.0 - 28.0 / (15.0 * PI);

// Fujii Oren-Nayar's directional albedo at cosine mu for a white surface, in closed form: A + B/pi G(mu), where
// G's (sin/mu)(1 - sin^3) is written as sin mu (1 + sin + sin^2) / (1 + sin), which keeps its precision at grazing
// mu (the albedo goes to 1 there).
float fon_albedo(float mu, float r) {
    float si = sqrt(max(1.0 - mu * mu, 0.0));
    float g = si * (acos(clamp(mu, -1.0, 1.0)) - si * mu) +
              2.0 / 3.0 * (si * mu * (1.0 + si + si * si) / (1.0 + si) - si);
    return (1.0 + r / PI * g) / (1.0 + EON_C1 * r);
}

// EON's f(wo, wi) for albedo rho, wo and wi on the same side (z > 0): the single scattering
// rho / pi A (1 + r s/t), s = wo.wi - mu_o mu_i, t = max(mu_o, mu_i) where s > 0 (else 1), A = 1 / (1 + C1 r), and
// the compensation rho_ms / pi (1 - E(mu_o)) (1 - E(mu_i)) / (1 - E_avg), rho_ms = rho^2 E_avg / (1 - rho (1 - E_avg))
// with E_avg = A (1 + C2 r). Symmetric in wo and wi.
Spectrum eon_eval(Spectrum rho, float r, vec3 wo, vec3 wi) {
    float s = dot(wo, wi) - wo.z * wi.z;
    float s_over_t = s > 0.0 ? s / max(max(wo.z, wi.z), 1e-7) : s;
    float a = 1.0 / (1.0 + EON_C1 * r);
    float e_avg = a * (1.0 + EON_C2 * r);
    Spectrum rho_ms = rho * rho * e_avg / max(Spectrum(1.0) - rho * (1.0 - e_avg), Spectrum(1e-7));
    float lobe = max(1.0 - fon_albedo(wo.z, r), 0.0) * max(1.0 - fon_albedo(wi.z, r), 0.0) / max(1.0 - e_avg, 1e-7);
    return (rho * (a * (1.0 + r * s_over_t)) + rho_ms * lobe) / PI;
}

// The diffuse lobe of albedo rho: Lambertian, or EON where the material's diffuse roughness asks for it (wi on wo's
// side; a transmitted wi is mirrored to it first).
Spectrum diffuse_lobe(Bsdf b, Spectrum rho, vec3 wo, vec3 wi) {
    if (scene_has(FEATURE_DIFFUSE_ROUGHNESS) && b.diffuse_roughness > 0.0) return eon_eval(rho, b.diffuse_roughness, wo, wi);
    return rho / PI;
}

// The base's f(wo, wi), below the layers.
Spectrum base_eval(Bsdf b, vec3 wo, vec3 wi) {
    float glass_w = (1.0 - b.metallic) * b.transmission;
    Spectrum glass_f = Spectrum(0.0);
    float glass_pdf;
    if (glass_w > 0.0) glass_eval_pdf(b, wo, wi, glass_f, glass_pdf);
    float opaque = (1.0 - b.metallic) * (1.0 - b.transmission);
    // The layer's multiple scattering at wi, or at its mirror image for diffuse transmission: one lookup either way.
    Spectrum ms_i = coat_ms(b, abs(wi.z));
    if (wi.z < 0.0) {
        Spectrum below = glass_w * glass_f;
        // Diffuse transmission: Lambertian on the far side, through the dielectric layer on both ways as the diffuse
        // reflection is (so the two share the energy the layer lets in).
        if (scene_has(FEATURE_DIFFUSE_TRANSMISSION) && b.diffuse_transmission > 0.0) {
            below += opaque * b.diffuse_transmission * coat_transmittance(b, flip_z(wi), ms_i) *
                     diffuse_lobe(b, b.dt_color, wo, flip_z(wi));
        }
        return below;
    }
    vec3 h = normalize(wo + wi);
    float c = dot(wo, h);
    Spectrum fd = dielectric_fresnel(b, c);
    Spectrum diffuse = opaque * coat_transmittance(b, wi, ms_i) * diffuse_lobe(b, b.diffuse_color, wo, wi);
    if (scene_has(FEATURE_DIFFUSE_TRANSMISSION)) diffuse *= 1.0 - b.diffuse_transmission;
    if (b.metallic > 0.0) diffuse += b.metallic * metal_multiple_scattering(b, wi);
    if (scene_has(FEATURE_COAT) && opaque > 0.0) diffuse += opaque * coat_ms_eval(b, ms_i);
    // No specular lobe at all (a mirror's is a delta; a pure Lambertian has neither coat nor metal).
    if (bsdf_is_delta(b) || (opaque * b.specular == 0.0 && b.metallic == 0.0)) return diffuse + glass_w * glass_f;
    float g = 1.0 / (1.0 + spec_lambda(b, wo) + spec_lambda(b, wi));
    float spec = spec_d(b, h) * g / (4.0 * wo.z * wi.z);
    return diffuse + spec * (opaque * b.specular * fd + b.metallic * metal_fresnel(b, c)) + glass_w * glass_f;
}

// f(wo, wi) without the cosine, wo the direction bsdf_at readied b for; zero for delta lobes.
Spectrum bsdf_eval(Bsdf b, vec3 wi) {
    vec3 wo = b.wo;
    if (wo.z <= 0.0 || wi.z == 0.0) return Spectrum(0.0);
    Spectrum f = base_eval(b, wo, wi);
    if (scene_has(FEATURE_CLEARCOAT | FEATURE_SHEEN)) {
        float cc = b.clearcoat_o;
        Spectrum under = f * b.under;
        if (scene_has(FEATURE_SHEEN) && wi.z > 0.0 && spectrum_max(b.sheen_color) > 0.0) {
            under += (1.0 - cc) * b.sheen_color * sheen_lobe(b.sheen_roughness, wo, wi);
        }
        f = under;
        if (scene_has(FEATURE_CLEARCOAT)) f += Spectrum(clearcoat_eval(b, wo, wi));
    }
    return f;
}

// Solid-angle density with which bsdf_sample returns wi (delta lobes have none).
float bsdf_pdf(Bsdf b, vec3 wi) {
    vec3 wo = b.wo;
    if (wo.z <= 0.0 || wi.z == 0.0) return 0.0;
    vec4 p = b.lobe_p;
    float pdf = 0.0;
    if (p.x > 0.0) {
        Spectrum f;
        float glass_pdf;
        glass_eval_pdf(b, wo, wi, f, glass_pdf);
        pdf += p.x * glass_pdf;
    }
    // The cosine lobe sends diffuse_transmission of its samples through the surface.
    if (wi.z < 0.0) {
        if (scene_has(FEATURE_DIFFUSE_TRANSMISSION)) pdf += cosine_share(p) * b.diffuse_transmission * -wi.z / PI;
        return pdf;
    }
    float cosine = cosine_share(p) * wi.z / PI;
    if (scene_has(FEATURE_DIFFUSE_TRANSMISSION)) cosine *= 1.0 - b.diffuse_transmission;
    pdf += cosine;
    if (scene_has(FEATURE_SHEEN)) pdf += p.w / (2.0 * PI);
    if (scene_has(FEATURE_CLEARCOAT) && p.z > 0.0) pdf += p.z * clearcoat_pdf(b, wo, wi);
    if (scene_has(FEATURE_COAT | FEATURE_METAL) && !bsdf_is_delta(b)) {
        // Visible-normal sampling then reflection: D_wo(h) / (4 wo.h) = G1(wo) D(h) / (4 wo.z).
        vec3 h = normalize(wo + wi);
        pdf += p.y * spec_d(b, h) / (4.0 * (1.0 + spec_lambda(b, wo)) * wo.z);
    }
    return pdf;
}

// Heitz 2018, "Sampling the GGX distribution of visible normals".
vec3 sample_ggx_vndf(vec3 wo, vec2 alpha, vec2 u) {
    vec3 vh = normalize(vec3(alpha.x * wo.x, alpha.y * wo.y, wo.z));
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
    return normalize(vec3(alpha.x * nh.x, alpha.y * nh.y, max(1e-6, nh.z)));
}

// A visible normal of the base's lobe.
vec3 sample_spec_vndf(Bsdf b, vec3 wo, vec2 u) {
    if (scene_has(FEATURE_ANISOTROPY) && b.anisotropic) {
        return from_aniso(b, sample_ggx_vndf(to_aniso(b, wo), b.aniso_alpha, u));
    }
    return sample_ggx_vndf(wo, vec2(b.alpha), u);
}

struct BsdfSample {
    vec3 wi;
    Spectrum weight; // f * |cos| / pdf (for a delta lobe: its throughput over the lobe's probability)
    float pdf;    // 0 for a delta lobe
    bool delta;
};

// Readies b for evaluations and samples seen from wo (in the shading frame, after shading_frame has set the clear
// coat's normal): the hemispherical averages, and what every evaluation at wo shares.
void bsdf_at(inout Bsdf b, vec3 wo) {
    b.wo = wo;
    b.coat_ms_avg = coat_ms_average(b);
    bsdf_averages(b);
    b.coat_ms_o = coat_ms(b, wo.z);
    b.coat_albedo_o = b.specular > 0.0 ? coat_albedo(b, wo, b.coat_ms_o) : Spectrum(0.0);
    b.metal_e_o = b.metallic > 0.0 && !bsdf_is_delta(b) ? spec_energy(b, 0u, wo) : 0.0;
    b.clearcoat_o = coat_albedo_at(b, wo);
    b.under = base_weight_under(b, wo, b.clearcoat_o);
    b.lobe_p = lobe_probabilities(b, wo);
}

// u.z picks the lobe (and, rescaled, reflection or transmission in the glass lobe), u.xy the direction.
// Returns false when the sample carries no energy.
bool bsdf_sample(Bsdf b, vec3 u, out BsdfSample s) {
    vec3 wo = b.wo;
    s.wi = vec3(0.0, 0.0, 1.0);
    s.weight = Spectrum(0.0);
    s.pdf = 0.0;
    s.delta = false;
    if (wo.z <= 0.0) return false;
    vec4 p = b.lobe_p;
    // What the layers leave of the base, for the base's delta lobes (whose weights are not evaluated).
    float under = b.under;
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
                s.weight = Spectrum(glass_w * under / p.x);
            } else if (b.thin) {
                s.wi = -wo;
                s.weight = b.base_color * (glass_w * under / p.x);
            } else {
                if (!refract_dir(wo, vec3(0.0, 0.0, 1.0), b.eta, s.wi)) return false;
                s.weight = b.base_color * (glass_w * under / (p.x * b.eta * b.eta));
            }
            return true;
        }
        vec3 m = sample_spec_vndf(b, wo, u.xy);
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
            Spectrum f = opaque * b.specular * dielectric_fresnel(b, wo.z) + b.metallic * metal_fresnel(b, wo.z);
            s.weight = f * under / p.y;
            return true;
        }
        vec3 h = sample_spec_vndf(b, wo, u.xy);
        s.wi = reflect(-wo, h);
        if (s.wi.z <= 0.0) return false;
    } else if (scene_has(FEATURE_CLEARCOAT) && u.z < p.x + p.y + p.z) {
        // The clear coat, sampled in its own frame; a direction its normal map sends below the surface is lost.
        vec3 o = to_coat(b, wo);
        if (coat_is_delta(b)) {
            s.wi = from_coat(b, vec3(-o.x, -o.y, o.z));
            if (s.wi.z <= 0.0) return false;
            s.delta = true;
            s.weight = Spectrum(b.clearcoat * coat_fresnel(o.z) / p.z);
            return true;
        }
        s.wi = from_coat(b, reflect(-o, sample_ggx_vndf(o, vec2(b.coat_alpha), u.xy)));
        if (s.wi.z <= 0.0 || dot(s.wi, b.coat_n) <= 0.0) return false;
    } else if (scene_has(FEATURE_SHEEN) && u.z < p.x + p.y + p.z + p.w) {
        s.wi = sample_uniform_hemisphere(u.xy);
    } else {
        s.wi = sample_cosine_hemisphere(vec3(0.0, 0.0, 1.0), u.xy);
        if (scene_has(FEATURE_DIFFUSE_TRANSMISSION) && b.diffuse_transmission > 0.0) {
            // u.z again, rescaled over the cosine lobe's share, chooses through or back.
            float u_t = (u.z - (p.x + p.y + p.z + p.w)) / max(cosine_share(p), 1e-12);
            if (u_t < b.diffuse_transmission) s.wi = flip_z(s.wi);
        }
    }
    s.pdf = bsdf_pdf(b, s.wi);
    if (!(s.pdf > 0.0)) return false;
    s.weight = bsdf_eval(b, s.wi) * (abs(s.wi.z) / s.pdf);
    return true;
}

#endif
