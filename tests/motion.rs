//! Motion blur against analytic images: an emissive quad seen straight on, with `max_depth` 0 (emission only), so a
//! pixel's value is the fraction of its area and of the shutter time the quad covers it. Moved by its node, by a
//! skin, by the camera and by a rotation; computed here by integrating that coverage, and compared pixel by pixel
//! within statistical bounds. Also: the BVH of a moving scene against brute force at several times, both schedules
//! the same bytes, and a shutter of 0 costing nothing.
mod common;

use common::gltf_builder::{upright, GltfBuilder, FACING_Z};
use glam::{Quat, Vec2, Vec3};
use pathwave::scene::{load, PoseTime};
use serde_json::json;
use std::path::Path;

const W: u32 = 48;
const H: u32 = 16;
const SPP: u32 = 256;
/// The camera on +z at this distance looks at the plane z = 0 with this vertical field of view.
const DISTANCE: f32 = 2.0;
const YFOV_DEG: f32 = 30.0;

/// Half the plane's extent the image sees, (x, y).
fn half_extent() -> Vec2 {
    let h = DISTANCE * (YFOV_DEG.to_radians() * 0.5).tan();
    Vec2::new(h * W as f32 / H as f32, h)
}

/// Pixel (px, py)'s footprint on z = 0 (lo, hi): a pinhole's image of a plane facing it is affine.
fn footprint(px: u32, py: u32) -> (Vec2, Vec2) {
    let e = half_extent();
    let x0 = -e.x + 2.0 * e.x * px as f32 / W as f32;
    let x1 = -e.x + 2.0 * e.x * (px + 1) as f32 / W as f32;
    let y1 = e.y - 2.0 * e.y * py as f32 / H as f32;
    let y0 = e.y - 2.0 * e.y * (py + 1) as f32 / H as f32;
    (Vec2::new(x0, y0), Vec2::new(x1, y1))
}

/// A black quad of half size `half` about the origin emitting `emission` (material `name`) on its own node (node 1)
/// facing +z, and the camera (node 2) on +z; node 0 is nothing but a root the tests may use.
fn quad_in_view(half: Vec2, name: &str, emission: [f32; 3]) -> GltfBuilder {
    let mut b = GltfBuilder::new();
    b.node("root", json!({}));
    let m = b.material(name, [0.0; 3], emission, false);
    b.quad("quad", upright([-half.x, half.x], [-half.y, half.y], 0.0), m, FACING_Z);
    b.camera([0.0, 0.0, DISTANCE], [0.0, 0.0, 0.0], [0.0, 1.0, 0.0], YFOV_DEG);
    b
}

/// A unit-radiance quad of half size `half` in `quad_in_view`.
fn emitter(half: Vec2) -> GltfBuilder {
    quad_in_view(half, "light", [1.0; 3])
}

/// The image rendered with the shutter open over [0, 1] s.
fn render_blurred(path: &Path) -> Vec<f32> {
    let mut scene = load(path, None).unwrap_or_else(|e| panic!("{e}"));
    scene.pose_shutter(PoseTime::default(), 1.0).unwrap();
    assert!(scene.motion.is_some(), "the scene should move over the shutter");
    let mut r = common::scene_renderer(&scene);
    let settings = pathwave::RenderSettings {
        max_depth: Some(0),
        ..common::settings(W, H, SPP, 7)
    };
    common::render(&mut r, &settings).mean().iter().map(|p| p[1]).collect()
}

/// Each pixel's expected value: the mean over the pixel's footprint and the shutter of `covered(point, time)`,
/// by the midpoint rule on a fine grid (its error is far below the statistical bounds).
fn expected(covered: impl Fn(Vec2, f32) -> bool) -> Vec<f32> {
    let (n, steps) = (12, 48);
    let mut out = Vec::with_capacity((W * H) as usize);
    for py in 0..H {
        for px in 0..W {
            let (lo, hi) = footprint(px, py);
            let mut hits = 0u32;
            for s in 0..steps {
                let t = (s as f32 + 0.5) / steps as f32;
                for i in 0..n {
                    for j in 0..n {
                        let f = Vec2::new((i as f32 + 0.5) / n as f32, (j as f32 + 0.5) / n as f32);
                        hits += covered(lo + (hi - lo) * f, t) as u32;
                    }
                }
            }
            out.push(hits as f32 / (n * n * steps) as f32);
        }
    }
    out
}

