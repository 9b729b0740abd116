//! Helpers shared by the integration tests.
#![allow(dead_code)]
pub mod gltf_builder;
pub mod scenes;

use std::path::PathBuf;

/// Tests run with the validation layer when it is installed, and fail on any of its errors.
pub fn enable_validation() {
    if std::env::var_os("PATHWAVE_VALIDATION").is_none() && validation_layer_installed() {
        std::env::set_var("PATHWAVE_VALIDATION", "1");
    }
}

pub fn validation_layer_installed() -> bool {
    ["/usr/share/vulkan/explicit_layer.d/VkLayer_khronos_validation.json", "/etc/vulkan/explicit_layer.d/VkLayer_khronos_validation.json"]
        .iter()
        .any(|p| std::path::Path::new(p).exists())
}

pub fn scenes_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenes")
}

/// Writes a built scene into a fresh temporary directory and returns (dir guard, path).
pub fn write_temp(b: &gltf_builder::GltfBuilder, name: &str) -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join(name);
    b.write(&path);
    (dir, path)
}
