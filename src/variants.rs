// Stages compiled more than once, with preprocessor defines: (stage, variant suffix, defines separated by spaces).
// Read by build.rs (via include!) and by run-time shader folders, so both build the same variants. A variant is
// named `{stage}_{suffix}`.
pub const STAGE_VARIANTS: &[(&str, &str, &str)] = &[
    // Alpha testing inside traversal (alphaMode MASK and BLEND), and BVH and per-triangle reads through texel
    // buffers (TEXEL_READS).
    ("extend", "alpha", "ALPHA_TEST"),
    ("extend", "texel", "TEXEL_READS"),
    ("extend", "alpha_texel", "ALPHA_TEST TEXEL_READS"),
    ("connect", "alpha", "ALPHA_TEST"),
    ("connect", "texel", "TEXEL_READS"),
    ("connect", "alpha_texel", "ALPHA_TEST TEXEL_READS"),
    ("probe_trace", "texel", "TEXEL_READS"),
    // Material textures and alpha coverage when shading and sampling emitters.
    ("shade", "textured", "TEXTURED"),
    ("shade", "texel", "TEXEL_READS"),
    ("shade", "textured_texel", "TEXTURED TEXEL_READS"),
    // The fused integrator runs traversal and shading: alpha testing implies textured shading.
    ("follow", "textured", "TEXTURED"),
    ("follow", "alpha", "ALPHA_TEST TEXTURED"),
    ("follow", "texel", "TEXEL_READS"),
    ("follow", "textured_texel", "TEXTURED TEXEL_READS"),
    ("follow", "alpha_texel", "ALPHA_TEST TEXTURED TEXEL_READS"),
    // survey traces and shades like follow.
    ("survey", "textured", "TEXTURED"),
    ("survey", "alpha", "ALPHA_TEST TEXTURED"),
    ("survey", "texel", "TEXEL_READS"),
    ("survey", "textured_texel", "TEXTURED TEXEL_READS"),
    ("survey", "alpha_texel", "ALPHA_TEST TEXTURED TEXEL_READS"),
];
