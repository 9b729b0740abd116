//! `pathwave bench`: a fixed set of renders measured the same way every time, printed as a table and as JSON.
pub mod adaptive;
pub mod compare;

use crate::error::Error;
use crate::render::{BvhReads, LightSampler, RenderSettings, Schedule, Traversal};
use crate::scene::{self, Camera, Environment, Material, Mesh, Primitive, Scene};
use crate::vk::{Context, DeviceChoice, Validation};
pub use compare::{EmbreeComparison, MitsubaComparison};
use glam::{Mat4, Vec3};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

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

pub struct BenchOptions {
    pub device: DeviceChoice,
    /// Where cornell-box.gltf and glass.gltf are.
    pub scenes: PathBuf,
    /// This program, spawned for whole-process timings.
    pub exe: PathBuf,
    /// Fewer samples, for a quick look (and the tests).
    pub quick: bool,
    /// Other renderers to measure against in the same run.
    pub compare: Vec<Compare>,
    /// The Python that has `mitsuba` and `embreex` installed.
    pub python: PathBuf,
    /// Skip the fixed cases and run only the comparisons.
    pub only_compare: bool,
    /// Light selection for the fixed cases and the Cornell box comparisons.
    pub light_sampler: LightSampler,
    /// Which traversals to measure: `Auto` both where the device has ray queries (side by side), else the one named.
    pub traversal: Traversal,
}

/// The traversals `o` asks for on its device, the compute BVH first: both under `Auto` where the device has ray
/// queries; `RayQuery` on a device without them is refused.
fn traversals(o: &BenchOptions) -> Result<Vec<Traversal>, Error> {
    let has = Context::new(&o.device, Validation::Off)?.accel.is_some();
    match (o.traversal, has) {
        (Traversal::Compute, _) | (Traversal::Auto, false) => Ok(vec![Traversal::Compute]),
        (Traversal::Auto, true) => Ok(vec![Traversal::Compute, Traversal::RayQuery]),
        (Traversal::RayQuery, true) => Ok(vec![Traversal::RayQuery]),
        (Traversal::RayQuery, false) => Err(Error::Settings(
            "bench --traversal ray-query: the device has no ray queries (`pathwave info --devices` says which do)"
                .into(),
        )),
    }
}

