//! LightBounds: what importance knows of an emitter or a group (box, power, normal cone), and its cone maths.
use crate::bvh::motion::{largest_turn, Pose};
use glam::{Mat3, Vec3};
use std::f32::consts::PI;

/// What importance needs to know of an emitter or a group of them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightBounds {
    pub lo: Vec3,
    pub hi: Vec3,
    /// Power (W), the same estimate the power table uses.
    pub phi: f32,
    /// Every emitting normal is within acos(cos_o) of `axis`.
    pub axis: Vec3,
    pub cos_o: f32,
    /// Emission reaches at most acos(cos_e) beyond the normal (pi/2 for a surface).
    pub cos_e: f32,
    /// Emits from both faces: the cone holds for -axis too.
    pub two_sided: bool,
}

/// Angles a float error can move a cone by; the union widens by it so it stays a bound.
pub(super) const CONE_SLACK: f32 = 1e-4;

impl LightBounds {
    /// A triangle (at one or more places over the shutter) emitting from its counter-clockwise face, or both.
    pub fn triangle(keys: &[[Vec3; 3]], phi: f32, two_sided: bool) -> Option<LightBounds> {
        let mut b: Option<LightBounds> = None;
        for &[a, v1, v2] in keys {
            let n = (v1 - a).cross(v2 - a);
            let n = if n.length_squared() > 0.0 {
                n.normalize()
            } else {
                Vec3::Z
            };
            let cone = LightBounds {
                lo: a.min(v1).min(v2),
                hi: a.max(v1).max(v2),
                phi,
                axis: n,
                cos_o: 1.0,
                cos_e: 0.0,
                two_sided,
            };
            b = Some(match b {
                None => cone,
                Some(prev) => LightBounds {
                    phi,
                    ..prev.union(&cone)
                },
            });
        }
        b
    }

    /// A point light: all directions.
    pub fn point(p: Vec3, phi: f32) -> LightBounds {
        LightBounds {
            lo: p,
            hi: p,
            phi,
            axis: Vec3::Z,
            cos_o: -1.0,
            cos_e: 0.0,
            two_sided: false,
        }
    }

    /// A spot light: full intensity within `inner` of `dir`, none beyond `outer`.
    pub fn spot(p: Vec3, dir: Vec3, inner: f32, outer: f32, phi: f32) -> LightBounds {
        let inner = inner.clamp(0.0, outer.max(0.0));
        LightBounds {
            lo: p,
            hi: p,
            phi,
            axis: dir.normalize_or(Vec3::Z),
            cos_o: inner.cos(),
            cos_e: (outer - inner).min(PI).cos(),
            two_sided: false,
        }
    }

    /// These bounds under an affine map (an instance's transform at each of its keys): the box's corners mapped,
    /// the cone's axis mapped as a normal. A map that is not a similarity does not keep angles, so the cone then
    /// opens to the sphere. Keys interpolated as `poses` (motion::Pose::toward) sweep the box along its arc
    /// (motion::swept_box), and a direction between two keys is within half their turn of one of them, so each
    /// key's cone opens by half the largest turn; keys interpolated as matrices move points linearly between keys.
    pub fn transformed(&self, keys: &[glam::Mat4], poses: Option<&[Pose]>, phi: f32) -> LightBounds {
        let mut out: Option<LightBounds> = None;
        for w in keys {
            let mut lo = Vec3::splat(f32::INFINITY);
            let mut hi = Vec3::splat(f32::NEG_INFINITY);
            for c in crate::scene::box_corners(self.lo, self.hi) {
                let q = w.transform_point3(c);
                lo = lo.min(q);
                hi = hi.max(q);
            }
            let m = Mat3::from_mat4(*w);
            let normal = m.inverse().transpose() * self.axis;
            let cos_o = if is_similarity(&m) && normal.length_squared() > 0.0 {
                self.cos_o
            } else {
                -1.0
            };
            let b = LightBounds {
                lo,
                hi,
                phi,
                axis: normal.normalize_or(Vec3::Z),
                cos_o,
                cos_e: self.cos_e,
                two_sided: self.two_sided,
            };
            out = Some(match out {
                None => b,
                Some(prev) => LightBounds { phi, ..prev.union(&b) },
            });
        }
        let (Some(mut out), Some(poses)) = (out, poses) else {
            return out.unwrap_or(*self);
        };
        (out.lo, out.hi) = crate::bvh::motion::swept_box(self.lo, self.hi, poses);
        if out.cos_o > -1.0 {
            out.cos_o = (out.cos_o.clamp(-1.0, 1.0).acos() + 0.5 * largest_turn(poses))
                .min(PI)
                .cos();
        }
        out
    }

