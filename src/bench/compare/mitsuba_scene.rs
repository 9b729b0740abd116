//! A scene as the helper hands it to Mitsuba: a PLY per material, EXRs for emission textures, a JSON description.
use super::err;
use super::reference::fnv_bytes;
use crate::error::Error;
use crate::scene::{self, Material, Projection, Scene, TextureRef, TriangleSoup};
use glam::Vec3;
use serde_json::{json, Value};
use std::path::{Path, PathBuf};

/// Writes `scene` for the helper: one PLY per material and a JSON description. Only what both renderers agree on
/// translates: Lambertian materials (KHR_materials_specular 0), emissive triangles (an emissive texture too: its
/// texels times the emissive factor, linear, in an EXR the emitter's bitmap reads bilinearly with the sampler's wrap
/// mode), clear volumetric dielectrics (Mitsuba's `dielectric` or `roughdielectric`) with what their volume holds (a
/// `homogeneous` medium: KHR_materials_volume's attenuation, KHR_materials_scatter's albedo and anisotropy) and a
/// pinhole camera. Returns the description's path and a text that names the scene's content (not where its files
/// are) for the reference cache.
pub(super) fn write_mitsuba_scene(scene: &Scene, size: (u32, u32), dir: &Path) -> Result<(PathBuf, String), Error> {
    if scene.environment.is_some() || !scene.punctual.is_empty() {
        return Err(err("only scenes lit by emissive triangles translate to Mitsuba"));
    }
    let camera = scene.camera.ok_or_else(|| err("the scene has no camera"))?;
    let soup = scene.flatten();
    let mut meshes = Vec::new();
    let mut content = Vec::new();
    for (k, m) in scene.materials.iter().enumerate() {
        if let Some((named, mesh)) = write_material(scene, &soup, k, m, dir)? {
            content.push(named);
            meshes.push(mesh);
        }
    }
    let Projection::Perspective { yfov } = camera.projection else {
        return Err(err("the comparison renderers are given perspective cameras only"));
    };
    let (_, up, forward) = camera.basis();
    let o = camera.origin();
    let camera = json!({
        "origin": o.to_array(),
        "target": (o + forward).to_array(),
        "up": up.to_array(),
        "yfov_deg": yfov.to_degrees(),
        "width": size.0,
        "height": size.1,
    });
    let path = dir.join("scene.json");
    std::fs::write(&path, json!({"camera": camera, "meshes": meshes}).to_string()).map_err(err)?;
    Ok((path, json!({"camera": camera, "meshes": content}).to_string()))
}

/// Writes material `k`'s triangles as a PLY in `dir` (its emission texture as an EXR before it): the entry that names
/// its content for the reference cache, and its entry in the description. None when no triangle has the material.
fn write_material(
    scene: &Scene,
    soup: &TriangleSoup,
    k: usize,
    m: &Material,
    dir: &Path,
) -> Result<Option<(Value, Value)>, Error> {
    let lambertian = m.specular == 0.0 && m.metallic == 0.0 && m.transmission == 0.0;
    let dielectric = dielectric(m);
    let emissive_map = m.emissive_texture.filter(|r| {
        let t = &scene.textures[r.texture];
        r.tex_coord == 0 && r.transform == scene::texture::IDENTITY_TRANSFORM && !t.nearest && t.wrap_s == t.wrap_t
    });
    let others = m.texture_refs().iter().filter(|r| r.is_some()).count();
    let textured = others > usize::from(emissive_map.is_some());
    let tris: Vec<usize> = (0..soup.len()).filter(|&t| soup.material()[t] as usize == k).collect();
    if tris.is_empty() {
        return Ok(None);
    }
    let layered = m.clearcoat.factor > 0.0
        || m.sheen.color != Vec3::ZERO
        || m.anisotropy.strength != 0.0
        || m.iridescence.factor > 0.0
        || m.diffuse_transmission.factor > 0.0
        || m.diffuse_roughness > 0.0
        || m.unlit;
    let plain = (lambertian && !m.double_sided) || dielectric.is_some();
    if !plain || layered || textured || m.alpha_tested() {
        return Err(err(format!(
            "material '{}' does not translate to Mitsuba (only single-sided Lambertian ones, untextured but for \
             their emission, and clear volumetric dielectrics do)",
            m.name
        )));
    }
    let ply = dir.join(format!("mesh{k}.ply"));
    let smooth = has_vertex_normals(soup, &tris);
    let bytes = ply_bytes(soup, &tris, emissive_map.is_some(), smooth);
    let e = m.emission;
    let mut mesh = json!({
        "ply": format!("{:016x}", fnv_bytes(&bytes)),
        "reflectance": m.base_color.to_array(),
        "radiance": if e.max_element() > 0.0 { json!(e.to_array()) } else { Value::Null },
    });
    if let Some(d) = dielectric {
        // Lambertian entries keep their old shape, so their references stay cached.
        mesh.as_object_mut().unwrap().remove("reflectance");
        mesh["dielectric"] = d;
    }
    if smooth {
        mesh["smooth"] = json!(true);
    }
    let named = if let Some(r) = emissive_map.filter(|_| e.max_element() > 0.0) {
        let exr = dir.join(format!("emission{k}.exr"));
        mesh["radiance_texture"] = write_emission(scene, r, e, &exr)?;
        let named = mesh.clone();
        mesh["radiance_texture"]["exr"] = json!(exr);
        named
    } else {
        mesh.clone()
    };
    mesh["ply"] = json!(ply);
    std::fs::write(&ply, bytes).map_err(err)?;
    Ok(Some((named, mesh)))
}

