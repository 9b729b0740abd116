//! The screen the texture, layer, anisotropy and variant tests look at: the square [-1, 1]^2 at z = 0, which fills
//! the view of `view`, its top-left corner at uv (0, 0).
#![allow(dead_code)]
use super::gltf_builder::GltfBuilder;

/// The corners of the square [-half, half]^2 at depth `z`: top left, bottom left, bottom right, top right
/// (counter-clockwise seen from +z).
pub fn corners(half: f32, z: f32) -> [[f32; 3]; 4] {
    [[-half, half, z], [-half, -half, z], [half, -half, z], [half, half, z]]
}

/// Texture coordinates of `corners`: u along +x, v down the view.
pub const UVS: [[f32; 2]; 4] = [[0.0, 0.0], [0.0, 1.0], [1.0, 1.0], [1.0, 0.0]];

/// The screen, moved to depth `z`, in `material`, with texture coordinates `UVS`.
pub fn quad(b: &mut GltfBuilder, material: usize, z: f32) {
    b.textured_quad("quad", corners(1.0, z), UVS, material);
}

/// A camera looking down -z at the screen, which fills its view: pixel (i, j) of an N x N image (row j from the top)
/// covers uv in [i/N, (i+1)/N] x [j/N, (j+1)/N].
pub fn view(b: &mut GltfBuilder) {
    let yfov = 2.0 * 0.5f32.atan();
    b.camera([0.0, 0.0, 2.0], [0.0; 3], [0.0, 1.0, 0.0], yfov.to_degrees());
}

/// A white directional light of intensity 2 shining along `dir` (its node 5 m in front of the screen).
pub fn light_along(b: &mut GltfBuilder, dir: glam::Vec3) {
    let rot = glam::Quat::from_rotation_arc(-glam::Vec3::Z, dir);
    b.directional_light([1.0; 3], 2.0, [0.0, 0.0, 5.0], rot.to_array());
}
