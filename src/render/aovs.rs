//! The AOVs a render surveyed (survey.comp): each pixel's sums read back from the device, and the images they make.
use crate::constants::AOV_NONE;
use crate::layout::AovSums;

/// Per-pixel AOV sums over the same samples as the film, row 0 at the top.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Aovs {
    pub sums: Vec<AovSums>,
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
