//! `pathwave info` (a scene, a folder's census, the devices) and `pathwave export-shaders`.
use super::args::*;
use anyhow::{bail, Context as _, Result};
use indicatif::ProgressBar;
use pathwave::scene;
use std::path::PathBuf;
use std::time::Instant;

pub(crate) fn export_shaders(dir: PathBuf) -> Result<()> {
    let written = pathwave::shaders::export_builtin(&dir)?;
    eprintln!(
        "wrote {} files into {}; use them with --shader-dir {}",
        written.len(),
        dir.display(),
        dir.display()
    );
    Ok(())
}

/// Most files a census looks at: a folder's listing is read before anything loads.
pub(crate) const CENSUS_FILES: usize = 100_000;

/// `info FOLDER`: every .gltf and .glb under `dir` (sorted, depth first, symbolic links not followed) loaded with
/// `limits` as `render` loads it; a line per file (what it holds, or why it is refused), then each extension the
/// loaded files use, with how many use it and whether pathwave renders it, then one summary line.
pub(crate) fn census(dir: &std::path::Path, limits: &LoadArgs) -> Result<()> {
    pub(crate) fn walk(dir: &std::path::Path, out: &mut Vec<PathBuf>) -> Result<()> {
        let mut entries: Vec<PathBuf> = std::fs::read_dir(dir)
            .with_context(|| format!("cannot list {}", dir.display()))?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .collect();
        entries.sort();
        for p in entries {
            let Ok(meta) = std::fs::symlink_metadata(&p) else {
                continue;
            };
            if meta.is_dir() {
                walk(&p, out)?;
            } else if !meta.is_symlink() && {
                // A FIFO or device named .gltf is listed so that its refusal is reported, not silently skipped;
                // the loader refuses it from its metadata without opening it.
                let ext = p.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
                matches!(ext.as_deref(), Some("gltf" | "glb"))
            } {
                out.push(p);
            }
            if out.len() > CENSUS_FILES {
                bail!(
                    "{}: more than {CENSUS_FILES} glTF files; take a census of a smaller folder",
                    dir.display()
                );
            }
        }
        Ok(())
    }
    let mut files = Vec::new();
    walk(dir, &mut files)?;
    if files.is_empty() {
        bail!("{}: no .gltf or .glb file under it", dir.display());
    }
    let bar = ProgressBar::new(files.len() as u64);
    let mut used: std::collections::BTreeMap<String, usize> = Default::default();
    let (mut loaded, mut warned) = (0usize, 0usize);
    for f in &files {
        let name = f.strip_prefix(dir).unwrap_or(f).display().to_string();
        let line = match limits.load(f, None) {
            Ok(scene) => {
                loaded += 1;
                warned += !scene.warnings.is_empty() as usize;
                for e in &scene.extensions_used {
                    *used.entry(e.clone()).or_default() += 1;
                }
                format!(
                    "loads    {name}: {} triangles, {} materials, {} warnings",
                    scene.triangle_count(),
                    scene.materials.len(),
                    scene.warnings.len()
                )
            }
            Err(e) => format!("refused  {name}: {}", format!("{e:#}").replace('\n', " ")),
        };
        bar.suspend(|| println!("{line}"));
        bar.inc(1);
    }
    bar.finish_and_clear();
    for (ext, n) in &used {
        let supported = pathwave::scene::SUPPORTED_EXTENSIONS.contains(&ext.as_str());
        let how = if supported {
            "supported"
        } else {
            "not supported, ignored"
        };
        println!("extension   {ext}: {n} of the files that load, {how}");
    }
    println!(
        "census: {loaded} of {} files load ({warned} with warnings), {} refused",
        files.len(),
        files.len() - loaded
    );
    Ok(())
}

