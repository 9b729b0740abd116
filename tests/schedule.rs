//! The two schedules, wavefront (queues between stages) and fused (follow: each invocation takes its paths from camera
//! to end), are one integrator: for a seed they give the same bytes and trace the same rays, on every scene feature.
mod common;
use common::{renderer, scene_renderer, scenes_dir, settings};
use pathwave::scene::{self, Environment};
use pathwave::{BvhReads, Film, RenderSettings, RenderStats, Renderer, Schedule};

fn render(r: &mut Renderer, s: &RenderSettings, schedule: Schedule) -> (Film, RenderStats) {
    r.set_schedule(schedule);
    let (film, stats) = r.render(s, &mut |_| {}).unwrap_or_else(|e| panic!("{e}"));
    eprintln!("  {schedule:?}: {}", stats.summary());
    (film, stats)
}

fn bits(f: &Film) -> Vec<u32> {
    f.sum.iter().chain(&f.sum_sq).flatten().map(|v| v.to_bits()).collect()
}

/// Renders with both schedules and requires identical film words (sums and sums of squares) and ray counts; returns
/// the film's words.
fn assert_schedules_agree(what: &str, r: &mut Renderer, s: &RenderSettings) -> Vec<u32> {
    eprintln!("{what}:");
    let (wave, wave_stats) = render(r, s, Schedule::Wavefront);
    let (fused, fused_stats) = render(r, s, Schedule::Fused);
    let (a, b) = (bits(&wave), bits(&fused));
    let differ = a.iter().zip(&b).filter(|(x, y)| x != y).count();
    assert_eq!(
        differ,
        0,
        "{what}: {differ} of {} film words differ between the schedules",
        a.len()
    );
    assert_eq!(
        (wave_stats.extension_rays, wave_stats.shadow_rays),
        (fused_stats.extension_rays, fused_stats.shadow_rays),
        "{what}: the schedules traced different numbers of (extension, shadow) rays"
    );
    // A film of zeros would agree trivially.
    let lit = wave.sum.iter().filter(|p| p[0] + p[1] + p[2] > 0.0).count();
    assert!(lit * 2 > wave.sum.len(), "{what}: only {lit} pixels received light");
    a
}

fn load(name: &str) -> scene::Scene {
    scene::load(&scenes_dir().join(name), None).unwrap_or_else(|e| panic!("{e}"))
}

#[test]
fn the_cornell_box_is_the_same_bytes_either_way_with_either_bvh_read() {
    let mut r = renderer(&scenes_dir().join("cornell-box.gltf"));
    // Several samples per pixel in one pass, so fused lanes start new samples mid-flight; a depth cap and a lens too.
    let s = settings(24, 20, 9, 3);
    let pinhole = assert_schedules_agree("cornell box", &mut r, &s);
    // The lens is folded out of the render stages until a pass has an aperture (FEATURE_LENS): the same renderer
    // must rebuild them for the lens, and again without it.
    let lens = RenderSettings {
        aperture: 0.02,
        ..s.clone()
    };
    let with_lens = assert_schedules_agree("cornell box, thin lens", &mut r, &lens);
    assert!(with_lens != pinhole, "the thin lens changed nothing");
    let again = assert_schedules_agree("cornell box again", &mut r, &s);
    assert!(again == pinhole, "the pinhole came back different");
    let capped = RenderSettings {
        max_depth: Some(3),
        ..lens.clone()
    };
    assert_schedules_agree("cornell box, thin lens, depth 3", &mut r, &capped);
    // Spectral transport: the wavelengths come from the pixel and sample alone, so both schedules find the same.
    let spectral = RenderSettings {
        spectral: true,
        ..s.clone()
    };
    let with_spectra = assert_schedules_agree("cornell box, spectral", &mut r, &spectral);
    assert!(with_spectra != pinhole, "spectral transport changed nothing");
    if r.set_bvh_reads(BvhReads::Storage).is_ok() {
        assert_schedules_agree("cornell box, storage reads", &mut r, &s);
    }
}

#[test]
fn glass_punctual_textured_alpha_and_layered_scenes_are_the_same_bytes_either_way() {
    // glass: delta reflection and refraction; punctual lights: delta lights; textured: the textured and alpha-tested
    // variants (MASK and BLEND in traversal, textures in shading and in emitters); layers: clear coats (delta and
    // rough), sheens and an unlit surface; anisotropy: stretched lobes in tangent frames; iridescence: thin films; translucency: diffuse transmission, thin and solid.
    for name in [
        "glass.gltf",
        "punctual-lights.gltf",
        "textured.gltf",
        "layers.gltf",
        "anisotropy.gltf",
    ] {
        let mut r = renderer(&scenes_dir().join(name));
        assert_schedules_agree(name, &mut r, &settings(20, 16, 6, 11));
    }
}

