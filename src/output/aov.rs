//! AOVs as image data: the ones a user can ask for (`Aov`), their EXR channels (`albedo.R`, `normal.X`, `depth.Z`,
//! ...) and the 8-bit pictures a PNG of one shows.
use super::srgb_encode;
use crate::render::Film;

/// An auxiliary image a render can write beside the beauty image.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Aov {
    /// The albedo of the first rough surface (through specular bounces), as Open Image Denoise defines it.
    Albedo,
    /// That surface's world-space shading normal.
    Normal,
    /// Distance along the camera ray to the first hit.
    Depth,
    /// World-space position of the first hit.
    Position,
    /// The variance of each pixel's mean, per channel.
    Variance,
    /// Samples each pixel holds.
    SampleCount,
    /// Index of the scene instance the first hit belongs to.
    InstanceId,
    /// Index of the first hit's material.
    MaterialId,
    /// The image before denoising (with --denoise).
    BeautyNoisy,
    /// Debug views, at each camera ray's first hit: the geometric normal (facing the ray),
    GeometricNormal,
    /// the shading normal,
    ShadingNormal,
    /// TEXCOORD_0,
    Uv,
    /// the BVH child boxes the camera ray tested,
    BvhCost,
    /// and the chance next-event estimation picks the light the ray found.
    LightPick,
}

impl Aov {
    pub const ALL: [Aov; 14] = [
        Aov::Albedo,
        Aov::Normal,
        Aov::Depth,
        Aov::Position,
        Aov::Variance,
        Aov::SampleCount,
        Aov::InstanceId,
        Aov::MaterialId,
        Aov::BeautyNoisy,
        Aov::GeometricNormal,
        Aov::ShadingNormal,
        Aov::Uv,
        Aov::BvhCost,
        Aov::LightPick,
    ];

    /// Its name on the command line, as an EXR layer and in a file of its own.
    pub fn name(self) -> &'static str {
        match self {
            Aov::Albedo => "albedo",
            Aov::Normal => "normal",
            Aov::Depth => "depth",
            Aov::Position => "position",
            Aov::Variance => "variance",
            Aov::SampleCount => "sample-count",
            Aov::InstanceId => "instance-id",
            Aov::MaterialId => "material-id",
            Aov::BeautyNoisy => "beauty-noisy",
            Aov::GeometricNormal => "geometric-normal",
            Aov::ShadingNormal => "shading-normal",
            Aov::Uv => "uv",
            Aov::BvhCost => "bvh-cost",
            Aov::LightPick => "light-pick",
        }
    }

    pub fn from_name(name: &str) -> Option<Aov> {
        Aov::ALL.into_iter().find(|a| a.name() == name)
    }

    /// Whether the render must survey it on the device (the others come from the film).
    pub fn surveyed(self) -> bool {
        !matches!(self, Aov::Variance | Aov::SampleCount | Aov::BeautyNoisy)
    }

    /// Whether it is a debug view (`RenderSettings::debug_aovs`).
    pub fn debug(self) -> bool {
        matches!(
            self,
            Aov::GeometricNormal | Aov::ShadingNormal | Aov::Uv | Aov::BvhCost | Aov::LightPick
        )
    }

    /// Its channels' names within its layer.
    fn channel_names(self) -> &'static [&'static str] {
        match self {
            Aov::Albedo | Aov::Variance | Aov::BeautyNoisy => &["R", "G", "B"],
            Aov::Normal | Aov::Position | Aov::GeometricNormal | Aov::ShadingNormal => &["X", "Y", "Z"],
            Aov::Uv => &["U", "V"],
            Aov::Depth => &["Z"],
            Aov::BvhCost | Aov::LightPick => &["Y"],
            Aov::SampleCount => &["N"],
            Aov::InstanceId | Aov::MaterialId => &["ID"],
        }
    }
}

/// One channel's pixels, row 0 at the top.
#[derive(Clone, Debug, PartialEq)]
pub enum Samples {
    F32(Vec<f32>),
    U32(Vec<u32>),
}

/// A named EXR channel.
#[derive(Clone, Debug, PartialEq)]
pub struct Channel {
    pub name: String,
    pub samples: Samples,
}

/// What an AOV's images are made from: the film (with its surveyed AOVs when the render asked for them) and, for
/// `beauty-noisy`, the image before denoising.
pub struct AovSource<'a> {
    pub film: &'a Film,
    pub noisy: Option<&'a [[f32; 3]]>,
}

