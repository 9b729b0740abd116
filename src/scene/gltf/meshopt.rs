//! EXT_meshopt_compression and KHR_meshopt_compression: every compressed bufferView decoded (meshoptimizer, through
//! the `meshopt` crate) into its fallback buffer at its own offset, before anything reads it, so the rest of the
//! reader sees plain glTF. KHR is EXT's successor with the same fields, one filter more (COLOR, YCoCg colours) and
//! the vertex codec's version 1 (which meshoptimizer's decoder reads from the data's header); a view or buffer with
//! both reads KHR's.
use super::scene_err;
use crate::error::Error;
use gltf::json::Value;
use std::path::Path;

const EXT: &str = "EXT_meshopt_compression";
const KHR: &str = "KHR_meshopt_compression";

/// Whether a buffer only stands in for decoded data (`"fallback": true`): it has no bytes of its own to load.
pub(super) fn is_fallback(buffer: &gltf::Buffer) -> bool {
    let ext = buffer.extension_value(KHR).or_else(|| buffer.extension_value(EXT));
    ext.and_then(|e| e.get("fallback"))
        .and_then(Value::as_bool)
        .unwrap_or(false)
}

/// One compressed view, its fields checked.
struct Compressed {
    source: usize,
    offset: usize,
    length: usize,
    stride: usize,
    count: usize,
    mode: String,
    filter: String,
}

impl Compressed {
    /// The view's fields, refused when a required one is missing or a text one is not a string.
    fn read(ext: &Value, err: &impl Fn(&str) -> Error) -> Result<Self, Error> {
        let text = |key: &str, default: &str| -> Result<String, Error> {
            match ext.get(key) {
                None => Ok(default.to_string()),
                Some(v) => v
                    .as_str()
                    .map(str::to_string)
                    .ok_or_else(|| err(&format!("{key} is not a string"))),
            }
        };
        Ok(Compressed {
            source: field(ext, "buffer").ok_or_else(|| err("has no source buffer"))?,
            offset: field(ext, "byteOffset").unwrap_or(0),
            length: field(ext, "byteLength").ok_or_else(|| err("has no byteLength"))?,
            stride: field(ext, "byteStride").ok_or_else(|| err("has no byteStride"))?,
            count: field(ext, "count").ok_or_else(|| err("has no count"))?,
            mode: text("mode", "")?,
            filter: text("filter", "NONE")?,
        })
    }

    /// Refuses a mode, byteStride, count and filter that do not go together; `name` is the extension read, as only
    /// KHR's has the COLOR filter.
    fn check(&self, name: &str, err: &impl Fn(&str) -> Error) -> Result<(), Error> {
        let (mode, filter) = (self.mode.as_str(), self.filter.as_str());
        let stride_ok = match mode {
            "ATTRIBUTES" => self.stride.is_multiple_of(4) && (4..=256).contains(&self.stride),
            "TRIANGLES" | "INDICES" => self.stride == 2 || self.stride == 4,
            _ => return Err(err(&format!("mode '{mode}' is not ATTRIBUTES, TRIANGLES or INDICES"))),
        };
        if !stride_ok {
            return Err(err(&format!("byteStride {} does not suit mode {mode}", self.stride)));
        }
        if mode == "TRIANGLES" && !self.count.is_multiple_of(3) {
            return Err(err(&format!(
                "count {} of a TRIANGLES view is not a multiple of 3",
                self.count
            )));
        }
        let filter_ok = match filter {
            "NONE" => true,
            "OCTAHEDRAL" => mode == "ATTRIBUTES" && (self.stride == 4 || self.stride == 8),
            "QUATERNION" => mode == "ATTRIBUTES" && self.stride == 8,
            "EXPONENTIAL" => mode == "ATTRIBUTES",
            "COLOR" => name == KHR && mode == "ATTRIBUTES" && (self.stride == 4 || self.stride == 8),
            _ => false,
        };
        if !filter_ok {
            return Err(err(&format!(
                "filter '{filter}' does not apply to mode {mode} with byteStride {}",
                self.stride
            )));
        }
        Ok(())
    }
}

