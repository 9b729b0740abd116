//! Writes small glTF 2.0 scenes (one .gltf with an embedded buffer) for tests and for scenes/.
#![allow(dead_code)]
use glam::{Mat3, Quat, Vec3};
use serde_json::{json, Value};

/// Which way a `quad`'s front face turns: up (+y), down (-y), or towards +z (a camera on the +z axis).
pub const FACING_UP: Option<[f32; 3]> = Some([0.0, 1.0, 0.0]);
pub const FACING_DOWN: Option<[f32; 3]> = Some([0.0, -1.0, 0.0]);
pub const FACING_Z: Option<[f32; 3]> = Some([0.0, 0.0, 1.0]);

/// The corners of a level rectangle at height `y` over `x` and `z` (each from, to), in the order (x0, z0), (x1, z0),
/// (x1, z1), (x0, z1).
pub fn level(x: [f32; 2], y: f32, z: [f32; 2]) -> [[f32; 3]; 4] {
    [[x[0], y, z[0]], [x[1], y, z[0]], [x[1], y, z[1]], [x[0], y, z[1]]]
}

/// A level square of half-side `half` about the y axis at height `y`: `level` over -half to half both ways.
pub fn square(half: f32, y: f32) -> [[f32; 3]; 4] {
    level([-half, half], y, [-half, half])
}

/// The corners of an upright rectangle at depth `z` over `x` and `y` (each from, to), in the order (x0, y0),
/// (x1, y0), (x1, y1), (x0, y1).
pub fn upright(x: [f32; 2], y: [f32; 2], z: f32) -> [[f32; 3]; 4] {
    [[x[0], y[0], z], [x[1], y[0], z], [x[1], y[1], z], [x[0], y[1], z]]
}

#[derive(Default)]
pub struct GltfBuilder {
    bin: Vec<u8>,
    views: Vec<Value>,
    accessors: Vec<Value>,
    meshes: Vec<Value>,
    materials: Vec<Value>,
    nodes: Vec<Value>,
    cameras: Vec<Value>,
    lights: Vec<Value>,
    images: Vec<Value>,
    samplers: Vec<Value>,
    textures: Vec<Value>,
    extensions: Vec<&'static str>,
    /// Each animation's name, samplers and channels.
    animations: Vec<(String, Vec<Value>, Vec<Value>)>,
    skins: Vec<Value>,
    /// Root-level extension objects beyond KHR_lights_punctual's.
    root_extensions: Vec<(&'static str, Value)>,
}

impl GltfBuilder {
    pub fn new() -> Self {
        Self::default()
    }

    pub fn use_extension(&mut self, ext: &'static str) {
        if !self.extensions.contains(&ext) {
            self.extensions.push(ext);
        }
    }

    /// A purely diffuse (Lambertian) material: dielectric with KHR_materials_specular's weight 0, so no coat.
    /// Emission is radiance (W sr^-1 m^-2), written with KHR_materials_emissive_strength past 1.
    pub fn material(&mut self, name: &str, base: [f32; 3], emission: [f32; 3], double_sided: bool) -> usize {
        let i = self.pbr_material(name, base, 0.0, 1.0, emission, double_sided);
        self.materials[i]["extensions"]["KHR_materials_specular"] = json!({ "specularFactor": 0.0 });
        self.use_extension("KHR_materials_specular");
        i
    }

    /// An unlit material (KHR_materials_unlit): the camera sees `color` as it is, whatever lights the scene.
    pub fn unlit_material(&mut self, name: &str, color: [f32; 3]) -> usize {
        let i = self.pbr_material(name, color, 0.0, 1.0, [0.0; 3], false);
        self.materials[i]["extensions"]["KHR_materials_unlit"] = json!({});
        self.use_extension("KHR_materials_unlit");
        i
    }

    /// A transmissive dielectric (KHR_materials_transmission, _ior, and _volume unless thin-walled), tinted `tint`,
    /// absorbing to `attenuation` colour over `distance` metres inside.
    pub fn glass_material(
        &mut self,
        name: &str,
        tint: [f32; 3],
        ior: f32,
        roughness: f32,
        thin: bool,
        absorb: Option<([f32; 3], f32)>,
    ) -> usize {
        let i = self.pbr_material(name, tint, 0.0, roughness, [0.0; 3], false);
        let ext = &mut self.materials[i]["extensions"];
        ext["KHR_materials_transmission"] = json!({ "transmissionFactor": 1.0 });
        ext["KHR_materials_ior"] = json!({ "ior": ior });
        if !thin {
            let mut volume = json!({ "thicknessFactor": 1.0 });
            if let Some((color, distance)) = absorb {
                volume["attenuationColor"] = json!(color);
                volume["attenuationDistance"] = json!(distance);
            }
            ext["KHR_materials_volume"] = volume;
            self.use_extension("KHR_materials_volume");
        }
        self.use_extension("KHR_materials_transmission");
        self.use_extension("KHR_materials_ior");
        i
    }

