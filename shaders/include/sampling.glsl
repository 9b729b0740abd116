// Warps from uniform numbers to directions and points, each with its pdf twin.
#ifndef SAMPLING_GLSL
#define SAMPLING_GLSL

const float PI = 3.14159265358979323846;

// Van der Corput's sequence in base 2, 24 bits: the second coordinate of the energy tables' stratified samples.
float radical_inverse(uint i) {
    return float(bitfieldReverse(i) >> 8u) * (1.0 / 16777216.0);
}

// Orthonormal basis around a unit normal (Duff et al. 2017).
void basis(vec3 n, out vec3 t, out vec3 b) {
    float s = n.z >= 0.0 ? 1.0 : -1.0;
    float a = -1.0 / (s + n.z);
    float c = n.x * n.y * a;
    t = vec3(1.0 + s * n.x * n.x * a, s * c, -s * n.x);
    b = vec3(c, s + n.y * n.y * a, -n.y);
}

// Uniform point on the unit disk (Shirley-Chiu concentric map: neighbouring samples stay neighbours).
vec2 sample_concentric_disk(vec2 u) {
    vec2 d = 2.0 * u - 1.0;
    float r, phi;
    if (d.x == 0.0 && d.y == 0.0) {
        r = 0.0; phi = 0.0;
    } else if (abs(d.x) > abs(d.y)) {
        r = d.x; phi = (PI / 4.0) * (d.y / d.x);
    } else {
        r = d.y; phi = (PI / 2.0) - (PI / 4.0) * (d.x / d.y);
    }
    return r * vec2(cos(phi), sin(phi));
}

// Cosine-weighted hemisphere around n (Malley's method on a concentric disk).
vec3 sample_cosine_hemisphere(vec3 n, vec2 u) {
    vec2 disk = sample_concentric_disk(u);
    float z = sqrt(max(0.0, 1.0 - dot(disk, disk)));
    vec3 t, b;
    basis(n, t, b);
    return normalize(disk.x * t + disk.y * b + z * n);
}

// Uniform direction on the hemisphere about +z (pdf 1 / 2 pi).
vec3 sample_uniform_hemisphere(vec2 u) {
    float r = sqrt(max(0.0, 1.0 - u.x * u.x));
    float phi = 2.0 * PI * u.y;
    return vec3(r * cos(phi), r * sin(phi), u.x);
}

float pdf_cosine_hemisphere(vec3 n, vec3 w) {
    return max(dot(n, w), 0.0) / PI;
}

// Uniform point on a triangle (Turk 1990); returns barycentrics of v1 and v2.
vec2 sample_triangle(vec2 u) {
    float su = sqrt(u.x);
    return vec2(su * (1.0 - u.y), su * u.y);
}

// Written as 1 / (1 + (pb / pa)^2) so huge pdfs (near-delta lobes) cannot overflow to inf / inf.
float power_heuristic(float pa, float pb) {
    if (!(pa > 0.0)) return 0.0;
    float r = pb / pa;
    return 1.0 / (1.0 + r * r);
}

#endif
