//! A progressive render: the film and path state on the device, and the passes that add samples to them.
use super::film::{ExactFilm, Film, RenderStats};
use super::integrator::{Pass, FUSED_FALLBACK};
use super::schedule::{Schedule, ScheduleChoice};
use super::settings::MEDIA_DEPTH_CAP;
use super::sizing::{path_capacity, path_fields, size_pass, PathLimits};
use super::Aovs;
use super::{RenderSettings, Renderer, DEPTH_SAFETY_CAP};
use crate::constants::*;
use crate::error::Error;
use crate::layout::{AovSums, Counters, DebugSums, Frame, FrameCamera};
use crate::vk::{Buffer, TexelViews};
use ash::vk;
use gpu_allocator::MemoryLocation;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

/// A progressive render: the film and path state stay on the device between `Renderer::advance` calls, so a
/// viewer can add samples frame by frame and show the running mean.
pub struct Session {
    pub settings: RenderSettings,
    frame: Frame,
    /// The FEATURE_* bits the settings ask for, decided with `frame` at each (re)start.
    features: u32,
    pixels: u64,
    capacity: u32,
    /// The path state's texel views: dropped before it.
    path_views: TexelViews,
    paths: Buffer,
    queues: Buffer,
    counters: Buffer,
    film: Buffer,
    /// The AOVs' sums (`AovSums` per pixel), when the settings ask for AOVs.
    aovs: Option<Buffer>,
    /// The debug views' sums (`DebugSums` per pixel), when the settings ask for them.
    debug: Option<Buffer>,
    /// Adaptive sampling's budgets and the pixels in their order (ORDER_BUCKETS), when the settings ask for it.
    budget: Option<Buffer>,
    /// Once the budgets are planned, where the render ends and which pixels each pass covers.
    planned: Option<Planned>,
    /// Samples per pixel accumulated so far.
    pub done: u32,
    /// Tallies since the last (re)start.
    pub stats: RenderStats,
    pub(super) started: Instant,
}

/// Adaptive sampling's plan as the host keeps it: the sample index past every pixel's budget (the render ends there),
/// and per bucket of budgets (plan.comp) how many pixels fall in it and the largest budget among them.
#[derive(Clone, Debug)]
pub(super) struct Planned {
    pub end: u32,
    pub counts: Vec<u32>,
    pub largest: Vec<u32>,
}

impl Planned {
    /// How many of the ordered pixels a pass from sample `s` covers: those of every bucket whose largest budget is
    /// above `s`. Larger budgets rank first and never fall in a lower bucket, so these are a prefix of the order and
    /// hold every pixel that still takes samples (and, within a bucket, a few that take fewer).
    pub fn active(&self, s: u32) -> u32 {
        (self.counts.iter().zip(&self.largest))
            .filter(|&(_, &largest)| largest > s)
            .map(|(&count, _)| count)
            .sum()
    }
}

impl Session {
    /// The session's buffers by binding.
    pub(super) fn bindings(&self) -> Vec<(u32, &Buffer)> {
        let mut b = vec![
            (BINDING_PATHS, &self.paths),
            (BINDING_QUEUES, &self.queues),
            (BINDING_COUNTERS, &self.counters),
            (BINDING_FILM, &self.film),
        ];
        b.extend(self.aovs.as_ref().map(|a| (BINDING_AOVS, a)));
        b.extend(self.budget.as_ref().map(|a| (BINDING_BUDGET, a)));
        b.extend(self.debug.as_ref().map(|a| (BINDING_DEBUG_AOVS, a)));
        b
    }

    /// Samples per pixel the render takes: the settings', or fewer where adaptive sampling planned every pixel's
    /// budget below them.
    pub fn target(&self) -> u32 {
        let s = &self.settings;
        match &self.planned {
            Some(p) => p.end.saturating_sub(s.first_sample).min(s.spp),
            None => s.spp,
        }
    }

