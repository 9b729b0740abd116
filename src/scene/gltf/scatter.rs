//! KHR_materials_scatter and the older KHR_materials_volume_scatter: what scatters inside a volumetric object.
//!
//! Implemented revision: KhronosGroup/glTF pull request 2579 ("Add KHR_materials_scatter", Draft) at commit
//! 47d612d29754d2b7c02bcdd84064ab0a02b9487b (2026-07-02). Files of the superseded KHR_materials_volume_scatter are read
//! as pull request 2453 at 134d07661f461ee26d02e0e11b7ebe3e26f28330 defines it (no strength, colour black by default,
//! the albedo mapping without the anisotropy term); a material with both takes the newer.
//!
//! At that revision the README names the strength `scatterStrengthFactor`/`scatterStrengthTexture` and the schema
//! `scatterFactor`/`scatterTexture`: both are read, the README's first.
use super::{scene_err, Loader};
use crate::error::Error;
use crate::scene::{Medium, ThinScatter};
use glam::Vec3;
use gltf::json::Value;

pub(super) const SCATTER: &str = "KHR_materials_scatter";
pub(super) const VOLUME_SCATTER: &str = "KHR_materials_volume_scatter";

/// The extension's factors as the file gives them.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Factors {
    strength: f32,
    color: Vec3,
    anisotropy: f32,
    /// KHR_materials_volume_scatter: its albedo mapping has no anisotropy term.
    legacy: bool,
}

/// The single-scattering albedo rho_ss a medium needs for the multiple-scattering albedo rho_ms (what the colour
/// looks like after many bounces) with Henyey-Greenstein anisotropy g, by the fit KHR_materials_scatter gives:
/// s = 4.09712 + 4.20863 rho_ms - sqrt(9.59217 + 41.6808 rho_ms + 17.7126 rho_ms^2), rho_ss = (1 - s^2) / (1 - g s^2).
/// The fit leaves 6e-6 at rho_ms = 0, where the spec asks for a purely absorbing medium ("behaves exactly as if not
/// present"): 0 is 0. Clamped to [0, 1], since s is slightly negative at rho_ms = 1.
pub fn single_scatter_albedo(rho_ms: f32, g: f32) -> f32 {
    if rho_ms <= 0.0 {
        return 0.0;
    }
    let (r, g) = (rho_ms as f64, g as f64);
    let s = 4.09712 + 4.20863 * r - (9.59217 + 41.6808 * r + 17.7126 * r * r).sqrt();
    ((1.0 - s * s) / (1.0 - g * s * s)).clamp(0.0, 1.0) as f32
}

/// The strength's key as `ext` spells it: the README's `readme` when present, else the schema's `schema`.
fn spelled<'a>(ext: &Value, readme: &'a str, schema: &'a str) -> &'a str {
    if ext.get(readme).is_some() {
        readme
    } else {
        schema
    }
}