/// Per pixel within five standard deviations of a mean of SPP independent coverage samples (the renderer's are
/// stratified, so its error is smaller still), plus the grid's error; and the mean error over the image within 0.01,
/// which a shutter too short or too long, or a blur in the wrong direction, exceeds many times over.
fn assert_matches(what: &str, got: &[f32], want: &[f32]) {
    let mut total = 0.0;
    let mut blurred = 0;
    for (i, (&g, &p)) in got.iter().zip(want).enumerate() {
        let sigma = (p * (1.0 - p) / SPP as f32).sqrt();
        let bound = 5.0 * sigma + 0.02;
        assert!(
            (g - p).abs() <= bound,
            "{what}: pixel ({}, {}) is {g}, expected {p} within {bound}",
            i as u32 % W,
            i as u32 / W
        );
        total += (g - p).abs();
        blurred += (p > 0.05 && p < 0.95) as u32;
    }
    let mean = total / got.len() as f32;
    eprintln!("{what}: mean error {mean}, {blurred} pixels partly covered");
    assert!(mean < 0.01, "{what}: mean error {mean}");
    // The test means something only if the blur covers many pixels partly.
    assert!(blurred >= 40, "{what}: only {blurred} pixels are partly covered");
}

/// Writes `b` as `name`, renders it with `render` and checks the image against the coverage of `covered` (`what`
/// names the case).
fn assert_blur(
    what: &str,
    b: &GltfBuilder,
    name: &str,
    render: fn(&Path) -> Vec<f32>,
    covered: impl Fn(Vec2, f32) -> bool,
) {
    let (_dir, path) = common::write_temp(b, name);
    assert_matches(what, &render(&path), &expected(covered));
}

const HALF: Vec2 = Vec2::new(0.25, 0.25);
const START_X: f32 = -0.6;
const TRAVEL: f32 = 0.8;

/// Moves node 1 (the quad) by TRAVEL along x over [0, 1] s, from START_X.
fn slide(b: &mut GltfBuilder) {
    b.slide("move", 1, [0.0, 1.0], [START_X, 0.0, 0.0], [START_X + TRAVEL, 0.0, 0.0]);
}

/// The rotation tests' quad: its half size, and how far node 1 turns it about z over [0, 1] s.
const SPIN_HALF: Vec2 = Vec2::new(0.45, 0.08);
const SPIN_DEGREES: f32 = 40.0;

fn spin(b: &mut GltfBuilder) {
    let keys: Vec<f32> = [0.0, SPIN_DEGREES.to_radians()]
        .iter()
        .flat_map(|&a| Quat::from_rotation_z(a).to_array())
        .collect();
    b.animate("spin", 1, "rotation", "LINEAR", &[0.0, 1.0], &keys);
}

fn inside_spinning_quad(p: Vec2, t: f32) -> bool {
    // Back into the quad's frame at time t.
    let q = glam::Mat2::from_angle(-SPIN_DEGREES.to_radians() * t) * p;
    q.abs().cmple(SPIN_HALF).all()
}

fn inside_moving_quad(p: Vec2, t: f32) -> bool {
    let c = Vec2::new(START_X + TRAVEL * t, 0.0);
    (p - c).abs().cmple(HALF).all()
}

/// Catches: no blur, a blur of the wrong length or direction, times not uniform over the shutter, the BVH not
/// holding the moving quad's path (pixels it crosses would stay black).
#[test]
fn a_node_moving_linearly_blurs_into_its_time_averaged_coverage() {
    let mut b = emitter(HALF);
    slide(&mut b);
    assert_blur(
        "node translation",
        &b,
        "moving.gltf",
        render_blurred,
        inside_moving_quad,
    );
}

/// Catches: the camera's keys ignored (a sharp quad), or applied in the wrong direction (the camera moving left
/// moves the image of a still quad right).
#[test]
fn a_moving_camera_blurs_a_still_quad_the_other_way() {
    let mut b = emitter(HALF);
    // The quad sits where the moving one starts; the camera slides left, so the quad slides right in the image,
    // just as the node moved it in the test above.
    b.transform_node(1, json!({ "translation": [START_X, 0.0, 0.0] }));
    b.slide("dolly", 2, [0.0, 1.0], [0.0, 0.0, DISTANCE], [-TRAVEL, 0.0, DISTANCE]);
    assert_blur(
        "camera translation",
        &b,
        "dolly.gltf",
        render_blurred,
        inside_moving_quad,
    );
}

