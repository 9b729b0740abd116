// Where paths start: camera rays (a jittered point in the pixel, box filter, through a pinhole, an orthographic image
// plane or a thin lens) and the path state they begin.
#ifndef CAMERA_GLSL
#define CAMERA_GLSL

#include "rng.glsl"
#include "sampling.glsl"
#include "spectrum.glsl"

// Where pixel (row-major from the top left) is on the image. An integer division is eight scalar divides on
// lavapipe, so follow finds this once per pixel rather than once per sample.
uvec2 pixel_xy(uint pixel) {
    return uvec2(pixel % frame.width, pixel / frame.width);
}

// Sample s of the camera ray of pixel, at xy = pixel_xy(pixel); the direction is unit length.
void camera_ray(uvec2 xy, uint pixel, uint s, out vec3 origin, out vec3 d) {
    uint px = xy.x;
    uint py = xy.y;
    vec2 j = pixel_jitter(pixel, s);
    float half_height = frame_half_height();
    float aspect = frame_aspect();
    vec3 right = frame.cam_right.xyz, up = frame.cam_up.xyz, forward = frame.cam_forward.xyz;
    origin = frame.cam_origin.xyz;
    if (scene_has(FEATURE_MOTION) && (frame.flags & FLAG_CAMERA_MOTION) != 0u) {
        // The scene's camera at the ray's time: between its keys, the basis renormalised (a turning camera's lerped
        // axes are a little short).
        uint k;
        float f;
        motion_segment(k, f);
        MotionKey a = fetch_motion_key(k), b = fetch_motion_key(k + 1u);
        origin = toward(a.v0.xyz, b.v0.xyz, f);
        right = normalize(toward(a.e1.xyz, b.e1.xyz, f));
        up = normalize(toward(a.e2.xyz, b.e2.xyz, f));
        forward = normalize(toward(a.n0.xyz, b.n0.xyz, f));
    }
    // Row 0 is the top of the image.
    float sx = (2.0 * (float(px) + j.x) / float(frame.width) - 1.0) * half_height * aspect;
    float sy = (1.0 - 2.0 * (float(py) + j.y) / float(frame.height)) * half_height;
    if ((frame.flags & FLAG_ORTHOGRAPHIC) != 0u) {
        origin += sx * right + sy * up;
        d = forward;
    } else {
        d = normalize(sx * right + sy * up + forward);
    }
    float aperture = frame_aperture();
    if (scene_has(FEATURE_LENS) && aperture > 0.0) {
        // Thin lens: every ray through the lens meets the pinhole ray on the plane of focus.
        vec3 focus = origin + d * (frame_focus_distance() / dot(d, forward));
        vec2 lens = aperture * sample_concentric_disk(rand2(pixel, s, 0u, DIM_LENS));
        origin += lens.x * right + lens.y * up;
        d = normalize(focus - origin);
    }
}

// What a path carries from one bounce to the next; the wavefront keeps it in the PATH_* fields, follow in registers.
struct PathVertex {
    vec4 origin;   // of the ray just traced; .w: the pdf of the BSDF sample that chose it, 0 after a delta bounce
    vec3 dir;      // of that ray, unit length
    Spectrum beta;     // throughput up to the ray's origin
    Spectrum radiance; // gathered so far
    bool hero_only;    // a dispersive surface left the path its hero wavelength alone (spectral transport)
    float light_normal; // the normal the light BVH picked with at the ray's origin (pack_light_normal)
    uvec4 media;       // the volumes the ray is inside (FEATURE_MEDIA: media.glsl's stack)
    Spectrum media_ratios; // each channel's density of the path's free flights over their mean (medium_sample)
};

// Sample s of pixel (at xy = pixel_xy(pixel)), about to trace its camera ray: full throughput, nothing gathered,
// counted like a delta bounce.
PathVertex start_path(uvec2 xy, uint pixel, uint s) {
    motion_begin(pixel, s);
    wavelengths_begin(pixel, s);
    PathVertex v;
    camera_ray(xy, pixel, s, v.origin.xyz, v.dir);
    v.origin.w = 0.0;
    v.beta = Spectrum(1.0);
    v.radiance = Spectrum(0.0);
    v.hero_only = false;
    v.light_normal = 0.0;
    v.media = uvec4(0u);
    v.media_ratios = Spectrum(1.0);
    return v;
}

#endif
