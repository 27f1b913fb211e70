//! The watertight ray/triangle test of Woop, Benthin & Wald 2013 (\[WBW13\]), in f32: the
//! scalar reference the tracer's SIMD kernels are to match hit for hit.
//!
//! The ray is sheared so that it runs along +z through the origin (`kz` the dimension in
//! which `|d|` is largest, `kx`, `ky` the next two, swapped when `d[kz] < 0` to keep the
//! winding), the triangle's vertices are translated and sheared the same way, and the
//! scaled barycentrics are the 2D edge functions `U`, `V`, `W` of the origin
//! (\[WBW13\] §3, Fig. 2 and its listing). Two triangles that share an edge evaluate that
//! edge's function from the same two sheared vertices, in the same order of operations with
//! opposite signs, so a ray through the edge is inside at least one of them: no ray slips
//! through a closed mesh. Where an edge function is exactly 0 it is evaluated again in f64
//! (\[WBW13\] §3.3), so the sign decides consistently on both sides.
//!
//! A hit is reported for either face; `t` is computed as `T / det` after the sign tests.

/// A watertight hit: distance and barycentric weights of the three vertices.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WatertightHit {
    /// Distance along the ray (in units of `|d|`).
    pub t: f32,
    /// Weights of vertices 0, 1 and 2 (sum 1 up to rounding).
    pub bary: [f32; 3],
}

/// A watertight hit before the barycentric division: the distance and the scaled
/// barycentrics `U`, `V`, `W` with their sum `det` (\[WBW13\] Fig. 2). The tracer's SIMD
/// kernels return exactly these values for every lane they report.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RawHit {
    /// Distance along the ray, `T / det`.
    pub t: f32,
    /// Scaled weights of vertices 0, 1 and 2.
    pub uvw: [f32; 3],
    /// `U + V + W` (computed as `(U + V) + W`).
    pub det: f32,
}

impl RawHit {
    /// Weights `(u, v)` of vertices 1 and 2, `V / det` and `W / det`.
    #[must_use]
    #[inline]
    pub fn bary12(&self) -> [f32; 2] {
        [self.uvw[1] / self.det, self.uvw[2] / self.det]
    }
}

/// The shear of one ray (\[WBW13\] §3.1): the axis permutation and the shear constants,
/// computed once per ray.
#[derive(Clone, Copy, Debug)]
pub struct Shear {
    /// The permuted axes `kx`, `ky`, `kz`.
    pub(crate) k: [usize; 3],
    /// The shear constants `Sz = 1 / d[kz]`, `Sx = d[kx]·Sz`, `Sy = d[ky]·Sz`.
    pub(crate) s: [f32; 3],
    /// The ray's origin.
    pub(crate) origin: [f32; 3],
}

impl Shear {
    /// The shear of the ray `origin + t·dir` (`dir` not zero).
    #[must_use]
    pub fn new(origin: [f32; 3], dir: [f32; 3]) -> Self {
        let a = dir.map(f32::abs);
        let kz = if a[0] > a[1] {
            if a[0] > a[2] { 0 } else { 2 }
        } else if a[1] > a[2] {
            1
        } else {
            2
        };
        let mut kx = (kz + 1) % 3;
        let mut ky = (kx + 1) % 3;
        if dir[kz] < 0.0 {
            std::mem::swap(&mut kx, &mut ky);
        }
        // One division: `Sx = dx·(1/dz)`, `Sy = dy·(1/dz)` (as Embree computes them; the
        // test is watertight for any shear that is the same for every triangle).
        let sz = 1.0 / dir[kz];
        let s = [dir[kx] * sz, dir[ky] * sz, sz];
        Self { k: [kx, ky, kz], s, origin }
    }

    /// The vertex `v` relative to the origin, sheared: `(x, y)` in the ray's plane and the
    /// unscaled `z`.
    fn vertex(&self, v: [f32; 3]) -> [f32; 3] {
        let [kx, ky, kz] = self.k;
        let a = [v[0] - self.origin[0], v[1] - self.origin[1], v[2] - self.origin[2]];
        [a[kx] - self.s[0] * a[kz], a[ky] - self.s[1] * a[kz], a[kz]]
    }
}

