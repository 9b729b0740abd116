//! Fuzzes `scene::load` (and `flatten`) with .gltf and .glb bytes; a refusal is fine, a panic, abort or hang is a bug.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    // The loader reads files (and resolves URIs beside them), so each input is written to a folder of its own.
    let dir = tempfile::tempdir().unwrap();
    let name = if data.starts_with(b"glTF") { "fuzz.glb" } else { "fuzz.gltf" };
    let path = dir.path().join(name);
    std::fs::write(&path, data).unwrap();
    if let Ok(scene) = pathwave::scene::load(&path, None) {
        drop(scene.flatten());
    }
});