    pub(super) fn texel_views(&self) -> &[(u32, vk::BufferView)] {
        &self.path_views.views
    }

    /// Samples (paths) per second since the session last (re)started.
    pub fn samples_per_sec(&self) -> f64 {
        self.stats.samples as f64 / self.started.elapsed().as_secs_f64().max(1e-9)
    }

    /// The film buffer on the device: running sums, then running sums of squares (see layout.glsl).
    pub fn film_buffer(&self) -> &Buffer {
        &self.film
    }
}

impl Renderer {
    /// Renders `settings.spp` samples per pixel; `progress` hears the samples per pixel done so far.
    pub fn render(
        &mut self,
        settings: &RenderSettings,
        progress: &mut dyn FnMut(u32),
    ) -> Result<(Film, RenderStats), Error> {
        self.render_until(settings, progress, &AtomicBool::new(false))
    }

    /// `render`, ending early (between passes, so within a pass's time) once `stop` is set: the film then holds the
    /// `film.spp` samples per pixel done so far, a valid image of fewer samples.
    pub fn render_until(
        &mut self,
        settings: &RenderSettings,
        progress: &mut dyn FnMut(u32),
        stop: &AtomicBool,
    ) -> Result<(Film, RenderStats), Error> {
        let mut session = self.begin(settings)?;
        while session.done < session.target() && !stop.load(Ordering::Relaxed) {
            let remaining = session.target() - session.done;
            self.advance(&mut session, remaining)?;
            progress(session.done);
        }
        let film = self.film(&session)?;
        let mut stats = std::mem::take(&mut session.stats);
        if settings.adaptive.is_some() {
            // Passes count every pixel's samples; adaptive ones take fewer.
            stats.samples = film.sample_count().iter().map(|&n| n as u64).sum();
        }
        stats.interrupted = session.done < session.target();
        stats.wall = session.started.elapsed();
        stats.light_sampler = self.light_sampler_run(settings);
        if stats.passes == 1 {
            stats.stage_ms = std::mem::take(&mut stats.first_pass_stage_ms);
        }
        Ok((film, stats))
    }

    /// Starts a progressive render: allocates the film and path state and clears the film. `settings.spp` is not
    /// used; `advance` adds samples until the caller stops.
    pub fn begin(&mut self, settings: &RenderSettings) -> Result<Session, Error> {
        let s = settings;
        s.check()?;
        let pixels = s.width as u64 * s.height as u64;
        let range = self.ctx.properties.limits.max_storage_buffer_range as u64;
        let film_bytes = film_bytes(s, range)?;
        let fields = path_fields(self.scene.features);
        let capacity = path_capacity(pixels * s.spp as u64, self.path_limits(), fields);
        let ctx = &self.ctx;
        let storage = vk::BufferUsageFlags::STORAGE_BUFFER;
        let (paths, path_views, queues) = path_state(ctx, capacity, fields)?;
        let counters = Buffer::new(
            ctx,
            "counters",
            std::mem::size_of::<Counters>() as u64,
            storage | vk::BufferUsageFlags::INDIRECT_BUFFER,
            MemoryLocation::GpuToCpu,
        )?;
        let film = Buffer::new(ctx, "film", film_bytes, storage, MemoryLocation::GpuOnly)?;
        // (whether asked for, the buffer's name, what the settings ask for, bytes, what they hold).
        let sums = |(asked, name, with, bytes, holds): (bool, &str, &str, u64, &str)| match asked {
            true if bytes > range => Err(Error::Settings(format!(
                "{}x{} with {with} needs {bytes} bytes of {holds} but this device's storage buffers hold at most \
                 {range} bytes",
                s.width, s.height
            ))),
            true => Buffer::new(ctx, name, bytes, storage, MemoryLocation::GpuOnly).map(Some),
            false => Ok(None),
        };
        let debug_bytes = pixels * std::mem::size_of::<DebugSums>() as u64;
        let debug = sums((
            s.debug_aovs,
            "debug views",
            "debug views",
            debug_bytes,
            "sums (48 a pixel)",
        ))?;
        let aov_bytes = pixels * std::mem::size_of::<AovSums>() as u64;
        let aovs = sums((
            s.aovs || s.debug_aovs,
            "aovs",
            "AOVs",
            aov_bytes,
            "AOV sums (64 a pixel)",
        ))?;
        let budget = match s.adaptive {
            Some(_) => Some(Buffer::new(
                ctx,
                "budgets",
                (2 * pixels + 3 * ORDER_BUCKETS as u64) * 4,
                storage,
                MemoryLocation::GpuOnly,
            )?),
            None => None,
        };
        let mut session = Session {
            settings: s.clone(),
            frame: Frame::default(),
            pixels,
            capacity,
            path_views,
            paths,
            queues,
            counters,
            film,
            aovs,
            debug,
            budget,
            planned: None,
            features: 0,
            done: 0,
            stats: RenderStats::default(),
            started: Instant::now(),
        };
        self.restart(&mut session)?;
        Ok(session)
    }

