//! The AOVs a render surveyed (survey.comp): each pixel's sums read back from the device, and the images they make.
use crate::constants::AOV_NONE;
use crate::layout::{AovSums, DebugSums};

/// Per-pixel AOV sums over the same samples as the film, row 0 at the top.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Aovs {
    pub sums: Vec<AovSums>,
    /// The debug views' sums, when the render asked for them (`RenderSettings::debug_aovs`).
    pub debug: Option<Vec<DebugSums>>,
}

impl Aovs {
    /// The mean albedo of the first rough surface each sample found (through specular bounces; the environment,
    /// within [0, 1], where a sample found none).
    pub fn albedo(&self) -> Vec<[f32; 3]> {
        (self.sums.iter())
            .map(|a| per_sample(a, [a.albedo[0], a.albedo[1], a.albedo[2]]))
            .collect()
    }

    /// The mean world-space shading normal of that surface, zero for samples that found none: unit inside a
    /// surface, shorter across edges and where part of the pixel sees nothing.
    pub fn normal(&self) -> Vec<[f32; 3]> {
        (self.sums.iter())
            .map(|a| per_sample(a, [a.normal[0], a.normal[1], a.normal[2]]))
            .collect()
    }

    /// The fraction of each pixel's camera samples whose ray hit the scene (whatever it hit first: glass counts,
    /// an alpha-tested cut-out it passed through does not): the alpha of `render --alpha`.
    pub fn coverage(&self) -> Vec<f32> {
        (self.sums.iter())
            .map(|a| match a.albedo[3] {
                0.0 => 0.0,
                n => a.normal[3] / n,
            })
            .collect()
    }

    /// The mean distance along the camera ray to the first hit, over the samples that hit; infinite where none did.
    pub fn depth(&self) -> Vec<f32> {
        (self.sums.iter())
            .map(|a| match a.normal[3] {
                0.0 => f32::INFINITY,
                hits => a.position[3] / hits,
            })
            .collect()
    }

    /// The mean world-space position of the first hit, over the samples that hit; zero where none did.
    pub fn position(&self) -> Vec<[f32; 3]> {
        (self.sums.iter())
            .map(|a| match a.normal[3] {
                0.0 => [0.0; 3],
                hits => [a.position[0] / hits, a.position[1] / hits, a.position[2] / hits],
            })
            .collect()
    }

    /// The index in `Scene::instances` of what the pixel's first sample hit first; None where it hit nothing.
    pub fn instance_id(&self) -> Vec<Option<u32>> {
        self.sums.iter().map(|a| id(a.ids[0])).collect()
    }

    /// The material index of that hit; None where it hit nothing.
    pub fn material_id(&self) -> Vec<Option<u32>> {
        self.sums.iter().map(|a| id(a.ids[1])).collect()
    }

    /// A debug view's per-sample mean (`pick` chooses from a pixel's DebugSums); None without debug views.
    fn debug_mean<const N: usize>(&self, pick: impl Fn(&DebugSums) -> [f32; N]) -> Option<Vec<[f32; N]>> {
        let debug = self.debug.as_ref()?;
        Some(
            (self.sums.iter().zip(debug))
                .map(|(a, d)| {
                    let n = a.albedo[3];
                    pick(d).map(|v| if n > 0.0 { v / n } else { 0.0 })
                })
                .collect(),
        )
    }

    /// The mean geometric normal at the camera rays' first hits (facing the rays; zero where they hit nothing).
    pub fn geometric_normal(&self) -> Option<Vec<[f32; 3]>> {
        self.debug_mean(|d| [d.geometric[0], d.geometric[1], d.geometric[2]])
    }

    /// The mean shading normal there (before any bounce, unlike `normal`).
    pub fn shading_normal(&self) -> Option<Vec<[f32; 3]>> {
        self.debug_mean(|d| [d.shading[0], d.shading[1], d.shading[2]])
    }

    /// The mean TEXCOORD_0 there (zero where the scene keeps no texture coordinates on the device: no textures).
    pub fn uv(&self) -> Option<Vec<[f32; 2]>> {
        self.debug_mean(|d| [d.uv[0], d.uv[1]])
    }

    /// The mean number of BVH child boxes a camera ray tested (four per node visited).
    pub fn bvh_cost(&self) -> Option<Vec<f32>> {
        Some(
            self.debug_mean(|d| [d.geometric[3]])?
                .into_iter()
                .map(|[v]| v)
                .collect(),
        )
    }

    /// The mean chance next-event estimation picks the light a camera ray found (an emitter's share of the light
    /// table, or the environment's; zero for everything else).
    pub fn light_pick(&self) -> Option<Vec<f32>> {
        Some(self.debug_mean(|d| [d.shading[3]])?.into_iter().map(|[v]| v).collect())
    }
}

fn per_sample(a: &AovSums, v: [f32; 3]) -> [f32; 3] {
    let n = a.albedo[3];
    if n > 0.0 {
        v.map(|c| c / n)
    } else {
        [0.0; 3]
    }
}

fn id(v: u32) -> Option<u32> {
    (v != AOV_NONE).then_some(v)
}
