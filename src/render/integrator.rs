//! The integrator: how one pass takes its paths through the stages. `Integrator::run` reads like the algorithm:
//! begin (clear the tallies, generate camera rays), the bounces (extend, shade, connect), end (accumulate, survey),
//! on the schedule it keeps (the wavefront, or the fused `follow`), backing off when lavapipe's loop budget cuts a
//! fused dispatch short. The wavefront's bounces go to the device in batches, so a deep `--max-depth` costs no host
//! memory.
use super::kernels::{Built, FusedKernels, Kernels, SceneVariant, WavefrontKernels};
use super::schedule::{FollowRows, Schedule, ScheduleChoice};
use super::session::Planned;
use super::sizing::wavefront_rows;
use super::Adaptive;
use crate::constants::*;
use crate::error::Error;
use crate::layout::{Counters, Frame, COUNTERS_DISPATCH_OFFSET};
use crate::vk::{add_labelled, Buffer, Context, Timestamps};
use ash::vk;
use std::time::{Duration, Instant};

/// Bounces recorded into one submission. A command buffer's host memory grows with what it holds, so a pass records
/// its bounces in batches of this many and, between batches, reads whether any path is left (a tiny download).
pub const BOUNCES_PER_SUBMISSION: usize = 16;

/// Records one pass's dispatches into a command buffer, each timed under its stage's name and followed by a barrier.
struct Recorder<'a> {
    ctx: &'a Context,
    kernels: &'a Kernels,
    ts: &'a mut Timestamps,
    counters: &'a Buffer,
    cmd: vk::CommandBuffer,
}

impl Recorder<'_> {
    fn run(&mut self, k: Built, frame: &Frame, invocations: u32) {
        let (kernels, cmd) = (self.kernels, self.cmd);
        let groups = invocations.div_ceil(WORKGROUP_SIZE);
        self.ts
            .time(cmd, k.stage.name(), || kernels.dispatch(cmd, k, frame, groups));
        self.ctx.barrier(cmd);
    }

    /// Sized by the queue counters queue_args turned into dispatch arguments.
    fn run_queued(&mut self, k: Built, frame: &Frame) {
        let (kernels, cmd, counters) = (self.kernels, self.cmd, self.counters);
        self.ts.time(cmd, k.stage.name(), || {
            kernels.dispatch_indirect(cmd, k, frame, counters, COUNTERS_DISPATCH_OFFSET)
        });
        self.ctx.barrier(cmd);
    }

    fn clear_counters(&mut self) {
        unsafe {
            self.ctx
                .device
                .cmd_fill_buffer(self.cmd, self.counters.raw, 0, vk::WHOLE_SIZE, 0)
        };
        self.ctx.barrier(self.cmd);
    }

    /// Camera rays for every path of the pass, into queue 0.
    fn generate(&mut self, k: &WavefrontKernels, frame: &Frame) {
        self.run(k.generate, frame, frame.path_count);
    }

    /// Turns the queue counters into the dispatch arguments of the bounce's stages.
    fn queue_args(&mut self, k: &WavefrontKernels, frame: &Frame) {
        self.run(k.queue_args, frame, 1);
    }

    /// Closest hits of the queued rays.
    fn extend(&mut self, k: &WavefrontKernels, frame: &Frame) {
        self.run_queued(k.extend, frame);
    }

    /// Emission, next-event estimation (a shadow ray) and the BSDF sample that continues each path.
    fn shade(&mut self, k: &WavefrontKernels, frame: &Frame) {
        self.run_queued(k.shade, frame);
    }

    /// Shade queues at most one shadow ray per path, so the extension dispatch size bounds connect's.
    fn connect(&mut self, k: &WavefrontKernels, frame: &Frame) {
        self.run_queued(k.connect, frame);
    }

    /// One bounce of every queued path: `frame` is `at_bounce` the bounce.
    fn bounce(&mut self, k: &WavefrontKernels, frame: &Frame) {
        self.queue_args(k, frame);
        self.extend(k, frame);
        self.shade(k, frame);
        self.connect(k, frame);
    }

    /// `rows` sample rows from `first_row`, each invocation one pixel's samples from camera to end.
    fn follow(&mut self, k: &FusedKernels, frame: &Frame, first_row: u32, rows: u32) {
        let f = frame.follow_rows(first_row, first_row + rows);
        self.run(k.follow, &f, frame.pass_pixels);
    }

    /// Adds the pass's samples to the film (or copies follow's running sums).
    fn accumulate(&mut self, k: Built, frame: &Frame) {
        self.run(k, frame, frame.pass_pixels);
    }

    /// The AOVs of every sample of the pass, a sample row per dispatch so they add in sample order.
    fn survey(&mut self, k: Option<Built>, frame: &Frame) {
        let Some(k) = k else { return };
        for row in 0..frame.path_count / frame.pass_pixels {
            self.run(k, &frame.survey_row(row), frame.pass_pixels);
        }
    }
}

