//! Tangent frames for normal maps whose mesh has no TANGENT: MikkTSpace, as glTF asks, with a per-triangle fallback.
use glam::{Vec2, Vec3, Vec4};

struct Faces<'a> {
    positions: &'a [[Vec3; 3]],
    normals: &'a [[Vec3; 3]],
    uvs: &'a [[Vec2; 3]],
    out: Vec<[Vec4; 3]>,
}

impl mikktspace::Geometry for Faces<'_> {
    fn num_faces(&self) -> usize {
        self.positions.len()
    }
    fn num_vertices_of_face(&self, _face: usize) -> usize {
        3
    }
    fn position(&self, face: usize, vert: usize) -> [f32; 3] {
        self.positions[face][vert].into()
    }
    fn normal(&self, face: usize, vert: usize) -> [f32; 3] {
        self.normals[face][vert].into()
    }
    fn tex_coord(&self, face: usize, vert: usize) -> [f32; 2] {
        up_uv(self.uvs[face][vert]).into()
    }
    fn set_tangent_encoded(&mut self, tangent: [f32; 4], face: usize, vert: usize) {
        self.out[face][vert] = Vec4::from(tangent);
    }
}

/// glTF's v grows down the image, but its normal maps' +Y points up the image (bitangent = cross(normal, tangent) * w
/// is "up"): tangent frames are built from (u, -v), so their bitangent follows decreasing v.
fn up_uv(uv: Vec2) -> Vec2 {
    Vec2::new(uv.x, -uv.y)
}

/// Per-vertex tangents (xyz) and bitangent signs (w) of world-space triangles. Vertices MikkTSpace leaves without
/// a usable tangent (degenerate uvs) get their triangle's uv-gradient frame.
pub fn generate(positions: &[[Vec3; 3]], normals: &[[Vec3; 3]], uvs: &[[Vec2; 3]]) -> Vec<[Vec4; 3]> {
    let mut faces = Faces {
        positions,
        normals,
        uvs,
        out: vec![[Vec4::ZERO; 3]; positions.len()],
    };
    // MikkTSpace is a port of C code; a panic on strange input must not take the loader down with it.
    let ok = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        mikktspace::generate_tangents(&mut faces)
    }))
    .unwrap_or(false);
    let mut out = if ok {
        faces.out
    } else {
        vec![[Vec4::ZERO; 3]; positions.len()]
    };
    for (f, tri) in out.iter_mut().enumerate() {
        let fallback = triangle_tangent(positions[f], uvs[f].map(up_uv));
        for (v, t) in tri.iter_mut().enumerate() {
            let usable = t.is_finite() && t.truncate().length_squared() > 1e-12 && t.w != 0.0;
            if !usable {
                let n = normals[f][v];
                // Gram-Schmidt against the vertex normal, or any perpendicular when the gradient is parallel to it.
                let tt =
                    (fallback.truncate() - n * n.dot(fallback.truncate())).normalize_or(n.any_orthonormal_vector());
                *t = tt.extend(fallback.w);
            }
        }
    }
    out
}

/// The direction of increasing u on the triangle, and the handedness of (tangent, direction of increasing v, normal).
fn triangle_tangent(p: [Vec3; 3], uv: [Vec2; 3]) -> Vec4 {
    let (e1, e2) = (p[1] - p[0], p[2] - p[0]);
    let (d1, d2) = (uv[1] - uv[0], uv[2] - uv[0]);
    let det = d1.x * d2.y - d2.x * d1.y;
    let n = e1.cross(e2);
    if det.abs() < 1e-20 {
        return n.normalize_or(Vec3::Z).any_orthonormal_vector().extend(1.0);
    }
    let t = (e1 * d2.y - e2 * d1.y) / det;
    let b = (e2 * d1.x - e1 * d2.x) / det;
    let sign = if n.cross(t).dot(b) < 0.0 { -1.0 } else { 1.0 };
    t.normalize_or(n.normalize_or(Vec3::Z).any_orthonormal_vector())
        .extend(sign)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A quad in the xy plane facing +z, with u along +x and v along -y (glTF's v points down the image).
    #[test]
    fn tangent_follows_u_and_sign_follows_v() {
        let p = [
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(1.0, 1.0, 0.0),
        ];
        let n = [Vec3::Z; 3];
        let uv = [Vec2::new(0.0, 1.0), Vec2::new(1.0, 1.0), Vec2::new(1.0, 0.0)];
        for t in generate(&[p], &[n], &[uv])[0] {
            assert!((t.truncate() - Vec3::X).length() < 1e-5, "{t}");
            // Bitangent = sign * cross(n, t) = sign * +y must point up the image, where v shrinks: +y.
            assert_eq!(t.w, 1.0);
        }
        // Mirrored uvs (v growing along +y) flip the sign.
        let mirrored = uv.map(|t| Vec2::new(t.x, 1.0 - t.y));
        for t in generate(&[p], &[n], &[mirrored])[0] {
            assert!((t.truncate() - Vec3::X).length() < 1e-5 && t.w == -1.0, "{t}");
        }
    }
}
