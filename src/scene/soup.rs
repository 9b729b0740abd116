//! The world-space triangle soup the renderer packs, and `Scene::flatten`, which places every instance to make it.
use super::{tangent, Primitive, Scene};
use crate::error::Error;
use glam::{Mat3, Mat4, Vec2, Vec3, Vec4};

/// The largest world coordinate (in magnitude) a scene may place geometry at; see `Scene::check_extent`.
pub const MAX_WORLD_COORDINATE: f32 = 1e9;

/// One world-space triangle and its per-vertex shading data: what `TriangleSoup::push` takes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WorldTriangle {
    /// Front face counter-clockwise.
    pub positions: [Vec3; 3],
    pub normals: [Vec3; 3],
    /// TEXCOORD_0 in xy and TEXCOORD_1 in zw (zero where the mesh has none).
    pub texcoords: [Vec4; 3],
    /// The tangent in xyz and the bitangent's sign in w (zero where the material has no normal map).
    pub tangents: [Vec4; 3],
    /// COLOR_0 as linear RGBA; `None` where the mesh has none.
    pub colors: Option<[Vec4; 3]>,
    pub material: u32,
    /// The index in `Scene::instances` of the instance that placed it (0 for a mesh in its own space): the
    /// instance-id AOV.
    pub instance: u32,
}

/// Per-triangle world-space arrays, index for index. `push` is the only way in, so they cannot fall out of step.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TriangleSoup {
    positions: Vec<[Vec3; 3]>,
    normals: Vec<[Vec3; 3]>,
    texcoords: Vec<[Vec4; 3]>,
    tangents: Vec<[Vec4; 3]>,
    colors: Vec<[Vec4; 3]>,
    material: Vec<u32>,
    instance: Vec<u32>,
}

impl TriangleSoup {
    /// Room for `n` triangles (COLOR_0 aside, which few scenes have), or the allocator's refusal.
    fn try_with_capacity(n: usize) -> Result<Self, std::collections::TryReserveError> {
        let mut soup = TriangleSoup::default();
        soup.positions.try_reserve_exact(n)?;
        soup.normals.try_reserve_exact(n)?;
        soup.texcoords.try_reserve_exact(n)?;
        soup.tangents.try_reserve_exact(n)?;
        soup.material.try_reserve_exact(n)?;
        soup.instance.try_reserve_exact(n)?;
        Ok(soup)
    }

    pub fn push(&mut self, t: WorldTriangle) {
        self.positions.push(t.positions);
        self.normals.push(t.normals);
        self.texcoords.push(t.texcoords);
        self.tangents.push(t.tangents);
        match t.colors {
            Some(c) => {
                // The first coloured triangle gives every earlier one white.
                self.colors.resize(self.positions.len() - 1, [Vec4::ONE; 3]);
                self.colors.push(c);
            }
            None if !self.colors.is_empty() => self.colors.push([Vec4::ONE; 3]),
            None => {}
        }
        self.material.push(t.material);
        self.instance.push(t.instance);
    }

    pub fn len(&self) -> usize {
        self.positions.len()
    }
    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }
    pub fn positions(&self) -> &[[Vec3; 3]] {
        &self.positions
    }
    pub fn normals(&self) -> &[[Vec3; 3]] {
        &self.normals
    }
    pub fn texcoords(&self) -> &[[Vec4; 3]] {
        &self.texcoords
    }
    pub fn tangents(&self) -> &[[Vec4; 3]] {
        &self.tangents
    }
    /// Empty when no triangle has COLOR_0; otherwise one per triangle (white where its mesh has none).
    pub fn colors(&self) -> &[[Vec4; 3]] {
        &self.colors
    }
    pub fn material(&self) -> &[u32] {
        &self.material
    }
    /// Each triangle's instance (`WorldTriangle::instance`).
    pub fn instance(&self) -> &[u32] {
        &self.instance
    }
    pub fn bounds(&self) -> (Vec3, Vec3) {
        bounds(self.positions.iter().copied())
    }

    /// MikkTSpace tangents for the triangles from `first` on, from their uv set `set`.
    fn generate_tangents(&mut self, first: usize, set: usize) {
        let range = first..self.positions.len();
        let uvs: Vec<[Vec2; 3]> = self.texcoords[range.clone()]
            .iter()
            .map(|t| {
                t.map(|v| {
                    if set == 0 {
                        Vec2::new(v.x, v.y)
                    } else {
                        Vec2::new(v.z, v.w)
                    }
                })
            })
            .collect();
        let generated = tangent::generate(&self.positions[range.clone()], &self.normals[range.clone()], &uvs);
        self.tangents[range].copy_from_slice(&generated);
    }
}