/// What the facade warns of when the integrator fell back to the wavefront.
pub(super) const FUSED_FALLBACK: &str =
    "the fused schedule ran past lavapipe's loop budget on this scene; using the wavefront";

/// The pass machinery's state: the schedule it runs (and, on CPU devices, the trial that picks it), the rows a follow
/// dispatch takes, and the stage timestamps.
pub(super) struct Integrator {
    timestamps: Timestamps,
    schedule: ScheduleChoice,
    follow: FollowRows,
}

/// One pass as the facade sizes it.
pub(super) struct Pass<'a> {
    /// The session's frame with this pass's pixels, paths and first sample.
    pub frame: Frame,
    /// The FEATURE_* bits the stages are specialised for.
    pub features: u32,
    pub variant: SceneVariant,
    /// Whether survey adds the pass's AOVs (the session keeps AOV or debug-view sums).
    pub survey: bool,
    pub counters: &'a Buffer,
}

/// What a pass did. `fell_back` is kept apart from the outcome: it holds even when the wavefront's rerun failed.
pub(super) struct PassReport {
    /// The fused schedule was cut short at the fewest rows and the pass ran again as a wavefront, which the
    /// integrator now keeps.
    pub fell_back: bool,
    pub outcome: Result<PassDone, Error>,
}

pub(super) struct PassDone {
    pub tally: Counters,
    /// GPU time per stage, in ns (empty on devices without timestamps).
    pub times: Vec<(&'static str, f64)>,
    /// The pass's wall time, compilation included.
    pub wall: Duration,
}

impl Integrator {
    pub fn new(ctx: &Context, schedule: ScheduleChoice) -> Result<Self, Error> {
        Ok(Integrator {
            timestamps: Timestamps::new(ctx, 2048)?,
            schedule,
            follow: FollowRows::default(),
        })
    }

    /// How the next pass takes paths through the stages.
    pub fn schedule(&self) -> Schedule {
        self.schedule.current()
    }

    /// Whether the next pass is one of the schedule trial's (ScheduleChoice::trial_rows sizes them).
    pub fn in_trial(&self) -> bool {
        self.schedule.in_trial()
    }

    /// Sample rows the next follow dispatch takes (see FOLLOW_SAMPLES).
    pub fn follow_rows(&self) -> u32 {
        self.follow.rows
    }

    pub fn fix(&mut self, schedule: Schedule) {
        self.schedule = ScheduleChoice::Fixed(schedule);
    }

    /// One pass: `pass.frame.path_count` paths (pixels x samples), the whole path, every bounce.
    pub fn run(&mut self, ctx: &Context, kernels: &mut Kernels, pass: &Pass) -> PassReport {
        let mut fell_back = false;
        let outcome = self.try_run(ctx, kernels, pass, &mut fell_back);
        PassReport { fell_back, outcome }
    }