    /// KHR_materials_dispersion on material `i`: `dispersion` is 20 / its Abbe number.
    pub fn dispersion(&mut self, i: usize, dispersion: f32) {
        self.materials[i]["extensions"]["KHR_materials_dispersion"] = json!({ "dispersion": dispersion });
        self.use_extension("KHR_materials_dispersion");
    }

    /// A closed convex solid from its corners and faces (corner indices, any winding, 3 or 4 corners): each face is
    /// wound to face away from the corners' centre.
    pub fn convex_solid(&mut self, name: &str, corners: &[[f32; 3]], faces: &[&[usize]], material: usize) {
        let centre = corners.iter().map(|c| Vec3::from(*c)).sum::<Vec3>() / corners.len() as f32;
        let mut indices = Vec::new();
        for f in faces {
            let p = |k: usize| Vec3::from(corners[f[k]]);
            let n = (p(1) - p(0)).cross(p(2) - p(0));
            let out = n.dot(p(0) - centre) > 0.0;
            for k in 1..f.len() - 1 {
                let tri = [f[0], f[k], f[k + 1]];
                let tri = if out { tri } else { [tri[0], tri[2], tri[1]] };
                indices.extend(tri.map(|i| i as u32));
            }
        }
        self.mesh(name, corners, &indices, material);
    }

    /// A glTF metallic-roughness material.
    pub fn pbr_material(
        &mut self,
        name: &str,
        base: [f32; 3],
        metallic: f32,
        roughness: f32,
        emission: [f32; 3],
        double_sided: bool,
    ) -> usize {
        let peak = emission.iter().cloned().fold(0.0f32, f32::max);
        let mut m = json!({
            "name": name,
            "pbrMetallicRoughness": { "baseColorFactor": [base[0], base[1], base[2], 1.0], "metallicFactor": metallic, "roughnessFactor": roughness },
            "doubleSided": double_sided,
        });
        if peak > 0.0 {
            let scale = peak.max(1.0);
            m["emissiveFactor"] = json!(emission.map(|e| e / scale));
            if scale > 1.0 {
                m["extensions"]["KHR_materials_emissive_strength"] = json!({ "emissiveStrength": scale });
                self.use_extension("KHR_materials_emissive_strength");
            }
        }
        self.materials.push(m);
        self.materials.len() - 1
    }

    /// A vertex-attribute accessor over float vectors (`kind`: "VEC2", "VEC3" or "VEC4"); returns its index.
    fn float_accessor<const N: usize>(&mut self, data: &[[f32; N]], kind: &str) -> usize {
        let bytes: Vec<u8> = data.iter().flatten().flat_map(|f| f.to_le_bytes()).collect();
        let v = self.push_view(&bytes, 34962);
        self.accessors
            .push(json!({ "bufferView": v, "componentType": 5126, "count": data.len(), "type": kind }));
        self.accessors.len() - 1
    }

    /// An accessor of float vectors (VEC3 or VEC4 by N) not tied to any mesh; returns its index.
    pub fn raw_accessor<const N: usize>(&mut self, data: &[[f32; N]]) -> usize {
        let kind = match N {
            2 => "VEC2",
            3 => "VEC3",
            4 => "VEC4",
            _ => "SCALAR",
        };
        let acc = self.float_accessor(data, kind);
        let view = self.accessors[acc]["bufferView"].as_u64().unwrap() as usize;
        self.views[view].as_object_mut().unwrap().remove("target");
        acc
    }

    /// Points attribute `name` of the last mesh at accessor `acc`.
    fn set_attribute(&mut self, name: &str, acc: usize) {
        self.meshes.last_mut().unwrap()["primitives"][0]["attributes"][name] = json!(acc);
    }

    fn push_view(&mut self, bytes: &[u8], target: u32) -> usize {
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        let offset = self.bin.len();
        self.bin.extend_from_slice(bytes);
        self.views
            .push(json!({ "buffer": 0, "byteOffset": offset, "byteLength": bytes.len(), "target": target }));
        self.views.len() - 1
    }

