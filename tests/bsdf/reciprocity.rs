//! The one reciprocity check, f(wo, wi) = f(wi, wo) at reflected samples, and which materials the model holds to it.
use crate::close;
use glam::Vec3;
use pathwave::render::BsdfProbe;
use pathwave::scene::Material;

/// Every lobe is reciprocal by itself, so a material is unless a clear coat or sheen lies over a base that reflects:
/// the layering scales the base by the layers' albedo at wo only. A layer over black is that layer alone.
pub(crate) fn expected(m: &Material) -> bool {
    let layered = m.clearcoat.factor > 0.0 || m.sheen.color != Vec3::ZERO;
    let over_black = m.base_color == Vec3::ZERO && m.specular == 0.0 && m.metallic == 0.0;
    !layered || over_black
}

/// f is symmetric in wo and wi for a sample that reflects; through the surface it need not be (refraction scales
/// radiance by the squared relative IOR one way and not the other).
pub(crate) fn assert_reciprocal(what: &str, s: &BsdfProbe) {
    if s.wi.z > 0.0 {
        for c in 0..3 {
            assert!(
                close(s.eval[c], s.eval_reverse[c]),
                "{what}: f(wo, wi) {} != f(wi, wo) {}",
                s.eval,
                s.eval_reverse
            );
        }
    }
}
