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
    // Ray-query traversal through the device's acceleration structures (src/render/accel.rs), storage reads only.
    ("extend", "rq", "RAY_QUERY"),
    ("extend", "alpha_rq", "ALPHA_TEST RAY_QUERY"),
    ("connect", "rq", "RAY_QUERY"),
    ("connect", "alpha_rq", "ALPHA_TEST RAY_QUERY"),
    ("follow", "rq", "RAY_QUERY"),
    ("follow", "textured_rq", "TEXTURED RAY_QUERY"),
    ("follow", "alpha_rq", "ALPHA_TEST TEXTURED RAY_QUERY"),
    ("probe_trace", "rq", "RAY_QUERY"),
    // The probe as extend and connect trace alpha-tested scenes, for tests of both traversals against brute force.
    ("probe_trace", "alpha", "ALPHA_TEST"),
    ("probe_trace", "alpha_texel", "ALPHA_TEST TEXEL_READS"),
    ("probe_trace", "alpha_rq", "ALPHA_TEST RAY_QUERY"),
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
    // The wavefront's film reads spectral samples' CIE rows through texels (BINDING_CIE_TEXELS): its conversion of
    // a sample fell from 8x RGB's accumulate stage to 3.5x.
    ("accumulate", "texel", "TEXEL_READS"),
];

/// The Vulkan version glslang targets for a variant's defines: 1.1 (SPIR-V 1.3) for every stage, but 1.2 for ray
/// queries, whose SPIR-V needs 1.4.
pub fn target_env(defines: Option<&str>) -> &'static str {
    match defines.is_some_and(|d| d.split_whitespace().any(|d| d == "RAY_QUERY")) {
        true => "vulkan1.2",
        false => "vulkan1.1",
    }
}
