// Spectra on the device: a path's wavelengths, RGB inputs as spectra at them (Jakob and Hanika 2019, with the
// conventions of Mitsuba 3 and pbrt-v4), and a sample's radiance at them as linear sRGB for the film. The host twin
// is src/spectrum/mod.rs; tests/spectrum.rs holds the two together. The tables live in the renderer's table buffer
// (SPECTRUM_* after the energy tables), whose CIE rows the TEXEL_READS variants read through a view (BINDING_CIE_TEXELS).
#ifndef SPECTRUM_GLSL
#define SPECTRUM_GLSL

#include "rng.glsl"

// A colour along a path: linear RGB in .rgb with w unused, or, under FEATURE_SPECTRAL, the quantity at the path's
// WAVELENGTHS wavelengths. RGB code reads .rgb alone, so nothing of w reaches a store and its arithmetic folds away.
#define Spectrum vec4

// The wavelengths (nm) of the sample being traced and their densities: wavelengths_begin sets them, as motion_begin
// sets the time, from the pixel and sample alone, so every stage finds the same ones. With them it keeps what every
// emitter needs at those wavelengths, D65 (Y = 1), so a bounce reads the CIE table once, not per light. The film's
// observer is read where a sample reaches it (spectrum_to_rgb): shading never needs it (computing it there made
// lavapipe's spectral shade stage 15 % slower, even unused).
vec4 path_lambda = vec4(550.0);
vec4 path_lambda_pdf = vec4(1.0);
vec4 path_d65 = vec4(1.0);

bool spectral() {
    return scene_has(FEATURE_SPECTRAL);
}

// Wavelength sampling: density ∝ sech²(A (λ − C)) over the visible range, close to the observer's curves summed.
const float LAMBDA_A = 0.0072;
const float LAMBDA_C = 538.0;

vec2 lambda_range() {
    return vec2(tanh(LAMBDA_A * (LAMBDA_MIN - LAMBDA_C)), tanh(LAMBDA_A * (LAMBDA_MAX - LAMBDA_C)));
}

float visible_pdf(float nm) {
    if (nm < LAMBDA_MIN || nm > LAMBDA_MAX) return 0.0;
    vec2 r = lambda_range();
    float sech = 1.0 / cosh(LAMBDA_A * (nm - LAMBDA_C));
    return LAMBDA_A * sech * sech / (r.y - r.x);
}

float sample_visible(float u) {
    vec2 r = lambda_range();
    return clamp(LAMBDA_C + atanh(r.x + u * (r.y - r.x)) / LAMBDA_A, LAMBDA_MIN, LAMBDA_MAX);
}

// The hero at u, the others a quarter of the sampling CDF apart (wrapped): together they stratify it.
void sample_wavelengths(float u, out vec4 nm, out vec4 pdf) {
    for (uint k = 0u; k < WAVELENGTHS; k++) {
        nm[k] = sample_visible(fract(u + float(k) / float(WAVELENGTHS)));
        pdf[k] = visible_pdf(nm[k]);
    }
}


// The CIE row at nm, linear between the 1 nm rows (two texels of BINDING_CIE_TEXELS in the TEXEL_READS variants): the
// observer over the integral of y-bar (xyz) and D65 with Y = 1 (w); zero outside the range.
vec4 cie_at(float nm) {
    float x = nm - LAMBDA_MIN;
    if (!(x >= 0.0 && x <= float(CIE_ROWS - 1u))) return vec4(0.0);
    uint i = min(uint(x), CIE_ROWS - 2u);
#ifdef TEXEL_READS
    return mix(texelFetch(cie_texels, int(i)), texelFetch(cie_texels, int(i + 1u)), x - float(i));
#else
    uint a = SPECTRUM_CIE + 4u * i;
    vec4 lo = vec4(energy[a], energy[a + 1u], energy[a + 2u], energy[a + 3u]);
    vec4 hi = vec4(energy[a + 4u], energy[a + 5u], energy[a + 6u], energy[a + 7u]);
    return mix(lo, hi, x - float(i));
#endif
}

void wavelengths_begin(uint pixel, uint sample_index) {
    if (!spectral()) return;
    sample_wavelengths(rand2(pixel, sample_index, 0u, DIM_WAVELENGTH).x, path_lambda, path_lambda_pdf);
    for (uint k = 0u; k < WAVELENGTHS; k++) path_d65[k] = cie_at(path_lambda[k]).w;
}

