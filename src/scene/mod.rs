//! The host scene model: meshes placed by instances, materials, textures, emitters and the camera.
pub mod animation;
mod budget;
mod environment;
pub mod framing;
mod gltf;
pub mod instancing;
pub mod pointer;
pub mod rig;
mod soup;
mod tangent;
pub mod texture;

pub use self::gltf::{load, load_with, LoadOptions, DEFAULT_MAX_TEXTURE_PIXELS, MAX_FILE_BYTES, SUPPORTED_EXTENSIONS};
pub use environment::Environment;
pub use framing::{CameraOverride, CameraSpec};
pub use instancing::{handedness, invertible, Instancing, INSTANCING_MIN_TRIANGLES};
pub use rig::{JointSet, MorphTarget, Motion, PoseTime, Rig};
pub use soup::{box_corners, soup_bounds, KeyTriangle, TriangleSoup, WorldTriangle};
pub use texture::{Image, Texture, TextureRef, Wrap};

use glam::{Mat3, Mat4, Vec2, Vec3, Vec4};
use std::path::PathBuf;

/// The largest radiance (or punctual intensity) per channel a scene, a map or an option may hold. Above the sun's
/// luminance (1.6e9 cd/m^2), so every physical scene fits, and 1e5 below SAMPLE_RADIANCE_MAX, which leaves that
/// much room for the factors the integrator multiplies in (MIS weights, 1/pdf, Russian roulette's 1/p) before a
/// sample is dropped as one that could overflow the film.
pub const RADIANCE_MAX: f32 = 1e10;

/// A glTF metallic-roughness material with emission (radiance in linear RGB, W sr^-1 m^-2).
#[derive(Clone, Debug, PartialEq)]
pub struct Material {
    pub name: String,
    pub base_color: Vec3,
    pub emission: Vec3,
    /// Emission leaves both faces; otherwise only the counter-clockwise (front) face emits.
    pub double_sided: bool,
    pub metallic: f32,
    /// Perceptual roughness; the GGX alpha is its square.
    pub roughness: f32,
    /// KHR_materials_ior (1.5 by default: F0 = 0.04).
    pub ior: f32,
    /// KHR_materials_dispersion: 20 / the Abbe number, how much the IOR changes with wavelength (0: not at all). Only
    /// spectral transport sees it (`Scene::wants_spectral`).
    pub dispersion: f32,
    /// KHR_materials_specular: weight of the dielectric coat (0 makes a pure Lambertian) and its F0 colour.
    pub specular: f32,
    pub specular_color: Vec3,
    /// KHR_materials_transmission: the fraction of the dielectric base that transmits (refracts) instead of diffusing.
    pub transmission: f32,
    /// No KHR_materials_volume (or thickness 0): a thin sheet, light passes without bending.
    pub thin_walled: bool,
    /// KHR_materials_volume's attenuation coefficient inside the object, per metre: -ln(attenuationColor) / distance.
    /// The medium's extinction: absorption alone, unless `medium` scatters part of it.
    pub attenuation: Vec3,
    /// KHR_materials_scatter's volumetric mode: what of `attenuation` scatters, and how.
    pub medium: Medium,
    /// KHR_materials_scatter's thin-walled mode: part of the transmission turns diffuse.
    pub thin_scatter: ThinScatter,
    /// baseColorFactor's alpha: opacity under alphaMode MASK and BLEND.
    pub alpha: f32,
    pub alpha_mode: AlphaMode,
    /// sRGB colour and alpha, multiplying base_color and alpha.
    pub base_color_texture: Option<TextureRef>,
    /// Roughness in G and metallic in B, multiplying the factors.
    pub metallic_roughness_texture: Option<TextureRef>,
    /// Tangent-space normals; `normal_scale` scales their x and y.
    pub normal_texture: Option<TextureRef>,
    pub normal_scale: f32,
    /// sRGB colour multiplying the emission.
    pub emissive_texture: Option<TextureRef>,
    /// KHR_materials_specular: A multiplies `specular`, sRGB RGB multiplies `specular_color`.
    pub specular_texture: Option<TextureRef>,
    pub specular_color_texture: Option<TextureRef>,
    /// KHR_materials_transmission: R multiplies `transmission`.
    pub transmission_texture: Option<TextureRef>,
    /// KHR_materials_clearcoat (factor 0: none).
    pub clearcoat: Clearcoat,
    /// KHR_materials_sheen (black: none).
    pub sheen: Sheen,
    /// KHR_materials_anisotropy (strength 0: none).
    pub anisotropy: Anisotropy,
    /// KHR_materials_iridescence (factor 0: none).
    pub iridescence: Iridescence,
    /// KHR_materials_diffuse_transmission (factor 0: none).
    pub diffuse_transmission: DiffuseTransmission,
    /// KHR_materials_diffuse_roughness: the roughness r in [0, 1] of the energy-preserving Oren-Nayar (EON) diffuse
    /// lobe (0: Lambertian), and a texture whose R multiplies it.
    pub diffuse_roughness: f32,
    pub diffuse_roughness_texture: Option<TextureRef>,
    /// KHR_materials_unlit: the surface shows its base colour (times texture and vertex colour) to every ray that
    /// reaches it, camera or bounce, and reflects nothing. It is not a light: next-event estimation never aims at it.
    pub unlit: bool,
}

