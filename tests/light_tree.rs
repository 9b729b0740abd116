//! Light selection on the device: the light BVH's descent and pdf twin against their CPU twin (bvh::lights), and the
//! three light samplers (bvh, power, uniform) with the three estimators converging to one image on many lights.
mod common;

use common::gltf_builder::{square, FACING_DOWN, FACING_UP};
use common::stats::image_mean_and_stderr;
use pathwave::constants::{LIGHT_KIND_SHIFT, LIGHT_KIND_TRIANGLE, LIGHT_NODE_LEAF, LIGHT_NONE};
use pathwave::layout::LightSelectRecord;
use pathwave::render::gpu_scene::pack;
use pathwave::{Estimator, Film, LightSampler, RenderSettings};

fn lamp_grid() -> pathwave::scene::Scene {
    pathwave::scene::load(&common::scenes_dir().join("lamp-grid.gltf"), None).unwrap()
}

fn lcg(state: &mut u64) -> f32 {
    *state = state
        .wrapping_mul(6364136223846793005)
        .wrapping_add(1442695040888963407);
    (*state >> 40) as f32 / (1u64 << 24) as f32
}

/// Points on and above the floor, normals up or random, the uniforms, and the entries whose pdf to ask for.
fn queries(entries: &[u32], n: usize) -> Vec<LightSelectRecord> {
    let mut s = 42;
    (0..n)
        .map(|k| {
            let p = [
                lcg(&mut s) * 20.0 - 10.0,
                if k % 3 == 0 { lcg(&mut s) * 2.0 } else { 0.0 },
                lcg(&mut s) * 20.0 - 10.0,
            ];
            let d = glam::Vec3::new(lcg(&mut s) - 0.5, lcg(&mut s) - 0.5, lcg(&mut s) - 0.5).normalize();
            let n = match k % 4 {
                0 => [0.0; 3],
                1 => d.to_array(),
                _ => [0.0, 1.0, 0.0],
            };
            LightSelectRecord {
                p,
                entry: entries[k % entries.len()],
                n,
                u: lcg(&mut s),
                v: lcg(&mut s),
                sub_entry: LIGHT_NONE,
                ..Default::default()
            }
        })
        .collect()
}

/// Catches a device descent or pdf twin that differs from the CPU twin the unit tests hold to chi-square and to a sum
/// of one: another child order, a trail bit read from the wrong word, the share of the infinite lights left out,
/// the fresh number taken at another depth, a two-sided flag read from the wrong node. Power and uniform selection's
/// pdfs are checked against the table too.
#[test]
fn device_light_selection_matches_its_cpu_twin() {
    let scene = lamp_grid();
    let packed = pack(&scene);
    let tree = &packed.light_tree;
    assert!(tree.stats.emitters > 500, "{} emitters", tree.stats.emitters);
    let entries: Vec<u32> = (0..packed.light_count)
        .filter(|&j| tree.nodes[1 + j as usize].link[0] == LIGHT_NODE_LEAF)
        .collect();
    let records = queries(&entries, 6000);
    let mut r = common::scene_renderer(&scene);
    let device = r.probe_light_select(&records, LightSampler::Bvh).unwrap();
    let share = tree.share();
    let (mut same, mut none) = (0, 0);
    for (q, d) in records.iter().zip(&device) {
        let (p, n) = (glam::Vec3::from(q.p), glam::Vec3::from(q.n));
        let host = tree.pick(p, n, q.u / share, q.v).map(|(e, prob)| (e, prob * share));
        match host {
            Some((e, prob)) if e == d.picked => {
                same += 1;
                assert!(
                    (prob - d.prob).abs() <= 1e-3 * prob,
                    "pick {e} at {p}: host {prob}, device {}",
                    d.prob
                );
            }
            None if d.picked == LIGHT_NONE => none += 1,
            _ => {}
        }
        let pmf = share * tree.pmf(p, n, q.entry);
        assert!(
            (pmf - d.pmf).abs() <= 1e-3 * pmf + 1e-12,
            "pmf of {} at {p} (n {n}): host {pmf}, device {}",
            q.entry,
            d.pmf
        );
    }
    // Picks near a child's boundary may go either way by an ulp of the importance; nothing more.
    eprintln!("{same} picks equal, {none} with nothing to pick, of {}", records.len());
    assert!(
        same + none >= records.len() * 995 / 1000,
        "only {same} + {none} of {} picks agree",
        records.len()
    );
    for (sampler, expect) in [
        (LightSampler::Power, None),
        (LightSampler::Uniform, Some(1.0 / packed.light_count as f32)),
    ] {
        for d in r.probe_light_select(&records[..500], sampler).unwrap() {
            let want = expect.unwrap_or(packed.lights[d.entry as usize].prob);
            assert_eq!(d.pmf, want, "{sampler:?}: pmf of entry {}", d.entry);
            assert_ne!(d.picked, LIGHT_NONE, "{sampler:?} found nothing to pick");
        }
    }
    // Every tree emitter of this scene is a world triangle; they are all leaves.
    assert!(entries
        .iter()
        .all(|&j| packed.lights[j as usize].id >> LIGHT_KIND_SHIFT == LIGHT_KIND_TRIANGLE));
}