    /// The device limits the path state must fit.
    fn path_limits(&self) -> PathLimits {
        let limits = &self.ctx.properties.limits;
        PathLimits {
            storage_range: limits.max_storage_buffer_range as u64,
            texel_elements: limits.max_texel_buffer_elements as u64,
            device_local_heap: self.ctx.device_local_heap(),
        }
    }

    /// Clears a session's film and starts again from sample 0 with the renderer's current camera and the session's
    /// settings (the image size must stay the same).
    pub fn restart(&mut self, session: &mut Session) -> Result<(), Error> {
        let mut frame = self.frame(&session.settings);
        frame.path_capacity = session.capacity;
        session.frame = frame;
        session.features = session.settings.features();
        session.done = 0;
        session.stats = RenderStats::default();
        session.started = Instant::now();
        session.planned = None;
        let (ctx, film, budget) = (&self.ctx, &session.film, &session.budget);
        let sums: Vec<&Buffer> = session.aovs.iter().chain(&session.debug).collect();
        ctx.submit_and_wait(|cmd| unsafe {
            ctx.device.cmd_fill_buffer(cmd, film.raw, 0, vk::WHOLE_SIZE, 0);
            for a in &sums {
                ctx.device.cmd_fill_buffer(cmd, a.raw, 0, vk::WHOLE_SIZE, 0);
            }
            // Every sample is taken until the budgets are planned.
            if let Some(b) = budget {
                ctx.device.cmd_fill_buffer(cmd, b.raw, 0, vk::WHOLE_SIZE, u32::MAX);
            }
        })
    }

    /// Runs one pass: up to `samples` more samples per pixel (as many as fit in flight; one when the image must be
    /// covered in chunks). Returns how many were added.
    ///
    /// Adaptive sampling plans the budgets once the film holds the pilot: a pass ends there. A render that starts
    /// past sample 0 (`--samples`, `--part`) renders the pilot first, plans from it and clears the film, so it takes
    /// the very samples a render from 0 takes there, and their parts merge to its bits.
    pub fn advance(&mut self, session: &mut Session, samples: u32) -> Result<u32, Error> {
        let Some(a) = session.settings.adaptive else {
            return self.advance_pass(session, samples);
        };
        let first = session.settings.first_sample;
        let end = first.saturating_add(session.settings.spp);
        if session.planned.is_none() && first > 0 && session.done == 0 && end > a.pilot {
            self.pilot(session, a)?;
        }
        let next = first + session.done;
        let samples = match session.planned {
            None if next < a.pilot => samples.min(a.pilot - next),
            _ => samples,
        };
        let added = self.advance_pass(session, samples)?;
        if session.planned.is_none() && first == 0 && session.done == a.pilot {
            self.bind(&session.bindings(), session.texel_views());
            session.planned = Some(self.plan_session(session, a, end)?);
            self.check_validation()?;
        }
        Ok(added)
    }

