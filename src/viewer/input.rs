//! Key bindings and the mouse: what each key, drag and click does to the view.
use super::{State, ViewOptions};
use crate::error::Error;
use glam::Vec3;
use std::path::PathBuf;
use winit::event::MouseButton;
use winit::keyboard::KeyCode;

impl State {
    pub(super) fn key(&mut self, code: KeyCode, options: &ViewOptions) -> Result<(), Error> {
        match code {
            KeyCode::KeyP => {
                let path = options
                    .screenshot
                    .clone()
                    .unwrap_or_else(|| PathBuf::from("pathwave.exr"));
                self.save(&path, true)?
            }
            KeyCode::KeyR => self.reset()?,
            KeyCode::Space if self.playback.scene.rig.animated() => {
                self.playback.playing = !self.playback.playing;
                eprintln!(
                    "animation {} at {:.3} s",
                    if self.playback.playing { "playing" } else { "paused" },
                    self.playback.time
                );
            }
            KeyCode::KeyV if !self.playback.scene.variants.is_empty() => self.next_variant(options)?,
            KeyCode::KeyT => {
                self.curve = self.curve.next();
                eprintln!("tone curve: {:?}", self.curve);
            }
            KeyCode::Equal | KeyCode::NumpadAdd => self.exposure += 0.5,
            KeyCode::Minus | KeyCode::NumpadSubtract => self.exposure -= 0.5,
            KeyCode::KeyF => {
                self.dof = !self.dof;
                self.reset()?;
            }
            KeyCode::ShiftLeft | KeyCode::ShiftRight => self.shift = true,
            KeyCode::KeyD if self.shift => self.toggle_denoise()?,
            KeyCode::KeyG => {
                self.display = next_display(self.display);
                eprintln!("showing {}", self.display.map_or("the image", |a| a.name()));
                self.reset()?;
            }
            KeyCode::KeyW | KeyCode::KeyA | KeyCode::KeyS | KeyCode::KeyD | KeyCode::KeyQ | KeyCode::KeyE
                if !self.held.contains(&code) =>
            {
                self.held.push(code)
            }
            _ => {}
        }
        Ok(())
    }

    /// Shift+D: denoising on or off; the library is found the first time (a failure leaves it off, with the reason).
    fn toggle_denoise(&mut self) -> Result<(), Error> {
        if !self.denoising && self.denoiser.is_none() {
            match crate::denoise::Denoiser::from_env() {
                Ok(d) => self.denoiser = Some(d),
                Err(e) => {
                    eprintln!("cannot denoise: {e}");
                    return Ok(());
                }
            }
        }
        self.denoising = !self.denoising;
        eprintln!(
            "denoising {}",
            if self.denoising {
                "on (once the camera is still)"
            } else {
                "off"
            }
        );
        self.reset()
    }

    /// Reads the scene again with its next KHR_materials_variants variant (after the last, none), at the same time
    /// and in the same environment; the device and pipelines stay.
    fn next_variant(&mut self, options: &ViewOptions) -> Result<(), Error> {
        let scene = &self.playback.scene;
        let next = match scene.variant {
            None => Some(0),
            Some(i) if i + 1 < scene.variants.len() => Some(i + 1),
            Some(_) => None,
        };
        let mut load = options.load.clone();
        load.variant = next.map(|i| scene.variants[i].clone());
        let mut fresh = crate::scene::load_with(&scene.path, &load)?;
        fresh.environment = scene.environment.clone();
        let pose = crate::scene::PoseTime {
            time: self.playback.time,
            animation: self.playback.animation,
        };
        fresh.pose_shutter(pose, self.playback.shutter)?;
        eprintln!(
            "variant: {}",
            load.variant
                .as_deref()
                .unwrap_or("none (the primitives' own materials)")
        );
        self.playback.scene = fresh;
        self.renderer.set_scene(&self.playback.scene)?;
        self.reset()
    }

    pub(super) fn cursor_moved(&mut self, to: (f64, f64)) -> Result<(), Error> {
        let (dx, dy) = ((to.0 - self.cursor.0) as f32, (to.1 - self.cursor.1) as f32);
        self.cursor = to;
        let h = self.swapchain.extent[1].max(1) as f32;
        match self.dragging {
            Some(MouseButton::Left) => {
                self.orbit.orbit(dx / h * 3.0, dy / h * 3.0);
                self.moved()
            }
            Some(MouseButton::Middle) => {
                self.orbit.pan(dx / h, dy / h);
                self.moved()
            }
            _ => Ok(()),
        }
    }

    pub(super) fn mouse(&mut self, button: MouseButton, pressed: bool) -> Result<(), Error> {
        if !pressed {
            self.dragging = None;
            return Ok(());
        }
        if button != MouseButton::Right {
            self.dragging = Some(button);
            return Ok(());
        }
        // Right click: focus on the surface under the cursor.
        let [w, h] = self.swapchain.extent;
        let (x, y) = (self.cursor.0 as f32 / w as f32, self.cursor.1 as f32 / h as f32);
        if let Some(d) = self.renderer.focus_distance_at(x, y, w as f32 / h as f32)? {
            eprintln!("focus distance {d:.3}");
            self.session.settings.focus_distance = Some(d);
            self.dof = true;
            self.reset()?;
        }
        Ok(())
    }

    /// W/S, D/A and E/Q fly forward and back, right and left, up and down while held.
    pub(super) fn fly_held(&mut self, dt: f32) -> Result<(), Error> {
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
        Ok(())
    }
}

/// G's cycle: the image, then the AOVs a viewer can show, then the debug views, then the image again.
fn next_display(now: Option<crate::output::Aov>) -> Option<crate::output::Aov> {
    use crate::output::Aov;
    const CYCLE: [Aov; 8] = [
        Aov::Albedo,
        Aov::Normal,
        Aov::Depth,
        Aov::GeometricNormal,
        Aov::ShadingNormal,
        Aov::Uv,
        Aov::BvhCost,
        Aov::LightPick,
    ];
    match now {
        None => Some(CYCLE[0]),
        Some(a) => CYCLE
            .iter()
            .position(|&c| c == a)
            .and_then(|i| CYCLE.get(i + 1))
            .copied(),
    }
}
