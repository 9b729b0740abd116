//! The scenes bench makes rather than loads: the terrain heightfield, its instanced forest, and textured props.
use crate::scene::texture::{Image, Texture, TextureRef, Wrap, IDENTITY_TRANSFORM};
use crate::scene::{Camera, Environment, Material, Mesh, Primitive, Scene};
use glam::{Mat4, Vec2, Vec3};
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

/// What a real textured asset asks of shading, made here (nothing downloaded): nine spheres on a floor under a
/// uniform sky, in three materials, each with its own `side` x `side` base colour (sRGB), metallic-roughness and
/// normal map of fine procedural detail (9 images: 144 MiB of texels at 2048, as much as a photoscanned prop), the
/// floor's tiled eight times; seen at an angle, so texels are magnified near the camera and minified far away.
pub fn textured_props(side: u32) -> Scene {
    let mut s = Scene {
        path: PathBuf::from(format!("textured-props-{side}")),
        ..Default::default()
    };
    // A hash of integer texel coordinates and a set, in [0, 1): the grain that makes every texel differ.
    let hash = |x: u32, y: u32, k: u32| {
        let mut h = x.wrapping_mul(0x8da6b343) ^ y.wrapping_mul(0xd8163841) ^ k.wrapping_mul(0xcb1ab31f);
        h ^= h >> 15;
        h = h.wrapping_mul(0x2c1b3c6d);
        h ^= h >> 12;
        (h & 0xffff) as f32 / 65536.0
    };
    let byte = |v: f32| (v.clamp(0.0, 1.0) * 255.0 + 0.5) as u8;
    let n = side as usize;
    for set in 0..3u32 {
        let f = (set + 3) as f32 * std::f32::consts::TAU / side as f32;
        // Tiles of `set + 3` per side with grout, and bumps within them.
        let height = |x: u32, y: u32| {
            let (u, v) = ((x as f32 * f * 8.0).sin(), (y as f32 * f * 8.0).sin());
            0.5 + 0.25 * u * v + 0.1 * hash(x, y, set)
        };
        let tint = [[0.8, 0.35, 0.2], [0.3, 0.5, 0.75], [0.85, 0.8, 0.6]][set as usize];
        let mut base = Vec::with_capacity(n * n);
        let mut rough = Vec::with_capacity(n * n);
        let mut normal = Vec::with_capacity(n * n);
        for y in 0..side {
            for x in 0..side {
                let grout = (x as f32 * f).sin().abs() < 0.06 || (y as f32 * f).sin().abs() < 0.06;
                let g = hash(x, y, set + 7);
                let shade = if grout { 0.25 } else { 0.7 + 0.3 * g };
                base.push([byte(tint[0] * shade), byte(tint[1] * shade), byte(tint[2] * shade), 255]);
                let r = if grout {
                    0.9
                } else {
                    0.25 + 0.5 * hash(x / 4, y / 4, set + 13)
                };
                let metal = if set == 1 && !grout { 1.0 } else { 0.0 };
                rough.push([0, byte(r), byte(metal), 255]);
                let dx = height(x + 1, y) - height(x.saturating_sub(1), y);
                let dy = height(x, y + 1) - height(x, y.saturating_sub(1));
                let nrm = Vec3::new(-dx * 2.0, -dy * 2.0, 1.0).normalize();
                normal.push([
                    byte(nrm.x * 0.5 + 0.5),
                    byte(nrm.y * 0.5 + 0.5),
                    byte(nrm.z * 0.5 + 0.5),
                    255,
                ]);
            }
        }
        let mut slot = |texels: Vec<[u8; 4]>| {
            s.images.push(Image {
                width: side,
                height: side,
                texels,
            });
            s.textures.push(Texture {
                image: s.images.len() - 1,
                wrap_s: Wrap::Repeat,
                wrap_t: Wrap::Repeat,
                nearest: false,
                mipmaps: true,
            });
            Some(TextureRef {
                texture: s.textures.len() - 1,
                tex_coord: 0,
                transform: IDENTITY_TRANSFORM,
            })
        };
        let (b, mr, nm) = (slot(base), slot(rough), slot(normal));
        s.materials.push(Material {
            name: format!("props-{set}"),
            base_color: Vec3::ONE,
            metallic: 1.0,
            roughness: 1.0,
            base_color_texture: b,
            metallic_roughness_texture: mr,
            normal_texture: nm,
            normal_scale: 1.0,
            ..Default::default()
        });
    }
    // UV spheres: u around, v from the top.
    let (rings, segments) = (48usize, 96usize);
    let mut sphere = Primitive::default();
    for j in 0..=rings {
        for i in 0..=segments {
            let (u, v) = (i as f32 / segments as f32, j as f32 / rings as f32);
            let (theta, phi) = (v * std::f32::consts::PI, u * std::f32::consts::TAU);
            let p = Vec3::new(theta.sin() * phi.cos(), theta.cos(), -theta.sin() * phi.sin());
            sphere.positions.push(p);
            sphere.normals.get_or_insert_with(Vec::new).push(p);
            sphere.texcoords[0]
                .get_or_insert_with(Vec::new)
                .push(Vec2::new(2.0 * u, v));
        }
    }
    let row = segments as u32 + 1;
    for j in 0..rings as u32 {
        for i in 0..segments as u32 {
            let a = j * row + i;
            sphere
                .triangles
                .extend([[a, a + row, a + 1], [a + 1, a + row, a + row + 1]]);
        }
    }
    for k in 0..9 {
        let mut p = sphere.clone();
        p.material = (k % 3) as u32;
        let at = Vec3::new((k % 3) as f32 * 2.2 - 2.2, 0.8, (k / 3) as f32 * -2.2);
        s.add_mesh(
            Mesh {
                name: format!("sphere-{k}"),
                primitives: vec![p],
            },
            Mat4::from_scale_rotation_translation(Vec3::splat(0.8), glam::Quat::from_rotation_y(k as f32), at),
        );
    }
    let floor = Primitive {
        positions: vec![
            Vec3::new(-10.0, 0.0, -10.0),
            Vec3::new(-10.0, 0.0, 10.0),
            Vec3::new(10.0, 0.0, 10.0),
            Vec3::new(10.0, 0.0, -10.0),
        ],
        normals: Some(vec![Vec3::Y; 4]),
        texcoords: [
            Some(vec![
                Vec2::new(0.0, 0.0),
                Vec2::new(0.0, 8.0),
                Vec2::new(8.0, 8.0),
                Vec2::new(8.0, 0.0),
            ]),
            None,
        ],
        triangles: vec![[0, 1, 2], [0, 2, 3]],
        material: 2,
        ..Default::default()
    };
    s.add_mesh(
        Mesh {
            name: "floor".into(),
            primitives: vec![floor],
        },
        Mat4::IDENTITY,
    );
    s.camera = Some(Camera::look_at(
        Vec3::new(0.5, 2.6, 4.2),
        Vec3::new(0.0, 0.5, -2.2),
        50f32.to_radians(),
    ));
    s.environment = Some(Environment::constant([1.0, 1.0, 1.0]));
    s
}
