//! Making the viewer's state (window, device, renderer, swapchain, first session), and starting its accumulation again.
use super::display::pixel_buffer;
use super::orbit::Orbit;
use super::playback::Playback;
use super::reload::watch_shaders;
use super::swapchain::Swapchain;
use super::{State, ViewOptions};
use crate::error::Error;
use crate::render::{RenderSettings, Renderer, SpectralChoice};
use crate::scene::Scene;
use crate::vk::{Context, Validation, WindowHandles};
use std::time::Instant;
use winit::dpi::PhysicalSize;
use winit::event_loop::ActiveEventLoop;
use winit::window::Window;

impl State {
    pub(super) fn new(event_loop: &ActiveEventLoop, scene: Scene, options: &ViewOptions) -> Result<Self, Error> {
        let s = &options.settings;
        let window = open_window(event_loop, s)?;
        let mut renderer = open_renderer(&window, &scene, options)?;
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
    pub(super) fn reset(&mut self) -> Result<(), Error> {
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

    pub(super) fn moved(&mut self) -> Result<(), Error> {
        self.last_move = Some(Instant::now());
        self.camera_moved = true;
        self.reset()
    }

    pub(super) fn resize(&mut self, size: PhysicalSize<u32>) -> Result<(), Error> {
        if size.width == 0 || size.height == 0 {
            return Ok(());
        }
        self.swapchain
            .recreate(self.renderer.context(), [size.width, size.height])?;
        self.pixels = pixel_buffer(self.renderer.context(), self.swapchain.extent)?;
        self.reset()
    }
}

fn open_window(event_loop: &ActiveEventLoop, s: &RenderSettings) -> Result<Window, Error> {
    let attributes = Window::default_attributes()
        .with_title("pathwave")
        .with_inner_size(PhysicalSize::new(s.width, s.height));
    event_loop
        .create_window(attributes)
        .map_err(|e| Error::Settings(format!("cannot open a window: {e}")))
}

/// The device for the window's surface and the renderer on it, with its warnings about the scene printed.
fn open_renderer(window: &Window, scene: &Scene, options: &ViewOptions) -> Result<Renderer, Error> {
    use winit::raw_window_handle::{HasDisplayHandle, HasWindowHandle};
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
    let renderer = Renderer::with_options(scene, ctx, renderer_options)?;
    for w in &renderer.warnings {
        eprintln!("warning: {}: {w}", scene.path.display());
    }
    Ok(renderer)
}