    /// An extension object at the document's root.
    pub fn set_root_extension(&mut self, name: &'static str, value: Value) {
        self.root_extensions.retain(|(n, _)| *n != name);
        self.root_extensions.push((name, value));
    }

    /// An extension object on mesh `mesh`'s (first) primitive.
    pub fn set_primitive_extension(&mut self, mesh: usize, name: &str, value: Value) {
        self.meshes[mesh]["primitives"][0]["extensions"][name] = value;
    }

    /// The JSON of material `i`, to add textures, alpha modes or extensions.
    pub fn material_json(&mut self, i: usize) -> &mut Value {
        &mut self.materials[i]
    }

    /// A PNG image (RGBA8, rows from the top) embedded in the buffer.
    pub fn png_image(&mut self, width: u32, height: u32, rgba: &[[u8; 4]]) -> usize {
        assert_eq!(rgba.len(), (width * height) as usize);
        let mut bytes = Vec::new();
        {
            let mut enc = png::Encoder::new(&mut bytes, width, height);
            enc.set_color(png::ColorType::Rgba);
            enc.set_depth(png::BitDepth::Eight);
            let mut w = enc.write_header().unwrap();
            w.write_image_data(rgba.as_flattened()).unwrap();
        }
        let view = self.push_view(&bytes, 0);
        self.views[view].as_object_mut().unwrap().remove("target");
        self.images.push(json!({ "bufferView": view, "mimeType": "image/png" }));
        self.images.len() - 1
    }

    /// A texture of `image` with a sampler (e.g. json!({"magFilter": 9728, "wrapS": 33648})).
    pub fn texture(&mut self, image: usize, sampler: Value) -> usize {
        self.samplers.push(sampler);
        self.textures
            .push(json!({ "source": image, "sampler": self.samplers.len() - 1 }));
        self.textures.len() - 1
    }

    /// A mesh with TEXCOORD_0 and optional normals and tangents.
    #[allow(clippy::too_many_arguments)]
    pub fn mesh_with_attributes(
        &mut self,
        name: &str,
        positions: &[[f32; 3]],
        normals: Option<&[[f32; 3]]>,
        uvs: &[[f32; 2]],
        tangents: Option<&[[f32; 4]]>,
        indices: &[u32],
        material: usize,
    ) {
        self.mesh_with_normals(name, positions, normals, indices, material);
        let uv = self.float_accessor(uvs, "VEC2");
        self.set_attribute("TEXCOORD_0", uv);
        if let Some(t) = tangents {
            let acc = self.float_accessor(t, "VEC4");
            self.set_attribute("TANGENT", acc);
        }
    }

    /// Gives the last mesh COLOR_0 (linear RGBA floats, one per vertex).
    pub fn add_colors(&mut self, colors: &[[f32; 4]]) {
        let acc = self.float_accessor(colors, "VEC4");
        self.set_attribute("COLOR_0", acc);
    }

    /// A quad with texture coordinates per corner; corners wind counter-clockwise seen from the front.
    pub fn textured_quad(&mut self, name: &str, corners: [[f32; 3]; 4], uvs: [[f32; 2]; 4], material: usize) {
        self.mesh_with_attributes(name, &corners, None, &uvs, None, &[0, 1, 2, 0, 2, 3], material);
    }

    /// An indexed triangle mesh on its own node; front faces wind counter-clockwise.
    pub fn mesh(&mut self, name: &str, positions: &[[f32; 3]], indices: &[u32], material: usize) {
        self.mesh_with_normals(name, positions, None, indices, material);
    }

    /// As `mesh`, with per-vertex normals when given.
    pub fn mesh_with_normals(
        &mut self,
        name: &str,
        positions: &[[f32; 3]],
        normals: Option<&[[f32; 3]]>,
        indices: &[u32],
        material: usize,
    ) {
        let pos_bytes: Vec<u8> = positions.iter().flatten().flat_map(|f| f.to_le_bytes()).collect();
        let idx_bytes: Vec<u8> = indices.iter().flat_map(|i| i.to_le_bytes()).collect();
        let pv = self.push_view(&pos_bytes, 34962);
        let iv = self.push_view(&idx_bytes, 34963);
        let (lo, hi) = bounds(positions);
        self.accessors.push(json!({ "bufferView": pv, "componentType": 5126, "count": positions.len(), "type": "VEC3", "min": lo, "max": hi }));
        let pa = self.accessors.len() - 1;
        self.accessors
            .push(json!({ "bufferView": iv, "componentType": 5125, "count": indices.len(), "type": "SCALAR" }));
        let ia = self.accessors.len() - 1;
        let mut attributes = json!({ "POSITION": pa });
        if let Some(normals) = normals {
            attributes["NORMAL"] = json!(self.float_accessor(normals, "VEC3"));
        }
        self.meshes.push(
            json!({ "name": name, "primitives": [{ "attributes": attributes, "indices": ia, "material": material }] }),
        );
        self.nodes.push(json!({ "name": name, "mesh": self.meshes.len() - 1 }));
    }

