//! The device BSDFs through Renderer::probe_bsdf: the materials, cases, sampling and albedo the modules share.
#[path = "../common/mod.rs"]
mod common;

mod agree;
mod chi2;
mod energy;
mod lobes;
mod phase;
mod reciprocity;

use common::rng::Rng;
use glam::Vec3;
use pathwave::render::{BsdfProbe, BsdfQuery};
use pathwave::scene::{
    Anisotropy, Clearcoat, DiffuseTransmission, Iridescence, Material, Mesh, Primitive, Scene, Sheen,
};
use pathwave::Renderer;

pub(crate) const INCIDENT_DEG: [f32; 4] = [1.0, 30.0, 60.0, 85.0];
pub(crate) const ROUGHNESS: [f32; 5] = [0.05, 0.1, 0.3, 0.6, 1.0];

/// A material under test, named for messages, seen from outside it (`front`) or from inside, where its IOR inverts.
pub(crate) struct Case {
    pub(crate) name: String,
    pub(crate) material: Material,
    pub(crate) front: bool,
}

impl Case {
    pub(crate) fn new(name: impl Into<String>, material: Material) -> Self {
        Case {
            name: name.into(),
            material,
            front: true,
        }
    }

    pub(crate) fn inside(name: impl Into<String>, material: Material) -> Self {
        Case {
            front: false,
            ..Case::new(name, material)
        }
    }
}

/// A one-triangle scene whose materials are the ones under test.
pub(crate) fn renderer_with(materials: Vec<Material>) -> Renderer {
    let mut scene = Scene {
        materials,
        ..Default::default()
    };
    let triangle = Primitive::from_triangles(&[[Vec3::ZERO, Vec3::X, Vec3::Y]], Some(&[[Vec3::Z; 3]]), 0);
    scene.add_mesh(
        Mesh {
            name: "triangle".into(),
            primitives: vec![triangle],
        },
        glam::Mat4::IDENTITY,
    );
    Renderer::with_validation(&scene, &Default::default(), common::validation()).unwrap()
}

pub(crate) fn wo_at(deg: f32) -> Vec3 {
    let t = deg.to_radians();
    Vec3::new(t.sin(), 0.0, t.cos())
}

/// wo at `deg` from the normal and `azimuth` degrees about it, so the lobe's axes are met at every angle (at azimuth 0
/// the same bits as `wo_at`).
pub(crate) fn wo_around(deg: f32, azimuth: f32) -> Vec3 {
    let (t, p) = (deg.to_radians(), azimuth.to_radians());
    Vec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos())
}

/// The harnesses' (degrees from the normal, azimuth) for wo at each of `degs` in the xz plane, as `wo_at` places it.
pub(crate) fn in_plane(degs: &[f32]) -> Vec<(f32, f32)> {
    degs.iter().map(|&deg| (deg, 0.0)).collect()
}

/// The material sends light through the surface (glass or diffuse transmission); otherwise it only reflects.
pub(crate) fn transmits(m: &Material) -> bool {
    m.transmission > 0.0 || m.diffuse_transmission.factor > 0.0
}

/// Two device values that should be one, computed along different routes in f32 (sample against eval and pdf, f one
/// way against the other).
pub(crate) fn close(a: f32, b: f32) -> bool {
    (a - b).abs() <= 2e-3 * a.abs().max(b.abs()) + 1e-6
}

pub(crate) fn sample_many(r: &mut Renderer, material: u32, wo: Vec3, n: usize, seed: u64) -> Vec<BsdfProbe> {
    sample_with(r, material, wo, n, seed, true)
}

pub(crate) fn sample_with(
    r: &mut Renderer,
    material: u32,
    wo: Vec3,
    n: usize,
    seed: u64,
    compensate: bool,
) -> Vec<BsdfProbe> {
    sample_side(r, material, wo, true, n, seed, compensate)
}

/// Samples with wo outside (front) or inside the object.
pub(crate) fn sample_side(
    r: &mut Renderer,
    material: u32,
    wo: Vec3,
    front: bool,
    n: usize,
    seed: u64,
    compensate: bool,
) -> Vec<BsdfProbe> {
    let mut rng = Rng(seed);
    let queries: Vec<BsdfQuery> = (0..n)
        .map(|_| BsdfQuery {
            material,
            wo,
            x: Vec3::new(rng.next(), rng.next(), rng.next()),
            front,
        })
        .collect();
    r.probe_bsdf(&queries, false, compensate).unwrap()
}

