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

// The mean over a colour's channels: RGB's three, or the path's wavelengths.
float channel_mean(Spectrum c) {
    return spectral() ? 0.25 * (c.x + c.y + c.z + c.w) : (c.x + c.y + c.z) / 3.0;
}

// The channel whose exponentials draw every free flight of sample s of pixel: one for the whole path, so that the
// path's weight can be taken against all channels' densities of the whole path (medium_sample). The path's own hero
// wavelength in spectral transport (already uniform over the spectrum); a uniform choice of R, G or B otherwise.
uint medium_channel(uint pixel, uint s) {
    return spectral() ? 0u : min(uint(rand2(pixel, s, 0u, DIM_MEDIUM).x * 3.0), 2u);
}

// A ray's run of length t_max (1e30 when it leaves the scene) through md: whether it scatters on the way, at distance
// t, with beta weighted for either outcome. A purely absorbing medium only attenuates (no noise). Otherwise the
// distance is drawn from channel c's exponential (medium_channel) with the uniform u, and the path is weighted by the
// one-sample balance heuristic over the channels of the whole path, as pbrt-v4's rescaled path probabilities do
// (spectral MIS; Mitsuba 3's volpathmis likewise): `ratios` holds every channel's density of the path's free flights
// so far over their mean (1 at the camera), so beta stays f / mean over channels of the path's density, below the
// channel count times the albedo, however many scatterings the path makes. Weighting each event by the mean of its
// own densities instead lets the weights' product wander per channel over hundreds of scatterings (coloured noise in
// dense chromatic media). Homogeneous media need no majorant or null collision.
bool medium_sample(Medium md, float t_max, uint c, float u, inout Spectrum beta, inout Spectrum ratios, out float t) {
    t = t_max;
    if (!md.scatters) {
        beta *= medium_transmittance(md, t_max);
        return false;
    }
    float sigma_c = md.sigma_t[c];
    float t_c = sigma_c > 0.0 ? -log(1.0 - u) / sigma_c : 3.0e38;
    bool scatters = t_c < t_max;
    t = scatters ? t_c : t_max;
    Spectrum tr = medium_transmittance(md, t);
    // Each channel's density of this outcome (scattering at t, or passing t_max), and f.
    Spectrum pdf = scatters ? md.sigma_t * tr : tr;
    Spectrum f = scatters ? md.sigma_t * md.albedo * tr : tr;
    float mean = channel_mean(ratios * pdf);
    beta = mean > 0.0 ? beta * f / mean : Spectrum(0.0);
    ratios = mean > 0.0 ? ratios * pdf / mean : ratios;
    return scatters;
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