impl Loader<'_> {
    /// What KHR_materials_scatter (or the older name) makes of material `name`: the medium inside a volumetric one
    /// (none: absorption alone, KHR_materials_volume's), or the thin-walled mode's diffuse share of the transmission.
    /// Values outside the schema's ranges are refused naming the material and the property.
    pub(super) fn scatter(
        &mut self,
        name: &str,
        m: &gltf::Material,
        thin_walled: bool,
    ) -> Result<(Medium, ThinScatter), Error> {
        let none = (Medium::default(), ThinScatter::default());
        let (what, ext, legacy) = match (m.extension_value(SCATTER), m.extension_value(VOLUME_SCATTER)) {
            (Some(ext), _) => (SCATTER, ext, false),
            (None, Some(ext)) => (VOLUME_SCATTER, ext, true),
            (None, None) => return Ok(none),
        };
        let f = self.scatter_factors(name, what, ext, legacy)?;
        // Checked like every texture reference, so a broken one is refused as elsewhere. The strength's texture
        // has the README's name, or the schema's at the implemented revision.
        let strength_key = spelled(ext, "scatterStrengthTexture", "scatterTexture");
        let strength_texture = self.json_texture(name, what, ext, strength_key)?;
        let color_texture = self.json_texture(name, what, ext, "multiscatterColorTexture")?;
        if !thin_walled || legacy {
            for key in [strength_key, "multiscatterColorTexture"]
                .iter()
                .filter(|k| ext.get(**k).is_some())
            {
                self.warn(format!(
                    "material '{name}': {what}.{key} is not applied inside a volume (its factor is): a texture on \
                     the surface does not say which texel owns the medium behind it, and the draft warns that \
                     letting each texel decide breaks reciprocity"
                ));
            }
        }
        if thin_walled {
            // The old draft scatters only inside a volume.
            if legacy {
                self.warn(format!(
                    "material '{name}': {what} acts only inside a volume (KHR_materials_volume with thicknessFactor \
                     above 0): ignored on this thin-walled material"
                ));
                return Ok(none);
            }
            let thin = ThinScatter {
                strength: f.strength,
                color: f.color,
                anisotropy: f.anisotropy,
                strength_texture,
                color_texture,
            };
            return Ok((Medium::default(), thin));
        }
        let rho_ms = f.color * f.strength;
        let g_fit = if f.legacy { 0.0 } else { f.anisotropy };
        let albedo = Vec3::new(
            single_scatter_albedo(rho_ms.x, g_fit),
            single_scatter_albedo(rho_ms.y, g_fit),
            single_scatter_albedo(rho_ms.z, g_fit),
        );
        let medium = Medium {
            albedo,
            anisotropy: if albedo == Vec3::ZERO { 0.0 } else { f.anisotropy },
        };
        Ok((medium, ThinScatter::default()))
    }

    fn scatter_factors(&self, name: &str, what: &str, ext: &Value, legacy: bool) -> Result<Factors, Error> {
        let bad =
            |key: &str, range: &str| scene_err(self.path, format!("material '{name}': {what}.{key} is not {range}"));
        let number = |key: &str, default: f32, ok: &dyn Fn(f64) -> bool, range: &str| match ext.get(key) {
            None => Ok(default),
            Some(v) => v
                .as_f64()
                .filter(|x| x.is_finite() && ok(*x))
                .map(|x| x as f32)
                .ok_or_else(|| bad(key, range)),
        };
        let unit = |x: f64| (0.0..=1.0).contains(&x);
        // The old draft had no strength: scattering was always on, and a black colour (its default) turned it off.
        let strength = if legacy {
            1.0
        } else {
            let key = spelled(ext, "scatterStrengthFactor", "scatterFactor");
            number(key, 0.0, &unit, "a number in [0, 1]")?
        };
        let color_keys: &[&str] = if legacy {
            &["multiscatterColorFactor", "multiscatterColor", "scatterAlbedo"]
        } else {
            &["multiscatterColorFactor"]
        };
        let mut color = if legacy { Vec3::ZERO } else { Vec3::ONE };
        if let Some((key, v)) = color_keys.iter().find_map(|k| ext.get(*k).map(|v| (*k, v))) {
            let c = v
                .as_array()
                .filter(|a| a.len() == 3)
                .and_then(|a| {
                    a.iter()
                        .map(|x| x.as_f64().filter(|x| x.is_finite() && unit(*x)))
                        .collect::<Option<Vec<f64>>>()
                })
                .ok_or_else(|| bad(key, "three numbers in [0, 1]"))?;
            color = Vec3::new(c[0] as f32, c[1] as f32, c[2] as f32);
        }
        // g = +-1 is a delta phase function, outside the open interval both drafts name.
        let anisotropy = number(
            "scatterAnisotropy",
            0.0,
            &|x| x > -1.0 && x < 1.0,
            "a number in (-1, 1)",
        )?;
        Ok(Factors {
            strength,
            color,
            anisotropy,
            legacy,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::single_scatter_albedo;

    /// The fit's values, computed independently of this code from the formula in PR 2579's README (research notes of
    /// issue 38: rho_ms down the rows, g across). Would catch a sign of g turned, s^2 for s, or the g term dropped.
    #[test]
    fn the_albedo_fit_matches_values_computed_from_the_spec() {
        let g = [-0.9f32, -0.5, 0.0, 0.5, 0.9];
        let rows: [(f32, [f32; 5]); 5] = [
            (0.1, [0.247230, 0.293789, 0.384240, 0.555164, 0.861880]),
            (0.25, [0.543472, 0.601260, 0.693425, 0.818962, 0.957660]),
            (0.5, [0.844596, 0.873163, 0.911709, 0.953816, 0.990409]),
            (0.8, [0.982269, 0.985949, 0.990589, 0.995272, 0.999051]),
            (0.9, [0.996031, 0.996864, 0.997907, 0.998952, 0.999790]),
        ];
        for (rho_ms, want) in rows {
            for (g, want) in g.iter().zip(want) {
                let got = single_scatter_albedo(rho_ms, *g);
                assert!((got - want).abs() < 2e-6, "rho_ms {rho_ms} g {g}: {got} against {want}");
            }
        }
    }

    /// The spec's two ends: strength 0 is "exactly as if not present", white scatters without loss.
    #[test]
    fn no_colour_absorbs_and_white_scatters_everything() {
        for g in [-0.99, 0.0, 0.7] {
            assert_eq!(single_scatter_albedo(0.0, g), 0.0);
            assert_eq!(single_scatter_albedo(1.0, g), 1.0);
        }
    }
}