    /// The index of the last node added.
    pub fn last_node(&self) -> usize {
        self.nodes.len() - 1
    }

    /// A node with the given JSON fields (e.g. a joint with a translation); returns its index.
    pub fn node(&mut self, name: &str, fields: Value) -> usize {
        self.nodes.push(json!({ "name": name }));
        self.transform_last_node(fields);
        self.last_node()
    }

    /// Makes `child` a child of `parent` (it is then no longer a root of the scene).
    pub fn add_child(&mut self, parent: usize, child: usize) {
        let node = &mut self.nodes[parent];
        if node.get("children").is_none() {
            node["children"] = json!([]);
        }
        node["children"].as_array_mut().unwrap().push(json!(child));
    }

    /// A keyframed channel of animation `animation` (created, by name, at first use) on `node`'s `path`
    /// ("translation", "rotation", "scale" or "weights"): `values` holds every output float in order.
    pub fn animate(
        &mut self,
        animation: &str,
        node: usize,
        path: &str,
        interpolation: &str,
        times: &[f32],
        values: &[f32],
    ) {
        let width = match path {
            "translation" | "scale" => 3,
            "rotation" => 4,
            _ => 1,
        };
        let target = json!({ "node": node, "path": path });
        self.channel(animation, target, interpolation, times, values, width, false);
    }

    /// A LINEAR translation channel of animation `animation` (created, by name, at first use) taking `node` from
    /// `from` at `times[0]` to `to` at `times[1]`.
    pub fn slide(&mut self, animation: &str, node: usize, times: [f32; 2], from: [f32; 3], to: [f32; 3]) {
        self.animate(animation, node, "translation", "LINEAR", &times, &[from, to].concat());
    }

    /// A KHR_animation_pointer channel: `values` (`width` floats a key: SCALAR, VEC2, VEC3 or VEC4) drive `pointer`;
    /// `as_bytes` writes them as unsigned bytes (a boolean's type). Marks the extension used.
    #[allow(clippy::too_many_arguments)]
    pub fn animate_pointer(
        &mut self,
        animation: &str,
        pointer: &str,
        interpolation: &str,
        times: &[f32],
        values: &[f32],
        width: usize,
        as_bytes: bool,
    ) {
        self.use_extension("KHR_animation_pointer");
        let target = json!({ "path": "pointer", "extensions": { "KHR_animation_pointer": { "pointer": pointer } } });
        self.channel(animation, target, interpolation, times, values, width, as_bytes);
    }

    /// A sampler over `times` and `values` (`width` floats a key, or unsigned bytes) and a channel of it on `target`,
    /// in animation `animation` (created, by name, at first use).
    #[allow(clippy::too_many_arguments)]
    fn channel(
        &mut self,
        animation: &str,
        target: Value,
        interpolation: &str,
        times: &[f32],
        values: &[f32],
        width: usize,
        as_bytes: bool,
    ) {
        let input: Vec<[f32; 1]> = times.iter().map(|&t| [t]).collect();
        let input = self.float_accessor(&input, "SCALAR");
        let lo = times.iter().copied().fold(f32::INFINITY, f32::min);
        let hi = times.iter().copied().fold(f32::NEG_INFINITY, f32::max);
        self.accessors[input]["min"] = json!([lo]);
        self.accessors[input]["max"] = json!([hi]);
        let output = if as_bytes {
            let bytes: Vec<u8> = values.iter().map(|&v| v as u8).collect();
            let v = self.push_view(&bytes, 34962);
            self.accessors
                .push(json!({ "bufferView": v, "componentType": 5121, "count": values.len(), "type": "SCALAR" }));
            self.accessors.len() - 1
        } else {
            match width {
                2 => self.float_accessor(&values.chunks(2).map(|c| [c[0], c[1]]).collect::<Vec<_>>(), "VEC2"),
                3 => self.float_accessor(
                    &values.chunks(3).map(|c| [c[0], c[1], c[2]]).collect::<Vec<_>>(),
                    "VEC3",
                ),
                4 => self.float_accessor(
                    &values.chunks(4).map(|c| [c[0], c[1], c[2], c[3]]).collect::<Vec<_>>(),
                    "VEC4",
                ),
                _ => self.float_accessor(&values.iter().map(|&v| [v]).collect::<Vec<_>>(), "SCALAR"),
            }
        };
        let a = match self.animations.iter().position(|(n, _, _)| n == animation) {
            Some(a) => a,
            None => {
                self.animations.push((animation.to_string(), Vec::new(), Vec::new()));
                self.animations.len() - 1
            }
        };
        // Animation data is no vertex buffer: a view target there is an error to the Khronos validator.
        self.untarget(input);
        self.untarget(output);
        let (_, samplers, channels) = &mut self.animations[a];
        samplers.push(json!({ "input": input, "output": output, "interpolation": interpolation }));
        channels.push(json!({ "sampler": samplers.len() - 1, "target": target }));
    }