    /// The pilot of a render that starts past sample 0: samples 0..pilot into the film, the budgets planned from
    /// them, and the film (and AOVs) cleared again.
    fn pilot(&mut self, session: &mut Session, a: super::Adaptive) -> Result<(), Error> {
        let first = session.settings.first_sample;
        session.settings.first_sample = 0;
        let result = (|| {
            while session.done < a.pilot {
                self.advance_pass(session, a.pilot - session.done)?;
            }
            self.bind(&session.bindings(), session.texel_views());
            let end = first.saturating_add(session.settings.spp);
            self.plan_session(session, a, end)
        })();
        session.settings.first_sample = first;
        session.done = 0;
        session.planned = Some(result?);
        // The pilot's samples leave the film (its work stays in the tallies).
        let (ctx, film) = (&self.ctx, &session.film);
        let sums: Vec<&Buffer> = session.aovs.iter().chain(&session.debug).collect();
        ctx.submit_and_wait(|cmd| unsafe {
            ctx.device.cmd_fill_buffer(cmd, film.raw, 0, vk::WHOLE_SIZE, 0);
            for a in &sums {
                ctx.device.cmd_fill_buffer(cmd, a.raw, 0, vk::WHOLE_SIZE, 0);
            }
        })?;
        self.check_validation()
    }

    /// The session's budgets, planned from the pilot in its film.
    fn plan_session(&mut self, session: &Session, a: super::Adaptive, end: u32) -> Result<Planned, Error> {
        let budget =
            (session.budget.as_ref()).ok_or_else(|| Error::Vulkan("an adaptive session has no budgets".into()))?;
        let pass = self.pass_of(session, session.frame);
        self.integrator
            .plan(&self.ctx, &mut self.kernels, &pass, budget, a, end)
    }

