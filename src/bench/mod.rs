//! `pathwave bench`: a fixed set of renders measured the same way every time, printed as a table and as JSON.
pub mod adaptive;
mod cases;
pub mod compare;
mod measure;
mod report;
pub mod scenes;

use crate::error::Error;
use crate::render::{LightSampler, Traversal};
use crate::vk::DeviceChoice;
use cases::{run_cases, traversals};
pub use compare::{EmbreeComparison, MitsubaComparison};
use glam::Vec3;
use measure::process_time;
pub use measure::CaseResult;
pub use report::BenchReport;
pub use scenes::{instanced_terrain, terrain};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

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
    /// One of CASE_GROUPS to measure alone (`--only`); None: all, with start-up and the light tree.
    pub only: Option<String>,
}

/// The groups of fixed cases, in the order they run (`bench --only` names one).
pub const CASE_GROUPS: [&str; 5] = ["cornell-box", "glass", "textured-props", "terrain", "instances"];

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
        mitsuba_media: None,
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
        run_fixed(o, &traversals, &cornell, &glass, &mut report, progress)?;
    }
    if o.compare.contains(&Compare::Embree) {
        progress("Embree comparison");
        report.embree = Some(compare::compare_embree(&o.python, &o.device, o.quick, &traversals)?);
    }
    if o.compare.contains(&Compare::Mitsuba) {
        against_mitsuba(o, &cornell, &glass, &mut report, progress)?;
    }
    if o.compare.contains(&Compare::Lights) {
        against_mitsuba_lights(o, &mut report, progress)?;
    }
    report.device = (report.cases.first().map(|c| c.device.clone()))
        .or_else(|| report.embree.as_ref().map(|e| e.device.clone()))
        .or_else(|| report.mitsuba.as_ref().map(|m| m.device.clone()))
        .unwrap_or_default();
    report.total = start.elapsed();
    Ok(report)
}

/// The start-up time (a first process warms the shader cache), the fixed cases, and the light tree's build over a
/// terrain whose every triangle emits.
fn run_fixed(
    o: &BenchOptions,
    traversals: &[Traversal],
    cornell: &Path,
    glass: &Path,
    report: &mut BenchReport,
    progress: &mut dyn FnMut(&str),
) -> Result<(), Error> {
    if o.only.is_some() {
        return run_cases(o, traversals, cornell, glass, &mut report.cases, progress);
    }
    progress("start-up");
    process_time(&o.exe, cornell, (64, 64), 1)?;
    report.startup_s = Some(process_time(&o.exe, cornell, (64, 64), 1)?);
    run_cases(o, traversals, cornell, glass, &mut report.cases, progress)?;
    progress("light tree");
    let mut glowing = terrain(if o.quick { 128 } else { 708 });
    glowing.materials[0].emission = Vec3::ONE;
    let tree = crate::render::gpu_scene::try_pack(&glowing)?.light_tree.stats;
    report.light_tree = Some((tree.emitters, tree.depth, tree.build.as_secs_f64()));
    Ok(())
}

/// Mitsuba on the Cornell box, RGB then spectral, and on the subsurface scene; then adaptive against uniform sampling
/// on three scenes. With `--only cornell-box`, the Cornell box's two alone; with another group, none of them.
fn against_mitsuba(
    o: &BenchOptions,
    cornell: &Path,
    glass: &Path,
    report: &mut BenchReport,
    progress: &mut dyn FnMut(&str),
) -> Result<(), Error> {
    progress("Mitsuba comparison");
    let case = |scene, spectral, light_sampler| compare::MitsubaCase {
        scene,
        spectral,
        light_sampler,
        size: (256, 256),
        reference_spp: 8192,
    };
    let mitsuba =
        |case, progress: &mut dyn FnMut(&str)| compare::compare_mitsuba(&o.python, &o.device, case, o.quick, progress);
    if o.only.as_deref().is_some_and(|only| only != "cornell-box") {
        return Ok(());
    }
    report.mitsuba = Some(mitsuba(case(cornell, false, o.light_sampler), progress)?);
    progress("Mitsuba comparison, spectral");
    report.mitsuba_spectral = Some(mitsuba(case(cornell, true, o.light_sampler), progress)?);
    if o.only.is_some() {
        return Ok(());
    }
    // Scattering media: four spheres of dense, chromatic media behind rough and smooth glass under a small light,
    // against Mitsuba's volpath. Smaller, as its paths are hundreds of scatterings long.
    progress("Mitsuba comparison, subsurface");
    let subsurface = o.scenes.join("subsurface.gltf");
    let media = compare::MitsubaCase {
        size: (128, 128),
        reference_spp: 4096,
        ..case(&subsurface, false, o.light_sampler)
    };
    report.mitsuba_media = Some(mitsuba(media, progress)?);
    // The halves scene's noise is uneven, where adaptive sampling pays; the others' is about even.
    let halves = o.scenes.join("halves.gltf");
    for scene in [cornell, glass, halves.as_path()] {
        report
            .adaptive
            .push(adaptive::compare_adaptive(&o.device, scene, o.quick, progress)?);
    }
    Ok(())
}

fn against_mitsuba_lights(
    o: &BenchOptions,
    report: &mut BenchReport,
    progress: &mut dyn FnMut(&str),
) -> Result<(), Error> {
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
    Ok(())
}
