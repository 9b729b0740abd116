//! The one consistency check: every sample the device draws agrees with its eval and pdf, over a sweep of cases.
use crate::{close, reciprocity, renderer_with, sample_side, transmits, wo_around, Case};
use pathwave::render::BsdfProbe;
use pathwave::scene::Material;

/// Samples of every case at every direction, each held to `assert_sample_agrees` and, where `reciprocity::expected`
/// says the material must be, to reciprocity. An opaque material must only reflect, and one that transmits must
/// send some sample through over its sweep (else its far side went untested).
pub(crate) struct Agree<'a> {
    directions: &'a [(f32, f32)],
    samples: usize,
    seed: u64,
    both_sides: bool,
}

impl<'a> Agree<'a> {
    /// `samples` draws at each of `directions` (wo's degrees from the normal, azimuth in degrees) from each case's own
    /// side, case i from seed `seed + i` (the same uniforms at every direction).
    pub(crate) fn new(directions: &'a [(f32, f32)], samples: usize, seed: u64) -> Self {
        Agree {
            directions,
            samples,
            seed,
            both_sides: false,
        }
    }

    /// From inside every case as well (its IOR inverted).
    pub(crate) fn both_sides(self) -> Self {
        Agree {
            both_sides: true,
            ..self
        }
    }

    pub(crate) fn run(&self, cases: &[Case]) {
        self.run_with(cases, |_, _, _| {});
    }

    /// `run`, handing every batch of samples (its case, whether wo is outside, the samples) to `also` as well.
    pub(crate) fn run_with(&self, cases: &[Case], mut also: impl FnMut(&Case, bool, &[BsdfProbe])) {
        let mut r = renderer_with(cases.iter().map(|c| c.material.clone()).collect());
        for (mi, case) in cases.iter().enumerate() {
            let m = &case.material;
            let reciprocal = reciprocity::expected(m);
            let sides: &[bool] = if self.both_sides {
                &[true, false]
            } else {
                std::slice::from_ref(&case.front)
            };
            let mut through = 0usize;
            for &(deg, azimuth) in self.directions {
                let wo = wo_around(deg, azimuth);
                for &front in sides {
                    let batch = format!("{} front {front} wo {wo}", case.name);
                    let samples = sample_side(&mut r, mi as u32, wo, front, self.samples, self.seed + mi as u64, true);
                    for s in samples.iter().filter(|s| s.ok) {
                        let what = format!("{batch} wi {}", s.wi);
                        through += usize::from(s.wi.z < 0.0);
                        assert!(
                            transmits(m) || s.wi.z > 0.0,
                            "{what}: an opaque material must reflect: {s:?}"
                        );
                        // A delta sample has no density to agree with.
                        if s.delta {
                            assert!(smooth(m), "{what}: a delta sample from a rough material: {s:?}");
                            continue;
                        }
                        assert_sample_agrees(&what, s);
                        if reciprocal {
                            reciprocity::assert_reciprocal(&what, s);
                        }
                    }
                    also(case, front, &samples);
                }
            }
            assert!(!transmits(m) || through > 0, "{}: nothing went through", case.name);
        }
    }
}

/// Only a lobe of roughness 0 (the base's or the clear coat's) is a delta, so only such a material may sample one.
fn smooth(m: &Material) -> bool {
    m.roughness == 0.0 || (m.clearcoat.factor > 0.0 && m.clearcoat.roughness == 0.0)
}

/// One non-delta sample agrees with eval and pdf: finite, non-negative, its pdf is pdf(wi), its weight is
/// f |cos| / pdf.
fn assert_sample_agrees(what: &str, s: &BsdfProbe) {
    assert!(
        s.wi.is_finite() && s.weight.is_finite() && s.pdf.is_finite(),
        "{what}: non-finite sample {s:?}"
    );
    assert!(s.weight.min_element() >= 0.0, "{what}: negative weight {}", s.weight);
    assert!(
        close(s.pdf, s.pdf_wi),
        "{what}: sample pdf {} but pdf() says {}",
        s.pdf,
        s.pdf_wi
    );
    let expect = s.eval * s.wi.z.abs() / s.pdf;
    for c in 0..3 {
        assert!(
            close(s.weight[c], expect[c]),
            "{what}: weight {} but eval |cos| / pdf = {expect}",
            s.weight
        );
    }
}
