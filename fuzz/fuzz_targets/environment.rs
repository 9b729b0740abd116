//! Fuzzes `scene::Environment::load` with .hdr and .exr bytes (picked by the input's magic number).
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let dir = tempfile::tempdir().unwrap();
    // OpenEXR's magic number is 0x762f3101; anything else goes to the Radiance reader.
    let name = if data.starts_with(&[0x76, 0x2f, 0x31, 0x01]) { "map.exr" } else { "map.hdr" };
    let path = dir.path().join(name);
    std::fs::write(&path, data).unwrap();
    let _ = pathwave::scene::Environment::load(&path, 1.0);
});
