//! Mitsuba's renders through the helper, and its converged reference: rendered in two halves, cached on disk.
use super::err;
use super::helper::{read_f32, write_f32, Helper};
use crate::error::Error;
use serde_json::json;
use std::path::PathBuf;

fn cache_dir() -> PathBuf {
    if let Some(d) = std::env::var_os("XDG_CACHE_HOME").filter(|d| !d.is_empty()) {
        return PathBuf::from(d).join("pathwave/bench");
    }
    match std::env::var_os("HOME") {
        Some(h) => PathBuf::from(h).join(".cache/pathwave/bench"),
        None => std::env::temp_dir().join("pathwave-bench"),
    }
}

/// FNV-1a, for naming the cached reference after everything that decides it.
pub(super) fn fnv_bytes(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325, |h, b| {
        (h ^ *b as u64).wrapping_mul(0x100_0000_01b3)
    })
}

/// One Mitsuba render of the loaded scene: its time and its pixels (RGB floats).
pub(super) fn mitsuba_render(
    h: &mut Helper,
    pixels: usize,
    sampler: &str,
    spp: u32,
    seed: u32,
) -> Result<(f64, Vec<f32>), Error> {
    let out = h.path("mitsuba.f32");
    let r = h.call(json!({"cmd": "mitsuba_render", "sampler": sampler, "spp": spp, "seed": seed, "out": out}))?;
    let img = read_f32(&out)?;
    if img.len() != 3 * pixels {
        return Err(err(format!(
            "Mitsuba returned {} floats for {pixels} pixels",
            img.len()
        )));
    }
    Ok((Helper::f64(&r, "seconds")?, img))
}

/// The reference: Mitsuba's, in two independent halves, cached under a name that changes with `key_text` (the
/// scene, the image, the sample count and Mitsuba's version). Returns the halves and whether they came from the cache.
pub(super) fn mitsuba_reference(
    h: &mut Helper,
    pixels: usize,
    key_text: &str,
    reference_spp: u32,
    progress: &mut dyn FnMut(&str),
) -> Result<(Vec<f32>, Vec<f32>, bool), Error> {
    let key = format!("{:016x}", fnv_bytes(key_text.as_bytes()));
    let cache = cache_dir().join(format!("cornell-reference-{key}"));
    if let (Ok(a), Ok(b)) = (read_f32(&cache.join("a.f32")), read_f32(&cache.join("b.f32"))) {
        if a.len() == 3 * pixels && b.len() == 3 * pixels {
            return Ok((a, b, true));
        }
    }
    let chunk = 256.min(reference_spp / 2);
    let chunks = reference_spp / 2 / chunk;
    let mut halves = [vec![0f32; 3 * pixels], vec![0f32; 3 * pixels]];
    for (half, acc) in halves.iter_mut().enumerate() {
        for c in 0..chunks {
            progress(&format!(
                "Mitsuba reference, {} of {} spp (cached afterwards in {})",
                (half as u32 * chunks + c) * chunk,
                reference_spp,
                cache.display()
            ));
            let seed = 1_000_000 + half as u32 * chunks + c;
            let (_, img) = mitsuba_render(h, pixels, "independent", chunk, seed)?;
            for (s, v) in acc.iter_mut().zip(img) {
                *s += v / chunks as f32;
            }
        }
    }
    std::fs::create_dir_all(&cache).map_err(err)?;
    write_f32(&cache.join("a.f32"), &halves[0])?;
    write_f32(&cache.join("b.f32"), &halves[1])?;
    let [a, b] = halves;
    Ok((a, b, false))
}