/// Catches: skinned vertices taken at one time only, or their keys not reaching the device.
#[test]
fn a_skinned_quad_moved_by_its_two_bones_blurs_the_same_way() {
    let mut b = emitter(HALF);
    let quad = 1;
    let bone0 = b.node("bone 0", json!({ "translation": [0.0, 0.0, 0.0] }));
    let bone1 = b.node("bone 1", json!({ "translation": [0.0, 0.0, 0.0] }));
    // Corners 0 and 1 follow bone 0, 2 and 3 half each: both bones move the same, so the quad moves rigidly; the
    // skinned node's own transform (far away) must be ignored.
    let joints = [[0, 0, 0, 0], [0, 0, 0, 0], [0, 1, 0, 0], [0, 1, 0, 0]];
    let weights = [
        [1.0, 0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0, 0.0],
        [0.5, 0.5, 0.0, 0.0],
        [0.5, 0.5, 0.0, 0.0],
    ];
    let identity = glam::Mat4::IDENTITY.to_cols_array();
    b.skin_last_mesh(&[bone0, bone1], &[identity, identity], &joints, &weights);
    b.transform_node(quad, json!({ "translation": [50.0, 0.0, 0.0] }));
    for bone in [bone0, bone1] {
        b.slide(
            "walk",
            bone,
            [0.0, 1.0],
            [START_X, 0.0, 0.0],
            [START_X + TRAVEL, 0.0, 0.0],
        );
    }
    assert_blur(
        "skinned translation",
        &b,
        "skinned.gltf",
        render_blurred,
        inside_moving_quad,
    );
}

/// Catches: rotations interpolated through the wrong keys or shrunk (the shutter is cut into segments, and the
/// vertices between keys must stay on the quad's path to within the bound).
#[test]
fn a_rotating_quad_blurs_into_its_swept_coverage() {
    let mut b = emitter(SPIN_HALF);
    spin(&mut b);
    assert_blur("rotation", &b, "spin.gltf", render_blurred, inside_spinning_quad);
}

/// `emitter`'s scene with a black quad (node 1) against a white environment, so a pixel's value is one less the
/// coverage, and the quad's mesh placed again far outside the view (node 3): two instances, which the renderer may
/// keep in object space under the two-level BVH, moving by their transforms.
fn occluder(half: Vec2) -> GltfBuilder {
    let mut b = quad_in_view(half, "black", [0.0; 3]);
    b.place_last_mesh("far copy", json!({ "translation": [0.0, 10.0, 0.0] }));
    b
}

/// One less the image `occluder`'s scene renders with the shutter open over [0, 1] s, its quad instanced.
fn render_blurred_instanced(path: &Path) -> Vec<f32> {
    use pathwave::scene::Instancing;
    let mut scene = load(path, None).unwrap_or_else(|e| panic!("{e}"));
    scene.pose_shutter(PoseTime::default(), 1.0).unwrap();
    scene.environment = Some(pathwave::scene::Environment::constant([1.0; 3]));
    let packed = pathwave::render::gpu_scene::try_pack_with(&scene, Instancing::Always).unwrap();
    let moving_records = 1 + 2 + pathwave::constants::MOTION_SEGMENTS as usize + 1;
    assert_eq!(
        packed.instances.len(),
        moving_records,
        "the header, two instances, one moving"
    );
    assert_eq!(packed.tri_verts.len(), 2, "the quad is stored once, in object space");
    let ctx = pathwave::vk::Context::new(&Default::default(), common::validation()).unwrap();
    let options = pathwave::RendererOptions {
        instancing: Instancing::Always,
        ..Default::default()
    };
    let mut r = pathwave::Renderer::with_options(&scene, ctx, options).unwrap_or_else(|e| panic!("{e}"));
    let settings = pathwave::RenderSettings {
        max_depth: Some(0),
        ..common::settings(W, H, SPP, 7)
    };
    common::render(&mut r, &settings)
        .mean()
        .iter()
        .map(|p| 1.0 - p[1])
        .collect()
}

