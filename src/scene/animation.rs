//! glTF animation: keyframe samplers (STEP, LINEAR with slerp for rotations, CUBICSPLINE) and the channels that
//! drive node translations, rotations, scales and morph-target weights, and what KHR_animation_pointer points to.
use glam::{Quat, Vec3};

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Interpolation {
    Step,
    Linear,
    /// Hermite splines: every key holds an in-tangent, a value and an out-tangent, in that order.
    CubicSpline,
}

/// What a channel drives on its node.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Property {
    Translation,
    Rotation,
    Scale,
    /// One weight per morph target of the node's mesh.
    Weights,
}

/// Keyframes: strictly increasing, finite times and `width` floats per element, one element per key (three, the
/// in-tangent, value and out-tangent, under CUBICSPLINE). Checked when loaded, so sampling cannot fail.
#[derive(Clone, Debug, PartialEq)]
pub struct Sampler {
    pub interpolation: Interpolation,
    pub times: Vec<f32>,
    pub values: Vec<f32>,
    pub width: usize,
}

impl Sampler {
    /// Element `e` of key `k` (e = 1 is the value under CUBICSPLINE, 0 and 2 its tangents; otherwise e = 0).
    fn element(&self, k: usize, e: usize) -> &[f32] {
        let per_key = if self.interpolation == Interpolation::CubicSpline {
            3
        } else {
            1
        };
        let at = (k * per_key + e) * self.width;
        &self.values[at..at + self.width]
    }

    fn value(&self, k: usize) -> &[f32] {
        let e = if self.interpolation == Interpolation::CubicSpline {
            1
        } else {
            0
        };
        self.element(k, e)
    }

    /// The channel's value at time `t` into `out` (`width` floats). Before the first key and after the last the
    /// end values hold. `rotation` makes LINEAR a spherical interpolation along the shorter arc, and normalises
    /// the CUBICSPLINE result, as glTF requires of quaternions.
    pub fn sample(&self, t: f32, rotation: bool, out: &mut [f32]) {
        let n = self.times.len();
        let last = n - 1;
        // NaN takes the first key.
        if t.is_nan() || t <= self.times[0] || n == 1 {
            out.copy_from_slice(self.value(0));
            return;
        }
        if t >= self.times[last] {
            out.copy_from_slice(self.value(last));
            return;
        }
        // The key at or before t: times[k] <= t < times[k + 1].
        let k = self.times.partition_point(|&key| key <= t) - 1;
        let dt = self.times[k + 1] - self.times[k];
        let u = (t - self.times[k]) / dt;
        match self.interpolation {
            Interpolation::Step => out.copy_from_slice(self.value(k)),
            Interpolation::Linear if rotation => {
                let q = slerp(quat(self.value(k)), quat(self.value(k + 1)), u);
                out.copy_from_slice(&q.to_array());
            }
            Interpolation::Linear => {
                let (a, b) = (self.value(k), self.value(k + 1));
                for (o, (a, b)) in out.iter_mut().zip(a.iter().zip(b)) {
                    *o = a + (b - a) * u;
                }
            }
            Interpolation::CubicSpline => {
                let (u2, u3) = (u * u, u * u * u);
                let h00 = 2.0 * u3 - 3.0 * u2 + 1.0;
                let h10 = u3 - 2.0 * u2 + u;
                let h01 = -2.0 * u3 + 3.0 * u2;
                let h11 = u3 - u2;
                let (v0, b0) = (self.element(k, 1), self.element(k, 2));
                let (v1, a1) = (self.element(k + 1, 1), self.element(k + 1, 0));
                for (i, o) in out.iter_mut().enumerate() {
                    // The tangents are per second: scaled by the segment's length in time.
                    *o = h00 * v0[i] + h10 * dt * b0[i] + h01 * v1[i] + h11 * dt * a1[i];
                }
                if rotation {
                    let q = quat(out).normalize();
                    out.copy_from_slice(&q.to_array());
                }
            }
        }
    }
}

fn quat(v: &[f32]) -> Quat {
    Quat::from_xyzw(v[0], v[1], v[2], v[3])
}