/// A clear volumetric dielectric's entry in the description: Mitsuba's smooth or GGX `roughdielectric` (alpha the
/// square of the perceptual roughness, as pathwave's) between the material's IOR and 1, and the `homogeneous` medium
/// inside it (none when it neither absorbs nor scatters). None for any other material. The glTF model's glass lobe is
/// this interface when the dielectric layer is whole (KHR_materials_specular 1, white) and the transmission white and
/// complete: pathwave reflects it by the exact Fresnel, as Mitsuba does.
fn dielectric(m: &Material) -> Option<Value> {
    let clear = m.transmission == 1.0
        && m.metallic == 0.0
        && m.specular == 1.0
        && m.specular_color == Vec3::ONE
        && m.base_color == Vec3::ONE
        && m.emission == Vec3::ZERO
        && m.dispersion == 0.0;
    if !clear || m.thin_walled {
        return None;
    }
    let sigma_t = m.attenuation;
    let interior = if sigma_t.max_element() > 0.0 {
        json!({
            "sigma_t": sigma_t.to_array(),
            "albedo": m.medium.albedo.to_array(),
            "g": m.medium.anisotropy,
        })
    } else {
        Value::Null
    };
    Some(json!({"ior": m.ior, "alpha": m.roughness * m.roughness, "interior": interior}))
}

/// Whether triangles `tris` carry shading normals of their own (smooth shading) rather than their faces' normals.
fn has_vertex_normals(soup: &TriangleSoup, tris: &[usize]) -> bool {
    tris.iter().any(|&t| {
        let [a, b, c] = soup.positions()[t];
        let face = (b - a).cross(c - a).normalize_or_zero();
        soup.normals()[t].iter().any(|n| n.dot(face) < 0.9999)
    })
}

/// A binary PLY of `soup`'s triangles `tris`, each with three vertices of its own, with texture coordinates when
/// `with_uv` and shading normals when `with_normals`.
fn ply_bytes(soup: &TriangleSoup, tris: &[usize], with_uv: bool, with_normals: bool) -> Vec<u8> {
    let uv = if with_uv {
        "property float u\nproperty float v\n"
    } else {
        ""
    };
    let normals = if with_normals {
        "property float nx\nproperty float ny\nproperty float nz\n"
    } else {
        ""
    };
    let mut bytes = format!(
        "ply\nformat binary_little_endian 1.0\nelement vertex {}\nproperty float x\nproperty float y\n\
         property float z\n{normals}{uv}element face {}\nproperty list uchar int vertex_indices\nend_header\n",
        3 * tris.len(),
        tris.len()
    )
    .into_bytes();
    for &t in tris {
        for c in 0..3 {
            bytes.extend(soup.positions()[t][c].to_array().iter().flat_map(|x| x.to_le_bytes()));
            if with_normals {
                let n = soup.normals()[t][c].normalize_or_zero();
                bytes.extend(n.to_array().iter().flat_map(|x| x.to_le_bytes()));
            }
            if with_uv {
                let w = soup.texcoords()[t][c];
                bytes.extend([w.x, w.y].iter().flat_map(|x| x.to_le_bytes()));
            }
        }
    }
    for f in 0..tris.len() as i32 {
        bytes.push(3);
        bytes.extend([3 * f, 3 * f + 1, 3 * f + 2].iter().flat_map(|i| i.to_le_bytes()));
    }
    bytes
}

/// Writes emission texture `r` times the emissive factor `e`, linear, as the EXR `exr`: its entry in the description,
/// named by its texels' hash, with the sampler's wrap mode.
fn write_emission(scene: &Scene, r: TextureRef, e: Vec3, exr: &Path) -> Result<Value, Error> {
    let t = &scene.textures[r.texture];
    let image = &scene.images[t.image];
    let linear: Vec<[f32; 3]> = (image.texels.iter())
        .map(|p| std::array::from_fn(|c| crate::output::srgb_decode(p[c] as f32 / 255.0) * e[c]))
        .collect();
    crate::output::write_image(exr, image.width, image.height, &linear, 0.0)?;
    let wrap = match t.wrap_s {
        scene::Wrap::Repeat => "repeat",
        scene::Wrap::ClampToEdge => "clamp",
        scene::Wrap::MirroredRepeat => "mirror",
    };
    let texels: Vec<u8> = linear.iter().flatten().flat_map(|x| x.to_le_bytes()).collect();
    Ok(json!({"exr": format!("{:016x}", fnv_bytes(&texels)), "wrap": wrap}))
}
