//! `pathwave view`: a window on the progressive render, camera controls, adaptive samples per frame, hot reload.
mod display;
mod frame;
mod input;
mod orbit;
mod playback;
mod reload;
mod swapchain;
mod title;

use crate::error::Error;
use crate::render::{RenderSettings, Renderer, Session, SpectralChoice};
use crate::scene::Scene;
use crate::shaders::{ShaderDir, ShaderWatcher};
use crate::vk::{Buffer, Context, DeviceChoice, Validation, WindowHandles};
use display::pixel_buffer;
use orbit::Orbit;
use playback::Playback;
use reload::watch_shaders;
use std::path::PathBuf;
use std::time::{Duration, Instant};
use swapchain::Swapchain;
use winit::application::ApplicationHandler;
use winit::dpi::PhysicalSize;
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

impl State {
    fn new(event_loop: &ActiveEventLoop, scene: Scene, options: &ViewOptions) -> Result<Self, Error> {
        use winit::raw_window_handle::{HasDisplayHandle, HasWindowHandle};
        let s = &options.settings;
        let attributes = Window::default_attributes()
            .with_title("pathwave")
            .with_inner_size(PhysicalSize::new(s.width, s.height));
        let window = event_loop
            .create_window(attributes)
            .map_err(|e| Error::Settings(format!("cannot open a window: {e}")))?;
        let handle_err = |e: winit::raw_window_handle::HandleError| Error::Settings(format!("window handle: {e}"));
        let handles = WindowHandles {
            display: window.display_handle().map_err(handle_err)?.as_raw(),
            window: window.window_handle().map_err(handle_err)?.as_raw(),
        };
        let ctx = Context::for_window(&options.device, Validation::from_env()?, handles)?;
        let mut renderer_options = crate::RendererOptions::from_env()?;
        if let Some(t) = options.traversal {
            renderer_options.traversal = t;
        }
        let mut renderer = Renderer::with_options(&scene, ctx, renderer_options)?;
        for w in &renderer.warnings {
            eprintln!("warning: {}: {w}", scene.path.display());
        }
        let shaders = watch_shaders(&mut renderer, options)?;
        let size = window.inner_size();
        let swapchain = Swapchain::new(renderer.context(), [size.width.max(1), size.height.max(1)])?;
        let focus = s.focus_distance.unwrap_or(renderer.default_focus());
        let orbit = Orbit::from_camera(&renderer.camera(), focus);
        let (lo, hi) = scene.bounds();
        let extent = (hi - lo).length().max(1e-3);
        let mut settings = s.clone();
        settings.width = swapchain.extent[0];
        settings.height = swapchain.extent[1];
        settings.focus_distance = Some(focus);
        settings.spectral = SpectralChoice::new(s.spectral, options.rgb, scene.wants_spectral()).spectral();
        let session = renderer.begin(&settings)?;
        let pixels = pixel_buffer(renderer.context(), swapchain.extent)?;
        if options.play && !scene.rig.animated() {
            eprintln!("warning: {}: the file has no animations to play", scene.path.display());
        }
        let mut state = State {
            playback: Playback {
                playing: options.play && scene.rig.animated(),
                scene,
                time: options.time,
                animation: options.animation,
                shutter: options.shutter,
            },
            window,
            renderer,
            session,
            swapchain,
            pixels,
            shaders,
            orbit,
            fly_speed: extent * 0.5,
            curve: options.tonemap,
            exposure: options.exposure,
            dof: s.aperture > 0.0,
            aperture: if s.aperture > 0.0 { s.aperture } else { extent * 0.01 },
            samples_per_pass: 1,
            scale: 1,
            last_move: None,
            camera_moved: false,
            held: Vec::new(),
            cursor: (0.0, 0.0),
            dragging: None,
            shift: false,
            display: None,
            denoiser: None,
            denoising: false,
            shown: None,
            frames: 0,
            started: Instant::now(),
            last_frame: Instant::now(),
            frame_ms: 0.0,
        };
        // A view or denoising asked for on the command line: the session then surveys the AOVs.
        if options.show.is_some() || options.denoise {
            state.display = options.show;
            if options.denoise {
                state.denoiser = Some(crate::denoise::Denoiser::from_env()?);
                state.denoising = true;
            }
            state.reset()?;
        }
        Ok(state)
    }

    /// Starts the accumulation again (camera, settings or shaders changed), at 1/scale of the window's resolution.
    fn reset(&mut self) -> Result<(), Error> {
        if self.camera_moved {
            self.renderer.set_camera(self.orbit.camera());
        }
        self.shown = None;
        let mut settings = self.session.settings.clone();
        settings.aperture = if self.dof { self.aperture } else { 0.0 };
        // The AOVs only while something shows them.
        settings.aovs = self.denoising || self.display.is_some_and(|a| a.surveyed());
        settings.debug_aovs = self.display.is_some_and(|a| a.debug());
        let w = (self.swapchain.extent[0] / self.scale).max(1);
        let h = (self.swapchain.extent[1] / self.scale).max(1);
        let buffers =
            (settings.aovs, settings.debug_aovs) != (self.session.settings.aovs, self.session.settings.debug_aovs);
        if (w, h) != (settings.width, settings.height) || buffers {
            settings.width = w;
            settings.height = h;
            self.session = self.renderer.begin(&settings)?;
        } else {
            self.session.settings = settings;
            self.renderer.restart(&mut self.session)?;
        }
        Ok(())
    }

    fn moved(&mut self) -> Result<(), Error> {
        self.last_move = Some(Instant::now());
        self.camera_moved = true;
        self.reset()
    }

    fn resize(&mut self, size: PhysicalSize<u32>) -> Result<(), Error> {
        if size.width == 0 || size.height == 0 {
            return Ok(());
        }
        self.swapchain
            .recreate(self.renderer.context(), [size.width, size.height])?;
        self.pixels = pixel_buffer(self.renderer.context(), self.swapchain.extent)?;
        self.reset()
    }
}
