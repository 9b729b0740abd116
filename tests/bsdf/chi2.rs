//! The one chi-square test: sampled directions binned on grids about their lobes against the device pdf over each cell.
use crate::common::stats::{chi2_p_value, chi2_statistic};
use crate::{renderer_with, sample_side, transmits, wo_around, Case};
use glam::Vec3;
use pathwave::render::BsdfQuery;
use pathwave::scene::Material;
use pathwave::Renderer;

/// wo at 10, 45 and 75 degrees from the normal, each met at its own azimuth (0, 60, 130 degrees about it).
pub(crate) const TURNED: [(f32, f32); 3] = [(10.0, 0.0), (45.0, 60.0), (75.0, 130.0)];

/// Cells expected to hold fewer samples are pooled into one (the Mitsuba 3 convention): Pearson's statistic is not
/// chi-square distributed over nearly empty cells.
const MIN_EXPECTED: f64 = 5.0;

/// How a sweep bins its samples, on grids of 48 x 96 cells in (s, phi) (theta = pi s^3 from the grid's axis).
pub(crate) enum Cells {
    /// One grid about the mirror direction over the whole sphere: every sample, and all of the pdf's mass, in it.
    Sphere,
    /// A grid per hemisphere, `fine` times as dense in each dimension, each centred on its lobe so a sharp transmitted
    /// lobe is resolved like a reflected one: the mirror direction above; below, the refracted axis for glass, the far
    /// side's normal otherwise (for an opaque material every cell below expects nothing, so samples there count).
    Hemispheres { fine: usize },
}

/// Chi-square of sampled directions against the integrated pdf for every case at every direction, Sidak-corrected at
/// 1 % over the sweep; the pdf's mass is checked against the samples that leave no direction.
pub(crate) struct Chi2<'a> {
    directions: &'a [(f32, f32)],
    samples: usize,
    seed: (u64, u64),
    cells: Cells,
}

impl<'a> Chi2<'a> {
    /// `samples` draws at each of `directions` (wo's degrees from the normal, azimuth in degrees) for every case, case
    /// i at d degrees from seed `seed.0 + i seed.1 + d`, binned as `cells` says.
    pub(crate) fn new(directions: &'a [(f32, f32)], samples: usize, seed: (u64, u64), cells: Cells) -> Self {
        Chi2 {
            directions,
            samples,
            seed,
            cells,
        }
    }

    pub(crate) fn run(&self, cases: &[Case]) {
        let mut r = renderer_with(cases.iter().map(|c| c.material.clone()).collect());
        let tests = cases.len() * self.directions.len();
        // Significance 1 % over the whole family of tests (Sidak correction), as Mitsuba's chi2 tests do.
        let threshold = 1.0 - 0.99f64.powf(1.0 / tests as f64);
        let n = self.samples;
        let mut failures = Vec::new();
        for (mi, case) in cases.iter().enumerate() {
            let (material, m, front) = (mi as u32, &case.material, case.front);
            for &(deg, azimuth) in self.directions {
                let wo = wo_around(deg, azimuth);
                let what = format!("{} at {deg} deg, azimuth {azimuth}", case.name);
                let mirror = Vec3::new(-wo.x, -wo.y, wo.z);
                let (upper, lower) = match self.cells {
                    Cells::Sphere => (Grid::around(mirror, 1), None),
                    Cells::Hemispheres { fine } => (
                        Grid::around(mirror, fine),
                        Some(Grid::around(below_axis(m, wo, front), fine)),
                    ),
                };
                let cells = upper.s_bins * upper.phi_bins;
                let seed = self.seed.0 + mi as u64 * self.seed.1 + deg as u64;
                let samples = sample_side(&mut r, material, wo, front, n, seed, true);
                // Samples that leave no direction (reflected below the horizon) are the pdf's missing mass; they are
                // checked against it below rather than binned, as quadrature error dwarfs that mass for sharp lobes.
                let mut observed = vec![0f64; if lower.is_some() { 2 * cells } else { cells }];
                let mut failed = 0usize;
                for s in &samples {
                    // A delta lobe has no density to bin against: every material swept here is rough.
                    assert!(!s.delta, "{what}: a delta sample {s:?}");
                    match (s.ok, s.wi.z > 0.0, &lower) {
                        (false, _, _) => failed += 1,
                        (true, false, Some(lower)) => observed[cells + lower.cell(s.wi)] += 1.0,
                        (true, _, _) => observed[upper.cell(s.wi)] += 1.0,
                    }
                }
                let expected = match &lower {
                    None => cell_masses(&mut r, &upper, material, wo, front, |_| true),
                    Some(lower) => {
                        // Each grid covers only its own hemisphere.
                        let mut e = cell_masses(&mut r, &upper, material, wo, front, |w| w.z > 0.0);
                        if transmits(m) {
                            e.extend(cell_masses(&mut r, lower, material, wo, front, |w| w.z <= 0.0));
                        } else {
                            e.resize(2 * cells, 0.0);
                        }
                        e
                    }
                };
                let mass: f64 = expected.iter().sum();
                let expected: Vec<f64> = expected.iter().map(|e| e * n as f64).collect();
                if std::env::var_os("BSDF_DEBUG").is_some() {
                    print_worst(&observed, &expected, cells, upper.phi_bins);
                }
                // The transmitted pdf has an integrable singularity where refraction turns grazing (its Jacobian's
                // denominator (wi.m + wo.m / eta)^2 vanishes), so quadrature converges slowly there: for roughness 1,
                // IOR 1.33 at 80 degrees, horizon-aligned grids of 1024^2 and 2048^2 gave 0.9799 and 0.9852 against
                // 0.9833 actually sampled. Hence 1 % for glass, against 0.2-0.3 % for reflection.
                let tolerance = if m.transmission > 0.0 { 1e-2 } else { 2e-3 };
                assert_mass_matches(&what, mass, failed as f64 / n as f64, tolerance);
                let (stat, dof) = chi2_statistic(&observed, &expected, MIN_EXPECTED);
                let p = chi2_p_value(stat, dof);
                let below = samples.iter().filter(|s| s.ok && s.wi.z < 0.0).count();
                eprintln!(
                    "{what}: chi2 {stat:8.1} dof {dof:4} p {p:.4} (mass {mass:.4}, {failed} failed, {below} below)"
                );
                if p < threshold {
                    failures.push(format!("{what}: p = {p:.2e}"));
                }
            }
        }
        assert!(
            failures.is_empty(),
            "chi-square rejects (threshold {threshold:.2e}): {failures:#?}"
        );
    }
}

