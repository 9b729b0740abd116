//! Extension property names against the Khronos JSON schemas (tests/data/khronos-gltf-schemas, copied unmodified
//! from KhronosGroup/glTF): every property of every material extension pathwave reads must change what it loads,
//! and every project scene and test fixture may use only the schemas' names.
mod common;

use common::gltf_builder::GltfBuilder;
use serde_json::{json, Map, Value};
use std::path::{Path, PathBuf};

fn schema_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/khronos-gltf-schemas")
}

/// (extension name, its schema's properties but `extensions` and `extras`), for every schema kept.
fn schemas(prefix: &str) -> Vec<(String, Map<String, Value>)> {
    let mut out = Vec::new();
    for entry in std::fs::read_dir(schema_dir()).unwrap() {
        let path = entry.unwrap().path();
        let file = path.file_name().unwrap().to_str().unwrap().to_string();
        let Some(ext) = file.strip_prefix(prefix).and_then(|f| f.strip_suffix(".schema.json")) else {
            continue;
        };
        let schema: Value = serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
        let mut props = schema["properties"].as_object().unwrap().clone();
        props.remove("extensions");
        props.remove("extras");
        out.push((ext.to_string(), props));
    }
    out.sort_by(|a, b| a.0.cmp(&b.0));
    out
}

/// Two valid values of a schema property that differ from each other and from its default: numbers inside its range,
/// arrays of its length, a texture absent and present (texture 0), a texCoord of 0 and 1.
fn two_values(schema: &Value) -> (Option<Value>, Value) {
    let num = |k: &str| schema.get(k).and_then(Value::as_f64);
    match schema.get("type").and_then(Value::as_str) {
        Some("number") => match (num("minimum"), num("maximum")) {
            (Some(lo), Some(hi)) => (Some(json!(lo + 0.25 * (hi - lo))), json!(lo + 0.75 * (hi - lo))),
            (lo, _) => {
                let base = num("default").or(lo).unwrap_or(0.0);
                (Some(json!(base + 0.5)), json!(base + 1.5))
            }
        },
        Some("integer") => (Some(json!(0)), json!(1)),
        Some("array") => {
            let n = schema["minItems"].as_u64().unwrap() as usize;
            (Some(json!([0.25, 0.5, 0.75][..n])), json!([0.75, 0.5, 0.25][..n]))
        }
        _ => {
            assert!(
                schema.to_string().contains("extureInfo.schema.json"),
                "a property kind this test does not know: {schema}"
            );
            (None, json!({ "index": 0 }))
        }
    }
}

/// Loads a textured quad whose one material is `material` (every extension it names marked used) and returns its
/// loaded material, or the error.
fn load(material: Value) -> Result<String, String> {
    let mut b = GltfBuilder::new();
    let image = b.png_image(1, 1, &[[200, 100, 50, 255]]);
    b.texture(image, json!({}));
    let m = b.material("m", [0.5; 3], [0.0; 3], false);
    // Every extension the test names is one the scene uses.
    for ext in material["extensions"].as_object().unwrap().keys() {
        b.use_extension(Box::leak(ext.clone().into_boxed_str()));
    }
    *b.material_json(m) = material;
    b.textured_quad(
        "quad",
        [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]],
        [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]],
        m,
    );
    let (_dir, path) = common::write_temp(&b, "schema.gltf");
    let scene = pathwave::scene::load(&path, None).map_err(|e| e.to_string())?;
    Ok(format!("{:?}", scene.materials[0]))
}

/// Schema properties pathwave does not read, as docs/guide/materials.md says: a path tracer measures the thickness its rays cross in
/// the geometry itself, where a rasterizer needs the volume's thickness map. KHR_materials_scatter's textures apply on
/// thin walls only (in a volume, a texel on the surface does not say which owns the medium behind it): the test reads
/// that extension twice, in a volume without them and on a thin wall with every property.
const UNUSED_BY_DESIGN: &[(&str, &str)] = &[
    ("KHR_materials_volume", "thicknessTexture"),
    ("KHR_materials_scatter", "scatterTexture"),
    ("KHR_materials_scatter", "multiscatterColorTexture"),
];

