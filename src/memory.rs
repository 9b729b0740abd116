//! The host memory budget: its default, `--max-memory`'s sizes (8G, 512M), and refusing a file or scene that would
//! not fit, before it is read or placed.
use crate::error::Error;
use crate::scene::Scene;

/// Host bytes a flattened triangle costs from the soup to the packed scene (world-space soup, BVH build, packed
/// arrays, light table): 330 measured on 2.5 M emissive triangles (`pathwave info`), rounded up.
pub const HOST_BYTES_PER_TRIANGLE: u64 = 400;
/// Host bytes an image pixel takes while it decodes (a 16-bit RGBA buffer, its RGBA8 conversion, the texels kept) and
/// once decoded (the texels, and their copy in the packed scene): what `--max-memory` must leave room for, checked
/// from each image's header before it is decoded.
pub const HOST_BYTES_PER_PIXEL_DECODING: u64 = 16;
pub const HOST_BYTES_PER_PIXEL_KEPT: u64 = 8;
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

/// Host bytes reading a glTF document takes, from its JSON alone: its buffers as declared, and every primitive's
/// accessors, morph targets, keyframes and inverse bind matrices decoded (at most 16 bytes an element, a vec4 of
/// f32, 64 a matrix; indices twice, as read and as triangles).
pub fn load_estimate(doc: &gltf::Document) -> u64 {
    let buffers: u64 = doc.buffers().map(|b| b.length() as u64).fold(0, u64::saturating_add);
    let decoded = doc
        .meshes()
        .flat_map(|m| m.primitives())
        .flat_map(|p| {
            // Counts come from the file unchecked (the mutation test raises them to 2^63): saturate.
            let attributes = p
                .attributes()
                .map(|(_, a)| (a.count() as u64).saturating_mul(16))
                .collect::<Vec<_>>();
            let indices = p.indices().map(|i| (i.count() as u64).saturating_mul(8));
            let targets = (p.morph_targets())
                .flat_map(|t| [t.positions(), t.normals(), t.tangents()])
                .flatten()
                .map(|a| (a.count() as u64).saturating_mul(16))
                .collect::<Vec<_>>();
            attributes.into_iter().chain(indices).chain(targets)
        })
        .fold(0, u64::saturating_add);
    // Keyframes as floats (at most 16 bytes a key's element) and inverse bind matrices (64 bytes each).
    let keys = (doc.animations())
        .flat_map(|a| a.samplers())
        .map(|s| {
            (s.input().count() as u64)
                .saturating_add(s.output().count() as u64)
                .saturating_mul(16)
        })
        .fold(0, u64::saturating_add);
    let skins = (doc.skins())
        .filter_map(|s| s.inverse_bind_matrices())
        .map(|a| (a.count() as u64).saturating_mul(64))
        .fold(0, u64::saturating_add);
    buffers
        .saturating_add(decoded)
        .saturating_add(keys)
        .saturating_add(skins)
}

impl Scene {
    /// Triangles flattening would emit at most (every instance's mesh, degenerate ones included), without
    /// flattening: O(instances + primitives).
    pub fn flattened_triangle_bound(&self) -> u64 {
        self.flattened_triangle_bound_except(&vec![false; self.meshes.len()])
    }

    /// `flattened_triangle_bound` of every mesh but those `instanced` marks, which are stored once each.
    pub fn flattened_triangle_bound_except(&self, instanced: &[bool]) -> u64 {
        let per_mesh: Vec<u64> = self
            .meshes
            .iter()
            .map(|m| m.primitives.iter().map(|p| p.triangles.len() as u64).sum())
            .collect();
        let placed = (self.instances.iter())
            .map(|i| if instanced[i.mesh] { 0 } else { per_mesh[i.mesh] })
            .fold(0, u64::saturating_add);
        let stored = (per_mesh.iter().zip(instanced))
            .map(|(&n, &inst)| if inst { n } else { 0 })
            .fold(0, u64::saturating_add);
        placed.saturating_add(stored)
    }

    /// Emissive triangles the light BVH could hold at most: those of primitives whose material emits, placed once
    /// per instance, or stored once for an instanced mesh (which is one emitter per instance).
    fn emissive_triangle_bound(&self, instanced: &[bool]) -> u64 {
        let emissive = |m: &crate::scene::Mesh| -> u64 {
            (m.primitives.iter())
                .filter(|p| {
                    (self.materials.get(p.material as usize)).is_some_and(|mat| mat.emission.max_element() > 0.0)
                })
                .map(|p| p.triangles.len() as u64)
                .sum()
        };
        let per_mesh: Vec<u64> = self.meshes.iter().map(emissive).collect();
        (self.instances.iter())
            .map(|i| if instanced[i.mesh] { 1 } else { per_mesh[i.mesh] })
            .fold(0, u64::saturating_add)
            .saturating_add(
                (per_mesh.iter().zip(instanced))
                    .map(|(&n, &i)| if i { n } else { 0 })
                    .sum::<u64>(),
            )
    }

    /// Refuses a scene whose flattening and packing would need more than `limit` bytes of host memory, before any
    /// of it is allocated, when the renderer instances meshes by `rule`.
    pub fn check_host_memory(&self, limit: u64, rule: crate::scene::Instancing) -> Result<(), Error> {
        // Meshes the renderer instances are stored once.
        let instanced = self.instanced_meshes(rule);
        let triangles = self.flattened_triangle_bound_except(&instanced);
        // Motion keys are per flattened triangle: an instanced mesh moves by its instances' records.
        let stored = (self.meshes.iter().zip(&instanced))
            .filter(|(_, &i)| i)
            .map(|(m, _)| m.primitives.iter().map(|p| p.triangles.len() as u64).sum::<u64>())
            .fold(0, u64::saturating_add);
        let keys = self.motion.as_ref().map_or(0, |m| m.keys.len() as u64);
        let per_triangle = HOST_BYTES_PER_TRIANGLE + keys * HOST_BYTES_PER_MOTION_KEY;
        let need = (triangles - stored)
            .saturating_mul(per_triangle)
            .saturating_add(stored.saturating_mul(HOST_BYTES_PER_TRIANGLE))
            .saturating_add(
                self.emissive_triangle_bound(&instanced)
                    .saturating_mul(HOST_BYTES_PER_EMITTER),
            );
        if need <= limit {
            return Ok(());
        }
        Err(Error::Scene {
            path: self.path.clone(),
            message: format!(
                "rendering it would need about {} of host memory ({triangles} triangles once its {} instances are \
                 placed, about {per_triangle} bytes each), over the limit of {} (--max-memory)",
                human(need),
                self.instances.len(),
                human(limit)
            ),
        })
    }
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
