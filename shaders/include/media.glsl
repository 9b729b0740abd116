// Light inside things (FEATURE_MEDIA): the volumes a path is inside, free-flight sampling through a homogeneous
// medium, and the Henyey-Greenstein phase function (KHR_materials_scatter's volumetric mode).
#ifndef MEDIA_GLSL
#define MEDIA_GLSL

#include "spectrum.glsl"
#include "sampling.glsl"

// The medium stack: the volumes a ray is inside as material index + 1, innermost (the one entered last and not yet
// left) in x, 0 for none. A ray travels in the innermost's medium: nested volumes (a bubble in a liquid) take the inner
// one's, overlapping ones the one entered last. Four deep: entering a fifth forgets the outermost. A path starts
// outside every volume (a camera inside a medium sees it as empty until its rays enter one).
uvec4 media_enter(uvec4 media, uint id) {
    return uvec4(id, media.xyz);
}

// Leaving volume id removes it wherever it is in the stack (overlapping volumes are left in any order); leaving one the
// path was not known to be in (the camera started inside, or it was forgotten) changes nothing.
uvec4 media_leave(uvec4 media, uint id) {
    if (media.x == id) return uvec4(media.yzw, 0u);
    if (media.y == id) return uvec4(media.x, media.zw, 0u);
    if (media.z == id) return uvec4(media.xy, media.w, 0u);
    if (media.w == id) return uvec4(media.xyz, 0u);
    return media;
}

// The innermost medium on the far side of a surface of material id: a volumetric one is entered from the front and
// left from the back; anything else (a thin sheet, an opaque surface) keeps the medium it sits in.
uint media_beyond(uvec4 media, uint id, bool volumetric, bool front) {
    if (!volumetric) return media.x;
    return front ? id : media_leave(media, id).x;
}

// A homogeneous medium at the path's wavelengths: extinction sigma_t (1/m), single-scattering albedo, and g.
struct Medium {
    Spectrum sigma_t;
    Spectrum albedo;
    float g;
    bool scatters;
};

Medium medium_at(uint id) {
    vec3 sigma_t;
    vec4 albedo_g;
    load_medium(id - 1u, sigma_t, albedo_g);
    Medium md;
    md.sigma_t = spectrum_unbounded(sigma_t);
    // A reflectance-bounded albedo keeps sigma_s = sigma_t * albedo at most sigma_t at every wavelength.
    md.albedo = spectrum_reflectance(albedo_g.rgb);
    md.g = albedo_g.w;
    md.scatters = any(greaterThan(albedo_g.rgb, vec3(0.0)));
    return md;
}

// The transmittance of a straight run of length t through md (exp(-sigma_t t) per channel): what a shadow ray keeps.
Spectrum medium_transmittance(Medium md, float t) {
    return exp(-md.sigma_t * t);
}

// Channels a colour carries: RGB's three, or the path's wavelengths.
uint medium_channels() {
    return spectral() ? uint(WAVELENGTHS) : 3u;
}

float channel_mean(Spectrum c) {
    return spectral() ? 0.25 * (c.x + c.y + c.z + c.w) : (c.x + c.y + c.z) / 3.0;
}

// A ray's run of length t_max (1e30 when it leaves the scene) through md: whether it scatters on the way, at distance
// t, with beta weighted for either outcome. A purely absorbing medium only attenuates (no noise). Otherwise the
// distance is drawn from one channel's exponential, the channel uniform (u.x), and beta divides by the mean of every
// channel's density: the one-sample balance heuristic over channels (spectral MIS, as Mitsuba 3's volpathmis and
// pbrt-v4's rescaled path probabilities do), so each channel stays unbiased, a chromatic medium's weights stay below
// the channel count, and no majorant or null collision is needed in a homogeneous medium.
bool medium_sample(Medium md, float t_max, vec2 u, inout Spectrum beta, out float t) {
    t = t_max;
    if (!md.scatters) {
        beta *= medium_transmittance(md, t_max);
        return false;
    }
    uint n = medium_channels();
    uint c = min(uint(u.x * float(n)), n - 1u);
    float sigma_c = md.sigma_t[c];
    float t_c = sigma_c > 0.0 ? -log(1.0 - u.y) / sigma_c : 3.0e38;
    if (t_c < t_max) {
        t = t_c;
        Spectrum tr = medium_transmittance(md, t);
        float pdf = channel_mean(md.sigma_t * tr);
        beta = pdf > 0.0 ? beta * md.sigma_t * md.albedo * tr / pdf : Spectrum(0.0);
        return true;
    }
    Spectrum tr = medium_transmittance(md, t_max);
    float pdf = channel_mean(tr);
    beta = pdf > 0.0 ? beta * tr / pdf : Spectrum(0.0);
    return false;
}

// Henyey-Greenstein's density over directions for cos_theta between the propagation directions before and after the
// scattering (both along the light's travel): g > 0 scatters forwards, towards cos_theta = 1.
float hg_phase(float cos_theta, float g) {
    float denom = max(1.0 + g * g - 2.0 * g * cos_theta, 1e-12);
    return (0.25 / PI) * (1.0 - g * g) / (denom * sqrt(denom));
}

// A propagation direction after scattering, drawn from hg_phase about d_in exactly (its pdf is hg_phase): the inverse
// of the cosine's CDF, (1 + g^2 - ((1 - g^2) / (1 - g + 2 g u))^2) / 2g, uniform below |g| = 1e-3 where it loses
// its digits.
vec3 hg_sample(vec3 d_in, float g, vec2 u) {
    float cos_theta = 1.0 - 2.0 * u.x;
    if (abs(g) >= 1e-3) {
        float k = (1.0 - g * g) / (1.0 - g + 2.0 * g * u.x);
        cos_theta = (1.0 + g * g - k * k) / (2.0 * g);
    }
    cos_theta = clamp(cos_theta, -1.0, 1.0);
    float sin_theta = sqrt(max(0.0, 1.0 - cos_theta * cos_theta));
    float phi = 2.0 * PI * u.y;
    vec3 t, b;
    basis(d_in, t, b);
    return normalize(sin_theta * cos(phi) * t + sin_theta * sin(phi) * b + cos_theta * d_in);
}

#endif
