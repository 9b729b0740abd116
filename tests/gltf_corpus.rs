//! Robustness of `scene::load` against the Khronos glTF-Validator corpus: no file may panic or hang, every refusal names its file, valid files with triangles load.
mod common;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::mpsc;
use std::time::{Duration, Instant};

const TIMEOUT: Duration = Duration::from_secs(20);

/// Why a file the validator finds error-free may still be refused: pathwave's documented limits, and where
/// gltf 1.4 (which parses and validates for the loader) is stricter than the glTF 2.0 specification. The loader
/// tolerates gltf's other over-strict findings (accessors without a bufferView, textures without a source,
/// animation targets without a node), so those files must load.
const DOCUMENTED_REFUSALS: &[(&str, &str)] = &[
    ("has no triangles to render", "no triangles"),
    ("which pathwave does not support", "unsupported required extension"),
    // A buffer without uri outside a GLB: the validator assumes the application supplies its data; pathwave has none.
    (
        "has no uri and no GLB binary chunk",
        "buffer data not in the file (no uri, no GLB chunk)",
    ),
    // An integer written as `1.0` is valid glTF; gltf 1.4's schema refuses it.
    ("invalid type: floating point", "gltf 1.4: integer written as a float"),
    // A primitive without POSITION is valid glTF (pathwave would skip it); gltf 1.4's validation refuses it.
    (
        "attributes[\"POSITION\"]: Missing data",
        "gltf 1.4: primitive without POSITION",
    ),
];

/// The validator's report beside `path` (`<file>.report.json`): (error count, triangle count).
fn report(path: &Path) -> Option<(u64, u64)> {
    let mut name = path.as_os_str().to_owned();
    name.push(".report.json");
    let json: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(name).ok()?).ok()?;
    let errors = json["issues"]["numErrors"].as_u64()?;
    let triangles = json["info"]["totalTriangleCount"].as_u64().unwrap_or(0);
    Some((errors, triangles))
}

/// A short label for a refusal, for the tally.
fn reason(message: &str) -> &'static str {
    if let Some((_, label)) = DOCUMENTED_REFUSALS.iter().find(|(needle, _)| message.contains(needle)) {
        return label;
    }
    [
        ("invalid glTF:", "fails gltf's validation (bad index, missing property)"),
        ("not a valid glTF file", "not parseable as glTF JSON/GLB"),
        ("cannot load buffer data", "buffer data missing or unreadable"),
        ("does not exist", "dangling index"),
        ("accessor", "accessor unusable"),
        ("appears twice in the hierarchy", "node cycle or shared child"),
    ]
    .iter()
    .find(|(needle, _)| message.contains(needle))
    .map_or("other", |(_, label)| label)
}

/// Whether a refusal is for documented reasons only: each of gltf's validation findings, or else the message.
fn documented(message: &str) -> bool {
    let is_documented = |m: &str| DOCUMENTED_REFUSALS.iter().any(|(needle, _)| m.contains(needle));
    match message.split_once("invalid glTF: ") {
        Some((_, findings)) => findings
            .split(';')
            .map(str::trim)
            .filter(|f| !f.is_empty())
            .all(is_documented),
        None => is_documented(message),
    }
}

enum Outcome {
    Loaded,
    Refused(String),
    Panicked(String),
}

fn load_guarded(path: &Path) -> Option<Outcome> {
    let (tx, rx) = mpsc::channel();
    let p = path.to_path_buf();
    std::thread::Builder::new()
        .name(format!("load {}", path.display()))
        .spawn(move || {
            let r = std::panic::catch_unwind(|| pathwave::scene::load(&p, None));
            let outcome = match r {
                Ok(Ok(_)) => Outcome::Loaded,
                Ok(Err(e)) => Outcome::Refused(e.to_string()),
                Err(payload) => Outcome::Panicked(
                    payload
                        .downcast_ref::<&str>()
                        .map(|s| s.to_string())
                        .or_else(|| payload.downcast_ref::<String>().cloned())
                        .unwrap_or_else(|| "(non-string panic payload)".into()),
                ),
            };
            let _ = tx.send(outcome);
        })
        .unwrap();
    // A hung loader thread is left behind; the process ends with the test.
    rx.recv_timeout(TIMEOUT).ok()
}

#[test]
fn gltf_validator_corpus_never_panics_or_hangs() {
    let corpus = Path::new(common::CORPUS);
    if !corpus.is_dir() {
        eprintln!("skipping: the glTF-Validator corpus is not at {}", corpus.display());
        return;
    }
    let mut files = Vec::new();
    common::corpus_files(corpus, &mut files);
    assert!(!files.is_empty(), "no .gltf/.glb files under {}", corpus.display());

    let start = Instant::now();
    let mut failures = Vec::new();
    let mut loaded = 0;
    let mut reasons: BTreeMap<&str, usize> = BTreeMap::new();
    for path in &files {
        let rel = path.strip_prefix(corpus).unwrap_or(path).display().to_string();
        let expected = report(path);
        match load_guarded(path) {
            None => failures.push(format!("{rel}: hung (no result within {TIMEOUT:?})")),
            Some(Outcome::Panicked(m)) => failures.push(format!("{rel}: panicked: {m}")),
            Some(Outcome::Loaded) => loaded += 1,
            Some(Outcome::Refused(m)) => {
                if !m.contains(&path.display().to_string()) {
                    failures.push(format!("{rel}: the error does not name the file: {m}"));
                }
                let valid_with_triangles = expected.is_some_and(|(errors, triangles)| errors == 0 && triangles > 0);
                if valid_with_triangles && !documented(&m) {
                    failures.push(format!("{rel}: valid per the validator but refused: {m}"));
                }
                *reasons.entry(reason(&m)).or_default() += 1;
            }
        }
    }

    let refused: usize = reasons.values().sum();
    eprintln!(
        "glTF-Validator corpus: {} files in {:.1?}: {loaded} loaded, {refused} refused",
        files.len(),
        start.elapsed()
    );
    let mut by_count: Vec<_> = reasons.into_iter().collect();
    by_count.sort_by(|a, b| b.1.cmp(&a.1).then(a.0.cmp(b.0)));
    for (r, n) in by_count {
        eprintln!("  {n:4}  {r}");
    }
    assert!(
        failures.is_empty(),
        "{} file(s) of the glTF-Validator corpus failed:\n{}",
        failures.len(),
        failures.join("\n")
    );
}