/// A clear dielectric coat (IOR 1.5) over the whole material, with its own roughness and normal map.
#[derive(Clone, Debug, PartialEq)]
pub struct Clearcoat {
    pub factor: f32,
    /// Perceptual roughness.
    pub roughness: f32,
    /// R multiplies the factor.
    pub texture: Option<TextureRef>,
    /// G multiplies the roughness.
    pub roughness_texture: Option<TextureRef>,
    /// The coat's tangent-space normals (without one, the coat follows the mesh's normal, not the base's map).
    pub normal_texture: Option<TextureRef>,
    pub normal_scale: f32,
}

impl Default for Clearcoat {
    fn default() -> Self {
        Clearcoat {
            factor: 0.0,
            roughness: 0.0,
            texture: None,
            roughness_texture: None,
            normal_texture: None,
            normal_scale: 1.0,
        }
    }
}

/// A sheen (cloth, dust) over the base: the Charlie microfiber lobe.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Sheen {
    pub color: Vec3,
    /// Perceptual roughness.
    pub roughness: f32,
    /// sRGB RGB multiplies the colour.
    pub color_texture: Option<TextureRef>,
    /// A multiplies the roughness.
    pub roughness_texture: Option<TextureRef>,
}

/// The base's specular lobes (dielectric, metal, glass) stretched along a direction in the tangent plane: brushed
/// metal, hair-like highlights. The GGX alpha along the direction is mix(alpha, 1, strength^2), across it alpha.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Anisotropy {
    pub strength: f32,
    /// Radians, counter-clockwise from the tangent towards the bitangent.
    pub rotation: f32,
    /// RG: a direction in tangent space (then rotated by `rotation`), B multiplies the strength. Linear.
    pub texture: Option<TextureRef>,
}

/// A thin dielectric film over the base (soap bubbles, oil on water, beetles): its interference colours the Fresnel
/// of the base's dielectric reflection and metal (Belcour and Barla 2017, as the extension approximates it).
#[derive(Clone, Debug, PartialEq)]
pub struct Iridescence {
    pub factor: f32,
    pub ior: f32,
    /// The film's thickness in nanometres: `thickness_max` without a thickness texture, else between the two by G.
    pub thickness_min: f32,
    pub thickness_max: f32,
    /// R multiplies the factor.
    pub texture: Option<TextureRef>,
    pub thickness_texture: Option<TextureRef>,
}

impl Default for Iridescence {
    fn default() -> Self {
        Iridescence {
            factor: 0.0,
            ior: 1.3,
            thickness_min: 100.0,
            thickness_max: 400.0,
            texture: None,
            thickness_texture: None,
        }
    }
}

