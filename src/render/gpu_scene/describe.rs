//! What `pathwave info` reports about a scene: its contents as loaded and as packed for the device, line by line.
use super::{try_pack_with, PackedScene};
use crate::constants::{BVH_WIDTH, LIGHT_KIND_INSTANCE, LIGHT_KIND_SHIFT};
use crate::error::Error;
use crate::scene::{Instancing, Scene, SUPPORTED_EXTENSIONS};
use std::time::{Duration, Instant};

/// A report: (label, text) lines, in the order `info` prints them.
pub struct Report {
    pub lines: Vec<(&'static str, String)>,
}

impl std::fmt::Display for Report {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        for (label, text) in &self.lines {
            writeln!(f, "{label:<12}{text}")?;
        }
        Ok(())
    }
}

/// Packs `scene` as a renderer with `rule` would (BVH, instancing, lights, textures) and reports what it holds.
pub fn describe(scene: &Scene, rule: Instancing) -> Result<Report, Error> {
    let start = Instant::now();
    let packed = try_pack_with(scene, rule)?;
    let build = start.elapsed();
    let mut r = Report { lines: Vec::new() };
    contents(&mut r, scene, &packed);
    rig(&mut r, scene);
    instancing(&mut r, scene, &packed, rule);
    r.lines.push(("materials", (scene.materials.len() - 1).to_string()));
    lights(&mut r, &packed);
    r.lines.push((
        "textures",
        format!(
            "{} ({} images, {:.2} MiB of texels)",
            scene.textures.len(),
            scene.images.len(),
            (packed.texels.len() * 4) as f64 / (1 << 20) as f64
        ),
    ));
    r.lines.push(("cameras", scene.camera_count.to_string()));
    bvh(&mut r, &packed, build);
    Ok(r)
}

/// A file's meshes: the ones it stores, before any instancing splits them.
fn file_meshes(scene: &Scene) -> &[crate::scene::Mesh] {
    &scene.meshes[..scene.rig.file_meshes.min(scene.meshes.len())]
}

/// Triangles, meshes, material variants and extensions.
fn contents(r: &mut Report, scene: &Scene, packed: &PackedScene) {
    let placed = scene.flattened_triangle_bound();
    r.lines.push((
        "triangles",
        format!("{} stored, {placed} placed", packed.tri_verts.len()),
    ));
    let meshes = file_meshes(scene);
    r.lines.push((
        "meshes",
        format!(
            "{} unique ({} triangles), placed by {} instances",
            meshes.len(),
            meshes.iter().map(|m| m.triangle_count()).sum::<usize>(),
            scene.instances.len()
        ),
    ));
    if scene.extensions_used.is_empty() {
        r.lines.push(("extensions", "none".into()));
    }
    if !scene.variants.is_empty() {
        let names = scene.variants.join("', '");
        r.lines.push((
            "variants",
            format!("{} (--variant NAME): '{names}'", scene.variants.len()),
        ));
    }
    for ext in &scene.extensions_used {
        let how = match SUPPORTED_EXTENSIONS.contains(&ext.as_str()) {
            true => "supported",
            false => "not supported, ignored",
        };
        r.lines.push(("extension", format!("{ext}: {how}")));
    }
}

/// Skins, morph targets and animations.
fn rig(r: &mut Report, scene: &Scene) {
    let (morphed, skinned) = crate::scene::rig::deformation_counts(scene);
    r.lines.push((
        "deforming",
        format!(
            "{} skins, {skinned} skinned meshes, {morphed} meshes with morph targets",
            scene.rig.skins.len()
        ),
    ));
    if scene.rig.animations.is_empty() {
        r.lines.push(("animations", "none".into()));
    }
    for (i, a) in scene.rig.animations.iter().enumerate() {
        let (lo, hi) = a.range();
        let name = match a.name.is_empty() {
            true => String::new(),
            false => format!(" '{}'", a.name),
        };
        r.lines.push((
            "animation",
            format!(
                "{i}{name}: {} channels, keys from {lo} s to {hi} s ({:.3} s)",
                a.channels.len(),
                hi - lo
            ),
        ));
    }
}

/// Which meshes stay in object space under the two-level BVH.
fn instancing(r: &mut Report, scene: &Scene, packed: &PackedScene, rule: Instancing) {
    let kept = scene.instanced_meshes(rule).iter().filter(|&&i| i).count();
    let text = match kept {
        0 => "none (every instance is placed into the world BVH)".to_string(),
        _ => format!(
            "{kept} of {} meshes kept once in object space under a two-level BVH, placed by {} instances ({:.2} MiB \
             of instance records)",
            file_meshes(scene).len(),
            packed.instances.first().map_or(0, |header| header.info[1]),
            std::mem::size_of_val(&packed.instances[..]) as f64 / (1 << 20) as f64
        ),
    };
    r.lines.push(("instancing", text));
}

/// The light table and the light BVH over it.
fn lights(r: &mut Report, packed: &PackedScene) {
    let kind = |id: u32| id >> LIGHT_KIND_SHIFT;
    let table = &packed.lights[..packed.light_count as usize];
    let instanced = table.iter().filter(|l| kind(l.id) == LIGHT_KIND_INSTANCE).count();
    let triangles = packed.lights.iter().filter(|l| kind(l.id) == 0).count();
    let instanced = match instanced {
        0 => String::new(),
        n => format!(" (instanced meshes' counted once) and {n} emissive instances"),
    };
    // + 0.0 turns a -0.0 into 0.
    let power = packed.total_light_power + 0.0;
    r.lines.push((
        "lights",
        format!("{triangles} emissive triangles{instanced}, {power:.4} W in total"),
    ));
    let tree = &packed.light_tree;
    let share = match tree.share() {
        s if s < 1.0 && tree.stats.emitters > 0 => {
            format!("; infinite lights take {:.1} % of the picks", 100.0 * (1.0 - s))
        }
        _ => String::new(),
    };
    r.lines.push((
        "light tree",
        format!(
            "{} emitters, {} interior nodes, depth {}, {} bytes, built in {:.1} ms{share}",
            tree.stats.emitters,
            tree.stats.interior,
            tree.stats.depth,
            tree.bytes(),
            tree.stats.build.as_secs_f64() * 1e3,
        ),
    ));
}

/// The BVH's shape and cost, and how long packing took (`build`).
fn bvh(r: &mut Report, packed: &PackedScene, build: Duration) {
    let st = &packed.bvh.stats;
    r.lines.push((
        "bvh",
        format!(
            "{} node records ({} leaves), {} children per node, binary depth {}, at most {} entries on the traversal \
             stack, at most {} triangles per leaf, SAH cost {:.2}, {} bytes, built in {:.1} ms",
            st.nodes,
            st.leaves,
            BVH_WIDTH,
            st.depth,
            st.max_waiting,
            st.max_leaf_tris,
            st.sah_cost,
            st.nodes * std::mem::size_of::<crate::layout::BvhNode>(),
            build.as_secs_f64() * 1e3
        ),
    ));
}
