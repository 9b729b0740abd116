//! Seeded mutations of scene and image files for tests/mutations.rs: byte-level damage, and JSON-aware edits of glTF (inside a GLB too).
#![allow(dead_code)]
use super::rng::Rng;
use serde_json::Value;

/// Numbers a careless or hostile writer puts where a count, index, offset or factor belongs.
const HOSTILE_NUMBERS: &[&str] = &[
    "-1",
    "0",
    "1e39",
    "-1e39",
    "3e38",
    "1e308",
    "-0.0",
    "0.5",
    "4294967295",
    "4294967296",
    "2147483647",
    "-2147483648",
    "18446744073709551615",
    "9007199254740993",
];
/// The glTF properties that size or place data: the ones worth raising.
const SIZE_KEYS: &[&str] = &["count", "byteOffset", "byteStride", "byteLength", "componentType"];
/// Strings that replace a URI: damaged data URIs, escapes, names that are not files.
const HOSTILE_URIS: &[&str] = &[
    "data:application/octet-stream;base64,!!!!",
    "data:application/octet-stream;base64,AAAA",
    "data:image/png;base64,iVBORw0KGgo=",
    "%ff%fe.bin",
    "missing.bin",
    ".",
    "",
];

/// A uniform integer in [0, n) (n > 0).
pub fn below(rng: &mut Rng, n: usize) -> usize {
    let hi = (rng.next() * (1u32 << 24) as f32) as u64;
    let lo = (rng.next() * (1u32 << 24) as f32) as u64;
    (((hi << 24) | lo) % n.max(1) as u64) as usize
}

fn pick<'a, T>(rng: &mut Rng, items: &'a [T]) -> &'a T {
    &items[below(rng, items.len())]
}

/// One mutant of `bytes`, and a short description of what was done. JSON-aware edits apply to a .gltf's text
/// and to a GLB's JSON chunk; anything else gets byte-level damage only.
pub fn mutate(bytes: &[u8], rng: &mut Rng) -> (Vec<u8>, String) {
    let (mut out, mut what) = mutate_once(bytes, rng);
    // A second or third edit reaches code behind the first check a single edit trips.
    for _ in 0..[0, 0, 0, 1, 1, 2][below(rng, 6)] {
        let (next, also) = mutate_once(&out, rng);
        (out, what) = (next, format!("{what}; {also}"));
    }
    (out, what)
}

fn mutate_once(bytes: &[u8], rng: &mut Rng) -> (Vec<u8>, String) {
    if below(rng, 4) == 0 {
        if let Some(done) = resize_image_header(bytes, rng) {
            return done;
        }
    }
    let json_aware = bytes.starts_with(b"glTF") || serde_json::from_slice::<Value>(bytes).is_ok();
    // Mostly JSON-aware: byte damage to JSON text rarely gets past the parser.
    if json_aware && below(rng, 5) != 0 {
        if let Some(done) = mutate_gltf_json(bytes, rng) {
            return done;
        }
    }
    mutate_bytes(bytes, rng)
}

/// Byte-level damage: flipped bits, a truncation, a duplicated or deleted span, a hostile 32-bit word.
pub fn mutate_bytes(bytes: &[u8], rng: &mut Rng) -> (Vec<u8>, String) {
    let mut out = bytes.to_vec();
    if out.is_empty() {
        return (vec![0], "empty file becomes one zero byte".into());
    }
    let len = out.len();
    let at = below(rng, len);
    let span = 1 + below(rng, (len - at).min(64));
    let what = match below(rng, 5) {
        0 => {
            let flips = 1 + below(rng, 8);
            for _ in 0..flips {
                let i = below(rng, len);
                out[i] ^= 1 << below(rng, 8);
            }
            format!("{flips} bit flips")
        }
        1 => {
            out.truncate(at);
            format!("truncated to {at} bytes")
        }
        2 => {
            let copy = out[at..at + span].to_vec();
            let to = below(rng, len + 1);
            out.splice(to..to, copy);
            format!("{span} bytes at {at} duplicated at {to}")
        }
        3 => {
            out.drain(at..at + span);
            format!("{span} bytes at {at} deleted")
        }
        _ => {
            let word: u32 = *pick(
                rng,
                &[0, u32::MAX, 0x7fff_ffff, 0x8000_0000, len as u32, 12, 0x4E4F_534A],
            );
            let at = at.min(len.saturating_sub(4));
            let n = (len - at).min(4);
            out[at..at + n].copy_from_slice(&word.to_le_bytes()[..n]);
            format!("word {word:#x} written at {at}")
        }
    };
    (out, what)
}

