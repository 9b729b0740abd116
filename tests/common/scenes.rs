//! The scenes in scenes/, as code: tests/scenes.rs checks the files match, examples/make_scenes.rs writes them.
#![allow(dead_code)]
use super::gltf_builder::{level, square, upright, GltfBuilder, FACING_DOWN, FACING_UP, FACING_Z};

/// A node rotation that turns a light's -z (where spot and directional lights shine) straight down: a quarter turn
/// about x.
pub const POINTING_DOWN: [f32; 4] = [
    -std::f32::consts::FRAC_1_SQRT_2,
    0.0,
    0.0,
    std::f32::consts::FRAC_1_SQRT_2,
];

/// Every scene in scenes/ by file name.
pub fn all() -> Vec<(&'static str, GltfBuilder)> {
    vec![
        ("cornell-box.gltf", cornell_box()),
        ("furnace.gltf", furnace(0.5, 0.5)),
        ("two-lights.gltf", two_lights()),
        ("unequal-lights.gltf", unequal_lights()),
        ("material-grid.gltf", material_grid()),
        ("glass.gltf", glass()),
        ("punctual-lights.gltf", punctual_lights()),
        ("textured.gltf", textured()),
        ("animated.gltf", animated()),
        ("layers.gltf", layers()),
        ("anisotropy.gltf", anisotropy()),
        ("iridescence.gltf", iridescence()),
        ("translucency.gltf", translucency()),
        ("subsurface.gltf", subsurface()),
        ("halves.gltf", halves()),
        ("prism.gltf", prism()),
    ]
}

/// The Cornell box with the measured dimensions (in metres) and the common RGB reflectances of its walls.
pub fn cornell_box() -> GltfBuilder {
    let mut b = GltfBuilder::new();
    let s = 0.001; // the original data is in millimetres
    let p = |v: [f32; 3]| [v[0] * s, v[1] * s, v[2] * s];
    let white = b.material("white", [0.725, 0.71, 0.68], [0.0; 3], false);
    let red = b.material("red", [0.63, 0.065, 0.05], [0.0; 3], false);
    let green = b.material("green", [0.14, 0.45, 0.091], [0.0; 3], false);
    let light = b.material("light", [0.78, 0.78, 0.78], [17.0, 12.0, 4.0], false);
    let inward = |c: [f32; 3]| Some([278.0 - c[0], 274.4 - c[1], 279.6 - c[2]]);
    let quad = |b: &mut GltfBuilder, name: &str, q: [[f32; 3]; 4], m: usize, facing: Option<[f32; 3]>| {
        b.quad(name, q.map(p), m, facing)
    };
    // The room's corners (mm): the floor's, then the ceiling's, each from the front corner on the red side round.
    let [f0, f1, f2, f3]: [[f32; 3]; 4] = [
        [552.8, 0.0, 0.0],
        [0.0, 0.0, 0.0],
        [0.0, 0.0, 559.2],
        [549.6, 0.0, 559.2],
    ];
    let [c0, c1, c2, c3]: [[f32; 3]; 4] = [
        [556.0, 548.8, 0.0],
        [556.0, 548.8, 559.2],
        [0.0, 548.8, 559.2],
        [0.0, 548.8, 0.0],
    ];
    let lamp = [[343.0, 227.0], [343.0, 332.0], [213.0, 332.0], [213.0, 227.0]].map(|[x, z]| [x, 548.7, z]);
    for (name, corners, m, facing) in [
        ("floor", [f0, f1, f2, f3], white, inward([278.0, 0.0, 279.6])),
        ("ceiling", [c0, c1, c2, c3], white, inward([278.0, 548.8, 279.6])),
        ("back wall", [f3, f2, c2, c1], white, inward([278.0, 274.4, 559.2])),
        ("green wall", [f2, f1, c3, c2], green, inward([0.0, 274.4, 279.6])),
        ("red wall", [f0, f3, c1, c0], red, inward([556.0, 274.4, 279.6])),
        ("light", lamp, light, FACING_DOWN),
    ] {
        quad(&mut b, name, corners, m, facing);
    }
    // Each block: its top's corners (x, z) at its height; sides from each top edge down to the floor, then the top,
    // faces pointing away from the block's axis.
    let short = [[130.0, 65.0], [82.0, 225.0], [240.0, 272.0], [290.0, 114.0]];
    let tall = [[423.0, 247.0], [265.0, 296.0], [314.0, 456.0], [472.0, 406.0]];
    for (name, height, top) in [("short block", 165.0, short), ("tall block", 330.0, tall)] {
        let top: [[f32; 3]; 4] = top.map(|[x, z]| [x, height, z]);
        let c = top
            .iter()
            .fold([0.0; 3], |a, v| [a[0] + v[0] / 4.0, 0.0, a[2] + v[2] / 4.0]);
        for i in 0..4 {
            let (a, d) = (top[i], top[(i + 1) % 4]);
            let q = [
                [a[0], 0.0, a[2]],
                [a[0], height, a[2]],
                [d[0], height, d[2]],
                [d[0], 0.0, d[2]],
            ];
            let mid = [(a[0] + d[0]) / 2.0 - c[0], 0.0, (a[2] + d[2]) / 2.0 - c[2]];
            quad(&mut b, &format!("{name} side {i}"), q, white, Some(mid));
        }
        quad(&mut b, &format!("{name} top"), top, white, FACING_UP);
    }
    b.camera(
        p([278.0, 273.0, -800.0]),
        p([278.0, 273.0, 0.0]),
        [0.0, 1.0, 0.0],
        39.3077,
    );
    b
}

