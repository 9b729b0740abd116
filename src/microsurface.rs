//! The random walk on a GGX microsurface (Heitz, Hanika, d'Eon and Dachsbacher 2016, "Multiple-Scattering Microfacet
//! BSDFs with the Smith Model"), reflection only: what a rough dielectric returns by bouncing more than once between
//! its microfacets, which single-scattering GGX loses. examples/dielectric_ms.rs tabulates it for the shaders
//! (data/dielectric_ms.bin); tests/bsdf/energy.rs holds the walk to the device's own single scattering and to reciprocity.
//!
//! The walk runs on the CPU in f64: it is the reference the table is made from, not a renderer path.
use crate::constants::{MS_RES_F0, MS_RES_MU, MS_RES_ROUGH};
use glam::DVec3;
use std::f64::consts::PI;

/// Splitmix64: a seed per walk group keeps the table the same on any number of threads.
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Self {
        Self(seed)
    }

    /// A uniform in [0, 1) with 53 random bits.
    pub fn uniform(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// Smith's Lambda of GGX for a direction pointing up (w.z > 0).
fn lambda(alpha: f64, w: DVec3) -> f64 {
    let t2 = (w.x * w.x + w.y * w.y) / (w.z * w.z).max(1e-300);
    0.5 * ((1.0 + alpha * alpha * t2).sqrt() - 1.0)
}

/// A microfacet normal seen from v, distributed as D(m) max(0, v.m): Dupuy and Benyoub 2023's spherical caps, which
/// hold for v anywhere on the sphere, as a walk needs (v points below the horizon after a downward bounce).
fn visible_normal(alpha: f64, v: DVec3, u1: f64, u2: f64) -> DVec3 {
    let vs = DVec3::new(v.x * alpha, v.y * alpha, v.z).normalize();
    let phi = 2.0 * PI * u1;
    let z = (1.0 - u2) * (1.0 + vs.z) - vs.z;
    let s = (1.0 - z * z).max(0.0).sqrt();
    let h = DVec3::new(s * phi.cos(), s * phi.sin(), z) + vs;
    DVec3::new(h.x * alpha, h.y * alpha, h.z).normalize()
}

/// Schlick's Fresnel with F90 = 1, as the shaders' dielectric layer reflects.
pub fn schlick(f0: f64) -> impl Fn(f64) -> f64 {
    move |c: f64| f0 + (1.0 - f0) * (1.0 - c).clamp(0.0, 1.0).powi(5)
}

/// The directional albedo of walks from cos theta `mu`, split by order: single scattering (one bounce) and multiple
/// (two or more), each a mean over `walks` walks with its standard error.
#[derive(Clone, Copy, Debug, Default)]
pub struct Albedo {
    pub single: f64,
    pub single_se: f64,
    pub multiple: f64,
    pub multiple_se: f64,
}

/// Walks that leave the surface after this many bounces are cut (their weight is below 1e-9 of what arrived for any
/// roughness the shaders use: the chance to stay falls by at least half a bounce).
const MAX_ORDER: u32 = 128;

/// One walk: light arrives along -wo's reverse (from direction wo, above), bounces on microfacets chosen by their
/// visibility, each reflecting `fresnel(cos)` of it, and leaves when the height it reaches is unshadowed. Escape is
/// taken as its expectation at each upward leg (the walk's weight goes on with what stays), so every walk
/// contributes to each order it reaches. `exit` receives (order, weight, direction) of each escaping share.
pub fn walk(alpha: f64, wo: DVec3, fresnel: &dyn Fn(f64) -> f64, rng: &mut Rng, exit: &mut dyn FnMut(u32, f64, DVec3)) {
    // The walk needs a height only through C1, the heights' distribution function at it (its albedo does not
    // depend on that distribution), so it carries C1 itself: 1 above the surface.
    let mut d = -wo;
    let mut c = 1.0;
    let mut weight = 1.0;
    for order in 1..=MAX_ORDER {
        // The next hit: a downward leg always meets the surface, an upward one does unless it escapes.
        let u = rng.uniform();
        if d.z < 0.0 {
            c *= (1.0 - u).powf(1.0 / (1.0 + lambda(alpha, -d)));
        } else {
            // The leg that escapes was counted when the bounce before it was made.
            let l = lambda(alpha, d);
            let escape = c.powf(l);
            let v = escape + (1.0 - escape) * (1.0 - u); // uniform over the legs that hit, (escape, 1]
            c /= v.powf(1.0 / l);
        }
        c = c.clamp(0.0, 1.0);
        let m = visible_normal(alpha, -d, rng.uniform(), rng.uniform());
        let cos = (-d).dot(m);
        if cos <= 0.0 {
            return;
        }
        weight *= fresnel(cos);
        d = (d - 2.0 * d.dot(m) * m).normalize();
        if d.z > 0.0 {
            let escape = if d.z >= 1.0 { 1.0 } else { c.powf(lambda(alpha, d)) };
            exit(order, weight * escape, d);
            weight *= 1.0 - escape;
        }
        if weight < 1e-12 {
            return;
        }
    }
}

/// The single- and multiple-scattering albedo from cos theta `mu` (wo in the xz plane) over `walks` walks.
pub fn albedo(mu: f64, alpha: f64, fresnel: &dyn Fn(f64) -> f64, walks: usize, seed: u64) -> Albedo {
    let wo = DVec3::new((1.0 - mu * mu).max(0.0).sqrt(), 0.0, mu);
    let mut rng = Rng::new(seed);
    let (mut s, mut s2, mut m, mut m2) = (0.0, 0.0, 0.0, 0.0);
    for _ in 0..walks {
        let (mut single, mut multiple) = (0.0, 0.0);
        walk(alpha, wo, fresnel, &mut rng, &mut |order, w, _| {
            if order == 1 {
                single += w;
            } else {
                multiple += w;
            }
        });
        s += single;
        s2 += single * single;
        m += multiple;
        m2 += multiple * multiple;
    }
    let n = walks as f64;
    let se = |sum: f64, sq: f64| ((sq / n - (sum / n).powi(2)).max(0.0) / (n - 1.0)).sqrt();
    Albedo {
        single: s / n,
        single_se: se(s, s2),
        multiple: m / n,
        multiple_se: se(m, m2),
    }
}

/// The table's grid points: cos theta (0 taken just above the horizon, as the energy tables take it), perceptual
/// roughness, and F0 on a square-root scale (dense where dielectrics are: F0 0.04 is node 1.8 of 9).
pub fn grid_mu(i: usize) -> f64 {
    (i as f64 / (MS_RES_MU - 1) as f64).max(1e-3)
}

pub fn grid_roughness(j: usize) -> f64 {
    j as f64 / (MS_RES_ROUGH - 1) as f64
}

pub fn grid_f0(k: usize) -> f64 {
    (k as f64 / (MS_RES_F0 - 1) as f64).powi(2)
}

/// The GGX alpha of a perceptual roughness, floored where the shaders' lobe becomes a mirror.
pub fn alpha_of(roughness: f64) -> f64 {
    (roughness * roughness).max(1e-4)
}

/// The seed of one cell's walks: the table is the same however its cells are shared out.
pub fn cell_seed(i: usize, j: usize, k: usize) -> u64 {
    0x5EED_0000 ^ (((k * MS_RES_ROUGH as usize + j) * MS_RES_MU as usize + i) as u64 * 0x1_0000_0001)
}

/// The multiple-scattering albedo of a Schlick dielectric of normal reflectance F0 at every cell of the grid
/// (F0-major, then roughness, then cos theta), then its hemispherical average 2 int E_ms(mu) mu dmu per (F0,
/// roughness) by the trapezoid rule; `walks` per cell, over `threads` threads. `progress` is told of each row done.
pub fn build_table(walks: usize, threads: usize, progress: &(dyn Fn() + Sync)) -> Vec<f32> {
    let (nm, nr, nf) = (MS_RES_MU as usize, MS_RES_ROUGH as usize, MS_RES_F0 as usize);
    let rows: Vec<(usize, usize)> = (0..nf).flat_map(|k| (0..nr).map(move |j| (k, j))).collect();
    let next = std::sync::atomic::AtomicUsize::new(0);
    let mut grid = vec![0f32; nm * nr * nf];
    let done = std::sync::Mutex::new(Vec::new());
    std::thread::scope(|scope| {
        for _ in 0..threads.max(1) {
            scope.spawn(|| loop {
                let r = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                let Some(&(k, j)) = rows.get(r) else { break };
                let (alpha, fresnel) = (alpha_of(grid_roughness(j)), schlick(grid_f0(k)));
                let row: Vec<f32> = (0..nm)
                    .map(|i| albedo(grid_mu(i), alpha, &fresnel, walks, cell_seed(i, j, k)).multiple as f32)
                    .collect();
                done.lock().unwrap().push((k, j, row));
                progress();
            });
        }
    });
    for (k, j, row) in done.into_inner().unwrap() {
        grid[(k * nr + j) * nm..(k * nr + j + 1) * nm].copy_from_slice(&row);
    }
    let h = 1.0 / (nm - 1) as f64;
    let mut averages = Vec::with_capacity(nf * nr);
    for row in grid.chunks(nm) {
        let integral: f64 = (0..nm - 1)
            .map(|i| 0.5 * h * (row[i] as f64 * i as f64 * h + row[i + 1] as f64 * (i + 1) as f64 * h))
            .sum();
        averages.push((2.0 * integral) as f32);
    }
    grid.extend(averages);
    grid
}

/// The table as the shaders read it: trilinear in (cos theta, roughness, square root of F0).
pub fn table_lookup(table: &[f32], mu: f64, roughness: f64, f0: f64) -> f64 {
    let (nm, nr, nf) = (MS_RES_MU as usize, MS_RES_ROUGH as usize, MS_RES_F0 as usize);
    let x = mu.clamp(0.0, 1.0) * (nm - 1) as f64;
    let y = roughness.clamp(0.0, 1.0) * (nr - 1) as f64;
    let z = f0.clamp(0.0, 1.0).sqrt() * (nf - 1) as f64;
    let (x0, y0, z0) = (
        (x as usize).min(nm - 2),
        (y as usize).min(nr - 2),
        (z as usize).min(nf - 2),
    );
    let (fx, fy, fz) = (x - x0 as f64, y - y0 as f64, z - z0 as f64);
    let mut sum = 0.0;
    for c in 0..8 {
        let (dx, dy, dz) = (c & 1, (c >> 1) & 1, (c >> 2) & 1);
        let w = [1.0 - fx, fx][dx] * [1.0 - fy, fy][dy] * [1.0 - fz, fz][dz];
        sum += w * table[((z0 + dz) * nr + y0 + dy) * nm + x0 + dx] as f64;
    }
    sum
}

/// The number of floats in the table: the grid, then its averages.
pub const TABLE_FLOATS: usize = (MS_RES_MU * MS_RES_ROUGH * MS_RES_F0 + MS_RES_ROUGH * MS_RES_F0) as usize;

/// The table the renderer ships (examples/dielectric_ms.rs).
pub fn shipped_table() -> Vec<f32> {
    static BYTES: &[u8] = include_bytes!("../data/dielectric_ms.bin");
    assert_eq!(
        BYTES.len(),
        TABLE_FLOATS * 4,
        "data/dielectric_ms.bin holds the MS_RES_* grid"
    );
    BYTES
        .chunks_exact(4)
        .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        .collect()
}
