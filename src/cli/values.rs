//! The CLI's value parsers: every number an option takes is checked here (finite, in range) so clap's error names
//! the option; the bounds and why they are where they are.
use crate::scene::RADIANCE_MAX;

/// Samples per pixel: the film counts samples in f32 (its w channel), exact up to 2^24; and SAMPLE_RADIANCE_MAX
/// is chosen so 2^24 squared samples at the limit still sum to a finite f32.
pub const SPP_LIMIT: u32 = 1 << 24;
/// Image side and pixel count: 2^26 pixels (8192x8192) is a 2 GiB film and ~3 GB of host copies to write it,
/// beyond which a render is a mistake rather than a request.
pub const SIDE_LIMIT: u32 = 65536;
pub const PIXELS_LIMIT: u64 = 1 << 26;
/// Scene units for the lens: beyond 1e18 the thin-lens ray arithmetic (aperture times a disk sample, focus
/// distance times a direction, squared in the normalisation) leaves f32.
const LENGTH_LIMIT: f32 = 1e18;

pub fn positive(s: &str) -> Result<u32, String> {
    match s.parse::<i64>() {
        Ok(n) if n >= 1 && n <= u32::MAX as i64 => Ok(n as u32),
        Ok(n) => Err(format!("{n} is not a positive number")),
        Err(_) => Err(format!("'{s}' is not a number")),
    }
}

fn at_most(s: &str, limit: u32) -> Result<u32, String> {
    let n = positive(s)?;
    if n > limit {
        return Err(format!("{n} is above the limit of {limit}"));
    }
    Ok(n)
}

pub fn parse_spp(s: &str) -> Result<u32, String> {
    at_most(s, SPP_LIMIT)
}

/// Any u32: the wavefront records bounces in batches and stops when no path is left, so a deep cap costs nothing
/// beyond the bounces paths really take (tests/bounds.rs).
pub fn parse_max_depth(s: &str) -> Result<u32, String> {
    match s.trim().parse::<i64>() {
        Ok(n) if (0..=u32::MAX as i64).contains(&n) => Ok(n as u32),
        Ok(n) => Err(format!("{n} is not a number of bounces (0 to {})", u32::MAX)),
        Err(_) => Err(format!("'{s}' is not a number")),
    }
}

/// A finite number within [lo, hi] (lo excluded when `open_lo`).
fn number(s: &str, lo: f32, hi: f32, open_lo: bool) -> Result<f32, String> {
    let v: f32 = s.trim().parse().map_err(|_| format!("'{s}' is not a number"))?;
    let below = if open_lo { v <= lo } else { v < lo };
    if !v.is_finite() || below || v > hi {
        let lo_bracket = if open_lo { "(" } else { "[" };
        let hi = if hi >= 1e6 { format!("{hi:e}") } else { hi.to_string() };
        return Err(format!("{s} is not a finite number in {lo_bracket}{lo}, {hi}]"));
    }
    Ok(v)
}

pub fn parse_exposure(s: &str) -> Result<f32, String> {
    // 2^64 times any radiance the film holds stays finite; a PNG is black or white long before.
    number(s, -64.0, 64.0, false)
}

pub fn parse_rotation(s: &str) -> Result<f32, String> {
    number(s, -360.0, 360.0, false)
}

pub fn parse_intensity(s: &str) -> Result<f32, String> {
    number(s, 0.0, RADIANCE_MAX, false)
}

pub fn parse_aperture(s: &str) -> Result<f32, String> {
    number(s, 0.0, LENGTH_LIMIT, false)
}

pub fn parse_focus_distance(s: &str) -> Result<f32, String> {
    number(s, 0.0, LENGTH_LIMIT, true)
}

/// Three finite numbers X,Y,Z each within `limit` in magnitude.
fn triple(s: &str, limit: f32, what: &str) -> Result<[f32; 3], String> {
    let parts: Vec<&str> = s.split(',').collect();
    let values: Vec<f32> = parts.iter().filter_map(|p| p.trim().parse::<f32>().ok()).collect();
    match values[..] {
        [x, y, z] if parts.len() == 3 && values.iter().all(|v| v.is_finite() && v.abs() <= limit) => Ok([x, y, z]),
        _ => Err(format!("'{s}' is not {what}")),
    }
}

/// A point for --eye and --target: scene units within LENGTH_LIMIT, as the lens's lengths.
pub fn parse_point(s: &str) -> Result<[f32; 3], String> {
    triple(s, LENGTH_LIMIT, "a point X,Y,Z of three finite numbers (e.g. 0,1,5)")
}

/// --up: any direction but zero; only its direction counts.
pub fn parse_up(s: &str) -> Result<[f32; 3], String> {
    let v = triple(
        s,
        LENGTH_LIMIT,
        "a direction X,Y,Z of three finite numbers (e.g. 0,1,0)",
    )?;
    if v.iter().all(|c| *c == 0.0) {
        return Err(format!("'{s}' has no direction"));
    }
    Ok(v)
}

