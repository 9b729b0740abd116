//! Meshes: each primitive's accessors checked against what the reader assumes, then read into object-space
//! vertex arrays and triangles.
use super::quantized::{POSITION_TYPES, TEXCOORD_TYPES, UNIT_TYPES};
use super::{scene_err, Loader};
use crate::error::Error;
use crate::scene::{AlphaMode, Material, Mesh, Primitive};
use glam::{Vec2, Vec3, Vec4};
use gltf::accessor::{DataType, Dimensions};
use gltf::mesh::Mode;

/// What an accessor accepted by `Loader::check_accessor` holds.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Contents {
    /// Elements in a bufferView, which gltf's reader can read.
    Data,
    /// No bufferView and no sparse: every element is zero, and there is nothing to read.
    Zeros,
}

/// The optional attributes of a primitive that are read: present, with data, and (texture coordinates and
/// tangents) of use to its material.
#[derive(Default)]
struct Present {
    colors: bool,
    normals: bool,
    texcoords: [bool; 2],
    tangents: bool,
}

impl Loader<'_> {
    /// Reads every primitive of a mesh; those that cannot render are skipped with a warning.
    pub(super) fn mesh(&mut self, mesh: &gltf::Mesh, default_material: u32) -> Result<Mesh, Error> {
        let name = mesh
            .name()
            .map(str::to_string)
            .unwrap_or_else(|| format!("#{}", mesh.index()));
        let mut primitives = Vec::new();
        for prim in mesh.primitives() {
            primitives.extend(self.primitive(&name, &prim, default_material)?);
        }
        Ok(Mesh { name, primitives })
    }

    /// Checks an accessor against what its reader assumes, so malformed files give errors instead of panics.
    /// An accessor without bufferView and sparse holds zeros (valid glTF); it must not be given to the reader.
    pub(super) fn check_accessor(
        &self,
        acc: &gltf::Accessor,
        what: &str,
        types: &[DataType],
        dims: Dimensions,
        normalized_ints: bool,
    ) -> Result<Contents, Error> {
        let err = |m: String| scene_err(self.path, format!("accessor {} ({what}): {m}", acc.index()));
        if acc.count() == 0 {
            return Err(err("count is 0".into()));
        }
        // Integer texture coordinates must be normalized; nothing else may be.
        let normalized_ok = acc.normalized() == (normalized_ints && acc.data_type() != DataType::F32);
        if !types.contains(&acc.data_type()) || acc.dimensions() != dims || !normalized_ok {
            return Err(err(format!(
                "expected {dims:?} of {types:?}, found {:?} of {:?}{}",
                acc.dimensions(),
                acc.data_type(),
                if acc.normalized() { " (normalized)" } else { "" }
            )));
        }
        self.check_extent(acc, what)
    }

    /// `check_accessor` for a vertex attribute that may take any (component type, normalized) pair of `allowed`
    /// (core glTF's and KHR_mesh_quantization's; see `quantized`).
    pub(super) fn check_attribute(
        &self,
        acc: &gltf::Accessor,
        what: &str,
        allowed: &[(DataType, bool)],
        dims: Dimensions,
    ) -> Result<Contents, Error> {
        let err = |m: String| scene_err(self.path, format!("accessor {} ({what}): {m}", acc.index()));
        if acc.count() == 0 {
            return Err(err("count is 0".into()));
        }
        if !allowed.contains(&(acc.data_type(), acc.normalized())) || acc.dimensions() != dims {
            let names: Vec<String> = allowed
                .iter()
                .map(|(t, n)| format!("{t:?}{}", if *n { " normalized" } else { "" }))
                .collect();
            return Err(err(format!(
                "expected {dims:?} of {}, found {:?} of {:?}{}",
                names.join(", "),
                acc.dimensions(),
                acc.data_type(),
                if acc.normalized() { " normalized" } else { "" }
            )));
        }
        // Core glTF allows floats, and normalized unsigned bytes and shorts for texture coordinates; the other
        // integer types need KHR_mesh_quantization, which a file must then name (the Khronos validator calls it an
        // error otherwise: a reader without the extension would misread the geometry).
        let core = acc.data_type() == DataType::F32
            || (what.starts_with("TEXCOORD")
                && acc.normalized()
                && matches!(acc.data_type(), DataType::U8 | DataType::U16));
        if !core && !self.document.extensions_used().any(|e| e == "KHR_mesh_quantization") {
            return Err(err(format!(
                "{:?}{} components need KHR_mesh_quantization, which the file does not list in extensionsUsed",
                acc.data_type(),
                if acc.normalized() { " normalized" } else { "" }
            )));
        }
        self.check_extent(acc, what)
    }

    /// The accessor's data lies inside its bufferView and buffer (and its sparse part is well formed).
    fn check_extent(&self, acc: &gltf::Accessor, what: &str) -> Result<Contents, Error> {
        let err = |m: String| scene_err(self.path, format!("accessor {} ({what}): {m}", acc.index()));
        if acc.view().is_none() && acc.sparse().is_none() {
            return Ok(Contents::Zeros);
        }
        if let Some(sparse) = acc.sparse() {
            self.check_sparse(acc, &sparse).map_err(err)?;
            // Without a bufferView the base is zeros, which gltf's reader supplies.
            if acc.view().is_none() {
                return Ok(Contents::Data);
            }
        }
        let view = acc.view().ok_or_else(|| err("has no bufferView".into()))?;
        let size = acc.size();
        let stride = view.stride().unwrap_or(size);
        if stride < size {
            return Err(err(format!(
                "byteStride {stride} is smaller than the element size {size}"
            )));
        }
        let buffer_len = self.buffers.get(view.buffer().index()).map(|b| b.len()).unwrap_or(0);
        let view_end = view.offset().checked_add(view.length());
        if view_end.is_none_or(|e| e > buffer_len) {
            return Err(err(format!(
                "bufferView {} runs past the end of its buffer",
                view.index()
            )));
        }
        let end = (acc.count() - 1)
            .checked_mul(stride)
            .and_then(|x| x.checked_add(size))
            .and_then(|x| x.checked_add(acc.offset()));
        if end.is_none_or(|e| e > view.length()) {
            return Err(err(format!("runs past the end of bufferView {}", view.index())));
        }
        Ok(Contents::Data)
    }

    /// A sparse accessor's indices and values lie inside their bufferViews and buffers, and its indices are strictly
    /// increasing and below the accessor's count, as glTF requires (gltf's reader would silently skip the others).
    fn check_sparse(&self, acc: &gltf::Accessor, sparse: &gltf::accessor::sparse::Sparse) -> Result<(), String> {
        let count = sparse.count();
        if count == 0 || count > acc.count() {
            return Err(format!(
                "sparse count {count} is not between 1 and the accessor's count {}",
                acc.count()
            ));
        }
        // The bytes [offset, offset + stride * (count - 1) + size) of a view, as gltf's reader slices them.
        let slice = |view: gltf::buffer::View, offset: usize, size: usize, what: &str| -> Result<&[u8], String> {
            let stride = view.stride().unwrap_or(size);
            let buffer = self.buffers.get(view.buffer().index()).map(|b| &b[..]).unwrap_or(&[]);
            let in_buffer = view.offset().checked_add(view.length()).filter(|&e| e <= buffer.len());
            let end = (count - 1)
                .checked_mul(stride)
                .and_then(|x| x.checked_add(size))
                .and_then(|x| x.checked_add(offset));
            match (in_buffer, end) {
                (Some(_), Some(end)) if stride >= size && end <= view.length() => {
                    Ok(&buffer[view.offset() + offset..][..end - offset])
                }
                _ => Err(format!(
                    "its sparse {what} run past the end of bufferView {}",
                    view.index()
                )),
            }
        };
        let index_size = sparse.indices().index_type().size();
        let indices = slice(
            sparse.indices().view(),
            sparse.indices().offset(),
            index_size,
            "indices",
        )?;
        slice(sparse.values().view(), sparse.values().offset(), acc.size(), "values")?;
        let stride = sparse.indices().view().stride().unwrap_or(index_size);
        let mut last: Option<u64> = None;
        for k in 0..count {
            let b = &indices[k * stride..k * stride + index_size];
            let i = match index_size {
                1 => b[0] as u64,
                2 => u16::from_le_bytes([b[0], b[1]]) as u64,
                _ => u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as u64,
            };
            if i >= acc.count() as u64 || last.is_some_and(|l| i <= l) {
                return Err(format!(
                    "sparse index {i} (entry {k}) is out of range or not above the one before it"
                ));
            }
            last = Some(i);
        }
        Ok(())
    }

    fn primitive(
        &mut self,
        mesh_name: &str,
        prim: &gltf::Primitive,
        default_material: u32,
    ) -> Result<Option<Primitive>, Error> {
        let mode = prim.mode();
        if !matches!(mode, Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan) {
            self.warn(format!(
                "mesh '{mesh_name}': a primitive of mode {mode:?} is skipped (only triangles render)"
            ));
            self.skipped_primitives += 1;
            return Ok(None);
        }
        let Some(mut present) = self.check_geometry(mesh_name, prim)? else {
            return Ok(None);
        };
        let material = self
            .variant_material(mesh_name, prim)?
            .unwrap_or(prim.material().index().map(|i| i as u32).unwrap_or(default_material));
        let mat = self.scene.materials[material as usize].clone();
        self.check_shading(mesh_name, prim, &mat, &mut present)?;
        let (read, indices) = self.read(mesh_name, prim, &present)?;
        self.check_counts(mesh_name, &read, &indices)?;
        let mut p = Primitive {
            triangles: unroll(mode, &indices),
            material,
            ..read
        };
        self.read_deformation(mesh_name, prim, &mut p)?;
        self.unfold_vertex_alpha(material, &p);
        Ok(Some(p))
    }

    /// COLOR_0's alpha multiplies the material's (glTF: COLOR_0 multiplies baseColorFactor), so a MASK or BLEND
    /// material the loader found opaque (its factor and texture leave alpha at 1) is alpha-tested again once a
    /// primitive's vertex alpha goes below 1. Under OPAQUE, alpha is ignored, as the spec says.
    fn unfold_vertex_alpha(&mut self, material: u32, p: &Primitive) {
        if !p.colors.as_ref().is_some_and(|c| c.iter().any(|v| v.w < 1.0)) {
            return;
        }
        let Some(declared) = self.document.materials().nth(material as usize) else {
            return;
        };
        let m = &mut self.scene.materials[material as usize];
        if m.alpha_mode == AlphaMode::Opaque {
            m.alpha_mode = match declared.alpha_mode() {
                gltf::material::AlphaMode::Mask => AlphaMode::Mask(declared.alpha_cutoff().unwrap_or(0.5)),
                gltf::material::AlphaMode::Blend => AlphaMode::Blend,
                gltf::material::AlphaMode::Opaque => AlphaMode::Opaque,
            };
        }
    }

    /// The material the selected KHR_materials_variants variant maps this primitive to, if it maps it. Every
    /// mapping is checked, whichever variant is selected, so a file is refused or read the same for all of them.
    fn variant_material(&self, mesh_name: &str, prim: &gltf::Primitive) -> Result<Option<u32>, Error> {
        let mut chosen = None;
        for (k, mapping) in prim.mappings().enumerate() {
            let err = |m: String| {
                scene_err(
                    self.path,
                    format!("mesh '{mesh_name}': KHR_materials_variants mapping {k}: {m}"),
                )
            };
            let material = mapping
                .material()
                .index()
                .ok_or_else(|| err("names a material that does not exist".into()))?;
            for &v in mapping.variants() {
                if v as usize >= self.scene.variants.len() {
                    return Err(err(format!(
                        "names variant {v}, but the file has {}",
                        self.scene.variants.len()
                    )));
                }
                if Some(v) == self.variant {
                    chosen = Some(material as u32);
                }
            }
        }
        Ok(chosen)
    }

    /// COLOR_0, POSITION, NORMAL and the indices; `None` when the primitive is skipped (with a warning).
    fn check_geometry(&mut self, mesh_name: &str, prim: &gltf::Primitive) -> Result<Option<Present>, Error> {
        let mut present = Present::default();
        if let Some(acc) = prim.get(&gltf::Semantic::Colors(0)) {
            let dims = if acc.dimensions() == Dimensions::Vec3 {
                Dimensions::Vec3
            } else {
                Dimensions::Vec4
            };
            let types = [DataType::F32, DataType::U8, DataType::U16];
            present.colors = self.check_accessor(&acc, "COLOR_0", &types, dims, true)? == Contents::Data;
        }
        let Some(pos_acc) = prim.get(&gltf::Semantic::Positions) else {
            self.warn(format!("mesh '{mesh_name}': a primitive without POSITION is skipped"));
            return Ok(None);
        };
        // All-zero positions or indices make every triangle degenerate.
        if self.check_attribute(&pos_acc, "POSITION", POSITION_TYPES, Dimensions::Vec3)? == Contents::Zeros {
            self.warn(format!(
                "mesh '{mesh_name}': POSITION accessor {} has no bufferView (all zeros); the primitive is skipped",
                pos_acc.index()
            ));
            return Ok(None);
        }
        if let Some(n) = prim.get(&gltf::Semantic::Normals) {
            present.normals = true;
            if self.check_attribute(&n, "NORMAL", UNIT_TYPES, Dimensions::Vec3)? == Contents::Zeros {
                self.warn(format!(
                    "mesh '{mesh_name}': NORMAL accessor {} has no bufferView (all zeros); face normals are used",
                    n.index()
                ));
                present.normals = false;
            }
        }
        if let Some(i) = prim.indices() {
            let types = [DataType::U8, DataType::U16, DataType::U32];
            if self.check_accessor(&i, "indices", &types, Dimensions::Scalar, false)? == Contents::Zeros {
                self.warn(format!(
                    "mesh '{mesh_name}': indices accessor {} has no bufferView (all zeros); the primitive is skipped",
                    i.index()
                ));
                return Ok(None);
            }
        }
        Ok(Some(present))
    }

    /// Texture coordinates and tangents matter only to textured materials; other primitives skip reading them.
    fn check_shading(
        &mut self,
        mesh_name: &str,
        prim: &gltf::Primitive,
        mat: &Material,
        present: &mut Present,
    ) -> Result<(), Error> {
        if mat.reads_texcoords() {
            for (set, slot) in present.texcoords.iter_mut().enumerate() {
                if let Some(acc) = prim.get(&gltf::Semantic::TexCoords(set as u32)) {
                    let what = format!("TEXCOORD_{set}");
                    *slot = self.check_attribute(&acc, &what, TEXCOORD_TYPES, Dimensions::Vec2)? == Contents::Data;
                }
            }
            for r in mat.texture_refs().iter().flatten() {
                if !present.texcoords[r.tex_coord as usize] {
                    self.warn(format!(
                        "mesh '{mesh_name}': material '{}' reads TEXCOORD_{}, which the primitive lacks; its texture is \
                         sampled at uv (0, 0)",
                        mat.name, r.tex_coord
                    ));
                }
            }
        }
        if mat.tangent_set().is_some() {
            if let Some(acc) = prim.get(&gltf::Semantic::Tangents) {
                present.tangents =
                    self.check_attribute(&acc, "TANGENT", UNIT_TYPES, Dimensions::Vec4)? == Contents::Data;
            }
        }
        Ok(())
    }

    /// The vertex attributes (in a Primitive without triangles) and the indices, as the file holds them.
    fn read(&self, mesh_name: &str, prim: &gltf::Primitive, present: &Present) -> Result<(Primitive, Vec<u32>), Error> {
        let buffers = self.buffers;
        let reader = prim.reader(|b| buffers.get(b.index()).map(|d| &d[..]));
        let mut texcoords: [Option<Vec<Vec2>>; 2] = [None, None];
        for (set, &read) in present.texcoords.iter().enumerate() {
            if read {
                let uvs: Vec<Vec2> = prim
                    .get(&gltf::Semantic::TexCoords(set as u32))
                    .and_then(|acc| self.read_floats::<2>(&acc))
                    .map(|t| t.into_iter().map(Vec2::from).collect())
                    .unwrap_or_default();
                if uvs.iter().any(|uv| !uv.is_finite()) {
                    return Err(scene_err(
                        self.path,
                        format!("mesh '{mesh_name}': TEXCOORD_{set} holds a non-finite value"),
                    ));
                }
                texcoords[set] = Some(uvs);
            }
        }
        let colors: Option<Vec<Vec4>> = match present.colors {
            true => reader.read_colors(0).map(|c| {
                c.into_rgba_f32()
                    .map(|c| Vec4::from(c).clamp(Vec4::ZERO, Vec4::ONE))
                    .collect()
            }),
            false => None,
        };
        let attribute = |s: gltf::Semantic| prim.get(&s);
        let tangents: Option<Vec<Vec4>> = match present.tangents {
            true => attribute(gltf::Semantic::Tangents)
                .and_then(|a| self.read_floats::<4>(&a))
                .map(|t| t.into_iter().map(Vec4::from).collect()),
            false => None,
        };
        let positions: Vec<Vec3> = attribute(gltf::Semantic::Positions)
            .and_then(|a| self.read_floats::<3>(&a))
            .ok_or_else(|| scene_err(self.path, format!("mesh '{mesh_name}': cannot read POSITION")))?
            .into_iter()
            .map(Vec3::from)
            .collect();
        // Quantised normals are only close to unit length; float ones are used as the file gives them.
        let normals: Option<Vec<Vec3>> = match attribute(gltf::Semantic::Normals) {
            Some(a) if present.normals => {
                let quantised = a.data_type() != DataType::F32;
                self.read_floats::<3>(&a).map(|n| {
                    n.into_iter()
                        .map(|n| {
                            if quantised {
                                Vec3::from(n).normalize_or_zero()
                            } else {
                                Vec3::from(n)
                            }
                        })
                        .collect()
                })
            }
            _ => None,
        };
        let indices: Vec<u32> = match reader.read_indices() {
            Some(i) => i.into_u32().collect(),
            None => (0..positions.len() as u32).collect(),
        };
        let p = Primitive {
            positions,
            normals,
            texcoords,
            tangents,
            colors,
            ..Default::default()
        };
        Ok((p, indices))
    }

    /// Every attribute as long as POSITION, every index in range and every position finite, so that placing the
    /// primitive cannot fail or panic.
    fn check_counts(&self, mesh_name: &str, p: &Primitive, indices: &[u32]) -> Result<(), Error> {
        let err = |m: String| Err(scene_err(self.path, format!("mesh '{mesh_name}': {m}")));
        let short = |n: usize| n != p.positions.len();
        if p.colors
            .as_ref()
            .is_some_and(|c| short(c.len()) || c.iter().any(|v| !v.is_finite()))
        {
            return err("COLOR_0 has a different count from POSITION or a non-finite value".into());
        }
        if p.texcoords.iter().flatten().any(|u| short(u.len())) || p.tangents.as_ref().is_some_and(|t| short(t.len())) {
            return err("TEXCOORD or TANGENT and POSITION have different counts".into());
        }
        if p.normals.as_ref().is_some_and(|n| short(n.len())) {
            return err("NORMAL and POSITION have different counts".into());
        }
        if let Some(&bad) = indices.iter().find(|&&i| i as usize >= p.positions.len()) {
            return err(format!("index {bad} is out of range ({} vertices)", p.positions.len()));
        }
        if p.positions.iter().any(|p| !p.is_finite()) {
            return err("POSITION holds a non-finite value".into());
        }
        Ok(())
    }
}

/// Triangles of a triangle list, strip or fan.
fn unroll(mode: Mode, indices: &[u32]) -> Vec<[u32; 3]> {
    match mode {
        Mode::Triangles => indices.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect(),
        // Strips alternate winding; swapping odd triangles keeps every front face counter-clockwise.
        Mode::TriangleStrip => (2..indices.len())
            .map(|i| {
                if i % 2 == 0 {
                    [indices[i - 2], indices[i - 1], indices[i]]
                } else {
                    [indices[i - 1], indices[i - 2], indices[i]]
                }
            })
            .collect(),
        _ => (2..indices.len())
            .map(|i| [indices[0], indices[i - 1], indices[i]])
            .collect(),
    }
}
