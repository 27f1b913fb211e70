//! Tangent frames: glTF `TANGENT` when the file has it, else MikkTSpace (Mikkelsen 2008,
//! through `bevy_mikktspace`, a byte-identical safe port of the reference implementation),
//! computed with the base texture coordinates so the lightmap's tangent space is the normal
//! map's (\[Ish11\] §2.2.2).
//!
//! Convention (glTF 2.0 §3.7.2.1, MikkTSpace): `t` follows `dP/du`, the bitangent is
//! `b = w · n × t` with the handedness `w = ±1`; tangent space is `(x, y, z) = (t, b, n)`.

use glam::{DVec2, DVec3, DVec4};

/// An orthonormal tangent frame at a surface point: `t`, `b = w · n × t`, `n` (the
/// interpolated, normalised shading normal). With `w = -1` the frame is left-handed, as a
/// mirrored normal map's.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TangentFrame {
    /// Tangent (tangent-space `x`).
    pub t: DVec3,
    /// Bitangent (tangent-space `y`).
    pub b: DVec3,
    /// Normal (tangent-space `z`).
    pub n: DVec3,
}

impl TangentFrame {
    /// The frame from an interpolated normal, tangent and handedness: `n` normalised, `t`
    /// Gram-Schmidt orthogonalised against it (any perpendicular when `t` is parallel to `n`
    /// or zero), `b = w · n × t`.
    #[must_use]
    pub fn from_normal_tangent(n: DVec3, t: DVec3, w: f64) -> Self {
        let n = n.normalize_or(DVec3::Z);
        let mut t = (t - n * n.dot(t)).normalize_or_zero();
        if t == DVec3::ZERO {
            t = n.any_orthonormal_vector();
        }
        let w = if w < 0.0 { -1.0 } else { 1.0 };
        Self { t, b: n.cross(t) * w, n }
    }

    /// Tangent-space vector to world space: `x t + y b + z n`.
    #[must_use]
    #[inline]
    pub fn to_world(&self, local: DVec3) -> DVec3 {
        self.t * local.x + self.b * local.y + self.n * local.z
    }

    /// World vector to tangent space: `(t·v, b·v, n·v)`.
    #[must_use]
    #[inline]
    pub fn to_local(&self, v: DVec3) -> DVec3 {
        DVec3::new(self.t.dot(v), self.b.dot(v), self.n.dot(v))
    }
}

/// Input of [`mikktspace_tangents`]: triangles as vertex indices into the arrays.
#[derive(Debug)]
pub struct MikkInput<'a> {
    /// Vertex positions.
    pub positions: &'a [DVec3],
    /// Per-vertex normals, or `None` for flat (geometric) face normals.
    pub normals: Option<&'a [DVec3]>,
    /// Per-vertex texture coordinates (the normal map's set).
    pub uvs: &'a [DVec2],
    /// Triangles (counter-clockwise front faces).
    pub faces: &'a [[u32; 3]],
}

struct Mikk<'a> {
    input: &'a MikkInput<'a>,
    flat: Vec<DVec3>,
    out: Vec<[DVec4; 3]>,
}

impl Mikk<'_> {
    fn vertex(&self, face: usize, vert: usize) -> usize {
        self.input.faces[face][vert] as usize
    }
}

impl bevy_mikktspace::Geometry for Mikk<'_> {
    fn num_faces(&self) -> usize {
        self.input.faces.len()
    }
    fn num_vertices_of_face(&self, _face: usize) -> usize {
        3
    }
    fn position(&self, face: usize, vert: usize) -> [f32; 3] {
        self.input.positions[self.vertex(face, vert)].as_vec3().to_array()
    }
    fn normal(&self, face: usize, vert: usize) -> [f32; 3] {
        match self.input.normals {
            Some(n) => n[self.vertex(face, vert)].as_vec3().to_array(),
            None => self.flat[face].as_vec3().to_array(),
        }
    }
    fn tex_coord(&self, face: usize, vert: usize) -> [f32; 2] {
        self.input.uvs[self.vertex(face, vert)].as_vec2().to_array()
    }
    fn set_tangent(&mut self, ts: Option<bevy_mikktspace::TangentSpace>, face: usize, vert: usize) {
        if let Some(ts) = ts {
            let [x, y, z, w] = ts.tangent_encoded().map(f64::from);
            self.out[face][vert] = DVec4::new(x, y, z, w);
        }
    }
}

