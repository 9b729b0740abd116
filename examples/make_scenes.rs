//! Regenerates the project's own scenes in scenes/ from tests/common/scenes.rs.
#[path = "../tests/common/gltf_builder.rs"]
mod gltf_builder;
#[path = "../tests/common/scenes.rs"]
mod scenes;

fn main() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    for (name, b) in [
        ("cornell-box.gltf", scenes::cornell_box()),
        ("furnace.gltf", scenes::furnace(0.5, 0.5)),
        ("two-lights.gltf", scenes::two_lights()),
        ("unequal-lights.gltf", scenes::unequal_lights()),
        ("material-grid.gltf", scenes::material_grid()),
        ("glass.gltf", scenes::glass()),
        ("punctual-lights.gltf", scenes::punctual_lights()),
        ("textured.gltf", scenes::textured()),
        ("animated.gltf", scenes::animated()),
        ("layers.gltf", scenes::layers()),
        ("anisotropy.gltf", scenes::anisotropy()),
        ("iridescence.gltf", scenes::iridescence()),
        ("translucency.gltf", scenes::translucency()),
    ] {
        b.write(&dir.join(name));
        println!("wrote scenes/{name}");
    }
}