    /// A pass of `session` over `frame`: its stages specialised for the scene, the session's settings and the light
    /// selection `frame` asks for (the light tree only where the scene has enough emitters for it, `lit`).
    fn pass_of<'a>(&self, session: &'a Session, frame: Frame) -> Pass<'a> {
        let tree = match frame.flags & FLAG_LIGHT_TREE != 0 {
            true => FEATURE_LIGHT_TREE,
            false => 0,
        };
        // Mip levels only where there are textures: an untextured scene keeps its pipelines.
        let lod = match self.scene.textured {
            true => FEATURE_TEXTURE_LOD,
            false => 0,
        };
        Pass {
            frame,
            features: self.scene.features | (session.features & (lod | !FEATURE_TEXTURE_LOD)) | tree,
            variant: self.scene_variant(),
            survey: session.aovs.is_some() || session.debug.is_some(),
            counters: &session.counters,
        }
    }

    /// Runs one pass and adds it to `stats`; a fall-back to the wavefront becomes a warning.
    fn run_pass(&mut self, pass: &Pass, stats: &mut RenderStats) -> Result<(), Error> {
        let report = self.integrator.run(&self.ctx, &mut self.kernels, pass);
        if report.fell_back {
            self.warnings.push(FUSED_FALLBACK.into());
        }
        stats.add_pass(&report.outcome?, pass.frame.path_count);
        Ok(())
    }

    /// One pass of `advance`, adaptive or not. Once adaptive sampling has planned, a pass covers only the pixels
    /// that take its first sample, in the order of their budgets (FLAG_PIXEL_ORDER).
    fn advance_pass(&mut self, session: &mut Session, samples: u32) -> Result<u32, Error> {
        self.bind(&session.bindings(), session.texel_views());
        let capacity = session.capacity;
        let mut frame = session.frame;
        frame.sample_index = session.settings.first_sample + session.done;
        let pixels = match &session.planned {
            Some(p) => {
                frame.flags |= FLAG_PIXEL_ORDER;
                // A pass covers one pixel at least (which then may take no sample).
                p.active(frame.sample_index).max(1) as u64
            }
            None => session.pixels,
        };
        let mut size = size_pass(pixels, capacity, self.integrator.schedule(), samples);
        if self.integrator.in_trial() && self.integrator.schedule() == Schedule::Fused && size.chunks == 1 {
            let fit = size_pass(pixels, capacity, Schedule::Wavefront, u32::MAX).rows;
            size.rows = size.rows.min(ScheduleChoice::trial_rows(fit));
        }
        let mut stats = std::mem::take(&mut session.stats);
        for i in 0..size.chunks {
            let slice = size.slice(pixels, i);
            frame.pixel_offset = slice.pixel_offset;
            frame.pass_pixels = slice.pass_pixels;
            frame.path_count = slice.path_count;
            let pass = self.pass_of(session, frame);
            if let Err(e) = self.run_pass(&pass, &mut stats) {
                session.stats = stats;
                return Err(e);
            }
        }
        session.stats = stats;
        let added = size.rows;
        session.done += added;
        self.check_validation()?;
        Ok(added)
    }

    /// The session's film so far (running sums over `done` samples per pixel).
    pub fn film(&self, session: &Session) -> Result<Film, Error> {
        let s = &session.settings;
        let pixels = session.pixels as usize;
        // An adaptive render that took every sample its budgets allow holds its whole range: the samples past the
        // budgets are ones no pixel takes.
        let done = match s.adaptive.is_some() && session.done == session.target() {
            true => s.spp,
            false => session.done,
        };
        let samples = s.first_sample..s.first_sample + done;
        let aovs = match &session.aovs {
            Some(buffer) => {
                let sums: Vec<AovSums> = buffer.download(&self.ctx)?;
                let debug = match &session.debug {
                    Some(d) => Some(d.download::<DebugSums>(&self.ctx)?[..pixels].to_vec()),
                    None => None,
                };
                Some(Aovs {
                    sums: sums[..pixels].to_vec(),
                    debug,
                })
            }
            None => None,
        };
        if s.exact_film {
            let words: Vec<u32> = session.film.download(&self.ctx)?;
            self.check_validation()?;
            let exact = ExactFilm::from_words(&words[..pixels * EXACT_FILM_TEXELS as usize * 4], samples)?;
            return Ok(Film {
                aovs,
                ..Film::from_exact(s.width, s.height, exact)
            });
        }
        let raw: Vec<[f32; 4]> = session.film.download(&self.ctx)?;
        self.check_validation()?;
        let (sum, sum_sq) = raw.split_at(pixels);
        Ok(Film {
            width: s.width,
            height: s.height,
            spp: done,
            sum: sum.to_vec(),
            sum_sq: sum_sq[..pixels].to_vec(),
            exact: None,
            aovs,
        })
    }

    /// The light selection a render with these settings runs: the tree falls back to power where the scene has
    /// fewer than two emitters for it (where both pick alike); None without lights.
    pub fn light_sampler_run(&self, s: &RenderSettings) -> Option<&'static str> {
        let flags = self
            .lit(Frame {
                flags: s.light_sampler.flags(),
                ..Frame::default()
            })
            .flags;
        (self.scene.light_count > 0).then_some(if flags & FLAG_LIGHT_TREE != 0 {
            "bvh"
        } else if flags & FLAG_LIGHT_UNIFORM != 0 {
            "uniform"
        } else {
            "power"
        })
    }

    /// The push constants of a render with `s` from the renderer's camera and scene.
    pub(super) fn frame(&self, s: &RenderSettings) -> Frame {
        let (right, up, forward) = self.camera.basis();
        let camera = FrameCamera {
            origin: self.camera.origin(),
            right,
            up,
            forward,
            half_height: self.camera.projection.half_height(),
            aspect: s.width as f32 / s.height as f32,
            aperture: s.aperture,
            focus_distance: s.focus_distance.unwrap_or(self.default_focus),
        };
        let flag = |on: bool, bit: u32| if on { bit } else { 0 };
        self.lit(Frame {
            width: s.width,
            height: s.height,
            seed: s.seed,
            // The cap applies to unbounded paths only; an explicit depth is taken as given.
            max_depth: s.max_depth.unwrap_or(match self.scene.features & FEATURE_MEDIA {
                0 => DEPTH_SAFETY_CAP,
                _ => MEDIA_DEPTH_CAP,
            }),
            flags: s.estimator.code() << ESTIMATOR_SHIFT
                | flag(s.energy_compensation, FLAG_ENERGY_COMPENSATION)
                | flag(s.hide_environment, FLAG_HIDE_ENV)
                | flag(self.scene.vertex_colors, FLAG_VERTEX_COLORS)
                | flag(
                    self.scene.camera_moves && self.scene_camera == Some(self.camera),
                    FLAG_CAMERA_MOTION,
                )
                | flag(self.camera.projection.is_orthographic(), FLAG_ORTHOGRAPHIC)
                | flag(s.debug_aovs, FLAG_DEBUG_AOVS)
                | s.light_sampler.flags(),
            ..Frame::default()
        })
        .with_camera(&camera)
    }
}

