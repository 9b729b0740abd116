//! Where the camera goes when the file does not say: the command line's --eye/--target/--up/--yfov/--orbit, and the
//! view a file without a camera gets.
//!
//! The default view (docs/guide/rendering.md, "Cameras"): from the direction 45° round from +z towards +x and 30° up, looking at
//! the centre of the scene's bounds, far enough that the bounding sphere fits the 45° vertical field of view with
//! 10 % to spare. A scene whose surfaces mostly face its centre (a room, a closed box with something inside) is
//! seen from inside instead: from 85 % of the way from the centre towards the bounds' corner in that direction, with
//! a 60° field of view.
use super::{Camera, Projection, Scene};
use glam::{Mat4, Vec3};

/// Azimuth (degrees from +z towards +x) and elevation (degrees up) of the default view.
pub const DEFAULT_AZIMUTH: f32 = 45.0;
pub const DEFAULT_ELEVATION: f32 = 30.0;
const OUTSIDE_YFOV: f32 = 45.0;
const INSIDE_YFOV: f32 = 60.0;
/// How far towards the bounds' corner an inside view stands.
const INSIDE_REACH: f32 = 0.85;
/// A triangle faces the centre when the cosine between its normal and the direction to the centre is above this
/// (away from it when below its negative): a floor seen from far to the side counts as neither.
const FACING_COS: f32 = 0.25;
/// At most this many triangles are looked at to decide inside or outside.
const FACING_SAMPLE: usize = 1 << 20;

/// The unit vector from a target towards an eye at `azimuth` and `elevation` (degrees): azimuth 0 is +z (the eye on
/// +z looks down -z, as glTF's default camera does), 90 is +x; elevation 90 is straight up (+y).
pub fn orbit_direction(azimuth: f32, elevation: f32) -> Vec3 {
    let (az, el) = ((azimuth as f64).to_radians(), (elevation as f64).to_radians());
    Vec3::new(
        (el.cos() * az.sin()) as f32,
        el.sin() as f32,
        (el.cos() * az.cos()) as f32,
    )
}

impl Camera {
    /// A camera at `eye` looking at `target`, `up` giving the image's up direction, with `projection`. Refused when
    /// `eye` and `target` are one point or `up` is parallel to the view.
    pub fn looking(eye: Vec3, target: Vec3, up: Vec3, projection: Projection) -> Result<Camera, String> {
        let view = target - eye;
        if view.length_squared() == 0.0 || !view.is_finite() {
            return Err(format!("the eye {eye} and the target {target} are one point"));
        }
        let forward = view.normalize();
        let right = forward.cross(up);
        if right.length() < 1e-4 * up.length() || !right.is_finite() {
            return Err(format!(
                "the up direction {up} is parallel to the view from {eye} to {target}"
            ));
        }
        let right = right.normalize();
        let up = right.cross(forward);
        let camera = Camera {
            world_from_camera: Mat4::from_cols(
                right.extend(0.0),
                up.extend(0.0),
                (-forward).extend(0.0),
                eye.extend(1.0),
            ),
            projection,
        };
        Camera::check_transform(&camera.world_from_camera).map(|_| camera)
    }
}

/// A camera the command line gives; what it leaves out comes from the file's camera (or the default view).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CameraSpec {
    pub eye: Option<Vec3>,
    pub target: Option<Vec3>,
    pub up: Option<Vec3>,
    /// Vertical field of view in degrees, in (0, 180); f64 so that a file's radians round-trip exactly.
    pub yfov: Option<f64>,
    /// Azimuth and elevation in degrees and distance in scene units (see `orbit_direction`), around `target` or
    /// the bounds' centre.
    pub orbit: Option<[f32; 3]>,
}

/// What a command-line camera does to every pose's camera.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum CameraOverride {
    /// This camera, whatever the file's does.
    Fixed(Camera),
    /// The file's camera (moving as it does) with this projection.
    Projection(Projection),
}

impl CameraOverride {
    pub fn apply(self, file: Option<Camera>) -> Option<Camera> {
        match self {
            CameraOverride::Fixed(c) => Some(c),
            CameraOverride::Projection(projection) => file.map(|c| Camera { projection, ..c }),
        }
    }
}

impl CameraSpec {
    pub fn is_empty(&self) -> bool {
        *self == CameraSpec::default()
    }

    /// What this spec makes of `scene`'s camera (as posed now), or None when it asks for nothing. A --yfov alone
    /// keeps the file's camera (moving, if it moves) and changes its field of view.
    pub fn resolve(&self, scene: &Scene) -> Result<Option<CameraOverride>, String> {
        if self.is_empty() {
            return Ok(None);
        }
        let projection = self.yfov.map(|deg| Projection::Perspective {
            yfov: deg.to_radians() as f32,
        });
        let placed = self.eye.is_some() || self.target.is_some() || self.up.is_some() || self.orbit.is_some();
        if !placed {
            let projection = projection.expect("a spec with nothing placed has a yfov");
            return Ok(Some(match scene.camera {
                Some(_) => CameraOverride::Projection(projection),
                None => CameraOverride::Fixed(Camera {
                    projection,
                    ..scene.camera_or_default()
                }),
            }));
        }
        let base = scene.camera_or_default();
        let (eye, target) = match self.orbit {
            Some([azimuth, elevation, distance]) => {
                let target = self.target.unwrap_or_else(|| match scene.is_empty() {
                    true => Vec3::ZERO,
                    false => {
                        let (lo, hi) = scene.bounds();
                        (lo + hi) * 0.5
                    }
                });
                (target + orbit_direction(azimuth, elevation) * distance, target)
            }
            None => {
                let eye = self.eye.unwrap_or_else(|| base.origin());
                (eye, self.target.unwrap_or_else(|| eye + base.basis().2))
            }
        };
        let up = self.up.unwrap_or(Vec3::Y);
        Camera::looking(eye, target, up, projection.unwrap_or(base.projection)).map(|c| Some(CameraOverride::Fixed(c)))
    }
}

