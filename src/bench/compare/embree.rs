//! Traversal against Embree: the terrain and one set of random rays traced by both, round by round.
use super::helper::{read_f32, write_f32, Helper};
use super::{err, median, tracer};
use crate::bench::terrain;
use crate::bvh::{Ray, TraceHit};
use crate::error::Error;
use crate::render::{Renderer, Traversal};
use crate::scene::{Scene, TriangleSoup};
use crate::vk::DeviceChoice;
use glam::Vec3;
use serde_json::{json, Value};
use std::path::Path;

/// Deterministic uniforms for the ray set (SplitMix64), so both tracers see the same rays every run.
struct SplitMix(u64);

impl SplitMix {
    fn next(&mut self) -> f32 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        ((z ^ (z >> 31)) >> 40) as f32 / (1u64 << 24) as f32
    }
}

/// Rays with origins uniform in the scene's bounding box and directions uniform on the sphere: the incoherent
/// case DESIGN.md's prototype figures use.
pub fn random_rays(scene: &Scene, n: usize, seed: u64) -> Vec<Ray> {
    let (lo, hi) = scene.bounds();
    let mut rng = SplitMix(seed);
    (0..n)
        .map(|_| {
            let o = lo + (hi - lo) * Vec3::new(rng.next(), rng.next(), rng.next());
            let z = 1.0 - 2.0 * rng.next();
            let phi = std::f32::consts::TAU * rng.next();
            let r = (1.0 - z * z).max(0.0).sqrt();
            Ray {
                origin: o,
                dir: Vec3::new(r * phi.cos(), r * phi.sin(), z),
                tmin: 0.0,
                tmax: f32::MAX,
            }
        })
        .collect()
}

/// Traversal against Embree: the same mesh and random rays, closest hit, all cores each.
#[derive(Clone, Debug, Default)]
pub struct EmbreeComparison {
    pub device: String,
    pub triangles: usize,
    pub rays: usize,
    pub threads: u32,
    pub embree_build_s: f64,
    pub pathwave_build_s: f64,
    /// Per round, interleaved: (pathwave, Embree) rays per second.
    pub rounds: Vec<(f64, f64)>,
    /// Median over rounds of pathwave / Embree.
    pub ratio: f64,
    /// Rays where both miss or both hit at the same distance (within 1e-3 relative).
    pub agreement: f64,
    /// How pathwave traced in `rounds`: "compute" (its BVH) or "ray queries".
    pub traversal: String,
    /// Where the device has ray queries and both traversals were asked for: the same rays traced with them in each
    /// round, right after the compute BVH.
    pub ray_query: Option<RayQueryRounds>,
}

#[derive(Clone, Debug, Default)]
pub struct RayQueryRounds {
    /// Per round, rays per second.
    pub rays_per_s: Vec<f64>,
    /// The acceleration structures' build, compaction included.
    pub build_s: f64,
    /// Rays whose hits agree with Embree's, as `agreement`.
    pub agreement: f64,
}

/// `traversals`: what bench measures (the compute BVH first); the first is timed against Embree, a second (ray
/// queries) beside it.
pub fn compare_embree(
    python: &Path,
    device: &DeviceChoice,
    quick: bool,
    traversals: &[Traversal],
) -> Result<EmbreeComparison, Error> {
    let mut h = Helper::start(python)?;
    let side = if quick { 128 } else { 708 };
    let rays_n = if quick { 1 << 16 } else { 1 << 20 };
    let rounds = if quick { 2 } else { 3 };
    let scene = terrain(side);
    let rays = random_rays(&scene, rays_n, 7);
    let soup = scene.flatten();
    let embree_build_s = embree_load(&mut h, &soup, &rays)?;
    let first = traversals.first().copied().unwrap_or(Traversal::Compute);
    let device_choice = device;
    let mut r = tracer(&scene, device_choice, first)?;
    let device = r.context().device_name();
    let pathwave_build_s = match r.acceleration_structures() {
        Some((_, _, t)) => t.as_secs_f64(),
        None => r.bvh_build_time().as_secs_f64(),
    };
    // The first dispatch compiles the pipeline: traced once untimed.
    let (ours, _) = r.trace_timed(&rays, false, 1)?;
    let mut second = match traversals.get(1) {
        Some(&t) => Some(beside(&scene, device_choice, t, &rays)?),
        None => None,
    };
    let mut result = EmbreeComparison {
        device,
        triangles: soup.len(),
        rays: rays.len(),
        embree_build_s,
        pathwave_build_s,
        traversal: match r.traversal() {
            Traversal::RayQuery => "ray queries".into(),
            _ => "compute".into(),
        },
        ..Default::default()
    };
    let second_r = second.as_mut().map(|(q, _, _)| q);
    let second_rates = time_rounds(&mut h, &mut r, second_r, &rays, rounds, &mut result)?;
    result.ratio = median(result.rounds.iter().map(|(a, b)| a / b).collect());
    let theirs = read_f32(&h.path("hits.f32"))?;
    result.agreement = agreement(&ours, &theirs, rays.len());
    result.ray_query = second.map(|(_, hits, build_s)| RayQueryRounds {
        rays_per_s: second_rates,
        build_s,
        agreement: agreement(&hits, &theirs, rays.len()),
    });
    Ok(result)
}