/// The 2D edge function `bx·ay − by·ax`, evaluated again in f64 when the f32 result is 0.
fn edge(a: [f32; 3], b: [f32; 3]) -> f32 {
    let e = b[0] * a[1] - b[1] * a[0];
    if e == 0.0 { (f64::from(b[0]) * f64::from(a[1]) - f64::from(b[1]) * f64::from(a[0])) as f32 } else { e }
}

/// The watertight test of the sheared ray `shear` against the triangle `v` for
/// `t ∈ [tmin, tmax]`, before the barycentric division (module docs).
#[must_use]
pub fn intersect_raw(shear: &Shear, v: &[[f32; 3]; 3], tmin: f32, tmax: f32) -> Option<RawHit> {
    let (a, b, c) = (shear.vertex(v[0]), shear.vertex(v[1]), shear.vertex(v[2]));
    // U is the weight of A (the edge B-C), V of B (C-A), W of C (A-B).
    let u = edge(b, c);
    let w_v = edge(c, a);
    let w = edge(a, b);
    if (u < 0.0 || w_v < 0.0 || w < 0.0) && (u > 0.0 || w_v > 0.0 || w > 0.0) {
        return None;
    }
    let det = u + w_v + w;
    if det == 0.0 {
        return None;
    }
    let sz = shear.s[2];
    let t_scaled = u * (sz * a[2]) + w_v * (sz * b[2]) + w * (sz * c[2]);
    let t = t_scaled / det;
    if !(t >= tmin && t <= tmax) {
        return None;
    }
    Some(RawHit { t, uvw: [u, w_v, w], det })
}

