//! Film files: EXR images that carry, beside the mean, the exact film's sums and what rendered them (the scene's,
//! frame's and shaders' fingerprints, the seed, the sample ranges), which `pathwave merge` and `pathwave diff` read.
use super::{output_err, Channel, Samples};
use crate::error::Error;
use crate::render::film::{ExactFilm, Wide};
use std::ops::Range;
use std::path::Path;

/// What the format's version is: a reader refuses a film file of another.
pub const FILM_FORMAT: &str = "pathwave film 1";
/// The EXR header attribute holding the metadata (one attribute: the exr crate writes several in hash order).
const META_ATTRIBUTE: &str = "pathwave";
const COUNT: &str = "pathwave.count";

/// `--part I/N` of `spp` samples per pixel: the I-th of N contiguous shares.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PartOf {
    pub index: u32,
    pub count: u32,
    pub spp: u32,
}

/// What made a film: parts merge only when everything but `samples` and `device` agrees.
#[derive(Clone, Debug, PartialEq)]
pub struct FilmMeta {
    /// BLAKE3 of the scene as packed for the device (geometry, BVH, materials, lights, textures, environment).
    pub scene: String,
    /// BLAKE3 of the frame every pass starts from: camera, image size, seed, depth, estimator, flags, environment.
    pub frame: String,
    /// BLAKE3 of the SPIR-V of every render stage (a --shader-dir or another pathwave build changes it).
    pub shaders: String,
    /// The options as given, for people and for naming what differs.
    pub settings: Vec<(String, String)>,
    pub seed: u32,
    pub samples: Vec<Range<u32>>,
    /// Which share of a `--part I/N` render this is, which lets `merge` name a missing part; None for a whole
    /// render or a merge.
    pub part: Option<PartOf>,
    /// Information only: parts rendered on different devices merge, but only one device's render gives their bits.
    pub device: String,
    pub version: String,
}

impl FilmMeta {
    fn to_json(&self) -> String {
        let settings: serde_json::Map<String, serde_json::Value> = (self.settings.iter())
            .map(|(k, v)| (k.clone(), serde_json::Value::String(v.clone())))
            .collect();
        let mut value = serde_json::json!({
            "format": FILM_FORMAT,
            "scene": self.scene,
            "frame": self.frame,
            "shaders": self.shaders,
            "settings": settings,
            "seed": self.seed,
            "samples": self.samples.iter().map(|r| [r.start, r.end]).collect::<Vec<_>>(),
            "device": self.device,
            "version": self.version,
            "sum_unit": format!("2^-{}", crate::constants::EXACT_SUM_BITS),
            "square_unit": format!("2^-{}", crate::constants::EXACT_SQUARE_BITS),
        });
        // Absent rather than null: a merge of every part writes the bytes of one render, which has no part.
        if let Some(p) = self.part {
            value["part"] = serde_json::json!([p.index, p.count, p.spp]);
        }
        ascii_only(&value.to_string())
    }

    fn from_json(text: &str) -> Result<FilmMeta, String> {
        let v: serde_json::Value = serde_json::from_str(text).map_err(|e| format!("its metadata is not JSON: {e}"))?;
        let format = v["format"].as_str().unwrap_or("none");
        if format != FILM_FORMAT {
            return Err(format!("its format is '{format}', not '{FILM_FORMAT}'"));
        }
        let text_of = |k: &str| {
            v[k].as_str()
                .map(str::to_string)
                .ok_or_else(|| format!("its metadata lacks '{k}'"))
        };
        let settings = (v["settings"].as_object())
            .ok_or("its metadata lacks 'settings'")?
            .iter()
            .map(|(k, v)| {
                Ok((
                    k.clone(),
                    v.as_str().ok_or(format!("setting '{k}' is not text"))?.to_string(),
                ))
            })
            .collect::<Result<Vec<_>, String>>()?;
        let samples = (v["samples"].as_array())
            .ok_or("its metadata lacks 'samples'")?
            .iter()
            .map(|r| match (r[0].as_u64(), r[1].as_u64()) {
                (Some(a), Some(b)) if a < b && b <= u32::MAX as u64 => Ok(a as u32..b as u32),
                _ => Err(format!("sample range {r} is not [first, end) with first < end")),
            })
            .collect::<Result<Vec<_>, String>>()?;
        let part = match &v["part"] {
            serde_json::Value::Null => None,
            p => match (p[0].as_u64(), p[1].as_u64(), p[2].as_u64()) {
                (Some(i), Some(n), Some(spp)) if i < n && n <= u32::MAX as u64 && spp <= u32::MAX as u64 => {
                    Some(PartOf {
                        index: i as u32,
                        count: n as u32,
                        spp: spp as u32,
                    })
                }
                _ => return Err(format!("part {p} is not [I, N, SPP] with I < N")),
            },
        };
        let seed = v["seed"]
            .as_u64()
            .filter(|&s| s <= u32::MAX as u64)
            .ok_or("its metadata lacks 'seed'")?;
        Ok(FilmMeta {
            scene: text_of("scene")?,
            frame: text_of("frame")?,
            shaders: text_of("shaders")?,
            settings,
            seed: seed as u32,
            samples,
            part,
            device: text_of("device")?,
            version: text_of("version")?,
        })
    }