/// A closed room whose walls emit `le` from their inner faces and reflect `albedo`: every pixel converges to le / (1 - albedo).
pub fn furnace(le: f32, albedo: f32) -> GltfBuilder {
    let mut b = GltfBuilder::new();
    let m = b.material("wall", [albedo; 3], [le; 3], false);
    b.cube("room", [-1.0; 3], [1.0; 3], m, true);
    b.camera([0.2, -0.1, 0.3], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0], 60.0);
    b
}

/// A grey floor lit from above by one large and one small area light of equal power.
pub fn two_lights() -> GltfBuilder {
    floor_and_two_lights([
        ("big light", level([-1.8, -0.2], 1.0, [-1.0, 1.0]), 1.0),
        ("small light", level([0.9, 1.1], 0.6, [-0.16, 0.16]), 100.0),
    ])
}

/// Two square lights whose power differs by a known ratio (4:1 by area, 3:1 by radiance: 12:1 overall).
pub fn unequal_lights() -> GltfBuilder {
    floor_and_two_lights([
        ("bright", level([-1.5, -0.5], 1.0, [-0.5, 0.5]), 3.0),
        ("dim", level([0.5, 1.0], 1.0, [-0.25, 0.25]), 1.0),
    ])
}

/// A grey floor 4 m square seen from above, under two black area lights facing down: each its name, corners and
/// radiance.
fn floor_and_two_lights(lights: [(&str, [[f32; 3]; 4], f32); 2]) -> GltfBuilder {
    let mut b = GltfBuilder::new();
    let floor = b.material("floor", [0.5; 3], [0.0; 3], false);
    let lamps = lights.map(|(name, _, radiance)| b.material(name, [0.0; 3], [radiance; 3], false));
    b.quad("floor", square(2.0, 0.0), floor, FACING_UP);
    for ((name, corners, _), m) in lights.into_iter().zip(lamps) {
        b.quad(name, corners, m, FACING_DOWN);
    }
    b.camera([0.0, 3.0, 3.0], [0.0, 0.0, 0.0], [0.0, 1.0, 0.0], 50.0);
    b
}

/// The grey floor and the large area light above it that the sphere grids stand on.
fn sphere_stage() -> GltfBuilder {
    let mut b = GltfBuilder::new();
    let floor = b.material("floor", [0.4; 3], [0.0; 3], false);
    let light = b.material("light", [0.0; 3], [6.0; 3], false);
    b.quad("floor", level([-6.0, 6.0], 0.0, [-4.0, 4.0]), floor, FACING_UP);
    b.quad("light", level([-3.0, 3.0], 5.0, [-1.5, 1.5]), light, FACING_DOWN);
    b
}

/// The sphere grids' camera, which they add last.
fn sphere_stage_camera(mut b: GltfBuilder) -> GltfBuilder {
    b.camera([0.0, 3.2, 6.5], [0.0, 0.3, 0.0], [0.0, 1.0, 0.0], 32.0);
    b
}

/// Where the sphere of radius 0.5 in column `col` (of four, from the left) of the row at depth `z` stands.
fn stage_spot(col: usize, z: f32) -> [f32; 3] {
    [-1.8 + 1.2 * col as f32, 0.5, z]
}

/// Spheres of glTF metallic-roughness materials: roughness 0 to 1 across, dielectric (top row) and metal (bottom row),
/// over a grey floor under one large area light.
pub fn material_grid() -> GltfBuilder {
    let mut b = sphere_stage();
    let roughness = [0.0, 0.25, 0.5, 0.75, 1.0];
    for (row, (metallic, color)) in [(0.0, [0.8, 0.1, 0.1]), (1.0, [0.95, 0.64, 0.54])].iter().enumerate() {
        for (col, &r) in roughness.iter().enumerate() {
            let name = format!(
                "{} roughness {r}",
                if *metallic > 0.0 { "copper" } else { "red plastic" }
            );
            let m = b.pbr_material(&name, *color, *metallic, r, [0.0; 3], false);
            let x = -2.4 + 1.2 * col as f32;
            let z = -0.7 + 1.4 * row as f32;
            b.sphere(&name, [x, 0.5, z], 0.5, m);
        }
    }
    sphere_stage_camera(b)
}

/// Caustics-prone glass on a white floor under a small bright light: a thick glass sphere (IOR 1.5), a thin pane, and a
/// rough amber block that absorbs inside.
pub fn glass() -> GltfBuilder {
    let mut b = GltfBuilder::new();
    let floor = b.material("floor", [0.8; 3], [0.0; 3], false);
    let light = b.material("light", [0.0; 3], [60.0, 56.0, 50.0], false);
    let sphere = b.glass_material("glass", [1.0; 3], 1.5, 0.0, false, None);
    let pane = b.glass_material("thin pane", [0.9, 1.0, 0.95], 1.5, 0.0, true, None);
    let amber = b.glass_material("rough amber", [1.0; 3], 1.55, 0.3, false, Some(([1.0, 0.6, 0.2], 0.5)));
    b.quad("floor", square(5.0, 0.0), floor, FACING_UP);
    b.quad("light", square(0.3, 4.0), light, FACING_DOWN);
    b.sphere("glass sphere", [-0.9, 0.7, 0.0], 0.7, sphere);
    b.quad(
        "pane",
        [[0.3, 0.0, -1.2], [0.3, 1.4, -1.2], [0.3, 1.4, -0.2], [0.3, 0.0, -0.2]],
        pane,
        Some([1.0, 0.0, 0.0]),
    );
    b.cube("amber block", [0.7, 0.0, 0.0], [1.5, 0.8, 0.8], amber, false);
    b.camera([0.0, 2.2, 4.5], [0.0, 0.5, 0.0], [0.0, 1.0, 0.0], 38.0);
    b
}

