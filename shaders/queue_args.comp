// queue_args: one invocation turns the queue counters into this bounce's indirect dispatch and resets the queues it frees.
#version 460
#extension GL_GOOGLE_include_directive : require
#include "layout.glsl"
layout(local_size_x = 1) in;

// frame.bounce == NO_HIT marks the call after the last bounce: only the shadow-ray tally remains.
void main() {
    counters.shadow_rays += counters.queue_count[QUEUE_SHADOW];
    counters.queue_count[QUEUE_SHADOW] = 0u;
    if (frame.bounce == NO_HIT) return;
    uint cur = frame.bounce & 1u;
    uint n = counters.queue_count[cur];
    counters.extension_rays += n;
    counters.dispatch[0] = (n + WORKGROUP_SIZE - 1u) / WORKGROUP_SIZE;
    counters.dispatch[1] = 1u;
    counters.dispatch[2] = 1u;
    counters.queue_count[1u - cur] = 0u;
}