    /// Why a film of `other` cannot be merged with one of `self`, naming the first thing that differs.
    pub fn incompatibility(&self, other: &FilmMeta) -> Option<String> {
        if self.seed != other.seed {
            return Some(format!("seed {} against {}", other.seed, self.seed));
        }
        for (k, v) in &self.settings {
            let theirs = other.settings.iter().find(|(ok, _)| ok == k).map(|(_, v)| v.as_str());
            if theirs != Some(v.as_str()) {
                return Some(format!("{k} {} against {v}", theirs.unwrap_or("(unset)")));
            }
        }
        if let Some((k, v)) = other
            .settings
            .iter()
            .find(|(k, _)| !self.settings.iter().any(|(sk, _)| sk == k))
        {
            return Some(format!("{k} {v} against (unset)"));
        }
        let hashes = [
            ("the scene", &self.scene, &other.scene),
            ("the camera or render settings", &self.frame, &other.frame),
            (
                "the shaders (another pathwave build or --shader-dir)",
                &self.shaders,
                &other.shaders,
            ),
        ];
        for (what, mine, theirs) in hashes {
            if mine != theirs {
                return Some(format!("{what}: fingerprint {} against {}", short(theirs), short(mine)));
            }
        }
        None
    }
}

fn short(hash: &str) -> &str {
    &hash[..hash.len().min(12)]
}

/// serde_json leaves non-ASCII characters as they are; EXR text is bytes, so they go as \u escapes.
fn ascii_only(json: &str) -> String {
    let mut out = String::with_capacity(json.len());
    for ch in json.chars() {
        if ch.is_ascii() {
            out.push(ch);
        } else {
            let mut units = [0u16; 2];
            for u in ch.encode_utf16(&mut units) {
                out.push_str(&format!("\\u{u:04x}"));
            }
        }
    }
    out
}

/// A film file read back: the mean, and the exact film and metadata when it carries them.
pub struct FilmFile {
    pub width: u32,
    pub height: u32,
    pub mean: Vec<[f32; 3]>,
    pub stats: Option<(ExactFilm, FilmMeta)>,
}

const CHANNELS: [&str; 3] = ["R", "G", "B"];

fn sum_word(k: usize, c: usize) -> String {
    format!("pathwave.sum{k}.{}", CHANNELS[c])
}

fn square_word(k: usize, c: usize) -> String {
    format!("pathwave.square{k}.{}", CHANNELS[c])
}

/// The EXR of a film with statistics: R, G, B the mean (what any EXR viewer shows); `pathwave.count`, and the
/// exact sums' 32-bit words (`pathwave.sum0.R` .. `pathwave.sum3.B`, `pathwave.square0.R` .. `pathwave.square4.B`,
/// least significant first) as u32 channels; the metadata as JSON in the header's `pathwave` attribute.
#[allow(clippy::too_many_arguments)]
pub(super) fn encode_film(
    file: &Path,
    path: &Path,
    width: u32,
    height: u32,
    rgb: &[[f32; 3]],
    film: &ExactFilm,
    meta: &FilmMeta,
    layers: &[Channel],
) -> Result<(), Error> {
    let mut list = super::rgb_channels(rgb, "");
    let words = |name: String, v: Vec<u32>| Channel {
        name,
        samples: Samples::U32(v),
    };
    list.push(words(COUNT.into(), film.count.clone()));
    for c in 0..3 {
        for k in 0..4 {
            list.push(words(
                sum_word(k, c),
                film.sum.iter().map(|s| (s[c] as u128 >> (32 * k)) as u32).collect(),
            ));
        }
        for k in 0..5 {
            let v = (film.sum_sq.iter())
                .map(|q| if k == 4 { q[c].hi } else { (q[c].lo >> (32 * k)) as u32 })
                .collect();
            list.push(words(square_word(k, c), v));
        }
    }
    list.extend_from_slice(layers);
    super::encode_channels(file, path, width, height, &list, Some((META_ATTRIBUTE, meta.to_json())))
}

