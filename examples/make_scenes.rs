//! Regenerates the project's own scenes in scenes/ from tests/common/scenes.rs.
#[path = "../tests/common/gltf_builder.rs"]
mod gltf_builder;
#[path = "../tests/common/scenes.rs"]
mod scenes;

fn main() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    for (name, b) in scenes::all() {
        b.write(&dir.join(name));
        println!("wrote scenes/{name}");
    }
}
