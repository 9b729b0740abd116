// The Lambertian BSDF: eval, sample and pdf live together so the estimator can never mix them up.
#ifndef BSDF_GLSL
#define BSDF_GLSL

#include "sampling.glsl"

// n: shading normal on the side of the incoming ray; wi points away from the surface.
vec3 lambert_eval(vec3 albedo, vec3 n, vec3 wi) {
    return dot(n, wi) > 0.0 ? albedo / PI : vec3(0.0);
}

float lambert_pdf(vec3 n, vec3 wi) {
    return pdf_cosine_hemisphere(n, wi);
}

vec3 lambert_sample(vec3 n, vec2 u) {
    return sample_cosine_hemisphere(n, u);
}

#endif
