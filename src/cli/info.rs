//! `pathwave info` (a scene, a folder's census, the devices) and `pathwave export-shaders`.
use super::args::*;
use crate::render::gpu_scene::describe;
use crate::scene;
use anyhow::{bail, Context as _, Result};
use indicatif::ProgressBar;
use std::path::PathBuf;

pub fn export_shaders(dir: PathBuf) -> Result<()> {
    let written = crate::shaders::export_builtin(&dir)?;
    eprintln!(
        "wrote {} files into {}; use them with --shader-dir {}",
        written.len(),
        dir.display(),
        dir.display()
    );
    Ok(())
}

/// Most files a census looks at: a folder's listing is read before anything loads.
pub const CENSUS_FILES: usize = 100_000;

/// `info FOLDER`: every .gltf and .glb under `dir` (sorted, depth first, symbolic links not followed) loaded with
/// `limits` as `render` loads it; a line per file (what it holds, or why it is refused), then each extension the
/// loaded files use, with how many use it and whether pathwave renders it, then one summary line.
pub fn census(dir: &std::path::Path, limits: &LoadArgs) -> Result<()> {
    pub fn walk(dir: &std::path::Path, out: &mut Vec<PathBuf>) -> Result<()> {
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
        let supported = crate::scene::SUPPORTED_EXTENSIONS.contains(&ext.as_str());
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

pub fn info(path: Option<PathBuf>, devices: bool, limits: &LoadArgs) -> Result<()> {
    if devices {
        for d in crate::vk::list_devices()? {
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
    println!("scene       {}", path.display());
    print!("{}", describe(&scene, instancing_rule())?);
    Ok(())
}

/// The instancing rule the renderer will use (PATHWAVE_INSTANCING; a bad value is refused when the renderer reads it).
pub fn instancing_rule() -> scene::Instancing {
    crate::RendererOptions::from_env().map_or(scene::Instancing::Auto, |o| o.instancing)
}