/// Part of the base's diffuse lobe passes through the surface, Lambertian on the other side, tinted by `color`:
/// to the far side of a thin sheet, or (with KHR_materials_volume) into the object, absorbed on the way like glass.
#[derive(Clone, Debug, PartialEq)]
pub struct DiffuseTransmission {
    pub factor: f32,
    pub color: Vec3,
    /// A multiplies the factor.
    pub texture: Option<TextureRef>,
    /// sRGB RGB multiplies the colour.
    pub color_texture: Option<TextureRef>,
}

impl Default for DiffuseTransmission {
    fn default() -> Self {
        DiffuseTransmission {
            factor: 0.0,
            color: Vec3::ONE,
            texture: None,
            color_texture: None,
        }
    }
}

/// The medium inside a volumetric object (KHR_materials_scatter, scene/gltf/scatter.rs): per channel the
/// single-scattering albedo rho_ss, so the scattering coefficient is `attenuation * albedo` and absorption the rest,
/// and Henyey-Greenstein's g for the phase function. Zero albedo: a purely absorbing medium.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Medium {
    pub albedo: Vec3,
    pub anisotropy: f32,
}

impl Medium {
    pub fn scatters(&self) -> bool {
        self.albedo != Vec3::ZERO
    }
}

/// KHR_materials_scatter on a thin-walled surface (no KHR_materials_volume, or thickness 0): `strength` of the
/// transmission lobe becomes the draft's scatter_bsdf, Lambertian on both sides tinted by `color`, a share (1 + g) / 2
/// through the surface and (1 - g) / 2 back (g = `anisotropy`), under the dielectric layer as the diffuse base is.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ThinScatter {
    pub strength: f32,
    pub color: Vec3,
    pub anisotropy: f32,
    /// A multiplies `strength`, sRGB RGB multiplies `color`.
    pub strength_texture: Option<TextureRef>,
    pub color_texture: Option<TextureRef>,
}

impl Default for ThinScatter {
    fn default() -> Self {
        ThinScatter {
            strength: 0.0,
            color: Vec3::ONE,
            anisotropy: 0.0,
            strength_texture: None,
            color_texture: None,
        }
    }
}

/// glTF's alphaMode. Transparent parts are skipped by every ray, camera, extension and shadow alike.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum AlphaMode {
    Opaque,
    /// Opaque where alpha >= the cutoff, absent elsewhere.
    Mask(f32),
    /// Present with probability alpha (stochastic transparency: unbiased coverage, no sorting).
    Blend,
}

impl Material {
    /// Whether rays may pass through the surface: traversal then evaluates alpha at each candidate hit.
    pub fn alpha_tested(&self) -> bool {
        match self.alpha_mode {
            AlphaMode::Opaque => false,
            AlphaMode::Mask(_) | AlphaMode::Blend => true,
        }
    }

    pub fn texture_refs(&self) -> [Option<TextureRef>; crate::constants::TEX_SLOTS as usize] {
        [
            self.base_color_texture,
            self.metallic_roughness_texture,
            self.normal_texture,
            self.emissive_texture,
            self.clearcoat.texture,
            self.clearcoat.roughness_texture,
            self.clearcoat.normal_texture,
            self.sheen.color_texture,
            self.sheen.roughness_texture,
            self.specular_texture,
            self.specular_color_texture,
            self.transmission_texture,
            self.anisotropy.texture,
            self.iridescence.texture,
            self.iridescence.thickness_texture,
            self.diffuse_transmission.texture,
            self.diffuse_transmission.color_texture,
            self.diffuse_roughness_texture,
            self.thin_scatter.strength_texture,
            self.thin_scatter.color_texture,
        ]
    }