impl AovSource<'_> {
    /// The AOV's channels, named `{layer}.{channel}` when `layered` (beside a beauty image) and by the channel alone
    /// otherwise (a file of its own). Ids are u32 (u32::MAX where nothing was hit), the sample count u32, the rest
    /// f32. None when the film lacks what it needs (AOVs not surveyed, or no noisy image).
    pub fn channels(&self, aov: Aov, layered: bool) -> Option<Vec<Channel>> {
        let names = aov.channel_names();
        let name = |c: usize| match layered {
            true => format!("{}.{}", aov.name(), names[c]),
            false => names[c].to_string(),
        };
        let split3 = |v: Vec<[f32; 3]>| -> Vec<Channel> {
            (0..3)
                .map(|c| Channel {
                    name: name(c),
                    samples: Samples::F32(v.iter().map(|p| p[c]).collect()),
                })
                .collect()
        };
        let ids = |v: Vec<Option<u32>>| {
            vec![Channel {
                name: name(0),
                samples: Samples::U32(v.iter().map(|i| i.unwrap_or(u32::MAX)).collect()),
            }]
        };
        let scalar = |v: Vec<f32>| {
            vec![Channel {
                name: name(0),
                samples: Samples::F32(v),
            }]
        };
        let aovs = self.film.aovs.as_ref();
        Some(match aov {
            Aov::GeometricNormal => split3(aovs?.geometric_normal()?),
            Aov::ShadingNormal => split3(aovs?.shading_normal()?),
            Aov::Uv => {
                let uv = aovs?.uv()?;
                (0..2)
                    .map(|c| Channel {
                        name: name(c),
                        samples: Samples::F32(uv.iter().map(|p| p[c]).collect()),
                    })
                    .collect()
            }
            Aov::BvhCost => scalar(aovs?.bvh_cost()?),
            Aov::LightPick => scalar(aovs?.light_pick()?),
            Aov::Albedo => split3(aovs?.albedo()),
            Aov::Normal => split3(aovs?.normal()),
            Aov::Position => split3(aovs?.position()),
            Aov::Depth => vec![Channel {
                name: name(0),
                samples: Samples::F32(aovs?.depth()),
            }],
            Aov::InstanceId => ids(aovs?.instance_id()),
            Aov::MaterialId => ids(aovs?.material_id()),
            Aov::Variance => split3(self.film.mean_variance()),
            Aov::SampleCount => vec![Channel {
                name: name(0),
                samples: Samples::U32(self.film.sample_count()),
            }],
            Aov::BeautyNoisy => split3(self.noisy?.to_vec()),
        })
    }

    /// The AOV as an 8-bit picture for a PNG: albedo and the noisy image in sRGB (with `exposure` for the latter),
    /// normals as n / 2 + 1/2, depth from white (nearest) to black (farthest, and nothing hit), positions over the
    /// box of the hits, the variance as the sRGB of its square root, the sample count as grey over the most any
    /// pixel has, ids as a colour per id (black for nothing hit).
    pub fn picture(&self, aov: Aov, exposure: f32) -> Option<Vec<[u8; 3]>> {
        let byte = |x: f32| (x.clamp(0.0, 1.0) * 255.0 + 0.5) as u8;
        let srgb = |v: Vec<[f32; 3]>, scale: f32| v.iter().map(|p| p.map(|c| byte(srgb_encode(c * scale)))).collect();
        let aovs = self.film.aovs.as_ref();
        Some(match aov {
            Aov::Albedo => srgb(aovs?.albedo(), 1.0),
            Aov::BeautyNoisy => srgb(self.noisy?.to_vec(), 2f32.powf(exposure)),
            Aov::Variance => srgb(
                self.film.mean_variance().iter().map(|v| v.map(f32::sqrt)).collect(),
                1.0,
            ),
            Aov::Normal => aovs?.normal().iter().map(|n| n.map(|c| byte(c * 0.5 + 0.5))).collect(),
            Aov::GeometricNormal => (aovs?.geometric_normal()?.iter())
                .map(|n| n.map(|c| byte(c * 0.5 + 0.5)))
                .collect(),
            Aov::ShadingNormal => (aovs?.shading_normal()?.iter())
                .map(|n| n.map(|c| byte(c * 0.5 + 0.5)))
                .collect(),
            // The fractional parts, so a repeating texture's tiles show.
            Aov::Uv => (aovs?.uv()?.iter())
                .map(|t| [byte(t[0].rem_euclid(1.0)), byte(t[1].rem_euclid(1.0)), 0])
                .collect(),
            Aov::BvhCost => aovs?.bvh_cost()?.into_iter().map(cost_colour).collect(),
            Aov::LightPick => (aovs?.light_pick()?.into_iter())
                .map(|p| [byte(srgb_encode(p)); 3])
                .collect(),
            Aov::Depth => {
                let depth = aovs?.depth();
                let (lo, hi) = finite_range(depth.iter().copied());
                let grey = |d: f32| match d.is_finite() {
                    true => byte(1.0 - (d - lo) / (hi - lo).max(f32::MIN_POSITIVE)),
                    false => 0,
                };
                depth.iter().map(|&d| [grey(d); 3]).collect()
            }
            Aov::Position => {
                let a = aovs?;
                let (pos, depth) = (a.position(), a.depth());
                let ranges: [(f32, f32); 3] = std::array::from_fn(|c| {
                    finite_range(pos.iter().zip(&depth).filter(|(_, d)| d.is_finite()).map(|(p, _)| p[c]))
                });
                (pos.iter().zip(&depth))
                    .map(|(p, d)| match d.is_finite() {
                        true => std::array::from_fn(|c| {
                            let (lo, hi) = ranges[c];
                            byte((p[c] - lo) / (hi - lo).max(f32::MIN_POSITIVE))
                        }),
                        false => [0; 3],
                    })
                    .collect()
            }
            Aov::SampleCount => {
                let counts = self.film.sample_count();
                let most = counts.iter().copied().max().unwrap_or(0).max(1) as f32;
                counts.iter().map(|&n| [byte(n as f32 / most); 3]).collect()
            }
            Aov::InstanceId => aovs?.instance_id().into_iter().map(id_colour).collect(),
            Aov::MaterialId => aovs?.material_id().into_iter().map(id_colour).collect(),
        })
    }
}