/// Spherical interpolation from `a` to `b` along the shorter arc: q and -q are the same rotation, and keys that
/// flip sign between them must not turn the long way round.
pub fn slerp(a: Quat, b: Quat, u: f32) -> Quat {
    let (a, mut b) = (a.normalize(), b.normalize());
    let mut cos = a.dot(b);
    if cos < 0.0 {
        b = -b;
        cos = -cos;
    }
    // Nearly equal keys: the sine below vanishes, and a normalised lerp is exact to float precision.
    if cos > 0.9995 {
        return (a + (b - a) * u).normalize();
    }
    let theta = cos.acos();
    let s = theta.sin();
    (a * (((1.0 - u) * theta).sin() / s) + b * ((u * theta).sin() / s)).normalize()
}

/// One channel: a sampler driving one property of a node (an index into `Rig::nodes`), a material, a light or a
/// camera (KHR_animation_pointer).
#[derive(Clone, Debug, PartialEq)]
pub struct Channel {
    pub target: super::pointer::Target,
    pub sampler: Sampler,
}

#[derive(Clone, Debug, Default, PartialEq)]
pub struct Animation {
    pub name: String,
    pub channels: Vec<Channel>,
}

impl Animation {
    /// The first and last key time over every channel ((0, 0) without channels).
    pub fn range(&self) -> (f32, f32) {
        let mut range: Option<(f32, f32)> = None;
        for c in &self.channels {
            let (a, b) = (c.sampler.times[0], c.sampler.times[c.sampler.times.len() - 1]);
            range = Some(range.map_or((a, b), |(lo, hi)| (lo.min(a), hi.max(b))));
        }
        range.unwrap_or((0.0, 0.0))
    }
}

/// A node's translation, rotation and scale, which channels replace one by one.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Trs {
    pub translation: Vec3,
    pub rotation: Quat,
    pub scale: Vec3,
}

impl Trs {
    pub fn matrix(&self) -> glam::Mat4 {
        glam::Mat4::from_scale_rotation_translation(self.scale, self.rotation, self.translation)
    }