/// --yfov in degrees, strictly between 0 and 180 (a perspective camera's range); parsed as f64 so a file's yfov
/// in radians, printed in degrees to 17 digits, comes back as the same f32.
pub fn parse_yfov(s: &str) -> Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(v) if v.is_finite() && v > 0.0 && v < 180.0 => Ok(v),
        _ => Err(format!("{s} is not a field of view in degrees, in (0, 180)")),
    }
}

/// --orbit AZIMUTH,ELEVATION,DISTANCE: azimuth in [-360, 360] degrees, elevation in (-90, 90) (straight up or
/// down has no image direction with +y up), distance in (0, LENGTH_LIMIT].
pub fn parse_orbit(s: &str) -> Result<[f32; 3], String> {
    let [az, el, d] = triple(
        s,
        LENGTH_LIMIT,
        "AZIMUTH,ELEVATION,DISTANCE (degrees, degrees, scene units; e.g. 45,30,5)",
    )?;
    if az.abs() > 360.0 {
        return Err(format!("'{s}': the azimuth {az} is not within -360 to 360 degrees"));
    }
    if el.abs() >= 90.0 {
        return Err(format!(
            "'{s}': the elevation {el} is not strictly between -90 and 90 degrees"
        ));
    }
    if d <= 0.0 {
        return Err(format!("'{s}': the distance {d} is not positive"));
    }
    Ok([az, el, d])
}

pub fn parse_rgb(s: &str) -> Result<[f32; 3], String> {
    let parts: Vec<&str> = s.split(',').collect();
    let values: Vec<f32> = parts.iter().filter_map(|p| p.trim().parse::<f32>().ok()).collect();
    match values[..] {
        [r, g, b] if parts.len() == 3 && values.iter().all(|v| v.is_finite() && *v >= 0.0) => {
            if values.iter().any(|v| *v > RADIANCE_MAX) {
                return Err(format!(
                    "'{s}' is above the radiance limit of {RADIANCE_MAX:e} per channel"
                ));
            }
            Ok([r, g, b])
        }
        _ => Err(format!("'{s}' is not three non-negative numbers R,G,B (e.g. 1,1,1)")),
    }
}

pub fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| format!("'{s}' is not WIDTHxHEIGHT (e.g. 640x480)"))?;
    let w = at_most(w, SIDE_LIMIT).map_err(|e| format!("width: {e}"))?;
    let h = at_most(h, SIDE_LIMIT).map_err(|e| format!("height: {e}"))?;
    if w as u64 * h as u64 > PIXELS_LIMIT {
        return Err(format!("{w}x{h} is above the limit of {PIXELS_LIMIT} pixels"));
    }
    Ok((w, h))
}

/// Seconds into the animation, within a year either way (keys outside the animation clamp to its ends anyway).
pub fn parse_time(s: &str) -> Result<f32, String> {
    number(s, -3.2e7, 3.2e7, false)
}

/// Frames per second: positive and at most a million.
pub fn parse_fps(s: &str) -> Result<f32, String> {
    number(s, 0.0, 1e6, true)
}

/// `FIRST..LAST`, inclusive, or a single frame `N`; at most a million frames, the numbers within u32.
pub fn parse_frames(s: &str) -> Result<(u32, u32), String> {
    let bad = || format!("'{s}' is not FIRST..LAST (e.g. 0..47) or one frame number");
    let (a, b) = match s.split_once("..") {
        Some((a, b)) => (a, b),
        None => (s, s),
    };
    let first: u32 = a.trim().parse().map_err(|_| bad())?;
    let last: u32 = b.trim().parse().map_err(|_| bad())?;
    if first > last {
        return Err(format!("'{s}': the first frame comes after the last"));
    }
    if last - first >= 1_000_000 {
        return Err(format!("'{s}' is more than a million frames"));
    }
    Ok((first, last))
}

/// Seconds the shutter is open: 0 (an instant) to an hour.
pub fn parse_shutter(s: &str) -> Result<f32, String> {
    number(s, 0.0, 3600.0, false)
}

/// `A..B`: sample indices A to B-1 of every pixel, at most SPP_LIMIT of them, B within u32.
pub fn parse_samples(s: &str) -> Result<(u32, u32), String> {
    let bad = || format!("'{s}' is not A..B (sample indices A to B-1, e.g. 0..64)");
    let (a, b) = s.split_once("..").ok_or_else(bad)?;
    let first: u32 = a.trim().parse().map_err(|_| bad())?;
    let end: u32 = b.trim().parse().map_err(|_| bad())?;
    if first >= end {
        return Err(format!("'{s}' holds no sample: A must be below B"));
    }
    if end - first > SPP_LIMIT {
        return Err(format!("'{s}' is more than {SPP_LIMIT} samples per pixel"));
    }
    Ok((first, end))
}

/// Which of N parts a render is: `I/N` with I from 0 to N-1, or `auto/N`, I then being the scheduler's array index.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Part {
    /// None: `auto`, read from the environment when the render starts (`Part::index`).
    pub index: Option<u32>,
    pub count: u32,
}

