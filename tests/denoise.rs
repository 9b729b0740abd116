//! --denoise through Open Image Denoise: on the Cornell box at 16 spp it cuts the error against a converged render
//! at least fourfold and keeps the image's means; without the library it fails before rendering and says how to
//! install it. Runs where OIDN loads (PATHWAVE_OIDN or the pyoidn package); under CI=true it must load.
mod common;
use common::{render, renderer, settings};
use pathwave::denoise::{Denoiser, Guides};
use pathwave::diff::rel_mse;
use pathwave::RenderSettings;

/// The denoiser, or None (skipping) outside CI when it is not installed.
fn denoiser() -> Option<Denoiser> {
    match Denoiser::from_env() {
        Ok(d) => Some(d),
        Err(e) if std::env::var("CI").as_deref() != Ok("true") => {
            eprintln!("skipped: {e}");
            None
        }
        Err(e) => panic!("CI must have Open Image Denoise (ci/setup.sh installs it): {e}"),
    }
}

fn means(image: &[[f32; 3]]) -> [f64; 3] {
    std::array::from_fn(|c| image.iter().map(|p| p[c] as f64).sum::<f64>() / image.len() as f64)
}

/// Would catch: guides in the wrong space or order (OIDN then keeps noise or smears edges), a denoiser run without
/// hdr (it clamps the light), a missing prefilter, and any shift of the image's brightness.
#[test]
fn denoising_the_cornell_box_at_16_spp_cuts_its_error_fourfold_and_keeps_its_means() {
    let Some(d) = denoiser() else { return };
    let mut r = renderer(&common::cornell());
    let (w, h) = (128, 128);
    let noisy_film = render(
        &mut r,
        &RenderSettings {
            aovs: true,
            ..settings(w, h, 16, 3)
        },
    );
    // The converged render: 64 times the samples, so its own noise is a 64th of the noisy image's relMSE.
    let reference = render(&mut r, &settings(w, h, 1024, 2)).mean();
    let noisy = noisy_film.mean();
    let aovs = noisy_film.aovs.as_ref().unwrap();
    let (albedo, normal) = (aovs.albedo(), aovs.normal());
    let guides = Guides {
        albedo: Some(&albedo),
        normal: Some(&normal),
        clean: false,
    };
    let denoised = d.denoise(w, h, &noisy, guides).unwrap();
    let (before, after) = (rel_mse(&noisy, &reference), rel_mse(&denoised, &reference));
    eprintln!(
        "relMSE against 1024 spp: noisy {before:.5}, denoised {after:.5} ({:.1}x less)",
        before / after
    );
    assert!(
        after * 4.0 <= before,
        "denoised relMSE {after} is not a quarter of the noisy {before}"
    );
    let (m_ref, m_den) = (means(&reference), means(&denoised));
    let m_noisy = means(&noisy);
    eprintln!("means: reference {m_ref:?}, noisy {m_noisy:?}, denoised {m_den:?}");
    let clamped = |img: &[[f32; 3]]| means(&img.iter().map(|p| p.map(|c| c.min(1.0))).collect::<Vec<_>>());
    eprintln!(
        "means within [0, 1]: reference {:?}, noisy {:?}, denoised {:?}",
        clamped(&reference),
        clamped(&noisy),
        clamped(&denoised)
    );
    for c in 0..3 {
        let shift = (m_den[c] - m_ref[c]).abs() / m_ref[c];
        assert!(
            shift < 0.01,
            "channel {c}: denoised mean {} vs {} ({:.2} %)",
            m_den[c],
            m_ref[c],
            shift * 100.0
        );
    }
}

/// Would catch: the beauty-noisy layer holding the denoised image (or the reverse), and the CLI writing a partial set.
#[test]
fn the_cli_writes_the_denoised_image_and_the_noisy_one_beside_it() {
    if denoiser().is_none() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let exr = dir.path().join("out.exr");
    let out = common::pathwave_cli()
        .args([
            "render",
            common::cornell().to_str().unwrap(),
            "--size",
            "32x32",
            "--spp",
            "4",
        ])
        .args(["--denoise", "--aov", "beauty-noisy,albedo", "-o"])
        .arg(&exr)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let image = exr::prelude::read_all_flat_layers_from_file(&exr).unwrap();
    let layer = &image.layer_data[0];
    let channel = |name: &str| -> Vec<f32> {
        let c = (layer.channel_data.list.iter())
            .find(|c| c.name.to_string() == name)
            .unwrap_or_else(|| panic!("no {name}"));
        c.sample_data.values_as_f32().collect()
    };
    let (denoised, noisy) = (channel("R"), channel("beauty-noisy.R"));
    // Neighbouring pixels differ less after denoising (within [0, 1]: the light's edge stays sharp, as it should).
    let roughness = |v: &[f32]| {
        (v.windows(2))
            .map(|p| (p[1].clamp(0.0, 1.0) - p[0].clamp(0.0, 1.0)).abs() as f64)
            .sum::<f64>()
    };
    assert!(
        roughness(&denoised) * 2.0 < roughness(&noisy),
        "the R channel is no smoother than beauty-noisy.R"
    );
}

/// Would catch: a missing library found only after the render, a panic or a partial output instead of an error.
#[test]
fn without_the_library_denoise_fails_before_rendering_and_says_how_to_install_it() {
    let dir = tempfile::tempdir().unwrap();
    let out_path = dir.path().join("out.png");
    // A denoised render with PATHWAVE_OIDN at `library`: it must exit 1 writing nothing; returns its message.
    let refused = |library: &std::path::Path| {
        let out = common::pathwave_cli()
            .env("PATHWAVE_OIDN", library)
            .args(["render", common::cornell().to_str().unwrap(), "--denoise", "-o"])
            .arg(&out_path)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr).into_owned();
        assert_eq!(out.status.code(), Some(1), "{err}");
        assert!(!out_path.exists());
        err
    };
    let err = refused(&dir.path().join("missing.so"));
    assert!(err.contains("PATHWAVE_OIDN") && err.contains("missing.so"), "{err}");
    // A file that is not OIDN: named, refused, no panic.
    let fake = dir.path().join("libOpenImageDenoise.so.2");
    std::fs::write(&fake, b"not a library").unwrap();
    let err = refused(&fake);
    assert!(err.contains("cannot load it"), "{err}");
}
