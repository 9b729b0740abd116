//! `pathwave view`: a window on the progressive render, camera controls, adaptive samples per frame, hot reload.
mod display;
mod frame;
mod input;
mod orbit;
mod playback;
mod reload;
mod state;
mod swapchain;
mod title;

use crate::error::Error;
use crate::render::{RenderSettings, Renderer, Session};
use crate::scene::Scene;
use crate::shaders::{ShaderDir, ShaderWatcher};
use crate::vk::{Buffer, DeviceChoice};
use orbit::Orbit;
use playback::Playback;
use std::path::PathBuf;
use std::time::{Duration, Instant};
use swapchain::Swapchain;
use winit::application::ApplicationHandler;
use winit::event::{ElementState, MouseButton, MouseScrollDelta, WindowEvent};
use winit::event_loop::{ActiveEventLoop, ControlFlow, EventLoop};
use winit::keyboard::{KeyCode, PhysicalKey};
use winit::window::{Window, WindowId};

/// What `pathwave view` was asked for.
pub struct ViewOptions {
    pub device: DeviceChoice,
    /// Window size; `settings.width/height` follow the window. A scene with dispersion renders spectrally even
    /// when `settings.spectral` is off, unless `rgb`.
    pub settings: RenderSettings,
    /// RGB transport even for a scene with dispersion (`--rgb`).
    pub rgb: bool,
    /// Stops of exposure before the tone curve.
    pub exposure: f32,
    pub tonemap: ToneCurve,
    pub shader_dir: Option<PathBuf>,
    /// Compute BVH or ray queries (--traversal); None: PATHWAVE_TRAVERSAL, else auto.
    pub traversal: Option<crate::render::Traversal>,
    /// Stop after this many frames (writing `screenshot` first, if given).
    pub frames: Option<u32>,
    pub screenshot: Option<PathBuf>,
    /// Time per frame the adaptive sampler aims at.
    pub budget: Duration,
    /// The animation's time the scene was posed at, which animation plays (None: all) and the shutter.
    pub time: f32,
    pub animation: Option<usize>,
    pub shutter: f32,
    /// Start with the animation playing (space toggles it).
    pub play: bool,
    /// How the scene was read, for reading it again with another KHR_materials_variants variant (V).
    pub load: crate::scene::LoadOptions,
    /// Start showing this AOV or debug view (G cycles them).
    pub show: Option<crate::output::Aov>,
    /// Start denoising (Shift+D toggles it).
    pub denoise: bool,
}

pub use crate::output::ToneCurve;

/// Opens the window and runs until it is closed (or `frames` are done).
pub fn run(scene: Scene, options: ViewOptions) -> Result<(), Error> {
    let event_loop = EventLoop::new().map_err(|e| Error::Settings(format!("cannot open a window: {e}")))?;
    event_loop.set_control_flow(ControlFlow::Poll);
    let mut app = App {
        scene: Some(scene),
        options,
        state: None,
        error: None,
    };
    event_loop
        .run_app(&mut app)
        .map_err(|e| Error::Settings(format!("the window's event loop failed: {e}")))?;
    match app.error {
        Some(e) => Err(e),
        None => Ok(()),
    }
}

struct App {
    scene: Option<Scene>,
    options: ViewOptions,
    state: Option<State>,
    error: Option<Error>,
}

// Field order is drop order: device objects before the renderer's device, the window after its surface.
struct State {
    playback: Playback,
    session: Session,
    swapchain: Swapchain,
    pixels: Buffer,
    /// The image the host made for `display` or denoising (on the device, and linear for P), and at how many
    /// samples: made again as they double.
    shown: Option<(u32, Buffer, Vec<[f32; 3]>)>,
    shaders: Option<(ShaderDir, ShaderWatcher)>,
    renderer: Renderer,
    window: Window,
    orbit: Orbit,
    fly_speed: f32,
    curve: ToneCurve,
    exposure: f32,
    dof: bool,
    aperture: f32,
    /// Samples per pixel each pass asks for, adapted to the frame budget.
    samples_per_pass: u32,
    /// Render resolution divisor while the camera moves on a slow device.
    scale: u32,
    last_move: Option<Instant>,
    /// Until the user moves, the file's camera is used as is (so a still view matches a headless render exactly).
    camera_moved: bool,
    held: Vec<KeyCode>,
    cursor: (f64, f64),
    dragging: Option<MouseButton>,
    shift: bool,
    /// What the window shows (G cycles it): the image, or an AOV or debug view.
    display: Option<crate::output::Aov>,
    /// Shift+D: show the image denoised (Open Image Denoise, loaded on first use) once the camera is still.
    denoiser: Option<crate::denoise::Denoiser>,
    denoising: bool,
    frames: u32,
    started: Instant,
    last_frame: Instant,
    frame_ms: f32,
}

impl ApplicationHandler for App {
    fn resumed(&mut self, event_loop: &ActiveEventLoop) {
        if self.state.is_some() {
            return;
        }
        let Some(scene) = self.scene.take() else { return };
        match State::new(event_loop, scene, &self.options) {
            Ok(s) => self.state = Some(s),
            Err(e) => {
                self.error = Some(e);
                event_loop.exit();
            }
        }
    }

    fn window_event(&mut self, event_loop: &ActiveEventLoop, _id: WindowId, event: WindowEvent) {
        let Some(state) = self.state.as_mut() else { return };
        let result = match event {
            WindowEvent::CloseRequested => {
                event_loop.exit();
                Ok(())
            }
            WindowEvent::Resized(size) => state.resize(size),
            WindowEvent::RedrawRequested => match state.frame(&self.options) {
                Ok(true) => Ok(()),
                Ok(false) => {
                    event_loop.exit();
                    Ok(())
                }
                Err(e) => Err(e),
            },
            WindowEvent::KeyboardInput { event, .. } => {
                let PhysicalKey::Code(code) = event.physical_key else {
                    return;
                };
                if event.state == ElementState::Pressed {
                    if code == KeyCode::Escape {
                        event_loop.exit();
                    }
                    state.key(code, &self.options)
                } else {
                    state.held.retain(|k| *k != code);
                    if matches!(code, KeyCode::ShiftLeft | KeyCode::ShiftRight) {
                        state.shift = false;
                    }
                    Ok(())
                }
            }
            WindowEvent::CursorMoved { position, .. } => state.cursor_moved((position.x, position.y)),
            WindowEvent::MouseInput {
                state: pressed, button, ..
            } => state.mouse(button, pressed == ElementState::Pressed),
            WindowEvent::MouseWheel { delta, .. } => {
                let steps = match delta {
                    MouseScrollDelta::LineDelta(_, y) => y,
                    MouseScrollDelta::PixelDelta(p) => p.y as f32 / 40.0,
                };
                state.orbit.zoom(steps);
                state.moved()
            }
            _ => Ok(()),
        };
        if let Err(e) = result {
            self.error = Some(e);
            event_loop.exit();
        }
    }

    fn about_to_wait(&mut self, _event_loop: &ActiveEventLoop) {
        if let Some(s) = &self.state {
            s.window.request_redraw();
        }
    }
}