/// Hands Embree the triangles and the rays, as files in the helper's folder, and has it build its BVH: returns that
/// build's seconds.
fn embree_load(h: &mut Helper, soup: &TriangleSoup, rays: &[Ray]) -> Result<f64, Error> {
    let tris: Vec<f32> = soup.positions().iter().flatten().flat_map(|p| p.to_array()).collect();
    let ray_data: Vec<f32> = rays
        .iter()
        .flat_map(|r| r.origin.to_array().into_iter().chain(r.dir.to_array()))
        .collect();
    let (tri_path, ray_path) = (h.path("tris.f32"), h.path("rays.f32"));
    write_f32(&tri_path, &tris)?;
    write_f32(&ray_path, &ray_data)?;
    let loaded = h
        .call(json!({"cmd": "embree_load", "triangles": tri_path}))
        .map_err(|e| err(format!("{e}; install it with `pip install embreex`")))?;
    Helper::f64(&loaded, "build_s")
}

/// The second traversal's renderer over `scene`, made right after the first's warm-up: the hits of its untimed first
/// trace (which compiles its pipeline) and its structures' build seconds come with it.
fn beside(
    scene: &Scene,
    device: &DeviceChoice,
    traversal: Traversal,
    rays: &[Ray],
) -> Result<(Renderer, Vec<TraceHit>, f64), Error> {
    let mut q = tracer(scene, device, traversal)?;
    let (hits, _) = q.trace_timed(rays, false, 1)?;
    let build_s = q.acceleration_structures().map_or(0.0, |(_, _, t)| t.as_secs_f64());
    Ok((q, hits, build_s))
}

/// The timed rounds into `result`, interleaved: in each, pathwave, then the second traversal where there is one, then
/// Embree (which writes its hits in the last round). Returns the second traversal's rays per second by round.
fn time_rounds(
    h: &mut Helper,
    r: &mut Renderer,
    mut second: Option<&mut Renderer>,
    rays: &[Ray],
    rounds: usize,
    result: &mut EmbreeComparison,
) -> Result<Vec<f64>, Error> {
    let rays_n = rays.len();
    let (ray_path, hit_path) = (h.path("rays.f32"), h.path("hits.f32"));
    let mut second_rates = Vec::new();
    let mut embree_t = Vec::new();
    for _ in 0..rounds {
        let (_, times) = r.trace_timed(rays, false, 2)?;
        let t_ours = median(times.iter().map(|t| t.as_secs_f64()).collect());
        if let Some(q) = &mut second {
            let (_, times) = q.trace_timed(rays, false, 2)?;
            second_rates.push(rays_n as f64 / median(times.iter().map(|t| t.as_secs_f64()).collect()));
        }
        let last = embree_t.len() + 1 == rounds;
        let hits = if last { json!(hit_path) } else { Value::Null };
        let traced = h.call(json!({"cmd": "embree_trace", "rays": ray_path, "hits": hits}))?;
        let t_embree = Helper::f64(&traced, "seconds")?;
        result.threads = traced["threads"].as_u64().unwrap_or(0) as u32;
        result.rounds.push((rays_n as f64 / t_ours, rays_n as f64 / t_embree));
        embree_t.push(t_embree);
    }
    Ok(second_rates)
}

/// The share of `rays` whose hits agree with Embree's distances `theirs` (infinite for a miss): both miss, or both
/// hit at the same distance within 1e-3 relative.
fn agreement(ours: &[TraceHit], theirs: &[f32], rays: usize) -> f64 {
    let agree = ours
        .iter()
        .zip(theirs)
        .filter(|(a, &b)| {
            let miss_a = a.tri == crate::constants::NO_HIT;
            let miss_b = !b.is_finite();
            (miss_a && miss_b) || (!miss_a && !miss_b && (a.t - b).abs() <= 1e-3 * b.abs().max(1e-3))
        })
        .count();
    agree as f64 / rays.max(1) as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn random_rays_are_repeatable_unit_and_inside_the_bounds() {
        let scene = terrain(8);
        let a = random_rays(&scene, 1000, 7);
        assert_eq!(a, random_rays(&scene, 1000, 7));
        assert_ne!(a, random_rays(&scene, 1000, 8));
        for r in &a {
            assert!((r.dir.length() - 1.0).abs() < 1e-5);
            assert!(r.origin.x.abs() <= 1.0 && r.origin.z.abs() <= 1.0 && r.origin.y.abs() < 0.2);
        }
        // Directions cover the sphere: each octant gets about an eighth.
        for octant in 0..8 {
            let k = a
                .iter()
                .filter(|r| {
                    (r.dir.x > 0.0) as usize + 2 * (r.dir.y > 0.0) as usize + 4 * (r.dir.z > 0.0) as usize == octant
                })
                .count();
            assert!((80..170).contains(&k), "octant {octant}: {k} of 1000");
        }
    }
}
