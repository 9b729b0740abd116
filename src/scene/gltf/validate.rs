//! Checks a glTF file before the reader takes it in: gltf 1.4's parsing and validation, minus what glTF 2.0 allows,
//! plus what gltf would otherwise panic on or read forever from.
use super::{scene_err, SUPPORTED_EXTENSIONS};
use crate::error::Error;
use std::path::Path;

/// Parses a .gltf or .glb into its JSON root and the GLB's binary chunk.
///
/// An animation channel whose target has no `node` is valid glTF (the channel is ignored, e.g. under
/// KHR_animation_pointer), but gltf 1.4's schema requires `node`: such channels are dropped before parsing.
/// A dropped channel's sampler index is still checked, and the dropped channels are returned: those with
/// KHR_animation_pointer's pointer are read from them (`Loader::animations`).
pub(super) fn parse(path: &Path, bytes: &[u8]) -> Result<Parsed, Error> {
    use gltf::json::deserialize::{from_slice, from_value};
    let invalid = |e: &dyn std::fmt::Display| scene_err(path, format!("not a valid glTF file: {e}"));
    let (json, blob) = if bytes.starts_with(b"glTF") {
        let glb = gltf::binary::Glb::from_slice(bytes).map_err(|e| invalid(&e))?;
        (glb.json, glb.bin.map(std::borrow::Cow::into_owned))
    } else {
        (std::borrow::Cow::Borrowed(bytes), None)
    };
    let mut value: Option<gltf::json::Value> = from_slice(&json).ok();
    let mut untargeted = Vec::new();
    let dropped = match value.as_mut() {
        Some(v) => {
            untargeted = drop_untargeted_channels(path, v)?;
            untargeted.len() + give_scenes_nodes(v)
        }
        None => 0,
    };
    let root = match value {
        Some(v) if dropped > 0 => from_value(v),
        // Unchanged JSON is parsed from its bytes, exactly as gltf does (e.g. duplicate keys are refused).
        _ => from_slice(&json),
    }
    .map_err(|e| invalid(&e))?;
    Ok((root, blob, untargeted))
}

/// The JSON root, the GLB's binary chunk, and the channels taken out before parsing.
pub(super) type Parsed = (gltf::json::Root, Option<Vec<u8>>, Vec<Untargeted>);

/// An animation channel without a node, taken out before parsing: where it was, its sampler, and its
/// KHR_animation_pointer pointer when it has one (the extension's `target.extensions.KHR_animation_pointer.pointer`
/// under `target.path` "pointer").
#[derive(Clone, Debug, PartialEq)]
pub(super) struct Untargeted {
    pub animation: usize,
    pub channel: usize,
    pub sampler: usize,
    pub pointer: Option<String>,
}

/// Gives every scene object without `nodes` (glTF 2.0 allows it: an empty scene) an empty list, which gltf 1.4's
/// schema requires; returns how many it changed.
fn give_scenes_nodes(root: &mut gltf::json::Value) -> usize {
    let Some(scenes) = root.get_mut("scenes").and_then(gltf::json::Value::as_array_mut) else {
        return 0;
    };
    let mut changed = 0;
    for scene in scenes.iter_mut().filter_map(gltf::json::Value::as_object_mut) {
        if !scene.contains_key("nodes") {
            scene.insert("nodes".into(), gltf::json::Value::Array(Vec::new()));
            changed += 1;
        }
    }
    changed
}

/// Removes the animation channels whose target has no `node` and which are otherwise well-formed, and returns them.
fn drop_untargeted_channels(path: &Path, root: &mut gltf::json::Value) -> Result<Vec<Untargeted>, Error> {
    use gltf::json::Value;
    let untargeted = |channel: &Value| {
        let Some(target) = channel.get("target").and_then(Value::as_object) else {
            return false;
        };
        if target.contains_key("node") {
            return false;
        }
        // Dropped only if a node is all it lacks, so every other defect is still reported by gltf's parser.
        let mut with_node = channel.clone();
        with_node["target"]["node"] = Value::from(0);
        gltf::json::deserialize::from_value::<gltf::json::animation::Channel>(with_node).is_ok()
    };
    let Some(animations) = root.get_mut("animations").and_then(Value::as_array_mut) else {
        return Ok(Vec::new());
    };
    let mut dropped = Vec::new();
    for (a, animation) in animations.iter_mut().enumerate() {
        let samplers = animation.get("samplers").and_then(Value::as_array).map_or(0, Vec::len);
        let Some(channels) = animation.get_mut("channels").and_then(Value::as_array_mut) else {
            continue;
        };
        let mut kept = Vec::with_capacity(channels.len());
        for (c, channel) in std::mem::take(channels).into_iter().enumerate() {
            if !untargeted(&channel) {
                kept.push(channel);
                continue;
            }
            let sampler = channel.get("sampler").and_then(Value::as_u64);
            let Some(sampler) = sampler.filter(|&s| s < samplers as u64) else {
                return Err(scene_err(
                    path,
                    format!("not a valid glTF file: invalid glTF: animations[{a}].channels[{c}].sampler: Index out of bounds"),
                ));
            };
            let target = &channel["target"];
            let pointer = (target.get("path").and_then(Value::as_str) == Some("pointer"))
                .then(|| target.pointer("/extensions/KHR_animation_pointer/pointer"))
                .flatten()
                .and_then(Value::as_str)
                .map(str::to_string);
            dropped.push(Untargeted {
                animation: a,
                channel: c,
                sampler: sampler as usize,
                pointer,
            });
        }
        *channels = kept;
    }
    Ok(dropped)
}

