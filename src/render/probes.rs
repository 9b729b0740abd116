//! The probe kernels: device functions (traversal, the BSDF, environment and light sampling, the sampler) run on
//! records from Rust, the tests' window onto the GLSL; and `run_kernel`, which runs any kernel outside a pass.
use super::kernels::{Kernel, SceneVariant, Stage};
use super::{BvhReads, LightSampler, Renderer};
use crate::bvh::{Ray, TraceHit};
use crate::constants::*;
use crate::error::Error;
use crate::layout::{BsdfRecord, EnvRecord, Frame, LightSelectRecord, PhaseRecord, TraceRecord};
use crate::vk::Buffer;
use ash::vk;
use gpu_allocator::MemoryLocation;
use std::time::{Duration, Instant};

/// One BSDF query for `Renderer::probe_bsdf`, in the shading frame (z = normal).
#[derive(Clone, Copy, Debug)]
pub struct BsdfQuery {
    pub material: u32,
    pub wo: glam::Vec3,
    /// Three uniforms in [0, 1) when sampling; the direction wi when evaluating.
    pub x: glam::Vec3,
    /// wo is outside the object (its front face); inside, the relative IOR inverts.
    pub front: bool,
}

/// What the device BSDF answered for one query.
#[derive(Clone, Copy, Debug, Default)]
pub struct BsdfProbe {
    pub wi: glam::Vec3,
    /// f cos / pdf of the sample.
    pub weight: glam::Vec3,
    pub pdf: f32,
    pub delta: bool,
    /// Sampling produced a direction (false: absorbed or below the horizon).
    pub ok: bool,
    /// f(wo, wi), pdf(wo, wi) and f(wi, wo) evaluated at the returned or given direction.
    pub eval: glam::Vec3,
    pub pdf_wi: f32,
    pub eval_reverse: glam::Vec3,
}

impl Renderer {
    /// Runs the device traversal on `rays` (closest or any hit): the BVH tests' window onto traverse.glsl. Every
    /// triangle is opaque to it (see `probe_trace_alpha`).
    pub fn probe_trace(&mut self, rays: &[Ray], any_hit: bool) -> Result<Vec<TraceHit>, Error> {
        self.probe_trace_at(rays, any_hit, 0.0)
    }

    /// `probe_trace` at `time` in the shutter, in [0, 1) (moving scenes: the triangles between their keys).
    pub fn probe_trace_at(&mut self, rays: &[Ray], any_hit: bool, time: f32) -> Result<Vec<TraceHit>, Error> {
        Ok(self.trace_records(rays, any_hit, time, 1, false)?.0)
    }

    /// `probe_trace` with alpha-tested triangles (alphaMode MASK and BLEND) tested as extend and connect test them:
    /// ray i's key for stochastic transparency is i, and the frame's seed 0.
    pub fn probe_trace_alpha(&mut self, rays: &[Ray], any_hit: bool) -> Result<Vec<TraceHit>, Error> {
        Ok(self.trace_records(rays, any_hit, 0.0, 1, true)?.0)
    }

    /// Traces `rays` `repeats` times after one upload; returns the hits and each dispatch's wall time. The bench's
    /// traversal figure: the same kernel the tests check, with nothing of the wavefront around it.
    pub fn trace_timed(
        &mut self,
        rays: &[Ray],
        any_hit: bool,
        repeats: u32,
    ) -> Result<(Vec<TraceHit>, Vec<Duration>), Error> {
        self.trace_records(rays, any_hit, 0.0, repeats, false)
    }

    fn trace_records(
        &mut self,
        rays: &[Ray],
        any_hit: bool,
        time: f32,
        repeats: u32,
        alpha: bool,
    ) -> Result<(Vec<TraceHit>, Vec<Duration>), Error> {
        let records: Vec<TraceRecord> = rays
            .iter()
            .enumerate()
            .map(|(i, r)| TraceRecord {
                origin: r.origin.to_array(),
                tmin: r.tmin,
                dir: r.dir.to_array(),
                tmax: r.tmax,
                time,
                key: i as u32,
                ..Default::default()
            })
            .collect();
        let kernel = Kernel::for_scene(
            Stage::ProbeTrace,
            SceneVariant {
                alpha: alpha && self.scene.alpha_tested,
                texel: self.bvh_reads == BvhReads::Texel,
                ray_query: self.scene.accel.is_some(),
                ..Default::default()
            },
        );
        let mode = if any_hit { PROBE_ANY_HIT } else { PROBE_SAMPLE };
        let (out, times) = self.run_probe(kernel, &records, Frame::probe(rays.len() as u32, mode), repeats)?;
        let hits = out
            .iter()
            .map(|r| TraceHit {
                t: r.t,
                tri: r.tri,
                uv: glam::Vec2::from(r.uv),
                inst: r.inst,
            })
            .collect();
        Ok((hits, times))
    }