// The node of the table's z axis at or below z: the nodes are smoothstep(smoothstep(k / (res - 1))), whose inverse
// gives k at once; one step either way absorbs its rounding against the stored nodes.
uint rgb2spec_node(float z) {
    const uint res = RGB2SPEC_RES;
    float u = 0.5 - sin(asin(clamp(1.0 - 2.0 * z, -1.0, 1.0)) / 3.0);
    u = 0.5 - sin(asin(clamp(1.0 - 2.0 * u, -1.0, 1.0)) / 3.0);
    uint zi = min(uint(max(u * float(res - 1u), 0.0)), res - 2u);
    if (zi > 0u && z < energy[SPECTRUM_Z + zi]) zi--;
    if (zi < res - 2u && z >= energy[SPECTRUM_Z + zi + 1u]) zi++;
    return zi;
}

// The sigmoid-of-quadratic coefficients (over (λ − LAMBDA_MIN) / (LAMBDA_MAX − LAMBDA_MIN)) of a reflectance that is
// not grey: the table's trilinear interpolation, as spectrum::Tables::coefficients.
vec3 rgb2spec_coefficients(vec3 rgb) {
    const uint res = RGB2SPEC_RES;
    uint l = rgb.r >= rgb.g && rgb.r >= rgb.b ? 0u : (rgb.g >= rgb.b ? 1u : 2u);
    float z = rgb[l];
    float scale = float(res - 1u) / z;
    float x = rgb[(l + 1u) % 3u] * scale;
    float y = rgb[(l + 2u) % 3u] * scale;
    uint zi = rgb2spec_node(z);
    uint xi = min(uint(x), res - 2u);
    uint yi = min(uint(y), res - 2u);
    float z0 = energy[SPECTRUM_Z + zi];
    vec3 f = vec3(x - float(xi), y - float(yi), (z - z0) / (energy[SPECTRUM_Z + zi + 1u] - z0));
    vec3 c = vec3(0.0);
    for (uint corner = 0u; corner < 8u; corner++) {
        uvec3 d = uvec3(corner & 1u, (corner >> 1u) & 1u, corner >> 2u);
        vec3 w = mix(vec3(1.0) - f, f, vec3(d));
        uint i = SPECTRUM_COEFFS + ((((l * res + zi + d.z) * res + yi + d.y) * res + xi + d.x) * 3u);
        c += (w.x * w.y * w.z) * vec3(energy[i], energy[i + 1u], energy[i + 2u]);
    }
    return c;
}

float rgb2spec_eval(vec3 c, float nm) {
    float t = (nm - LAMBDA_MIN) / (LAMBDA_MAX - LAMBDA_MIN);
    float x = (c.x * t + c.y) * t + c.z;
    return 0.5 + x / (2.0 * sqrt(1.0 + x * x));
}

Spectrum rgb2spec_eval4(vec3 c, vec4 nm) {
    return vec4(rgb2spec_eval(c, nm.x), rgb2spec_eval(c, nm.y), rgb2spec_eval(c, nm.z), rgb2spec_eval(c, nm.w));
}

// A reflectance (RGB clamped to [0, 1]) at the path's wavelengths; greys are constant spectra. A scene whose colours
// are all grey or known (no FEATURE_SPECTRUM_TABLE) never gets here with another, and the table's code folds away;
// if one came, its NaN would show as a sample the film drops and counts.
Spectrum spectrum_reflectance_at(vec3 rgb, vec4 nm) {
    rgb = clamp(rgb, vec3(0.0), vec3(1.0));
    if (rgb.r == rgb.g && rgb.g == rgb.b) return vec4(rgb.r);
    if (!scene_has(FEATURE_SPECTRUM_TABLE)) return vec4(uintBitsToFloat(0x7fc00000u));
    return rgb2spec_eval4(rgb2spec_coefficients(rgb), nm);
}

// An RGB of any size (colours above 1, absorption coefficients): twice its largest component times the spectrum of
// the RGB over that (pbrt-v4's RGBUnboundedSpectrum).
Spectrum spectrum_unbounded_at(vec3 rgb, vec4 nm) {
    float m = 2.0 * max(rgb.r, max(rgb.g, rgb.b));
    return m > 0.0 ? m * spectrum_reflectance_at(rgb / m, nm) : vec4(0.0);
}