    fn try_run(
        &mut self,
        ctx: &Context,
        kernels: &mut Kernels,
        pass: &Pass,
        fell_back: &mut bool,
    ) -> Result<PassDone, Error> {
        let started = Instant::now();
        kernels.set_features(pass.features);
        let schedule = self.schedule.current();
        let mut times = Vec::new();
        let mut tally = self.attempt(ctx, kernels, pass, &pass.frame, schedule, &mut times)?;
        while tally.follow_cut != 0 {
            times.clear();
            tally = self.back_off(ctx, kernels, pass, &mut times, fell_back)?;
        }
        if tally.stage_cut != 0 {
            return Err(Error::Shader(format!(
                "{} invocations of the wavefront stages ran past lavapipe's loop budget (65535 loop iterations per \
                 invocation), which cuts every loop short silently: an endless or very long loop in a stage, and the \
                 image would be wrong",
                tally.stage_cut
            )));
        }
        if schedule == Schedule::Fused && self.schedule.current() == Schedule::Fused {
            self.follow.after_fused_pass();
        }
        // Without timestamps (some devices), the pass's wall time, which also holds the tally's download.
        let gpu_ns: f64 = times.iter().map(|(_, ns)| ns).sum();
        let ns = match gpu_ns > 0.0 {
            true => gpu_ns,
            false => started.elapsed().as_nanos() as f64,
        };
        self.schedule.record(ns, pass.frame.path_count);
        Ok(PassDone {
            tally,
            times,
            wall: started.elapsed(),
        })
    }