/// The variables job arrays number their tasks by, from 0: Slurm, Kubernetes Indexed Jobs, AWS Batch.
pub const ARRAY_INDEX_VARIABLES: [&str; 3] = [
    "SLURM_ARRAY_TASK_ID",
    "JOB_COMPLETION_INDEX",
    "AWS_BATCH_JOB_ARRAY_INDEX",
];

pub fn parse_part(s: &str) -> Result<Part, String> {
    let bad = || format!("'{s}' is not I/N (e.g. 0/4) or auto/N");
    let (i, n) = s.split_once('/').ok_or_else(bad)?;
    let count = positive(n.trim()).map_err(|e| format!("'{s}': N: {e}"))?;
    if count > 1_000_000 {
        return Err(format!("'{s}': more than a million parts"));
    }
    let index = match i.trim() {
        "auto" => None,
        i => Some(i.parse::<u32>().map_err(|_| bad())?),
    };
    if index.is_some_and(|i| i >= count) {
        return Err(format!("'{s}': parts count from 0, so I must be below N"));
    }
    Ok(Part { index, count })
}

impl Part {
    /// The part's index: given, or the first job-array variable set (checked like a given one).
    pub fn index(&self) -> Result<u32, String> {
        if let Some(i) = self.index {
            return Ok(i);
        }
        let (name, value) = (ARRAY_INDEX_VARIABLES.iter())
            .find_map(|v| std::env::var(v).ok().map(|value| (*v, value)))
            .ok_or_else(|| {
                format!(
                    "--part auto/{}: none of {} is set; give the index as --part I/{}",
                    self.count,
                    ARRAY_INDEX_VARIABLES.join(", "),
                    self.count
                )
            })?;
        match value.trim().parse::<u32>() {
            Ok(i) if i < self.count => Ok(i),
            _ => Err(format!(
                "--part auto/{}: {name}={value} is not an index from 0 to {}",
                self.count,
                self.count - 1
            )),
        }
    }

    /// The part's share of `total` items (samples or frames): contiguous, in order, sizes differing by at most one.
    pub fn range(index: u32, count: u32, total: u64) -> std::ops::Range<u64> {
        let at = |k: u64| k * total / count as u64;
        at(index as u64)..at(index as u64 + 1)
    }
}

/// A false-positive rate: above 0 and at most 0.5.
pub fn parse_alpha(s: &str) -> Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(a) if a > 0.0 && a <= 0.5 => Ok(a),
        _ => Err(format!("'{s}' is not a probability above 0 and at most 0.5")),
    }
}

/// A non-negative finite threshold.
pub fn parse_threshold(s: &str) -> Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(t) if t.is_finite() && t >= 0.0 => Ok(t),
        _ => Err(format!("'{s}' is not a finite number of at least 0")),
    }
}

/// `--aov`'s list (one value to clap, which would take a Vec for repeats).
#[derive(Clone, Debug)]
pub struct AovList(pub Vec<crate::output::Aov>);

/// `--aov albedo,normal,...`: AOV names, each once.
pub fn parse_aovs(s: &str) -> Result<AovList, String> {
    use crate::output::Aov;
    let mut list = Vec::new();
    for name in s.split(',').map(str::trim) {
        let aov = Aov::from_name(name).ok_or_else(|| {
            let known: Vec<&str> = Aov::ALL.iter().map(|a| a.name()).collect();
            format!("'{name}' is no AOV; the AOVs are {}", known.join(", "))
        })?;
        if list.contains(&aov) {
            return Err(format!("'{name}' is named twice"));
        }
        list.push(aov);
    }
    Ok(AovList(list))
}

/// --noise-threshold: a relative standard error, above 0 (nothing would ever stop) and at most 1 (a mean as
/// uncertain as itself).
pub fn parse_noise_threshold(s: &str) -> Result<f32, String> {
    match s.trim().parse::<f32>() {
        Ok(t) if t.is_finite() && t > 0.0 && t <= 1.0 => Ok(t),
        Ok(t) => Err(format!("{t} is not within (0, 1]")),
        Err(_) => Err(format!("'{s}' is not a number")),
    }
}

/// --min-spp: the pilot every pixel takes; two at least, for a variance.
pub fn parse_min_spp(s: &str) -> Result<u32, String> {
    let n = at_most(s, SPP_LIMIT)?;
    if n < 2 {
        return Err("the pilot needs at least 2 samples (a variance)".into());
    }
    Ok(n)
}

/// `view --show`: one AOV the viewer can show (not those that need a film's statistics or a denoise).
pub fn parse_view_aov(s: &str) -> Result<crate::output::Aov, String> {
    use crate::output::Aov;
    let AovList(list) = parse_aovs(s)?;
    match list[..] {
        [a] if a.surveyed() => Ok(a),
        _ => {
            let known: Vec<&str> = Aov::ALL.iter().filter(|a| a.surveyed()).map(|a| a.name()).collect();
            Err(format!("'{s}': the viewer shows one of {}", known.join(", ")))
        }
    }
}