/// A GLB split into its JSON chunk and the rest of its chunks (as bytes), if its framing holds.
fn split_glb(bytes: &[u8]) -> Option<(Vec<u8>, Vec<u8>)> {
    let len = u32::from_le_bytes(bytes.get(12..16)?.try_into().ok()?) as usize;
    let json = bytes.get(20..20 + len)?.to_vec();
    Some((json, bytes.get(20 + len..)?.to_vec()))
}

/// A GLB with `json` as its first chunk (padded with spaces) and `rest` after it, the header's length updated.
fn join_glb(json: &[u8], rest: &[u8], version: u32) -> Vec<u8> {
    let mut json = json.to_vec();
    while !json.len().is_multiple_of(4) {
        json.push(b' ');
    }
    let total = 12 + 8 + json.len() + rest.len();
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&version.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(json.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&json);
    out.extend_from_slice(rest);
    out
}

/// A JSON-aware edit of a .gltf or of a GLB's JSON chunk; `None` if the JSON does not parse.
fn mutate_gltf_json(bytes: &[u8], rng: &mut Rng) -> Option<(Vec<u8>, String)> {
    let glb = bytes.starts_with(b"glTF");
    let (json, rest) = if glb {
        split_glb(bytes)?
    } else {
        (bytes.to_vec(), Vec::new())
    };
    let mut value: Value = serde_json::from_slice(&json).ok()?;
    let what = mutate_value(&mut value, rng)?;
    let text = serde_json::to_vec(&value).ok()?;
    let out = if glb {
        join_glb(&text, &rest, u32::from_le_bytes(bytes[4..8].try_into().ok()?))
    } else {
        text
    };
    Some((out, what))
}

/// Every JSON pointer under `v`, with the value's kind.
fn pointers(v: &Value, at: &str, out: &mut Vec<String>) {
    out.push(at.to_string());
    match v {
        Value::Object(map) => {
            for (k, child) in map {
                pointers(child, &format!("{at}/{}", k.replace('~', "~0").replace('/', "~1")), out);
            }
        }
        Value::Array(items) => {
            for (i, child) in items.iter().enumerate() {
                pointers(child, &format!("{at}/{i}"), out);
            }
        }
        _ => {}
    }
}

fn hostile_number(rng: &mut Rng) -> Value {
    let text = *pick::<&str>(rng, HOSTILE_NUMBERS);
    serde_json::from_str(text).expect("a JSON number")
}