    /// lavapipe cut follow's loops short (follow.comp), and accumulate skipped the pass. With fewer rows per dispatch
    /// the pass runs fused again, and never with as many again; at the fewest, it runs again as a wavefront, whose
    /// invocations each trace one ray (in as many passes as the path state needs), and the integrator keeps it.
    fn back_off(
        &mut self,
        ctx: &Context,
        kernels: &mut Kernels,
        pass: &Pass,
        times: &mut Vec<(&'static str, f64)>,
        fell_back: &mut bool,
    ) -> Result<Counters, Error> {
        let frame = &pass.frame;
        let taken = self.follow.rows.min(frame.path_count / frame.pass_pixels.max(1));
        if self.follow.after_cut(taken).is_some() {
            return self.attempt(ctx, kernels, pass, frame, Schedule::Fused, times);
        }
        *fell_back = true;
        self.fix(Schedule::Wavefront);
        let mut total = Counters::default();
        for (first, rows) in wavefront_rows(frame.path_count, frame.pass_pixels, frame.path_capacity) {
            let f = Frame {
                sample_index: frame.sample_index + first,
                path_count: rows * frame.pass_pixels,
                ..*frame
            };
            let t = self.attempt(ctx, kernels, pass, &f, Schedule::Wavefront, times)?;
            // The device's tallies are u32 and wrap; so do these.
            total.extension_rays = total.extension_rays.wrapping_add(t.extension_rays);
            total.shadow_rays = total.shadow_rays.wrapping_add(t.shadow_rays);
            total.nonfinite = total.nonfinite.wrapping_add(t.nonfinite);
            total.stage_cut = total.stage_cut.wrapping_add(t.stage_cut);
        }
        Ok(total)
    }

    /// `frame`'s paths on `schedule`, then the pass's tallies; its GPU stage times are added to `times`.
    fn attempt(
        &mut self,
        ctx: &Context,
        kernels: &mut Kernels,
        pass: &Pass,
        frame: &Frame,
        schedule: Schedule,
        times: &mut Vec<(&'static str, f64)>,
    ) -> Result<Counters, Error> {
        match schedule {
            Schedule::Wavefront => self.wavefront(ctx, kernels, pass, frame)?,
            Schedule::Fused => self.fused(ctx, kernels, pass, frame)?,
        }
        let tally: Counters = pass.counters.download(ctx)?[0];
        for (label, ns) in self.timestamps.read()? {
            add_labelled(times, label, ns);
        }
        Ok(tally)
    }

    /// The wavefront: generate, the bounces in batches that end once no path is left, then the end of the pass.
    fn wavefront(&mut self, ctx: &Context, kernels: &mut Kernels, pass: &Pass, frame: &Frame) -> Result<(), Error> {
        let survey = pass.survey.then(|| kernels.survey(ctx, pass.variant)).transpose()?;
        let k = kernels.wavefront(ctx, pass.variant)?;
        let mut bounces = 0..=frame.max_depth;
        let (mut begins, mut paths_left) = (true, true);
        loop {
            // With no path queued, every bounce left would dispatch nothing: only the end of the pass remains.
            let batch: Vec<u32> = match paths_left {
                true => bounces.by_ref().take(BOUNCES_PER_SUBMISSION).collect(),
                false => Vec::new(),
            };
            let ends = !paths_left || bounces.is_empty();
            record(ctx, kernels, &mut self.timestamps, pass.counters, begins, |rec| {
                if begins {
                    rec.generate(&k, frame);
                }
                for &bounce in &batch {
                    rec.bounce(&k, &frame.at_bounce(bounce));
                }
                if ends {
                    // After the last bounce only the shadow-ray tally remains (queue_args.comp).
                    rec.queue_args(&k, &frame.after_last_bounce());
                    rec.accumulate(k.accumulate, frame);
                    rec.survey(survey, frame);
                }
            })?;
            if ends {
                return Ok(());
            }
            begins = false;
            paths_left = queued_rays(ctx, pass.counters, *bounces.start())? > 0;
        }
    }

    /// The fused schedule in one submission: follow dispatches of `follow.rows` sample rows, then the end of the pass.
    fn fused(&mut self, ctx: &Context, kernels: &mut Kernels, pass: &Pass, frame: &Frame) -> Result<(), Error> {
        let survey = pass.survey.then(|| kernels.survey(ctx, pass.variant)).transpose()?;
        let k = kernels.fused(ctx, pass.variant)?;
        let follow_rows = self.follow.rows;
        record(ctx, kernels, &mut self.timestamps, pass.counters, true, |rec| {
            // Each invocation keeps its pixel's running film sums itself (FLAG_FUSED_SUMS).
            let f = frame.with_fused_sums();
            let rows = frame.path_count / frame.pass_pixels;
            for first in (0..rows).step_by(follow_rows as usize) {
                rec.follow(&k, &f, first, follow_rows.min(rows - first));
            }
            rec.accumulate(k.accumulate, &f);
            rec.survey(survey, frame);
        })
    }

    /// Adaptive sampling's budgets from the film, which holds exactly `a.pilot` samples of every pixel (`pass.frame`
    /// is the session's): each pixel's from its neighbours' (plan.comp), then the pixels ranked by them into the
    /// budget buffer's order.
    pub fn plan(
        &mut self,
        ctx: &Context,
        kernels: &mut Kernels,
        pass: &Pass,
        budget: &Buffer,
        a: Adaptive,
        end: u32,
    ) -> Result<Planned, Error> {
        kernels.set_features(pass.features);
        let k = kernels.plan(ctx)?;
        let f = pass.frame.plan(a.pilot, a.threshold, end);
        let pixels = f.width * f.height;
        let rank = Frame {
            flags: f.flags | FLAG_PIXEL_ORDER,
            ..f
        };
        record(ctx, kernels, &mut self.timestamps, pass.counters, true, |rec| {
            // The buckets' counts, cursors and largest budgets start at zero.
            let (offset, size) = (2 * pixels as u64 * 4, 3 * ORDER_BUCKETS as u64 * 4);
            unsafe { ctx.device.cmd_fill_buffer(rec.cmd, budget.raw, offset, size, 0) };
            ctx.barrier(rec.cmd);
            rec.run(k, &f, pixels);
            rec.run(k, &rank, pixels);
        })?;
        let c: Counters = pass.counters.download(ctx)?[0];
        let words: Vec<u32> = budget.download(ctx)?;
        let (at, n) = (2 * pixels as usize, ORDER_BUCKETS as usize);
        Ok(Planned {
            end: c.budget_max,
            counts: words[at..at + n].to_vec(),
            largest: words[at + 2 * n..at + 3 * n].to_vec(),
        })
    }
}

/// Records (part of) a pass into one submission and waits for it. The submission that `begins` the pass clears the
/// counters and resets the timestamps; later ones keep both, so the pass's tallies and stage times add up.
fn record(
    ctx: &Context,
    kernels: &Kernels,
    ts: &mut Timestamps,
    counters: &Buffer,
    begins: bool,
    body: impl FnOnce(&mut Recorder),
) -> Result<(), Error> {
    ctx.submit_and_wait(|cmd| {
        if begins {
            ts.reset(cmd);
        }
        let mut rec = Recorder {
            ctx,
            kernels,
            ts,
            counters,
            cmd,
        };
        if begins {
            rec.clear_counters();
        }
        body(&mut rec);
    })
}

/// Rays queued for `bounce`: the paths still alive when it begins.
fn queued_rays(ctx: &Context, counters: &Buffer, bounce: u32) -> Result<u32, Error> {
    let c: Counters = counters.download(ctx)?[0];
    Ok(c.queue_count[(bounce & 1) as usize])
}