/// Catches a property read under another name than its schema's (the loader read `iridescenceIOR` where the
/// schema says `iridescenceIor`, so every film had the default IOR): for each property of each material extension,
/// a material whose other properties are set, with the property at one value and at another, must load as two
/// different materials. The other properties are set so that each one matters (a volume's thickness for its
/// attenuation, a strength's emission), and KHR_texture_transform rides on the base colour texture.
#[test]
fn every_schema_property_of_every_material_extension_is_read() {
    let mut checked = 0;
    let mut failures = Vec::new();
    let transform = &schemas("textureInfo.")[0].1;
    let mut cases: Vec<(String, Map<String, Value>, bool)> =
        schemas("material.").into_iter().map(|(e, p)| (e, p, false)).collect();
    let scatter = cases.iter().find(|c| c.0 == "KHR_materials_scatter").cloned();
    cases.extend(scatter.map(|(e, p, _)| (e, p, true)));
    for (ext, props, thin) in cases {
        let label = if thin {
            format!("{ext} (thin-walled)")
        } else {
            ext.clone()
        };
        let mut base = Map::new();
        for (name, schema) in &props {
            if let (Some(v), _) = two_values(schema) {
                base.insert(name.clone(), v);
            }
        }
        let material = |ext_json: Map<String, Value>, transform_json: Map<String, Value>| {
            let mut exts = Map::new();
            exts.insert(ext.clone(), Value::Object(ext_json));
            // Transmission for the volume, which is its interior.
            exts.entry("KHR_materials_transmission")
                .or_insert(json!({ "transmissionFactor": 0.5 }));
            // A scattering medium needs a volume to fill, with an extinction for its albedo to split.
            if ext == "KHR_materials_scatter" && !thin {
                exts.insert(
                    "KHR_materials_volume".into(),
                    json!({ "thicknessFactor": 1.0, "attenuationColor": [0.5, 0.5, 0.5], "attenuationDistance": 1.0 }),
                );
            }
            json!({
                "name": "m",
                "emissiveFactor": [0.5, 0.25, 0.125],
                "pbrMetallicRoughness": {
                    "baseColorFactor": [0.5, 0.5, 0.5, 1.0],
                    "baseColorTexture": { "index": 0, "extensions": { "KHR_texture_transform": transform_json } },
                },
                "extensions": exts,
            })
        };
        let mut transform_base = Map::new();
        for (name, schema) in transform {
            transform_base.insert(name.clone(), two_values(schema).0.unwrap());
        }
        let reference = load(material(base.clone(), transform_base.clone()))
            .unwrap_or_else(|e| panic!("{label} with every property set: {e}"));
        for (name, schema) in &props {
            if !thin && UNUSED_BY_DESIGN.contains(&(ext.as_str(), name.as_str())) {
                continue;
            }
            // The second value, else the schema's default: a factor that only decides whether a layer is there
            // (a volume's thickness) changes what loads only at its default.
            let mut outcomes = Vec::new();
            for value in [Some(two_values(schema).1), schema.get("default").cloned()]
                .into_iter()
                .flatten()
            {
                let mut variant = base.clone();
                variant.insert(name.clone(), value);
                outcomes.push(load(material(variant, transform_base.clone())));
            }
            if !outcomes.iter().any(|o| matches!(o, Ok(m) if *m != reference)) {
                match outcomes.into_iter().find_map(Result::err) {
                    Some(e) => failures.push(format!("{label}.{name}: {e}")),
                    None => failures.push(format!("{label}.{name} changes nothing that loads")),
                }
            }
            checked += 1;
        }
        if ext == "KHR_materials_transmission" {
            for (name, schema) in transform {
                let mut variant = transform_base.clone();
                variant.insert(name.clone(), two_values(schema).1);
                match load(material(base.clone(), variant)) {
                    Ok(m) if m != reference => {}
                    Ok(_) => failures.push(format!("KHR_texture_transform.{name} changes nothing that loads")),
                    Err(e) => failures.push(format!("KHR_texture_transform.{name}: {e}")),
                }
                checked += 1;
            }
        }
    }
    eprintln!("{checked} schema properties checked");
    assert!(failures.is_empty(), "{failures:#?}");
    assert!(checked >= 40, "only {checked} properties: the schemas are missing");
}