#[test]
fn scattering_media_are_the_same_bytes_either_way() {
    // The medium stack rides in the wavefront's extra path field (PATH_MEDIUM) and in follow's registers; so do the
    // free flights' and scatterings' randomness, and the light BVH's pick at a scattering point without a normal
    // (LIGHT_NORMAL_NONE in PATH_SHADOW_DIR.w). RGB and spectral (four channels in the free flights' mixture).
    let mut r = renderer(&scenes_dir().join("subsurface.gltf"));
    let s = settings(20, 16, 6, 13);
    assert_schedules_agree("subsurface", &mut r, &s);
    let spectral = RenderSettings {
        spectral: true,
        ..s.clone()
    };
    assert_schedules_agree("subsurface, spectral", &mut r, &spectral);
    let tree = RenderSettings {
        light_sampler: pathwave::LightSampler::Bvh,
        ..s.clone()
    };
    assert_schedules_agree("subsurface, light tree", &mut r, &tree);
}

#[test]
fn many_lights_through_the_light_tree_are_the_same_bytes_either_way() {
    // The lamp grid by the light BVH: the wavefront keeps the normal the tree picked with at a path's last vertex in
    // its path state (PATH_SHADOW_DIR.w) for the pdf twin at the next hit, the fused schedule in registers; and
    // spectrally, where the hero-only flag shares the path state too.
    let mut r = renderer(&scenes_dir().join("lamp-grid.gltf"));
    let s = settings(24, 16, 8, 5);
    assert_eq!(r.light_sampler_run(&s), Some("bvh"));
    let tree = assert_schedules_agree("lamp grid, bvh", &mut r, &s);
    let power = RenderSettings {
        light_sampler: pathwave::LightSampler::Power,
        ..s.clone()
    };
    assert!(
        tree != assert_schedules_agree("lamp grid, power", &mut r, &power),
        "the sampler changed nothing"
    );
    let spectral = RenderSettings { spectral: true, ..s };
    assert_schedules_agree("lamp grid, bvh, spectral", &mut r, &spectral);
}

#[test]
fn a_dispersive_scene_is_the_same_bytes_either_way() {
    // The prism, spectral: a path that crossed dispersive glass keeps its hero wavelength alone, which the wavefront
    // carries in its path state between stages (PATH_HERO_ONLY) and the fused schedule in registers.
    let mut r = renderer(&scenes_dir().join("prism.gltf"));
    let s = RenderSettings {
        spectral: true,
        ..settings(24, 16, 8, 3)
    };
    let spectral = assert_schedules_agree("prism, spectral", &mut r, &s);
    let rgb = assert_schedules_agree("prism, RGB", &mut r, &settings(24, 16, 8, 3));
    assert!(spectral != rgb, "dispersion changed nothing");
}

#[test]
fn an_environment_lit_scene_is_the_same_bytes_either_way() {
    let mut scene = load("material-grid.gltf");
    scene.environment = Some(Environment::constant([0.6, 0.7, 0.9]));
    let mut r = scene_renderer(&scene);
    assert_schedules_agree("material grid in an environment", &mut r, &settings(20, 16, 6, 5));
}

/// The built-in shaders in `dir`, with follow.comp spending `burn_steps` loop iterations (a GLSL expression the
/// compiler cannot see through) before its work; returns the folder and every follow variant's name, to load.
fn burning_follow(dir: &std::path::Path, burn_steps: &str) -> (pathwave::shaders::ShaderDir, Vec<String>) {
    pathwave::shaders::export_builtin(dir).unwrap();
    let follow = dir.join("follow.comp");
    let src = std::fs::read_to_string(&follow).unwrap();
    let anchor = "    uint rays = 0u;\n";
    assert!(src.contains(anchor), "follow.comp changed; update this test's anchor");
    // A use of the result, so the loop stays.
    let burn = format!("    uint burn = 0u;\n    for (uint k = 0u; k < {burn_steps}; k++) burn += k;\n");
    let patched = src.replacen(anchor, &format!("{burn}{anchor}    if (burn == 1u) rays++;\n"), 1);
    std::fs::write(&follow, patched).unwrap();
    let follows = pathwave::render::builtin_stage_names()
        .filter(|n| *n == "follow" || n.starts_with("follow_"))
        .map(String::from)
        .collect();
    (pathwave::shaders::ShaderDir::open(dir).unwrap(), follows)
}