fn render(sampler: LightSampler, estimator: Estimator, spp: u32, seed: u32) -> Film {
    let mut r = common::scene_renderer(&lamp_grid());
    let s = RenderSettings {
        light_sampler: sampler,
        estimator,
        ..common::settings(36, 24, spp, seed)
    };
    common::render(&mut r, &s)
}

fn summed_variance(film: &Film) -> f64 {
    film.sample_variance().iter().map(|v| (v[0] + v[1] + v[2]) as f64).sum()
}

/// Catches a biased sampler or MIS weights that do not add to one under the tree (a pdf twin evaluated at another
/// point or normal than the descent, a probability that is not the one picked with). Per pixel, light sampling alone
/// must agree with MIS under the tree: MIS weighs emission hits by the pdf twin, light sampling ignores them, so a
/// wrong twin shows in the pixels it lights. Power, uniform and BSDF-only selection have tails too heavy here for
/// per-pixel tests at these sample counts (at 2048 spp power's image put one pixel at half the 0.09 that 16k spp of
/// every sampler agree on), so they are held to the image mean. And the tree must earn its keep: on this scene (92 %
/// of the power in panels far outside the view) its per-sample variance must be far below power's and uniform's.
#[test]
fn samplers_and_estimators_agree_on_many_lights() {
    // 2048 samples: a pdf twin that leaves out the receiver's normal moves MIS's mean by 1.3 %, 6.6 standard errors
    // here (3.3 at 512).
    let mis = render(LightSampler::Bvh, Estimator::Mis, 2048, 11);
    let light = render(LightSampler::Bvh, Estimator::Light, 2048, 12);
    let bad = common::stats::beyond_noise(&light, &mis, 1e-3);
    eprintln!("bvh light sampling against bvh MIS: {bad} pixel channels beyond noise");
    assert!(
        bad <= 3,
        "bvh light sampling: {bad} pixel channels differ from MIS beyond noise"
    );
    let (mr, sr) = image_mean_and_stderr(&mis);
    let mut variances = vec![("bvh mis", summed_variance(&mis))];
    for (what, sampler, estimator, seed) in [
        ("bvh light", LightSampler::Bvh, Estimator::Light, 0),
        ("bvh bsdf", LightSampler::Bvh, Estimator::Bsdf, 13),
        ("power mis", LightSampler::Power, Estimator::Mis, 14),
        ("uniform mis", LightSampler::Uniform, Estimator::Mis, 15),
    ] {
        let film = if seed == 0 {
            light.clone()
        } else {
            render(sampler, estimator, 512, seed)
        };
        let (m, s) = image_mean_and_stderr(&film);
        let z = (m - mr) / (s * s + sr * sr).sqrt();
        eprintln!("{what}: mean {m:.5} +- {s:.5} against bvh MIS {mr:.5} +- {sr:.5} (z {z:.2})");
        assert!(
            z.abs() < 4.0,
            "{what}: mean {m} against bvh MIS's {mr}, {z:.1} standard errors"
        );
        variances.push((what, summed_variance(&film)));
    }
    eprintln!("summed per-sample variance: {variances:?}");
    let var = |name: &str| variances.iter().find(|v| v.0 == name).unwrap().1;
    assert!(
        var("bvh mis") * 3.0 < var("power mis"),
        "bvh is not well below power: {variances:?}"
    );
    assert!(
        var("bvh mis") * 2.0 < var("uniform mis"),
        "bvh is not well below uniform: {variances:?}"
    );
}

