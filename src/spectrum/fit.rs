// The Jakob–Hanika fit (2019): for an RGB, the sigmoid-of-quadratic reflectance whose colour under D65 is that RGB,
// and the table of them the renderer ships (data/rgb2spec_srgb_32.bin, made by examples/rgb2spec.rs).

/// The CIE 1931 2° observer and the D65 illuminant at 1 nm (data/cie1931_d65.tsv; data/make_cie.py says where the
/// numbers come from).
pub struct Cie {
    pub first_nm: f64,
    pub xyz: Vec<[f64; 3]>,
    pub d65: Vec<f64>,
}

impl Cie {
    pub fn parse(text: &str) -> Cie {
        let mut first_nm = None;
        let (mut xyz, mut d65) = (Vec::new(), Vec::new());
        for line in text.lines().filter(|l| !l.starts_with('#') && !l.trim().is_empty()) {
            let v: Vec<f64> = line
                .split('\t')
                .map(|s| s.trim().parse().expect("a number in the CIE table"))
                .collect();
            assert_eq!(v.len(), 5, "the CIE table has five columns");
            let nm = *first_nm.get_or_insert(v[0]);
            assert_eq!(v[0], nm + xyz.len() as f64, "the CIE table is at 1 nm without gaps");
            xyz.push([v[1], v[2], v[3]]);
            d65.push(v[4]);
        }
        Cie {
            first_nm: first_nm.expect("rows in the CIE table"),
            xyz,
            d65,
        }
    }

    pub fn last_nm(&self) -> f64 {
        self.first_nm + (self.xyz.len() - 1) as f64
    }
}

/// Rec. 709 primaries (x, y): sRGB's.
const PRIMARIES: [[f64; 2]; 3] = [[0.64, 0.33], [0.30, 0.60], [0.15, 0.06]];

pub type M3 = [[f64; 3]; 3];

pub fn mul(m: &M3, v: [f64; 3]) -> [f64; 3] {
    [0, 1, 2].map(|r| m[r][0] * v[0] + m[r][1] * v[1] + m[r][2] * v[2])
}

pub fn invert(m: &M3) -> M3 {
    let c = |r: usize, k: usize| {
        let (r1, r2, k1, k2) = ((r + 1) % 3, (r + 2) % 3, (k + 1) % 3, (k + 2) % 3);
        m[r1][k1] * m[r2][k2] - m[r1][k2] * m[r2][k1]
    };
    let det = m[0][0] * c(0, 0) + m[0][1] * c(0, 1) + m[0][2] * c(0, 2);
    // The inverse is the transposed cofactor matrix over the determinant.
    [0, 1, 2].map(|r| [0, 1, 2].map(|k| c(k, r) / det))
}

/// Linear sRGB to XYZ, from the primaries and the white: D65's XYZ as the tables integrate it (Y = 1), so that
/// (1, 1, 1) is exactly the white the tables make (sRGB's nominal (0.3127, 0.3290) is D65 rounded).
pub fn srgb_to_xyz(white: [f64; 3]) -> M3 {
    let xyz = |p: [f64; 2]| [p[0] / p[1], 1.0, (1.0 - p[0] - p[1]) / p[1]];
    let cols = PRIMARIES.map(xyz);
    let p: M3 = [0, 1, 2].map(|r| [cols[0][r], cols[1][r], cols[2][r]]);
    let s = mul(&invert(&p), white);
    [0, 1, 2].map(|r| [0, 1, 2].map(|k| p[r][k] * s[k]))
}

/// The sigmoid that maps the quadratic to (0, 1); ±infinity give the constant spectra 1 and 0.
pub fn sigmoid(x: f64) -> f64 {
    if x.is_infinite() {
        return if x > 0.0 { 1.0 } else { 0.0 };
    }
    0.5 + x / (2.0 * (1.0 + x * x).sqrt())
}

/// Coefficients are over the normalised wavelength t = (λ − first) / (last − first): the quadratic c0 t² + c1 t + c2.
pub fn quadratic(c: [f64; 3], t: f64) -> f64 {
    (c[0] * t + c[1]) * t + c[2]
}

/// The fit's integrator: a reflectance's XYZ under D65 (trapezoid rule at 1 nm), white normalised to Y = 1.
pub struct Fit {
    t: Vec<f64>,
    /// Per wavelength: its trapezoid weight times D65 times the observer, over D65's Y.
    weights: Vec<[f64; 3]>,
    pub to_srgb: M3,
    pub to_xyz: M3,
    /// D65's XYZ, Y = 1.
    pub white: [f64; 3],
    /// ∫ ȳ dλ (the film divides XYZ by it), and the factor that gives D65 a Y of 1 against it.
    pub y_integral: f64,
    pub d65_scale: f64,
}