/// One light of each KHR_lights_punctual type over a floor with spheres: a warm point light, a spot cone, a cool sun.
pub fn punctual_lights() -> GltfBuilder {
    use serde_json::json;
    let mut b = GltfBuilder::new();
    let floor = b.material("floor", [0.7; 3], [0.0; 3], false);
    let white = b.pbr_material("white plastic", [0.8; 3], 0.0, 0.4, [0.0; 3], false);
    let gold = b.pbr_material("gold", [1.0, 0.78, 0.34], 1.0, 0.3, [0.0; 3], false);
    b.quad("floor", square(6.0, 0.0), floor, FACING_UP);
    b.sphere("white sphere", [-1.0, 0.5, 0.0], 0.5, white);
    b.sphere("gold sphere", [1.0, 0.5, 0.0], 0.5, gold);
    b.point_light([1.0, 0.8, 0.6], 4.0, [-1.8, 1.6, 1.0]);
    let spot = json!({ "type": "spot", "spot": { "innerConeAngle": 0.25, "outerConeAngle": 0.45 } });
    b.punctual(spot, [1.0; 3], 30.0, [1.0, 3.0, 0.0], POINTING_DOWN);
    let sun = -50f32.to_radians();
    b.directional_light(
        [0.6, 0.7, 1.0],
        0.8,
        [0.0; 3],
        [(sun * 0.5).sin(), 0.0, 0.0, (sun * 0.5).cos()],
    );
    b.camera([0.0, 2.0, 4.5], [0.0, 0.4, 0.0], [0.0, 1.0, 0.0], 40.0);
    b
}

