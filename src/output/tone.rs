//! Tone curves: linear radiance (after exposure) to display-linear values in [0, 1], for PNG output and the viewer.
//!
//! The host's operators here write `render`'s PNG; tonemap.comp is the viewer's twin, held to these by
//! tests/tonemap.rs. Each follows its published definition:
//! - ACES: Narkowicz's 2015 fit of the ACES RRT+ODT curve, x (2.51 x + 0.03) / (x (2.43 x + 0.59) + 0.14), per
//!   channel, clamped to [0, 1] (not Hill's fit with its input and output matrices).
//! - AgX: Sobotka's AgX base transform as Wrensch's minimal implementation states it: the inset matrix, log2
//!   encoding between -12.47393 and 4.026069 EV about 0.18, the default contrast sigmoid's 6th-order polynomial fit,
//!   the inset's inverse, then the 2.2 power that undoes the curve's display encoding (so sRGB encoding follows as
//!   for the other curves).
//! - PBR Neutral: Khronos's reference (KhronosGroup/ToneMapping, PBR_Neutral): start of compression 0.76,
//!   desaturation 0.15.
use glam::{Mat3, Vec3};

/// A display image's tone curve; `None` is linear clipped at 1 (pathwave's PNG before tone curves existed).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum ToneCurve {
    /// Linear, clipped at 1.
    #[default]
    #[value(name = "none", alias = "clamp")]
    None,
    /// Narkowicz's fit of the ACES filmic curve.
    Aces,
    /// Sobotka's AgX (Wrensch's minimal implementation).
    Agx,
    /// Khronos PBR Neutral.
    #[value(name = "pbr-neutral", alias = "neutral")]
    PbrNeutral,
}

/// AgX's inset matrix (linear sRGB to the AgX working space), column by column.
const AGX_INSET: [f32; 9] = [
    0.842_479_06,
    0.042_328_24,
    0.042_375_655,
    0.078_433_6,
    0.878_468_6,
    0.078_433_6,
    0.079_223_745,
    0.079_166_13,
    0.879_143,
];
pub const AGX_MIN_EV: f32 = -12.473_93;
pub const AGX_MAX_EV: f32 = 4.026_069;

impl ToneCurve {
    /// The shader's code for this curve (constants.rs's TONEMAP_*).
    pub fn code(self) -> u32 {
        use crate::constants::*;
        match self {
            ToneCurve::None => TONEMAP_CLAMP,
            ToneCurve::Aces => TONEMAP_ACES,
            ToneCurve::Agx => TONEMAP_AGX,
            ToneCurve::PbrNeutral => TONEMAP_NEUTRAL,
        }
    }

    /// The curve after this one, as the viewer's T key cycles them.
    pub fn next(self) -> Self {
        match self {
            ToneCurve::None => ToneCurve::Aces,
            ToneCurve::Aces => ToneCurve::Agx,
            ToneCurve::Agx => ToneCurve::PbrNeutral,
            ToneCurve::PbrNeutral => ToneCurve::None,
        }
    }

    /// The display-linear value in [0, 1] of linear radiance `c` (exposure already applied).
    pub fn apply(self, c: [f32; 3]) -> [f32; 3] {
        let v = Vec3::from(c);
        let out = match self {
            ToneCurve::None => v,
            ToneCurve::Aces => v * (2.51 * v + 0.03) / (v * (2.43 * v + 0.59) + 0.14),
            ToneCurve::Agx => agx(v),
            ToneCurve::PbrNeutral => pbr_neutral(v.max(Vec3::ZERO)),
        };
        out.clamp(Vec3::ZERO, Vec3::ONE).to_array()
    }
}

/// AgX's default contrast sigmoid on log-encoded [0, 1]: Wrensch's 6th-order fit (mean squared error 3.7e-6).
fn agx_contrast(x: f32) -> f32 {
    let x2 = x * x;
    let x4 = x2 * x2;
    15.5 * x4 * x2 - 40.14 * x4 * x + 31.96 * x4 - 6.868 * x2 * x + 0.4298 * x2 + 0.1191 * x - 0.00232
}

fn agx(c: Vec3) -> Vec3 {
    let inset = Mat3::from_cols_array(&AGX_INSET);
    // Below 2^-40 every channel is at the log encoding's floor anyway; the max keeps log2 finite.
    let working = (inset * c).max(Vec3::splat(1e-12));
    let encoded = working.to_array().map(|x| {
        let ev = x.log2().clamp(AGX_MIN_EV, AGX_MAX_EV);
        agx_contrast((ev - AGX_MIN_EV) / (AGX_MAX_EV - AGX_MIN_EV))
    });
    let display = inset.inverse() * Vec3::from(encoded);
    display.max(Vec3::ZERO).powf(2.2)
}

fn pbr_neutral(mut c: Vec3) -> Vec3 {
    const START: f32 = 0.8 - 0.04;
    const DESATURATION: f32 = 0.15;
    let x = c.min_element();
    let offset = if x < 0.08 { x - 6.25 * x * x } else { 0.04 };
    c -= Vec3::splat(offset);
    let peak = c.max_element();
    if peak < START {
        return c;
    }
    let d = 1.0 - START;
    let new_peak = 1.0 - d * d / (peak + d - START);
    c *= new_peak / peak;
    let g = 1.0 - 1.0 / (DESATURATION * (peak - new_peak) + 1.0);
    c.lerp(Vec3::splat(new_peak), g)
}