/// Child boxes tested as false colour, blue (none) through green to red (BVH_COST_SCALE or more), as the bvh-cost
/// example shader draws them.
fn cost_colour(boxes: f32) -> [u8; 3] {
    const BVH_COST_SCALE: f32 = 128.0;
    let t = (boxes / BVH_COST_SCALE).clamp(0.0, 1.0);
    let (r, g, b) = match t < 0.5 {
        true => (0.0, 2.0 * t, 1.0 - 2.0 * t),
        false => (2.0 * t - 1.0, 2.0 - 2.0 * t, 0.0),
    };
    [r, g, b].map(|c| (c * 255.0 + 0.5) as u8)
}

/// The smallest and largest finite values (0, 1 when there are none).
fn finite_range(values: impl Iterator<Item = f32>) -> (f32, f32) {
    let (lo, hi) = values
        .filter(|v| v.is_finite())
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), v| (lo.min(v), hi.max(v)));
    if lo <= hi {
        (lo, hi)
    } else {
        (0.0, 1.0)
    }
}

/// A bright colour per id, the same in every image (a hash of the id), black for none.
fn id_colour(id: Option<u32>) -> [u8; 3] {
    let Some(id) = id else { return [0; 3] };
    let h = (id as u64 + 1).wrapping_mul(0x9E37_79B9_7F4A_7C15);
    let h = h ^ (h >> 29);
    [(h >> 8) as u8 | 0x40, (h >> 24) as u8 | 0x40, (h >> 40) as u8 | 0x40]
}

/// `path` with `.{aov}` before its extension: `out.png` and albedo give `out.albedo.png`.
pub fn aov_path(path: &std::path::Path, aov: Aov) -> std::path::PathBuf {
    let stem = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    let ext = path.extension().map(|e| e.to_string_lossy().into_owned());
    let name = match ext {
        Some(e) => format!("{stem}.{}.{e}", aov.name()),
        None => format!("{stem}.{}", aov.name()),
    };
    path.with_file_name(name)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_and_paths_take_the_aov_before_the_extension() {
        for a in Aov::ALL {
            assert_eq!(Aov::from_name(a.name()), Some(a));
        }
        let p = aov_path(std::path::Path::new("renders/out.0007.exr"), Aov::SampleCount);
        assert_eq!(p, std::path::Path::new("renders/out.0007.sample-count.exr"));
    }

    #[test]
    fn id_colours_are_stable_and_distinct() {
        let colours: std::collections::HashSet<[u8; 3]> = (0..256).map(|i| id_colour(Some(i))).collect();
        assert!(colours.len() > 250);
        assert_eq!(id_colour(None), [0; 3]);
        assert_eq!(id_colour(Some(7)), id_colour(Some(7)));
    }
}