/// The lamps of tests/instances.rs with two more bulbs, three instances of a one-sided panel, and two point and two
/// spot lights: thirteen emitters for the tree, none a world triangle when instanced.
fn bulbs_and_punctual_lights() -> common::gltf_builder::GltfBuilder {
    use glam::Quat;
    use serde_json::json;
    let mut b = common::scenes::lamps();
    let glow = 2;
    b.place_last_mesh("plain 2", json!({ "translation": [-2.0, 0.4, -2.0] }));
    b.place_last_mesh("plain 3", json!({ "translation": [2.2, 2.5, 1.5] }));
    // A one-sided panel facing up in its mesh, turned over, mirrored and tilted to light the floor: its instances'
    // normal cones must follow their transforms, or the floor falls outside them.
    b.quad("panel", square(0.3, 0.0), glow, FACING_UP);
    b.transform_last_node(
        json!({ "translation": [-1.0, 2.0, 0.5], "rotation": Quat::from_rotation_x(3.1).to_array() }),
    );
    b.place_last_mesh(
        "panel mirrored",
        json!({ "translation": [0.8, 2.2, -0.5], "scale": [1.0, -1.0, 1.0] }),
    );
    b.place_last_mesh(
        "panel tilted",
        json!({ "translation": [1.8, 1.5, 1.0], "rotation": Quat::from_rotation_z(2.5).to_array() }),
    );
    let down = common::scenes::POINTING_DOWN;
    b.point_light([1.0, 0.9, 0.8], 3.0, [1.5, 1.5, 1.5]);
    b.point_light([0.6, 0.8, 1.0], 2.0, [-1.5, 0.8, 1.8]);
    let spot = json!({"type": "spot", "spot": {"innerConeAngle": 0.2, "outerConeAngle": 0.5}});
    b.punctual(spot.clone(), [1.0, 1.0, 1.0], 8.0, [-0.8, 2.5, -0.5], down);
    b.punctual(spot, [1.0, 0.5, 0.3], 6.0, [1.2, 2.0, 1.0], down);
    b
}

fn renderer_with(scene: &pathwave::scene::Scene, instancing: pathwave::scene::Instancing) -> pathwave::Renderer {
    let ctx = pathwave::vk::Context::new(&Default::default(), common::validation()).unwrap();
    let options = pathwave::RendererOptions {
        instancing,
        ..Default::default()
    };
    pathwave::Renderer::with_options(scene, ctx, options).unwrap_or_else(|e| panic!("{e}"))
}

