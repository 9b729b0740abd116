//! One pass of the integrator on the device: generate, then extend / shade / connect per bounce, then accumulate
//! (the wavefront), or follow then accumulate (fused). Each stage is a method; `pass` reads like the algorithm.
//! The wavefront's bounces go to the device in batches, so a deep `--max-depth` costs no host memory.
use super::kernels::{Built, FusedKernels, Kernels, WavefrontKernels};
use super::session::Planned;
use super::{Renderer, Schedule};
use crate::constants::*;
use crate::error::Error;
use crate::layout::{Counters, Frame, COUNTERS_DISPATCH_OFFSET};
use crate::vk::{Buffer, Context, Timestamps};
use ash::vk;

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

impl Renderer {
    /// The FEATURE_* bits the render stages are specialised for: the scene's, and the render settings' in `frame`.
    pub(super) fn render_features(&self, frame: &Frame) -> u32 {
        let lens = if frame.aperture() > 0.0 { FEATURE_LENS } else { 0 };
        let flag = |bit: u32, feature: u32| if frame.flags & bit != 0 { feature } else { 0 };
        let exact = flag(FLAG_EXACT_FILM, FEATURE_EXACT_FILM);
        let adaptive = flag(FLAG_ADAPTIVE, FEATURE_ADAPTIVE);
        let spectral = flag(FLAG_SPECTRAL, FEATURE_SPECTRAL);
        let tree = flag(FLAG_LIGHT_TREE, FEATURE_LIGHT_TREE);
        self.scene.features | lens | exact | adaptive | spectral | tree
    }

    /// Adaptive sampling's budgets from the film, which holds exactly `pilot` samples of every pixel: each pixel's
    /// from its neighbours' (plan.comp), then the pixels ranked by them into the budget buffer's order.
    pub(super) fn plan(
        &mut self,
        frame: &Frame,
        counters: &Buffer,
        budget: &Buffer,
        pilot: u32,
        threshold: f32,
        end: u32,
    ) -> Result<Planned, Error> {
        self.kernels.set_features(self.render_features(frame));
        let k = self.kernels.plan(&self.ctx)?;
        let f = frame.plan(pilot, threshold, end);
        let pixels = f.width * f.height;
        let rank = Frame {
            flags: f.flags | FLAG_PIXEL_ORDER,
            ..f
        };
        let Renderer {
            ctx,
            kernels,
            timestamps,
            ..
        } = self;
        record(ctx, kernels, timestamps, counters, true, |rec| {
            // The buckets' counts, cursors and largest budgets start at zero.
            let (offset, size) = (2 * pixels as u64 * 4, 3 * ORDER_BUCKETS as u64 * 4);
            unsafe { ctx.device.cmd_fill_buffer(rec.cmd, budget.raw, offset, size, 0) };
            ctx.barrier(rec.cmd);
            rec.run(k, &f, pixels);
            rec.run(k, &rank, pixels);
        })?;
        let c: Counters = counters.download(ctx)?[0];
        let words: Vec<u32> = budget.download(ctx)?;
        let (at, n) = (2 * pixels as usize, ORDER_BUCKETS as usize);
        Ok(Planned {
            end: c.budget_max,
            counts: words[at..at + n].to_vec(),
            largest: words[at + 2 * n..at + 3 * n].to_vec(),
        })
    }

    /// One pass: `frame.path_count` paths (pixels x samples), the whole path, every bounce: the fused schedule in one
    /// submission, the wavefront in batches of bounces that end once no path is left.
    pub(super) fn pass(&mut self, frame: &Frame, counters: &Buffer, schedule: Schedule) -> Result<(), Error> {
        self.kernels.set_features(self.render_features(frame));
        let variant = self.scene_variant();
        let follow_rows = self.follow.rows;
        let survey = match frame.flags & FLAG_AOVS != 0 {
            true => Some(self.kernels.survey(&self.ctx, variant)?),
            false => None,
        };
        let Renderer {
            ctx,
            kernels,
            timestamps,
            ..
        } = self;
        match schedule {
            Schedule::Wavefront => {
                let k = kernels.wavefront(ctx, variant)?;
                let mut bounces = 0..=frame.max_depth;
                let (mut begins, mut paths_left) = (true, true);
                loop {
                    // With no path queued, every bounce left would dispatch nothing: only the end of the pass remains.
                    let batch: Vec<u32> = match paths_left {
                        true => bounces.by_ref().take(BOUNCES_PER_SUBMISSION).collect(),
                        false => Vec::new(),
                    };
                    let ends = !paths_left || bounces.is_empty();
                    record(ctx, kernels, timestamps, counters, begins, |rec| {
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
                    paths_left = queued_rays(ctx, counters, *bounces.start())? > 0;
                }
            }
            Schedule::Fused => {
                let k = kernels.fused(ctx, variant)?;
                record(ctx, kernels, timestamps, counters, true, |rec| {
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
        }
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