Spectrum spectrum_reflectance(vec3 rgb) {
    return spectral() ? spectrum_reflectance_at(rgb, path_lambda) : vec4(rgb, 0.0);
}

Spectrum spectrum_unbounded(vec3 rgb) {
    return spectral() ? spectrum_unbounded_at(rgb, path_lambda) : vec4(rgb, 0.0);
}

// Emitted radiance: the unbounded spectrum times D65 with Y = 1, so RGB (1, 1, 1) emits D65 and renders as white.
Spectrum spectrum_illuminant(vec3 rgb) {
    if (!spectral()) return vec4(rgb, 0.0);
    return spectrum_unbounded_at(rgb, path_lambda) * path_d65;
}

// A material's colour whose coefficients the host may have found: known.w is 1 when known.xyz are rgb's (an
// untextured base colour: Material.base_color_spectrum), and the hit evaluates them instead of interpolating the
// table. On lavapipe the table's 26 scattered loads per colour were half of spectral shading's time.
Spectrum spectrum_reflectance_known(vec3 rgb, vec4 known) {
    if (!spectral() || known.w == 0.0) return spectrum_reflectance(rgb);
    return rgb2spec_eval4(known.xyz, path_lambda);
}

// An emission whose coefficients the host may have found (Material.emission_spectrum: those of rgb over twice its
// largest component, as spectrum_unbounded_at takes them).
Spectrum spectrum_illuminant_known(vec3 rgb, vec4 known) {
    if (!spectral() || known.w == 0.0) return spectrum_illuminant(rgb);
    return 2.0 * max(rgb.r, max(rgb.g, rgb.b)) * rgb2spec_eval4(known.xyz, path_lambda) * path_d65;
}

// The largest and the mean of a colour's components (a throughput's, for Russian roulette and lobe choice).
float spectrum_max(Spectrum c) {
    return spectral() ? max(max(c.x, c.y), max(c.z, c.w)) : max(c.x, max(c.y, c.z));
}

float spectrum_luminance(Spectrum c) {
    return spectral() ? 0.25 * (c.x + c.y + c.z + c.w) : dot(c.rgb, vec3(0.2126, 0.7152, 0.0722));
}

bool spectrum_positive(Spectrum c) {
    return spectral() ? any(greaterThan(c, vec4(0.0))) : any(greaterThan(c.rgb, vec3(0.0)));
}

// KHR_materials_dispersion's IOR at nm: Cauchy's n = A + B / λ², through the IOR ior at the Fraunhofer d line with
// Abbe number V = 20 / dispersion, which fixes the change between the F and C lines: n_F − n_C = (ior − 1) / V.
float dispersive_ior(float ior, float dispersion, float nm) {
    const float d_line = 587.56;
    const float f_line = 486.13;
    const float c_line = 656.27;
    float b = (ior - 1.0) * dispersion / 20.0 / (1.0 / (f_line * f_line) - 1.0 / (c_line * c_line));
    return max(ior + b * (1.0 / (nm * nm) - 1.0 / (d_line * d_line)), 1.0);
}

// As a path-state texel: RGB keeps w at zero, as before spectra.
vec4 spectrum_store(Spectrum c) {
    return spectral() ? c : vec4(c.rgb, 0.0);
}

// A sample's radiance at the path's wavelengths as linear sRGB: the mean over wavelengths of the observer times the
// radiance over the density, to XYZ, to sRGB. RGB passes through.
vec3 spectrum_to_rgb(Spectrum l) {
    if (!spectral()) return l.rgb;
    vec3 xyz = vec3(0.0);
    for (uint k = 0u; k < WAVELENGTHS; k++) {
        float nm = path_lambda[k];
        float pdf = path_lambda_pdf[k];
        vec3 observer = cie_at(nm).xyz;
        if (pdf > 0.0) xyz += observer * (l[k] / (pdf * float(WAVELENGTHS)));
    }
    uint m = SPECTRUM_MATRIX;
    return vec3(dot(vec3(energy[m], energy[m + 1u], energy[m + 2u]), xyz),
                dot(vec3(energy[m + 4u], energy[m + 5u], energy[m + 6u]), xyz),
                dot(vec3(energy[m + 8u], energy[m + 9u], energy[m + 10u]), xyz));
}

#endif