/// Reads an EXR: its R, G, B (f32 or f16) and, when it is a pathwave film file, its exact sums and metadata. Any EXR
/// with RGB reads; one that claims to be a film file must be a whole one.
pub fn read_film(path: &Path) -> Result<FilmFile, Error> {
    use exr::prelude::*;
    let err = |message: String| output_err(path, message);
    super::check_declared_size(path)?;
    let image = read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes()
        .non_parallel()
        .from_file(path)
        .map_err(|e| err(format!("cannot read EXR: {e}")))?;
    let layer = &image.layer_data;
    let (width, height) = (layer.size.width(), layer.size.height());
    let pixels = width * height;
    let channel = |name: &str| layer.channel_data.list.iter().find(|c| c.name.eq(name));
    let floats = |name: &str| -> std::result::Result<Vec<f32>, crate::error::Error> {
        match channel(name).map(|c| &c.sample_data) {
            Some(FlatSamples::F32(v)) => Ok(v.clone()),
            Some(FlatSamples::F16(v)) => Ok(v.iter().map(|h| h.to_f32()).collect()),
            Some(FlatSamples::U32(_)) => Err(err(format!("channel {name} holds integers, not colour"))),
            None => Err(err(format!("no {name} channel: pathwave reads RGB images"))),
        }
    };
    let (r, g, b) = (floats("R")?, floats("G")?, floats("B")?);
    let mean: Vec<[f32; 3]> = (0..pixels).map(|i| [r[i], g[i], b[i]]).collect();
    let attribute = layer.attributes.other.get(&Text::from(META_ATTRIBUTE));
    let stats = match (attribute, channel(COUNT)) {
        (None, None) => None,
        (Some(AttributeValue::Text(text)), Some(_)) => Some(read_exact_film(
            path,
            &layer.channel_data.list,
            pixels,
            &text.to_string(),
        )?),
        _ => {
            return Err(err(
                "not a whole film file: its metadata or its count channel is missing".into(),
            ))
        }
    };
    Ok(FilmFile {
        width: width as u32,
        height: height as u32,
        mean,
        stats,
    })
}

/// The exact film and metadata of a film file: its metadata parsed from `meta_json`, its count and sums from the
/// u32 `channels`; an error when it is not a whole film file of `pixels` pixels.
fn read_exact_film(
    path: &Path,
    channels: &[exr::prelude::AnyChannel<exr::prelude::FlatSamples>],
    pixels: usize,
    meta_json: &str,
) -> Result<(ExactFilm, FilmMeta), Error> {
    use exr::prelude::FlatSamples;
    let err = |message: String| output_err(path, message);
    let channel = |name: &str| channels.iter().find(|c| c.name.eq(name));
    let meta = FilmMeta::from_json(meta_json).map_err(|e| err(format!("not a film file: {e}")))?;
    let words = |name: &str| -> std::result::Result<&Vec<u32>, crate::error::Error> {
        match channel(name).map(|c| &c.sample_data) {
            Some(FlatSamples::U32(v)) => Ok(v),
            _ => Err(err(format!(
                "not a whole film file: channel {name} is missing or not u32"
            ))),
        }
    };
    let mut exact = ExactFilm {
        samples: meta.samples.clone(),
        count: words(COUNT)?.clone(),
        sum: vec![[0; 3]; pixels],
        sum_sq: vec![[Wide::default(); 3]; pixels],
    };
    for c in 0..3 {
        for k in 0..4 {
            for (p, w) in words(&sum_word(k, c))?.iter().enumerate() {
                exact.sum[p][c] |= ((*w as u128) << (32 * k)) as i128;
            }
        }
        for k in 0..5 {
            for (p, w) in words(&square_word(k, c))?.iter().enumerate() {
                match k {
                    4 => exact.sum_sq[p][c].hi = *w,
                    _ => exact.sum_sq[p][c].lo |= (*w as u128) << (32 * k),
                }
            }
        }
    }
    let spp = exact.spp();
    if let Some(p) = exact.count.iter().position(|&n| n as u64 != spp) {
        return Err(err(format!(
            "not a whole film file: pixel {p} holds {} samples where its ranges hold {spp}",
            exact.count[p]
        )));
    }
    Ok((exact, meta))
}