/// KHR_node_visibility by its schema's one property, at the value that is not its default: a node so marked hides its
/// mesh and light and every node below it, even one marked the other way, and keeps its camera (the extension's
/// text); the same tree at the default value shows everything.
#[test]
fn node_visibility_is_read_by_its_schemas_name() {
    let schemas = schemas("node.");
    let (ext, props) = schemas
        .iter()
        .find(|(e, _)| e == "KHR_node_visibility")
        .expect("the schema is kept");
    assert_eq!(props.len(), 1, "{props:?}");
    let (name, schema) = props.iter().next().unwrap();
    let default = schema["default"].as_bool().unwrap();
    let build = |value: bool| {
        let mut b = GltfBuilder::new();
        let m = b.material("m", [0.5; 3], [1.0; 3], false);
        let c = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]];
        b.quad("parent quad", c, m, None);
        let parent = b.last_node();
        b.quad("child quad", c, m, None);
        let child = b.last_node();
        b.point_light([1.0; 3], 1.0, [0.0, 2.0, 0.0]);
        let light = b.last_node();
        b.camera([0.0, 0.0, 3.0], [0.0; 3], [0.0, 1.0, 0.0], 40.0);
        let camera = b.last_node();
        b.quad("sibling quad", c, m, None);
        for k in [child, light, camera] {
            b.add_child(parent, k);
        }
        b.use_extension("KHR_node_visibility");
        b.transform_node(
            parent,
            json!({ "extensions": { ext.as_str(): { name.as_str(): value } } }),
        );
        b.transform_node(
            child,
            json!({ "extensions": { ext.as_str(): { name.as_str(): default } } }),
        );
        let (_dir, path) = common::write_temp(&b, "visibility.gltf");
        pathwave::scene::load(&path, None).unwrap_or_else(|e| panic!("{e}"))
    };
    let shown = build(default);
    assert_eq!((shown.triangle_count(), shown.punctual.len()), (6, 1));
    let hidden = build(!default);
    assert_eq!(hidden.triangle_count(), 2, "only the sibling's quad is left");
    assert!(hidden.punctual.is_empty(), "the hidden node's light is gone");
    assert!(hidden.camera.is_some(), "visibility does not affect cameras");
}

/// Names a draft extension's README gives where its schema at the same revision says otherwise: KHR_materials_scatter
/// at pull request 2579's head names the strength `scatterStrengthFactor` in its README (which the renderers that read
/// the draft follow: nvpro_core2, Babylon.js) and `scatterFactor` in its schema. pathwave reads both; its fixtures use
/// both.
const README_NAMES: &[(&str, &str)] = &[("KHR_materials_scatter", "scatterStrengthFactor")];

