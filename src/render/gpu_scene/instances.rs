//! Instancing on the device: each instanced mesh in its own space with a BVH of its own, the top-level BVH over the
//! instances that place them, their records (and a moving instance's keys), and an emissive mesh's light table.
use super::emission::Emission;
use super::lights::Emitter;
use super::pack::{pack_triangles, MeshTriangles, PackedTriangles};
use crate::bvh::lights::LightBounds;
use crate::bvh::motion::Pose;
use crate::bvh::{self, Bvh};
use crate::constants::*;
use crate::layout::{GpuInstance, GpuLight, TriColors};
use crate::scene::Scene;
use glam::Vec3;

/// What instancing adds to the packed scene: the instance records (the header first), each emissive mesh's light
/// table, its emitters for the light tree, and where each mesh's triangles are.
#[derive(Default)]
pub(super) struct Instanced {
    pub records: Vec<GpuInstance>,
    pub mesh_lights: Vec<GpuLight>,
    pub mesh_emitters: Vec<MeshEmitters>,
    pub meshes: Vec<MeshTriangles>,
}

/// An instanced mesh in its own space: its BVH, its packed triangles and their box.
struct Part {
    mesh: usize,
    blas: Bvh,
    packed: PackedTriangles,
    bounds: (Vec3, Vec3),
}

/// An instance that places a part: world from object at each key of the shutter (one key when the instance does not
/// move; MOTION_SEGMENTS + 1 when it does, the rule made every one invertible), the keys as poses (None for a still
/// instance, or keys with shear, which the device interpolates as matrices), and the instance's index in the scene.
struct Placed {
    part: usize,
    keys: Vec<glam::Mat4>,
    poses: Option<Vec<Pose>>,
    index: u32,
}

/// Where a part's triangles and light table went: its BVH's root, and its table's start, length, power in the mesh's
/// space and the bounds of all its emitters.
struct Appended {
    root: u32,
    first_light: u32,
    lights: u32,
    power: f64,
    cone: Option<LightBounds>,
}

/// Every mesh `instanced` marks in its own space, after the world's triangles, with a BVH of its own; a top-level
/// BVH over the instances that place them; and the instance records (the header first). Nodes end up as [world
/// BVH][TLAS][each mesh's BVH], every index offset to its place. Grows `bounds` by the instances' boxes.
///
/// An emissive mesh's triangles get a table of their own (records point into it from 0, so the caller offsets them
/// past light selection's table), picked in proportion to their power in the mesh's space by the power and uniform
/// samplers, and the bounds of its emitters (entries of that table) for the light tree's subtree of the mesh; each of
/// its instances becomes one emitter in `t.emitters`, whose power is the mesh's scaled by the transform's area factor
/// |det|^(2/3). Exact for rotations and uniform scales; under a stretch the pick is a little off the power, which
/// costs variance, not bias: the device divides by the pick's own probability and the triangle's area in the world.
/// None when the host runs out of memory.
pub(super) fn pack_instances(
    scene: &Scene,
    instanced: &[bool],
    bvh: &mut Bvh,
    t: &mut PackedTriangles,
    bounds: &mut Option<(Vec3, Vec3)>,
    emission: &mut Emission,
) -> Option<Instanced> {
    let mut parts = parts(scene, instanced, emission)?;
    let placed = placements(scene, instanced, &parts);
    let boxes: Vec<(Vec3, Vec3)> = placed.iter().map(|p| placed_box(parts[p.part].bounds, p)).collect();
    for b in &boxes {
        *bounds = Some(bounds.map_or(*b, |(lo, hi)| (lo.min(b.0), hi.max(b.1))));
    }
    let tlas = bvh::build_boxes(&boxes);
    let tlas_root = bvh.nodes.len() as u32;
    // TLAS leaves index instance records, which start at 1 (after the header) in the TLAS's order.
    bvh.nodes.extend(tlas.nodes.iter().map(|n| {
        let mut n = *n;
        n.offset(tlas_root, 1);
        n
    }));
    let first_blas_triangle = t.tri_verts.len() as u32;
    let mut out = Instanced::default();
    let appended = append_parts(&mut parts, bvh, t, &mut out)?;
    let moving = placed.iter().filter(|p| p.keys.len() > 1).count();
    out.records
        .try_reserve_exact(1 + placed.len() + moving * (MOTION_SEGMENTS as usize + 1))
        .ok()?;
    out.records.push(GpuInstance {
        info: [tlas_root, placed.len() as u32, first_blas_triangle, 0],
        ..Default::default()
    });
    let ordered = tlas.order.iter().map(|&i| &placed[i as usize]);
    instance_records(ordered, &appended, &mut out.records, &mut t.emitters)?;
    Some(out)
}