/// Procedural textures on every supported slot: a tiled floor (sRGB base colour and a bevelled normal map, repeated
/// by KHR_texture_transform), a sphere striped metal/plastic by its metallic-roughness texture, a perforated screen
/// (alphaMode MASK) that casts dotted shadows, a half-transparent pane (BLEND), and a glowing sign whose emissive
/// texture lights the room.
pub fn textured() -> GltfBuilder {
    use serde_json::json;
    let mut b = GltfBuilder::new();
    let (size, tile, bevel) = (128usize, 32usize, 4usize);
    let tile_of = |x: usize, y: usize| (x / tile + y / tile) % 2;
    let checker: Vec<[u8; 4]> = (0..size * size)
        .map(|k| match tile_of(k % size, k / size) {
            0 => [235, 225, 200, 255],
            _ => [170, 80, 55, 255],
        })
        .collect();
    // Tangent-space normals (+x right, +y up the image) tilted outwards over each tile's bevel.
    let bumps: Vec<[u8; 4]> = (0..size * size)
        .map(|k| {
            let (lx, ly) = (k % size % tile, k / size % tile);
            let nx = if lx < bevel {
                -0.6
            } else if lx >= tile - bevel {
                0.6
            } else {
                0.0
            };
            let ny = if ly < bevel {
                0.6
            } else if ly >= tile - bevel {
                -0.6
            } else {
                0.0
            };
            let n = glam::Vec3::new(nx, ny, 1.0).normalize();
            let e = |c: f32| ((c + 1.0) * 0.5 * 255.0).round() as u8;
            [e(n.x), e(n.y), e(n.z), 255]
        })
        .collect();
    let floor = b.pbr_material("tiles", [1.0; 3], 0.0, 0.6, [0.0; 3], false);
    let repeat = json!({ "wrapS": 10497, "wrapT": 10497 });
    let checker_img = b.png_image(size as u32, size as u32, &checker);
    let checker_tex = b.texture(checker_img, repeat.clone());
    let bumps_img = b.png_image(size as u32, size as u32, &bumps);
    let bumps_tex = b.texture(bumps_img, repeat);
    let tiled = json!({ "KHR_texture_transform": { "scale": [3.0, 3.0] } });
    b.use_extension("KHR_texture_transform");
    let fm = b.material_json(floor);
    fm["pbrMetallicRoughness"]["baseColorTexture"] = json!({ "index": checker_tex, "extensions": tiled });
    fm["normalTexture"] = json!({ "index": bumps_tex, "extensions": tiled });
    b.textured_quad(
        "floor",
        [[-4.0, 0.0, -4.0], [-4.0, 0.0, 4.0], [4.0, 0.0, 4.0], [4.0, 0.0, -4.0]],
        [[0.0, 0.0], [0.0, 1.0], [1.0, 1.0], [1.0, 0.0]],
        floor,
    );

    // Stripes: metal (blue 255) with roughness 0.2 (green 51), plastic with roughness 0.6.
    let stripes: Vec<[u8; 4]> = (0..64 * 64)
        .map(|k| {
            if (k / 64 / 8) % 2 == 0 {
                [0, 51, 255, 255]
            } else {
                [0, 153, 0, 255]
            }
        })
        .collect();
    let sphere = b.pbr_material("striped", [0.95, 0.7, 0.35], 1.0, 1.0, [0.0; 3], false);
    let stripes_img = b.png_image(64, 64, &stripes);
    let stripes_tex = b.texture(stripes_img, json!({ "magFilter": 9728 }));
    b.material_json(sphere)["pbrMetallicRoughness"]["metallicRoughnessTexture"] = json!({ "index": stripes_tex });
    b.textured_sphere("striped sphere", [-1.1, 0.7, 0.3], 0.7, sphere);

    // A screen with round holes: alpha 0 inside circles, 1 between them.
    let holes: Vec<[u8; 4]> = (0..64 * 64)
        .map(|k| {
            let (x, y) = ((k % 64) % 16, (k / 64) % 16);
            let (dx, dy) = (x as f32 - 7.5, y as f32 - 7.5);
            let inside = dx * dx + dy * dy < 30.0;
            [240, 240, 240, if inside { 0 } else { 255 }]
        })
        .collect();
    let screen = b.material("perforated screen", [1.0; 3], [0.0; 3], true);
    let holes_img = b.png_image(64, 64, &holes);
    let holes_tex = b.texture(holes_img, json!({ "magFilter": 9728 }));
    let sm = b.material_json(screen);
    sm["pbrMetallicRoughness"]["baseColorTexture"] = json!({ "index": holes_tex });
    sm["alphaMode"] = json!("MASK");
    b.textured_quad(
        "screen",
        [[0.2, 2.2, -0.6], [0.2, 0.6, -0.6], [1.8, 0.6, -0.6], [1.8, 2.2, -0.6]],
        [[0.0, 0.0], [0.0, 1.0], [1.0, 1.0], [1.0, 0.0]],
        screen,
    );

    let pane = b.material("blue veil", [0.2, 0.4, 0.9], [0.0; 3], true);
    let pm = b.material_json(pane);
    pm["alphaMode"] = json!("BLEND");
    pm["pbrMetallicRoughness"]["baseColorFactor"][3] = json!(0.5);
    b.quad("veil", upright([-0.2, 1.4], [0.0, 1.2], 1.2), pane, FACING_Z);

    // The sign: a horizontal rainbow-ish gradient, brighter towards the middle.
    let gradient: Vec<[u8; 4]> = (0..32 * 8)
        .map(|k| {
            let t = (k % 32) as f32 / 31.0;
            let c = |phase: f32| (((t * 6.0 + phase).sin() * 0.5 + 0.5) * 255.0) as u8;
            [c(0.0), c(2.1), c(4.2), 255]
        })
        .collect();
    let sign = b.pbr_material("sign", [0.0; 3], 0.0, 1.0, [4.0; 3], false);
    let gradient_img = b.png_image(32, 8, &gradient);
    let gradient_tex = b.texture(gradient_img, json!({}));
    b.material_json(sign)["emissiveTexture"] = json!({ "index": gradient_tex });
    b.textured_quad(
        "sign",
        [[-2.0, 2.4, -2.5], [-2.0, 1.6, -2.5], [1.0, 1.6, -2.5], [1.0, 2.4, -2.5]],
        [[0.0, 0.0], [0.0, 1.0], [1.0, 1.0], [1.0, 0.0]],
        sign,
    );
    // Behind the screen, so its holes throw spots of light towards the camera.
    let light = b.material("light", [0.0; 3], [120.0; 3], false);
    b.quad("light", level([0.8, 1.2], 3.0, [-1.9, -1.5]), light, FACING_DOWN);
    b.camera([0.3, 2.4, 5.2], [0.0, 0.8, 0.0], [0.0, 1.0, 0.0], 45.0);
    b
}