pub(crate) fn info(path: Option<PathBuf>, devices: bool, limits: &LoadArgs) -> Result<()> {
    if devices {
        for d in pathwave::vk::list_devices()? {
            println!(
                "{}: {} ({}, Vulkan {}, {}, maxStorageBufferRange {} MiB, ray queries: {})",
                d.index,
                d.name,
                d.kind,
                d.api_version,
                d.driver,
                d.max_storage_buffer_range >> 20,
                if d.ray_query { "yes" } else { "no" }
            );
        }
        return Ok(());
    }
    let Some(path) = path else {
        bail!("name a scene, or pass --devices")
    };
    if path.is_dir() {
        return census(&path, limits);
    }
    let scene = limits.load(&path, None).with_context(|| "cannot describe the scene")?;
    for w in &scene.warnings {
        eprintln!("warning: {}: {w}", path.display());
    }
    let start = Instant::now();
    let packed = pathwave::render::gpu_scene::try_pack_with(&scene, instancing_rule())?;
    let build = start.elapsed();
    let st = &packed.bvh.stats;
    println!("scene       {}", path.display());
    let placed = scene.flattened_triangle_bound();
    println!("triangles   {} stored, {placed} placed", packed.tri_verts.len());
    let file_meshes = &scene.meshes[..scene.rig.file_meshes.min(scene.meshes.len())];
    println!(
        "meshes      {} unique ({} triangles), placed by {} instances",
        file_meshes.len(),
        file_meshes.iter().map(|m| m.triangle_count()).sum::<usize>(),
        scene.instances.len()
    );
    if scene.extensions_used.is_empty() {
        println!("extensions  none");
    }
    if !scene.variants.is_empty() {
        println!(
            "variants    {} (--variant NAME): '{}'",
            scene.variants.len(),
            scene.variants.join("', '")
        );
    }
    for ext in &scene.extensions_used {
        let supported = pathwave::scene::SUPPORTED_EXTENSIONS.contains(&ext.as_str());
        println!(
            "extension   {ext}: {}",
            if supported {
                "supported"
            } else {
                "not supported, ignored"
            }
        );
    }
    let (morphed, skinned) = pathwave::scene::rig::deformation_counts(&scene);
    println!(
        "deforming   {} skins, {skinned} skinned meshes, {morphed} meshes with morph targets",
        scene.rig.skins.len()
    );
    if scene.rig.animations.is_empty() {
        println!("animations  none");
    }
    for (i, a) in scene.rig.animations.iter().enumerate() {
        let (lo, hi) = a.range();
        let name = if a.name.is_empty() {
            String::new()
        } else {
            format!(" '{}'", a.name)
        };
        println!(
            "animation   {i}{name}: {} channels, keys from {lo} s to {hi} s ({:.3} s)",
            a.channels.len(),
            hi - lo
        );
    }
    let instanced = scene.instanced_meshes(instancing_rule());
    let kept = instanced.iter().filter(|&&i| i).count();
    if kept > 0 {
        println!(
            "instancing  {kept} of {} meshes kept once in object space under a two-level BVH, placed by {} instances \
             ({:.2} MiB of instance records)",
            file_meshes.len(),
            packed.instances.first().map_or(0, |header| header.info[1]),
            std::mem::size_of_val(&packed.instances[..]) as f64 / (1 << 20) as f64
        );
    } else {
        println!("instancing  none (every instance is placed into the world BVH)");
    }
    println!("materials   {}", scene.materials.len() - 1);
    let instanced_lights = (packed.lights.iter().take(packed.light_count as usize))
        .filter(|l| l.id >> pathwave::constants::LIGHT_KIND_SHIFT == pathwave::constants::LIGHT_KIND_INSTANCE)
        .count();
    let triangles = packed
        .lights
        .iter()
        .filter(|l| l.id >> pathwave::constants::LIGHT_KIND_SHIFT == 0)
        .count();
    println!(
        "lights      {triangles} emissive triangles{}, {:.4} W in total",
        match instanced_lights {
            0 => String::new(),
            n => format!(" (instanced meshes' counted once) and {n} emissive instances"),
        },
        packed.total_light_power + 0.0
    );
    let tree = &packed.light_tree;
    println!(
        "light tree  {} emitters, {} interior nodes, depth {}, {} bytes, built in {:.1} ms{}",
        tree.stats.emitters,
        tree.stats.interior,
        tree.stats.depth,
        tree.bytes(),
        tree.stats.build.as_secs_f64() * 1e3,
        match tree.share() {
            s if s < 1.0 && tree.stats.emitters > 0 =>
                format!("; infinite lights take {:.1} % of the picks", 100.0 * (1.0 - s)),
            _ => String::new(),
        }
    );
    println!(
        "textures    {} ({} images, {:.2} MiB of texels)",
        scene.textures.len(),
        scene.images.len(),
        (packed.texels.len() * 4) as f64 / (1 << 20) as f64
    );
    println!("cameras     {}", scene.camera_count);
    println!(
        "bvh         {} node records ({} leaves), {} children per node, binary depth {}, at most {} entries on the \
         traversal stack, at most {} triangles per leaf, SAH cost {:.2}, {} bytes, built in {:.1} ms",
        st.nodes,
        st.leaves,
        pathwave::constants::BVH_WIDTH,
        st.depth,
        st.max_waiting,
        st.max_leaf_tris,
        st.sah_cost,
        st.nodes * std::mem::size_of::<pathwave::layout::BvhNode>(),
        build.as_secs_f64() * 1e3
    );
    Ok(())
}

/// The instancing rule the renderer will use (PATHWAVE_INSTANCING; a bad value is refused when the renderer reads it).
pub(crate) fn instancing_rule() -> scene::Instancing {
    pathwave::RendererOptions::from_env().map_or(scene::Instancing::Auto, |o| o.instancing)
}