/// The film's bytes for `s`, refused when one storage buffer cannot hold them (or the exact film's texels outgrow
/// u32).
fn film_bytes(s: &RenderSettings, range: u64) -> Result<u64, Error> {
    let pixels = s.width as u64 * s.height as u64;
    let film_bytes = pixels * film_bytes_per_pixel(s) as u64;
    if film_bytes > range || pixels > u32::MAX as u64 / EXACT_FILM_TEXELS as u64 {
        let exact = match s.exact_film {
            true => " (an exact film, for film statistics, takes 112 bytes a pixel)",
            false => "",
        };
        return Err(Error::Settings(format!(
            "{}x{} needs a {film_bytes}-byte film but this device's storage buffers hold at most {range} bytes{exact}",
            s.width, s.height
        )));
    }
    Ok(film_bytes)
}

/// The path state for `capacity` paths, its texel view, and the queues.
fn path_state(ctx: &crate::vk::Context, capacity: u32, fields: u32) -> Result<(Buffer, TexelViews, Buffer), Error> {
    let storage = vk::BufferUsageFlags::STORAGE_BUFFER;
    let per_path = fields as u64 * 16;
    let paths = Buffer::new(
        ctx,
        "path state",
        capacity as u64 * per_path,
        storage | vk::BufferUsageFlags::UNIFORM_TEXEL_BUFFER,
        MemoryLocation::GpuOnly,
    )?;
    let path_views = TexelViews::new(ctx, &[(BINDING_PATH_TEXELS, &paths, vk::Format::R32G32B32A32_SFLOAT)])?;
    let queue_bytes = capacity as u64 * 4 * QUEUE_COUNT as u64;
    let queues = Buffer::new(ctx, "queues", queue_bytes, storage, MemoryLocation::GpuOnly)?;
    Ok((paths, path_views, queues))
}

/// Film bytes a pixel takes: the float film's sum and sum of squares, or the exact film's texels.
fn film_bytes_per_pixel(s: &RenderSettings) -> u32 {
    match s.exact_film {
        true => EXACT_FILM_TEXELS * 16,
        false => FILM_BYTES_PER_PIXEL,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A pass from sample s covers the buckets whose largest budget is above s: those pixels still take samples.
    #[test]
    fn planned_passes_cover_the_buckets_still_sampling() {
        let p = Planned {
            end: 40,
            counts: vec![3, 5, 7],
            largest: vec![40, 20, 10],
        };
        assert_eq!(p.active(0), 15);
        assert_eq!(p.active(10), 8);
        assert_eq!(p.active(19), 8);
        assert_eq!(p.active(20), 3);
        assert_eq!(p.active(40), 0);
    }
}