/// A case's name with its traversal: "+rq" after ray queries' cases.
fn traced_name(name: &str, traversal: Traversal) -> String {
    match traversal {
        Traversal::RayQuery => format!("{name}+rq"),
        _ => name.to_string(),
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Compare {
    /// Mitsuba 3 (llvm_ad_rgb) on the Cornell box: relMSE x time against a converged reference.
    Mitsuba,
    /// Embree (embreex) on the terrain mesh: random-ray traversal speed.
    Embree,
    /// Mitsuba 3 on the lamp grid, the city block and the emissive panel (many lights), once per light sampler:
    /// relMSE x time.
    Lights,
}

/// `count` instances (a square grid, each turned about +y) of the `side` terrain's mesh, seen from above at an
/// angle: the instancing case, whose placed triangles would not fit in memory flattened.
pub fn instanced_terrain(count: usize, side: usize) -> Scene {
    let mut s = terrain(side);
    s.path = PathBuf::from(format!("instanced-terrain-{count}x{side}"));
    s.instances.clear();
    let row = (count as f32).sqrt().ceil() as usize;
    for i in 0..count {
        let (x, z) = ((i % row) as f32 - row as f32 / 2.0, (i / row) as f32 - row as f32 / 2.0);
        s.instances.push(crate::scene::Instance {
            mesh: 0,
            world_from_object: Mat4::from_rotation_translation(
                glam::Quat::from_rotation_y(i as f32 * 0.7),
                Vec3::new(x * 2.2, 0.0, z * 2.2),
            ),
        });
    }
    let extent = row as f32 * 1.1;
    let eye = Vec3::new(0.0, extent * 0.8, extent * 1.6);
    s.camera = Some(Camera::look_at(eye, Vec3::ZERO, 45f32.to_radians()));
    s
}

/// A heightfield of `side`^2 quads (2 side^2 triangles) of rolling hills under a uniform sky.
pub fn terrain(side: usize) -> Scene {
    let h = |x: f32, z: f32| {
        0.08 * (x * 9.0).sin() * (z * 7.0).cos() + 0.03 * (x * 31.0 + z * 17.0).sin() + 0.01 * (x * 97.0).cos()
    };
    let n = side + 1;
    let mut p = Vec::with_capacity(n * n);
    let mut nrm = Vec::with_capacity(n * n);
    let e = 1e-3;
    for j in 0..n {
        for i in 0..n {
            let (x, z) = (i as f32 / side as f32 * 2.0 - 1.0, j as f32 / side as f32 * 2.0 - 1.0);
            p.push(Vec3::new(x, h(x, z), z));
            let dx = (h(x + e, z) - h(x - e, z)) / (2.0 * e);
            let dz = (h(x, z + e) - h(x, z - e)) / (2.0 * e);
            nrm.push(Vec3::new(-dx, 1.0, -dz).normalize());
        }
    }
    let mut s = Scene {
        path: PathBuf::from(format!("terrain-{side}")),
        ..Default::default()
    };
    s.materials.push(Material {
        name: "ground".into(),
        base_color: Vec3::splat(0.6),
        metallic: 0.0,
        specular: 0.0,
        ..Default::default()
    });
    let mut triangles = Vec::with_capacity(2 * side * side);
    for j in 0..side {
        for i in 0..side {
            let a = (j * n + i) as u32;
            let (b, c, d) = (a + 1, a + n as u32, a + n as u32 + 1);
            // Counter-clockwise seen from above (+y).
            triangles.extend([[a, c, b], [b, c, d]]);
        }
    }
    let ground = Primitive {
        positions: p,
        normals: Some(nrm),
        triangles,
        material: 0,
        ..Default::default()
    };
    s.add_mesh(
        Mesh {
            name: "terrain".into(),
            primitives: vec![ground],
        },
        Mat4::IDENTITY,
    );
    let eye = Vec3::new(0.0, 1.2, 2.2);
    s.camera = Some(Camera::look_at(eye, Vec3::ZERO, 45f32.to_radians()));
    s.environment = Some(Environment::constant([1.0, 1.0, 1.0]));
    s
}

/// How a case departs from the default render: BVH reads, a fixed schedule, spectral transport, the traversal.
#[derive(Clone, Copy, Default)]
struct Variation {
    reads: Option<BvhReads>,
    schedule: Option<Schedule>,
    spectral: bool,
    traversal: Traversal,
}

fn measure(
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
        ..Default::default()
    };
    let (film, stats) = r.render(&settings, &mut |_| {})?;
    let extend_ms = stats.stage_ms.iter().find(|(l, _)| *l == "extend").map_or(0.0, |s| s.1);
    // Stage times cover the passes after the first (or the only one): scale the ray count to match.
    let steady_share = if stats.passes > 1 {
        (stats.passes - 1) as f64 / stats.passes as f64
    } else {
        1.0
    };
    let mean = film.mean();
    // What the timed passes ran: on a CPU device the default tries both schedules before it keeps one.
    let ran = |stage: &str| stats.stage_ms.iter().any(|(l, _)| *l == stage);
    let schedule = match (ran("follow"), ran("extend")) {
        (true, true) => "both",
        (true, false) => "fused",
        _ => "wavefront",
    };
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
        // Only when every timed pass ran the wavefront: fused passes trace extension rays outside any extend stage.
        extend_stage_rays_per_s: if extend_ms > 0.0 && schedule == "wavefront" {
            stats.extension_rays as f64 * steady_share / (extend_ms * 1e-3)
        } else {
            0.0
        },
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

/// Wall time of a whole `pathwave render` process.
fn process_time(exe: &Path, scene: &Path, size: (u32, u32), spp: u32) -> Result<f64, Error> {
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

pub struct BenchReport {
    pub device: String,
    pub cases: Vec<CaseResult>,
    /// A 64x64, 1-spp Cornell box render as a whole process, after one run warmed the shader cache.
    pub startup_s: Option<f64>,
    pub embree: Option<EmbreeComparison>,
    pub mitsuba: Option<MitsubaComparison>,
    /// The same with spectral transport, against Mitsuba's llvm_ad_spectral.
    pub mitsuba_spectral: Option<MitsubaComparison>,
    /// The lamp grid, the city block and the emissive panel, once per light sampler.
    pub mitsuba_lights: Vec<MitsubaComparison>,
    /// The light BVH's build over the terrain with every triangle emitting: (emitters, depth, seconds).
    pub light_tree: Option<(usize, u32, f64)>,
    /// With the Mitsuba comparison: --adaptive against uniform sampling at equal time, per scene.
    pub adaptive: Vec<adaptive::AdaptiveComparison>,
    pub total: Duration,
}

pub fn run(o: &BenchOptions, progress: &mut dyn FnMut(&str)) -> Result<BenchReport, Error> {
    let start = Instant::now();
    let cornell = o.scenes.join("cornell-box.gltf");
    let glass = o.scenes.join("glass.gltf");
    for p in [&cornell, &glass] {
        if !p.exists() {
            return Err(Error::Settings(format!(
                "bench: {} not found; run from the repository or pass --scenes DIR",
                p.display()
            )));
        }
    }
    let mut report = BenchReport {
        device: String::new(),
        cases: Vec::new(),
        startup_s: None,
        embree: None,
        mitsuba: None,
        mitsuba_spectral: None,
        mitsuba_lights: Vec::new(),
        light_tree: None,
        adaptive: Vec::new(),
        total: Duration::ZERO,
    };
    // Which traversals the cases and the Embree comparison measure, from one look at the device.
    let traversals = match !o.only_compare || o.compare.contains(&Compare::Embree) {
        true => traversals(o)?,
        false => Vec::new(),
    };
    if !o.only_compare {
        progress("start-up");
        process_time(&o.exe, &cornell, (64, 64), 1)?;
        report.startup_s = Some(process_time(&o.exe, &cornell, (64, 64), 1)?);
        run_cases(o, &traversals, &cornell, &glass, &mut report.cases, progress)?;
        progress("light tree");
        let mut glowing = terrain(if o.quick { 128 } else { 708 });
        glowing.materials[0].emission = Vec3::ONE;
        let tree = crate::render::gpu_scene::try_pack(&glowing)?.light_tree.stats;
        report.light_tree = Some((tree.emitters, tree.depth, tree.build.as_secs_f64()));
    }
    if o.compare.contains(&Compare::Embree) {
        progress("Embree comparison");
        report.embree = Some(compare::compare_embree(&o.python, &o.device, o.quick, &traversals)?);
    }
    if o.compare.contains(&Compare::Mitsuba) {
        progress("Mitsuba comparison");
        let case = |scene, spectral, light_sampler| compare::MitsubaCase {
            scene,
            spectral,
            light_sampler,
            size: (256, 256),
            reference_spp: 8192,
        };
        let mitsuba = |case, progress: &mut dyn FnMut(&str)| {
            compare::compare_mitsuba(&o.python, &o.device, case, o.quick, progress)
        };
        report.mitsuba = Some(mitsuba(case(&cornell, false, o.light_sampler), progress)?);
        progress("Mitsuba comparison, spectral");
        report.mitsuba_spectral = Some(mitsuba(case(&cornell, true, o.light_sampler), progress)?);
        // The halves scene's noise is uneven, where adaptive sampling pays; the others' is about even.
        let halves = o.scenes.join("halves.gltf");
        for scene in [&cornell, &glass, &halves] {
            report
                .adaptive
                .push(adaptive::compare_adaptive(&o.device, scene, o.quick, progress)?);
        }
    }
    if o.compare.contains(&Compare::Lights) {
        // Many lights: each light sampler against Mitsuba's uniform emitter choice on the lamp grid (hundreds of
        // lamps, a few far bright panels), the city block (thousands of lit windows, most facing away) and the
        // emissive panel (a screen's triangles under one emissive texture, mostly black).
        for (name, file) in [
            ("lamp grid", "lamp-grid.gltf"),
            ("city block", "city-block.gltf"),
            ("emissive panel", "emissive-panel.gltf"),
        ] {
            let scene = o.scenes.join(file);
            for light_sampler in [LightSampler::Bvh, LightSampler::Power, LightSampler::Uniform] {
                progress(&format!(
                    "Mitsuba comparison, {name}, lights by {}",
                    light_sampler.name()
                ));
                let case = compare::MitsubaCase {
                    scene: &scene,
                    spectral: false,
                    light_sampler,
                    size: (192, 128),
                    reference_spp: 4096,
                };
                let m = compare::compare_mitsuba(&o.python, &o.device, case, o.quick, progress)?;
                report.mitsuba_lights.push(m);
            }
        }
    }
    report.device = (report.cases.first().map(|c| c.device.clone()))
        .or_else(|| report.embree.as_ref().map(|e| e.device.clone()))
        .or_else(|| report.mitsuba.as_ref().map(|m| m.device.clone()))
        .unwrap_or_default();
    report.total = start.elapsed();
    Ok(report)
}

fn run_cases(
    o: &BenchOptions,
    traversals: &[Traversal],
    cornell: &Path,
    glass: &Path,
    cases: &mut Vec<CaseResult>,
    progress: &mut dyn FnMut(&str),
) -> Result<(), Error> {
    // Every full case takes at least two passes (16 spp of 256x256 fit in flight on lavapipe), so its stage times
    // exclude the first, which compiles the pipelines.
    let (spp_cornell, spp_glass, spp_mesh, side) = if o.quick { (4, 2, 1, 128) } else { (64, 32, 32, 708) };
    // The main cases once per traversal, each right after the other so the machine's load is shared alike; the
    // variations of the compute BVH's reads and schedules after the compute case.
    let traced = |traversal| Variation {
        traversal,
        ..Default::default()
    };
    let compute_only = traversals.first() == Some(&Traversal::Compute);
    for (name, path, spp) in [("cornell-box", cornell, spp_cornell), ("glass", glass, spp_glass)] {
        progress(name);
        let scene = scene::load(path, None)?;
        for &t in traversals {
            let mut c = measure(&traced_name(name, t), &scene, (256, 256), spp, o, traced(t))?;
            if t == Traversal::Compute {
                c.process_s = Some(process_time(&o.exe, path, (256, 256), spp)?);
            }
            cases.push(c);
        }
        if name == "cornell-box" && compute_only {
            // The same render with the BVH read from storage buffers (the texel path's gain), and with each schedule
            // fixed (the default on a CPU device tries both in its first passes), in this run.
            let storage = Variation {
                reads: Some(BvhReads::Storage),
                ..Default::default()
            };
            cases.push(measure("cornell-storage", &scene, (256, 256), spp, o, storage)?);
            for (name, schedule) in [
                ("cornell-fused", Schedule::Fused),
                ("cornell-wavefront", Schedule::Wavefront),
            ] {
                let fixed = Variation {
                    schedule: Some(schedule),
                    ..Default::default()
                };
                cases.push(measure(name, &scene, (256, 256), spp, o, fixed)?);
            }
            // Spectral transport's cost (--spectral): four wavelengths per path and every colour upsampled.
            let spectral = Variation {
                spectral: true,
                ..Default::default()
            };
            cases.push(measure("cornell-spectral", &scene, (256, 256), spp, o, spectral)?);
        }
    }
    progress("terrain");
    let t = terrain(side);
    let name = format!("terrain-{}k", t.triangle_count() / 1000);
    for &traversal in traversals {
        cases.push(measure(
            &traced_name(&name, traversal),
            &t,
            (256, 256),
            spp_mesh,
            o,
            traced(traversal),
        )?);
    }
    if compute_only {
        let storage = Variation {
            reads: Some(BvhReads::Storage),
            ..Default::default()
        };
        cases.push(measure("terrain-storage", &t, (256, 256), spp_mesh, o, storage)?);
    }
    // 10,000 instances of a 51,200-triangle mesh: 512 M placed triangles, about 200 GB flattened; stored once.
    progress("instances");
    let (count, mesh_side) = if o.quick { (400, 40) } else { (10_000, 160) };
    let name = format!("instances-{count}x{}k", 2 * mesh_side * mesh_side / 1000);
    for &traversal in traversals {
        let build = Instant::now();
        let forest = instanced_terrain(count, mesh_side);
        let mut c = measure(
            &traced_name(&name, traversal),
            &forest,
            (256, 256),
            spp_mesh.min(8),
            o,
            traced(traversal),
        )?;
        c.process_s = Some(build.elapsed().as_secs_f64());
        cases.push(c);
    }
    if !o.quick && compute_only {
        // Past lavapipe's 128 MiB storage-buffer range: the per-triangle buffers (162 MiB of shading alone) are
        // read through texel views, which is the only way this device can hold the scene.
        progress("terrain past the storage range");
        let big = terrain(1300);
        let name = format!("terrain-{}k", big.triangle_count() / 1000);
        cases.push(measure(&name, &big, (256, 256), 8, o, Variation::default())?);
    }
    Ok(())
}

impl BenchReport {
    pub fn table(&self) -> String {
        let mut s = format!(
            "pathwave bench on {} ({:.0} s in all)\n",
            self.device,
            self.total.as_secs_f64()
        );
        if let Some(t) = self.startup_s {
            s += &format!("start-up, 64x64 Cornell box at 1 spp, whole process: {t:.2} s\n");
        }
        if !self.cases.is_empty() {
            s += &self.cases_table();
        }
        if let Some((emitters, depth, build)) = self.light_tree {
            s += &format!("light tree over the terrain, every triangle emitting: {emitters} emitters, depth {depth}, built in {build:.3} s\n");
        }
        if let Some(e) = &self.embree {
            s += &format!(
                "traversal vs Embree ({} tris, {} random rays, closest hit, {} threads; BVH build {:.2} s vs {:.2} s):\n",
                e.triangles, e.rays, e.threads, e.pathwave_build_s, e.embree_build_s
            );
            for (k, (ours, theirs)) in e.rounds.iter().enumerate() {
                s += &format!(
                    "  round {}: pathwave {:.2} Mrays/s, Embree {:.2} Mrays/s, ratio {:.3}\n",
                    k + 1,
                    ours * 1e-6,
                    theirs * 1e-6,
                    ours / theirs
                );
            }
            s += &format!(
                "  median ratio {:.3} (target >= 0.5); hits agree on {:.3} % of rays{}\n",
                e.ratio,
                100.0 * e.agreement,
                if e.traversal == "compute" {
                    ""
                } else {
                    " (pathwave with ray queries)"
                }
            );
            if let Some(q) = &e.ray_query {
                let rates: Vec<String> = q.rays_per_s.iter().map(|r| format!("{:.2}", r * 1e-6)).collect();
                let over: Vec<f64> = q.rays_per_s.iter().zip(&e.rounds).map(|(q, (c, _))| q / c).collect();
                s += &format!(
                    "  the same rays with ray queries: {} Mrays/s by round, {:.3} x the compute BVH (median); \
                     structures built in {:.2} s; hits agree with Embree's on {:.3} %\n",
                    rates.join(", "),
                    compare::median(over),
                    q.build_s,
                    100.0 * q.agreement
                );
            }
        }
        for m in self
            .mitsuba
            .iter()
            .chain(&self.mitsuba_spectral)
            .chain(&self.mitsuba_lights)
        {
            s += &m.summary();
        }
        if let (Some(rgb), Some(spectral)) = (&self.mitsuba, &self.mitsuba_spectral) {
            s += &format!(
                "spectral transport's cost (pathwave, Cornell box {}x{}): {} against {} spp in the same budget; \
                 relMSE x time, spectral over RGB (each against its own Mitsuba reference): {:.3}\n",
                rgb.width,
                rgb.height,
                spectral.rounds.first().map_or(0, |r| r[0].0),
                rgb.rounds.first().map_or(0, |r| r[0].0),
                spectral.pathwave_score() / rgb.pathwave_score()
            );
        }
        for a in &self.adaptive {
            s += &a.summary();
        }
        s
    }

    /// Ray queries against the compute BVH, case by case where both ran: samples/s and extension rays/s of the
    /// extend stage, ray queries over compute (above 1: ray queries are faster).
    fn traversal_ratios(&self) -> Option<String> {
        let mut s = String::new();
        for rq in self.cases.iter().filter(|c| c.traversal == "ray queries") {
            let Some(base) = rq.name.strip_suffix("+rq") else {
                continue;
            };
            let Some(compute) = self.cases.iter().find(|c| c.name == base) else {
                continue;
            };
            let extend = if rq.extend_stage_rays_per_s > 0.0 && compute.extend_stage_rays_per_s > 0.0 {
                format!("{:.2}", rq.extend_stage_rays_per_s / compute.extend_stage_rays_per_s)
            } else {
                "-".into()
            };
            s += &format!(
                "  {:<22} samples/s {:.2}, extend-stage rays/s {}\n",
                base,
                rq.samples_per_s / compute.samples_per_s.max(1e-9),
                extend
            );
        }
        (!s.is_empty()).then(|| format!("ray queries over the compute BVH (above 1: ray queries faster):\n{s}"))
    }

    fn cases_table(&self) -> String {
        let mut s = format!(
            "{:<22} {:>9} {:>9} {:>9} {:>9} {:>10} {:>9} {:>9} {:>10} {:>8} {:>7}\n",
            "case",
            "tris",
            "process",
            "render",
            "1st pass",
            "samples/s",
            "ext Mr/s",
            "shd Mr/s",
            "extend Mr/s",
            "bvh s",
            "B/tri"
        );
        for c in &self.cases {
            s += &format!(
                "{:<22} {:>9} {:>9} {:>9.2} {:>9.2} {:>10.0} {:>9.2} {:>9.2} {:>10} {:>8.3} {:>7.1}\n",
                c.name,
                c.triangles,
                c.process_s.map_or("-".into(), |t| format!("{t:.2}")),
                c.render_s,
                c.first_pass_s,
                c.samples_per_s,
                c.extension_rays_per_s * 1e-6,
                c.shadow_rays_per_s * 1e-6,
                // The fused schedule has no extend stage to time.
                if c.extend_stage_rays_per_s > 0.0 {
                    format!("{:.2}", c.extend_stage_rays_per_s * 1e-6)
                } else {
                    "-".into()
                },
                c.bvh_build_s,
                c.bytes_per_triangle
            );
        }
        s += "GPU ms per stage (the passes after the first, or the only one):\n";
        for c in &self.cases {
            let stages: Vec<String> = c.stage_ms.iter().map(|(l, ms)| format!("{l} {ms:.1}")).collect();
            let schedule = format!("({})", c.schedule);
            s += &format!("  {:<22} {:<11} {}\n", c.name, schedule, stages.join(", "));
        }
        // Ray queries' cases: their structures beside the compute BVH (bvh s and B/tri above are the compute BVH's,
        // which such a scene uploads too).
        for c in &self.cases {
            if let Some((bytes, uncompacted, build_s)) = c.ray_query_structures {
                s += &format!(
                    "  {:<22} ray-query structures {:.1} MiB compacted from {:.1} MiB ({:.1} B/tri), built in {:.3} s\n",
                    c.name,
                    bytes as f64 / (1 << 20) as f64,
                    uncompacted as f64 / (1 << 20) as f64,
                    bytes as f64 / c.triangles.max(1) as f64,
                    build_s
                );
            }
        }
        if let Some(ratios) = self.traversal_ratios() {
            s += &ratios;
        }
        s
    }

    pub fn json(&self) -> String {
        let cases: Vec<serde_json::Value> = self
            .cases
            .iter()
            .map(|c| {
                serde_json::json!({
                    "name": c.name,
                    "triangles": c.triangles,
                    "width": c.size.0,
                    "height": c.size.1,
                    "spp": c.spp,
                    "process_s": c.process_s,
                    "render_s": c.render_s,
                    "first_pass_s": c.first_pass_s,
                    "samples_per_s": c.samples_per_s,
                    "extension_rays_per_s": c.extension_rays_per_s,
                    "shadow_rays_per_s": c.shadow_rays_per_s,
                    "extend_stage_rays_per_s": c.extend_stage_rays_per_s,
                    "stage_ms": c.stage_ms.iter().map(|(l, ms)| (l.clone(), serde_json::json!(ms))).collect::<serde_json::Map<_, _>>(),
                    "schedule": c.schedule,
                    "bvh_build_s": c.bvh_build_s,
                    "bytes_per_triangle": c.bytes_per_triangle,
                    "image_mean": c.image_mean,
                    "traversal": c.traversal,
                    "ray_query_structures": c.ray_query_structures.map(|(bytes, uncompacted, build_s)| serde_json::json!({"bytes": bytes, "uncompacted_bytes": uncompacted, "build_s": build_s})),
                })
            })
            .collect();
        serde_json::to_string_pretty(&serde_json::json!({
            "device": self.device,
            "startup_s": self.startup_s,
            "embree": self.embree.as_ref().map(|e| serde_json::json!({
                "triangles": e.triangles,
                "rays": e.rays,
                "threads": e.threads,
                "embree_build_s": e.embree_build_s,
                "pathwave_build_s": e.pathwave_build_s,
                "rounds": e.rounds.iter().map(|(a, b)| serde_json::json!({"pathwave_rays_per_s": a, "embree_rays_per_s": b})).collect::<Vec<_>>(),
                "ratio": e.ratio,
                "agreement": e.agreement,
                "traversal": e.traversal,
                "ray_query": e.ray_query.as_ref().map(|q| serde_json::json!({"rays_per_s": q.rays_per_s, "build_s": q.build_s, "agreement": q.agreement})),
            })),
            "mitsuba": self.mitsuba.as_ref().map(|m| m.json()),
            "mitsuba_spectral": self.mitsuba_spectral.as_ref().map(|m| m.json()),
            "mitsuba_lights": self.mitsuba_lights.iter().map(|m| m.json()).collect::<Vec<_>>(),
            "light_tree": self.light_tree.map(|(emitters, depth, build_s)| serde_json::json!({"emitters": emitters, "depth": depth, "build_s": build_s})),
            "adaptive": self.adaptive.iter().map(|a| a.json()).collect::<Vec<_>>(),
            "total_s": self.total.as_secs_f64(),
            "cases": cases,
        }))
        .unwrap_or_default()
    }
}
