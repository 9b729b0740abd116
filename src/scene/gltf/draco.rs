//! KHR_draco_mesh_compression: each compressed primitive's Draco stream decoded (the `draco-core` crate) into a
//! buffer of decoded data, and its accessors pointed there, before anything reads them, so the rest of the reader
//! sees plain glTF.
use super::scene_err;
use crate::error::Error;
use draco_core::decode_limits::DecodeLimits;
use draco_core::decoder_buffer::DecoderBuffer;
use draco_core::mesh::Mesh as DracoMesh;
use draco_core::mesh_decoder::MeshDecoder;
use gltf::json::accessor::{ComponentType, GenericComponentType, Type};
use gltf::json::validation::{Checked, USize64};
use gltf::json::{self, Index, Value};
use std::collections::HashSet;
use std::path::Path;

const EXT: &str = "KHR_draco_mesh_compression";

/// Whether any primitive of `doc` is Draco-compressed.
pub(super) fn used(doc: &gltf::Document) -> bool {
    doc.meshes()
        .flat_map(|m| m.primitives())
        .any(|p| p.extension_value(EXT).is_some())
}

/// Decodes every compressed primitive of `root` (whose buffers are `buffers`), appending the decoded vertices and
/// indices as one new buffer and pointing the primitives' accessors at it. The decode of each is bounded by what
/// its accessors declare, which `estimate::load_estimate` has already checked against `--max-memory`.
pub(super) fn decompress(
    path: &Path,
    root: &mut json::Root,
    buffers: &mut Vec<gltf::buffer::Data>,
) -> Result<(), Error> {
    let buffer = Index::new(root.buffers.len() as u32);
    let mut out = Vec::new();
    let mut decoded = HashSet::new();
    // What each decode wrote: its extension JSON, the accessors it filled and the faces accessor it added, so that
    // a primitive naming the same stream with the same accessors (gltf-pipeline writes one of each for meshes of
    // identical geometry) takes what is already there instead of decoding again.
    let mut done: Vec<(Value, Vec<usize>, Option<Index<json::Accessor>>)> = Vec::new();
    for m in 0..root.meshes.len() {
        for p in 0..root.meshes[m].primitives.len() {
            let prim = &root.meshes[m].primitives[p];
            let Some(ext) = prim.extensions.as_ref().and_then(|e| e.others.get(EXT)) else {
                continue;
            };
            let name = root.meshes[m].name.clone().unwrap_or_else(|| format!("#{m}"));
            let err = |msg: String| scene_err(path, format!("mesh '{name}' primitive {p} ({EXT}): {msg}"));
            let ext = ext.clone();
            let stream = stream(root, buffers, &ext).map_err(err)?;
            let plan = Plan::of(root, prim, &ext).map_err(err)?;
            let accessors: Vec<usize> = plan.attributes.iter().map(|(_, a, _)| *a).chain(plan.indices).collect();
            if let Some((_, _, faces)) = done.iter().find(|(e, a, _)| *e == ext && *a == accessors) {
                if faces.is_some() {
                    root.meshes[m].primitives[p].indices = *faces;
                }
                continue;
            }
            for &a in &accessors {
                if !decoded.insert(a) {
                    return Err(err(format!(
                        "accessor {a} is decoded by another Draco primitive too, from another stream or with other \
                         attributes"
                    )));
                }
            }
            let mesh = decode(stream, &plan).map_err(err)?;
            plan.write(root, &mesh, buffer, &mut out).map_err(err)?;
            let mut faces = None;
            if plan.indices.is_none() {
                // A primitive without indices gets an accessor for the decoded faces.
                let indices = push_indices(root, &mesh, buffer, &mut out);
                root.meshes[m].primitives[p].indices = Some(indices);
                faces = Some(indices);
            }
            done.push((ext, accessors, faces));
        }
    }
    if !out.is_empty() {
        root.buffers.push(json::Buffer {
            byte_length: USize64(out.len() as u64),
            name: Some(format!("{EXT} decoded")),
            uri: None,
            extensions: None,
            extras: Default::default(),
        });
        buffers.push(gltf::buffer::Data(out));
    }
    Ok(())
}

/// The compressed bytes the extension's bufferView holds.
fn stream<'b>(root: &json::Root, buffers: &'b [gltf::buffer::Data], ext: &Value) -> Result<&'b [u8], String> {
    let v = (ext.get("bufferView").and_then(Value::as_u64))
        .ok_or("has no bufferView")?
        .try_into()
        .unwrap_or(usize::MAX);
    let view = root
        .buffer_views
        .get(v)
        .ok_or(format!("bufferView {v} does not exist"))?;
    let start = view.byte_offset.map_or(0, |o| o.0);
    let range = usize::try_from(start)
        .ok()
        .and_then(|s| Some(s..s.checked_add(usize::try_from(view.byte_length.0).ok()?)?));
    buffers
        .get(view.buffer.value())
        .zip(range)
        .and_then(|(b, r)| b.0.get(r))
        .ok_or(format!("bufferView {v} runs past the end of its buffer"))
}