/// A triangle with everything gltf 1.4 refuses but glTF 2.0 allows: a NORMAL accessor without bufferView (zeros:
/// face normals), a primitive whose POSITION and one whose indices have no bufferView (zeros: skipped), a texture
/// without source, an animation channel without a target node.
fn spec_valid_but_strict_for_gltf() -> serde_json::Value {
    serde_json::json!({
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0}],
        "meshes": [{"name": "m", "primitives": [
            {"attributes": {"POSITION": 0, "NORMAL": 1}, "material": 0},
            {"attributes": {"POSITION": 3}},
            {"attributes": {"POSITION": 0}, "indices": 2}
        ]}],
        "materials": [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}],
        "textures": [{}],
        "animations": [{
            "channels": [{"sampler": 0, "target": {"path": "translation"}}],
            "samplers": [{"input": 4, "output": 5}]
        }],
        "buffers": [{"uri": "tri.bin", "byteLength": 36}],
        "bufferViews": [{"buffer": 0, "byteLength": 36}],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]},
            {"componentType": 5126, "count": 3, "type": "VEC3"},
            {"componentType": 5125, "count": 3, "type": "SCALAR"},
            {"componentType": 5126, "count": 3, "type": "VEC3", "min": [0, 0, 0], "max": [0, 0, 0]},
            {"componentType": 5126, "count": 1, "type": "SCALAR", "min": [0], "max": [0]},
            {"componentType": 5126, "count": 1, "type": "VEC3"}
        ]
    })
}

fn load_json(dir: &Path, name: &str, json: &serde_json::Value) -> (PathBuf, Result<pathwave::Scene, pathwave::Error>) {
    let path = dir.join(name);
    std::fs::write(&path, serde_json::to_vec(json).unwrap()).unwrap();
    let scene = pathwave::scene::load(&path, None);
    (path, scene)
}

#[test]
fn what_gltf_refuses_but_gltf_2_allows_loads() {
    let dir = tempfile::tempdir().unwrap();
    let vertices: [[f32; 3]; 3] = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
    let bytes: Vec<u8> = vertices.iter().flatten().flat_map(|v| v.to_le_bytes()).collect();
    std::fs::write(dir.path().join("tri.bin"), bytes).unwrap();

    let (_, scene) = load_json(dir.path(), "ok.gltf", &spec_valid_but_strict_for_gltf());
    let scene = scene.unwrap_or_else(|e| panic!("{e}"));
    let soup = scene.flatten();
    assert_eq!(soup.len(), 1, "only the first primitive has area");
    assert!(soup.normals()[0].iter().all(|n| *n == glam::Vec3::Z));
    // The channel without a target node is valid glTF and ignored: the animation is read without it.
    assert!(scene.rig.animations[0].channels.is_empty());
    for expected in [
        "mesh 'm': NORMAL accessor 1 has no bufferView (all zeros); face normals are used",
        "mesh 'm': POSITION accessor 3 has no bufferView (all zeros); the primitive is skipped",
        "mesh 'm': indices accessor 2 has no bufferView (all zeros); the primitive is skipped",
        "baseColorTexture uses texture 0, which names no image; it is ignored",
    ] {
        assert!(
            scene.warnings.iter().any(|w| w.contains(expected)),
            "no warning '{expected}' in {:?}",
            scene.warnings
        );
    }

    // The same places with real errors are still refused, naming the file and the path.
    type Breakage = fn(&mut serde_json::Value);
    let refusals: [(&str, Breakage, &str); 4] = [
        (
            "view.gltf",
            |j| j["accessors"][1]["bufferView"] = 7.into(),
            "accessors[1].bufferView: Index out of bounds",
        ),
        (
            "source.gltf",
            |j| j["textures"][0]["source"] = 7.into(),
            "textures[0].source: Index out of bounds",
        ),
        (
            "sampler.gltf",
            |j| j["animations"][0]["channels"][0]["sampler"] = 7.into(),
            "animations[0].channels[0].sampler: Index out of bounds",
        ),
        (
            "path.gltf",
            |j| j["animations"][0]["channels"][0]["target"]["path"] = 7.into(),
            "invalid type: integer `7`",
        ),
    ];
    for (name, break_it, expected) in refusals {
        let mut json = spec_valid_but_strict_for_gltf();
        break_it(&mut json);
        let (path, scene) = load_json(dir.path(), name, &json);
        let message = scene.expect_err("refused").to_string();
        assert!(
            message.contains(&path.display().to_string()) && message.contains(expected),
            "{name}: expected '{expected}', got: {message}"
        );
    }
}