/// Everything glTF animation moves, in a small lit room, over two seconds: a cube that slides (LINEAR translation)
/// and turns (LINEAR rotation, slerped), a sphere that bounces (CUBICSPLINE), a quad whose corner morphs up and
/// down (morph-target weights), a two-bone bar that bends (a skin), a light that blinks on and off (STEP scale),
/// and a camera that dollies in.
pub fn animated() -> GltfBuilder {
    use glam::{Quat, Vec3};
    let mut b = GltfBuilder::new();
    let white = b.material("white", [0.7, 0.7, 0.7], [0.0; 3], false);
    let red = b.material("red", [0.7, 0.1, 0.08], [0.0; 3], false);
    let blue = b.material("blue", [0.1, 0.2, 0.7], [0.0; 3], true);
    let yellow = b.material("yellow", [0.8, 0.6, 0.1], [0.0; 3], false);
    let light = b.material("light", [0.8; 3], [12.0, 11.0, 9.0], false);
    b.quad("floor", square(2.0, 0.0), white, FACING_UP);
    b.quad("back wall", upright([-2.0, 2.0], [0.0, 3.0], -2.0), white, FACING_Z);
    b.quad("lamp", square(0.6, 2.9), light, FACING_DOWN);
    b.quad("blinker", upright([1.2, 1.8], [2.0, 2.6], -1.99), light, FACING_Z);
    let blinker = b.last_node();
    b.animate(
        "blink",
        blinker,
        "scale",
        "STEP",
        &[0.0, 0.5, 1.0, 1.5],
        &[1.0, 1.0, 1.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 0.0, 0.0, 0.0],
    );

    b.cube("cube", [-0.25, 0.0, -0.25], [0.25, 0.5, 0.25], red, false);
    // `cube` makes one node per face: a parent moves them together.
    let faces: Vec<usize> = (b.last_node() - 5..=b.last_node()).collect();
    let cube = b.node("cube", serde_json::json!({ "translation": [-1.2, 0.0, 0.0] }));
    for f in faces {
        b.add_child(cube, f);
    }
    b.slide("move", cube, [0.0, 2.0], [-1.2, 0.0, 0.3], [-0.6, 0.0, -0.6]);
    let turn = |deg: f32| Quat::from_rotation_y(deg.to_radians()).to_array();
    let rotations: Vec<f32> = [0.0, 90.0, 180.0].iter().flat_map(|&d| turn(d)).collect();
    b.animate("move", cube, "rotation", "LINEAR", &[0.0, 1.0, 2.0], &rotations);

    b.sphere("ball", [0.0, 0.0, 0.0], 0.25, yellow);
    let ball = b.last_node();
    b.transform_last_node(serde_json::json!({ "translation": [0.2, 0.25, 0.6] }));
    // In-tangent, value, out-tangent per key (metres per second): up fast, down fast, a rest at the top.
    let bounce = [
        [0.0, 0.0, 0.0],
        [0.2, 0.25, 0.6],
        [0.0, 3.0, 0.0],
        [0.0, 0.0, 0.0],
        [0.2, 1.2, 0.6],
        [0.0, 0.0, 0.0],
        [0.0, -3.0, 0.0],
        [0.2, 0.25, 0.6],
        [0.0, 0.0, 0.0],
    ];
    b.animate(
        "move",
        ball,
        "translation",
        "CUBICSPLINE",
        &[0.0, 1.0, 2.0],
        &bounce.concat(),
    );

    let corners = [[0.6, 0.01, 0.2], [1.6, 0.01, 0.2], [1.6, 0.01, 1.2], [0.6, 0.01, 1.2]];
    b.mesh("sheet", &corners, &[0, 2, 1, 0, 3, 2], blue);
    b.add_morph_target(&[[0.0; 3], [0.0; 3], [0.0, 0.9, 0.0], [0.0; 3]], &[0.0]);
    let sheet = b.last_node();
    b.animate("move", sheet, "weights", "LINEAR", &[0.0, 1.0, 2.0], &[0.0, 1.0, 0.0]);

    // A bar of two segments along +y from (-0.5, 0, -1): the lower joint holds the bottom, the upper the top.
    let (w, h) = (0.12, 0.6);
    let mut positions = Vec::new();
    for level in 0..=2 {
        let y = level as f32 * h;
        for (x, z) in [(-w, -w), (w, -w), (w, w), (-w, w)] {
            positions.push([-0.5 + x, y, -1.0 + z]);
        }
    }
    let mut indices = Vec::new();
    for level in 0..2u32 {
        let (lo, hi) = (level * 4, level * 4 + 4);
        for s in 0..4 {
            let (a, c) = (s, (s + 1) % 4);
            indices.extend([lo + a, lo + c, hi + c, lo + a, hi + c, hi + a]);
        }
    }
    indices.extend([8, 10, 9, 8, 11, 10]);
    b.mesh("bar", &positions, &indices, yellow);
    let root = b.node("bone 0", serde_json::json!({ "translation": [-0.5, 0.0, -1.0] }));
    let upper = b.node("bone 1", serde_json::json!({ "translation": [0.0, h, 0.0] }));
    b.add_child(root, upper);
    let joints: Vec<[u16; 4]> = (0..12)
        .map(|v| {
            if v < 4 {
                [0, 0, 0, 0]
            } else if v < 8 {
                [0, 1, 0, 0]
            } else {
                [1, 0, 0, 0]
            }
        })
        .collect();
    let weights: Vec<[f32; 4]> = (0..12)
        .map(|v| {
            if (4..8).contains(&v) {
                [0.5, 0.5, 0.0, 0.0]
            } else {
                [1.0, 0.0, 0.0, 0.0]
            }
        })
        .collect();
    let inverse = |t: Vec3| glam::Mat4::from_translation(-t).to_cols_array();
    b.skin_last_mesh(
        &[root, upper],
        &[inverse(Vec3::new(-0.5, 0.0, -1.0)), inverse(Vec3::new(-0.5, h, -1.0))],
        &joints,
        &weights,
    );
    let bend = |deg: f32| Quat::from_rotation_z(deg.to_radians()).to_array();
    let bends: Vec<f32> = [0.0, -70.0, 0.0].iter().flat_map(|&d| bend(d)).collect();
    b.animate("move", upper, "rotation", "LINEAR", &[0.0, 1.0, 2.0], &bends);

    b.camera([0.0, 1.4, 4.6], [0.0, 0.8, 0.0], [0.0, 1.0, 0.0], 40.0);
    let camera = b.last_node();
    b.slide("move", camera, [0.0, 2.0], [0.0, 1.4, 4.6], [0.0, 1.3, 3.8]);
    b
}