    /// The texture coordinate set the tangents follow, for a material that needs tangents: the base's normal map's,
    /// else the clear coat's, else the anisotropy texture's; an anisotropic material without any takes set 0, as
    /// MikkTSpace does.
    pub fn tangent_set(&self) -> Option<u32> {
        let mapped = self
            .normal_texture
            .or(self.clearcoat.normal_texture)
            .or(self.anisotropy.texture);
        match mapped {
            Some(r) => Some(r.tex_coord),
            None if self.anisotropy.strength > 0.0 => Some(0),
            None => None,
        }
    }

    /// Whether shading reads the primitive's texture coordinates: for a texture, or for tangents made from them.
    pub fn reads_texcoords(&self) -> bool {
        self.texture_refs().iter().any(Option::is_some) || self.tangent_set().is_some()
    }
}

impl Default for Material {
    /// glTF's default material: white, fully metallic, fully rough.
    fn default() -> Self {
        Material {
            name: "(default)".into(),
            base_color: Vec3::ONE,
            emission: Vec3::ZERO,
            double_sided: false,
            metallic: 1.0,
            roughness: 1.0,
            ior: 1.5,
            specular: 1.0,
            specular_color: Vec3::ONE,
            transmission: 0.0,
            thin_walled: true,
            attenuation: Vec3::ZERO,
            medium: Medium::default(),
            thin_scatter: ThinScatter::default(),
            alpha: 1.0,
            alpha_mode: AlphaMode::Opaque,
            base_color_texture: None,
            metallic_roughness_texture: None,
            normal_texture: None,
            normal_scale: 1.0,
            emissive_texture: None,
            specular_texture: None,
            specular_color_texture: None,
            transmission_texture: None,
            clearcoat: Clearcoat::default(),
            sheen: Sheen::default(),
            anisotropy: Anisotropy::default(),
            iridescence: Iridescence::default(),
            diffuse_transmission: DiffuseTransmission::default(),
            diffuse_roughness: 0.0,
            diffuse_roughness_texture: None,
            unlit: false,
            dispersion: 0.0,
        }
    }
}

/// A camera in world space; its vertical extent is fixed, the horizontal follows the image's aspect ratio.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    pub world_from_camera: Mat4,
    pub projection: Projection,
}

/// How a camera maps the image to rays: glTF's two projections.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Projection {
    /// Rays from one point; `yfov` is the vertical field of view in radians, in (0, pi).
    Perspective { yfov: f32 },
    /// Parallel rays along the view direction from an image plane `2 ymag` high (glTF's ymag, in scene units).
    Orthographic { ymag: f32 },
}

impl Projection {
    /// Half the image plane's height: at distance 1 for a perspective camera (tan(yfov / 2)), in scene units for an
    /// orthographic one. What the generate stage scales the pixel's position by.
    pub fn half_height(&self) -> f32 {
        match *self {
            Projection::Perspective { yfov } => (yfov * 0.5).tan(),
            Projection::Orthographic { ymag } => ymag,
        }
    }

    pub fn is_orthographic(&self) -> bool {
        matches!(self, Projection::Orthographic { .. })
    }
}

impl Camera {
    /// A camera at `eye` looking at `target`, +y up (`eye` not straight above or below it).
    pub fn look_at(eye: Vec3, target: Vec3, yfov: f32) -> Camera {
        let forward = (target - eye).normalize();
        let right = forward.cross(Vec3::Y).normalize();
        let up = right.cross(forward);
        Camera {
            world_from_camera: Mat4::from_cols(
                right.extend(0.0),
                up.extend(0.0),
                (-forward).extend(0.0),
                eye.extend(1.0),
            ),
            projection: Projection::Perspective { yfov },
        }
    }

    /// The ray through image position (x, y) in [0, 1]^2 (0, 0 at the top left) of an image `aspect` wide per
    /// unit of height, through the lens's centre: origin and unit direction. The host's twin of camera_ray in
    /// camera.glsl (click-to-focus, tests).
    pub fn ray(&self, x: f32, y: f32, aspect: f32) -> (Vec3, Vec3) {
        let (right, up, forward) = self.basis();
        let h = self.projection.half_height();
        let plane = right * ((2.0 * x - 1.0) * h * aspect) + up * ((1.0 - 2.0 * y) * h);
        match self.projection {
            Projection::Perspective { .. } => (self.origin(), (forward + plane).normalize()),
            Projection::Orthographic { .. } => (self.origin() + plane, forward),
        }
    }