/// Catches: a moving instance placed by one key only (no blur), its transform interpolated to the wrong time or its
/// inverse not the interpolated map's (the quad would be found where it is not), TLAS boxes not holding the motion.
#[test]
fn an_instance_moving_linearly_blurs_into_its_time_averaged_coverage() {
    let mut b = occluder(HALF);
    slide(&mut b);
    assert_blur(
        "instance translation",
        &b,
        "moving-instance.gltf",
        render_blurred_instanced,
        inside_moving_quad,
    );
}

/// Catches: a rotating instance's rays moved by a rotation other than the one its keys interpolate to.
#[test]
fn a_rotating_instance_blurs_into_its_swept_coverage() {
    let mut b = occluder(SPIN_HALF);
    spin(&mut b);
    assert_blur(
        "instance rotation",
        &b,
        "spinning-instance.gltf",
        render_blurred_instanced,
        inside_spinning_quad,
    );
}

fn moving_scene() -> (tempfile::TempDir, std::path::PathBuf) {
    let mut b = emitter(HALF);
    slide(&mut b);
    b.animate(
        "spin",
        1,
        "rotation",
        "LINEAR",
        &[0.0, 1.0],
        &[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.5f32.sin(), 0.5f32.cos()],
    );
    common::write_temp(&b, "moving.gltf")
}

/// A renderer of `scene` under instancing `rule`.
fn renderer_with(scene: &pathwave::scene::Scene, rule: pathwave::scene::Instancing) -> pathwave::Renderer {
    let ctx = pathwave::vk::Context::new(&Default::default(), common::validation()).unwrap();
    let options = pathwave::RendererOptions {
        instancing: rule,
        ..Default::default()
    };
    pathwave::Renderer::with_options(scene, ctx, options).unwrap_or_else(|e| panic!("{e}"))
}

/// Catches: the BVH's boxes not holding a triangle at every time of the shutter, or the device interpolating
/// the keys differently from the host. The quad slides and turns: flattened (`Instancing::Never`) its vertices move
/// linearly between keys, which is the reference there; by default it is an instance turned by slerp, and the
/// reference is the animation posed at each time itself.
#[test]
fn moving_triangles_are_found_where_brute_force_finds_them_at_every_time() {
    use pathwave::scene::Instancing;
    let (_dir, path) = moving_scene();
    let mut scene = load(&path, None).unwrap();
    scene.pose_shutter(PoseTime::default(), 1.0).unwrap();
    let mut rng = common::rng::Rng(11);
    let rays: Vec<pathwave::bvh::Ray> = (0..2000)
        .map(|_| {
            let target = Vec3::new(rng.next() * 2.4 - 1.2, rng.next() * 0.8 - 0.4, 0.0);
            let origin = Vec3::new(rng.next() - 0.5, rng.next() - 0.5, 1.5);
            common::ray_towards(origin, target)
        })
        .collect();
    let segments = pathwave::constants::MOTION_SEGMENTS as f32;
    for rule in [Instancing::Never, Instancing::Auto] {
        let instanced = pathwave::render::gpu_scene::try_pack_with(&scene, rule)
            .unwrap()
            .features()
            & pathwave::constants::FEATURE_INSTANCES
            != 0;
        assert_eq!(
            instanced,
            rule == Instancing::Auto,
            "a turning mesh is instanced unless told not to be"
        );
        let mut r = renderer_with(&scene, rule);
        for time in [0.0, 0.1, 0.25, 0.6, 0.999] {
            let at = match rule {
                Instancing::Never => common::posed_tri_verts(&scene, time * segments),
                _ => common::exact_tri_verts(&scene, time),
            };
            let hits = r.probe_trace_at(&rays, false, time).unwrap();
            let mut found = 0;
            for (ray, hit) in rays.iter().zip(&hits) {
                let want = pathwave::bvh::brute_force(&at, ray);
                let want = (want.tri != pathwave::constants::NO_HIT).then_some(want.t);
                assert_eq!(
                    hit.tri != pathwave::constants::NO_HIT,
                    want.is_some(),
                    "{rule:?}, time {time}, ray {ray:?}"
                );
                if let (Some(t), true) = (want, hit.tri != pathwave::constants::NO_HIT) {
                    assert!(
                        (hit.t - t).abs() < 1e-4 * t.max(1.0),
                        "{rule:?}, time {time}: t {} against {t}",
                        hit.t
                    );
                    found += 1;
                }
            }
            assert!(found > 200, "{rule:?}, time {time}: only {found} rays hit the quad");
        }
    }
}

