//! How many paths a pass holds and how it covers the image with them: pure arithmetic, tested here without a device.
use super::Schedule;
use crate::constants::{FEATURE_MEDIA, FOLLOW_ROWS_MAX, PATH_FIELDS};

/// The device limits the path state must fit.
#[derive(Clone, Copy, Debug)]
pub(super) struct PathLimits {
    /// maxStorageBufferRange: the path state is one storage buffer.
    pub storage_range: u64,
    /// maxTexelBufferElements: the TEXEL_READS stages read the path state through one texel view, which must see
    /// all of it.
    pub texel_elements: u64,
    /// The largest device-local heap, in bytes.
    pub device_local_heap: u64,
}

/// Paths in flight for `wanted` paths: every pixel times as many samples as fit, or chunks of pixels when one sample
/// of the image alone is larger. The budget is a sixteenth of the largest device-local heap (1024 paths at least),
/// within one storage buffer's range: on lavapipe that is 2^20 paths (128 MiB), 6 % faster on the Cornell box than
/// 2^18. path_count (rows x pixels, up to four times the capacity in a fused pass) must stay within u32.
pub(super) fn path_capacity(wanted: u64, limits: PathLimits, fields: u32) -> u32 {
    let per_path = fields as u64 * 16;
    let budget = (limits.device_local_heap / 16).max(per_path * 1024);
    wanted
        .min(limits.storage_range / per_path)
        .min(limits.texel_elements / fields as u64)
        .min(budget / per_path)
        .min(u32::MAX as u64 / 4) as u32
}

/// The vec4 fields a path keeps for a scene of `features`: PATH_FIELDS, and where media are, the medium stack and
/// the free flights' channel densities (PATH_MEDIUM, PATH_MEDIUM_RATIOS).
pub(super) fn path_fields(features: u32) -> u32 {
    match features & FEATURE_MEDIA {
        0 => PATH_FIELDS,
        _ => PATH_FIELDS + 2,
    }
}

/// How one pass covers `pixels` pixels: `chunks` dispatches of `chunk` pixels each (the last may hold fewer), every
/// pixel taking `rows` samples. `rows` is what the pass adds to the session's samples.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct PassSize {
    pub rows: u32,
    pub chunk: u32,
    pub chunks: u32,
}

/// One dispatch of a pass: the pixels it covers and its paths.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct Slice {
    pub pixel_offset: u32,
    pub pass_pixels: u32,
    pub path_count: u32,
}

/// A pass of up to `samples` rows (one at least) over `pixels` pixels with room for `capacity` paths. When every pixel
/// fits, whole samples of every pixel, as many as fit: a fused pass keeps only a pixel's running sums in the path
/// state, so it may take more than fit there (FOLLOW_ROWS_MAX: a dispatch takes up to that many, and the more, the
/// less lanes wait for the last paths). Otherwise one sample, the image in chunks of `capacity` pixels.
pub(super) fn size_pass(pixels: u64, capacity: u32, schedule: Schedule, samples: u32) -> PassSize {
    let pixels = pixels.max(1);
    let capacity = capacity.max(1);
    if pixels <= capacity as u64 {
        let fit = (capacity as u64 / pixels) as u32;
        let rows = match schedule {
            // path_count must stay within u32, as the path state's capacity does.
            Schedule::Fused => fit.max(FOLLOW_ROWS_MAX).min((u32::MAX as u64 / 4 / pixels) as u32),
            Schedule::Wavefront => fit,
        }
        .min(samples.max(1));
        PassSize {
            rows,
            chunk: pixels as u32,
            chunks: 1,
        }
    } else {
        PassSize {
            rows: 1,
            chunk: capacity,
            chunks: pixels.div_ceil(capacity as u64) as u32,
        }
    }
}

impl PassSize {
    /// Dispatch `i` (below `chunks`) of a pass over `pixels` pixels.
    pub fn slice(&self, pixels: u64, i: u32) -> Slice {
        let offset = i as u64 * self.chunk as u64;
        let pass_pixels = (pixels.max(1) - offset).min(self.chunk as u64) as u32;
        Slice {
            pixel_offset: offset as u32,
            pass_pixels,
            path_count: pass_pixels * self.rows,
        }
    }
}