fn field(ext: &Value, key: &str) -> Option<usize> {
    ext.get(key)
        .and_then(Value::as_u64)
        .and_then(|v| usize::try_from(v).ok())
}

/// Decodes every compressed view of `doc` into `buffers` (which hold its fallback buffers as zeros).
pub(super) fn decompress(path: &Path, doc: &gltf::Document, buffers: &mut [gltf::buffer::Data]) -> Result<(), Error> {
    for view in doc.views() {
        let (name, ext) = match (view.extension_value(KHR), view.extension_value(EXT)) {
            (Some(e), _) => (KHR, e),
            (None, Some(e)) => (EXT, e),
            (None, None) => continue,
        };
        let err = |m: &str| scene_err(path, format!("bufferView {} ({name}): {m}", view.index()));
        let c = Compressed::read(ext, &err)?;
        c.check(name, &err)?;
        let (mode, filter) = (c.mode.as_str(), c.filter.as_str());
        let size = c
            .count
            .checked_mul(c.stride)
            .filter(|&s| s <= view.length())
            .ok_or_else(|| {
                err(&format!(
                    "{} elements of {} bytes do not fit the view's byteLength {}",
                    c.count,
                    c.stride,
                    view.length()
                ))
            })?;
        let source = buffers
            .get(c.source)
            .and_then(|b| b.0.get(c.offset..c.offset.checked_add(c.length)?))
            .ok_or_else(|| err(&format!("its data lies outside buffer {}", c.source)))?;
        // u32 storage keeps the filters' 16- and 32-bit accesses aligned.
        let mut decoded = vec![0u32; size.div_ceil(4)];
        let out = decoded.as_mut_ptr().cast::<std::ffi::c_void>();
        // SAFETY: `out` holds at least count * stride bytes, and `source` is a live slice; meshoptimizer's decoders
        // are written for untrusted input and never write past count * stride.
        let code = unsafe {
            match mode {
                "ATTRIBUTES" => {
                    ::meshopt::ffi::meshopt_decodeVertexBuffer(out, c.count, c.stride, source.as_ptr(), source.len())
                }
                "TRIANGLES" => {
                    ::meshopt::ffi::meshopt_decodeIndexBuffer(out, c.count, c.stride, source.as_ptr(), source.len())
                }
                _ => ::meshopt::ffi::meshopt_decodeIndexSequence(out, c.count, c.stride, source.as_ptr(), source.len()),
            }
        };
        if code != 0 {
            return Err(err(&format!(
                "the compressed data does not decode (meshoptimizer error {code})"
            )));
        }
        // SAFETY: as above; each filter reads and writes count elements of `stride` bytes in place, its stride
        // checked against what it accepts (`Compressed::check`).
        unsafe {
            match filter {
                "OCTAHEDRAL" => ::meshopt::ffi::meshopt_decodeFilterOct(out, c.count, c.stride),
                "QUATERNION" => ::meshopt::ffi::meshopt_decodeFilterQuat(out, c.count, c.stride),
                "EXPONENTIAL" => ::meshopt::ffi::meshopt_decodeFilterExp(out, c.count, c.stride),
                "COLOR" => ::meshopt::ffi::meshopt_decodeFilterColor(out, c.count, c.stride),
                _ => {}
            }
        }
        let target = view.buffer().index();
        let bytes: &[u8] = bytemuck::cast_slice(&decoded);
        let dest = buffers
            .get_mut(target)
            .and_then(|b| b.0.get_mut(view.offset()..view.offset().checked_add(size)?))
            .ok_or_else(|| err(&format!("the decoded data does not fit buffer {target}")))?;
        dest.copy_from_slice(&bytes[..size]);
    }
    Ok(())
}