/// The bar of the turn tests: its half size, and the angle it starts at (a diagonal, so that the boxes of its
/// places at the keys, a quarter turn or less apart, do not hold its arc: its ends reach past them on the axes).
const BAR_HALF: Vec2 = Vec2::new(0.45, 0.08);
const BAR_START_DEGREES: f32 = 45.0;

/// `emitter`'s scene with the bar turning `degrees` about z over [0, 1] s, by keys a quarter turn apart at most.
fn turning_bar(degrees: f32) -> GltfBuilder {
    let mut b = emitter(BAR_HALF);
    let quarters = (degrees / 90.0).ceil().max(1.0) as usize;
    let times: Vec<f32> = (0..=quarters).map(|k| k as f32 / quarters as f32).collect();
    let keys: Vec<f32> = (times.iter())
        .flat_map(|&t| Quat::from_rotation_z((BAR_START_DEGREES + degrees * t).to_radians()).to_array())
        .collect();
    b.animate("turn", 1, "rotation", "LINEAR", &times, &keys);
    b
}

/// Where the turning bar is at time t: the point p of the plane z = 0 in the bar's own frame.
fn in_bar_frame(p: Vec2, t: f32, degrees: f32) -> Vec2 {
    glam::Mat2::from_angle(-(BAR_START_DEGREES + degrees * t).to_radians()) * p
}

/// Catches: turns interpolated linearly between the shutter's keys (a bar turning a quarter turn between keys
/// shrinks to 71 % of its length half way, and the images of the half and whole turns lose whole rings of their
/// swept discs: 9 % and 34 % less coverage than exact, measured; a quarter turn loses 1.6 % here, below this
/// test's noise, 2.5 % in the measurement), slerp taking the long way round, or a turning mesh left to move
/// its flattened vertices on straight lines.
#[test]
fn a_bar_turning_a_quarter_half_and_whole_turn_blurs_into_its_swept_coverage() {
    for degrees in [90.0f32, 180.0, 360.0] {
        let (_dir, path) = common::write_temp(&turning_bar(degrees), "bar.gltf");
        let covered = |p: Vec2, t: f32| in_bar_frame(p, t, degrees).abs().cmple(BAR_HALF).all();
        let (got, want) = (render_blurred(&path), expected(covered));
        let mean = |v: &[f32]| v.iter().sum::<f32>() / v.len() as f32;
        // The bar's total coverage: the image mean, whose standard error is at most the binomial one of its
        // pixels (the stratified sampler only lowers it). Linear keys lose 9 % of it at half a turn.
        let sigma = (want.iter().map(|p| p * (1.0 - p)).sum::<f32>() / SPP as f32).sqrt() / want.len() as f32;
        eprintln!(
            "{degrees} degrees: mean {} against {} (sigma {sigma})",
            mean(&got),
            mean(&want)
        );
        assert!(
            (mean(&got) - mean(&want)).abs() < 4.0 * sigma,
            "a bar turning {degrees} degrees covers {} of the image on average, expected {} within {}",
            mean(&got),
            mean(&want),
            4.0 * sigma
        );
        assert_matches(&format!("a bar turning {degrees} degrees"), &got, &want);
    }
}