/// Each instanced mesh's BVH and packed triangles (meshes without triangles have none).
fn parts(scene: &Scene, instanced: &[bool], emission: &mut Emission) -> Option<Vec<Part>> {
    let mut parts = Vec::new();
    for (mesh, _) in instanced.iter().enumerate().filter(|(_, &i)| i) {
        let soup = scene.object_soup(mesh);
        if soup.is_empty() {
            continue;
        }
        let blas = bvh::build(soup.positions());
        let packed = pack_triangles(scene, &soup, None, &blas.order, emission)?;
        parts.push(Part {
            mesh,
            blas,
            packed,
            bounds: soup.bounds(),
        });
    }
    Some(parts)
}

/// The scene's instances of instanced meshes that have a part, with their keys over the shutter.
fn placements(scene: &Scene, instanced: &[bool], parts: &[Part]) -> Vec<Placed> {
    let part_of = |m: usize| parts.iter().position(|p| p.mesh == m);
    (scene.instances.iter().enumerate())
        .filter(|(_, i)| instanced[i.mesh] && crate::scene::invertible(&i.world_from_object))
        .filter_map(|(k, i)| {
            let mut keys = vec![i.world_from_object];
            if let Some(motion) = &scene.motion {
                keys.extend(motion.keys.iter().map(|key| key.instances[k].world_from_object));
                if keys.iter().all(|w| *w == keys[0]) {
                    keys.truncate(1);
                }
            }
            let poses = (keys.len() > 1)
                .then(|| crate::bvh::motion::decompose_keys(&keys))
                .flatten();
            Some(Placed {
                part: part_of(i.mesh)?,
                keys,
                poses,
                index: k as u32,
            })
        })
        .collect()
}

/// A placed part's box in the world. A moving instance's holds its mesh all along its arc (see swept_box); keys
/// interpolated as matrices move each point linearly between its places at the keys, so there the keys' boxes hold
/// it.
fn placed_box((lo, hi): (Vec3, Vec3), p: &Placed) -> (Vec3, Vec3) {
    if let Some(poses) = &p.poses {
        return crate::bvh::motion::swept_box(lo, hi, poses);
    }
    let mut b = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
    for (w, corner) in (p.keys.iter()).flat_map(|w| crate::scene::box_corners(lo, hi).map(|c| (w, c))) {
        let q = w.transform_point3(corner);
        b = (b.0.min(q), b.1.max(q));
    }
    b
}

/// Appends each part's triangles after the world's, its BVH after the nodes, and its emitters' table to
/// `out.mesh_lights` (with their bounds to `out.mesh_emitters`); vertex colours become white where only some parts
/// have them.
fn append_parts(
    parts: &mut [Part],
    bvh: &mut Bvh,
    t: &mut PackedTriangles,
    out: &mut Instanced,
) -> Option<Vec<Appended>> {
    let colored = !t.tri_colors.is_empty() || parts.iter().any(|p| !p.packed.tri_colors.is_empty());
    let white = TriColors {
        c0: [1.0; 4],
        c1: [1.0; 4],
        c2: [1.0; 4],
    };
    if colored && t.tri_colors.is_empty() {
        t.tri_colors = vec![white; t.tri_verts.len()];
    }
    let mut appended = Vec::with_capacity(parts.len());
    for Part { blas, packed, .. } in parts {
        let root = bvh.nodes.len() as u32;
        let tri_base = t.tri_verts.len() as u32;
        let power: f64 = packed.emitters.iter().map(|e| e.power).sum();
        let cone = (packed.emitters.iter().filter_map(|e| e.bounds)).reduce(|a, b| a.union(&b));
        let first_light = out.mesh_lights.len() as u32;
        appended.push(Appended {
            root,
            first_light,
            lights: packed.emitters.len() as u32,
            power,
            cone,
        });
        if !packed.emitters.is_empty() {
            let bounds = packed.emitters.iter().enumerate();
            let bounds = bounds.filter_map(|(i, e)| e.bounds.map(|b| (first_light + i as u32, b)));
            out.mesh_emitters.push((first_light, bounds.collect()));
        }
        mesh_light_table(&packed.emitters, tri_base, power, &mut out.mesh_lights)?;
        bvh.nodes.extend(blas.nodes.iter().map(|n| {
            let mut n = *n;
            n.offset(root, tri_base);
            n
        }));
        let n = packed.tri_verts.len();
        out.meshes.push(MeshTriangles {
            root,
            first: tri_base,
            count: n as u32,
        });
        t.tri_verts.try_reserve(n).ok()?;
        t.tri_verts.append(&mut packed.tri_verts);
        t.tri_shading.append(&mut packed.tri_shading);
        t.tri_texcoords.append(&mut packed.tri_texcoords);
        t.tri_tangents.append(&mut packed.tri_tangents);
        if colored && packed.tri_colors.is_empty() {
            packed.tri_colors = vec![white; n];
        }
        t.tri_colors.append(&mut packed.tri_colors);
        let s = &blas.stats;
        bvh.stats.max_waiting = bvh.stats.max_waiting.max(s.max_waiting);
        bvh.stats.leaves += s.leaves;
        bvh.stats.max_leaf_tris = bvh.stats.max_leaf_tris.max(s.max_leaf_tris);
    }
    bvh.stats.nodes = bvh.nodes.len();
    Some(appended)
}