    /// The light shade would pick for each of `n` samples (first bounce, sample index `sample`).
    pub fn probe_light_pick(&mut self, n: u32, sample: u32, seed: u32) -> Result<Vec<u32>, Error> {
        let frame = Frame {
            sample_index: sample,
            seed,
            ..Frame::probe(n, PROBE_SAMPLE)
        };
        let (out, _) = self.run_probe(Kernel::of(Stage::ProbeLightPick), &vec![0u32; n as usize], frame, 1)?;
        Ok(out)
    }

    /// Light selection on the device at each record's point, normal and uniforms, and the pmf of its `entry`, with the
    /// light sampler `sampler` (records in, answered records out).
    pub fn probe_light_select(
        &mut self,
        records: &[LightSelectRecord],
        sampler: LightSampler,
    ) -> Result<Vec<LightSelectRecord>, Error> {
        let frame = Frame {
            flags: sampler.flags(),
            ..Frame::probe(records.len() as u32, PROBE_SAMPLE)
        };
        let (out, _) = self.run_probe(Kernel::of(Stage::ProbeLightSelect), records, frame, 1)?;
        Ok(out)
    }

    /// The sampler's uniforms (as 24-bit integers) at `bounce` and dimension `dim` (see rand2 in rng.glsl) for
    /// every pixel of `pixels` and sample of `samples`, pixel-minor as paths are numbered.
    pub fn probe_rand(
        &mut self,
        pixels: std::ops::Range<u32>,
        samples: std::ops::Range<u32>,
        (bounce, dim): (u32, u32),
        seed: u32,
    ) -> Result<Vec<[u32; 2]>, Error> {
        let n = pixels.len() as u32 * samples.len() as u32;
        // probe_mode() is the bounce and probe_dimension() the dimension (layout.glsl).
        let frame = Frame {
            pass_pixels: pixels.len() as u32,
            pixel_offset: pixels.start,
            sample_index: samples.start,
            max_depth: dim,
            seed,
            ..Frame::probe(n, bounce)
        };
        let (out, _) = self.run_probe(Kernel::of(Stage::ProbeRand), &vec![[0u32; 2]; n as usize], frame, 1)?;
        Ok(out)
    }

    /// Runs the device BSDF on `queries`: sampling (x = three uniforms) or evaluation (x = wi).
    pub fn probe_bsdf(
        &mut self,
        queries: &[BsdfQuery],
        evaluate: bool,
        energy_compensation: bool,
    ) -> Result<Vec<BsdfProbe>, Error> {
        let records: Vec<BsdfRecord> = queries
            .iter()
            .map(|q| BsdfRecord {
                wo: q.wo.to_array(),
                material: q.material,
                x: q.x.to_array(),
                front: q.front as u32,
                ..Default::default()
            })
            .collect();
        let mode = if evaluate { PROBE_EVALUATE } else { PROBE_SAMPLE };
        let frame = Frame {
            flags: if energy_compensation {
                FLAG_ENERGY_COMPENSATION
            } else {
                0
            },
            ..Frame::probe(queries.len() as u32, mode)
        };
        let (out, _) = self.run_probe(Kernel::of(Stage::ProbeBsdf), &records, frame, 1)?;
        Ok(out
            .iter()
            .map(|r| BsdfProbe {
                wi: r.wi.into(),
                weight: r.weight.into(),
                pdf: r.pdf,
                delta: r.flags & PROBE_DELTA != 0,
                ok: r.flags & PROBE_OK != 0,
                eval: r.eval.into(),
                pdf_wi: r.pdf_wi,
                eval_reverse: r.eval_reverse.into(),
            })
            .collect())
    }