/// What one primitive's stream must decode to: (attribute name, accessor, Draco unique id) for each compressed
/// attribute, and the indices accessor if it has one.
struct Plan {
    attributes: Vec<(String, usize, u32)>,
    indices: Option<usize>,
    points: u64,
    /// The triangles the indices accessor declares, or a triangle list over the points without one.
    faces: u64,
}

impl Plan {
    fn of(root: &json::Root, prim: &json::mesh::Primitive, ext: &Value) -> Result<Plan, String> {
        if prim.mode != Checked::Valid(json::mesh::Mode::Triangles) {
            return Err("only triangle lists may be Draco-compressed".into());
        }
        let ids = ext
            .get("attributes")
            .and_then(Value::as_object)
            .ok_or("has no attributes")?;
        let mut attributes = Vec::new();
        for (semantic, accessor) in &prim.attributes {
            let Checked::Valid(semantic) = semantic else { continue };
            let name = semantic.to_string();
            let Some(id) = ids.get(&name) else { continue };
            let id = id
                .as_u64()
                .and_then(|i| u32::try_from(i).ok())
                .ok_or(format!("{name}'s Draco attribute id is not a number"))?;
            attributes.push((name, accessor.value(), id));
        }
        if let Some(missing) = ids.keys().find(|k| !attributes.iter().any(|(n, _, _)| n == *k)) {
            return Err(format!("compresses {missing}, which the primitive does not name"));
        }
        let position = (attributes.iter().find(|(n, _, _)| n == "POSITION"))
            .ok_or("POSITION is not compressed")?
            .1;
        let count = |a: usize| {
            root.accessors
                .get(a)
                .map(|a| a.count.0)
                .ok_or(format!("accessor {a} does not exist"))
        };
        let points = count(position)?;
        for &(ref name, a, _) in &attributes {
            if count(a)? != points {
                return Err(format!("{name}'s accessor {a} and POSITION's have different counts"));
            }
            if root.accessors[a].sparse.is_some() {
                return Err(format!("{name}'s accessor {a} is sparse"));
            }
        }
        let indices = prim.indices.map(|i| i.value());
        let faces = match indices {
            Some(i) => count(i)? / 3,
            None => points / 3,
        };
        Ok(Plan {
            attributes,
            indices,
            points,
            faces,
        })
    }

    /// Writes the decoded attributes in their accessors' component types, and the faces as u32 indices, to `out`,
    /// and points the accessors at them.
    fn write(
        &self,
        root: &mut json::Root,
        mesh: &DracoMesh,
        buffer: Index<json::Buffer>,
        out: &mut Vec<u8>,
    ) -> Result<(), String> {
        if mesh.num_points() as u64 != self.points {
            return Err(format!(
                "the stream decodes {} points where the accessors declare {}",
                mesh.num_points(),
                self.points
            ));
        }
        for (name, a, id) in &self.attributes {
            let attribute = mesh
                .attribute_by_unique_id(*id)
                .ok_or(format!("{name}: the stream has no attribute {id}"))?;
            let acc = &root.accessors[*a];
            let (Checked::Valid(GenericComponentType(kind)), Checked::Valid(ty)) = (acc.component_type, acc.type_)
            else {
                return Err(format!("{name}'s accessor {a} has an unknown type"));
            };
            let components = ty.multiplicity();
            if (attribute.num_components() as usize) < components {
                return Err(format!(
                    "{name}: the stream's attribute has {} components where accessor {a} has {components}",
                    attribute.num_components()
                ));
            }
            let values = attribute.read_f32s(mesh.num_points(), components);
            let start = append_view(out);
            for v in values {
                push_component(out, kind, v).ok_or(format!(
                    "{name}: decoded value {v} does not fit accessor {a}'s {kind:?}"
                ))?;
            }
            finish_view(root, buffer, out, start);
            let view = Index::new(root.buffer_views.len() as u32 - 1);
            let acc = &mut root.accessors[*a];
            acc.buffer_view = Some(view);
            acc.byte_offset = None;
        }
        if let Some(i) = self.indices {
            if mesh.num_faces() as u64 * 3 != root.accessors[i].count.0 {
                return Err(format!(
                    "the stream decodes {} triangles where indices accessor {i} declares {} indices",
                    mesh.num_faces(),
                    root.accessors[i].count.0
                ));
            }
            let view = write_faces(root, mesh, buffer, out);
            let acc = &mut root.accessors[i];
            acc.buffer_view = Some(view);
            acc.byte_offset = None;
            acc.component_type = Checked::Valid(GenericComponentType(ComponentType::U32));
            acc.type_ = Checked::Valid(Type::Scalar);
            acc.normalized = false;
            acc.sparse = None;
        }
        Ok(())
    }
}

