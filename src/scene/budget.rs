//! The scene's host-memory bounds: how many triangles and emitters flattening would emit, counted without
//! flattening, and refusing a scene over `--max-memory` before any of it is placed.
use super::Scene;
use crate::error::Error;
use crate::memory::{human, HOST_BYTES_PER_EMITTER, HOST_BYTES_PER_MOTION_KEY, HOST_BYTES_PER_TRIANGLE};

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
        let emissive = |m: &super::Mesh| -> u64 {
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
    pub fn check_host_memory(&self, limit: u64, rule: super::Instancing) -> Result<(), Error> {
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
        Err(Error::Limit(format!(
            "{}: rendering it would need about {} of host memory ({triangles} triangles once its {} instances are \
                 placed, about {per_triangle} bytes each), over the limit of {} (--max-memory)",
            self.path.display(),
            human(need),
            self.instances.len(),
            human(limit)
        )))
    }
}
