//! The AOVs (survey.comp) on scenes whose answers are known: Lambertian albedo is the base colour, a mirror shows the
//! albedo and normal of what it reflects, depth and position are the analytic ones, normals are unit and face the
//! camera; AOVs are the same bytes with either schedule and leave the image's bytes alone; and the CLI writes them.
mod common;
use common::gltf_builder::{upright, GltfBuilder, FACING_Z};
use common::{render, scene_renderer, settings};
use glam::Vec3;
use pathwave::{Film, RenderSettings, Schedule};

fn with_aovs(s: RenderSettings) -> RenderSettings {
    RenderSettings { aovs: true, ..s }
}

fn load(b: &GltfBuilder) -> pathwave::scene::Scene {
    let (_dir, path) = common::write_temp(b, "aovs.gltf");
    pathwave::scene::load(&path, None).unwrap_or_else(|e| panic!("{e}"))
}

/// Pixels of `material` whose 3x3 neighbourhood's first hits are all the pixel's instance and material: every
/// sample of such a pixel sees that one flat surface.
fn interior(film: &Film, material: u32) -> Vec<usize> {
    let aovs = film.aovs.as_ref().unwrap();
    let ids: Vec<_> = aovs.instance_id().into_iter().zip(aovs.material_id()).collect();
    let (w, h) = (film.width as i64, film.height as i64);
    (0..(w * h) as usize)
        .filter(|&p| {
            let (x, y) = (p as i64 % w, p as i64 / w);
            ids[p].1 == Some(material)
                && (-1..=1).all(|dy| {
                    (-1..=1).all(|dx| {
                        let (nx, ny) = (x + dx, y + dy);
                        nx >= 0 && ny >= 0 && nx < w && ny < h && ids[(ny * w + nx) as usize] == ids[p]
                    })
                })
        })
        .collect()
}

/// Would catch: an albedo taken from the wrong lobe weight, or scaled (e.g. by 1/pi or a pdf); normals not unit, or
/// on the far side; ids not the first hit's.
#[test]
fn lambertian_walls_show_their_base_colour_and_unit_normals_facing_the_camera() {
    let b = common::scenes::cornell_box();
    let scene = load(&b);
    let eye = scene.camera.as_ref().expect("the box has a camera").origin();
    let mut r = scene_renderer(&scene);
    let film = render(&mut r, &with_aovs(settings(48, 48, 4, 1)));
    let aovs = film.aovs.as_ref().expect("AOVs were asked for");
    let (albedo, normal, position) = (aovs.albedo(), aovs.normal(), aovs.position());
    // The builder's materials: white, red, green, light (scenes::cornell_box).
    let colours = [[0.725, 0.71, 0.68], [0.63, 0.065, 0.05], [0.14, 0.45, 0.091]];
    for (m, colour) in colours.iter().enumerate() {
        let pixels = interior(&film, m as u32);
        assert!(pixels.len() > 20, "material {m}: only {} interior pixels", pixels.len());
        for &p in &pixels {
            for c in 0..3 {
                assert!(
                    (albedo[p][c] - colour[c]).abs() < 1e-5,
                    "material {m}, pixel {p}: albedo {:?}, base colour {colour:?}",
                    albedo[p]
                );
            }
            let n = Vec3::from(normal[p]);
            assert!((n.length() - 1.0).abs() < 1e-4, "pixel {p}: normal {n} is not unit");
            let to_eye = (eye - Vec3::from(position[p])).normalize();
            assert!(
                n.dot(to_eye) > 0.05,
                "pixel {p}: normal {n} faces away from the camera ({to_eye})"
            );
        }
    }
}

/// A camera at the origin looking down -z at a white mirror tilted 45 degrees, which sends every camera ray along +x
/// to a red Lambertian wall facing back along -x.
fn mirror_scene() -> GltfBuilder {
    let mut b = GltfBuilder::new();
    let red = b.material("red", [0.6, 0.1, 0.05], [0.0; 3], false);
    let mirror = b.pbr_material("mirror", [1.0; 3], 1.0, 0.0, [0.0; 3], false);
    // The mirror: the plane x + z = -3 (normal (1, 0, 1) / sqrt 2), big enough to fill the view.
    b.quad(
        "mirror",
        [[-4.0, -4.0, 1.0], [4.0, -4.0, -7.0], [4.0, 4.0, -7.0], [-4.0, 4.0, 1.0]],
        mirror,
        Some([1.0, 0.0, 1.0]),
    );
    b.quad(
        "wall",
        [
            [6.0, -50.0, -50.0],
            [6.0, 50.0, -50.0],
            [6.0, 50.0, 50.0],
            [6.0, -50.0, 50.0],
        ],
        red,
        Some([-1.0, 0.0, 0.0]),
    );
    b.camera([0.0; 3], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0], 20.0);
    b
}