    /// Drops the `target` of `accessor`'s bufferView: for data that is not vertex attributes (animation samplers,
    /// inverse bind matrices).
    fn untarget(&mut self, accessor: usize) {
        let view = self.accessors[accessor]["bufferView"].as_u64().unwrap() as usize;
        self.views[view].as_object_mut().unwrap().remove("target");
    }

    /// Gives the last mesh a morph target of position displacements (one per vertex) and the mesh default weights.
    pub fn add_morph_target(&mut self, displacements: &[[f32; 3]], weights: &[f32]) {
        let acc = self.float_accessor(displacements, "VEC3");
        let (lo, hi) = bounds(displacements);
        self.accessors[acc]["min"] = json!(lo);
        self.accessors[acc]["max"] = json!(hi);
        let mesh = self.meshes.last_mut().unwrap();
        let prim = &mut mesh["primitives"][0];
        if prim.get("targets").is_none() {
            prim["targets"] = json!([]);
        }
        prim["targets"].as_array_mut().unwrap().push(json!({ "POSITION": acc }));
        mesh["weights"] = json!(weights);
    }

    /// Skins the last mesh (placed by the last mesh node): JOINTS_0 and WEIGHTS_0 per vertex, and a skin over
    /// `joints` (node indices) with their inverse bind matrices (column-major, as glTF stores them).
    pub fn skin_last_mesh(
        &mut self,
        joints: &[usize],
        inverse_bind: &[[f32; 16]],
        vertex_joints: &[[u16; 4]],
        vertex_weights: &[[f32; 4]],
    ) {
        let jb: Vec<u8> = vertex_joints.iter().flatten().flat_map(|j| j.to_le_bytes()).collect();
        let jv = self.push_view(&jb, 34962);
        self.accessors
            .push(json!({ "bufferView": jv, "componentType": 5123, "count": vertex_joints.len(), "type": "VEC4" }));
        let ja = self.accessors.len() - 1;
        self.set_attribute("JOINTS_0", ja);
        let wa = self.float_accessor(vertex_weights, "VEC4");
        self.set_attribute("WEIGHTS_0", wa);
        let ibm = self.float_accessor(inverse_bind, "MAT4");
        self.untarget(ibm);
        self.skins.push(json!({ "joints": joints, "inverseBindMatrices": ibm }));
        let mesh = self.meshes.len() - 1;
        let node = (self.nodes.iter_mut().rev())
            .find(|n| n.get("mesh").and_then(Value::as_u64) == Some(mesh as u64))
            .unwrap();
        node["skin"] = json!(self.skins.len() - 1);
    }

    /// Sets node `i`'s glTF fields (e.g. its `translation`).
    pub fn transform_node(&mut self, i: usize, fields: Value) {
        for (k, v) in fields.as_object().unwrap() {
            self.nodes[i][k] = v.clone();
        }
    }

    /// Sets the last node's glTF transform fields (`translation`, `rotation`, `scale` or `matrix`).
    pub fn transform_last_node(&mut self, transform: Value) {
        let node = self.nodes.last_mut().unwrap();
        for (k, v) in transform.as_object().unwrap() {
            node[k] = v.clone();
        }
    }

