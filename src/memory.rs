//! The host memory budget: its default, `--max-memory`'s sizes (8G, 512M), and what a triangle, pixel, key and
//! emitter cost; the scene's own estimates against it live in `scene/budget.rs` and `scene/gltf/estimate.rs`.

/// Host bytes a flattened triangle costs from the soup to the packed scene (world-space soup, BVH build, packed
/// arrays, light table): 330 measured on 2.5 M emissive triangles (`pathwave info`), rounded up.
pub const HOST_BYTES_PER_TRIANGLE: u64 = 400;
/// Host bytes an image pixel takes while it decodes (a 16-bit RGBA buffer, its RGBA8 conversion, the texels kept) and
/// once decoded (the texels, and their copy in the packed scene with the mip chain, a third more: 4 + 16 / 3, rounded
/// up): what `--max-memory` must leave room for, checked from each image's header before it is decoded.
pub const HOST_BYTES_PER_PIXEL_DECODING: u64 = 16;
pub const HOST_BYTES_PER_PIXEL_KEPT: u64 = 10;
/// And per later key of the motion over the shutter: its placed vertices and normals (72 bytes) and its device
/// record (96), rounded up.
pub const HOST_BYTES_PER_MOTION_KEY: u64 = 176;
/// And per emissive triangle, for the light BVH: its emitter record with bounds (72 bytes, 16 of which the light
/// table had before), the build's copy of them (56 and 68) and two tree nodes (128), rounded up.
pub const HOST_BYTES_PER_EMITTER: u64 = 320;

/// The budget when none is given: half of MemAvailable, at most 8 GiB (8 GiB when /proc/meminfo cannot be read).
pub fn default_max_memory() -> u64 {
    let cap = 8 << 30;
    let available = std::fs::read_to_string("/proc/meminfo").ok().and_then(|m| {
        let line = m.lines().find(|l| l.starts_with("MemAvailable:"))?;
        let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
        Some(kb.saturating_mul(1024))
    });
    available.map_or(cap, |a| (a / 2).min(cap))
}

/// A size in bytes with an optional binary suffix: 1073741824, 512M, 8G, 1T (K, M, G, T; a trailing B or iB is
/// allowed).
pub fn parse_size(s: &str) -> Result<u64, String> {
    let t = s.trim();
    let t = t.strip_suffix("iB").or_else(|| t.strip_suffix('B')).unwrap_or(t);
    let (digits, shift) = match t.chars().last().map(|c| c.to_ascii_uppercase()) {
        Some('K') => (&t[..t.len() - 1], 10),
        Some('M') => (&t[..t.len() - 1], 20),
        Some('G') => (&t[..t.len() - 1], 30),
        Some('T') => (&t[..t.len() - 1], 40),
        _ => (t, 0),
    };
    let n: u64 = digits
        .trim()
        .parse()
        .map_err(|_| format!("'{s}' is not a size in bytes (e.g. 8G, 512M, 1073741824)"))?;
    match n.checked_mul(1 << shift) {
        Some(0) => Err(format!("'{s}': the budget must be above 0")),
        Some(b) => Ok(b),
        None => Err(format!("'{s}' is too large")),
    }
}

/// A byte count for messages: 41.5 GiB.
pub fn human(bytes: u64) -> String {
    const UNITS: [&str; 5] = ["B", "KiB", "MiB", "GiB", "TiB"];
    let mut v = bytes as f64;
    let mut unit = 0;
    while v >= 1024.0 && unit + 1 < UNITS.len() {
        v /= 1024.0;
        unit += 1;
    }
    format!("{v:.1} {}", UNITS[unit])
}

#[cfg(test)]
mod tests {
    use super::parse_size;

    #[test]
    fn sizes_take_binary_suffixes_and_refuse_junk() {
        assert_eq!(parse_size("8G"), Ok(8 << 30));
        assert_eq!(parse_size("512m"), Ok(512 << 20));
        assert_eq!(parse_size("2GiB"), Ok(2 << 30));
        assert_eq!(parse_size("1000"), Ok(1000));
        for bad in ["", "G", "-1G", "1.5G", "0", "99999999999T", "8X"] {
            assert!(parse_size(bad).is_err(), "{bad}");
        }
    }
}
