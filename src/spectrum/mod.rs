//! Spectra on the host: the CIE observer and D65, visible-wavelength sampling, RGB upsampled to spectra (Jakob &
//! Hanika 2019, with the conventions of Mitsuba 3 and pbrt-v4) and XYZ to linear sRGB. shaders/include/spectrum.glsl
//! is the device twin; tests/spectrum.rs holds both to the fit.
pub mod fit;

use crate::constants::{
    CIE_ROWS, LAMBDA_MAX, LAMBDA_MIN, RGB2SPEC_RES, SPECTRUM_CIE, SPECTRUM_FLOATS, SPECTRUM_MATRIX, WAVELENGTHS,
};
use std::sync::OnceLock;

const CIE_TEXT: &str = include_str!("../../data/cie1931_d65.tsv");
/// fit::build_table's output for RGB2SPEC_RES, f32 little-endian (examples/rgb2spec.rs writes it).
static RGB2SPEC: &[u8] = include_bytes!("../../data/rgb2spec_srgb_32.bin");

/// Wavelength sampling's density is ∝ sech²(A (λ − C)) over the visible range: close to the sum of the observer's
/// curves, so the film's XYZ weights vary little and no wavelength the eye sees goes unsampled (the shape pbrt-v4
/// and Mitsuba 3 use).
const A: f64 = 0.0072;
const C: f64 = 538.0;

/// The tables every spectral computation reads, parsed once.
pub struct Tables {
    pub cie: fit::Cie,
    pub fit: fit::Fit,
    /// ∫ ȳ dλ: the film divides XYZ by it, so a reflectance of 1 under the scaled D65 gives Y = 1.
    y_integral: f64,
    /// D65 times this has Y = 1 (an emitter of RGB (1, 1, 1) renders as (1, 1, 1)).
    d65_scale: f64,
    coefficients: Vec<f32>,
    z_nodes: Vec<f32>,
}

pub fn tables() -> &'static Tables {
    static TABLES: OnceLock<Tables> = OnceLock::new();
    TABLES.get_or_init(|| {
        let cie = fit::Cie::parse(CIE_TEXT);
        let coefficients: Vec<f32> = RGB2SPEC
            .chunks_exact(4)
            .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            .collect();
        let res = RGB2SPEC_RES as usize;
        assert_eq!(
            coefficients.len(),
            3 * res * res * res * 3,
            "data/rgb2spec_srgb_32.bin holds RGB2SPEC_RES's table"
        );
        let fit = fit::Fit::new(&cie);
        Tables {
            y_integral: fit.y_integral,
            d65_scale: fit.d65_scale,
            fit,
            cie,
            coefficients,
            z_nodes: fit::z_nodes(res).into_iter().map(|z| z as f32).collect(),
        }
    })
}

/// The normalised wavelength the coefficients are over.
pub fn unit_wavelength(nm: f32) -> f32 {
    (nm - LAMBDA_MIN) / (LAMBDA_MAX - LAMBDA_MIN)
}

impl Tables {
    /// The spectral tables as the device reads them (SPECTRUM_* in constants.rs): the matrix, zeros to the CIE rows'
    /// alignment, the CIE rows, the nodes and the coefficients.
    pub fn device_floats(&self) -> Vec<f32> {
        let mut out = Vec::with_capacity(SPECTRUM_FLOATS as usize);
        for row in self.xyz_to_srgb() {
            out.extend_from_slice(&[row[0], row[1], row[2], 0.0]);
        }
        out.resize((SPECTRUM_CIE - SPECTRUM_MATRIX) as usize, 0.0);
        out.extend(self.cie_rows().into_iter().flatten());
        out.extend_from_slice(&self.z_nodes);
        out.extend_from_slice(&self.coefficients);
        assert_eq!(out.len(), SPECTRUM_FLOATS as usize);
        out
    }

