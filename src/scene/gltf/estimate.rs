//! What reading a glTF document will take in host memory, from its JSON alone, before any of it is read.

/// Host bytes reading a glTF document takes, from its JSON alone: its buffers as declared, and every primitive's
/// accessors, morph targets, keyframes and inverse bind matrices decoded (at most 16 bytes an element, a vec4 of
/// f32, 64 a matrix; indices twice, as read and as triangles).
pub(super) fn load_estimate(doc: &gltf::Document) -> u64 {
    let buffers: u64 = doc.buffers().map(|b| b.length() as u64).fold(0, u64::saturating_add);
    let decoded = doc
        .meshes()
        .flat_map(|m| m.primitives())
        .flat_map(|p| {
            // Counts come from the file unchecked (the mutation test raises them to 2^63): saturate.
            let attributes = p
                .attributes()
                .map(|(_, a)| (a.count() as u64).saturating_mul(16))
                .collect::<Vec<_>>();
            let indices = p.indices().map(|i| (i.count() as u64).saturating_mul(8));
            let targets = (p.morph_targets())
                .flat_map(|t| [t.positions(), t.normals(), t.tangents()])
                .flatten()
                .map(|a| (a.count() as u64).saturating_mul(16))
                .collect::<Vec<_>>();
            attributes.into_iter().chain(indices).chain(targets)
        })
        .fold(0, u64::saturating_add);
    // Keyframes as floats (at most 16 bytes a key's element) and inverse bind matrices (64 bytes each).
    let keys = (doc.animations())
        .flat_map(|a| a.samplers())
        .map(|s| {
            (s.input().count() as u64)
                .saturating_add(s.output().count() as u64)
                .saturating_mul(16)
        })
        .fold(0, u64::saturating_add);
    let skins = (doc.skins())
        .filter_map(|s| s.inverse_bind_matrices())
        .map(|a| (a.count() as u64).saturating_mul(64))
        .fold(0, u64::saturating_add);
    buffers
        .saturating_add(decoded)
        .saturating_add(keys)
        .saturating_add(skins)
}