/// Every property a project scene or test fixture gives a material extension (or KHR_texture_transform) is one its
/// schema names: a fixture written from the same misreading as the loader would pass the test above for ever.
#[test]
fn project_scenes_and_fixtures_use_the_schemas_names() {
    let known: Vec<(String, Vec<String>)> = schemas("material.")
        .into_iter()
        .chain(schemas("textureInfo."))
        .chain(schemas("node."))
        .map(|(ext, props)| (ext, props.keys().cloned().collect()))
        .collect();
    let mut files = Vec::new();
    for dir in ["scenes", "tests", "ci", "src", "docs"] {
        walk(&Path::new(env!("CARGO_MANIFEST_DIR")).join(dir), &mut files);
    }
    let mut unknown = Vec::new();
    let mut seen = 0;
    for file in files.iter().filter(|f| {
        let ext = f.extension().and_then(|e| e.to_str());
        matches!(ext, Some("gltf" | "rs" | "py")) && !f.starts_with(schema_dir())
    }) {
        let text = std::fs::read_to_string(file).unwrap_or_default();
        for (ext, props) in &known {
            // Each use: the extension's name, then its object's keys up to the closing brace.
            for (at, _) in text.match_indices(&format!("\"{ext}\"")) {
                let rest = &text[at + ext.len() + 2..];
                let Some(open) = rest.find('{').filter(|&o| opens_object(&rest[..o])) else {
                    continue;
                };
                for key in top_level_keys(&rest[open + 1..]) {
                    seen += 1;
                    let alias = README_NAMES.contains(&(ext.as_str(), key.as_str()));
                    if !props.contains(&key) && !alias && key != "extensions" && key != "extras" {
                        unknown.push(format!("{}: {ext}.{key}", file.display()));
                    }
                }
            }
        }
    }
    eprintln!("{seen} extension properties in project scenes and fixtures");
    unknown.sort();
    unknown.dedup();
    assert!(unknown.is_empty(), "not in the Khronos schemas: {unknown:#?}");
    assert!(seen > 50, "only {seen} properties found: the scan is broken");
}

/// The keys of the JSON (or json! macro) object whose text follows its opening brace: strings at depth 0 followed by
/// a colon, up to the closing brace.
fn top_level_keys(body: &str) -> Vec<String> {
    let mut keys = Vec::new();
    let mut depth = 0;
    let mut chars = body.char_indices();
    while let Some((i, c)) = chars.next() {
        match c {
            '{' | '[' => depth += 1,
            '}' | ']' if depth == 0 => break,
            '}' | ']' => depth -= 1,
            '"' => {
                let start = i + 1;
                let mut end = start;
                for (j, d) in chars.by_ref() {
                    if d == '"' {
                        end = j;
                        break;
                    }
                }
                if depth == 0 && body[end + 1..].trim_start().starts_with(':') {
                    keys.push(body[start..end].to_string());
                }
            }
            _ => {}
        }
    }
    keys
}

fn walk(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else { return };
    for p in entries.map(|e| e.unwrap().path()) {
        if p.is_dir() {
            walk(&p, out);
        } else {
            out.push(p);
        }
    }
}

/// Whether the text between an extension's quoted name and a brace makes that brace its object: a JSON member
/// (`: {`), an index assigned a macro's object (`"] = json!({`), or a tuple's next element (`, json!({`).
fn opens_object(between: &str) -> bool {
    let t = between.trim_start_matches(['"', ']']).trim_start();
    let t = t.strip_prefix([':', '=', ',']).unwrap_or(t).trim_start();
    let t = t.strip_prefix("serde_json::").unwrap_or(t);
    let t = t.strip_prefix("json!(").unwrap_or(t);
    t.trim().is_empty()
}

/// Every material pointer KHR_animation_pointer may name under an extension (scene::pointer::MATERIAL_POINTERS)
/// names a property of that extension's schema. Catches: a pointer spelled as the loader once misspelled a property
/// (iridescenceIOR), which files would never use, so its animation would be dropped with a warning.
#[test]
fn animation_pointers_name_the_schemas_properties() {
    let mut checked = 0;
    let schemas = schemas("material.");
    for (pointer, _) in pathwave::scene::pointer::MATERIAL_POINTERS {
        let Some(rest) = pointer.strip_prefix("extensions/") else {
            continue;
        };
        let (ext, property) = rest.split_once('/').unwrap();
        let Some((_, props)) = schemas.iter().find(|(e, _)| e == ext) else {
            panic!("{pointer}: no schema of {ext} is kept in tests/data/khronos-gltf-schemas");
        };
        assert!(
            props.contains_key(property),
            "{pointer}: {ext}'s schema has no property {property}"
        );
        checked += 1;
    }
    assert!(checked >= 15, "only {checked} pointers checked");
}
