//! One case measured: a render in this process (its times, rates, stages and memory), or a whole process's time.
use super::{compare, BenchOptions};
use crate::error::Error;
use crate::render::{BvhReads, RenderSettings, RenderStats, Schedule, TextureFilter, Traversal};
use crate::scene::Scene;
use std::path::Path;
use std::process::Command;
use std::time::Instant;

/// One measured render.
#[derive(Clone, Debug, Default)]
pub struct CaseResult {
    pub name: String,
    pub device: String,
    pub triangles: usize,
    pub size: (u32, u32),
    pub spp: u32,
    /// The whole `pathwave render` process (load, device, shaders, render, write), when the case has a file.
    pub process_s: Option<f64>,
    /// Renderer::render inside this process.
    pub render_s: f64,
    /// The first pass, which includes the device compiling the pipelines.
    pub first_pass_s: f64,
    pub samples_per_s: f64,
    pub extension_rays_per_s: f64,
    pub shadow_rays_per_s: f64,
    /// Extension rays per second of GPU time in the extend stage alone: traversal speed inside the wavefront.
    pub extend_stage_rays_per_s: f64,
    pub stage_ms: Vec<(String, f64)>,
    /// Which schedule the timed passes ran ("wavefront", "fused", or "both" while a CPU device tries them): the
    /// stages in stage_ms depend on it.
    pub schedule: String,
    pub bvh_build_s: f64,
    /// Device bytes per placed triangle: BVH nodes, triangle vertices, shading data and instance records.
    pub bytes_per_triangle: f64,
    pub image_mean: f64,
    /// How rays found surfaces: "compute" (pathwave's BVH) or "ray queries".
    pub traversal: String,
    /// With ray queries: the structures' compacted bytes, their bytes before compaction, and their build's seconds.
    pub ray_query_structures: Option<(u64, u64, f64)>,
}

/// How a case departs from the default render: BVH reads, a fixed schedule, spectral transport, the traversal, the
/// texture filter.
#[derive(Clone, Copy, Default)]
pub(super) struct Variation {
    pub(super) reads: Option<BvhReads>,
    pub(super) schedule: Option<Schedule>,
    pub(super) spectral: bool,
    pub(super) traversal: Traversal,
    pub(super) texture_filter: TextureFilter,
}

pub(super) fn measure(
    name: &str,
    scene: &Scene,
    size: (u32, u32),
    spp: u32,
    o: &BenchOptions,
    variation: Variation,
) -> Result<CaseResult, Error> {
    let Variation {
        reads,
        schedule,
        spectral,
        traversal,
        texture_filter,
    } = variation;
    let mut r =
        compare::tracer(scene, &o.device, traversal).map_err(|e| Error::Settings(format!("bench: {name}: {e}")))?;
    let device_name = r.context().device_name();
    let bvh_build_s = r.bvh_build_time().as_secs_f64();
    let bytes = r.traversal_bytes();
    if let Some(reads) = reads {
        r.set_bvh_reads(reads)?;
    }
    if let Some(schedule) = schedule {
        r.set_schedule(schedule);
    }
    let settings = RenderSettings {
        width: size.0,
        height: size.1,
        spp,
        spectral,
        light_sampler: o.light_sampler,
        texture_filter,
        ..Default::default()
    };
    let (film, stats) = r.render(&settings, &mut |_| {})?;
    let mean = film.mean();
    let schedule = schedule_ran(&stats);
    Ok(CaseResult {
        name: name.into(),
        device: device_name,
        triangles: scene.flattened_triangle_bound() as usize,
        size,
        spp,
        process_s: None,
        render_s: stats.wall.as_secs_f64(),
        first_pass_s: stats.first_pass.as_secs_f64(),
        samples_per_s: stats.samples_per_sec(),
        extension_rays_per_s: stats.rays_per_sec_split().0,
        shadow_rays_per_s: stats.rays_per_sec_split().1,
        extend_stage_rays_per_s: extend_stage_rays_per_s(&stats, schedule),
        stage_ms: stats.stage_ms.iter().map(|(l, ms)| (l.to_string(), *ms)).collect(),
        schedule: schedule.into(),
        bvh_build_s,
        bytes_per_triangle: bytes as f64 / scene.flattened_triangle_bound().max(1) as f64,
        image_mean: mean.iter().map(|c| (c[0] + c[1] + c[2]) as f64 / 3.0).sum::<f64>() / mean.len().max(1) as f64,
        traversal: match r.traversal() {
            Traversal::RayQuery => "ray queries".into(),
            _ => "compute".into(),
        },
        ray_query_structures: r
            .acceleration_structures()
            .map(|(bytes, uncompacted, t)| (bytes, uncompacted, t.as_secs_f64())),
    })
}

/// What the timed passes ran: on a CPU device the default tries both schedules before it keeps one.
fn schedule_ran(stats: &RenderStats) -> &'static str {
    let ran = |stage: &str| stats.stage_ms.iter().any(|(l, _)| *l == stage);
    match (ran("follow"), ran("extend")) {
        (true, true) => "both",
        (true, false) => "fused",
        _ => "wavefront",
    }
}

/// Extension rays per second of the extend stage's GPU time. Only when every timed pass ran the wavefront (`schedule`):
/// fused passes trace extension rays outside any extend stage.
fn extend_stage_rays_per_s(stats: &RenderStats, schedule: &str) -> f64 {
    let extend_ms = stats.stage_ms.iter().find(|(l, _)| *l == "extend").map_or(0.0, |s| s.1);
    // Stage times cover the passes after the first (or the only one): scale the ray count to match.
    let steady_share = if stats.passes > 1 {
        (stats.passes - 1) as f64 / stats.passes as f64
    } else {
        1.0
    };
    if extend_ms > 0.0 && schedule == "wavefront" {
        stats.extension_rays as f64 * steady_share / (extend_ms * 1e-3)
    } else {
        0.0
    }
}

/// Wall time of a whole `pathwave render` process.
pub(super) fn process_time(exe: &Path, scene: &Path, size: (u32, u32), spp: u32) -> Result<f64, Error> {
    let out = tempfile::Builder::new()
        .suffix(".exr")
        .tempfile()
        .map_err(|e| Error::Settings(format!("bench: {e}")))?;
    let start = Instant::now();
    let status = Command::new(exe)
        .arg("render")
        .arg(scene)
        .args([
            "--size",
            &format!("{}x{}", size.0, size.1),
            "--spp",
            &spp.to_string(),
            "-o",
        ])
        .arg(out.path())
        .env_remove("PATHWAVE_VALIDATION")
        .output()
        .map_err(|e| Error::Settings(format!("bench: cannot run {}: {e}", exe.display())))?;
    let t = start.elapsed().as_secs_f64();
    if !status.status.success() {
        return Err(Error::Settings(format!(
            "bench: pathwave render {} failed: {}",
            scene.display(),
            String::from_utf8_lossy(&status.stderr)
        )));
    }
    Ok(t)
}
