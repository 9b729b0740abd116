//! Adaptive sampling (--adaptive): on a scene of a smooth half and a noisy half it spends its samples on the noisy
//! half, its image agrees with a uniform render within their standard errors, it beats uniform sampling at an equal
//! number of samples, and it stays exact: both schedules give the same bytes, and parts merge to one render's bits.
mod common;
use common::{render, scene_renderer, settings};
use pathwave::diff::rel_mse;
use pathwave::{Adaptive, Film, RenderSettings, Renderer, Schedule};

/// scenes/halves.gltf (tests/common/scenes.rs): a floor half in the sun (smooth) and half under a roof lit by
/// bounces (noisy).
fn halves() -> pathwave::scene::Scene {
    let (_dir, path) = common::write_temp(&common::scenes::halves(), "halves.gltf");
    pathwave::scene::load(&path, None).unwrap_or_else(|e| panic!("{e}"))
}

const W: u32 = 48;
const H: u32 = 32;

fn adaptive(s: RenderSettings, threshold: f32, pilot: u32) -> RenderSettings {
    RenderSettings {
        adaptive: Some(Adaptive { threshold, pilot }),
        ..s
    }
}

fn means(img: &[[f32; 3]]) -> [f64; 3] {
    std::array::from_fn(|c| img.iter().map(|p| p[c] as f64).sum::<f64>() / img.len() as f64)
}

/// The standard error of the image-wide mean, per channel: each pixel's mean's variance, over the pixels.
fn mean_standard_error(f: &Film) -> [f64; 3] {
    let v = f.mean_variance();
    std::array::from_fn(|c| (v.iter().map(|p| p[c] as f64).sum::<f64>()).sqrt() / v.len() as f64)
}

/// Would catch: budgets that ignore the noise (or favour the wrong half), a stopping rule that biases the mean
/// (beyond 4 standard errors), pixel means divided by the render's spp rather than their own counts, and an adaptive
/// render that does not beat uniform sampling for the samples it spends.
#[test]
fn the_noisy_half_gets_the_samples_the_mean_stays_and_the_error_drops() {
    let scene = halves();
    let mut r = scene_renderer(&scene);
    let cap = 256;
    let a = render(&mut r, &adaptive(settings(W, H, cap, 11), 0.05, 16));
    let counts = a.sample_count();
    let half = |right: bool| -> f64 {
        let px: Vec<u32> = (0..(W * H) as usize)
            .filter(|&p| ((p as u32 % W) >= W / 2) == right)
            .map(|p| counts[p])
            .collect();
        px.iter().map(|&n| n as f64).sum::<f64>() / px.len() as f64
    };
    let (left, right) = (half(false), half(true));
    let total: u64 = counts.iter().map(|&n| n as u64).sum();
    eprintln!("samples per pixel: left (smooth) {left:.1}, right (noisy) {right:.1}; total {total}");
    assert!(
        right > 1.5 * left,
        "the noisy half got {right:.1} spp, the smooth half {left:.1}"
    );
    assert!(
        counts.iter().all(|&n| (16..=cap).contains(&n)),
        "a count outside [pilot, cap]"
    );

    // The same work spread evenly: the uniform render of as many samples.
    let even = (total / (W * H) as u64) as u32;
    let u = render(&mut r, &settings(W, H, even, 12));
    let reference = render(&mut r, &settings(W, H, 2048, 13)).mean();
    let (ma, mu) = (means(&a.mean()), means(&u.mean()));
    let (sa, su) = (mean_standard_error(&a), mean_standard_error(&u));
    for c in 0..3 {
        let z = (ma[c] - mu[c]) / (sa[c] * sa[c] + su[c] * su[c]).sqrt();
        eprintln!(
            "channel {c}: adaptive {:.7} ± {:.7}, uniform {:.7} ± {:.7}, z = {z:.2}",
            ma[c], sa[c], mu[c], su[c]
        );
        assert!(z.abs() < 4.0, "channel {c}: the means differ by {z:.2} standard errors");
    }
    let (ea, eu) = (rel_mse(&a.mean(), &reference), rel_mse(&u.mean(), &reference));
    eprintln!(
        "relMSE at {even} spp of work: adaptive {ea:.5}, uniform {eu:.5} ({:.2}x)",
        eu / ea
    );
    assert!(
        ea < eu,
        "adaptive relMSE {ea} is not below uniform's {eu} at equal samples"
    );
}

fn exact_film(r: &mut Renderer, s: &RenderSettings) -> pathwave::render::film::ExactFilm {
    let s = RenderSettings {
        exact_film: true,
        ..s.clone()
    };
    render(r, &s).exact.expect("an exact film")
}

/// Would catch: budgets that depend on where a part starts (a part planning from its own samples rather than the
/// pilot), samples past a budget taken by one schedule and not the other, and a pilot left in a part's film.
#[test]
fn adaptive_renders_are_the_same_bits_on_both_schedules_and_merge_exactly() {
    let scene = halves();
    let mut r = scene_renderer(&scene);
    let s = adaptive(settings(24, 16, 64, 5), 0.05, 8);
    r.set_schedule(Schedule::Wavefront);
    let whole = exact_film(&mut r, &s);
    r.set_schedule(Schedule::Fused);
    assert_eq!(exact_film(&mut r, &s), whole, "the schedules differ");
    // Parts: inside the pilot, across its end, and past it.
    let mut merged: Option<pathwave::render::film::ExactFilm> = None;
    for (first, spp) in [(0, 5), (5, 11), (16, 48)] {
        let part = exact_film(
            &mut r,
            &RenderSettings {
                first_sample: first,
                spp,
                ..s.clone()
            },
        );
        match merged.as_mut() {
            Some(m) => m.add(&part).unwrap(),
            None => merged = Some(part),
        }
    }
    assert_eq!(merged.unwrap(), whole, "the parts do not merge to the whole render");
    assert!(whole.count.iter().any(|&n| n < 64) && whole.count.contains(&64));
}

/// Would catch: adaptive options accepted without --adaptive or with values that cannot work, and an adaptive CLI
/// render that fails or writes no sample-count map.
#[test]
fn the_cli_takes_adaptive_options_and_refuses_bad_ones() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.exr");
    let run = |args: &[&str]| {
        common::pathwave_cli()
            .args([
                "render",
                common::cornell().to_str().unwrap(),
                "--size",
                "16x16",
                "--spp",
                "8",
            ])
            .args(args)
            .arg("-o")
            .arg(&out)
            .output()
            .unwrap()
    };
    let ok = run(&[
        "--adaptive",
        "--min-spp",
        "4",
        "--noise-threshold",
        "0.2",
        "--aov",
        "sample-count",
    ]);
    assert!(ok.status.success(), "{}", String::from_utf8_lossy(&ok.stderr));
    let meta = exr::meta::MetaData::read_from_file(&out, false).unwrap();
    assert!(meta.headers[0]
        .channels
        .list
        .iter()
        .any(|c| c.name.to_string() == "sample-count.N"));
    std::fs::remove_file(&out).unwrap();
    for (args, says) in [
        (&["--noise-threshold", "0.1"][..], "--adaptive"),
        (&["--adaptive", "--min-spp", "1"][..], "--min-spp"),
        (&["--adaptive", "--noise-threshold", "0"][..], "--noise-threshold"),
        (&["--adaptive", "--noise-threshold", "nan"][..], "--noise-threshold"),
    ] {
        let o = run(args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success() && err.contains(says), "{args:?}: {err}");
        assert!(!out.exists());
    }
}