/// A mesh's emitters as a table picked in proportion to power (`power` their sum), its triangles numbered from
/// `tri_base`.
fn mesh_light_table(emitters: &[Emitter], tri_base: u32, power: f64, table: &mut Vec<GpuLight>) -> Option<()> {
    let (mut acc, mut previous_cdf) = (0.0f64, 0.0f32);
    for (i, e) in emitters.iter().enumerate() {
        acc += e.power;
        let cdf = match i + 1 == emitters.len() {
            true => 1.0,
            false => (acc / power) as f32,
        };
        let prob = cdf - previous_cdf;
        previous_cdf = cdf;
        table.try_reserve(1).ok()?;
        table.push(GpuLight {
            id: LIGHT_KIND_TRIANGLE << LIGHT_KIND_SHIFT | (tri_base + e.id),
            cdf,
            prob,
            area: e.area,
        });
    }
    Some(())
}

/// The instances' records in the TLAS's order, then each moving instance's keys (MOTION_SEGMENTS + 1 records from
/// the one its own record's info.w names); an instance of an emissive mesh becomes one emitter.
fn instance_records<'a>(
    ordered: impl ExactSizeIterator<Item = &'a Placed>,
    appended: &[Appended],
    records: &mut Vec<GpuInstance>,
    emitters: &mut Vec<Emitter>,
) -> Option<()> {
    let mut later_keys = 1 + ordered.len() as u32;
    let mut key_records = Vec::new();
    for p in ordered {
        let (keys, poses) = (&p.keys, p.poses.as_deref());
        let mirrored = crate::scene::handedness(&keys[0]);
        let moves = keys.len() > 1;
        let first_key = if moves { later_keys } else { 0 };
        later_keys += if moves { keys.len() as u32 } else { 0 };
        let a = &appended[p.part];
        let info = [a.root, mirrored as u32, p.index, first_key];
        let light = [a.first_light, a.lights, 0, 0];
        if a.lights > 0 {
            let stretch = glam::Mat3::from_mat4(keys[0]).determinant().abs().powf(2.0 / 3.0) as f64;
            emitters.try_reserve(1).ok()?;
            emitters.push(Emitter {
                id: LIGHT_KIND_INSTANCE << LIGHT_KIND_SHIFT | records.len() as u32,
                power: a.power * stretch,
                area: 0.0,
                bounds: a.cone.map(|c| c.transformed(keys, poses, (a.power * stretch) as f32)),
            });
        }
        records.push(instance_record(&keys[0], info, light));
        if moves {
            // Only a key record's transforms are read (instance_at keeps the instance's own info and light).
            key_records.extend(
                keys.iter()
                    .enumerate()
                    .map(|(j, w)| key_record(w, poses.map(|p| p[j]), info)),
            );
        }
    }
    records.append(&mut key_records);
    Some(())
}

/// An instanced mesh's emitters for its light subtree: where its table starts among the instanced meshes' tables,
/// and each emitter's place there with its bounds in the mesh's space.
pub(super) type MeshEmitters = (u32, Vec<(u32, LightBounds)>);

/// One instance record: `world_from_object` and its inverse as rows, `info` and `light` (see GpuInstance).
pub(super) fn instance_record(world_from_object: &glam::Mat4, info: [u32; 4], light: [u32; 4]) -> GpuInstance {
    let (w, o) = (world_from_object, world_from_object.inverse());
    GpuInstance {
        world0: w.row(0).to_array(),
        world1: w.row(1).to_array(),
        world2: w.row(2).to_array(),
        object0: o.row(0).to_array(),
        object1: o.row(1).to_array(),
        object2: o.row(2).to_array(),
        info,
        light,
    }
}

/// One key of a moving instance: `world_from_object` as rows (interpolated when the keys do not decompose), and in
/// place of the inverse, which instance_at computes, the key's pose (see GpuInstance).
pub(super) fn key_record(
    world_from_object: &glam::Mat4,
    pose: Option<crate::bvh::motion::Pose>,
    info: [u32; 4],
) -> GpuInstance {
    let w = world_from_object;
    let (object0, object1, object2) = match pose {
        Some(p) => (
            p.translation.extend(1.0).to_array(),
            p.rotation.to_array(),
            p.scale.extend(0.0).to_array(),
        ),
        None => ([0.0; 4], [0.0; 4], [0.0; 4]),
    };
    GpuInstance {
        world0: w.row(0).to_array(),
        world1: w.row(1).to_array(),
        world2: w.row(2).to_array(),
        object0,
        object1,
        object2,
        info,
        light: [0; 4],
    }
}