impl Scene {
    /// The camera a file without one is seen through (the module comment's rule), for `bounds` (the scene's, given
    /// by a caller that has them) or the unit cube about the origin when there are none.
    pub fn default_camera(&self, bounds: Option<(Vec3, Vec3)>) -> Camera {
        let Some((lo, hi)) = bounds else {
            return Camera::framing(None);
        };
        if !self.faces_inward((lo + hi) * 0.5) {
            return Camera::framing(Some((lo, hi)));
        }
        let center = (lo + hi) * 0.5;
        let toward = orbit_direction(DEFAULT_AZIMUTH, DEFAULT_ELEVATION);
        let eye = center + (hi - lo) * 0.5 * toward * INSIDE_REACH;
        let projection = Projection::Perspective {
            yfov: INSIDE_YFOV.to_radians(),
        };
        Camera::looking(eye, center, Vec3::Y, projection).unwrap_or_else(|_| Camera::framing(Some((lo, hi))))
    }

    /// Whether the scene's surfaces mostly face `center`: of the area facing it or facing away (FACING_COS), at
    /// least two thirds faces it, and that is at least a quarter of all the area looked at.
    fn faces_inward(&self, center: Vec3) -> bool {
        let (mut toward, mut away, mut total) = (0.0f64, 0.0f64, 0.0f64);
        for (_, [a, b, c]) in self.world_triangles().take(FACING_SAMPLE) {
            let n = (b - a).cross(c - a);
            let area = n.length() as f64 * 0.5;
            let to_center = center - (a + b + c) / 3.0;
            let cos = n.normalize_or_zero().dot(to_center.normalize_or_zero());
            total += area;
            if cos > FACING_COS {
                toward += area;
            } else if cos < -FACING_COS {
                away += area;
            }
        }
        total > 0.0 && toward >= 2.0 * away && toward >= 0.25 * total
    }
}

impl Camera {
    /// The default view from outside (module comment) of `bounds` (lo, hi), or of the unit cube about the origin
    /// when there are none.
    pub fn framing(bounds: Option<(Vec3, Vec3)>) -> Camera {
        let (lo, hi) = bounds.unwrap_or((Vec3::splat(-1.0), Vec3::splat(1.0)));
        let center = (lo + hi) * 0.5;
        let radius = ((hi - lo).length() * 0.5).max(1e-3);
        let yfov = OUTSIDE_YFOV.to_radians();
        let distance = 1.1 * radius / (yfov * 0.5).sin();
        let eye = center + orbit_direction(DEFAULT_AZIMUTH, DEFAULT_ELEVATION) * distance;
        let projection = Projection::Perspective { yfov };
        Camera::looking(eye, center, Vec3::Y, projection).expect("the default direction is not vertical")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_orbit_looks_at_its_target_from_its_angles() {
        let target = Vec3::new(1.0, 2.0, 3.0);
        let eye = target + orbit_direction(90.0, 0.0) * 4.0;
        assert!((eye - Vec3::new(5.0, 2.0, 3.0)).length() < 1e-5, "{eye}");
        let c = Camera::looking(eye, target, Vec3::Y, Projection::Perspective { yfov: 1.0 }).unwrap();
        let (o, d) = c.ray(0.5, 0.5, 1.0);
        assert!((o + d * 4.0 - target).length() < 1e-5);
        assert!((orbit_direction(0.0, 90.0) - Vec3::Y).length() < 1e-6);
    }

    #[test]
    fn a_camera_cannot_look_at_its_own_eye_or_along_its_up() {
        let p = Projection::Perspective { yfov: 1.0 };
        assert!(Camera::looking(Vec3::ONE, Vec3::ONE, Vec3::Y, p).is_err());
        assert!(Camera::looking(Vec3::ZERO, Vec3::Y * 3.0, Vec3::Y, p).is_err());
    }

    #[test]
    fn the_default_view_fits_the_bounding_sphere() {
        let (lo, hi) = (Vec3::new(-1.0, 0.0, -2.0), Vec3::new(3.0, 1.0, 2.0));
        let c = Camera::framing(Some((lo, hi)));
        let center = (lo + hi) * 0.5;
        let radius = (hi - lo).length() * 0.5;
        let (right, up, forward) = c.basis();
        let to = center - c.origin();
        assert!(to.normalize().dot(forward) > 1.0 - 1e-6, "looks at the centre");
        assert!(right.y.abs() < 1e-6 && up.y > 0.0, "level and upright");
        // The sphere's angular radius seen from the eye is 1/1.1 of the half field of view's sine.
        let half = c.projection.half_height().atan();
        assert!((radius / to.length() - half.sin() / 1.1).abs() < 1e-5);
    }
}