/// With BSDF_DEBUG set, the cells that add most to the statistic (grid 1 is the lower hemisphere's).
fn print_worst(observed: &[f64], expected: &[f64], cells: usize, phi_bins: usize) {
    let mut worst: Vec<(f64, usize)> = (0..observed.len())
        .map(|c| ((observed[c] - expected[c]).powi(2) / expected[c].max(1e-9), c))
        .collect();
    worst.sort_by(|a, b| b.0.total_cmp(&a.0));
    for &(x, c) in worst.iter().take(8) {
        let (grid, s, phi, o, e) = (c / cells, c % cells / phi_bins, c % phi_bins, observed[c], expected[c]);
        eprintln!("  grid {grid} cell s={s} phi={phi}: observed {o} expected {e:.1} ({x:.0})");
    }
}

/// The centre of what `m` sends below the surface: for glass, where a smooth interface would refract wo (or, under
/// total internal reflection or through a thin sheet, the mirror image of the reflection); else the far side's normal.
fn below_axis(m: &Material, wo: Vec3, front: bool) -> Vec3 {
    if m.transmission <= 0.0 {
        return Vec3::NEG_Z;
    }
    let eta = if front { m.ior } else { 1.0 / m.ior };
    let (cos_i, sin2_i) = (wo.z, 1.0 - wo.z * wo.z);
    let sin2_t = sin2_i / (eta * eta);
    if m.thin_walled || sin2_t >= 1.0 {
        return Vec3::new(-wo.x, -wo.y, -wo.z);
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    -wo / eta + Vec3::Z * (cos_i / eta - cos_t)
}

/// The pdf integrates to at most 1, and samples that fail (leave no direction) are no more than the mass it misses,
/// both within the quadrature's `tolerance`.
fn assert_mass_matches(what: &str, mass: f64, failed_fraction: f64, tolerance: f64) {
    assert!(mass <= 1.0 + tolerance, "{what}: pdf integrates to {mass}");
    assert!(
        failed_fraction <= (1.0 - mass).max(0.0) + tolerance,
        "{what}: {failed_fraction} of samples failed but the pdf only misses {}",
        1.0 - mass
    );
}

/// Histogram cells in a frame around `axis`, dense near it (theta = pi s^3) so sharp lobes are resolved.
struct Grid {
    axis: Vec3,
    tx: Vec3,
    ty: Vec3,
    s_bins: usize,
    phi_bins: usize,
}

impl Grid {
    fn around(axis: Vec3, fine: usize) -> Self {
        let axis = axis.normalize();
        let tx = axis.any_orthonormal_vector();
        let ty = axis.cross(tx);
        Grid {
            axis,
            tx,
            ty,
            s_bins: 48 * fine,
            phi_bins: 96 * fine,
        }
    }

    fn cell(&self, w: Vec3) -> usize {
        // f64 and atan2: acos in f32 cannot tell apart angles below ~3e-4 rad, where sharp lobes live.
        let (w, axis, tx, ty) = (
            w.as_dvec3().normalize(),
            self.axis.as_dvec3(),
            self.tx.as_dvec3(),
            self.ty.as_dvec3(),
        );
        let theta = w.cross(axis).length().atan2(w.dot(axis));
        let phi = w.dot(ty).atan2(w.dot(tx)).rem_euclid(2.0 * std::f64::consts::PI);
        let s = (theta / std::f64::consts::PI).cbrt();
        let i = ((s * self.s_bins as f64) as usize).min(self.s_bins - 1);
        let j = ((phi / (2.0 * std::f64::consts::PI) * self.phi_bins as f64) as usize).min(self.phi_bins - 1);
        i * self.phi_bins + j
    }

    /// Gauss-Legendre nodes (4 per dimension per cell) with their solid-angle weights, for integrating the pdf over
    /// each cell: exact for polynomials of degree 7, so sharp but smooth lobes integrate accurately. A cell the
    /// horizon crosses is split 4 x 4 first: a pdf that does not fall to zero there (the sheen's uniform lobe) steps
    /// down to nothing, which 4 nodes integrate to within a fifth of the cell's mass (at 10 degrees, where the
    /// horizon runs along a ring of cells, that alone made a correct sampler fail, chi2 2418 on 2164).
    fn quadrature(&self) -> Vec<(usize, Vec3, f32)> {
        const NODES: [(f64, f64); 4] = [
            (-0.861_136_311_594_052_6, 0.347_854_845_137_453_9),
            (-0.339_981_043_584_856_3, 0.652_145_154_862_546_1),
            (0.339_981_043_584_856_3, 0.652_145_154_862_546_1),
            (0.861_136_311_594_052_6, 0.347_854_845_137_453_9),
        ];
        use std::f64::consts::PI as PI64;
        let (axis, tx, ty) = (self.axis.as_dvec3(), self.tx.as_dvec3(), self.ty.as_dvec3());
        let (ds, dphi) = (1.0 / self.s_bins as f64, 2.0 * PI64 / self.phi_bins as f64);
        // The direction at (s, phi) in [0, 1] x [0, 2 pi).
        let dir = |s: f64, phi: f64| {
            let theta = PI64 * s * s * s;
            theta.cos() * axis + theta.sin() * (phi.cos() * tx + phi.sin() * ty)
        };
        let mut out = Vec::new();
        for i in 0..self.s_bins {
            for j in 0..self.phi_bins {
                let corners = [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0), (0.5, 0.5)]
                    .map(|(a, b)| dir((i as f64 + a) * ds, (j as f64 + b) * dphi).z);
                let straddles = corners.iter().any(|&z| z < 0.0) && corners.iter().any(|&z| z > 0.0);
                let sub = if straddles { 4 } else { 1 };
                for a in 0..sub {
                    for (xs, ws) in NODES {
                        let s = (i as f64 + (a as f64 + 0.5 + 0.5 * xs) / sub as f64) * ds;
                        let theta = PI64 * s * s * s;
                        // d(omega) = sin(theta) d(theta) d(phi), d(theta) = 3 pi s^2 ds; each node covers half its
                        // weight of its (sub-)interval.
                        let w_s = theta.sin() * 3.0 * PI64 * s * s * ds / sub as f64 * 0.5 * ws;
                        for b in 0..sub {
                            for (xp, wp) in NODES {
                                let phi = (j as f64 + (b as f64 + 0.5 + 0.5 * xp) / sub as f64) * dphi;
                                let weight = w_s * dphi / sub as f64 * 0.5 * wp;
                                out.push((i * self.phi_bins + j, dir(s, phi).as_vec3(), weight as f32));
                            }
                        }
                    }
                }
            }
        }
        out
    }
}

/// The device pdf integrated over each of `grid`'s cells (Gauss-Legendre), counting only directions `keep` accepts.
fn cell_masses(
    r: &mut Renderer,
    grid: &Grid,
    material: u32,
    wo: Vec3,
    front: bool,
    keep: impl Fn(Vec3) -> bool,
) -> Vec<f64> {
    let quad = grid.quadrature();
    let queries: Vec<BsdfQuery> = quad
        .iter()
        .map(|(_, w, _)| BsdfQuery {
            material,
            wo,
            x: *w,
            front,
        })
        .collect();
    let pdfs = r.probe_bsdf(&queries, true, true).unwrap();
    let mut masses = vec![0f64; grid.s_bins * grid.phi_bins];
    for ((cell, w, weight), p) in quad.iter().zip(&pdfs) {
        if keep(*w) {
            masses[*cell] += (p.pdf * weight) as f64;
        }
    }
    masses
}