/// A pass of `path_count` paths over `pass_pixels` pixels as wavefront passes of as many sample rows as `path_capacity`
/// holds (a fused pass may have more): (first row, rows) of each.
pub(super) fn wavefront_rows(
    path_count: u32,
    pass_pixels: u32,
    path_capacity: u32,
) -> impl Iterator<Item = (u32, u32)> {
    let rows = path_count / pass_pixels.max(1);
    let fit = (path_capacity / pass_pixels.max(1)).max(1);
    (0..rows)
        .step_by(fit as usize)
        .map(move |first| (first, fit.min(rows - first)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::constants::FOLLOW_SAMPLES;

    fn whole(rows: u32, pixels: u32) -> PassSize {
        PassSize {
            rows,
            chunk: pixels,
            chunks: 1,
        }
    }

    /// A wavefront pass takes as many rows as fit, no more than asked, and one when asked for none.
    #[test]
    fn a_wavefront_pass_takes_the_rows_that_fit() {
        assert_eq!(size_pass(100, 1000, Schedule::Wavefront, 16), whole(10, 100));
        assert_eq!(size_pass(100, 1000, Schedule::Wavefront, 4), whole(4, 100));
        assert_eq!(size_pass(100, 1000, Schedule::Wavefront, 0), whole(1, 100));
    }

    /// A fused pass takes FOLLOW_ROWS_MAX rows even where fewer fit in the path state, but no more than asked, and
    /// never so many that rows x pixels leaves u32 (the follow rows and path counts are u32 on the device).
    #[test]
    fn a_fused_pass_takes_more_rows_than_fit_within_u32() {
        assert_eq!(size_pass(100, 1000, Schedule::Fused, 1000), whole(FOLLOW_ROWS_MAX, 100));
        assert_eq!(size_pass(100, 1000, Schedule::Fused, 20), whole(20, 100));
        let pixels = 1u64 << 28;
        let s = size_pass(pixels, 1 << 28, Schedule::Fused, 1000);
        assert_eq!(s.rows, (u32::MAX as u64 / 4 / pixels) as u32);
        assert!(s.rows as u64 * pixels <= u32::MAX as u64);
        assert_eq!(s.slice(pixels, 0).path_count as u64, s.rows as u64 * pixels);
    }

    /// An image of exactly the capacity is one whole pass; one pixel more needs chunks of one sample.
    #[test]
    fn chunks_begin_one_pixel_past_the_capacity() {
        assert_eq!(size_pass(1000, 1000, Schedule::Wavefront, 8), whole(1, 1000));
        let s = size_pass(1001, 1000, Schedule::Fused, 8);
        assert_eq!(
            s,
            PassSize {
                rows: 1,
                chunk: 1000,
                chunks: 2
            }
        );
        assert_eq!(s.slice(1001, 1).pass_pixels, 1);
    }

    /// Chunks cover every pixel once, in order, the last holding the remainder.
    #[test]
    fn chunks_cover_the_image_once() {
        let s = size_pass(2500, 1000, Schedule::Wavefront, 16);
        assert_eq!((s.rows, s.chunks), (1, 3));
        let slices: Vec<Slice> = (0..s.chunks).map(|i| s.slice(2500, i)).collect();
        let at = |pixel_offset, pass_pixels| Slice {
            pixel_offset,
            pass_pixels,
            path_count: pass_pixels,
        };
        assert_eq!(slices, [at(0, 1000), at(1000, 1000), at(2000, 500)]);
        assert_eq!(size_pass(100, 1000, Schedule::Wavefront, 4).slice(100, 0), {
            Slice {
                pixel_offset: 0,
                pass_pixels: 100,
                path_count: 400,
            }
        });
    }

    /// The capacity is the least of what the wanted paths, the storage range, the texel view, a sixteenth of the
    /// heap (1024 paths at least) and u32 allow.
    #[test]
    fn the_path_capacity_is_the_tightest_limit() {
        let per_path = PATH_FIELDS as u64 * 16;
        let lavapipe = PathLimits {
            storage_range: 1 << 27,
            texel_elements: 1 << 27,
            device_local_heap: 1 << 35,
        };
        assert_eq!(
            path_capacity(u64::MAX, lavapipe, PATH_FIELDS),
            (1 << 27) / per_path as u32
        );
        assert_eq!(path_capacity(5000, lavapipe, PATH_FIELDS), 5000, "no more than wanted");
        let no_heap = PathLimits {
            device_local_heap: 0,
            ..lavapipe
        };
        assert_eq!(path_capacity(u64::MAX, no_heap, PATH_FIELDS), 1024);
        let small_view = PathLimits {
            texel_elements: 64 * PATH_FIELDS as u64,
            ..lavapipe
        };
        assert_eq!(path_capacity(u64::MAX, small_view, PATH_FIELDS), 64);
        let huge = PathLimits {
            storage_range: u64::MAX,
            texel_elements: u64::MAX,
            device_local_heap: u64::MAX,
        };
        assert_eq!(path_capacity(u64::MAX, huge, PATH_FIELDS), u32::MAX / 4);
    }

    /// A fused pass too large for the path state reruns as wavefront passes of the rows that fit, the last holding
    /// the rest; a pass of no pixels is guarded.
    #[test]
    fn wavefront_rows_split_what_does_not_fit() {
        let p = 100;
        let rows: Vec<_> = wavefront_rows(20 * p, p, 6 * p).collect();
        assert_eq!(rows, [(0, 6), (6, 6), (12, 6), (18, 2)]);
        let rows: Vec<_> = wavefront_rows(FOLLOW_SAMPLES * p, p, 1000 * p).collect();
        assert_eq!(rows, [(0, FOLLOW_SAMPLES)]);
        assert_eq!(wavefront_rows(5, 0, 0).count(), 5);
    }
}
