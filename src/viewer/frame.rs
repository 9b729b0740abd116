//! One frame of the viewer: hot reload, playback, fly keys, samples until the budget is spent, present, title.
use super::{State, ViewOptions};
use crate::error::Error;
use glam::Vec3;
use std::time::{Duration, Instant};
use winit::keyboard::KeyCode;

impl State {
    /// One frame: hot reload, fly keys, samples until the budget is spent, tone map, present. False when done.
    pub(super) fn frame(&mut self, options: &ViewOptions) -> Result<bool, Error> {
        let now = Instant::now();
        let dt = (now - self.last_frame).as_secs_f32().min(0.1);
        self.last_frame = now;
        self.reload_shaders()?;
        if self.playback.advance(dt)? {
            // The new pose keeps the device and pipelines; the accumulation starts again from it.
            self.renderer.set_scene(&self.playback.scene)?;
            self.reset()?;
        }
        if !self.held.is_empty() {
            let mut v = Vec3::ZERO;
            for k in &self.held {
                v += match k {
                    KeyCode::KeyW => Vec3::Z,
                    KeyCode::KeyS => -Vec3::Z,
                    KeyCode::KeyD => Vec3::X,
                    KeyCode::KeyA => -Vec3::X,
                    KeyCode::KeyE => Vec3::Y,
                    KeyCode::KeyQ => -Vec3::Y,
                    _ => Vec3::ZERO,
                };
            }
            self.orbit.fly(v * self.fly_speed * dt);
            self.moved()?;
        }
        // Back to full resolution once the camera has been still for a moment.
        let still = self.last_move.is_none_or(|t| t.elapsed() > Duration::from_millis(300));
        if still && self.scale > 1 {
            self.scale = 1;
            self.reset()?;
        }
        let budget = options.budget;
        let start = Instant::now();
        loop {
            let pass_start = Instant::now();
            self.renderer.advance(&mut self.session, self.samples_per_pass)?;
            let pass = pass_start.elapsed();
            // Fewer, larger passes amortise dispatch overhead; smaller ones keep the window responsive.
            if pass < budget / 4 {
                self.samples_per_pass = (self.samples_per_pass * 2).min(256);
            } else if pass > budget && self.samples_per_pass > 1 {
                self.samples_per_pass /= 2;
            } else if pass > budget && !still && self.scale < 8 {
                self.scale *= 2;
                self.reset()?;
                break;
            }
            if start.elapsed() + pass > budget {
                break;
            }
        }
        self.present()?;
        self.frames += 1;
        self.frame_ms = 0.9 * self.frame_ms + 0.1 * now.elapsed().as_secs_f32() * 1e3;
        let rate = self.session.samples_per_sec();
        let clock = match (self.playback.scene.rig.animated(), self.playback.playing) {
            (false, _) => String::new(),
            (true, playing) => format!(
                ", t {:.2} s{}",
                self.playback.time,
                if playing { "" } else { " (paused)" }
            ),
        };
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
        if options.frames.is_some_and(|n| self.frames >= n) {
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
            if let Some(path) = &options.screenshot {
                self.save(path, false)?;
            }
            return Ok(false);
        }
        Ok(true)
    }
}