/// The layer extensions on a grid of spheres under one area light: front row KHR_materials_clearcoat (a red base
/// under a smooth, a 0.3 and a fully rough coat, then a rough copper under a smooth coat: car paint), back row
/// KHR_materials_sheen (a dark blue base under a white sheen of roughness 0.3 and 0.8, a purple velvet, then an
/// unlit sphere of KHR_materials_unlit).
pub fn layers() -> GltfBuilder {
    let mut b = sphere_stage();
    b.use_extension("KHR_materials_clearcoat");
    b.use_extension("KHR_materials_sheen");
    b.use_extension("KHR_materials_unlit");
    let coats = [
        ("red under a smooth coat", [0.8, 0.1, 0.1], 0.0, 0.6, 0.0),
        ("red under a coat of roughness 0.3", [0.8, 0.1, 0.1], 0.0, 0.6, 0.3),
        ("red under a rough coat", [0.8, 0.1, 0.1], 0.0, 0.6, 1.0),
        ("car paint", [0.95, 0.64, 0.54], 1.0, 0.5, 0.0),
    ];
    for (col, (name, color, metallic, roughness, coat)) in coats.into_iter().enumerate() {
        let m = b.pbr_material(name, color, metallic, roughness, [0.0; 3], false);
        b.material_json(m)["extensions"]["KHR_materials_clearcoat"] =
            serde_json::json!({ "clearcoatFactor": 1.0, "clearcoatRoughnessFactor": coat });
        b.sphere(name, stage_spot(col, 0.7), 0.5, m);
    }
    let sheens = [
        ("white sheen 0.3 over blue", [0.05, 0.1, 0.4], [1.0, 1.0, 1.0], 0.3),
        ("white sheen 0.8 over blue", [0.05, 0.1, 0.4], [1.0, 1.0, 1.0], 0.8),
        ("purple velvet", [0.1, 0.02, 0.1], [0.8, 0.3, 0.9], 0.5),
    ];
    for (col, (name, base, sheen, roughness)) in sheens.into_iter().enumerate() {
        let m = b.material(name, base, [0.0; 3], false);
        b.material_json(m)["extensions"]["KHR_materials_sheen"] =
            serde_json::json!({ "sheenColorFactor": sheen, "sheenRoughnessFactor": roughness });
        b.sphere(name, stage_spot(col, -0.7), 0.5, m);
    }
    let unlit = b.unlit_material("unlit", [0.9, 0.7, 0.2]);
    b.sphere("unlit", [1.8, 0.5, -0.7], 0.5, unlit);
    sphere_stage_camera(b)
}

/// KHR_materials_anisotropy on UV spheres (the tangent runs around the equator): front row brushed aluminium of
/// roughness 0.3 at strength 0, 0.5 and 1, then strength 1 turned a quarter (stretched from pole to pole); back row
/// a brushed copper of roughness 0.1, an anisotropic white plastic and an anisotropic rough glass. Lit by the sphere
/// stage's area light and a small point light, whose highlights show the stretch.
pub fn anisotropy() -> GltfBuilder {
    let mut b = sphere_stage();
    b.use_extension("KHR_materials_anisotropy");
    let quarter = std::f32::consts::FRAC_PI_2;
    let front = [
        ("aluminium, isotropic", 0.0, 0.0),
        ("aluminium, strength 0.5", 0.5, 0.0),
        ("aluminium, strength 1", 1.0, 0.0),
        ("aluminium, strength 1 turned a quarter", 1.0, quarter),
    ];
    for (col, (name, strength, rotation)) in front.into_iter().enumerate() {
        let m = b.pbr_material(name, [0.91, 0.92, 0.92], 1.0, 0.3, [0.0; 3], false);
        b.material_json(m)["extensions"]["KHR_materials_anisotropy"] =
            serde_json::json!({ "anisotropyStrength": strength, "anisotropyRotation": rotation });
        b.textured_sphere(name, stage_spot(col, 0.7), 0.5, m);
    }
    let copper = b.pbr_material("brushed copper", [0.95, 0.64, 0.54], 1.0, 0.1, [0.0; 3], false);
    let plastic = b.pbr_material("anisotropic plastic", [0.8, 0.8, 0.8], 0.0, 0.2, [0.0; 3], false);
    let glass = b.glass_material("anisotropic glass", [1.0, 1.0, 1.0], 1.5, 0.2, false, None);
    for (col, m) in [copper, plastic, glass].into_iter().enumerate() {
        b.material_json(m)["extensions"]["KHR_materials_anisotropy"] =
            serde_json::json!({ "anisotropyStrength": 0.8, "anisotropyRotation": 0.0 });
        let name = format!("back {col}");
        b.textured_sphere(&name, stage_spot(col, -0.7), 0.5, m);
    }
    b.point_light([1.0; 3], 30.0, [2.5, 3.0, 3.0]);
    sphere_stage_camera(b)
}

/// KHR_materials_iridescence: front row a near-black plastic under a soap film (IOR 1.33) 200, 350, 500 and 700 nm
/// thick; back row a grey metal under a film of IOR 1.8 and 300 nm, copper under 1.5 and 450 nm, and a white plastic
/// under 2.0 and 250 nm. The sphere stage's area light and an environment-free sky: the colours are the films'.
pub fn iridescence() -> GltfBuilder {
    let mut b = sphere_stage();
    b.use_extension("KHR_materials_iridescence");
    let film = |b: &mut GltfBuilder, m: usize, ior: f32, thickness: f32| {
        b.material_json(m)["extensions"]["KHR_materials_iridescence"] = serde_json::json!({
            "iridescenceFactor": 1.0, "iridescenceIor": ior, "iridescenceThicknessMaximum": thickness
        });
    };
    for (col, thickness) in [200.0f32, 350.0, 500.0, 700.0].into_iter().enumerate() {
        let name = format!("soap film {thickness} nm");
        let m = b.pbr_material(&name, [0.02, 0.02, 0.02], 0.0, 0.15, [0.0; 3], false);
        film(&mut b, m, 1.33, thickness);
        b.sphere(&name, stage_spot(col, 0.7), 0.5, m);
    }
    let back = [
        ("grey metal, film 1.8 300 nm", [0.6, 0.6, 0.6], 1.0, 1.8, 300.0),
        ("copper, film 1.5 450 nm", [0.95, 0.64, 0.54], 1.0, 1.5, 450.0),
        ("white plastic, film 2.0 250 nm", [0.8, 0.8, 0.8], 0.0, 2.0, 250.0),
    ];
    for (col, (name, color, metallic, ior, thickness)) in back.into_iter().enumerate() {
        let m = b.pbr_material(name, color, metallic, 0.25, [0.0; 3], false);
        film(&mut b, m, ior, thickness);
        b.sphere(name, stage_spot(col, -0.7), 0.5, m);
    }
    sphere_stage_camera(b)
}