/// The eight corners of the box (lo, hi).
pub fn box_corners(lo: Vec3, hi: Vec3) -> [Vec3; 8] {
    std::array::from_fn(|c| {
        Vec3::new(
            if c & 1 == 0 { lo.x } else { hi.x },
            if c & 2 == 0 { lo.y } else { hi.y },
            if c & 4 == 0 { lo.z } else { hi.z },
        )
    })
}

/// The box around `triangles` (inverted, +inf to -inf, when there is none).
pub fn soup_bounds(triangles: &[[Vec3; 3]]) -> (Vec3, Vec3) {
    bounds(triangles.iter().copied())
}

pub(super) fn bounds(triangles: impl Iterator<Item = [Vec3; 3]>) -> (Vec3, Vec3) {
    let mut lo = Vec3::splat(f32::INFINITY);
    let mut hi = Vec3::splat(f32::NEG_INFINITY);
    for t in triangles {
        for v in t {
            lo = lo.min(v);
            hi = hi.max(v);
        }
    }
    (lo, hi)
}

/// What an instance's transform does to its mesh: to points, to normals, and to the winding.
#[derive(Clone, Copy)]
struct Placement {
    world: Mat4,
    normal_matrix: Mat3,
    /// A mirroring transform turns counter-clockwise into clockwise; two vertices are swapped to keep the front face.
    flip: bool,
    /// What the triangles' `instance` says.
    instance: u32,
}

impl Placement {
    fn new(world: Mat4) -> Placement {
        Placement {
            instance: 0,
            world,
            normal_matrix: Mat3::from_mat4(world).inverse().transpose(),
            flip: Mat3::from_mat4(world).determinant() < 0.0,
        }
    }

    /// The triangle's vertex indices in front-face order.
    fn corners(&self, [a, b, c]: [u32; 3]) -> [u32; 3] {
        if self.flip {
            [a, c, b]
        } else {
            [a, b, c]
        }
    }

    /// The world-space vertices of corners `abc`.
    fn positions(&self, positions: &[Vec3], abc: [u32; 3]) -> [Vec3; 3] {
        abc.map(|i| self.world.transform_point3(positions[i as usize]))
    }

    /// The triangle's vertex indices in front-face order, its world-space vertices and its face normal, or `None`
    /// when it is degenerate in world space (no area: it can be neither hit nor emit).
    fn triangle(&self, positions: &[Vec3], tri: [u32; 3]) -> Option<([u32; 3], [Vec3; 3], Vec3)> {
        let abc = self.corners(tri);
        let v = self.positions(positions, abc);
        Some((abc, v, face_normal(v)?))
    }

    /// World-space shading normals of corners `abc`, the face normal where the primitive has none (or one that
    /// does not survive the transform).
    fn normals(&self, p: &Primitive, abc: [u32; 3], face_n: Vec3) -> [Vec3; 3] {
        match &p.normals {
            Some(ns) => abc.map(|i| {
                let n = self.normal_matrix * ns[i as usize];
                if n.is_finite() && n.length_squared() > 0.0 {
                    n.normalize()
                } else {
                    face_n
                }
            }),
            None => [face_n; 3],
        }
    }

    /// The placed triangle with its shading data, given its corners, world-space vertices and face normal.
    fn world_triangle(&self, p: &Primitive, abc: [u32; 3], positions: [Vec3; 3], face_n: Vec3) -> WorldTriangle {
        let normals = self.normals(p, abc, face_n);
        let uv = |set: usize, i: u32| p.texcoords[set].as_ref().map_or(Vec2::ZERO, |u| u[i as usize]);
        let texcoords = abc.map(|i| {
            let (t0, t1) = (uv(0, i), uv(1, i));
            Vec4::new(t0.x, t0.y, t1.x, t1.y)
        });
        let tangents = match &p.tangents {
            // A mirroring transform flips the bitangent relative to cross(normal, tangent).
            Some(ts) => abc.map(|i| {
                let t = ts[i as usize];
                let tw = (Mat3::from_mat4(self.world) * t.truncate()).normalize_or_zero();
                let sign = if (t.w < 0.0) != self.flip { -1.0 } else { 1.0 };
                tw.extend(sign)
            }),
            None => [Vec4::ZERO; 3],
        };
        WorldTriangle {
            positions,
            normals,
            texcoords,
            tangents,
            colors: p.colors.as_ref().map(|c| abc.map(|i| c[i as usize])),
            material: p.material,
            instance: self.instance,
        }
    }

    fn push_primitive(&self, p: &Primitive, soup: &mut TriangleSoup) {
        for &tri in &p.triangles {
            let Some((abc, positions, face_n)) = self.triangle(&p.positions, tri) else {
                continue;
            };
            soup.push(self.world_triangle(p, abc, positions, face_n));
        }
    }
}