/// Mean and standard error of the sampled weight (f cos / pdf), channel 0: the directional albedo.
pub(crate) fn albedo(samples: &[BsdfProbe]) -> (f64, f64) {
    albedo_in(samples, 0)
}

/// `albedo` in channel `c`.
pub(crate) fn albedo_in(samples: &[BsdfProbe], c: usize) -> (f64, f64) {
    let n = samples.len() as f64;
    let w: Vec<f64> = samples
        .iter()
        .map(|s| if s.ok { s.weight[c] as f64 } else { 0.0 })
        .collect();
    let mean = w.iter().sum::<f64>() / n;
    let var = w.iter().map(|x| (x - mean) * (x - mean)).sum::<f64>() / (n - 1.0);
    (mean, (var / n).sqrt())
}

/// Grid `grid` of the energy tables at (cos theta, roughness), interpolated bilinearly as the shaders read it.
pub(crate) fn table_lookup(t: &[f32], grid: usize, mu: f32, rough: f32) -> f64 {
    let n = pathwave::constants::ENERGY_RES as usize;
    let e = |i: usize, j: usize| t[grid * n * n + j * n + i];
    let (x, y) = (mu * (n - 1) as f32, rough * (n - 1) as f32);
    let (x0, y0) = ((x as usize).min(n - 2), (y as usize).min(n - 2));
    let (fx, fy) = (x - x0 as f32, y - y0 as f32);
    let a = e(x0, y0) * (1.0 - fx) + e(x0 + 1, y0) * fx;
    let b = e(x0, y0 + 1) * (1.0 - fx) + e(x0 + 1, y0 + 1) * fx;
    (a * (1.0 - fy) + b * fy) as f64
}

// ---- The materials: glTF's metallic-roughness parameters, and each extension over a base.

pub(crate) fn material(roughness: f32, metallic: f32, base: Vec3) -> Material {
    Material {
        roughness,
        metallic,
        base_color: base,
        ..Material::default()
    }
}

/// An orange dielectric: the specular layer over a diffuse base, the base the extensions' sweeps put under a layer.
pub(crate) fn plastic(roughness: f32) -> Material {
    Material {
        specular: 1.0,
        ..material(roughness, 0.0, Vec3::new(0.8, 0.6, 0.4))
    }
}

/// A white dielectric over a white diffuse base.
pub(crate) fn white_plastic(roughness: f32) -> Material {
    Material {
        specular: 1.0,
        ..material(roughness, 0.0, Vec3::ONE)
    }
}

pub(crate) fn lambert_white() -> Material {
    Material {
        specular: 0.0,
        ..material(1.0, 0.0, Vec3::ONE)
    }
}

/// A base that reflects nothing (black, no specular layer, no metal): only the layer over it is left.
pub(crate) fn black() -> Material {
    Material {
        specular: 0.0,
        ..material(1.0, 0.0, Vec3::ZERO)
    }
}

pub(crate) fn glass(roughness: f32, ior: f32, thin: bool) -> Material {
    Material {
        roughness,
        metallic: 0.0,
        ior,
        transmission: 1.0,
        thin_walled: thin,
        base_color: Vec3::ONE,
        ..Material::default()
    }
}

pub(crate) fn coated(base: Material, roughness: f32) -> Material {
    Material {
        clearcoat: Clearcoat {
            factor: 1.0,
            roughness,
            ..Clearcoat::default()
        },
        ..base
    }
}

pub(crate) fn sheened(base: Material, color: Vec3, roughness: f32) -> Material {
    Material {
        sheen: Sheen {
            color,
            roughness,
            ..Sheen::default()
        },
        ..base
    }
}

pub(crate) fn anisotropic(base: Material, strength: f32, rotation: f32) -> Material {
    Material {
        anisotropy: Anisotropy {
            strength,
            rotation,
            texture: None,
        },
        ..base
    }
}

pub(crate) fn filmed(base: Material, ior: f32, thickness: f32) -> Material {
    Material {
        iridescence: Iridescence {
            factor: 1.0,
            ior,
            thickness_min: 0.0,
            thickness_max: thickness,
            ..Iridescence::default()
        },
        ..base
    }
}

pub(crate) fn translucent(base: Material, factor: f32, color: Vec3) -> Material {
    Material {
        diffuse_transmission: DiffuseTransmission {
            factor,
            color,
            ..DiffuseTransmission::default()
        },
        ..base
    }
}

pub(crate) fn rough_diffuse(base: Material, r: f32) -> Material {
    Material {
        diffuse_roughness: r,
        ..base
    }
}
