// Stages compiled more than once, with preprocessor defines: (stage, variant suffix, defines separated by spaces).
// Read by build.rs (via include!) and by run-time shader folders, so both build the same variants. A variant is
// named `{stage}_{suffix}`.
pub const STAGE_VARIANTS: &[(&str, &str, &str)] = &[
    // Alpha testing inside traversal (alphaMode MASK and BLEND), and BVH reads through texel buffers (TEXEL_BVH).
    ("extend", "alpha", "ALPHA_TEST"),
    ("extend", "texel", "TEXEL_BVH"),
    ("extend", "alpha_texel", "ALPHA_TEST TEXEL_BVH"),
    ("connect", "alpha", "ALPHA_TEST"),
    ("connect", "texel", "TEXEL_BVH"),
    ("connect", "alpha_texel", "ALPHA_TEST TEXEL_BVH"),
    ("probe_trace", "texel", "TEXEL_BVH"),
    // Material textures and alpha coverage when shading and sampling emitters.
    ("shade", "textured", "TEXTURED"),
];