/// Catches: a turning instance's TLAS box holding its places at the keys but not its arc between them (rays at the
/// bar's ends half way between keys would miss), the CPU twin or the device turning it another way than the
/// animation does (rays just past its ends or sides would hit, or rays at it miss).
#[test]
fn a_turning_bar_is_found_all_along_its_arc() {
    use pathwave::constants::NO_HIT;
    let degrees = 360.0;
    let (_dir, path) = common::write_temp(&turning_bar(degrees), "bar.gltf");
    let mut scene = load(&path, None).unwrap();
    scene.pose_shutter(PoseTime::default(), 1.0).unwrap();
    let packed = pathwave::render::gpu_scene::try_pack_with(&scene, pathwave::scene::Instancing::Auto).unwrap();
    assert_ne!(
        packed.features() & pathwave::constants::FEATURE_INSTANCES,
        0,
        "the bar is an instance"
    );
    let mut device = common::scene_renderer(&scene);
    let origin = Vec3::new(0.0, 0.0, DISTANCE);
    let mut rng = common::rng::Rng(5);
    let mut at_ends = 0;
    for step in 0..64 {
        let time = (step as f32 + rng.next()) / 64.0;
        // Points in the bar's frame: inside it (ends and middle), and just past its ends and sides.
        let mut targets = Vec::new();
        for _ in 0..48 {
            let inside = Vec2::new(rng.next() * 1.96 - 0.98, rng.next() * 1.96 - 0.98) * BAR_HALF;
            targets.push((inside, true));
            let end = Vec2::new(if rng.next() < 0.5 { -0.97 } else { 0.97 }, rng.next() * 1.9 - 0.95) * BAR_HALF;
            targets.push((end, true));
            targets.push((Vec2::new(end.x.signum() * (BAR_HALF.x + 0.01), end.y), false));
            targets.push((Vec2::new(inside.x, inside.y.signum() * (BAR_HALF.y + 0.01)), false));
        }
        let turn = glam::Mat2::from_angle((BAR_START_DEGREES + degrees * time).to_radians());
        let rays: Vec<pathwave::bvh::Ray> = (targets.iter())
            .map(|(p, _)| {
                let q = (turn * *p).extend(0.0);
                common::ray_towards(origin, q)
            })
            .collect();
        let gpu = device.probe_trace_at(&rays, false, time).unwrap();
        for ((ray, (p, hits)), g) in rays.iter().zip(&targets).zip(&gpu) {
            let cpu = pathwave::bvh::trace_two_level(
                &packed.bvh.nodes,
                &packed.tri_verts,
                &packed.instances,
                ray,
                false,
                time,
            );
            let distance = ((turn * *p).extend(0.0) - origin).length();
            for (who, got) in [("cpu twin", cpu), ("device", *g)] {
                assert_eq!(got.tri != NO_HIT, *hits, "{who} at time {time}, bar point {p}");
                if *hits {
                    assert!(
                        (got.t - distance).abs() < 1e-4,
                        "{who} at {time}: t {} against {distance}",
                        got.t
                    );
                }
            }
            at_ends += (*hits && p.x.abs() > 0.9 * BAR_HALF.x) as u32;
        }
    }
    assert!(at_ends > 2000, "only {at_ends} rays at the bar's ends");
}

/// Catches: the wavefront and fused schedules giving moving scenes different times (their bytes would differ).
#[test]
fn both_schedules_give_the_same_bytes_on_a_moving_scene() {
    let (_dir, path) = moving_scene();
    let mut scene = load(&path, None).unwrap();
    scene.pose_shutter(PoseTime::default(), 1.0).unwrap();
    let mut r = common::scene_renderer(&scene);
    let s = common::settings(W, H, 16, 3);
    r.set_schedule(pathwave::Schedule::Wavefront);
    let a = common::render(&mut r, &s);
    r.set_schedule(pathwave::Schedule::Fused);
    let b = common::render(&mut r, &s);
    assert!(
        a.sum == b.sum && a.sum_sq == b.sum_sq,
        "the schedules differ on a moving scene"
    );
}

/// Catches: a shutter of 0, or a shutter over which nothing moves, turning the motion code on.
#[test]
fn no_motion_costs_nothing() {
    let (_dir, path) = moving_scene();
    let mut scene = load(&path, None).unwrap();
    scene.pose_shutter(PoseTime::default(), 0.0).unwrap();
    assert!(scene.motion.is_none());
    let features = pathwave::render::gpu_scene::pack(&scene).features();
    assert_eq!(features & pathwave::constants::FEATURE_MOTION, 0);
    // After the animation's end nothing moves, whatever the shutter.
    scene
        .pose_shutter(
            PoseTime {
                time: 2.0,
                animation: None,
            },
            0.5,
        )
        .unwrap();
    assert!(scene.motion.is_none());
    scene.pose_shutter(PoseTime::default(), 0.5).unwrap();
    let features = pathwave::render::gpu_scene::pack(&scene).features();
    assert_ne!(features & pathwave::constants::FEATURE_MOTION, 0);
}
