//! The fixed cases: which scenes, sizes, sample counts, traversals and variations bench measures, in which order.
use super::measure::{measure, process_time, CaseResult, Variation};
use super::scenes::{instanced_terrain, terrain, textured_props};
use super::BenchOptions;
use crate::error::Error;
use crate::render::{BvhReads, Schedule, TextureFilter, Traversal};
use crate::scene::{self, Scene};
use crate::vk::{Context, Validation};
use std::path::Path;
use std::time::Instant;

/// The traversals `o` asks for on its device, the compute BVH first: both under `Auto` where the device has ray
/// queries; `RayQuery` on a device without them is refused.
pub(super) fn traversals(o: &BenchOptions) -> Result<Vec<Traversal>, Error> {
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

pub(super) fn run_cases(
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
    let compute_only = traversals.first() == Some(&Traversal::Compute);
    let wanted = |group: &str| o.only.as_deref().is_none_or(|only| only == group);
    for (name, path, spp) in [("cornell-box", cornell, spp_cornell), ("glass", glass, spp_glass)] {
        if !wanted(name) {
            continue;
        }
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
            cornell_variations(o, &scene, spp, cases)?;
        }
    }
    if wanted("textured-props") {
        progress("textured props");
        textured_cases(o, traversals, cases)?;
    }
    if wanted("terrain") {
        progress("terrain");
        terrain_cases(o, traversals, side, spp_mesh, compute_only, cases)?;
    }
    // 10,000 instances of a 51,200-triangle mesh: 512 M placed triangles, about 200 GB flattened; stored once.
    if wanted("instances") {
        progress("instances");
        instanced_cases(o, traversals, spp_mesh, cases)?;
    }
    if !o.quick && compute_only && wanted("terrain") {
        // Past lavapipe's 128 MiB storage-buffer range: the per-triangle buffers (162 MiB of shading alone) are
        // read through texel views, which is the only way this device can hold the scene.
        progress("terrain past the storage range");
        let big = terrain(1300);
        let name = format!("terrain-{}k", big.triangle_count() / 1000);
        cases.push(measure(&name, &big, (256, 256), 8, o, Variation::default())?);
    }
    Ok(())
}

/// The default render with `traversal`.
fn traced(traversal: Traversal) -> Variation {
    Variation {
        traversal,
        ..Default::default()
    }
}

/// The Cornell box's variations of the compute BVH's render, after it.
fn cornell_variations(o: &BenchOptions, scene: &Scene, spp: u32, cases: &mut Vec<CaseResult>) -> Result<(), Error> {
    // The same render with the BVH read from storage buffers (the texel path's gain), and with each schedule
    // fixed (the default on a CPU device tries both in its first passes), in this run.
    let storage = Variation {
        reads: Some(BvhReads::Storage),
        ..Default::default()
    };
    cases.push(measure("cornell-storage", scene, (256, 256), spp, o, storage)?);
    for (name, schedule) in [
        ("cornell-fused", Schedule::Fused),
        ("cornell-wavefront", Schedule::Wavefront),
    ] {
        let fixed = Variation {
            schedule: Some(schedule),
            ..Default::default()
        };
        cases.push(measure(name, scene, (256, 256), spp, o, fixed)?);
    }
    // Spectral transport's cost (--spectral): four wavelengths per path and every colour upsampled.
    let spectral = Variation {
        spectral: true,
        ..Default::default()
    };
    cases.push(measure("cornell-spectral", scene, (256, 256), spp, o, spectral)?);
    Ok(())
}

/// The textured props (scenes.rs) once per traversal with mip-mapped textures, then with bilinear lookups of level 0
/// alone (`--texture-filter bilinear`): the share of shading that goes to texture reads the caches cannot hold.
fn textured_cases(o: &BenchOptions, traversals: &[Traversal], cases: &mut Vec<CaseResult>) -> Result<(), Error> {
    // 64 spp: at 16 the first pass (which compiles) was 90 % of the render, and samples/s came from one pass.
    let (side, size, spp) = if o.quick {
        (256, (160, 120), 2)
    } else {
        (2048, (320, 240), 64)
    };
    let scene = textured_props(side);
    for &t in traversals {
        cases.push(measure(
            &traced_name("textured-props", t),
            &scene,
            size,
            spp,
            o,
            traced(t),
        )?);
    }
    let bilinear = Variation {
        texture_filter: TextureFilter::Bilinear,
        ..Default::default()
    };
    cases.push(measure("textured-props-bilinear", &scene, size, spp, o, bilinear)?);
    Ok(())
}

/// The terrain once per traversal, then (`compute_only`: the compute BVH's case came first) with the BVH read from
/// storage buffers.
fn terrain_cases(
    o: &BenchOptions,
    traversals: &[Traversal],
    side: usize,
    spp_mesh: u32,
    compute_only: bool,
    cases: &mut Vec<CaseResult>,
) -> Result<(), Error> {
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
    Ok(())
}

/// The instanced terrain once per traversal, each case's process_s the time from before its scene is built.
fn instanced_cases(
    o: &BenchOptions,
    traversals: &[Traversal],
    spp_mesh: u32,
    cases: &mut Vec<CaseResult>,
) -> Result<(), Error> {
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
    Ok(())
}