    /// Sets `property` from a sampled value (Weights are not a transform and leave it as it is).
    pub fn set(&mut self, property: Property, v: &[f32]) {
        match property {
            Property::Translation => self.translation = Vec3::from_slice(v),
            Property::Rotation => self.rotation = quat(v).normalize(),
            Property::Scale => self.scale = Vec3::from_slice(v),
            Property::Weights => {}
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sampler(interpolation: Interpolation, times: &[f32], values: &[f32], width: usize) -> Sampler {
        Sampler {
            interpolation,
            times: times.to_vec(),
            values: values.to_vec(),
            width,
        }
    }

    fn at(s: &Sampler, t: f32, rotation: bool) -> Vec<f32> {
        let mut out = vec![0.0; s.width];
        s.sample(t, rotation, &mut out);
        out
    }

    fn close(a: &[f32], b: &[f32]) -> bool {
        a.iter().zip(b).all(|(a, b)| (a - b).abs() < 1e-6)
    }

    #[test]
    fn step_holds_each_key_until_the_next_and_clamps_outside() {
        let s = sampler(Interpolation::Step, &[1.0, 2.0, 4.0], &[10.0, 20.0, 40.0], 1);
        for (t, want) in [
            (0.0, 10.0),
            (1.0, 10.0),
            (1.99, 10.0),
            (2.0, 20.0),
            (3.9, 20.0),
            (4.0, 40.0),
            (9.0, 40.0),
        ] {
            assert_eq!(at(&s, t, false), [want], "t = {t}");
        }
        assert_eq!(at(&s, f32::NAN, false), [10.0]);
    }

    #[test]
    fn linear_interpolates_componentwise_between_keys() {
        let s = sampler(
            Interpolation::Linear,
            &[0.0, 2.0],
            &[0.0, 10.0, -4.0, 4.0, 20.0, 0.0],
            3,
        );
        assert_eq!(at(&s, 0.0, false), [0.0, 10.0, -4.0]);
        assert!(close(&at(&s, 0.5, false), &[1.0, 12.5, -3.0]));
        assert!(close(&at(&s, 1.5, false), &[3.0, 17.5, -1.0]));
        assert_eq!(at(&s, 2.0, false), [4.0, 20.0, 0.0]);
        assert_eq!(at(&s, -1.0, false), [0.0, 10.0, -4.0]);
    }

    #[test]
    fn linear_rotations_slerp_at_constant_angular_speed() {
        // 0 to 90 degrees about z: a lerp would give 45 degrees at u = 0.5 too, so check u = 0.25, where a
        // normalised lerp gives 26.57 degrees and a slerp 22.5.
        let b = Quat::from_rotation_z(std::f32::consts::FRAC_PI_2);
        let s = sampler(
            Interpolation::Linear,
            &[0.0, 1.0],
            &[0.0, 0.0, 0.0, 1.0, b.x, b.y, b.z, b.w],
            4,
        );
        let q = quat(&at(&s, 0.25, true));
        assert!(
            q.angle_between(Quat::from_rotation_z(22.5f32.to_radians())) < 1e-5,
            "{q}"
        );
    }

    #[test]
    fn rotations_take_the_shorter_arc_when_keys_flip_sign() {
        // -q90 is the same rotation as q90; from identity to it the path must still pass through 45 degrees,
        // not through 225 (which it would if the sign were kept).
        let b = -Quat::from_rotation_z(std::f32::consts::FRAC_PI_2);
        let s = sampler(
            Interpolation::Linear,
            &[0.0, 1.0],
            &[0.0, 0.0, 0.0, 1.0, b.x, b.y, b.z, b.w],
            4,
        );
        let q = quat(&at(&s, 0.5, true));
        assert!(q.angle_between(Quat::from_rotation_z(45f32.to_radians())) < 1e-5, "{q}");
    }

    #[test]
    fn cubic_spline_follows_hermite_basis_with_tangents_scaled_by_the_segment() {
        // Keys at t = 1 and 3 (dt = 2): value 0 with out-tangent 1, value 4 with in-tangent -1.
        // p(u) = h00*0 + h10*2*1 + h01*4 + h11*2*(-1); at u = 0.5: h10 = 0.125, h01 = 0.5, h11 = -0.125 gives
        // 0.25 + 2 + 0.25 = 2.5. At u = 0.25: h10 = 0.140625, h01 = 0.15625, h11 = -0.046875 gives
        // 0.28125 + 0.625 + 0.09375 = 1.0.
        let s = sampler(
            Interpolation::CubicSpline,
            &[1.0, 3.0],
            &[9.0, 0.0, 1.0, /* key 1: */ -1.0, 4.0, 9.0],
            1,
        );
        assert!(close(&at(&s, 2.0, false), &[2.5]));
        assert!(close(&at(&s, 1.5, false), &[1.0]));
        // At the keys the value, not a tangent; outside them the end values.
        assert_eq!(at(&s, 1.0, false), [0.0]);
        assert_eq!(at(&s, 3.0, false), [4.0]);
        assert_eq!(at(&s, 0.0, false), [0.0]);
        assert_eq!(at(&s, 5.0, false), [4.0]);
    }

    #[test]
    fn cubic_spline_rotations_come_out_normalised() {
        let b = Quat::from_rotation_x(1.0);
        let zero = [0.0; 4];
        let mut values = zero.to_vec();
        values.extend([0.0, 0.0, 0.0, 1.0]);
        values.extend(zero);
        values.extend(zero);
        values.extend(b.to_array());
        values.extend(zero);
        let s = sampler(Interpolation::CubicSpline, &[0.0, 1.0], &values, 4);
        let q = quat(&at(&s, 0.5, true));
        assert!((q.length() - 1.0).abs() < 1e-6);
        // Zero tangents and a symmetric basis: halfway in value is halfway in angle for this small arc.
        assert!(q.angle_between(Quat::from_rotation_x(0.5)) < 1e-3, "{q}");
    }

    #[test]
    fn a_single_key_holds_for_ever() {
        let s = sampler(Interpolation::Linear, &[2.0], &[7.0], 1);
        for t in [-1.0, 2.0, 10.0] {
            assert_eq!(at(&s, t, false), [7.0]);
        }
    }
}
