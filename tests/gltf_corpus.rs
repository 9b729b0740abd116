//! Robustness of `scene::load` against the Khronos glTF-Validator corpus: no file may panic or hang, every refusal names its file, valid files with triangles load.
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::mpsc;
use std::time::{Duration, Instant};

const CORPUS: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../shared/gltf-validator-corpus"
);
const TIMEOUT: Duration = Duration::from_secs(20);

/// Why a file the validator finds error-free may still be refused: pathwave's documented limits, and where
/// gltf 1.4 (which parses and validates for the loader) is stricter than the glTF 2.0 specification.
const DOCUMENTED_REFUSALS: &[(&str, &str)] = &[
    ("has no triangles to render", "no triangles"),
    (
        "which pathwave does not support",
        "unsupported required extension",
    ),
    // Accessors without a bufferView (all zeros) and textures without a source are valid glTF; gltf 1.4 refuses them.
    (
        "bufferView: Missing data",
        "gltf 1.4: accessor without bufferView",
    ),
    ("source: Missing data", "gltf 1.4: texture without source"),
    // An integer written as `1.0` and an animation target without `node` are valid glTF; gltf 1.4's schema refuses them.
    (
        "invalid type: floating point",
        "gltf 1.4: integer written as a float",
    ),
    (
        "missing field `node`",
        "gltf 1.4: animation target without node",
    ),
    // A primitive without POSITION is valid glTF (pathwave would skip it); gltf 1.4 refuses it.
    (
        "attributes[\"POSITION\"]: Missing data",
        "gltf 1.4: primitive without POSITION",
    ),
];

fn corpus_files(dir: &Path, out: &mut Vec<PathBuf>) {
    let mut entries: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    entries.sort();
    for p in entries {
        if p.is_dir() {
            corpus_files(&p, out);
        } else if matches!(p.extension().and_then(|e| e.to_str()), Some("gltf" | "glb")) {
            out.push(p);
        }
    }
}

/// The validator's report beside `path` (`<file>.report.json`): (error count, triangle count).
fn report(path: &Path) -> Option<(u64, u64)> {
    let mut name = path.as_os_str().to_owned();
    name.push(".report.json");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(name).ok()?).ok()?;
    let errors = json["issues"]["numErrors"].as_u64()?;
    let triangles = json["info"]["totalTriangleCount"].as_u64().unwrap_or(0);
    Some((errors, triangles))
}

/// A short label for a refusal, for the tally.
fn reason(message: &str) -> &'static str {
    if let Some((_, label)) = DOCUMENTED_REFUSALS
        .iter()
        .find(|(needle, _)| message.contains(needle))
    {
        return label;
    }
    [
        (
            "invalid glTF:",
            "fails gltf's validation (bad index, missing property)",
        ),
        ("not a valid glTF file", "not parseable as glTF JSON/GLB"),
        (
            "cannot load buffer data",
            "buffer data missing or unreadable",
        ),
        ("does not exist", "dangling index"),
        ("accessor", "accessor unusable"),
        (
            "appears twice in the hierarchy",
            "node cycle or shared child",
        ),
    ]
    .iter()
    .find(|(needle, _)| message.contains(needle))
    .map_or("other", |(_, label)| label)
}

/// Whether a refusal is for documented reasons only: each of gltf's validation findings, or else the message.
fn documented(message: &str) -> bool {
    let is_documented = |m: &str| {
        DOCUMENTED_REFUSALS
            .iter()
            .any(|(needle, _)| m.contains(needle))
    };
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
    let corpus = Path::new(CORPUS);
    if !corpus.is_dir() {
        eprintln!(
            "skipping: the glTF-Validator corpus is not at {}",
            corpus.display()
        );
        return;
    }
    let mut files = Vec::new();
    corpus_files(corpus, &mut files);
    assert!(
        !files.is_empty(),
        "no .gltf/.glb files under {}",
        corpus.display()
    );

    let start = Instant::now();
    let mut failures = Vec::new();
    let mut loaded = 0;
    let mut reasons: BTreeMap<&str, usize> = BTreeMap::new();
    for path in &files {
        let rel = path
            .strip_prefix(corpus)
            .unwrap_or(path)
            .display()
            .to_string();
        let expected = report(path);
        match load_guarded(path) {
            None => failures.push(format!("{rel}: hung (no result within {TIMEOUT:?})")),
            Some(Outcome::Panicked(m)) => failures.push(format!("{rel}: panicked: {m}")),
            Some(Outcome::Loaded) => loaded += 1,
            Some(Outcome::Refused(m)) => {
                if !m.contains(&path.display().to_string()) {
                    failures.push(format!("{rel}: the error does not name the file: {m}"));
                }
                let valid_with_triangles =
                    expected.is_some_and(|(errors, triangles)| errors == 0 && triangles > 0);
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