impl Fit {
    pub fn new(cie: &Cie) -> Fit {
        let n = cie.xyz.len();
        let span = cie.last_nm() - cie.first_nm;
        let trapezoid = |i: usize| if i == 0 || i == n - 1 { 0.5 } else { 1.0 };
        let norm: f64 = (0..n).map(|i| trapezoid(i) * cie.d65[i] * cie.xyz[i][1]).sum();
        let y_integral: f64 = (0..n).map(|i| trapezoid(i) * cie.xyz[i][1]).sum();
        let weights = (0..n)
            .map(|i| cie.xyz[i].map(|c| trapezoid(i) * cie.d65[i] * c / norm))
            .collect::<Vec<_>>();
        let mut white = [0.0; 3];
        for w in &weights {
            (0..3).for_each(|k| white[k] += w[k]);
        }
        let to_xyz = srgb_to_xyz(white);
        Fit {
            t: (0..n).map(|i| i as f64 / span).collect(),
            weights,
            to_srgb: invert(&to_xyz),
            to_xyz,
            white,
            y_integral,
            d65_scale: y_integral / norm,
        }
    }

    /// XYZ of the reflectance with coefficients c, and its derivatives d XYZ_i / d c_k.
    fn xyz(&self, c: [f64; 3]) -> ([f64; 3], M3) {
        let (mut v, mut j) = ([0.0; 3], [[0.0; 3]; 3]);
        for (t, w) in self.t.iter().zip(&self.weights) {
            let x = quadratic(c, *t);
            let s = sigmoid(x);
            let ds = 0.5 / (1.0 + x * x).powf(1.5);
            let dc = [t * t * ds, t * ds, ds];
            for i in 0..3 {
                v[i] += w[i] * s;
                for k in 0..3 {
                    j[i][k] += w[i] * dc[k];
                }
            }
        }
        (v, j)
    }

    /// The linear sRGB of the reflectance with coefficients c, seen under D65 (its white is (1, 1, 1)).
    pub fn project(&self, c: [f64; 3]) -> [f64; 3] {
        mul(&self.to_srgb, self.xyz(c).0)
    }

    /// CIELAB of an XYZ (relative to D65), and its derivatives: the fit's residual is perceptual, as in the paper.
    fn lab(&self, xyz: [f64; 3]) -> ([f64; 3], M3) {
        const D: f64 = 6.0 / 29.0;
        let f = |t: f64| {
            if t > D * D * D {
                (t.cbrt(), 1.0 / (3.0 * t.cbrt() * t.cbrt()))
            } else {
                (t / (3.0 * D * D) + 4.0 / 29.0, 1.0 / (3.0 * D * D))
            }
        };
        let (fx, dx) = f(xyz[0] / self.white[0]);
        let (fy, dy) = f(xyz[1] / self.white[1]);
        let (fz, dz) = f(xyz[2] / self.white[2]);
        let (dx, dy, dz) = (dx / self.white[0], dy / self.white[1], dz / self.white[2]);
        (
            [116.0 * fy - 16.0, 500.0 * (fx - fy), 200.0 * (fy - fz)],
            [
                [0.0, 116.0 * dy, 0.0],
                [500.0 * dx, -500.0 * dy, 0.0],
                [0.0, 200.0 * dy, -200.0 * dz],
            ],
        )
    }

    /// Gauss–Newton from `start` to the coefficients whose colour is `rgb` (linear sRGB in [0, 1]), each step halved
    /// until the residual falls; and its squared residual (ΔE², CIELAB).
    pub fn solve(&self, rgb: [f64; 3], start: [f64; 3]) -> ([f64; 3], f64) {
        let target = self.lab(mul(&self.to_xyz, rgb)).0;
        let residual = |c: [f64; 3]| {
            let (xyz, dxyz) = self.xyz(c);
            let (lab, dlab) = self.lab(xyz);
            let r = [0, 1, 2].map(|i| lab[i] - target[i]);
            let jac: M3 = [0, 1, 2].map(|i| [0, 1, 2].map(|k| (0..3).map(|m| dlab[i][m] * dxyz[m][k]).sum()));
            (r, r.iter().map(|x| x * x).sum::<f64>(), jac)
        };
        let mut c = start;
        let (mut r, mut err, mut jac) = residual(c);
        for _ in 0..40 {
            if err < 1e-12 {
                break;
            }
            let step = mul(&invert(&jac), r);
            if step.iter().any(|s| !s.is_finite()) {
                break;
            }
            let mut scale = 1.0;
            let mut taken = false;
            while scale > 1e-4 {
                let mut next = [0, 1, 2].map(|k| c[k] - scale * step[k]);
                // Saturated colours push the coefficients outwards without bound; past this the sigmoid is a step
                // and larger values change nothing but the conditioning.
                let largest = next.iter().fold(0.0f64, |m, x| m.max(x.abs()));
                if largest > CLAMP {
                    next = next.map(|x| x * CLAMP / largest);
                }
                let (r2, err2, jac2) = residual(next);
                if err2 < err {
                    (c, r, err, jac, taken) = (next, r2, err2, jac2, true);
                    break;
                }
                scale *= 0.5;
            }
            if !taken {
                break;
            }
        }
        (c, err)
    }
}