    /// Why `world_from_camera` cannot place a camera (not finite, or a basis of scale 0 or otherwise singular), if
    /// it cannot: the view direction and image plane would be NaN and the image black.
    pub fn check_transform(world_from_camera: &Mat4) -> Result<(), String> {
        if !world_from_camera.is_finite() {
            return Err("is not finite".into());
        }
        // A normal determinant (not 0, not subnormal) keeps every basis vector long enough to normalise.
        if !Mat3::from_mat4(*world_from_camera).determinant().is_normal() {
            return Err("has scale 0 or is otherwise not invertible".into());
        }
        Ok(())
    }

    pub fn origin(&self) -> Vec3 {
        self.world_from_camera.transform_point3(Vec3::ZERO)
    }
    /// Right, up and forward unit vectors; glTF cameras look down -Z with +Y up.
    pub fn basis(&self) -> (Vec3, Vec3, Vec3) {
        let forward = self.world_from_camera.transform_vector3(-Vec3::Z).normalize();
        let up0 = self.world_from_camera.transform_vector3(Vec3::Y);
        let right = forward.cross(up0).normalize();
        let up = right.cross(forward);
        (right, up, forward)
    }
}

/// A glTF mesh: what every node referring to it places, stored once however many nodes do.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Mesh {
    pub name: String,
    pub primitives: Vec<Primitive>,
}

impl Mesh {
    /// Object-space triangles, before instancing and before degenerate ones are dropped.
    pub fn triangle_count(&self) -> usize {
        self.primitives.iter().map(|p| p.triangles.len()).sum()
    }
}

/// One primitive's object-space vertices and triangles, checked when loaded (every array as long as `positions`,
/// every index in range, every value finite) so that placing it cannot fail.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Primitive {
    pub positions: Vec<Vec3>,
    /// `None`: each triangle takes its face normal.
    pub normals: Option<Vec<Vec3>>,
    /// TEXCOORD_0 and TEXCOORD_1, read only for textured materials (uv (0, 0) where absent).
    pub texcoords: [Option<Vec<Vec2>>; 2],
    /// The file's TANGENT, read only for normal-mapped materials; without it tangents are generated when placed.
    pub tangents: Option<Vec<Vec4>>,
    /// COLOR_0 as linear RGBA, clamped to [0, 1].
    pub colors: Option<Vec<Vec4>>,
    /// Vertex indices with counter-clockwise front faces: strips and fans are already unrolled.
    pub triangles: Vec<[u32; 3]>,
    pub material: u32,
    /// Displacements `Scene::pose` blends by the node's weights; empty in posed meshes.
    pub morph_targets: Vec<MorphTarget>,
    /// JOINTS_n and WEIGHTS_n: which joints move each vertex, for a node with a skin; empty in posed meshes.
    pub skin: Vec<JointSet>,
}

impl Primitive {
    /// Unindexed triangles, three vertices each, as synthetic scenes (benchmarks, tests) give them.
    pub fn from_triangles(triangles: &[[Vec3; 3]], normals: Option<&[[Vec3; 3]]>, material: u32) -> Primitive {
        assert!(
            normals.is_none_or(|n| n.len() == triangles.len()),
            "one normal per vertex"
        );
        Primitive {
            positions: triangles.iter().flatten().copied().collect(),
            normals: normals.map(|n| n.iter().flatten().copied().collect()),
            triangles: (0..triangles.len() as u32)
                .map(|t| [3 * t, 3 * t + 1, 3 * t + 2])
                .collect(),
            material,
            ..Default::default()
        }
    }
}

/// A mesh placed in the world.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Instance {
    /// Index into `Scene::meshes`.
    pub mesh: usize,
    pub world_from_object: Mat4,
}

