//! Rigid motion over the shutter: an instance's transform at each key decomposed into translation, rotation and
//! scale and interpolated between keys as pbrt-v4 and Cycles do (translation and scale linearly, rotation by slerp,
//! exact for a rigid turn), and the boxes that hold what such an instance places along its whole arc.
use glam::{Mat3, Mat4, Quat, Vec3};

/// One key of an instance's transform: world = translate(translation) · rotate(rotation) · scale(scale); a mirroring
/// transform has a negative scale.x.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pose {
    pub translation: Vec3,
    pub rotation: Quat,
    pub scale: Vec3,
}

/// Largest error of a rebuilt key, relative to the matrix's largest entry, for the key to count as T·R·S. A matrix
/// with shear (a child under a parent scaled unevenly along a turned axis) misses by far more; then the instance
/// keeps the linear interpolation of its matrices, which does not shrink what does not turn.
const DECOMPOSE_TOLERANCE: f32 = 1e-4;

/// Above this cosine between two keys' rotations slerp's 1/sin(θ) loses precision; the normalised linear blend is
/// within f32 rounding of it there. layout.glsl's SLERP_LINEAR is the same number.
pub const SLERP_LINEAR: f32 = 0.9995;

/// Cuts of each segment between keys that swept_box places the box at.
const SWEEP_STEPS: u32 = 16;

impl Pose {
    /// `m` as translation, rotation and scale, or None if it is not one (shear, or not finite).
    pub fn decompose(m: &Mat4) -> Option<Pose> {
        let (scale, rotation, translation) = m.to_scale_rotation_translation();
        let pose = Pose {
            translation,
            rotation: rotation.normalize(),
            scale,
        };
        let back = pose.matrix();
        let size = (0..4).map(|c| m.col(c).abs().max_element()).fold(0.0f32, f32::max);
        let error = (0..4)
            .map(|c| (m.col(c) - back.col(c)).abs().max_element())
            .fold(0.0f32, f32::max);
        (pose.rotation.is_finite() && scale.is_finite() && error <= DECOMPOSE_TOLERANCE * size).then_some(pose)
    }

    pub fn matrix(&self) -> Mat4 {
        Mat4::from_scale_rotation_translation(self.scale, self.rotation, self.translation)
    }

    /// The pose a fraction `f` of the way to `b` (b's rotation on the same side as this one's, see decompose_keys).
    pub fn toward(&self, b: &Pose, f: f32) -> Pose {
        Pose {
            translation: self.translation.lerp(b.translation, f),
            rotation: slerp(self.rotation, b.rotation, f),
            scale: self.scale.lerp(b.scale, f),
        }
    }
}

/// Each key's pose, every rotation on the same side of the sphere as the one before it so that slerp between them
/// takes the shorter arc; None if any key does not decompose.
pub fn decompose_keys(keys: &[Mat4]) -> Option<Vec<Pose>> {
    let mut poses: Vec<Pose> = Vec::with_capacity(keys.len());
    for m in keys {
        let mut p = Pose::decompose(m)?;
        if poses.last().is_some_and(|prev| prev.rotation.dot(p.rotation) < 0.0) {
            p.rotation = -p.rotation;
        }
        poses.push(p);
    }
    Some(poses)
}

/// Spherical linear interpolation from `a` to `b` (their dot product not negative): a turn about one axis at a
/// constant rate, as layout.glsl's slerp.
pub fn slerp(a: Quat, b: Quat, f: f32) -> Quat {
    let c = a.dot(b).min(1.0);
    if c > SLERP_LINEAR {
        return (a * (1.0 - f) + b * f).normalize();
    }
    let theta = c.acos();
    let s = theta.sin();
    a * (((1.0 - f) * theta).sin() / s) + b * ((f * theta).sin() / s)
}

/// The angle the rotation turns by from `a` to `b` (same side).
fn turn(a: Quat, b: Quat) -> f32 {
    2.0 * a.dot(b).abs().min(1.0).acos()
}

/// The largest turn in one segment of the shutter a mesh placed once is flattened for, its vertices moving on
/// straight lines between keys: those chords stray inside the arc by at most 1 - cos(φ/2) of a point's distance
/// from the axis, 0.5 % here (11.5°, a turn of 46° over the shutter). Faster turns are instanced and slerped,
/// exactly; slower ones stay flattened because an instance placed per ray costs about twice a flattened mesh on
/// lavapipe (scenes/animated.gltf's cube, 36° over a 0.4 s shutter: 0.45 against 0.9 M samples/s).
pub const FLATTENED_TURN_MAX: f32 = 0.2001;

/// The largest angle any of the poses' segments turns through, which bounds how far a direction a moving instance
/// carries can be from its direction at the nearer key: half of it.
pub fn largest_turn(poses: &[Pose]) -> f32 {
    poses
        .windows(2)
        .map(|w| turn(w[0].rotation, w[1].rotation))
        .fold(0.0, f32::max)
}