/// KHR_materials_diffuse_transmission: front row solid spheres (KHR_materials_volume) of a white wax transmitting all
/// of its diffuse lobe, one absorbing towards orange inside, and a green jade under a clear dielectric; back row thin
/// white sheets (paper) passing 0.2, 0.5 and 1.0 of their diffuse light, lit from behind by a second area light.
pub fn translucency() -> GltfBuilder {
    let mut b = sphere_stage();
    b.use_extension("KHR_materials_diffuse_transmission");
    b.use_extension("KHR_materials_volume");
    let translucent =
        |b: &mut GltfBuilder, m: usize, factor: f32, color: [f32; 3], volume: Option<serde_json::Value>| {
            let ext = &mut b.material_json(m)["extensions"];
            ext["KHR_materials_diffuse_transmission"] =
                serde_json::json!({ "diffuseTransmissionFactor": factor, "diffuseTransmissionColorFactor": color });
            if let Some(v) = volume {
                ext["KHR_materials_volume"] = v;
            }
        };
    let front = [
        (
            "white wax",
            [0.9, 0.9, 0.9],
            1.0,
            [1.0, 1.0, 1.0],
            serde_json::json!({ "thicknessFactor": 1.0 }),
        ),
        (
            "orange wax",
            [0.9, 0.9, 0.9],
            1.0,
            [1.0, 1.0, 1.0],
            serde_json::json!({ "thicknessFactor": 1.0, "attenuationColor": [1.0, 0.5, 0.2], "attenuationDistance": 0.3 }),
        ),
        (
            "jade",
            [0.3, 0.7, 0.4],
            0.8,
            [0.4, 0.9, 0.5],
            serde_json::json!({ "thicknessFactor": 1.0 }),
        ),
    ];
    for (col, (name, base, factor, color, volume)) in front.into_iter().enumerate() {
        let m = b.pbr_material(name, base, 0.0, if col == 2 { 0.1 } else { 0.6 }, [0.0; 3], false);
        translucent(&mut b, m, factor, color, Some(volume));
        b.sphere(name, [-1.2 + 1.2 * col as f32, 0.5, 0.9], 0.5, m);
    }
    for (col, factor) in [0.2f32, 0.5, 1.0].into_iter().enumerate() {
        let name = format!("paper {factor}");
        let m = b.material(&name, [0.9, 0.9, 0.85], [0.0; 3], true);
        translucent(&mut b, m, factor, [1.0, 0.95, 0.8], None);
        let x = -1.6 + 1.2 * col as f32;
        b.quad(&name, upright([x, x + 1.0], [0.0, 1.4], -0.8), m, FACING_Z);
    }
    let back = b.material("back light", [0.0; 3], [1.5; 3], false);
    b.quad("back light", upright([-3.0, 3.0], [0.2, 2.0], -2.5), back, FACING_Z);
    b.camera([0.0, 2.2, 6.5], [0.0, 0.6, 0.0], [0.0, 1.0, 0.0], 32.0);
    b
}

/// KHR_materials_scatter: four solid spheres of scattering media under smooth or slightly rough dielectric skins, lit
/// by one area light above and to the left so light diffusing through them shows against their shadowed
/// sides. Left to right: a white marble (dense, rho_ms near 1), a skin-like wax scattering red furthest, a green jade,
/// and a thin milky glass scattering forwards (g 0.7). Mean free paths are 2 to 10 cm in spheres of 1 m.
pub fn subsurface() -> GltfBuilder {
    let mut b = GltfBuilder::new();
    let floor = b.material("floor", [0.4; 3], [0.0; 3], false);
    let light = b.material("light", [0.0; 3], [20.0; 3], false);
    b.quad("floor", level([-6.0, 6.0], 0.0, [-4.0, 4.0]), floor, FACING_UP);
    b.quad("light", level([-2.8, -1.2], 4.0, [0.2, 1.8]), light, FACING_DOWN);
    b.use_extension("KHR_materials_scatter");
    // (name, roughness, ior, attenuation colour over distance (m), multiscatter colour, anisotropy)
    let media = [
        ("marble", 0.4, 1.5, [0.2, 0.2, 0.2], 0.05, [0.95, 0.94, 0.9], 0.0),
        ("wax", 0.5, 1.45, [0.3, 0.15, 0.1], 0.05, [0.95, 0.6, 0.4], 0.3),
        ("jade", 0.3, 1.6, [0.4, 0.2, 0.3], 0.1, [0.3, 0.85, 0.55], 0.0),
        ("milk glass", 0.0, 1.5, [0.5, 0.5, 0.5], 0.5, [0.9, 0.9, 0.9], 0.7),
    ];
    for (col, (name, roughness, ior, attenuation, distance, multiscatter, g)) in media.into_iter().enumerate() {
        let m = b.glass_material(name, [1.0; 3], ior, roughness, false, Some((attenuation, distance)));
        b.material_json(m)["extensions"]["KHR_materials_scatter"] = serde_json::json!({
            "scatterStrengthFactor": 1.0,
            "multiscatterColorFactor": multiscatter,
            "scatterAnisotropy": g,
        });
        b.sphere(name, stage_spot(col, 0.0), 0.5, m);
    }
    sphere_stage_camera(b)
}