/// lavapipe silently ends a shader's loops once their iterations reach 65535 per invocation. A follow stage that burns
/// that budget first must be caught: the pass runs again as a wavefront (same bytes as one from the start), and the
/// renderer stays with the wavefront and says why.
#[test]
fn a_follow_dispatch_cut_short_by_the_loop_budget_is_run_again_as_a_wavefront() {
    let dir = tempfile::tempdir().unwrap();
    // 70,000 steps, past the budget.
    let (shaders, follows) = burning_follow(dir.path(), "70000u + frame.seed");

    let mut r = renderer(&scenes_dir().join("cornell-box.gltf"));
    let s = settings(16, 12, 4, 2);
    r.set_schedule(Schedule::Wavefront);
    let (want, _) = r.render(&s, &mut |_| {}).unwrap();
    r.load_shaders(&shaders, Some(&follows)).unwrap();
    assert_eq!(
        r.schedule(),
        Schedule::Fused,
        "an edited follow stage must be the one that runs"
    );
    let (got, stats) = r.render(&s, &mut |_| {}).unwrap();
    eprintln!("{}", stats.summary());
    assert!(
        stats.stage_ms.iter().any(|(l, _)| *l == "follow") || stats.passes == 1,
        "follow never ran: {}",
        stats.summary()
    );
    assert_eq!(
        r.schedule(),
        Schedule::Wavefront,
        "the renderer kept the fused schedule after a cut"
    );
    assert!(r.warnings.iter().any(|w| w.contains("loop budget")), "{:?}", r.warnings);
    assert!(
        bits(&want) == bits(&got),
        "the pass run again differs from a wavefront render"
    );
}

/// A follow dispatch over more sample rows than FOLLOW_SAMPLES that runs past the loop budget is run again with half
/// as many rows per dispatch, still fused (same bytes as a wavefront), and the renderer never takes as many again.
#[test]
fn a_cut_follow_dispatch_of_many_rows_runs_again_with_fewer() {
    let dir = tempfile::tempdir().unwrap();
    // 70,000 steps when this dispatch takes more than FOLLOW_SAMPLES rows (the host sets path_count per dispatch).
    let taken = "frame.path_count / frame.pass_pixels - frame.bounce";
    let steps = format!("({taken} > FOLLOW_SAMPLES ? 70000u : 1u) + frame.seed");
    let (shaders, follows) = burning_follow(dir.path(), &steps);

    let mut r = renderer(&scenes_dir().join("cornell-box.gltf"));
    let s = settings(16, 12, 80, 2);
    r.set_schedule(Schedule::Wavefront);
    let (want, _) = r.render(&s, &mut |_| {}).unwrap();
    r.load_shaders(&shaders, Some(&follows)).unwrap();
    assert_eq!(r.schedule(), Schedule::Fused);
    let rows = pathwave::constants::FOLLOW_SAMPLES;
    let mut session = r.begin(&s).unwrap();
    // rows + 4 samples: dispatches of `rows` and 4, within the budget; the next pass may take twice as many.
    assert_eq!(r.advance(&mut session, rows + 4).unwrap(), rows + 4);
    assert_eq!(
        r.follow_rows(),
        2 * rows,
        "a fused pass within the budget doubles the rows per dispatch"
    );
    // A dispatch of 2 * rows burns the budget: the pass runs again in dispatches of `rows`.
    let rest = s.spp - (rows + 4);
    assert_eq!(r.advance(&mut session, rest).unwrap(), rest);
    assert_eq!(
        r.follow_rows(),
        rows,
        "the cut pass did not halve the rows per dispatch"
    );
    assert_eq!(
        r.schedule(),
        Schedule::Fused,
        "a cut with rows to spare must stay fused"
    );
    assert!(r.warnings.is_empty(), "{:?}", r.warnings);
    let got = r.film(&session).unwrap();
    assert!(
        bits(&want) == bits(&got),
        "the pass run again differs from a wavefront render"
    );
    // Never as many rows again.
    let mut session = r.begin(&s).unwrap();
    r.advance(&mut session, rows + 4).unwrap();
    assert_eq!(r.follow_rows(), rows);
}