    /// The CIE rows as the device reads them: the observer over the integral of y-bar, and D65 with Y = 1, per nm
    /// from LAMBDA_MIN.
    fn cie_rows(&self) -> Vec<[f32; 4]> {
        assert_eq!(self.cie.xyz.len(), CIE_ROWS as usize, "the CIE table has CIE_ROWS rows");
        let xyz = |c: &[f64; 3]| c.map(|v| (v / self.y_integral) as f32);
        (self.cie.xyz.iter().zip(&self.cie.d65))
            .map(|(c, d65)| {
                let [x, y, z] = xyz(c);
                [x, y, z, (d65 * self.d65_scale) as f32]
            })
            .collect()
    }

    /// The RGB-to-spectrum table as kept (fit::build_table's layout).
    pub fn coefficient_table(&self) -> &[f32] {
        &self.coefficients
    }

    /// The table's rows around nm and the weight of the upper one; None outside the range.
    fn row(&self, nm: f32) -> Option<(usize, f64)> {
        let x = nm as f64 - self.cie.first_nm;
        if !(0.0..=(self.cie.xyz.len() - 1) as f64).contains(&x) {
            return None;
        }
        let i = (x as usize).min(self.cie.xyz.len() - 2);
        Some((i, x - i as f64))
    }

    /// The CIE 1931 observer at nm over ∫ ȳ dλ (linear between the 1 nm rows), zero outside the range.
    pub fn observer(&self, nm: f32) -> [f32; 3] {
        self.row(nm).map_or([0.0; 3], |(i, t)| {
            [0, 1, 2].map(|k| (((1.0 - t) * self.cie.xyz[i][k] + t * self.cie.xyz[i + 1][k]) / self.y_integral) as f32)
        })
    }

    /// D65 at nm, scaled so that its Y is 1.
    pub fn illuminant(&self, nm: f32) -> f32 {
        self.row(nm).map_or(0.0, |(i, t)| {
            (((1.0 - t) * self.cie.d65[i] + t * self.cie.d65[i + 1]) * self.d65_scale) as f32
        })
    }

    /// XYZ (Y = 1 for the white) to linear sRGB.
    pub fn xyz_to_srgb(&self) -> [[f32; 3]; 3] {
        self.fit.to_srgb.map(|r| r.map(|v| v as f32))
    }

    /// The sigmoid-of-quadratic coefficients (over unit_wavelength) of a reflectance, RGB clamped to [0, 1]: the
    /// table's trilinear interpolation; greys exactly, as constant spectra.
    pub fn coefficients(&self, rgb: [f32; 3]) -> [f32; 3] {
        let rgb = rgb.map(|c| if c.is_nan() { 0.0 } else { c.clamp(0.0, 1.0) });
        if rgb[0] == rgb[1] && rgb[1] == rgb[2] {
            // sigmoid(c2) = r; ±infinity for 0 and 1, which the sigmoid maps to the constants.
            let r = rgb[0];
            return [0.0, 0.0, (r - 0.5) / (r * (1.0 - r)).sqrt()];
        }
        let res = RGB2SPEC_RES as usize;
        let l = if rgb[0] >= rgb[1] && rgb[0] >= rgb[2] {
            0
        } else if rgb[1] >= rgb[2] {
            1
        } else {
            2
        };
        let z = rgb[l];
        let scale = (res - 1) as f32 / z;
        let (x, y) = (rgb[(l + 1) % 3] * scale, rgb[(l + 2) % 3] * scale);
        let zi = self.node(z);
        let (xi, yi) = ((x as usize).min(res - 2), (y as usize).min(res - 2));
        let (dx, dy) = (x - xi as f32, y - yi as f32);
        let dz = (z - self.z_nodes[zi]) / (self.z_nodes[zi + 1] - self.z_nodes[zi]);
        let mut c = [0.0; 3];
        for (a, wz) in [(0, 1.0 - dz), (1, dz)] {
            for (b, wy) in [(0, 1.0 - dy), (1, dy)] {
                for (d, wx) in [(0, 1.0 - dx), (1, dx)] {
                    let i = (((l * res + zi + a) * res + yi + b) * res + xi + d) * 3;
                    for (k, ck) in c.iter_mut().enumerate() {
                        *ck += wz * wy * wx * self.coefficients[i + k];
                    }
                }
            }
        }
        c
    }

