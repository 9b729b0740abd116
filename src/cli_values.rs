//! The CLI's value parsers: every number an option takes is checked here (finite, in range) so clap's error names
//! the option; the bounds and why they are where they are.
use pathwave::scene::RADIANCE_MAX;

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