    /// Another node placing the last mesh, which the file then holds once for both.
    pub fn place_last_mesh(&mut self, name: &str, transform: Value) {
        self.nodes.push(json!({ "name": name, "mesh": self.meshes.len() - 1 }));
        self.transform_last_node(transform);
    }

    /// A UV sphere with smooth vertex normals, front faces outwards.
    pub fn sphere(&mut self, name: &str, center: [f32; 3], radius: f32, material: usize) {
        self.uv_sphere(name, center, radius, material, true);
    }

    /// A UV sphere, with smooth vertex normals or faceted (geometric normals only: exact energy balance).
    pub fn uv_sphere(&mut self, name: &str, center: [f32; 3], radius: f32, material: usize, smooth: bool) {
        let (positions, normals, _, indices) = Self::sphere_mesh(center, radius);
        self.mesh_with_normals(name, &positions, smooth.then_some(&normals[..]), &indices, material);
    }

    /// A smooth UV sphere with TEXCOORD_0: u around the equator, v from the north pole (0) to the south (1).
    pub fn textured_sphere(&mut self, name: &str, center: [f32; 3], radius: f32, material: usize) {
        let (positions, normals, uvs, indices) = Self::sphere_mesh(center, radius);
        self.mesh_with_attributes(name, &positions, Some(&normals), &uvs, None, &indices, material);
    }

    #[allow(clippy::type_complexity)]
    fn sphere_mesh(center: [f32; 3], radius: f32) -> (Vec<[f32; 3]>, Vec<[f32; 3]>, Vec<[f32; 2]>, Vec<u32>) {
        let (rings, segments) = (32u32, 64u32);
        let c = Vec3::from(center);
        let mut positions = Vec::new();
        let mut normals = Vec::new();
        let mut uvs = Vec::new();
        for i in 0..=rings {
            let theta = std::f32::consts::PI * i as f32 / rings as f32;
            for j in 0..=segments {
                let phi = 2.0 * std::f32::consts::PI * j as f32 / segments as f32;
                let n = Vec3::new(theta.sin() * phi.cos(), theta.cos(), theta.sin() * phi.sin());
                positions.push((c + n * radius).to_array());
                normals.push(n.to_array());
                uvs.push([j as f32 / segments as f32, i as f32 / rings as f32]);
            }
        }
        let at = |i: u32, j: u32| i * (segments + 1) + j;
        let mut indices = Vec::new();
        for i in 0..rings {
            for j in 0..segments {
                // Counter-clockwise seen from outside.
                indices.extend([at(i, j), at(i, j + 1), at(i + 1, j)]);
                indices.extend([at(i, j + 1), at(i + 1, j + 1), at(i + 1, j)]);
            }
        }
        (positions, normals, uvs, indices)
    }

    /// The stage the traversal tests place things on: a 6 m floor at y = 0 facing up, and a 2 m lamp 3 m above it
    /// facing down.
    pub fn floor_and_lamp(&mut self, floor: usize, lamp: usize) {
        self.quad("floor", square(3.0, 0.0), floor, FACING_UP);
        self.quad("lamp", square(1.0, 3.0), lamp, FACING_DOWN);
    }

    /// A planar quad (corners in order around it); when `facing` is given the front face is turned towards it.
    pub fn quad(&mut self, name: &str, corners: [[f32; 3]; 4], material: usize, facing: Option<[f32; 3]>) {
        let c = corners.map(Vec3::from);
        let n = (c[1] - c[0]).cross(c[2] - c[0]);
        let flip = facing.is_some_and(|f| n.dot(Vec3::from(f)) < 0.0);
        let idx: &[u32] = if flip { &[0, 2, 1, 0, 3, 2] } else { &[0, 1, 2, 0, 2, 3] };
        self.mesh(name, &corners, idx, material);
    }