    /// The node of the z axis at or below z, as spectrum.glsl finds it: inverting the nodes' smoothstep(smoothstep),
    /// then one step either way against the stored nodes.
    fn node(&self, z: f32) -> usize {
        let res = RGB2SPEC_RES as usize;
        let inverse = |y: f32| 0.5 - ((1.0 - 2.0 * y).clamp(-1.0, 1.0).asin() / 3.0).sin();
        let mut zi = ((inverse(inverse(z)) * (res - 1) as f32).max(0.0) as usize).min(res - 2);
        if zi > 0 && z < self.z_nodes[zi] {
            zi -= 1;
        }
        if zi < res - 2 && z >= self.z_nodes[zi + 1] {
            zi += 1;
        }
        zi
    }

    /// The reflectance spectrum of an RGB (clamped to [0, 1]) at nm.
    pub fn reflectance(&self, rgb: [f32; 3], nm: f32) -> f32 {
        evaluate(self.coefficients(rgb), nm)
    }

    /// The emitted spectrum of an RGB radiance at nm: the RGB over twice its largest component upsampled, times
    /// that scale and the scaled D65 (pbrt-v4's RGBIlluminantSpectrum, Mitsuba 3's d65 emitters), so RGB (1, 1, 1)
    /// is D65 with Y = 1.
    pub fn emission(&self, rgb: [f32; 3], nm: f32) -> f32 {
        let scale = 2.0 * rgb[0].max(rgb[1]).max(rgb[2]);
        if scale.is_nan() || scale <= 0.0 {
            return 0.0;
        }
        scale * self.reflectance(rgb.map(|c| c / scale), nm) * self.illuminant(nm)
    }
}

/// A spectrum from its coefficients at nm.
pub fn evaluate(c: [f32; 3], nm: f32) -> f32 {
    let t = unit_wavelength(nm);
    fit::sigmoid(((c[0] * t + c[1]) * t + c[2]) as f64) as f32
}

fn sampling_range() -> (f64, f64) {
    (
        ((LAMBDA_MIN as f64 - C) * A).tanh(),
        ((LAMBDA_MAX as f64 - C) * A).tanh(),
    )
}

/// The density sample_visible draws wavelengths with, per nm; zero outside the range.
pub fn visible_pdf(nm: f32) -> f32 {
    if !(LAMBDA_MIN..=LAMBDA_MAX).contains(&nm) {
        return 0.0;
    }
    let (lo, hi) = sampling_range();
    let sech = 1.0 / (A * (nm as f64 - C)).cosh();
    (A * sech * sech / (hi - lo)) as f32
}

/// A wavelength from u in [0, 1), by inverting the CDF (tanh(A (λ − C)) − tanh(A (min − C))) / (hi − lo).
pub fn sample_visible(u: f32) -> f32 {
    let (lo, hi) = sampling_range();
    let nm = C + (lo + u as f64 * (hi - lo)).atanh() / A;
    (nm as f32).clamp(LAMBDA_MIN, LAMBDA_MAX)
}

/// A path's wavelengths from one u: the hero at u, the others at u + k / WAVELENGTHS (wrapped) of the sampling
/// CDF, so together they stratify it; and each one's density.
pub fn sample_wavelengths(u: f32) -> ([f32; WAVELENGTHS as usize], [f32; WAVELENGTHS as usize]) {
    let nm = std::array::from_fn(|k| {
        let v = u + k as f32 / WAVELENGTHS as f32;
        sample_visible(if v >= 1.0 { v - 1.0 } else { v })
    });
    (nm, nm.map(visible_pdf))
}
