// Stages compiled more than once, with a preprocessor define: (stage, variant suffix, define). Read by build.rs (via
// include!) and by run-time shader folders, so both build the same variants. A variant is named `{stage}_{suffix}`.
pub const STAGE_VARIANTS: &[(&str, &str, &str)] = &[
    // Alpha testing inside traversal (alphaMode MASK and BLEND).
    ("extend", "alpha", "ALPHA_TEST"),
    ("connect", "alpha", "ALPHA_TEST"),
    // Material textures and alpha coverage when shading and sampling emitters.
    ("shade", "textured", "TEXTURED"),
];