    /// An axis-aligned box whose faces look inwards (for closed rooms) or outwards.
    pub fn cube(&mut self, name: &str, lo: [f32; 3], hi: [f32; 3], material: usize, inward: bool) {
        let (l, h) = (Vec3::from(lo), Vec3::from(hi));
        let center = (l + h) * 0.5;
        let v = |x: f32, y: f32, z: f32| [x, y, z];
        let faces = [
            [v(l.x, l.y, l.z), v(l.x, h.y, l.z), v(l.x, h.y, h.z), v(l.x, l.y, h.z)],
            [v(h.x, l.y, l.z), v(h.x, h.y, l.z), v(h.x, h.y, h.z), v(h.x, l.y, h.z)],
            [v(l.x, l.y, l.z), v(h.x, l.y, l.z), v(h.x, l.y, h.z), v(l.x, l.y, h.z)],
            [v(l.x, h.y, l.z), v(h.x, h.y, l.z), v(h.x, h.y, h.z), v(l.x, h.y, h.z)],
            [v(l.x, l.y, l.z), v(h.x, l.y, l.z), v(h.x, h.y, l.z), v(l.x, h.y, l.z)],
            [v(l.x, l.y, h.z), v(h.x, l.y, h.z), v(h.x, h.y, h.z), v(l.x, h.y, h.z)],
        ];
        for (i, f) in faces.iter().enumerate() {
            let fc = f.iter().map(|p| Vec3::from(*p)).sum::<Vec3>() / 4.0;
            let out = fc - center;
            let facing = if inward { -out } else { out };
            self.quad(&format!("{name} {i}"), *f, material, Some(facing.into()));
        }
    }

    /// A KHR_lights_punctual light on its own node at `position`, pointing along `rotation` applied to -z.
    /// `light` is the light object without its type-independent parts, e.g. json!({"type": "point"}).
    pub fn punctual(
        &mut self,
        mut light: Value,
        color: [f32; 3],
        intensity: f32,
        position: [f32; 3],
        rotation: [f32; 4],
    ) {
        light["color"] = json!(color);
        light["intensity"] = json!(intensity);
        self.lights.push(light);
        self.use_extension("KHR_lights_punctual");
        self.nodes.push(json!({
            "name": format!("light {}", self.lights.len() - 1),
            "translation": position,
            "rotation": rotation,
            "extensions": { "KHR_lights_punctual": { "light": self.lights.len() - 1 } },
        }));
    }

    /// A point light (KHR_lights_punctual) at `position`.
    pub fn point_light(&mut self, color: [f32; 3], intensity: f32, position: [f32; 3]) {
        self.punctual(
            json!({ "type": "point" }),
            color,
            intensity,
            position,
            [0.0, 0.0, 0.0, 1.0],
        );
    }

    /// A directional light (KHR_lights_punctual) on a node at `position` turned by `rotation`: it shines along the
    /// turned -z.
    pub fn directional_light(&mut self, color: [f32; 3], intensity: f32, position: [f32; 3], rotation: [f32; 4]) {
        self.punctual(json!({ "type": "directional" }), color, intensity, position, rotation);
    }

    /// A perspective camera at `eye` looking at `target`; yfov in degrees.
    pub fn camera(&mut self, eye: [f32; 3], target: [f32; 3], up: [f32; 3], yfov_deg: f32) {
        let camera = json!({ "type": "perspective", "perspective": { "yfov": yfov_deg.to_radians(), "znear": 0.01, "aspectRatio": 1.0 } });
        self.place_camera(camera, eye, target, up);
    }

    /// An orthographic camera at `eye` looking at `target`, its image plane `2 ymag` high (xmag as given).
    pub fn orthographic_camera(&mut self, eye: [f32; 3], target: [f32; 3], up: [f32; 3], xmag: f32, ymag: f32) {
        let camera = json!({ "type": "orthographic", "orthographic": { "xmag": xmag, "ymag": ymag, "znear": 0.0, "zfar": 100.0 } });
        self.place_camera(camera, eye, target, up);
    }

    fn place_camera(&mut self, camera: serde_json::Value, eye: [f32; 3], target: [f32; 3], up: [f32; 3]) {
        // glTF cameras look down -Z with +Y up.
        let forward = (Vec3::from(target) - Vec3::from(eye)).normalize();
        let right = forward.cross(Vec3::from(up)).normalize();
        let true_up = right.cross(forward);
        let rot = Quat::from_mat3(&Mat3::from_cols(right, true_up, -forward)).normalize();
        self.cameras.push(camera);
        self.nodes.push(json!({ "name": "camera", "camera": self.cameras.len() - 1, "translation": eye, "rotation": rot.to_array() }));
    }

    pub fn to_json(&self) -> String {
        let uri = format!("data:application/octet-stream;base64,{}", base64(&self.bin));
        serde_json::to_string_pretty(&self.document(Some(&uri))).unwrap() + "\n"
    }

    /// The same scene with its buffer in a separate file named `bin_name` (returns the JSON and the bytes).
    pub fn to_json_and_bin(&self, bin_name: &str) -> (String, Vec<u8>) {
        (
            serde_json::to_string_pretty(&self.document(Some(bin_name))).unwrap(),
            self.bin.clone(),
        )
    }

