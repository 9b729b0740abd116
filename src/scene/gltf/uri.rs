//! Where a glTF URI may lead: data: URIs decode in memory, paths stay inside the scene's folder (unless allowed
//! out), and a file is read only if it is a regular one, and only as far as the scene declares.
use super::scene_err;
use crate::error::Error;
use std::io::Read;
use std::path::{Component, Path, PathBuf};

/// Largest scene file (and largest image file) read into memory; a bigger one is refused before it is read.
pub const MAX_FILE_BYTES: u64 = 2 << 30;

/// What a URI names once resolved.
pub(super) enum Target<'u> {
    /// A `data:` URI: its text after `data:`.
    Data(&'u str),
    File(PathBuf),
}

/// Resolves URIs against the scene's folder, confining them to it unless `allow_outside`.
pub(super) struct UriPolicy {
    base: PathBuf,
    allow_outside: bool,
    /// The folder with symlinks resolved, against which a file's resolved path is checked.
    canonical_base: Option<PathBuf>,
}

impl UriPolicy {
    pub(super) fn new(base: &Path, allow_outside: bool) -> Self {
        let base = if base.as_os_str().is_empty() {
            PathBuf::from(".")
        } else {
            base.to_path_buf()
        };
        let canonical_base = std::fs::canonicalize(&base).ok();
        UriPolicy {
            base,
            allow_outside,
            canonical_base,
        }
    }

    /// The file or data a URI names; errors are sentences for the caller to put after the item's name.
    pub(super) fn resolve<'u>(&self, uri: &'u str) -> Result<Target<'u>, String> {
        const HOW: &str = "(--allow-outside-paths allows it)";
        if let Some(rest) = uri.strip_prefix("data:") {
            return Ok(Target::Data(rest));
        }
        let scheme = uri.split_once(':').map(|(s, _)| s.to_ascii_lowercase());
        if scheme.as_deref() == Some("file") {
            if !self.allow_outside {
                return Err(format!("file: URIs are refused, they may name any file {HOW}"));
            }
            let rest = &uri[5..];
            return Ok(Target::File(PathBuf::from(rest.strip_prefix("//").unwrap_or(rest))));
        }
        if scheme.is_some() {
            return Err("the URI is neither a relative path nor a data: URI".into());
        }
        let decoded = percent_decode(uri).ok_or("the URI's percent-escapes do not decode to UTF-8")?;
        let relative = Path::new(&decoded);
        if self.allow_outside {
            return Ok(Target::File(self.base.join(relative)));
        }
        if relative.has_root() {
            return Err(format!(
                "an absolute path is refused: it must lie inside the scene's folder {HOW}"
            ));
        }
        let mut depth = 0usize;
        for c in relative.components() {
            depth = match c {
                Component::ParentDir => depth
                    .checked_sub(1)
                    .ok_or(format!("the path climbs above the scene's folder {HOW}"))?,
                Component::Normal(_) => depth + 1,
                _ => depth,
            };
        }
        let file = self.base.join(relative);
        // A symlink inside the folder may still point out of it; a file that does not exist is reported by the read.
        if let (Some(base), Ok(real)) = (&self.canonical_base, std::fs::canonicalize(&file)) {
            if !real.starts_with(base) {
                return Err(format!(
                    "it resolves (through a symlink) to {}, outside the scene's folder {HOW}",
                    real.display()
                ));
            }
        }
        Ok(Target::File(file))
    }
}

/// Reads a regular file of at most `max` bytes. A FIFO, a device or a folder is refused before it is opened
/// (opening a FIFO blocks), and a larger file before it is read. Errors do not name the file; callers do.
pub fn read_regular(file: &Path, max: u64, what: &str) -> Result<Vec<u8>, String> {
    let len = regular_len(file)?;
    if len > max {
        return Err(format!("it holds {len} bytes, more than the {max} bytes {what}"));
    }
    // Bounded even if the file grows between the check and the read.
    read_prefix(file, max)
}

/// The length of a regular file; anything else is refused without opening it. Errors do not name the file.
pub fn regular_len(file: &Path) -> Result<u64, String> {
    match std::fs::metadata(file) {
        Ok(m) if m.is_file() => Ok(m.len()),
        Ok(m) if m.is_dir() => Err("it is a folder, not a regular file".into()),
        Ok(_) => Err("it is not a regular file (a FIFO, socket or device is refused)".into()),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Err("file not found".into()),
        Err(e) => Err(format!("cannot read it: {e}")),
    }
}

