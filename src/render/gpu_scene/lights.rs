//! The scene's lights for the device: punctual lights, the table light selection picks from by power, and the
//! light BVH over the finite emitters.
use super::pack::v4;
use crate::bvh;
use crate::bvh::lights::{LightBounds, LightTree};
use crate::constants::*;
use crate::layout::{GpuInstance, GpuLight, GpuPunctual};
use crate::scene::{PunctualKind, Scene};

/// A light's entry before the table is made.
pub(super) struct Emitter {
    /// LIGHT_KIND_* and index, as `GpuLight::id`.
    pub id: u32,
    /// Estimated power (W).
    pub power: f64,
    /// A triangle's area (its mean over the shutter when it moves).
    pub area: f32,
    /// What the light BVH needs of it; None for an infinite light (the environment, a directional light).
    pub bounds: Option<LightBounds>,
}

/// Punctual lights for the device, and each as an emitter by its emitted power; a directional one by what crosses
/// the disk of the scene's bounding sphere (`radius`).
pub(super) fn pack_punctual(scene: &Scene, radius: f32, emitters: &mut Vec<Emitter>) -> Vec<GpuPunctual> {
    let mut punctual = Vec::with_capacity(scene.punctual.len());
    for (i, l) in scene.punctual.iter().enumerate() {
        let mean = (l.intensity.x + l.intensity.y + l.intensity.z) as f64 / 3.0;
        let pi = std::f64::consts::PI;
        let (kind, cos_outer, cos_inner, p) = match l.kind {
            PunctualKind::Point => (PUNCTUAL_POINT, -1.0, -1.0, 4.0 * pi * mean),
            PunctualKind::Spot { inner, outer } => {
                let (ci, co) = (inner.cos(), outer.cos());
                (PUNCTUAL_SPOT, co, ci, 2.0 * pi * (1.0 - 0.5 * (ci + co) as f64) * mean)
            }
            PunctualKind::Directional => (PUNCTUAL_DIRECTIONAL, 1.0, 1.0, pi * (radius as f64).powi(2) * mean),
        };
        punctual.push(GpuPunctual {
            position: v4(l.position, f32::from_bits(kind)),
            direction: v4(l.direction, cos_outer),
            intensity: v4(l.intensity, cos_inner),
        });
        if p > 0.0 {
            let bounds = match l.kind {
                PunctualKind::Point => Some(LightBounds::point(l.position, p as f32)),
                PunctualKind::Spot { inner, outer } => {
                    Some(LightBounds::spot(l.position, l.direction, inner, outer, p as f32))
                }
                PunctualKind::Directional => None,
            };
            emitters.push(Emitter {
                id: LIGHT_KIND_PUNCTUAL << LIGHT_KIND_SHIFT | i as u32,
                power: p,
                area: 0.0,
                bounds,
            });
        }
    }
    punctual
}

/// The light table light selection picks from in proportion to power, the environment's probability in it, and
/// the total power; each emissive instance's record learns its entry.
pub(super) fn light_table(emitters: &[Emitter], instances: &mut [GpuInstance]) -> (Vec<GpuLight>, f32, f64) {
    let total: f64 = emitters.iter().map(|e| e.power).sum();
    let mut lights = Vec::with_capacity(emitters.len());
    let mut acc = 0.0f64;
    let mut env_prob = 0.0;
    let mut previous_cdf = 0.0f32;
    for (i, e) in emitters.iter().enumerate() {
        let (id, area) = (e.id, e.area);
        acc += e.power;
        // The last cdf is exactly 1 so every u in [0, 1) finds a light.
        let cdf = if i + 1 == emitters.len() {
            1.0
        } else {
            (acc / total) as f32
        };
        // The probability the device actually picks with is the gap between stored f32 cdfs, not p / total: for tiny
        // lights late in the table they differ.
        let prob = cdf - previous_cdf;
        previous_cdf = cdf;
        lights.push(GpuLight { id, cdf, prob, area });
        match id >> LIGHT_KIND_SHIFT {
            LIGHT_KIND_ENV => env_prob = prob,
            // Its triangles' density per unit area is its probability times their own within the mesh over their
            // world area, which the device finds at the hit (the instance may stretch or move).
            LIGHT_KIND_INSTANCE => instances[(id & LIGHT_INDEX_MASK) as usize].light[2] = i as u32,
            _ => {}
        }
    }
    (lights, env_prob, total)
}

/// The light BVH over the finite emitters of light selection's table (the first entries of `lights`, one per
/// emitter), with a leaf's place for every entry of `lights` (the instanced meshes' tables too), and the infinite
/// lights' own table, appended to `lights`. The infinite lights keep the share the power table gives them (their
/// estimated power, the environment's through the scene's bounding sphere, over the total) and split it by power;
/// the tree gets the rest. Returns the tree and the environment's probability under it.
pub(super) fn light_tree(emitters: &[Emitter], lights: &mut Vec<GpuLight>) -> (LightTree, f32) {
    let infinite: Vec<usize> = (0..emitters.len()).filter(|&j| emitters[j].bounds.is_none()).collect();
    let inf_total: f32 = infinite.iter().map(|&j| lights[j].prob).sum();
    let finite: Vec<(u32, LightBounds)> = (emitters.iter().enumerate())
        .filter_map(|(j, e)| e.bounds.map(|b| (j as u32, b)))
        .collect();
    let share = match (finite.is_empty(), infinite.is_empty()) {
        (true, _) => 0.0,
        (false, true) => 1.0,
        (false, false) => (1.0 - inf_total).clamp(0.0, 1.0),
    };
    let first = lights.len() as u32;
    let mut env_prob = 0.0;
    let mut acc = 0.0f32;
    let mut previous_cdf = 0.0f32;
    for (k, &j) in infinite.iter().enumerate() {
        acc += lights[j].prob;
        let cdf = if k + 1 == infinite.len() { 1.0 } else { acc / inf_total };
        // What the device picks with: the tree's complement times the gap between the stored cdfs.
        let prob = (1.0 - share) * (cdf - previous_cdf);
        previous_cdf = cdf;
        if lights[j].id >> LIGHT_KIND_SHIFT == LIGHT_KIND_ENV {
            env_prob = prob;
        }
        lights.push(GpuLight {
            id: lights[j].id,
            cdf,
            prob,
            area: 0.0,
        });
    }
    let tree = bvh::lights::build(finite, first, share, (first, infinite.len() as u32));
    (tree, env_prob)
}