/// Catches, through the tree: an instance's bounds or cone not holding its mesh in the world (a turned, stretched or
/// mirrored bulb, or one moving over the shutter, would lose light where importance calls it zero), a punctual
/// light's cone cut too tight (a spot's edge dark), an instance's pdf twin (the tree's pick of the instance times its
/// triangle's within the mesh) that differs from the pick. Each image must match the one with the bulb's triangles
/// placed one by one and picked by power, the path every earlier test holds.
#[test]
fn instanced_and_punctual_emitters_through_the_tree_light_as_placed_ones_do() {
    use pathwave::scene::{load, Instancing, PoseTime};
    let (dir, path) = common::write_temp(&bulbs_and_punctual_lights(), "bulbs.gltf");
    let still = load(&path, None).unwrap();
    let packed = pathwave::render::gpu_scene::try_pack_with(&still, Instancing::Always).unwrap();
    assert_eq!(
        packed.light_tree.stats.emitters, 13,
        "nine instances and four punctual lights"
    );
    let mut b = bulbs_and_punctual_lights();
    b.slide("move", 3, [0.0, 1.0], [1.3, 1.0, -0.4], [0.6, 1.4, 0.2]);
    b.animate(
        "turn",
        2,
        "rotation",
        "LINEAR",
        &[0.0, 1.0],
        &[0.0, 0.0, 0.3429, 0.93937, 0.0, 0.0, 0.9, 0.43589],
    );
    let moving_path = dir.path().join("moving-bulbs.gltf");
    b.write(&moving_path);
    let mut moving = load(&moving_path, None).unwrap();
    moving.pose_shutter(PoseTime::default(), 1.0).unwrap();
    for (what, scene, estimator) in [
        ("mis", &still, Estimator::Mis),
        ("light", &still, Estimator::Light),
        ("moving mis", &moving, Estimator::Mis),
    ] {
        let s = |light_sampler, seed| RenderSettings {
            estimator,
            light_sampler,
            ..common::settings(40, 30, 256, seed)
        };
        let flat = common::render(&mut renderer_with(scene, Instancing::Never), &s(LightSampler::Power, 6));
        let mut r = renderer_with(scene, Instancing::Always);
        assert_eq!(r.light_sampler_run(&s(LightSampler::Bvh, 7)), Some("bvh"));
        let tree = common::render(&mut r, &s(LightSampler::Bvh, 7));
        common::stats::assert_same_within_noise(what, &tree, &flat);
    }
}

/// A panel facing down over a floor, cut into 12 x 12 quads that share one emissive texture: black but for a bright
/// disc (the logo on a dark screen).
fn screen_with_a_logo() -> (common::gltf_builder::GltfBuilder, Vec<[u8; 4]>) {
    use serde_json::json;
    let n = 64usize;
    let texels: Vec<[u8; 4]> = (0..n * n)
        .map(|i| {
            let (x, y) = ((i % n) as f32 + 0.5, (i / n) as f32 + 0.5);
            let lit = (x - 20.0).powi(2) + (y - 44.0).powi(2) < 25.0;
            if lit {
                [255, 230, 200, 255]
            } else {
                [0, 0, 0, 255]
            }
        })
        .collect();
    let mut b = common::gltf_builder::GltfBuilder::new();
    let white = b.material("white", [0.7; 3], [0.0; 3], false);
    b.quad("floor", square(2.0, 0.0), white, FACING_UP);
    let screen = b.material("screen", [0.0; 3], [1.0; 3], false);
    let image = b.png_image(n as u32, n as u32, &texels);
    let texture = b.texture(image, json!({"magFilter": 9729, "minFilter": 9729}));
    b.material_json(screen)["emissiveTexture"] = json!({ "index": texture });
    b.use_extension("KHR_materials_emissive_strength");
    b.material_json(screen)["extensions"] = json!({"KHR_materials_emissive_strength": {"emissiveStrength": 8.0}});
    let k = 12;
    for i in 0..k {
        for j in 0..k {
            let (u0, u1, v0, v1) = (
                i as f32 / k as f32,
                (i + 1) as f32 / k as f32,
                j as f32 / k as f32,
                (j + 1) as f32 / k as f32,
            );
            let (x0, x1, z0, z1) = (-1.0 + 2.0 * u0, -1.0 + 2.0 * u1, -1.0 + 2.0 * v0, -1.0 + 2.0 * v1);
            // Counter-clockwise seen from below: the panel faces down.
            b.textured_quad(
                &format!("screen {i} {j}"),
                [[x0, 1.5, z0], [x1, 1.5, z0], [x1, 1.5, z1], [x0, 1.5, z1]],
                [[u0, v0], [u1, v0], [u1, v1], [u0, v1]],
                screen,
            );
        }
    }
    b.camera([0.0, 2.5, 4.0], [0.0, 0.3, 0.0], [0.0, 1.0, 0.0], 45.0);
    (b, texels)
}