/// The unit normal of a counter-clockwise triangle, or None when it has no area (or is not finite).
fn face_normal(v: [Vec3; 3]) -> Option<Vec3> {
    let face = (v[1] - v[0]).cross(v[2] - v[0]);
    if face.length_squared() == 0.0 || !face.is_finite() {
        return None;
    }
    Some(face.normalize())
}

/// One triangle at one key of the motion: world-space vertices and shading normals.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct KeyTriangle {
    pub positions: [Vec3; 3],
    pub normals: [Vec3; 3],
}

impl Scene {
    /// Every instance's triangles in world space, instances in order, then primitives, then triangles, dropping those
    /// without area. The arithmetic is the loader's before meshes were shared, so images stay byte for byte the same.
    pub fn flatten(&self) -> TriangleSoup {
        let mut soup = TriangleSoup::default();
        self.flatten_into(&mut soup, &vec![false; self.meshes.len()]);
        soup
    }

    /// Refuses geometry placed beyond MAX_WORLD_COORDINATE, naming the mesh and the instance: traversal's slab tests
    /// stay finite only within it (the Cornell box renders the same scaled by anything from 1e-8 to 7e9; scaled by
    /// 1e10 it loses light). O(vertices + instances): each mesh's box, its corners placed by each instance and key.
    pub fn check_extent(&self) -> Result<(), Error> {
        let mesh_box =
            |m: &super::Mesh| bounds(m.primitives.iter().flat_map(|p| p.positions.iter().map(|&v| [v, v, v])));
        let boxes: Vec<(Vec3, Vec3)> = self.meshes.iter().map(mesh_box).collect();
        let keys = self.motion.as_ref().map_or(0, |m| m.keys.len());
        for k in 0..=keys {
            let instances = match (k, &self.motion) {
                (k, Some(m)) if k > 0 => &m.keys[k - 1].instances,
                _ => &self.instances,
            };
            for (i, instance) in instances.iter().enumerate() {
                let (lo, hi) = if k == 0 {
                    boxes[instance.mesh]
                } else {
                    mesh_box(self.key_mesh(k, instance.mesh))
                };
                if lo.x > hi.x {
                    continue;
                }
                let reach = (box_corners(lo, hi).iter())
                    .map(|&c| instance.world_from_object.transform_point3(c).abs().max_element())
                    .fold(0.0f32, |a, b| if b.is_nan() { f32::INFINITY } else { a.max(b) });
                if reach > MAX_WORLD_COORDINATE {
                    let mesh = self.key_mesh(k, instance.mesh).name.as_str();
                    return Err(Error::Scene {
                        path: self.path.clone(),
                        message: format!(
                            "mesh '{mesh}' (instance {i}) reaches {reach:e} in world space; pathwave renders geometry \
                             within ±{MAX_WORLD_COORDINATE:e} units (1e9 m is past the Moon's orbit): rescale the scene"
                        ),
                    });
                }
            }
        }
        Ok(())
    }

    /// `flatten`, with the soup's memory reserved first, so a host out of memory is an error rather than an abort.
    pub fn try_flatten(&self) -> Result<TriangleSoup, Error> {
        self.try_flatten_except(&vec![false; self.meshes.len()])
    }

    /// `try_flatten` of the instances of every mesh but those `instanced` marks (which stay in object space).
    pub fn try_flatten_except(&self, instanced: &[bool]) -> Result<TriangleSoup, Error> {
        let n = self.flattened_triangle_bound_except(instanced);
        let mut soup = usize::try_from(n)
            .ok()
            .and_then(|n| TriangleSoup::try_with_capacity(n).ok())
            .ok_or_else(|| Error::Scene {
                path: self.path.clone(),
                message: format!("out of host memory placing its {n} triangles"),
            })?;
        self.flatten_into(&mut soup, instanced);
        Ok(soup)
    }

    /// Mesh `m` in its own space: its triangles placed by the identity, for a BVH of its own.
    pub fn object_soup(&self, m: usize) -> TriangleSoup {
        let mut soup = TriangleSoup::default();
        let identity = Placement::new(Mat4::IDENTITY);
        for p in &self.meshes[m].primitives {
            let first = soup.len();
            identity.push_primitive(p, &mut soup);
            // In the mesh's space, once for all its instances (each takes them into the world when shading).
            if let (Some(set), None) = (self.materials[p.material as usize].tangent_set(), &p.tangents) {
                soup.generate_tangents(first, set as usize);
            }
        }
        soup
    }

    /// `try_flatten` over the shutter: the soup at key 0 (the shutter's opening) and, for each later key of
    /// `Scene::motion`, every soup triangle's vertices and normals there, index for index (None without motion).
    /// Every key places the same triangles: one is dropped only when it has no area at any key, and one without
    /// area at key 0 takes the normals of the first key where it has some.
    #[allow(clippy::type_complexity)]
    pub fn try_flatten_motion(&self) -> Result<(TriangleSoup, Option<Vec<Vec<KeyTriangle>>>), Error> {
        self.try_flatten_motion_except(&vec![false; self.meshes.len()])
    }

