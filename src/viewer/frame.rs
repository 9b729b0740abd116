//! One frame of the viewer: hot reload, playback, fly keys, samples until the budget is spent, present, title.
use super::{State, ViewOptions};
use crate::error::Error;
use std::time::{Duration, Instant};

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
        self.fly_held(dt)?;
        // Back to full resolution once the camera has been still for a moment.
        let still = self.last_move.is_none_or(|t| t.elapsed() > Duration::from_millis(300));
        if still && self.scale > 1 {
            self.scale = 1;
            self.reset()?;
        }
        self.sample(options.budget, still)?;
        self.present()?;
        self.frames += 1;
        self.frame_ms = 0.9 * self.frame_ms + 0.1 * now.elapsed().as_secs_f32() * 1e3;
        let rate = self.session.samples_per_sec();
        let clock = self.clock();
        self.show_title(rate, &clock);
        if options.frames.is_some_and(|n| self.frames >= n) {
            self.report(rate, &clock);
            if let Some(path) = &options.screenshot {
                self.save(path, false)?;
            }
            return Ok(false);
        }
        Ok(true)
    }

    /// Renders passes until `budget` is spent, adapting the samples per pass (and, while the camera moves, the
    /// resolution) to it.
    fn sample(&mut self, budget: Duration, still: bool) -> Result<(), Error> {
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
        Ok(())
    }
}
