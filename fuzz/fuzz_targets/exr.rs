//! Fuzzes `output::read_exr`, the reader for pathwave's own EXR output (tests and tools today; merging films later).
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("film.exr");
    std::fs::write(&path, data).unwrap();
    let _ = pathwave::output::read_exr(&path);
});