/// One edit of the glTF JSON; `None` if nothing fit the chosen kind of edit.
fn mutate_value(root: &mut Value, rng: &mut Rng) -> Option<String> {
    let mut all = Vec::new();
    pointers(root, "", &mut all);
    let last_key = |p: &str| p.rsplit('/').next().unwrap_or("").to_string();
    let of = |pred: &dyn Fn(&Value, &str) -> bool, root: &Value| -> Vec<String> {
        all.iter()
            .filter(|p| pred(root.pointer(p).unwrap(), &last_key(p)))
            .cloned()
            .collect()
    };
    match below(rng, 7) {
        0 => {
            let numbers = of(&|v, _| v.is_number(), root);
            let p = numbers.get(below(rng, numbers.len().max(1)))?.clone();
            let old = root.pointer(&p)?.as_f64()?;
            // Near values pass the schema and reach the reader's own checks; hostile ones test the schema.
            let n = match below(rng, 2) {
                0 => hostile_number(rng),
                _ => serde_json::json!(*pick(rng, &[old + 1.0, old - 1.0, old * 2.0, -old, 0.0])),
            };
            *root.pointer_mut(&p)? = n.clone();
            Some(format!("{p} = {n}"))
        }
        1 => {
            let sizes = of(&|v, k| v.is_u64() && SIZE_KEYS.contains(&k), root);
            let p = sizes.get(below(rng, sizes.len().max(1)))?.clone();
            let old = root.pointer(&p)?.as_u64()?;
            let new = *pick(
                rng,
                &[
                    old.saturating_add(1),
                    old.saturating_mul(2).saturating_add(4),
                    old.saturating_add(4096),
                    u32::MAX as u64,
                    u64::MAX / 2,
                ],
            );
            *root.pointer_mut(&p)? = new.into();
            Some(format!("{p} raised from {old} to {new}"))
        }
        2 => {
            let strings = of(&|v, _| v.is_string(), root);
            let p = strings.get(below(rng, strings.len().max(1)))?.clone();
            let n = hostile_number(rng);
            *root.pointer_mut(&p)? = n.clone();
            Some(format!("string {p} replaced by {n}"))
        }
        3 => {
            let keys: Vec<String> = all.iter().filter(|p| !p.is_empty()).cloned().collect();
            let p = keys.get(below(rng, keys.len().max(1)))?.clone();
            let (parent, key) = p.rsplit_once('/')?;
            match root.pointer_mut(parent)? {
                Value::Object(map) => map.remove(&key.replace("~1", "/").replace("~0", "~")),
                Value::Array(items) => Some(items.remove(key.parse().ok()?)),
                _ => None,
            }?;
            Some(format!("{p} deleted"))
        }
        4 => {
            let uris = of(&|v, k| v.is_string() && k == "uri", root);
            let p = uris.get(below(rng, uris.len().max(1)))?.clone();
            let uri = *pick(rng, HOSTILE_URIS);
            *root.pointer_mut(&p)? = uri.into();
            Some(format!("{p} = {uri:?}"))
        }
        5 => {
            // Damage inside a data URI's bytes (geometry, an embedded PNG or JPEG), the URI itself left valid.
            use base64::Engine;
            let data = of(
                &|v, k| k == "uri" && v.as_str().is_some_and(|u| u.starts_with("data:")),
                root,
            );
            let p = data.get(below(rng, data.len().max(1)))?.clone();
            let uri = root.pointer(&p)?.as_str()?.to_string();
            let (header, payload) = uri.split_once(";base64,")?;
            let engine = base64::engine::general_purpose::STANDARD;
            let (bytes, what) = mutate_bytes(&engine.decode(payload).ok()?, rng);
            *root.pointer_mut(&p)? = format!("{header};base64,{}", engine.encode(bytes)).into();
            Some(format!("{p}: {what} in its data"))
        }
        _ => {
            // An array or object where a scalar belongs, or the reverse.
            let p = pick(rng, &all).clone();
            let new = match root.pointer(&p)? {
                Value::Array(_) | Value::Object(_) => Value::from(7),
                Value::Number(_) => serde_json::json!([1, 2, 3]),
                _ => serde_json::json!({}),
            };
            *root.pointer_mut(&p)? = new.clone();
            Some(format!("{p} = {new}"))
        }
    }
}

/// Sizes an image header declares where a reader may allocate before it reads a pixel.
const HOSTILE_SIZES: &[i32] = &[0, 1, 65_535, 60_000, 1 << 20, i32::MAX];

/// A Radiance .hdr's resolution line or an EXR's dataWindow rewritten to a hostile size; `None` for other files.
fn resize_image_header(bytes: &[u8], rng: &mut Rng) -> Option<(Vec<u8>, String)> {
    let (w, h) = (*pick(rng, HOSTILE_SIZES), *pick(rng, HOSTILE_SIZES));
    if bytes.starts_with(b"#?") {
        let at = bytes.windows(4).position(|x| x == b"\n-Y ")? + 1;
        let end = at + bytes[at..].iter().position(|&c| c == b'\n')?;
        let mut out = bytes[..at].to_vec();
        out.extend_from_slice(format!("-Y {h} +X {w}").as_bytes());
        out.extend_from_slice(&bytes[end..]);
        return Some((out, format!("hdr resolution {w}x{h}")));
    }
    if bytes.starts_with(&[0x76, 0x2f, 0x31, 0x01]) {
        let key = b"dataWindow\0box2i\0";
        let at = bytes.windows(key.len()).position(|x| x == key)? + key.len() + 4;
        let mut out = bytes.to_vec();
        out.get_mut(at + 8..at + 16)?
            .copy_from_slice(&[(w - 1).to_le_bytes(), (h - 1).to_le_bytes()].concat());
        return Some((out, format!("exr dataWindow {w}x{h}")));
    }
    None
}
