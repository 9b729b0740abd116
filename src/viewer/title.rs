//! What the viewer reports: the window's title every frame, and a summary once its frames are done.
use super::State;

impl State {
    /// The animation's time, for the title and the summary; empty for a still scene.
    pub(super) fn clock(&self) -> String {
        match (self.playback.scene.rig.animated(), self.playback.playing) {
            (false, _) => String::new(),
            (true, playing) => format!(
                ", t {:.2} s{}",
                self.playback.time,
                if playing { "" } else { " (paused)" }
            ),
        }
    }

    pub(super) fn show_title(&self, rate: f64, clock: &str) {
        let scene = &self.playback.scene;
        let variant = match scene.variant {
            Some(i) => format!(", variant '{}'", scene.variants[i]),
            None => String::new(),
        };
        self.window.set_title(&format!(
            "pathwave: {} spp, {:.2} M samples/s, {:.0} ms/frame, {:?}, exposure {:+.1}{}{variant}{clock}",
            self.session.done,
            rate * 1e-6,
            self.frame_ms,
            self.curve,
            self.exposure,
            if self.dof { ", depth of field" } else { "" }
        ));
    }

    pub(super) fn report(&self, rate: f64, clock: &str) {
        let secs = self.started.elapsed().as_secs_f64();
        eprintln!(
            "{} frames in {secs:.2} s ({:.1} frames/s) at {}x{}: {} spp, {:.2} M samples/s{clock}",
            self.frames,
            self.frames as f64 / secs,
            self.swapchain.extent[0],
            self.swapchain.extent[1],
            self.session.done,
            rate * 1e-6
        );
    }
}
