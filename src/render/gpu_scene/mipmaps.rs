//! Mip chains of the texture images: each level half the one above (rounded up), a 2x2 box average, in linear light
//! for images whose colour is sRGB-encoded.
use crate::output::srgb_encode;
use crate::scene::texture::{srgb_to_linear, Image};

/// Levels at most: a 16384-texel side (MAX_IMAGE_SIDE) halves to 1 in 14 steps, so 15 levels; the count fits
/// TextureInfo.flags' TEXTURE_LEVELS bits.
pub const MAX_LEVELS: u32 = 15;

/// The size of level `k` of a `w` x `h` image: each level halves the one above, rounding up (so an odd row's last
/// texel is averaged with itself), down to 1 x 1. textures.glsl's level_size computes the same.
pub fn level_size(w: u32, h: u32, k: u32) -> (u32, u32) {
    let half = |n: u32| ((n as u64 + (1u64 << k) - 1) >> k).max(1) as u32;
    (half(w), half(h))
}

/// How many levels a `w` x `h` image has: down to 1 x 1.
pub fn level_count(w: u32, h: u32) -> u32 {
    let side = w.max(h).max(1);
    (32 - (side - 1).leading_zeros() + 1).min(MAX_LEVELS)
}

/// The levels below level 0 of `image`, in order, each row-major like the image. `srgb`: the colour channels are
/// sRGB-encoded (the image is a base colour or another colour texture), so they are averaged as linear values and
/// encoded again; alpha and the channels of data textures (normals, roughness) are averaged as stored.
pub fn chain(image: &Image, srgb: bool) -> Vec<Vec<[u8; 4]>> {
    let decode: [f32; 256] = std::array::from_fn(|i| {
        let c = i as f32 / 255.0;
        if srgb {
            srgb_to_linear(c)
        } else {
            c
        }
    });
    let unorm: [f32; 256] = std::array::from_fn(|i| i as f32 / 255.0);
    let encode = |x: f32, colour: bool| -> u8 {
        let x = x.clamp(0.0, 1.0);
        let e = if colour && srgb { srgb_encode(x) } else { x };
        (e * 255.0 + 0.5) as u8
    };
    let mut levels: Vec<Vec<[u8; 4]>> = Vec::new();
    // Each level from the stored (rounded) level above, as a GPU's mipmap generation does: no float copy of a large
    // image is ever held (a 16384-texel square would take 4 GiB).
    let (mut w, mut h) = (image.width, image.height);
    for k in 1..level_count(image.width, image.height) {
        let (lw, lh) = level_size(image.width, image.height, k);
        let above: &[[u8; 4]] = levels.last().map_or(&image.texels, |l| l);
        let mut next = Vec::with_capacity((lw * lh) as usize);
        for y in 0..lh {
            let (y0, y1) = (2 * y, (2 * y + 1).min(h - 1));
            for x in 0..lw {
                let (x0, x1) = (2 * x, (2 * x + 1).min(w - 1));
                let quad = [(x0, y0), (x1, y0), (x0, y1), (x1, y1)].map(|(xx, yy)| above[(yy * w + xx) as usize]);
                let mean = |i: usize, table: &[f32; 256]| 0.25 * quad.iter().map(|t| table[t[i] as usize]).sum::<f32>();
                next.push([
                    encode(mean(0, &decode), true),
                    encode(mean(1, &decode), true),
                    encode(mean(2, &decode), true),
                    encode(mean(3, &unorm), false),
                ]);
            }
        }
        levels.push(next);
        (w, h) = (lw, lh);
    }
    levels
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_halve_rounding_up_down_to_one_texel() {
        assert_eq!(level_count(1, 1), 1);
        assert_eq!(level_count(2, 1), 2);
        assert_eq!(level_count(4, 4), 3);
        assert_eq!(level_count(5, 3), 4); // 5x3, 3x2, 2x1, 1x1
        assert_eq!(level_count(16384, 16384), 15);
        assert_eq!(level_size(5, 3, 1), (3, 2));
        assert_eq!(level_size(5, 3, 2), (2, 1));
        assert_eq!(level_size(5, 3, 3), (1, 1));
        assert_eq!(level_size(5, 3, 9), (1, 1));
    }

    /// A black and white checkerboard averages to mid-grey in linear light: sRGB 188, not the 128 an average of the
    /// encoded values would give (which would darken every minified sRGB texture); data channels average as stored.
    #[test]
    fn srgb_colour_averages_in_linear_light() {
        let texels = (0..16).map(|i| {
            if (i + i / 4) % 2 == 0 {
                [255, 255, 255, 255]
            } else {
                [0, 0, 0, 0]
            }
        });
        let image = Image {
            width: 4,
            height: 4,
            texels: texels.collect(),
        };
        let levels = chain(&image, true);
        assert_eq!(levels.len(), 2);
        assert_eq!(levels[0].len(), 4);
        assert_eq!(levels[1], vec![[188, 188, 188, 128]]);
        assert_eq!(chain(&image, false)[1], vec![[128, 128, 128, 128]]);
    }

    /// An odd side's last texel is averaged with itself: a 3x1 ramp (0, 100, 200) gives (50, 200), then 125.
    #[test]
    fn odd_sides_repeat_their_last_texel() {
        let image = Image {
            width: 3,
            height: 1,
            texels: vec![[0, 0, 0, 255], [100, 100, 100, 255], [200, 200, 200, 255]],
        };
        let levels = chain(&image, false);
        assert_eq!(levels[0], vec![[50, 50, 50, 255], [200, 200, 200, 255]]);
        assert_eq!(levels[1], vec![[125, 125, 125, 255]]);
    }
}