/// The watertight test of the sheared ray `shear` against the triangle `v` for
/// `t ∈ [tmin, tmax]` (module docs).
#[must_use]
pub fn intersect(shear: &Shear, v: &[[f32; 3]; 3], tmin: f32, tmax: f32) -> Option<WatertightHit> {
    intersect_raw(shear, v, tmin, tmax).map(|h| WatertightHit { t: h.t, bary: h.uvw.map(|x| x / h.det) })
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use glam::DVec3;
    use lightvol_sh::lowdisc::SplitMix64;

    /// An icosahedron subdivided once (42 vertices, 80 faces) around the origin, outward
    /// winding: a closed mesh whose shared edges and vertices the rays below aim at.
    pub(crate) fn closed_mesh() -> (Vec<[f32; 3]>, Vec<[usize; 3]>) {
        let p = (1.0 + 5f64.sqrt()) / 2.0;
        let mut verts: Vec<DVec3> = [
            [-1.0, p, 0.0],
            [1.0, p, 0.0],
            [-1.0, -p, 0.0],
            [1.0, -p, 0.0],
            [0.0, -1.0, p],
            [0.0, 1.0, p],
            [0.0, -1.0, -p],
            [0.0, 1.0, -p],
            [p, 0.0, -1.0],
            [p, 0.0, 1.0],
            [-p, 0.0, -1.0],
            [-p, 0.0, 1.0],
        ]
        .iter()
        .map(|v| DVec3::from_array(*v).normalize())
        .collect();
        let faces0 = [
            [0, 11, 5],
            [0, 5, 1],
            [0, 1, 7],
            [0, 7, 10],
            [0, 10, 11],
            [1, 5, 9],
            [5, 11, 4],
            [11, 10, 2],
            [10, 7, 6],
            [7, 1, 8],
            [3, 9, 4],
            [3, 4, 2],
            [3, 2, 6],
            [3, 6, 8],
            [3, 8, 9],
            [4, 9, 5],
            [2, 4, 11],
            [6, 2, 10],
            [8, 6, 7],
            [9, 8, 1],
        ];
        let mut mid = std::collections::HashMap::new();
        let mut faces = Vec::new();
        for f in faces0 {
            let mut m = [0usize; 3];
            for e in 0..3 {
                let (i, j) = (f[e], f[(e + 1) % 3]);
                m[e] = *mid.entry((i.min(j), i.max(j))).or_insert_with(|| {
                    verts.push(((verts[i] + verts[j]) / 2.0).normalize());
                    verts.len() - 1
                });
            }
            faces.extend([[f[0], m[0], m[2]], [f[1], m[1], m[0]], [f[2], m[2], m[1]], [m[0], m[1], m[2]]]);
        }
        (verts.iter().map(|v| v.as_vec3().to_array()).collect(), faces)
    }

    /// Rays from points near the centre and outside through points on every shared edge
    /// (its ends, its middle and seeded fractions) and through every vertex: each meets the
    /// mesh. Möller-Trumbore in f32 on the same rays is counted for comparison (it can miss
    /// at an edge), printed, not asserted.
    #[test]
    fn no_ray_escapes_a_closed_mesh_through_its_edges_or_vertices() {
        let (verts, faces) = closed_mesh();
        assert_eq!((verts.len(), faces.len()), (42, 80));
        let tri = |f: &[usize; 3]| [verts[f[0]], verts[f[1]], verts[f[2]]];
        let mut targets: Vec<[f32; 3]> = verts.clone();
        let mut rng = SplitMix64::new(7);
        let mut edges = std::collections::BTreeSet::new();
        for f in &faces {
            for e in 0..3 {
                edges.insert((f[e].min(f[(e + 1) % 3]), f[e].max(f[(e + 1) % 3])));
            }
        }
        assert_eq!(edges.len(), 120, "a closed mesh: V - E + F = 2");
        for &(i, j) in &edges {
            let fractions: Vec<f32> = [0.5f32, 1e-7, 1.0 - 1e-7]
                .into_iter()
                .chain((0..12).map(|_| rng.next_f64() as f32))
                .collect();
            for s in fractions {
                targets.push(std::array::from_fn(|k| verts[i][k] + s * (verts[j][k] - verts[i][k])));
            }
        }
        // Eight origins near the centre and eight outside (at distance 3, so that rays also
        // cross edges at shallow angles).
        let origins: Vec<[f32; 3]> = (0..16)
            .map(|i| {
                let p: [f32; 3] = std::array::from_fn(|_| rng.next_f64() as f32 - 0.5);
                let scale = if i < 8 { 0.2 } else { 3.0 / p.iter().map(|x| x * x).sum::<f32>().sqrt() };
                p.map(|x| x * scale)
            })
            .collect();
        let (mut rays, mut escaped, mut mt_escaped) = (0usize, 0usize, 0usize);
        for o in &origins {
            for t in &targets {
                let d: [f32; 3] = std::array::from_fn(|k| t[k] - o[k]);
                // From outside, only rays whose line passes through the interior (closer
                // than 0.8 to the centre; the mesh holds the ball of radius 0.9): a ray
                // that only touches the silhouette may miss it without slipping through.
                let (od, dd) = (DVec3::from(o.map(f64::from)), DVec3::from(d.map(f64::from)));
                if od.length() > 1.0 && od.cross(dd).length() / dd.length() > 0.8 {
                    continue;
                }
                let shear = Shear::new(*o, d);
                rays += 1;
                let hit = faces.iter().any(|f| intersect(&shear, &tri(f), 0.0, f32::INFINITY).is_some());
                escaped += usize::from(!hit);
                let mt = faces.iter().any(|f| moller_trumbore_f32(&tri(f), *o, d).is_some());
                mt_escaped += usize::from(!mt);
            }
        }
        eprintln!(
            "{rays} rays at edges and vertices: watertight {escaped} escaped, Möller-Trumbore f32 {mt_escaped}"
        );
        assert_eq!(escaped, 0, "{escaped} of {rays} rays slipped through the closed mesh");
    }

    /// Möller-Trumbore in f32 as lightvol's tracer intersected before the watertight test
    /// (obvhs' `RtTriangle`): the distance, or `None` for a miss.
    fn moller_trumbore_f32(v: &[[f32; 3]; 3], o: [f32; 3], d: [f32; 3]) -> Option<f32> {
        use glam::Vec3A;
        let tri =
            obvhs::triangle::Triangle { v0: Vec3A::from(v[0]), v1: Vec3A::from(v[1]), v2: Vec3A::from(v[2]) };
        let ray = obvhs::ray::Ray::new(Vec3A::from(o), Vec3A::from(d), f32::NEG_INFINITY, f32::INFINITY);
        let t = obvhs::rt_triangle::RtTriangle::from(&tri).intersect(&ray);
        t.is_finite().then_some(t)
    }

    /// Away from edges and grazing incidence the watertight test agrees with the f64
    /// Möller-Trumbore reference of the tracer (`triangle::intersect_f64`): the same hit or miss,
    /// `t` and barycentrics to f32 rounding (1e-4 relative: a few ulps of the sheared
    /// coordinates, divided by `det`, which the incidence filter keeps above a tenth of its
    /// largest value).
    #[test]
    fn agrees_with_the_f64_reference_away_from_edges() {
        const EDGE_MARGIN: f64 = 1e-3;
        const F32_REL: f64 = 1e-4;
        let mut rng = SplitMix64::new(11);
        let mut r = || rng.next_f64() * 2.0 - 1.0;
        let (mut compared, mut hits) = (0, 0);
        for _ in 0..20_000 {
            let v: [DVec3; 3] = std::array::from_fn(|_| DVec3::new(r(), r(), r()));
            let o = DVec3::new(r(), r(), r()) * 3.0;
            // Aimed at a point of the triangle's plane around it (weights in [-0.25, 1.25]
            // before normalising): many hit.
            let b = [r() * 0.75 + 0.5, r() * 0.75 + 0.5, r() * 0.75 + 0.5];
            let sum = b[0] + b[1] + b[2];
            if sum.abs() < 0.1 {
                continue;
            }
            let d = (v[0] * b[0] + v[1] * b[1] + v[2] * b[2]) / sum - o;
            // Not grazing: the hit distance's conditioning is 1 / |cos| of the incidence.
            let n = (v[1] - v[0]).cross(v[2] - v[0]);
            if d.length() < 1e-3 || n.dot(d).abs() < 0.1 * n.length() * d.length() {
                continue;
            }
            let want = crate::triangle::intersect_f64(&v, o, d).filter(|h| h.0 >= 0.0);
            if let Some((_, u, w)) = want
                && (u.min(w).min(1.0 - u - w) < EDGE_MARGIN)
            {
                continue;
            }
            let vf = v.map(|p| p.as_vec3().to_array());
            let got = intersect(
                &Shear::new(o.as_vec3().to_array(), d.as_vec3().to_array()),
                &vf,
                0.0,
                f32::INFINITY,
            );
            compared += 1;
            match (want, got) {
                (None, None) => {}
                (Some((t, u, w)), Some(h)) => {
                    hits += 1;
                    assert!((f64::from(h.t) - t).abs() <= F32_REL * t.abs().max(1.0), "t {} vs {t}", h.t);
                    for (a, b) in h.bary.iter().zip([1.0 - u - w, u, w]) {
                        assert!((f64::from(*a) - b).abs() <= F32_REL * 10.0, "bary {:?} vs {u} {w}", h.bary);
                    }
                }
                (Some(want), None) => {
                    panic!("the reference hits {want:?} away from any edge; watertight misses")
                }
                // A watertight hit the reference misses lies at an edge (within the margin).
                (None, Some(g)) => {
                    assert!(g.bary.iter().any(|&b| f64::from(b) < EDGE_MARGIN), "{g:?}");
                }
            }
        }
        assert!(compared > 15_000 && hits > 5_000, "{compared} rays compared, {hits} hits");
    }
}