    /// Runs environment sampling on the device: `x` holds uniforms (sampling) or directions (`evaluate`).
    /// Returns (direction, pdf from sampling, pdf of the direction, radiance) per query.
    pub fn probe_env(
        &mut self,
        x: &[glam::Vec3],
        evaluate: bool,
    ) -> Result<Vec<(glam::Vec3, f32, f32, glam::Vec3)>, Error> {
        let records: Vec<EnvRecord> = x
            .iter()
            .map(|v| EnvRecord {
                x: v.to_array(),
                ..Default::default()
            })
            .collect();
        let mode = if evaluate { PROBE_EVALUATE } else { PROBE_SAMPLE };
        let frame = Frame::probe(x.len() as u32, mode);
        let (out, _) = self.run_probe(Kernel::of(Stage::ProbeEnv), &records, frame, 1)?;
        Ok(out
            .iter()
            .map(|r| (r.dir.into(), r.pdf, r.pdf_dir, r.radiance.into()))
            .collect())
    }

    /// Runs Henyey-Greenstein's phase function on the device (media.glsl) about `d_in` with anisotropy `g`: from `x`'s
    /// uniforms (xy) it samples a direction, or with `evaluate` it takes x as the direction. Returns per query the
    /// direction and the phase function's value there (which is sampling's pdf).
    pub fn probe_phase(
        &mut self,
        d_in: glam::Vec3,
        g: f32,
        x: &[glam::Vec3],
        evaluate: bool,
    ) -> Result<Vec<(glam::Vec3, f32)>, Error> {
        let records: Vec<PhaseRecord> = x
            .iter()
            .map(|x| PhaseRecord {
                d_in: d_in.to_array(),
                g,
                x: x.to_array(),
                ..Default::default()
            })
            .collect();
        let mode = if evaluate { PROBE_EVALUATE } else { PROBE_SAMPLE };
        let frame = Frame::probe(x.len() as u32, mode);
        let (out, _) = self.run_probe(Kernel::of(Stage::ProbePhase), &records, frame, 1)?;
        Ok(out.iter().map(|r| (r.wi.into(), r.pdf)).collect())
    }

    /// Every shared constant as the device's GLSL computes it, in crate::shaders::SHARED_CONSTANTS order.
    pub fn probe_constants(&mut self) -> Result<Vec<u32>, Error> {
        let n = crate::shaders::SHARED_CONSTANTS.len();
        let frame = Frame::probe(1, PROBE_SAMPLE);
        let (out, _) = self.run_probe(Kernel::of(Stage::ProbeConstants), &vec![0u32; n], frame, 1)?;
        Ok(out)
    }

    /// Runs `kernel` `repeats` times over a probe buffer holding `records`; returns them as the kernel left them
    /// and each run's time.
    fn run_probe<T: bytemuck::Pod>(
        &mut self,
        kernel: Kernel,
        records: &[T],
        frame: Frame,
        repeats: u32,
    ) -> Result<(Vec<T>, Vec<Duration>), Error> {
        let mut probe = Buffer::new(
            &self.ctx,
            "probe",
            std::mem::size_of_val(records) as u64,
            vk::BufferUsageFlags::STORAGE_BUFFER,
            MemoryLocation::CpuToGpu,
        )?;
        probe.upload(&self.ctx, bytemuck::cast_slice(records))?;
        let times = self.run_kernel(kernel, &[(BINDING_PROBE, &probe)], frame, repeats)?;
        let mut out: Vec<T> = probe.download(&self.ctx)?;
        // The buffer may be larger than asked (an empty one is 16 bytes).
        out.truncate(records.len());
        Ok((out, times))
    }

    /// Runs one kernel `repeats` times over `frame.path_count` invocations with the scene and `extra` bindings bound
    /// (stand-ins elsewhere); fails on any validation error, else returns each submission's wall time.
    pub(super) fn run_kernel(
        &mut self,
        kernel: Kernel,
        extra: &[(u32, &Buffer)],
        frame: Frame,
        repeats: u32,
    ) -> Result<Vec<Duration>, Error> {
        self.bind(extra, &[]);
        let frame = self.lit(frame);
        let k = self.kernels.get(&self.ctx, kernel)?;
        let n = frame.path_count;
        let (ctx, kernels) = (&self.ctx, &self.kernels);
        let mut times = Vec::with_capacity(repeats as usize);
        for _ in 0..repeats.max(1) {
            let start = Instant::now();
            ctx.submit_and_wait(|cmd| kernels.dispatch(cmd, k, &frame, n.div_ceil(WORKGROUP_SIZE)))?;
            times.push(start.elapsed());
        }
        self.check_validation()?;
        Ok(times)
    }
}