/// Catches an emissive triangle's power taken from the texture's average (every screen triangle would get the same
/// power, and 95 % of light samples would land on black), from the wrong texels (a transposed or flipped lookup
/// puts the power on dark triangles) or with a summed-area table that does not add up: each emitter's power must be
/// its footprint's texels summed here by brute force. And the selection stays unbiased: power (which uses these
/// figures) and uniform selection (which does not) give the same image, power with less noise.
#[test]
fn emissive_textures_are_sampled_where_they_glow() {
    use pathwave::constants::{LIGHT_INDEX_MASK, LIGHT_KIND_SHIFT};
    let (b, texels) = screen_with_a_logo();
    let (_dir, path) = common::write_temp(&b, "screen.gltf");
    let scene = pathwave::scene::load(&path, None).unwrap();
    let packed = pack(&scene);
    let table = &packed.lights[..packed.light_count as usize];
    let srgb = |c: u8| {
        let c = c as f64 / 255.0;
        if c <= 0.04045 {
            c / 12.92
        } else {
            ((c + 0.055) / 1.055).powf(2.4)
        }
    };
    // Brute force: every emitter's footprint from its packed texture coordinates (texel centres at half-integers,
    // one texel more each way for bilinear filtering, clamped at the edges, as the panel never wraps).
    let mut lit_triangles = 0;
    for t in 0..packed.tri_verts.len() {
        let uv = packed.tri_texcoords[t];
        let us = [uv.t0[0], uv.t1[0], uv.t2[0]];
        let vs = [uv.t0[1], uv.t1[1], uv.t2[1]];
        let range = |c: [f32; 3]| {
            let lo = (c.iter().cloned().fold(f32::INFINITY, f32::min) as f64 * 64.0 - 0.5).floor() as i64;
            let hi = (c.iter().cloned().fold(f32::NEG_INFINITY, f32::max) as f64 * 64.0 - 0.5).floor() as i64 + 1;
            (lo.clamp(0, 63) as usize, hi.clamp(0, 63) as usize)
        };
        let ((x0, x1), (y0, y1)) = (range(us), range(vs));
        let mut sum = 0.0;
        for y in y0..=y1 {
            for x in x0..=x1 {
                let p = texels[y * 64 + x];
                sum += (srgb(p[0]) + srgb(p[1]) + srgb(p[2])) / 3.0;
            }
        }
        let mean = 8.0 * sum / ((x1 - x0 + 1) * (y1 - y0 + 1)) as f64;
        let area = packed.tri_shading[t].n1[3] as f64;
        let want = mean * area * std::f64::consts::PI;
        let entry = table
            .iter()
            .find(|l| l.id >> LIGHT_KIND_SHIFT == 0 && (l.id & LIGHT_INDEX_MASK) as usize == t);
        match entry {
            None => assert!(
                want == 0.0 || packed.tri_verts[t].v0[1] == 0.0,
                "triangle {t} emits {want} W but is no light"
            ),
            Some(_) => lit_triangles += 1,
        }
        if let Some(l) = entry {
            let got = l.prob as f64 * packed.total_light_power;
            assert!(
                (got - want).abs() <= 1e-3 * want,
                "triangle {t}: {got} W against {want} W by brute force"
            );
        }
    }
    eprintln!("{lit_triangles} of 288 screen triangles can emit");
    // By the texture's average every screen triangle would carry 1/288 of the screen's picks, 6 % of them on the
    // triangles that glow; by footprint all of them are, at least 10x as many.
    assert!(
        lit_triangles > 0 && lit_triangles * 10 <= 288,
        "{lit_triangles} lit triangles"
    );
    let mut r = common::scene_renderer(&scene);
    let s = |light_sampler, seed| RenderSettings {
        light_sampler,
        ..common::settings(32, 24, 256, seed)
    };
    let power = common::render(&mut r, &s(LightSampler::Power, 3));
    let uniform = common::render(&mut r, &s(LightSampler::Uniform, 4));
    let bad = common::stats::beyond_noise(&power, &uniform, 1e-3);
    let ((mp, sp), (mu, su)) = (image_mean_and_stderr(&power), image_mean_and_stderr(&uniform));
    let z = (mp - mu) / (sp * sp + su * su).sqrt();
    let (vp, vu) = (summed_variance(&power), summed_variance(&uniform));
    eprintln!("power {mp:.5} +- {sp:.5}, uniform {mu:.5} +- {su:.5} (z {z:.2}), {bad} beyond noise; variance {vp:.3} against {vu:.3}");
    assert!(
        bad <= 3 && z.abs() < 4.0,
        "power and uniform selection disagree: z {z:.2}, {bad} pixel channels"
    );
    // Among the glowing triangles, power still favours the logo's centre over its rim.
    assert!(
        vp < vu,
        "per-sample variance {vp} by footprint power is not below uniform's {vu}"
    );
}

