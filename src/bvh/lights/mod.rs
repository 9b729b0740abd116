//! The light BVH: a binary tree over the finite emitters (bounds, power and normal cone per node), its GPU layout
//! (`GpuLightNode`) and the CPU twin of the device's descent and pmf (`shaders/include/light_tree.glsl`).
//!
//! Light selection descends from the root, choosing a child in proportion to its importance at the shading point:
//! power over squared distance, times the cosines left once the node's normal cone and its bounds' solid angle are
//! allowed for, at the emitter and at the receiver (the bound of pbrt-v4's `LightBounds::Importance`, after Conty
//! Estevez and Kulla 2018). The importance is a bound, so a node it calls zero cannot light the point; where it
//! misjudges, MIS with BSDF sampling still gives the right mean, since the pdf twin returns exactly the probability
//! the descent picks with.
mod bounds;
mod build;
mod pick;
#[cfg(test)]
mod tests;

pub use self::bounds::LightBounds;
pub use self::build::build;
pub use self::pick::{importance, LightWalk};
use crate::layout::GpuLightNode;

/// The tree on the host: the device's records and what `pathwave info` reports.
#[derive(Clone, Debug, Default)]
pub struct LightTree {
    /// Record 0 is the header, then a leaf per entry of the light buffer before the infinite lights' table (1 +
    /// entry; a record of zeros for an entry outside the tree), then the interior nodes, the instanced meshes'
    /// subtrees' after the tree's. See `GpuLightNode`.
    pub nodes: Vec<GpuLightNode>,
    pub stats: LightTreeStats,
}

#[derive(Clone, Debug, Default)]
pub struct LightTreeStats {
    /// Emitters in the tree (triangles, emissive instances, point and spot lights).
    pub emitters: usize,
    /// Emitters in instanced meshes' subtrees (each mesh's triangles once).
    pub instanced: usize,
    /// Interior nodes.
    pub interior: usize,
    /// Longest path from the root to a leaf, in edges.
    pub depth: u32,
    /// Longest path from an instanced mesh's subtree's root to its leaves.
    pub subtree_depth: u32,
    pub build: std::time::Duration,
}

impl LightTree {
    pub fn bytes(&self) -> usize {
        std::mem::size_of_val(&self.nodes[..])
    }
    pub fn root(&self) -> u32 {
        self.nodes[0].link[0]
    }
    /// The probability light selection descends the tree rather than picking an infinite light.
    pub fn share(&self) -> f32 {
        self.nodes[0].sphere[0]
    }
}
