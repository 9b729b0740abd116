//! Which meshes the renderer keeps once in object space, placed by instances through a two-level BVH, rather than
//! copied into the world-space soup once per instance.
use super::{Mesh, Scene};
use glam::{Mat3, Mat4};

/// How the renderer chooses the meshes it instances.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Instancing {
    /// The rule of `Scene::instanced_meshes`.
    #[default]
    Auto,
    /// Every mesh the rule allows, however few triangles its instances place (for tests).
    Always,
    /// None: every instance is flattened into the world BVH.
    Never,
}

/// A mesh is instanced only when its instances place at least this many triangles in all: below it, flattening
/// costs little memory and traversal stays one level, which is faster (one BVH walk, no ray transforms).
pub const INSTANCING_MIN_TRIANGLES: u64 = 1 << 16;

impl Mesh {
    fn triangles(&self) -> u64 {
        self.primitives.iter().map(|p| p.triangles.len() as u64).sum()
    }
}

/// Whether a transform can place a mesh in object space: the ray goes back through its inverse.
pub fn invertible(world_from_object: &Mat4) -> bool {
    world_from_object.is_finite() && Mat3::from_mat4(*world_from_object).determinant().is_normal()
}

impl Scene {
    /// Per mesh, whether it is instanced. The rule: a mesh placed by two or more instances (with invertible
    /// transforms), whose instances place at least INSTANCING_MIN_TRIANGLES triangles (any number under
    /// Instancing::Always); emissive ones too (light selection picks an instance, then a triangle from the mesh's
    /// own table). In a scene that
    /// moves over the shutter, the mesh must also be one of the file's own (not a skinned or morphed copy, whose
    /// vertices move), and each of its instances invertible at every key with the same handedness: its instances
    /// then move as rigid transforms interpolated per ray. A rigid mesh that turns over the shutter by more than
    /// `motion::FLATTENED_TURN_MAX` in a segment (by any angle under Instancing::Always) is instanced however often
    /// it is placed; flattened, its vertices move linearly between keys. Every other mesh is flattened. Normal maps
    /// are instanced
    /// too: tangents are generated once in the mesh's space and taken into the world per instance.
    pub fn instanced_meshes(&self, rule: Instancing) -> Vec<bool> {
        let none = vec![false; self.meshes.len()];
        if rule == Instancing::Never {
            return none;
        }
        let mut uses = vec![0u64; self.meshes.len()];
        let mut rigid = vec![true; self.meshes.len()];
        let mut turning = vec![false; self.meshes.len()];
        for (k, i) in self.instances.iter().enumerate() {
            let still = invertible(&i.world_from_object);
            if let Some(motion) = &self.motion {
                // Out of object space at some key (a scale through 0), an instance is flattened, not dropped.
                let hand = handedness(&i.world_from_object);
                let keeps = |key: &super::rig::Placed| {
                    let at = &key.instances[k];
                    at.mesh == i.mesh && invertible(&at.world_from_object) && handedness(&at.world_from_object) == hand
                };
                rigid[i.mesh] &= still && i.mesh < self.rig.file_meshes && motion.keys.iter().all(keeps);
                let keys: Vec<Mat4> = std::iter::once(i.world_from_object)
                    .chain(motion.keys.iter().map(|key| key.instances[k].world_from_object))
                    .collect();
                let turn =
                    crate::bvh::motion::decompose_keys(&keys).map_or(0.0, |p| crate::bvh::motion::largest_turn(&p));
                let least = if rule == Instancing::Always {
                    0.0
                } else {
                    crate::bvh::motion::FLATTENED_TURN_MAX
                };
                turning[i.mesh] |= turn > least;
            }
            if still {
                uses[i.mesh] += 1;
            }
        }
        (self.meshes.iter().zip(uses.iter().zip(rigid.iter().zip(&turning))))
            .map(|(mesh, (&n, (&rigid, &turning)))| {
                let big = rule == Instancing::Always || n.saturating_mul(mesh.triangles()) >= INSTANCING_MIN_TRIANGLES;
                // A mesh that turns rigidly faster than FLATTENED_TURN_MAX is instanced even when placed once: its
                // flattened vertices would move on straight lines between keys and shrink the turn between them.
                (n >= 2 && big || n >= 1 && turning) && rigid && mesh.triangles() > 0
            })
            .collect()
    }
}

/// Whether a transform mirrors (turns the winding of what it places).
pub fn handedness(world_from_object: &Mat4) -> bool {
    Mat3::from_mat4(*world_from_object).determinant() < 0.0
}