    /// `try_flatten_motion` of the instances of every mesh but those `instanced` marks (which stay in object space,
    /// moved by their instances' keys).
    #[allow(clippy::type_complexity)]
    pub fn try_flatten_motion_except(
        &self,
        instanced: &[bool],
    ) -> Result<(TriangleSoup, Option<Vec<Vec<KeyTriangle>>>), Error> {
        let Some(motion) = &self.motion else {
            return Ok((self.try_flatten_except(instanced)?, None));
        };
        let n = self.flattened_triangle_bound_except(instanced);
        let oom = || Error::Scene {
            path: self.path.clone(),
            message: format!("out of host memory placing its {n} triangles at every key of the motion"),
        };
        let mut soup = usize::try_from(n)
            .ok()
            .and_then(|n| TriangleSoup::try_with_capacity(n).ok())
            .ok_or_else(oom)?;
        let mut keys: Vec<Vec<KeyTriangle>> = Vec::new();
        for _ in &motion.keys {
            let mut v = Vec::new();
            v.try_reserve_exact(n as usize).map_err(|_| oom())?;
            keys.push(v);
        }
        let key_count = motion.keys.len() + 1;
        for (i, instance) in self.instances.iter().enumerate().filter(|(_, i)| !instanced[i.mesh]) {
            let placements: Vec<Placement> = (0..key_count)
                .map(|k| match k {
                    0 => Placement::new(instance.world_from_object),
                    k => Placement::new(motion.keys[k - 1].instances[i].world_from_object),
                })
                .map(|p| Placement {
                    instance: i as u32,
                    ..p
                })
                .collect();
            let meshes: Vec<&super::Mesh> = (0..key_count)
                .map(|k| match k {
                    0 => &self.meshes[instance.mesh],
                    k => self.key_mesh(k, motion.keys[k - 1].instances[i].mesh),
                })
                .collect();
            for (pi, p) in meshes[0].primitives.iter().enumerate() {
                let first = soup.len();
                for &tri in &p.triangles {
                    // Key 0's winding for every key, so that the corners correspond.
                    let abc = placements[0].corners(tri);
                    let at: Vec<[Vec3; 3]> = (0..key_count)
                        .map(|k| placements[k].positions(&meshes[k].primitives[pi].positions, abc))
                        .collect();
                    let faces: Vec<Option<Vec3>> = at.iter().map(|v| face_normal(*v)).collect();
                    let Some(some_face) = faces.iter().flatten().next().copied() else {
                        continue;
                    };
                    soup.push(placements[0].world_triangle(p, abc, at[0], faces[0].unwrap_or(some_face)));
                    for k in 1..key_count {
                        let pk = &meshes[k].primitives[pi];
                        keys[k - 1].push(KeyTriangle {
                            positions: at[k],
                            normals: placements[k].normals(pk, abc, faces[k].unwrap_or(some_face)),
                        });
                    }
                }
                if let (Some(set), None) = (self.materials[p.material as usize].tangent_set(), &p.tangents) {
                    soup.generate_tangents(first, set as usize);
                }
            }
        }
        Ok((soup, Some(keys)))
    }

    fn flatten_into(&self, soup: &mut TriangleSoup, instanced: &[bool]) {
        for (i, instance) in self.instances.iter().enumerate().filter(|(_, i)| !instanced[i.mesh]) {
            let placement = Placement {
                instance: i as u32,
                ..Placement::new(instance.world_from_object)
            };
            for p in &self.meshes[instance.mesh].primitives {
                let first = soup.len();
                placement.push_primitive(p, soup);
                // Generated per instance on world-space triangles, as the loader did before meshes were shared: the
                // same tangents to the last bit. The two-level BVH moves this to object space, once per mesh.
                if let (Some(set), None) = (self.materials[p.material as usize].tangent_set(), &p.tangents) {
                    soup.generate_tangents(first, set as usize);
                }
            }
        }
    }

    /// The material and world-space vertices of every triangle `flatten` emits, in its order, without the shading data.
    pub(super) fn world_triangles(&self) -> impl Iterator<Item = (u32, [Vec3; 3])> + '_ {
        self.instances.iter().flat_map(move |instance| {
            let placement = Placement::new(instance.world_from_object);
            self.meshes[instance.mesh].primitives.iter().flat_map(move |p| {
                p.triangles
                    .iter()
                    .filter_map(move |&t| placement.triangle(&p.positions, t).map(|(_, v, _)| (p.material, v)))
            })
        })
    }
}
