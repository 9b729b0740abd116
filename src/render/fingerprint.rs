//! What a film file names a render by: the scene, the frame every pass starts from and the render stages, hashed.
use super::{RenderSettings, Renderer};
use crate::constants::FLAG_DEBUG_AOVS;
use crate::error::Error;

impl Renderer {
    /// What a film file names a render with `s` by: the scene's fingerprint, the frame every pass starts from
    /// (camera, size, seed, depth, estimator, flags, environment) and the render stages' SPIR-V, each a BLAKE3.
    /// The scene's is kept only when `RendererOptions::fingerprint` asked for it.
    pub fn fingerprints(&self, s: &RenderSettings) -> Result<[String; 3], Error> {
        let scene = self.scene.fingerprint.clone().ok_or_else(|| {
            Error::Settings("the renderer did not keep the scene's fingerprint (RendererOptions::fingerprint)".into())
        })?;
        let mut frame = self.frame(s);
        frame.flags = film_frame_flags(frame.flags, s);
        let frame = blake3::hash(bytemuck::bytes_of(&frame)).to_hex().to_string();
        Ok([scene, frame, self.kernels.render_fingerprint()])
    }
}

/// Bits film format 1 hashes into a film file's frame fingerprint for settings no shader reads. Frame.flags carried
/// them once (constants.rs keeps them retired); hashing them as then keeps film files written before and after
/// mergeable, and keeps spectral and RGB parts, and adaptive and uniform ones, from merging.
const FILM_FRAME_EXACT: u32 = 256;
const FILM_FRAME_ADAPTIVE: u32 = 1024;
const FILM_FRAME_SPECTRAL: u32 = 8192;

/// The flags a film file's frame fingerprint hashes: a pass's flags without the debug views (AOVs do not change the
/// samples: parts with and without them merge), with the retired settings bits.
fn film_frame_flags(flags: u32, s: &RenderSettings) -> u32 {
    let bit = |on: bool, b: u32| if on { b } else { 0 };
    flags & !FLAG_DEBUG_AOVS
        | bit(s.exact_film, FILM_FRAME_EXACT)
        | bit(s.adaptive.is_some(), FILM_FRAME_ADAPTIVE)
        | bit(s.spectral, FILM_FRAME_SPECTRAL)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::constants::*;
    use crate::render::Adaptive;

    /// A film file's frame fingerprint hashes the bits Frame.flags carried for these settings before they were
    /// retired, written out as numbers: a renumbering, or a flag the shaders read taking a retired bit, fails here
    /// (either would change every film file's bytes and which parts merge).
    #[test]
    fn film_files_keep_hashing_the_retired_flag_bits() {
        let s = |edit: fn(&mut RenderSettings)| {
            let mut s = RenderSettings::default();
            edit(&mut s);
            s
        };
        assert_eq!(film_frame_flags(0, &s(|_| {})), 0);
        assert_eq!(film_frame_flags(0, &s(|s| s.exact_film = true)), 256);
        assert_eq!(
            film_frame_flags(
                0,
                &s(|s| s.adaptive = Some(Adaptive {
                    threshold: 0.01,
                    pilot: 16
                }))
            ),
            1024
        );
        assert_eq!(film_frame_flags(0, &s(|s| s.spectral = true)), 8192);
        // The debug views leave; every other flag stays.
        assert_eq!(film_frame_flags(1 | 2048 | 32768, &s(|s| s.aovs = true)), 1 | 32768);
        let live = FLAG_ENERGY_COMPENSATION
            | FLAG_HIDE_ENV
            | FLAG_VERTEX_COLORS
            | FLAG_FUSED_SUMS
            | 3 << ESTIMATOR_SHIFT
            | FLAG_CAMERA_MOTION
            | FLAG_ORTHOGRAPHIC
            | FLAG_DEBUG_AOVS
            | FLAG_PIXEL_ORDER
            | FLAG_LIGHT_UNIFORM
            | FLAG_LIGHT_TREE;
        assert_eq!(live & (256 | 512 | 1024 | 8192), 0, "a live flag took a retired bit");
    }
}