    /// The same scene as a binary .glb: a JSON chunk and a BIN chunk, each padded to 4 bytes.
    pub fn to_glb(&self) -> Vec<u8> {
        let mut json = serde_json::to_vec(&self.document(None)).unwrap();
        while !json.len().is_multiple_of(4) {
            json.push(b' ');
        }
        let mut bin = self.bin.clone();
        while !bin.len().is_multiple_of(4) {
            bin.push(0);
        }
        let total = 12 + 8 + json.len() + 8 + bin.len();
        let mut out = Vec::with_capacity(total);
        out.extend_from_slice(b"glTF");
        out.extend_from_slice(&2u32.to_le_bytes());
        out.extend_from_slice(&(total as u32).to_le_bytes());
        out.extend_from_slice(&(json.len() as u32).to_le_bytes());
        out.extend_from_slice(b"JSON");
        out.extend_from_slice(&json);
        out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
        out.extend_from_slice(b"BIN\0");
        out.extend_from_slice(&bin);
        out
    }

    /// The glTF JSON; `uri` None means the buffer is the GLB's BIN chunk.
    fn document(&self, uri: Option<&str>) -> Value {
        let buffer = match uri {
            Some(u) => json!({ "byteLength": self.bin.len(), "uri": u }),
            None => json!({ "byteLength": self.bin.len() }),
        };
        let mut doc = json!({
            "asset": { "version": "2.0", "generator": "pathwave tests/common/gltf_builder.rs" },
            "scene": 0,
            "scenes": [{ "nodes": self.roots() }],
            "nodes": self.nodes,
            "meshes": self.meshes,
            "materials": self.materials,
            "accessors": self.accessors,
            "bufferViews": self.views,
            "buffers": [buffer],
        });
        if !self.cameras.is_empty() {
            doc["cameras"] = json!(self.cameras);
        }
        if !self.animations.is_empty() {
            let animations: Vec<Value> = (self.animations.iter())
                .map(|(name, samplers, channels)| json!({ "name": name, "samplers": samplers, "channels": channels }))
                .collect();
            doc["animations"] = json!(animations);
        }
        if !self.skins.is_empty() {
            doc["skins"] = json!(self.skins);
        }
        if !self.extensions.is_empty() {
            doc["extensionsUsed"] = json!(self.extensions);
        }
        if !self.lights.is_empty() {
            doc["extensions"]["KHR_lights_punctual"] = json!({ "lights": self.lights });
        }
        for (name, v) in &self.root_extensions {
            doc["extensions"][*name] = v.clone();
        }
        if !self.images.is_empty() {
            doc["images"] = json!(self.images);
            doc["samplers"] = json!(self.samplers);
            doc["textures"] = json!(self.textures);
        }
        doc
    }

    /// Every node no other node lists as a child, in order.
    fn roots(&self) -> Vec<usize> {
        let children: Vec<u64> = (self.nodes.iter())
            .filter_map(|n| n.get("children").and_then(Value::as_array))
            .flatten()
            .filter_map(Value::as_u64)
            .collect();
        (0..self.nodes.len())
            .filter(|i| !children.contains(&(*i as u64)))
            .collect()
    }

    pub fn write(&self, path: &std::path::Path) {
        std::fs::write(path, self.to_json()).unwrap();
    }
}

/// The smallest and the largest of `points` in each coordinate (an accessor's min and max).
fn bounds(points: &[[f32; 3]]) -> ([f32; 3], [f32; 3]) {
    let mut lo = [f32::INFINITY; 3];
    let mut hi = [f32::NEG_INFINITY; 3];
    for p in points {
        for c in 0..3 {
            lo[c] = lo[c].min(p[c]);
            hi[c] = hi[c].max(p[c]);
        }
    }
    (lo, hi)
}

fn base64(data: &[u8]) -> String {
    const A: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut s = String::with_capacity(data.len().div_ceil(3) * 4);
    for c in data.chunks(3) {
        let b = [c[0], *c.get(1).unwrap_or(&0), *c.get(2).unwrap_or(&0)];
        let n = (b[0] as u32) << 16 | (b[1] as u32) << 8 | b[2] as u32;
        for (i, shift) in [18, 12, 6, 0].into_iter().enumerate() {
            if i <= c.len() {
                s.push(A[(n >> shift & 63) as usize] as char);
            } else {
                s.push('=');
            }
        }
    }
    s
}