/// Decodes `stream`, its output bounded by what the plan declares.
fn decode(stream: &[u8], plan: &Plan) -> Result<DracoMesh, String> {
    let limits = DecodeLimits::default()
        .with_max_points(plan.points)
        .with_max_faces(plan.faces)
        // The widest attribute glTF has is a 4 x f32 vector, or a 4 x 4 matrix of f32 (64 bytes).
        .with_max_decoded_bytes(
            plan.points
                .saturating_mul(64)
                .saturating_mul(plan.attributes.len().max(1) as u64),
        );
    // The decoder ports C++ that trusted its input; should a stream still make it panic, that is this primitive's
    // error, not the loader's end.
    std::panic::catch_unwind(|| {
        let mut buffer = DecoderBuffer::new(stream).with_limits(limits);
        let mut mesh = DracoMesh::new();
        MeshDecoder::new()
            .decode(&mut buffer, &mut mesh)
            .map_err(|e| format!("the Draco stream does not decode: {e}"))?;
        Ok(mesh)
    })
    .unwrap_or_else(|_| Err("the Draco stream is malformed (the decoder failed on it)".into()))
}

/// Starts a bufferView in `out` at a 4-byte boundary; returns its offset.
fn append_view(out: &mut Vec<u8>) -> usize {
    out.resize(out.len().next_multiple_of(4), 0);
    out.len()
}

/// Ends the bufferView begun at `start` and adds it to the file.
fn finish_view(root: &mut json::Root, buffer: Index<json::Buffer>, out: &[u8], start: usize) {
    root.buffer_views.push(json::buffer::View {
        buffer,
        byte_length: USize64((out.len() - start) as u64),
        byte_offset: Some(USize64(start as u64)),
        byte_stride: None,
        name: None,
        target: None,
        extensions: None,
        extras: Default::default(),
    });
}

/// The decoded faces as a bufferView of u32 indices.
fn write_faces(
    root: &mut json::Root,
    mesh: &DracoMesh,
    buffer: Index<json::Buffer>,
    out: &mut Vec<u8>,
) -> Index<json::buffer::View> {
    let start = append_view(out);
    for face in mesh.faces() {
        for v in face {
            out.extend_from_slice(&v.0.to_le_bytes());
        }
    }
    finish_view(root, buffer, out, start);
    Index::new(root.buffer_views.len() as u32 - 1)
}

/// A new u32 indices accessor over the decoded faces.
fn push_indices(
    root: &mut json::Root,
    mesh: &DracoMesh,
    buffer: Index<json::Buffer>,
    out: &mut Vec<u8>,
) -> Index<json::Accessor> {
    let view = write_faces(root, mesh, buffer, out);
    root.accessors.push(json::Accessor {
        buffer_view: Some(view),
        byte_offset: None,
        count: USize64(mesh.num_faces() as u64 * 3),
        component_type: Checked::Valid(GenericComponentType(ComponentType::U32)),
        extensions: None,
        extras: Default::default(),
        type_: Checked::Valid(Type::Scalar),
        min: None,
        max: None,
        name: None,
        normalized: false,
        sparse: None,
    });
    Index::new(root.accessors.len() as u32 - 1)
}

/// Appends one decoded component in the accessor's type. Draco hands integer attributes over as their integer
/// values (widened to f32, exactly, for every type glTF attributes use), which must fit the type as integers.
fn push_component(out: &mut Vec<u8>, kind: ComponentType, v: f32) -> Option<()> {
    let int = |lo: f32, hi: f32| (v.fract() == 0.0 && v >= lo && v <= hi).then_some(v);
    match kind {
        ComponentType::F32 => out.extend_from_slice(&v.to_le_bytes()),
        ComponentType::I8 => out.push(int(-128.0, 127.0)? as i8 as u8),
        ComponentType::U8 => out.push(int(0.0, 255.0)? as u8),
        ComponentType::I16 => out.extend_from_slice(&(int(-32768.0, 32767.0)? as i16).to_le_bytes()),
        ComponentType::U16 => out.extend_from_slice(&(int(0.0, 65535.0)? as u16).to_le_bytes()),
        ComponentType::U32 => out.extend_from_slice(&(int(0.0, 16_777_216.0)? as u32).to_le_bytes()),
    }
    Some(())
}