/// Catches, in an instanced mesh's light subtree (stored once, entered with the shading point taken into the mesh's
/// space): a pick whose probability is not its pdf twin's (the instance's pick times its triangle's within the
/// subtree), picks not distributed as that pmf (chi-square), a pmf that does not sum to one over every emitter of
/// every instance, and a point or normal taken into the mesh's space wrongly (a turned, stretched or mirrored bulb
/// would then favour its triangles facing away from the point, where a power pick gives them half the picks).
#[test]
fn instanced_meshes_subtrees_pick_as_their_pdf_twin_says() {
    use pathwave::constants::{LIGHT_INDEX_MASK, LIGHT_KIND_INSTANCE};
    use pathwave::scene::{load, Instancing};
    use std::collections::HashMap;
    let (_dir, path) = common::write_temp(&bulbs_and_punctual_lights(), "bulbs.gltf");
    let scene = load(&path, None).unwrap();
    let packed = pathwave::render::gpu_scene::try_pack_with(&scene, Instancing::Always).unwrap();
    let tree = &packed.light_tree;
    assert!(
        tree.stats.instanced > 100,
        "{} emitters in subtrees",
        tree.stats.instanced
    );
    // Every emitter: (entry, sub-entry or LIGHT_NONE), and for an instanced triangle its front's normal and a
    // point on it in the world.
    type Placed = Option<(glam::Vec3, glam::Vec3)>;
    let mut pairs: Vec<(u32, u32, Placed)> = Vec::new();
    for j in 0..packed.light_count {
        let id = packed.lights[j as usize].id;
        if id >> LIGHT_KIND_SHIFT != LIGHT_KIND_INSTANCE {
            pairs.push((j, LIGHT_NONE, None));
            continue;
        }
        let inst = &packed.instances[(id & LIGHT_INDEX_MASK) as usize];
        assert_ne!(inst.light[3], 0, "instance entry {j} has no subtree");
        let rows = [inst.world0, inst.world1, inst.world2].map(glam::Vec4::from);
        let to_world = |v: glam::Vec3| {
            glam::Vec3::new(
                rows[0].dot(v.extend(1.0)),
                rows[1].dot(v.extend(1.0)),
                rows[2].dot(v.extend(1.0)),
            )
        };
        for e in inst.light[0]..inst.light[0] + inst.light[1] {
            let t = &packed.tri_verts[(packed.lights[e as usize].id & LIGHT_INDEX_MASK) as usize];
            let v0 = glam::Vec3::from_slice(&t.v0[..3]);
            let (a, b, c) = (
                to_world(v0),
                to_world(v0 + glam::Vec3::from_slice(&t.e1[..3])),
                to_world(v0 + glam::Vec3::from_slice(&t.e2[..3])),
            );
            let mirrored = if inst.info[1] != 0 { -1.0 } else { 1.0 };
            let normal = (b - a).cross(c - a).normalize_or_zero() * mirrored;
            pairs.push((j, e, Some(((a + b + c) / 3.0, normal))));
        }
    }
    let points = [
        ([0.0, 0.0, 0.0], [0.0, 1.0, 0.0]),
        ([-1.2, 0.0, 1.1], [0.0, 1.0, 0.0]),
        ([1.0, 0.5, -1.0], [0.0, 0.0, 0.0]),
        ([0.3, 1.2, 0.4], [0.6, 0.0, 0.8]),
    ];
    let picks = 40_000;
    let mut r = renderer_with(&scene, Instancing::Always);
    let mut s = 7;
    for (p, n) in points {
        let mut records: Vec<LightSelectRecord> = (pairs.iter())
            .map(|&(entry, sub_entry, _)| LightSelectRecord {
                p,
                n,
                entry,
                sub_entry,
                ..Default::default()
            })
            .collect();
        records.extend((0..picks).map(|_| LightSelectRecord {
            p,
            n,
            entry: 0,
            sub_entry: LIGHT_NONE,
            u: lcg(&mut s),
            v: lcg(&mut s),
            ..Default::default()
        }));
        let out = r.probe_light_select(&records, LightSampler::Bvh).unwrap();
        let (twin, picked) = out.split_at(pairs.len());
        let pmf: HashMap<(u32, u32), f64> = twin.iter().map(|d| ((d.entry, d.sub_entry), d.pmf as f64)).collect();
        let total: f64 = pmf.values().sum();
        assert!(total <= 1.0 + 1e-4, "at {p:?}: the pmf sums to {total}");
        let mut counts: HashMap<(u32, u32), u64> = HashMap::new();
        for d in picked {
            let key = (d.picked, d.sub_picked);
            if key != (LIGHT_NONE, LIGHT_NONE) {
                let want = *pmf.get(&key).unwrap_or_else(|| panic!("pick {key:?} is no emitter"));
                assert!(
                    (d.prob as f64 - want).abs() <= 1e-5 * want,
                    "pick {key:?} at {p:?} with probability {}, its pdf twin says {want}",
                    d.prob
                );
            }
            *counts.entry(key).or_default() += 1;
        }
        // A descent that reaches a node whose children both have no importance picks nothing (the bound is loose
        // near a curved mesh's silhouette): exactly the mass the pmf is short of one, a cell of its own.
        let mut pmf = pmf;
        pmf.insert((LIGHT_NONE, LIGHT_NONE), (1.0 - total).max(0.0));
        // Chi-square over emitters expected at least 5 times, the rest pooled; 5 sigma of the statistic's spread.
        let (mut chi2, mut cells, mut pooled_n, mut pooled_e) = (0.0, 0usize, 0.0, 0.0);
        for (key, &q) in &pmf {
            let (o, e) = (*counts.get(key).unwrap_or(&0) as f64, q * picks as f64);
            if e >= 5.0 {
                chi2 += (o - e) * (o - e) / e;
                cells += 1;
            } else {
                pooled_n += o;
                pooled_e += e;
            }
        }
        if pooled_e > 0.0 {
            chi2 += (pooled_n - pooled_e) * (pooled_n - pooled_e) / pooled_e;
            cells += 1;
        }
        let dof = (cells - 1) as f64;
        // The share of picks on instanced triangles whose emitting face turns away from p (none of its light can
        // reach p): a power pick within the mesh gives them half of each bulb's picks.
        let p = glam::Vec3::from(p);
        let (mut away, mut instanced) = (0.0, 0.0);
        for &(entry, sub, placed) in &pairs {
            let Some((c, normal)) = placed else {
                continue;
            };
            let q = pmf[&(entry, sub)];
            instanced += q;
            if normal.dot(p - c) < -0.2 * (p - c).length() {
                away += q;
            }
        }
        eprintln!(
            "at {p}: chi-square {chi2:.1} over {dof} degrees of freedom; {:.4} of the instanced picks face away, {:.4} pick nothing",
            away / instanced,
            1.0 - total
        );
        assert!(
            chi2 < dof + 5.0 * (2.0 * dof).sqrt(),
            "at {p}: chi-square {chi2} over {dof} degrees of freedom"
        );
        assert!(
            away < 0.05 * instanced,
            "at {p}: {away} of {instanced} on triangles facing away"
        );
    }
}