/// Would catch: the AOVs stopping at a perfect mirror (its own albedo and normal) rather than looking through it, or
/// a mirror's throughput not carried into what it reflects; depth and position taken past the first hit.
#[test]
fn through_a_mirror_the_albedo_and_normal_are_what_it_reflects() {
    let scene = load(&mirror_scene());
    let mut r = scene_renderer(&scene);
    let film = render(&mut r, &with_aovs(settings(16, 16, 4, 2)));
    let aovs = film.aovs.as_ref().unwrap();
    let (albedo, normal, depth, position) = (aovs.albedo(), aovs.normal(), aovs.depth(), aovs.position());
    let (instances, materials) = (aovs.instance_id(), aovs.material_id());
    for p in 0..albedo.len() {
        for (c, want) in [0.6, 0.1, 0.05].iter().enumerate() {
            assert!((albedo[p][c] - want).abs() < 1e-5, "pixel {p}: albedo {:?}", albedo[p]);
        }
        assert!(
            (Vec3::from(normal[p]) - Vec3::NEG_X).length() < 1e-5,
            "pixel {p}: normal {:?}",
            normal[p]
        );
        // The first hit is the mirror, on the plane x + z = -3, at its distance from the eye.
        let q = Vec3::from(position[p]);
        assert!(
            (q.x + q.z + 3.0).abs() < 1e-4,
            "pixel {p}: position {q} is not on the mirror"
        );
        assert!(
            (depth[p] - q.length()).abs() < 1e-3 * q.length(),
            "pixel {p}: depth {} at {q}",
            depth[p]
        );
        assert_eq!(
            (instances[p], materials[p]),
            (Some(0), Some(1)),
            "pixel {p}: ids of the mirror"
        );
    }
}

/// Would catch: depth measured from the wrong origin, along the wrong axis, or averaged with the misses.
#[test]
fn depth_is_the_distance_along_the_camera_ray() {
    let mut b = GltfBuilder::new();
    let grey = b.material("grey", [0.5; 3], [0.0; 3], false);
    // A plane at z = -5 facing a camera at the origin, covering the middle of the view only.
    b.quad("plane", upright([-1.0, 1.0], [-1.0, 1.0], -5.0), grey, FACING_Z);
    b.camera([0.0; 3], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0], 40.0);
    let scene = load(&b);
    let mut r = scene_renderer(&scene);
    let (w, h) = (32u32, 32u32);
    let film = render(&mut r, &with_aovs(settings(w, h, 8, 3)));
    let aovs = film.aovs.as_ref().unwrap();
    let (depth, position, normal) = (aovs.depth(), aovs.position(), aovs.normal());
    let half = (20f32).to_radians().tan();
    let (mut hits, mut misses) = (0, 0);
    for y in 0..h {
        for x in 0..w {
            let p = (y * w + x) as usize;
            // The pixel centre's ray: its depth to the plane is 5 / cos; within the pixel the depth changes by less
            // than the tolerance.
            let dx = (2.0 * (x as f32 + 0.5) / w as f32 - 1.0) * half;
            let dy = (1.0 - 2.0 * (y as f32 + 0.5) / h as f32) * half;
            let on_plane = [5.0 * dx, 5.0 * dy];
            let margin = 5.0 * 2.0 * half / w as f32;
            let inside = on_plane.iter().all(|c| c.abs() < 1.0 - margin);
            let outside = on_plane.iter().any(|c| c.abs() > 1.0 + margin);
            if inside {
                hits += 1;
                let want = 5.0 * (1.0 + dx * dx + dy * dy).sqrt();
                assert!(
                    (depth[p] - want).abs() < 2e-3 * want,
                    "pixel {x},{y}: depth {}, want {want}",
                    depth[p]
                );
                assert!(
                    (position[p][2] + 5.0).abs() < 1e-4,
                    "pixel {x},{y}: position {:?}",
                    position[p]
                );
                assert!((Vec3::from(normal[p]) - Vec3::Z).length() < 1e-5);
            } else if outside {
                misses += 1;
                assert_eq!(
                    depth[p],
                    f32::INFINITY,
                    "pixel {x},{y}: nothing there, depth {}",
                    depth[p]
                );
                assert_eq!(normal[p], [0.0; 3]);
            }
        }
    }
    assert!(hits > 100 && misses > 100, "{hits} hits, {misses} misses");
}

