//! Fuzzes `output::read_exr` and `output::read_film`, the readers of pathwave's own EXR output and film files (merge,
//! diff).
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("film.exr");
    std::fs::write(&path, data).unwrap();
    let _ = pathwave::output::read_exr(&path);
    let _ = pathwave::output::read_film(&path);
});
