// Next-event estimation's light selection: emissive triangles picked in proportion to power.
#ifndef LIGHTS_GLSL
#define LIGHTS_GLSL

// Smallest index whose inclusive cdf exceeds u; the host makes the last cdf exactly 1.
uint pick_light(float u) {
    uint lo = 0u;
    uint hi = frame.light_count - 1u;
    while (lo < hi) {
        uint mid = (lo + hi) >> 1u;
        if (u < lights[mid].cdf) hi = mid; else lo = mid + 1u;
    }
    return lo;
}

#endif
