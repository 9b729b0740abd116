//! Animation playback: the time the scene is posed at, looping over the animation's keys.
use crate::error::Error;
use crate::scene::Scene;

/// The animation as the viewer plays it: where it is, and whether it runs.
pub(super) struct Playback {
    /// The scene the renderer holds, posed at `time`.
    pub(super) scene: Scene,
    pub(super) time: f32,
    pub(super) playing: bool,
    pub(super) animation: Option<usize>,
    pub(super) shutter: f32,
}

impl Playback {
    /// Moves on by `dt` seconds, looping over the animation's keys; true when the scene was posed anew.
    pub(super) fn advance(&mut self, dt: f32) -> Result<bool, Error> {
        if !self.playing {
            return Ok(false);
        }
        let (lo, hi) = self.scene.rig.range(self.animation);
        let length = hi - lo;
        let t = self.time + dt;
        self.time = if length > 0.0 && t > hi {
            lo + (t - lo) % length
        } else {
            t
        };
        let pose = crate::scene::PoseTime {
            time: self.time,
            animation: self.animation,
        };
        self.scene.pose_shutter(pose, self.shutter)?;
        Ok(true)
    }
}
