//! The scenes bench makes rather than loads: the terrain heightfield and its instanced forest.
use crate::scene::{Camera, Environment, Material, Mesh, Primitive, Scene};
use glam::{Mat4, Vec3};
use std::path::PathBuf;

/// `count` instances (a square grid, each turned about +y) of the `side` terrain's mesh, seen from above at an
/// angle: the instancing case, whose placed triangles would not fit in memory flattened.
pub fn instanced_terrain(count: usize, side: usize) -> Scene {
    let mut s = terrain(side);
    s.path = PathBuf::from(format!("instanced-terrain-{count}x{side}"));
    s.instances.clear();
    let row = (count as f32).sqrt().ceil() as usize;
    for i in 0..count {
        let (x, z) = ((i % row) as f32 - row as f32 / 2.0, (i / row) as f32 - row as f32 / 2.0);
        s.instances.push(crate::scene::Instance {
            mesh: 0,
            world_from_object: Mat4::from_rotation_translation(
                glam::Quat::from_rotation_y(i as f32 * 0.7),
                Vec3::new(x * 2.2, 0.0, z * 2.2),
            ),
        });
    }
    let extent = row as f32 * 1.1;
    let eye = Vec3::new(0.0, extent * 0.8, extent * 1.6);
    s.camera = Some(Camera::look_at(eye, Vec3::ZERO, 45f32.to_radians()));
    s
}

/// A heightfield of `side`^2 quads (2 side^2 triangles) of rolling hills under a uniform sky.
pub fn terrain(side: usize) -> Scene {
    let h = |x: f32, z: f32| {
        0.08 * (x * 9.0).sin() * (z * 7.0).cos() + 0.03 * (x * 31.0 + z * 17.0).sin() + 0.01 * (x * 97.0).cos()
    };
    let n = side + 1;
    let mut p = Vec::with_capacity(n * n);
    let mut nrm = Vec::with_capacity(n * n);
    let e = 1e-3;
    for j in 0..n {
        for i in 0..n {
            let (x, z) = (i as f32 / side as f32 * 2.0 - 1.0, j as f32 / side as f32 * 2.0 - 1.0);
            p.push(Vec3::new(x, h(x, z), z));
            let dx = (h(x + e, z) - h(x - e, z)) / (2.0 * e);
            let dz = (h(x, z + e) - h(x, z - e)) / (2.0 * e);
            nrm.push(Vec3::new(-dx, 1.0, -dz).normalize());
        }
    }
    let mut s = Scene {
        path: PathBuf::from(format!("terrain-{side}")),
        ..Default::default()
    };
    s.materials.push(Material {
        name: "ground".into(),
        base_color: Vec3::splat(0.6),
        metallic: 0.0,
        specular: 0.0,
        ..Default::default()
    });
    let mut triangles = Vec::with_capacity(2 * side * side);
    for j in 0..side {
        for i in 0..side {
            let a = (j * n + i) as u32;
            let (b, c, d) = (a + 1, a + n as u32, a + n as u32 + 1);
            // Counter-clockwise seen from above (+y).
            triangles.extend([[a, c, b], [b, c, d]]);
        }
    }
    let ground = Primitive {
        positions: p,
        normals: Some(nrm),
        triangles,
        material: 0,
        ..Default::default()
    };
    s.add_mesh(
        Mesh {
            name: "terrain".into(),
            primitives: vec![ground],
        },
        Mat4::IDENTITY,
    );
    let eye = Vec3::new(0.0, 1.2, 2.2);
    s.camera = Some(Camera::look_at(eye, Vec3::ZERO, 45f32.to_radians()));
    s.environment = Some(Environment::constant([1.0, 1.0, 1.0]));
    s
}
