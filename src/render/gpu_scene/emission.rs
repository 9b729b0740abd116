//! The power an emissive triangle sends out, for light selection: its material's emission over the texels its texture
//! coordinates reach (a summed-area table per emissive image), not over the whole texture.
use crate::scene::{Image, Scene, TextureRef, TriangleSoup, Wrap};
use std::collections::HashMap;

/// Prefix sums of an image's texels weighted by an emission colour: the mean over channels of the colour times the
/// texel decoded from sRGB. `sums[(y + 1) * (w + 1) + x + 1]` is the sum over [0, x] × [0, y]; f64 keeps a 4096²
/// image's sums exact to far below one texel.
struct Sat {
    w: usize,
    h: usize,
    sums: Vec<f64>,
}

impl Sat {
    fn new(image: &Image, weights: [f32; 3]) -> Sat {
        let lut: Vec<f64> = (0..256)
            .map(|i| crate::scene::texture::srgb_to_linear(i as f32 / 255.0) as f64)
            .collect();
        let (w, h) = (image.width as usize, image.height as usize);
        let mut sums = vec![0.0; (w + 1) * (h + 1)];
        for y in 0..h {
            let mut row = 0.0;
            for x in 0..w {
                let t = image.texels[y * w + x];
                row += (0..3).map(|c| weights[c] as f64 * lut[t[c] as usize]).sum::<f64>() / 3.0;
                sums[(y + 1) * (w + 1) + x + 1] = sums[y * (w + 1) + x + 1] + row;
            }
        }
        Sat { w, h, sums }
    }

    /// The sum over texels [x0, x1] × [y0, y1], inclusive and within the image.
    fn rect(&self, (x0, x1): (usize, usize), (y0, y1): (usize, usize)) -> f64 {
        let at = |x: usize, y: usize| self.sums[y * (self.w + 1) + x];
        at(x1 + 1, y1 + 1) - at(x0, y1 + 1) - at(x1 + 1, y0) + at(x0, y0)
    }
}

/// The texels of a row (or column) of n that lookups anywhere in texel positions [a, b] read under `wrap`: one or two
/// intervals, or all n when the range spans the image.
fn intervals(a: i64, b: i64, n: i64, wrap: Wrap) -> Vec<(usize, usize)> {
    if wrap == Wrap::ClampToEdge {
        return vec![(a.clamp(0, n - 1) as usize, b.clamp(0, n - 1) as usize)];
    }
    if b - a + 1 >= n {
        return vec![(0, n as usize - 1)];
    }
    let mut out = Vec::with_capacity(2);
    let mut x = a;
    while x <= b {
        let tile = x.div_euclid(n);
        let end = b.min((tile + 1) * n - 1);
        let (lo, hi) = (x - tile * n, end - tile * n);
        // A mirrored repeat reads odd tiles backwards.
        let (lo, hi) = if wrap == Wrap::MirroredRepeat && tile.rem_euclid(2) == 1 {
            (n - 1 - hi, n - 1 - lo)
        } else {
            (lo, hi)
        };
        out.push((lo as usize, hi as usize));
        x = end + 1;
    }
    out
}

/// Emitted power of the scene's triangles, with the summed-area tables of their emissive images made once each.
pub struct Emission<'a> {
    scene: &'a Scene,
    /// By (image, the emission colour's bits).
    sats: HashMap<(usize, [u32; 3]), Sat>,
}

impl<'a> Emission<'a> {
    pub fn new(scene: &'a Scene) -> Self {
        Emission {
            scene,
            sats: HashMap::new(),
        }
    }

    /// Mean emitted radiance (over channels) of triangle `tri` of `soup`: its material's emission, times the mean of
    /// the texels its emissive texture's lookups can read (the box around its texture coordinates, widened by the
    /// texel bilinear filtering reaches). A footprint whose texels are all black emits nothing: such a triangle
    /// gets no power, so light selection never picks it and MIS gives its emission to BSDF sampling in full.
    pub fn radiance(&mut self, soup: &TriangleSoup, tri: usize) -> f64 {
        let m = &self.scene.materials[soup.material()[tri] as usize];
        let e = m.emission;
        let Some(r) = m.emissive_texture else {
            return (e.x + e.y + e.z) as f64 / 3.0;
        };
        let texture = &self.scene.textures[r.texture];
        let image = &self.scene.images[texture.image];
        if image.width == 0 || image.height == 0 || e.max_element() <= 0.0 {
            return 0.0;
        }
        let sat = (self.sats)
            .entry((texture.image, e.to_array().map(f32::to_bits)))
            .or_insert_with(|| Sat::new(image, e.to_array()));
        let (xs, ys) = footprint(&r, soup.texcoords()[tri], sat.w as i64, sat.h as i64);
        let (wrap_x, wrap_y) = (texture.wrap_s, texture.wrap_t);
        let (xs, ys) = (
            intervals(xs.0, xs.1, sat.w as i64, wrap_x),
            intervals(ys.0, ys.1, sat.h as i64, wrap_y),
        );
        let (mut sum, mut count) = (0.0, 0usize);
        for &x in &xs {
            for &y in &ys {
                sum += sat.rect(x, y);
                count += (x.1 - x.0 + 1) * (y.1 - y.0 + 1);
            }
        }
        sum / count.max(1) as f64
    }