/// MikkTSpace tangents per face corner (`xyz` unit tangent, `w` handedness). Corners the
/// algorithm leaves without a value (isolated degenerate faces) get `(0, 0, 0, 1)`, which
/// [`TangentFrame::from_normal_tangent`] turns into an arbitrary perpendicular.
///
/// # Errors
/// A message when an index is out of range.
pub fn mikktspace_tangents(input: &MikkInput<'_>) -> Result<Vec<[DVec4; 3]>, String> {
    let nv = input.positions.len();
    if input.uvs.len() != nv || input.normals.is_some_and(|n| n.len() != nv) {
        return Err("attribute arrays differ in length".into());
    }
    if let Some(f) = input.faces.iter().find(|f| f.iter().any(|&i| i as usize >= nv)) {
        return Err(format!("face {f:?} refers to a vertex beyond {nv}"));
    }
    let flat = input
        .faces
        .iter()
        .map(|f| {
            let [a, b, c] = f.map(|i| input.positions[i as usize]);
            (b - a).cross(c - a).normalize_or(DVec3::Z)
        })
        .collect();
    let mut m = Mikk { input, flat, out: vec![[DVec4::new(0.0, 0.0, 0.0, 1.0); 3]; input.faces.len()] };
    bevy_mikktspace::generate_tangents(&mut m).map_err(|e| format!("{e:?}"))?;
    Ok(m.out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Tangents from MikkTSpace are unit, orthogonal to the normal after Gram-Schmidt, and
    /// on a flat UV-mapped quad equal the analytic `dP/du` (normalised), with the bitangent
    /// along `dP/dv`: here `P = (2u, v)` rotated by 30° in the plane, so `dP/du ∥ (cos, sin)`.
    #[test]
    fn flat_quad_matches_dp_du() {
        const TOL: f64 = 1e-6; // MikkTSpace works in f32
        let (c, s) = (30f64.to_radians().cos(), 30f64.to_radians().sin());
        let du = DVec3::new(2.0 * c, 2.0 * s, 0.0);
        let dv = DVec3::new(-s, c, 0.0);
        let uvs = [DVec2::new(0.0, 0.0), DVec2::new(1.0, 0.0), DVec2::new(1.0, 1.0), DVec2::new(0.0, 1.0)];
        let positions: Vec<DVec3> = uvs.iter().map(|uv| du * uv.x + dv * uv.y).collect();
        let normals = [DVec3::Z; 4];
        let faces = [[0, 1, 2], [0, 2, 3]];
        let input = MikkInput { positions: &positions, normals: Some(&normals), uvs: &uvs, faces: &faces };
        let t = mikktspace_tangents(&input).unwrap();
        for corner in t.iter().flatten() {
            assert!((corner.truncate() - du.normalize()).length() < TOL, "{corner}");
            assert_eq!(corner.w, 1.0);
            let f = TangentFrame::from_normal_tangent(DVec3::Z, corner.truncate(), corner.w);
            assert!((f.b - dv.normalize()).length() < TOL);
        }
        // Mirrored UVs (u → 1 - u) flip the handedness: b = w n × t still follows dP/dv.
        let mirrored: Vec<DVec2> = uvs.iter().map(|uv| DVec2::new(1.0 - uv.x, uv.y)).collect();
        let input = MikkInput { uvs: &mirrored, ..input };
        for corner in mikktspace_tangents(&input).unwrap().iter().flatten() {
            assert!((corner.truncate() + du.normalize()).length() < TOL, "{corner}");
            assert_eq!(corner.w, -1.0);
            let f = TangentFrame::from_normal_tangent(DVec3::Z, corner.truncate(), corner.w);
            assert!((f.b - dv.normalize()).length() < TOL);
        }
    }

    /// On a curved mesh with smooth normals every generated frame is orthonormal with
    /// `n` equal to the shading normal.
    #[test]
    fn frames_are_orthonormal_on_a_sphere_patch() {
        const TOL: f64 = 1e-9; // f64 Gram-Schmidt
        let n = 6;
        let mut positions = Vec::new();
        let mut uvs = Vec::new();
        for j in 0..=n {
            for i in 0..=n {
                let (u, v) = (i as f64 / n as f64, j as f64 / n as f64);
                let (th, ph) = (0.3 + 1.0 * v, 2.0 * u);
                positions.push(DVec3::new(th.sin() * ph.cos(), th.sin() * ph.sin(), th.cos()));
                uvs.push(DVec2::new(u, v));
            }
        }
        let normals: Vec<DVec3> = positions.iter().map(|p| p.normalize()).collect();
        let mut faces = Vec::new();
        for j in 0..n {
            for i in 0..n {
                let a = (j * (n + 1) + i) as u32;
                let (b, c, d) = (a + 1, a + n as u32 + 2, a + n as u32 + 1);
                faces.push([a, b, c]);
                faces.push([a, c, d]);
            }
        }
        let input = MikkInput { positions: &positions, normals: Some(&normals), uvs: &uvs, faces: &faces };
        let t = mikktspace_tangents(&input).unwrap();
        for (f, corners) in faces.iter().zip(&t) {
            for (k, c) in corners.iter().enumerate() {
                let nrm = normals[f[k] as usize];
                // The raw MikkTSpace tangent is already nearly perpendicular to the normal.
                assert!(c.truncate().dot(nrm).abs() < 1e-5, "{c} vs {nrm}");
                let fr = TangentFrame::from_normal_tangent(nrm, c.truncate(), c.w);
                assert!(
                    fr.t.dot(fr.n).abs() < TOL && fr.b.dot(fr.n).abs() < TOL && fr.t.dot(fr.b).abs() < TOL
                );
                assert!((fr.t.length() - 1.0).abs() < TOL && (fr.b.length() - 1.0).abs() < TOL);
                assert!((fr.n - nrm).length() < TOL);
            }
        }
        let bad = [[0, 1, 999]];
        assert!(mikktspace_tangents(&MikkInput { faces: &bad, ..input }).is_err());
    }
}