/// The largest coefficient the fit keeps (over t in [0, 1]); f32 holds the quadratic to 1e-4 at this size.
const CLAMP: f64 = 1000.0;

/// The table's nodes along the largest component: denser near 0 and 1, where the coefficients change fastest.
pub fn z_nodes(res: usize) -> Vec<f64> {
    let smooth = |x: f64| x * x * (3.0 - 2.0 * x);
    (0..res).map(|k| smooth(smooth(k as f64 / (res - 1) as f64))).collect()
}

/// One column of the table: the coefficients at every node z for largest channel l and the next two channels over
/// the largest at x / (res − 1) and y / (res − 1). The sweep starts a fifth of the way up, where a start at zero
/// converges, and goes outwards, each node starting from its neighbour's answer (a start that leads nowhere, its
/// neighbour sat on a step, gets a second try from zero).
pub fn solve_column(fit: &Fit, res: usize, l: usize, x: usize, y: usize) -> Vec<[f64; 3]> {
    let zs = z_nodes(res);
    let solve_at = |zi: usize, start: [f64; 3]| {
        let z = zs[zi];
        let mut rgb = [0.0; 3];
        rgb[l] = z;
        rgb[(l + 1) % 3] = x as f64 / (res - 1) as f64 * z;
        rgb[(l + 2) % 3] = y as f64 / (res - 1) as f64 * z;
        let (c, err) = fit.solve(rgb, start);
        if err > 1e-6 {
            let (c0, err0) = fit.solve(rgb, [0.0; 3]);
            if err0 < err {
                return c0;
            }
        }
        c
    };
    let mut column = vec![[0.0; 3]; res];
    let first = res / 5;
    let mut c = [0.0; 3];
    for (zi, node) in column.iter_mut().enumerate().skip(first) {
        c = solve_at(zi, c);
        *node = c;
    }
    c = column[first];
    for (zi, node) in column.iter_mut().enumerate().take(first).rev() {
        c = solve_at(zi, c);
        *node = c;
    }
    column
}

/// The table: for each largest channel l, node z (the largest component), y and x (the next two channels over the
/// largest, in (res − 1) steps), the three coefficients; f32, index ((((l·res + z)·res + y)·res + x)·3 + c). It is
/// made once (`cargo run --release --example rgb2spec`, about 7 s on two cores) and kept in data/; tests/spectrum.rs
/// checks columns of the kept table against solve_column.
pub fn build_table(fit: &Fit, res: usize) -> Vec<f32> {
    let columns = 3 * res * res;
    let mut table = vec![0.0f32; columns * res * 3];
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    let solved: Vec<Vec<(usize, Vec<[f64; 3]>)>> = std::thread::scope(|scope| {
        let handles: Vec<_> = (0..threads)
            .map(|t| {
                scope.spawn(move || {
                    (t..columns)
                        .step_by(threads)
                        .map(|col| {
                            (
                                col,
                                solve_column(fit, res, col / (res * res), col % res, (col / res) % res),
                            )
                        })
                        .collect()
                })
            })
            .collect();
        handles.into_iter().map(|h| h.join().expect("a table thread")).collect()
    });
    for (col, column) in solved.into_iter().flatten() {
        let (l, y, x) = (col / (res * res), (col / res) % res, col % res);
        for (z, c) in column.iter().enumerate() {
            let i = (((l * res + z) * res + y) * res + x) * 3;
            for k in 0..3 {
                table[i + k] = c[k] as f32;
            }
        }
    }
    continue_grey_nodes(&mut table, res);
    table
}

/// The grey node of each slice (x = y = res − 1) is never read alone: an exact grey takes the constant spectrum
/// (spectrum::Tables::coefficients). It only steers the interpolation of colours next to it, and its own fit, the
/// constant, sits at the clamp far from its neighbours' bumps (0.031 off at (1, 0.97, 1)). Continued from the
/// diagonal instead, the worst round trip falls to 0.019.
pub fn continue_grey_nodes(table: &mut [f32], res: usize) {
    for l in 0..3 {
        for z in 0..res {
            let node = |d: usize| (((l * res + z) * res + d) * res + d) * 3;
            let (grey, a, b) = (node(res - 1), node(res - 2), node(res - 3));
            for k in 0..3 {
                table[grey + k] = 2.0 * table[a + k] - table[b + k];
            }
        }
    }
}
