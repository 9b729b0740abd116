//! The orbit camera the mouse and fly keys move.
use crate::scene::{Camera, Projection};
use glam::{Mat4, Vec3};

/// An orbit camera: the eye circles `target`; flying moves both.
#[derive(Clone, Copy)]
pub(super) struct Orbit {
    eye: Vec3,
    target: Vec3,
    projection: Projection,
}

impl Orbit {
    pub(super) fn from_camera(c: &Camera, distance: f32) -> Self {
        let (_, _, forward) = c.basis();
        Orbit {
            eye: c.origin(),
            target: c.origin() + forward * distance,
            projection: c.projection,
        }
    }

    fn basis(&self) -> (Vec3, Vec3, Vec3) {
        let forward = (self.target - self.eye).normalize_or(-Vec3::Z);
        let right = forward.cross(Vec3::Y).normalize_or(Vec3::X);
        (right, right.cross(forward), forward)
    }

    pub(super) fn camera(&self) -> Camera {
        let (right, up, forward) = self.basis();
        Camera {
            world_from_camera: Mat4::from_cols(
                right.extend(0.0),
                up.extend(0.0),
                (-forward).extend(0.0),
                self.eye.extend(1.0),
            ),
            projection: self.projection,
        }
    }

    pub(super) fn orbit(&mut self, dx: f32, dy: f32) {
        let offset = self.eye - self.target;
        let (right, _, _) = self.basis();
        let yaw = glam::Quat::from_axis_angle(Vec3::Y, -dx);
        let pitched = glam::Quat::from_axis_angle(right, -dy) * offset;
        // Stop short of the poles, where "up" would flip.
        let offset = if pitched.normalize().dot(Vec3::Y).abs() < 0.99 {
            pitched
        } else {
            offset
        };
        self.eye = self.target + yaw * offset;
    }

    pub(super) fn pan(&mut self, dx: f32, dy: f32) {
        let (right, up, _) = self.basis();
        // What a drag across the view moves it by: the image plane's size at the target.
        let d = match self.projection {
            Projection::Perspective { .. } => (self.eye - self.target).length(),
            Projection::Orthographic { ymag } => ymag,
        };
        let shift = (-right * dx + up * dy) * d;
        self.eye += shift;
        self.target += shift;
    }

    /// Moves in toward the target; an orthographic view, which distance does not change, shrinks its image plane.
    pub(super) fn zoom(&mut self, steps: f32) {
        let offset = self.eye - self.target;
        self.eye = self.target + offset * 0.9f32.powf(steps);
        if let Projection::Orthographic { ymag } = &mut self.projection {
            *ymag *= 0.9f32.powf(steps);
        }
    }

    pub(super) fn fly(&mut self, local: Vec3) {
        let (right, up, forward) = self.basis();
        let shift = right * local.x + up * local.y + forward * local.z;
        self.eye += shift;
        self.target += shift;
    }
}