    /// The power the triangle emits over `area`: radiance × area × pi (× 2 when both faces emit).
    pub fn power(&mut self, soup: &TriangleSoup, tri: usize, area: f32) -> f64 {
        let sides = if self.scene.materials[soup.material()[tri] as usize].double_sided {
            2.0
        } else {
            1.0
        };
        self.radiance(soup, tri) * area as f64 * std::f64::consts::PI * sides
    }
}

/// The texel positions (inclusive, before wrapping) a lookup anywhere in the triangle can read: the box around its
/// transformed texture coordinates in texel space (texel centres at half-integers), and the next texel each way for
/// bilinear filtering. Coordinates that are not finite reach every texel.
fn footprint(r: &TextureRef, uvs: [glam::Vec4; 3], w: i64, h: i64) -> ((i64, i64), (i64, i64)) {
    let (mut lo, mut hi) = (glam::Vec2::splat(f32::INFINITY), glam::Vec2::splat(f32::NEG_INFINITY));
    for t in uvs {
        let uv = if r.tex_coord == 0 {
            t.truncate().truncate()
        } else {
            glam::Vec2::new(t.z, t.w)
        };
        let [a, b] = r.transform;
        let p = glam::Vec2::new(a[0] * uv.x + a[1] * uv.y + a[2], b[0] * uv.x + b[1] * uv.y + b[2]);
        lo = lo.min(p);
        hi = hi.max(p);
    }
    let span = |lo: f32, hi: f32, n: i64| {
        let (a, b) = (lo as f64 * n as f64 - 0.5, hi as f64 * n as f64 - 0.5);
        if !(a.is_finite() && b.is_finite()) || b - a > 4.0 * n as f64 {
            return (0, 4 * n);
        }
        (a.floor() as i64, b.floor() as i64 + 1)
    };
    (span(lo.x, hi.x, w), span(lo.y, hi.y, h))
}

#[cfg(test)]
mod tests {
    use super::*;

    // The box sums against brute force, and the wrap modes' intervals against a texel-by-texel walk.
    #[test]
    fn sums_and_wrapped_intervals_match_brute_force() {
        let (w, h) = (7usize, 5usize);
        let texels: Vec<[u8; 4]> = (0..w * h)
            .map(|i| [(i * 37 % 256) as u8, (i * 11 % 256) as u8, 9, 255])
            .collect();
        let image = Image {
            width: w as u32,
            height: h as u32,
            texels: texels.clone(),
        };
        let weights = [1.0, 2.0, 0.5];
        let sat = Sat::new(&image, weights);
        let value = |x: usize, y: usize| {
            let t = texels[y * w + x];
            (0..3)
                .map(|c| weights[c] as f64 * crate::scene::texture::srgb_to_linear(t[c] as f32 / 255.0) as f64)
                .sum::<f64>()
                / 3.0
        };
        for (x0, x1, y0, y1) in [(0, 6, 0, 4), (2, 3, 1, 1), (5, 6, 3, 4), (0, 0, 0, 0)] {
            let brute: f64 = (x0..=x1)
                .flat_map(|x| (y0..=y1).map(move |y| (x, y)))
                .map(|(x, y)| value(x, y))
                .sum();
            assert!((sat.rect((x0, x1), (y0, y1)) - brute).abs() < 1e-9);
        }
        for wrap in [Wrap::Repeat, Wrap::MirroredRepeat, Wrap::ClampToEdge] {
            for (a, b) in [(-3i64, 2i64), (5, 9), (-9, -8), (3, 3), (-2, 12)] {
                let n = 7i64;
                let mut want = vec![false; 7];
                for x in a..=b {
                    let t = match wrap {
                        Wrap::Repeat => x.rem_euclid(n),
                        Wrap::MirroredRepeat => {
                            let m = x.rem_euclid(2 * n);
                            if m < n {
                                m
                            } else {
                                2 * n - 1 - m
                            }
                        }
                        Wrap::ClampToEdge => x.clamp(0, n - 1),
                    };
                    want[t as usize] = true;
                }
                let mut got = vec![false; 7];
                for (lo, hi) in intervals(a, b, n, wrap) {
                    got[lo..=hi].iter_mut().for_each(|g| *g = true);
                }
                assert_eq!(got, want, "{wrap:?} [{a}, {b}]");
            }
        }
    }
}