/// The form factor from a point to a parallel rectangle at height 1 with one corner straight above it and sides x
/// and y (in units of the height; signed, the formula is odd in each): the irradiance it gives over pi times its
/// radiance (Siegel and Howell, "Thermal Radiation Heat Transfer", configuration factor C-11).
fn corner_rectangle_form_factor(x: f64, y: f64) -> f64 {
    let (sx, sy) = ((1.0 + x * x).sqrt(), (1.0 + y * y).sqrt());
    (x / sx * (y / sx).atan() + y / sy * (x / sy).atan()) / (2.0 * std::f64::consts::PI)
}

/// Catches a shadow ray that overshoots the light it aims at. A floor at y = 6 (where the ray offset, 256 ulps of
/// the coordinate, is 1.2e-4) lit by a parallel square emitter half a metre above it, seen straight down: every
/// sampler and estimator must give the analytic irradiance. When the shadow ray left from the offset point but
/// measured its length from the unoffset one, it ended 1.2e-4 further up, beyond the emitter, which then shadowed
/// itself: power and uniform selection lost all of light sampling's share (facades facing each other across the city
/// block's street lost up to 6 %).
#[test]
fn shadow_rays_end_at_the_light_they_aim_at() {
    const Y0: f32 = 6.0;
    const H: f64 = 0.5;
    const ALBEDO: f64 = 0.5;
    let mut b = common::gltf_builder::GltfBuilder::new();
    let floor = b.material("floor", [ALBEDO as f32; 3], [0.0; 3], false);
    let lamp = b.material("lamp", [0.0; 3], [1.0; 3], false);
    let y1 = Y0 + H as f32;
    b.quad("floor", square(4.0, Y0), floor, FACING_UP);
    b.quad("lamp", square(1.0, y1), lamp, FACING_DOWN);
    // Between the two, looking down at a 0.2 m patch of the floor under the lamp's centre.
    b.orthographic_camera([0.0, Y0 + 0.25, 0.0], [0.0, Y0, 0.0], [0.0, 0.0, -1.0], 0.1, 0.1);
    let (_dir, path) = common::write_temp(&b, "facing.gltf");
    let scene = pathwave::scene::load(&path, None).unwrap();
    let mut r = common::scene_renderer(&scene);
    // The patch's mean radiance: albedo times the form factor, on a 16 x 16 grid over the patch (it varies by 0.2 %).
    let n = 16;
    let expected = (0..n * n)
        .map(|k| {
            let (x, z) = (
                -0.1 + 0.2 * ((k % n) as f64 + 0.5) / n as f64,
                -0.1 + 0.2 * ((k / n) as f64 + 0.5) / n as f64,
            );
            let (x0, x1, z0, z1) = ((-1.0 - x) / H, (1.0 - x) / H, (-1.0 - z) / H, (1.0 - z) / H);
            ALBEDO
                * (corner_rectangle_form_factor(x1, z1)
                    - corner_rectangle_form_factor(x0, z1)
                    - corner_rectangle_form_factor(x1, z0)
                    + corner_rectangle_form_factor(x0, z0))
        })
        .sum::<f64>()
        / (n * n) as f64;
    for (k, (sampler, estimator)) in [
        (LightSampler::Bvh, Estimator::Mis),
        (LightSampler::Power, Estimator::Mis),
        (LightSampler::Uniform, Estimator::Mis),
        (LightSampler::Power, Estimator::Light),
    ]
    .into_iter()
    .enumerate()
    {
        let s = RenderSettings {
            light_sampler: sampler,
            estimator,
            ..common::settings(16, 16, 256, 40 + k as u32)
        };
        let film = common::render(&mut r, &s);
        let (m, se) = image_mean_and_stderr(&film);
        let z = (m - expected) / se;
        eprintln!("{sampler:?} {estimator:?}: {m:.5} +- {se:.5}, analytic {expected:.5} (z {z:.2})");
        // The bound is 4 standard errors and half a percent: the patch's mean is integrated to well under that.
        assert!(
            z.abs() < 4.0 || (m / expected - 1.0).abs() < 0.005,
            "{sampler:?} {estimator:?}: {m} against the analytic {expected}, {z:.1} standard errors"
        );
    }
}