/// A box holding the box (lo, hi) placed by `poses` at every time between the first key and the last, interpolated
/// as Pose::toward. Each segment is cut SWEEP_STEPS times and the corners are placed at the cuts; between two cuts
/// a corner c leaves the chord between its places by at most φ/4 (|S0 c| + |S1 c|), φ the cut's turn: with
/// y(u) = S(u) c linear and R(u) = R0 Q(u), Q a turn about one axis by uφ, the chord's error is
/// R0 [(1-u)(Q(u) - I) y0 + u (Q(u) - Q(1)) y1] (translation, linear, cancels), and a turn moves a vector by at
/// most its angle times its length. Points inside the box are convex blends of its corners at every time (the map
/// is affine), so the corners' bounds hold them.
pub fn swept_box(lo: Vec3, hi: Vec3, poses: &[Pose]) -> (Vec3, Vec3) {
    let corners = crate::scene::box_corners(lo, hi);
    let mut b = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
    let mut grow = |p: Vec3, pad: f32| b = (b.0.min(p - pad), b.1.max(p + pad));
    if let [only] = poses {
        corners
            .iter()
            .for_each(|&c| grow(only.matrix().transform_point3(c), 0.0));
    }
    for w in poses.windows(2) {
        let cuts: Vec<Pose> = (0..=SWEEP_STEPS)
            .map(|step| w[0].toward(&w[1], step as f32 / SWEEP_STEPS as f32))
            .collect();
        for pair in cuts.windows(2) {
            let phi = turn(pair[0].rotation, pair[1].rotation);
            let ends = [pair[0].matrix(), pair[1].matrix()];
            for &c in &corners {
                let reach = (pair[0].scale * c).length() + (pair[1].scale * c).length();
                for m in &ends {
                    let q = m.transform_point3(c);
                    // f32 slack: the device composes its own matrix from the same numbers.
                    grow(q, phi / 4.0 * reach + 1e-5 * (q.abs().max_element() + reach));
                }
            }
        }
    }
    b
}

/// Whether a key's linear part differs from the first key's: the instance turns or stretches over the shutter.
pub fn turns(keys: &[Mat4]) -> bool {
    let first = keys.first().map(|k| Mat3::from_mat4(*k));
    keys.iter().any(|k| Some(Mat3::from_mat4(*k)) != first)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Catches: FLATTENED_TURN_MAX not being the turn whose chord strays 0.5 % inside the arc, as documented.
    #[test]
    fn a_flattened_turn_strays_half_a_percent_at_most() {
        let p = Vec3::new(3.0, 0.0, 1.0);
        let q = Quat::from_rotation_z(FLATTENED_TURN_MAX) * p;
        let mid = (p + q) * 0.5;
        let stray = 1.0 - mid.truncate().length() / p.truncate().length();
        assert!((stray - 0.005).abs() < 1e-5, "{stray}");
    }

    /// Catches: slerp not turning at a constant rate, or the box not holding a point on the arc between cuts.
    #[test]
    fn a_quarter_turn_is_held_by_its_swept_box() {
        let keys: Vec<Mat4> = (0..=4)
            .map(|k| Mat4::from_rotation_z(k as f32 * std::f32::consts::FRAC_PI_2) * Mat4::from_scale(Vec3::splat(2.0)))
            .collect();
        let poses = decompose_keys(&keys).unwrap();
        let (lo, hi) = swept_box(Vec3::new(0.9, -0.1, 0.0), Vec3::new(1.0, 0.1, 0.0), &poses);
        for i in 0..=4000 {
            let t = i as f32 / 4000.0;
            let a = t * std::f32::consts::TAU;
            let p = Vec3::new(2.0 * a.cos(), 2.0 * a.sin(), 0.0);
            assert!(p.cmpge(lo).all() && p.cmple(hi).all(), "{p} at {t} outside {lo}..{hi}");
            let x = t * 4.0;
            let k = (x as usize).min(3);
            let at = poses[k]
                .toward(&poses[k + 1], x - k as f32)
                .matrix()
                .transform_point3(Vec3::X);
            assert!(
                (at - p).length() < 1e-4,
                "slerp puts the corner at {at}, the turn at {p}"
            );
        }
        // Tight: a full turn of radius 2 plus the box's own size and the pads.
        assert!(hi.x < 2.2 && lo.x > -2.2, "{lo}..{hi}");
    }

    #[test]
    fn a_sheared_key_does_not_decompose() {
        let shear = Mat4::from_cols(Vec4::X, Vec4::new(0.5, 1.0, 0.0, 0.0), Vec4::Z, Vec4::W);
        assert!(Pose::decompose(&shear).is_none());
        let mirror = Mat4::from_rotation_y(0.3) * Mat4::from_scale(Vec3::new(-1.0, 2.0, 3.0));
        let p = Pose::decompose(&mirror).unwrap();
        assert!(p.matrix().abs_diff_eq(mirror, 1e-5));
    }

    use glam::Vec4;
}