    /// Both groups: the box around both, the powers added, a cone holding both cones.
    pub fn union(&self, b: &LightBounds) -> LightBounds {
        let (axis, cos_o) = cone_union(self.axis, self.cos_o, b.axis, b.cos_o);
        LightBounds {
            lo: self.lo.min(b.lo),
            hi: self.hi.max(b.hi),
            phi: self.phi + b.phi,
            axis,
            cos_o,
            cos_e: self.cos_e.min(b.cos_e),
            two_sided: self.two_sided || b.two_sided,
        }
    }

    pub(super) fn centroid(&self) -> Vec3 {
        0.5 * (self.lo + self.hi)
    }

    /// The build's measure of how much space and how many directions the group lights (pbrt-v4's M_Omega times the
    /// box's area), so that splits keep emitters of one place and one facing together.
    pub(super) fn cost(&self) -> f32 {
        // One inverse cosine: a surface's theta_e is pi/2, and theta_o's sine and cosine follow from cos_o.
        let cos_o = self.cos_o.clamp(-1.0, 1.0);
        let theta_o = cos_o.acos();
        let theta_e = if self.cos_e == 0.0 {
            PI / 2.0
        } else {
            self.cos_e.clamp(-1.0, 1.0).acos()
        };
        let theta_w = (theta_o + theta_e).min(PI);
        let sin_o = (1.0 - cos_o * cos_o).max(0.0).sqrt();
        let m_omega = 2.0 * PI * (1.0 - cos_o)
            + PI / 2.0 * (2.0 * theta_w * sin_o - (theta_o - 2.0 * theta_w).cos() - 2.0 * theta_o * sin_o + cos_o);
        let d = (self.hi - self.lo).max(Vec3::ZERO);
        // A flat or point-like group still has some extent, so groups of point lights are still told apart.
        let area = 2.0 * (d.x * d.y + d.y * d.z + d.z * d.x) + 1e-12 * (d.x + d.y + d.z);
        self.phi * m_omega * area
    }
}

/// Whether m keeps angles: its columns orthogonal and of one length.
fn is_similarity(m: &Mat3) -> bool {
    let g = m.transpose() * *m;
    let s = (g.x_axis.x + g.y_axis.y + g.z_axis.z) / 3.0;
    if s.is_nan() || s <= 0.0 || !s.is_finite() {
        return false;
    }
    let off = (g - Mat3::from_diagonal(Vec3::splat(s))).to_cols_array();
    off.iter().all(|v| v.abs() <= 1e-4 * s)
}

/// The smallest cone (axis, cos of its half angle) that holds cones a and b, widened by CONE_SLACK.
pub(super) fn cone_union(a: Vec3, cos_a: f32, b: Vec3, cos_b: f32) -> (Vec3, f32) {
    // One cone inside the other, tested without inverse cosines (the build's common case): b lies within a when
    // the angle between the axes is at most theta_a - theta_b, whose cosine the sines and cosines give.
    let d = a.dot(b);
    // One of them a single direction (an emitter's normal: every union of the build's binning): no roots needed.
    if cos_b >= 1.0 && d >= cos_a {
        return (a, cos_a);
    }
    if cos_a >= 1.0 && d >= cos_b {
        return (b, cos_b);
    }
    let (sin_a, sin_b) = (
        (1.0 - cos_a * cos_a).max(0.0).sqrt(),
        (1.0 - cos_b * cos_b).max(0.0).sqrt(),
    );
    if cos_a <= -1.0 || (cos_a <= cos_b && d >= cos_a * cos_b + sin_a * sin_b) {
        return (a, cos_a);
    }
    if cos_b <= -1.0 || (cos_b <= cos_a && d >= cos_a * cos_b + sin_a * sin_b) {
        return (b, cos_b);
    }
    // A single direction's angle is 0 without an inverse cosine (both cones are one, often).
    let angle = |c: f32| if c >= 1.0 { 0.0 } else { c.clamp(-1.0, 1.0).acos() };
    let (theta_a, theta_b, theta_d) = (angle(cos_a), angle(cos_b), angle(d));
    if (theta_d + theta_b).min(PI) <= theta_a {
        return (a, cos_a);
    }
    if (theta_d + theta_a).min(PI) <= theta_b {
        return (b, cos_b);
    }
    let theta_o = 0.5 * (theta_a + theta_d + theta_b) + CONE_SLACK;
    if theta_o >= PI {
        return (a, -1.0);
    }
    // Turn a towards b by the angle that puts both edges inside.
    let theta_r = theta_o - theta_a;
    let w = a.cross(b);
    if w.length_squared() < 1e-12 {
        // Axes too close to turn between (neighbouring triangles of a curved mesh): a's axis, opened to reach b's
        // edge. Opening it to the sphere here once lost half of a light bulb's picks: such a node has importance
        // where its two faces turned away have none, and a descent that reaches it picks nothing.
        let theta = theta_a.max(theta_d + theta_b) + CONE_SLACK;
        return (a, if theta >= PI { -1.0 } else { theta.cos() });
    }
    let axis = glam::Quat::from_axis_angle(w.normalize(), theta_r) * a;
    (axis.normalize(), theta_o.cos())
}