/// gltf 1.4's validation, except where it is stricter than glTF 2.0: an accessor without a bufferView (all
/// zeros; `check_accessor` handles it) and a texture without a source (pathwave never reads texture sources); and
/// a required extension gltf does not know but pathwave reads itself (KHR_mesh_quantization: `quantized`).
/// Every other finding refuses the file, listed as gltf would.
pub(super) fn validate(path: &Path, root: &gltf::json::Root) -> Result<Vec<String>, Error> {
    use gltf::json::validation::Validate;
    let mut findings = Vec::new();
    let mut unbounded: Vec<String> = Vec::new();
    root.validate(root, gltf::json::Path::new, &mut |p, error| {
        let p = p();
        // POSITION's min and max are required, but Blender and three.js read files without them, and pathwave
        // bounds its geometry from the positions themselves.
        if error == gltf::json::validation::Error::Missing
            && (p.as_str().ends_with("attributes[\"POSITION\"].min")
                || p.as_str().ends_with("attributes[\"POSITION\"].max"))
        {
            let at = p.as_str().trim_end_matches(".min").trim_end_matches(".max").to_string();
            if !unbounded.contains(&at) {
                unbounded.push(at);
            }
            return;
        }
        let read_here = error == gltf::json::validation::Error::Unsupported
            && p.as_str().starts_with("extensionsRequired[")
            && SUPPORTED_EXTENSIONS
                .iter()
                .any(|e| p.as_str().ends_with(&format!("= \"{e}\"")));
        if !spec_valid(p.as_str(), error) && !read_here {
            findings.push(format!("{p}: {error}"));
        }
    });
    let mut warnings = Vec::new();
    if let Some(first) = unbounded.first() {
        let more = match unbounded.len() {
            1 => String::new(),
            n => format!(" and {} more", n - 1),
        };
        warnings.push(format!(
            "{first}{more}: POSITION without min and max, which glTF requires; the bounds are computed from the positions"
        ));
    }
    if findings.is_empty() {
        return Ok(warnings);
    }
    Err(scene_err(
        path,
        format!("not a valid glTF file: invalid glTF: {}", findings.join("; ")),
    ))
}

/// Whether a finding of gltf 1.4's validator is valid glTF 2.0: exactly `accessors[N].bufferView` or
/// `textures[N].source` reported missing.
fn spec_valid(path: &str, error: gltf::json::validation::Error) -> bool {
    let indexed = |array: &str, field: &str| {
        path.strip_prefix(array)
            .and_then(|rest| rest.strip_prefix('['))
            .and_then(|rest| rest.strip_suffix(field))
            .and_then(|rest| rest.strip_suffix("]."))
            .is_some_and(|i| !i.is_empty() && i.bytes().all(|b| b.is_ascii_digit()))
    };
    error == gltf::json::validation::Error::Missing
        && (indexed("accessors", "bufferView") || indexed("textures", "source"))
}

/// What gltf 1.4's own validation assumes instead of checking (it indexes the POSITION accessor unchecked and
/// unwraps an image's uri, or its bufferView's mimeType), plus required extensions, refused here with a clearer message than its "Unsupported extension".
pub(super) fn pre_validate(path: &Path, json: &gltf::json::Root) -> Result<(), Error> {
    for ext in &json.extensions_required {
        if !SUPPORTED_EXTENSIONS.contains(&ext.as_str()) {
            return Err(scene_err(
                path,
                format!("requires extension {ext}, which pathwave does not support"),
            ));
        }
    }
    // gltf's Image::source unwraps both, so an image that breaks the rule would panic where it is read.
    for (i, image) in json.images.iter().enumerate() {
        let problem = match (&image.uri, &image.buffer_view, &image.mime_type) {
            (Some(_), None, _) | (None, Some(_), Some(_)) => continue,
            (None, None, _) => "has neither a uri nor a bufferView",
            (Some(_), Some(_), _) => "has both a uri and a bufferView",
            (None, Some(_), None) => "has a bufferView but no mimeType",
        };
        return Err(scene_err(
            path,
            format!("image {i} {problem}; glTF requires exactly one of them, and a mimeType with a bufferView"),
        ));
    }
    let positions = gltf::json::validation::Checked::Valid(gltf::json::mesh::Semantic::Positions);
    for (m, mesh) in json.meshes.iter().enumerate() {
        for (p, prim) in mesh.primitives.iter().enumerate() {
            if let Some(i) = prim
                .attributes
                .get(&positions)
                .filter(|i| i.value() >= json.accessors.len())
            {
                return Err(scene_err(
                    path,
                    format!(
                        "mesh {m} primitive {p}: POSITION refers to accessor {}, which does not exist",
                        i.value()
                    ),
                ));
            }
        }
    }
    Ok(())
}