/// Each buffer's data: the GLB chunk, a data: URI, or a regular file inside the folder, read up to its
/// byteLength (a shorter file is refused; bytes past byteLength are not read).
pub(super) fn import_buffers(
    path: &Path,
    policy: &UriPolicy,
    doc: &gltf::Document,
    mut blob: Option<Vec<u8>>,
) -> Result<Vec<gltf::buffer::Data>, Error> {
    let mut buffers = Vec::with_capacity(doc.buffers().len());
    for buffer in doc.buffers() {
        let declared = buffer.length();
        let (mut data, name) = match buffer.source() {
            // Filled by the meshopt decoder (EXT_ or KHR_meshopt_compression); `load_estimate` has bounded its byteLength already.
            _ if super::meshopt::is_fallback(&buffer) => (vec![0; declared], "its decoded views".to_string()),
            gltf::buffer::Source::Bin => match blob.take() {
                Some(b) => (b, "the GLB binary chunk".to_string()),
                None => {
                    return Err(scene_err(
                        path,
                        format!(
                            "buffer {} has no uri and no GLB binary chunk is left for it: its data is not in the file",
                            buffer.index()
                        ),
                    ))
                }
            },
            gltf::buffer::Source::Uri(uri) => {
                let err = |m: String| scene_err(path, format!("buffer {} ({}): {m}", buffer.index(), describe(uri)));
                match policy.resolve(uri).map_err(err)? {
                    Target::Data(_) => {
                        let d = gltf::buffer::Data::from_source(buffer.source(), None)
                            .map_err(|e| err(format!("cannot load buffer data: {e}")))?;
                        (d.0, "its data: URI".to_string())
                    }
                    Target::File(file) => {
                        let named = |m: String| err(format!("cannot load buffer data from {}: {m}", file.display()));
                        let len = regular_len(&file).map_err(named)?;
                        if len < declared as u64 {
                            return Err(named(format!(
                                "it holds {len} bytes, fewer than the buffer's byteLength {declared}"
                            )));
                        }
                        // Bytes past byteLength are never used, so a longer file costs no more than declared.
                        let bytes = read_prefix(&file, declared as u64).map_err(named)?;
                        (bytes, file.display().to_string())
                    }
                }
            }
        };
        while data.len() % 4 != 0 {
            data.push(0);
        }
        if data.len() < declared {
            return Err(scene_err(
                path,
                format!(
                    "buffer {}: {name} holds {} bytes, fewer than its byteLength {declared}",
                    buffer.index(),
                    data.len()
                ),
            ));
        }
        buffers.push(gltf::buffer::Data(data));
    }
    Ok(buffers)
}

/// An image's encoded bytes: a data: URI's (base64) or a regular file's inside the folder.
pub(super) fn image_bytes(policy: &UriPolicy, uri: &str) -> Result<Vec<u8>, String> {
    use base64::Engine;
    match policy.resolve(uri)? {
        Target::Data(rest) => {
            let (header, payload) = rest
                .split_once(',')
                .ok_or_else(|| "its data URI has no ',' before the data".to_string())?;
            if !header.ends_with(";base64") {
                return Err("its data URI is not base64-encoded".into());
            }
            base64::engine::general_purpose::STANDARD
                .decode(payload.trim())
                .map_err(|e| format!("its data URI is not valid base64: {e}"))
        }
        Target::File(file) => read_regular(&file, MAX_FILE_BYTES, "an image file may hold")
            .map_err(|e| format!("{}: {e}", file.display())),
    }
}

/// The first `n` bytes of a regular file (checked by the caller).
fn read_prefix(file: &Path, n: u64) -> Result<Vec<u8>, String> {
    let cannot = |e: std::io::Error| format!("cannot read it: {e}");
    let mut bytes = Vec::new();
    std::fs::File::open(file)
        .map_err(cannot)?
        .take(n)
        .read_to_end(&mut bytes)
        .map_err(cannot)?;
    Ok(bytes)
}

/// A URI as errors quote it: a data: URI by its media type only, a long path shortened.
pub(super) fn describe(uri: &str) -> String {
    if let Some(rest) = uri.strip_prefix("data:") {
        let media = rest.split([';', ',']).next().unwrap_or("");
        return format!("a data:{media} URI");
    }
    match uri.char_indices().nth(200) {
        Some((cut, _)) => format!("{}...", &uri[..cut]),
        None => uri.to_string(),
    }
}

/// Percent-decodes a relative URI as gltf 1.4 does (malformed escapes stay literal); `None` if not UTF-8.
pub(super) fn percent_decode(uri: &str) -> Option<String> {
    let b = uri.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        let hex = b.get(i + 1..i + 3).filter(|h| h.iter().all(u8::is_ascii_hexdigit));
        let hex = hex.and_then(|h| u8::from_str_radix(std::str::from_utf8(h).ok()?, 16).ok());
        match (b[i], hex) {
            (b'%', Some(v)) => {
                out.push(v);
                i += 3;
            }
            (c, _) => {
                out.push(c);
                i += 1;
            }
        }
    }
    String::from_utf8(out).ok()
}