#[derive(Clone, Debug, Default)]
pub struct Scene {
    pub path: PathBuf,
    pub meshes: Vec<Mesh>,
    /// In the file's node order (depth first), which is the order `flatten` emits triangles in.
    pub instances: Vec<Instance>,
    pub materials: Vec<Material>,
    pub camera: Option<Camera>,
    /// How many cameras the file holds (for `--camera`).
    pub camera_count: usize,
    /// Everything the file asked for that pathwave ignored, one sentence each.
    pub warnings: Vec<String>,
    /// The file's extensionsUsed, in its order.
    pub extensions_used: Vec<String>,
    /// KHR_materials_variants: the file's variant names, and which one the primitives were read with.
    pub variants: Vec<String>,
    pub variant: Option<usize>,
    /// Light from infinitely far away; glTF has none, so it comes from the caller (`--env`, `--env-color`).
    pub environment: Option<Environment>,
    /// KHR_lights_punctual lights, in world space.
    pub punctual: Vec<PunctualLight>,
    /// The textures materials use (indexed by TextureRef::texture) and their images.
    pub textures: Vec<Texture>,
    pub images: Vec<Image>,
    /// The node hierarchy, animations and skins `pose` places the scene from.
    pub rig: Rig,
    /// What moves while the shutter is open (`pose_shutter`); None for a still image.
    pub motion: Option<rig::Motion>,
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PunctualKind {
    Point,
    /// Cone half-angles in radians; light falls off smoothly between them (the extension's formula).
    Spot {
        inner: f32,
        outer: f32,
    },
    Directional,
}

/// A point, spot or directional light. `intensity` is colour times the glTF intensity, read radiometrically:
/// W/sr for point and spot lights (the extension's candela), W/m^2 for directional ones (its lux).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PunctualLight {
    pub kind: PunctualKind,
    pub position: Vec3,
    /// Where the light points (its node's -z): spot and directional lights.
    pub direction: Vec3,
    pub intensity: Vec3,
}

impl Scene {
    /// Whether the scene needs spectral transport to look right: some material disperses light
    /// (KHR_materials_dispersion), which RGB transport ignores.
    pub fn wants_spectral(&self) -> bool {
        self.materials
            .iter()
            .any(|m| m.dispersion > 0.0 && m.transmission > 0.0 && !m.thin_walled)
    }

    /// Adds a mesh with one instance of it; returns the mesh's index.
    pub fn add_mesh(&mut self, mesh: Mesh, world_from_object: Mat4) -> usize {
        self.meshes.push(mesh);
        let mesh = self.meshes.len() - 1;
        self.instances.push(Instance {
            mesh,
            world_from_object,
        });
        mesh
    }

    /// The world-space bounds of every triangle `flatten` emits (inverted, +inf to -inf, when there is none).
    pub fn bounds(&self) -> (Vec3, Vec3) {
        soup::bounds(self.world_triangles().map(|(_, t)| t))
    }

    /// Whether no instance places a triangle with area.
    pub fn is_empty(&self) -> bool {
        self.world_triangles().next().is_none()
    }

    /// How many world-space triangles `flatten` emits.
    pub fn triangle_count(&self) -> usize {
        self.world_triangles().count()
    }

    /// The file's camera, or the default view (`framing`).
    pub fn camera_or_default(&self) -> Camera {
        match self.camera {
            Some(c) => c,
            None => self.default_camera((!self.is_empty()).then(|| self.bounds())),
        }
    }

    /// Makes `o` the camera this pose and every later one places (a command-line camera).
    pub fn override_camera(&mut self, o: CameraOverride) {
        self.rig.camera_override = Some(o);
        self.camera = o.apply(self.camera);
        if let Some(m) = &mut self.motion {
            for k in &mut m.keys {
                k.camera = o.apply(k.camera);
            }
        }
    }

    pub fn emissive_triangle_count(&self) -> usize {
        self.world_triangles()
            .filter(|&(m, _)| self.materials[m as usize].emission.max_element() > 0.0)
            .count()
    }
}
