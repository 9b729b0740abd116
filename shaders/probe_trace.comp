// probe_trace: runs the device traversal on rays from Rust so tests can compare it with a CPU brute force.
// One TraceRecord per ray; probe_mode() PROBE_ANY_HIT asks for any hit instead of the closest. The _alpha variants
// test alpha-tested triangles as extend and connect do, with the record's key.
#version 460
#extension GL_GOOGLE_include_directive : require
#include "stage.glsl"
#include "traverse.glsl"

layout(std430, set = 0, binding = BINDING_PROBE) buffer Probe { TraceRecord records[]; };

void main() {
    uint k = gl_GlobalInvocationID.x;
    if (k >= frame.path_count) return;
    TraceRecord r = records[k];
    motion_time = r.time;
    Hit h = trace(r.origin, r.dir, r.tmin, r.tmax, probe_mode() == PROBE_ANY_HIT, r.key);
    records[k].t = h.t;
    records[k].tri = h.tri;
    records[k].uv = h.uv;
    records[k].inst = h.inst;
}