fn aov_words(film: &Film) -> Vec<u32> {
    (film.aovs.as_ref().unwrap().sums.iter())
        .flat_map(|a| bytemuck::cast::<_, [u32; 16]>(*a))
        .collect()
}

fn film_words(f: &Film) -> Vec<u32> {
    f.sum.iter().chain(&f.sum_sq).flatten().map(|v| v.to_bits()).collect()
}

/// Would catch: AOV sums that depend on the schedule or on how samples fall into passes (atomics, or an order that
/// is not the samples'), a survey that disturbs the image (shared state, the path state: with scattering media
/// too, whose paths carry a medium stack, and whose AOVs are their boundaries'), and survey running again over a pass
/// the host repeats.
#[test]
fn aovs_are_the_same_bytes_with_either_schedule_and_leave_the_image_alone() {
    for file in ["glass.gltf", "subsurface.gltf"] {
        let scene = pathwave::scene::load(&common::scenes_dir().join(file), None).unwrap();
        let mut r = scene_renderer(&scene);
        let s = settings(24, 20, 6, 5);
        r.set_schedule(Schedule::Wavefront);
        let plain = render(&mut r, &s);
        let wave = render(&mut r, &with_aovs(s.clone()));
        r.set_schedule(Schedule::Fused);
        let fused = render(&mut r, &with_aovs(s.clone()));
        assert_eq!(film_words(&plain), film_words(&wave), "{file}: AOVs changed the image");
        assert_eq!(
            film_words(&wave),
            film_words(&fused),
            "{file}: the schedules' images differ"
        );
        assert_eq!(
            aov_words(&wave),
            aov_words(&fused),
            "{file}: the schedules' AOVs differ"
        );
        // Samples 0..6 in passes of 2: the same sums as one pass.
        let mut session = r.begin(&with_aovs(s.clone())).unwrap();
        while session.done < s.spp {
            r.advance(&mut session, 2).unwrap();
        }
        let passes = r.film(&session).unwrap();
        assert_eq!(
            aov_words(&passes),
            aov_words(&fused),
            "{file}: AOVs depend on the passes"
        );
        assert!(plain.aovs.is_none());
    }
}

/// Would catch: layers missing from or misnamed in the EXR, PNG outputs without their AOV files, and bad lists
/// accepted.
#[test]
fn the_cli_writes_aovs_as_layers_and_files() {
    let dir = tempfile::tempdir().unwrap();
    let (exr, png) = (dir.path().join("out.exr"), dir.path().join("out.png"));
    let out = common::pathwave_cli()
        .args([
            "render",
            common::cornell().to_str().unwrap(),
            "--size",
            "24x16",
            "--spp",
            "2",
        ])
        .args(["--aov", "albedo,normal,depth,sample-count,instance-id"])
        .arg("-o")
        .arg(&exr)
        .arg("-o")
        .arg(&png)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let meta = exr::meta::MetaData::read_from_file(&exr, false).unwrap();
    let names: Vec<String> = meta.headers[0]
        .channels
        .list
        .iter()
        .map(|c| c.name.to_string())
        .collect();
    for want in [
        "R",
        "G",
        "B",
        "albedo.R",
        "albedo.G",
        "albedo.B",
        "normal.X",
        "normal.Y",
        "normal.Z",
        "depth.Z",
        "sample-count.N",
        "instance-id.ID",
    ] {
        assert!(names.iter().any(|n| n == want), "no {want} channel in {names:?}");
    }
    for aov in ["albedo", "normal", "depth", "sample-count", "instance-id"] {
        let file = dir.path().join(format!("out.{aov}.png"));
        assert!(file.is_file(), "{} was not written", file.display());
        // EXR outputs hold their AOVs as layers; files only with --aov-files.
        assert!(!dir.path().join(format!("out.{aov}.exr")).exists());
    }
    for (list, says) in [
        ("albedo,glow", "'glow' is no AOV"),
        ("albedo,albedo", "named twice"),
        ("beauty-noisy", "needs --denoise"),
    ] {
        let out = common::pathwave_cli()
            .args(["render", common::cornell().to_str().unwrap(), "--aov", list, "-o"])
            .arg(dir.path().join("bad.exr"))
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success() && err.contains(says), "--aov {list}: {err}");
        assert!(!dir.path().join("bad.exr").exists());
    }
}
