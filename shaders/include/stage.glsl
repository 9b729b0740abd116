// The preamble every compute stage starts with: shared layout, workgroup size, and the invocation's index.
#ifndef STAGE_GLSL
#define STAGE_GLSL
#extension GL_GOOGLE_include_directive : require
#include "layout.glsl"
layout(local_size_x = WORKGROUP_SIZE, local_size_y = 1, local_size_z = 1) in;
#endif