/// Adaptive sampling's scene (tests/adaptive.rs, the bench): a grey floor seen from low down. The left half of the
/// view is lit by the sun straight above (smooth: next-event estimation of a directional light is exact, and a plane
/// sees nothing else), the right half is under a low roof the light reaches only by bouncing in from the lit side
/// (noisy).
pub fn halves() -> GltfBuilder {
    let mut b = GltfBuilder::new();
    let grey = b.material("grey", [0.6; 3], [0.0; 3], true);
    b.quad("floor", square(8.0, 0.0), grey, FACING_UP);
    b.quad("roof", level([0.0, 8.0], 0.6, [-8.0, 3.0]), grey, None);
    // A directional light shines along its node's -z: turned a quarter about x, straight down.
    b.directional_light([1.0; 3], 3.0, [0.0, 5.0, 0.0], POINTING_DOWN);
    b.camera([0.0, 0.4, 5.0], [0.0, 0.0, 0.0], [0.0, 1.0, 0.0], 60.0);
    b
}

/// A triangular prism of strongly dispersive glass (KHR_materials_dispersion 1.5: an Abbe number of 13, three times
/// dense flint's dispersion) before thin white stripes on a dark wall, under a small light: seen through the prism
/// each stripe fans out into its spectrum. The scene renders spectrally by default; `--rgb` shows it without.
pub fn prism() -> GltfBuilder {
    let mut b = GltfBuilder::new();
    let floor = b.material("floor", [0.5; 3], [0.0; 3], false);
    let wall = b.material("wall", [0.05; 3], [0.0; 3], false);
    let stripe = b.material("stripe", [0.0; 3], [6.0; 3], false);
    let light = b.material("light", [0.0; 3], [30.0; 3], false);
    let glass = b.glass_material("flint", [1.0; 3], 1.6, 0.0, false, None);
    b.dispersion(glass, 1.5);
    b.quad("floor", level([-4.0, 4.0], 0.0, [-2.0, 4.0]), floor, FACING_UP);
    b.quad("wall", upright([-4.0, 4.0], [0.0, 3.0], -1.5), wall, FACING_Z);
    for i in 0..7 {
        let x = -1.2 + 0.4 * i as f32;
        let corners = upright([x - 0.015, x + 0.015], [0.2, 2.2], -1.49);
        b.quad(&format!("stripe {i}"), corners, stripe, FACING_Z);
    }
    b.quad("light", level([-0.2, 0.2], 3.5, [0.3, 0.7]), light, FACING_DOWN);
    // Upright, its apex towards the camera: rays enter a front face and leave by the back one, bent sideways.
    let (r, lo, hi) = (0.6f32, 0.3f32, 1.9f32);
    let corner = |deg: f32, y: f32| {
        let a = deg.to_radians();
        [r * a.cos(), y, r * a.sin() + 0.2]
    };
    let corners = [
        corner(90.0, lo),
        corner(210.0, lo),
        corner(330.0, lo),
        corner(90.0, hi),
        corner(210.0, hi),
        corner(330.0, hi),
    ];
    b.convex_solid(
        "prism",
        &corners,
        &[&[0, 1, 2], &[3, 4, 5], &[0, 1, 4, 3], &[1, 2, 5, 4], &[2, 0, 3, 5]],
        glass,
    );
    b.camera([0.0, 1.1, 3.6], [0.0, 1.1, 0.0], [0.0, 1.0, 0.0], 40.0);
    b
}

/// A floor and a grey ball under one emissive bulb mesh placed four times: turned, stretched, mirrored and plain
/// (tests/instances.rs, tests/light_tree.rs). Materials: white 0, grey 1, glow 2.
pub fn lamps() -> GltfBuilder {
    use serde_json::json;
    let mut b = GltfBuilder::new();
    let white = b.material("white", [0.7; 3], [0.0; 3], false);
    let grey = b.material("grey", [0.5; 3], [0.0; 3], false);
    let glow = b.material("glow", [0.2; 3], [4.0, 3.0, 2.0], false);
    b.quad("floor", square(3.0, 0.0), white, FACING_UP);
    b.uv_sphere("ball", [0.0, 0.5, 0.0], 0.5, grey, true);
    b.uv_sphere("bulb", [0.0, 0.0, 0.0], 0.3, glow, true);
    b.transform_last_node(
        json!({ "translation": [-1.4, 1.2, 0.3], "rotation": glam::Quat::from_rotation_z(0.7).to_array() }),
    );
    b.place_last_mesh(
        "stretched",
        json!({ "translation": [1.3, 1.0, -0.4], "scale": [1.8, 0.5, 1.0] }),
    );
    b.place_last_mesh(
        "mirrored",
        json!({ "translation": [0.2, 1.8, -1.2], "scale": [-1.6, 1.6, 1.6] }),
    );
    b.place_last_mesh("plain", json!({ "translation": [0.5, 0.5, 1.2] }));
    b.camera([0.0, 2.0, 5.0], [0.0, 0.6, 0.0], [0.0, 1.0, 0.0], 45.0);
    b
}
