//! Atlas sizing, the lightmap-UV overlap check, and conservative rasterization of UV
//! triangles into texel footprints.
//!
//! Texel `(x, y)` of a `W × H` atlas covers `u ∈ [x/W, (x+1)/W]`, `v ∈ [y/H, (y+1)/H]`; its
//! centre is at `((x + ½)/W, (y + ½)/H)`. Row `y = 0` is `v ≈ 0`, the top row of a glTF image
//! (glTF's UV origin is the image's top-left corner). Internally UVs are scaled to *texel
//! space* `(u W, v H)`, where texel squares are unit squares.

use glam::{DVec2, DVec3};

use super::SurfaceError;
use super::geometry::{SurfaceGeometry, SurfaceObject};

/// Largest atlas side the bake accepts (a 8192² map of 9 RGB f32 coefficients is 7 GiB).
pub const MAX_ATLAS_SIZE: u32 = 8192;

/// Two UV triangles of one object overlap when, inside some texel, the intersection of their
/// pieces exceeds this area (texel²). Pieces are intersected in coordinates relative to the
/// texel's corner, where every vertex lies in `[0, 1]²` and f64 round-off is ~1e-16, so
/// triangles that only share an edge or a vertex give areas of ~1e-16: ten orders below. An
/// overlap under 1e-6 of a texel mixes at most that fraction of another surface into a texel,
/// invisible next to the Monte Carlo noise of a bake. (UVs of one chart that were quantized
/// *independently*, e.g. unwelded f32 seam vertices, can differ by an f32 ulp, ~5e-4 texels at
/// 8192²; such a coincident edge is reported once it folds a sliver above this area.)
pub const UV_OVERLAP_AREA_TOLERANCE: f64 = 1e-6;

/// Clipped pieces smaller than this (texel²) are dropped: a triangle that only touches a
/// texel along an edge or at a corner has no footprint there.
pub const PIECE_MIN_AREA: f64 = 1e-9;

/// Triangles whose geometric normal deviates from the texel's primary triangle's by more than
/// this angle's cosine (60°) do not contribute to its footprint: a texel straddling two
/// charts packed edge to edge must not mix, e.g., two faces of a box.
pub const FOOTPRINT_MIN_COS: f64 = 0.5;

/// `W = H = ceil(D · s)` where `D` is `texels_per_unit` and `s` the object's
/// [`max_world_per_uv`](SurfaceObject::max_world_per_uv): every triangle gets at least `D`
/// texels per world unit along its most stretched direction (at least 1 texel).
///
/// # Errors
/// [`SurfaceError::Settings`] for a non-positive density, [`SurfaceError::AtlasTooLarge`]
/// beyond [`MAX_ATLAS_SIZE`].
pub fn atlas_size(object: &SurfaceObject, texels_per_unit: f64) -> Result<[u32; 2], SurfaceError> {
    if !(texels_per_unit > 0.0 && texels_per_unit.is_finite()) {
        return Err(SurfaceError::Settings(format!(
            "texels per unit must be positive, got {texels_per_unit}"
        )));
    }
    let n = (texels_per_unit * object.max_world_per_uv).ceil().max(1.0);
    if !(n <= f64::from(MAX_ATLAS_SIZE)) {
        let side = if n.is_finite() { n as u64 } else { u64::MAX };
        return Err(SurfaceError::AtlasTooLarge { mesh: object.name.clone(), width: side, height: side });
    }
    Ok([n as u32; 2])
}

/// The part of one triangle inside one texel, in texel space (a convex polygon of up to 7
/// vertices: a triangle clipped by 4 half-planes).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Piece {
    /// Scene triangle.
    pub tri: u32,
    /// Area in texels².
    pub area: f64,
    poly: [DVec2; 7],
    len: u8,
}

impl Piece {
    /// The polygon's vertices (texel space).
    #[must_use]
    pub fn polygon(&self) -> &[DVec2] {
        &self.poly[..usize::from(self.len)]
    }
}

/// A covered texel: its index `y·W + x` and the pieces of its footprint.
#[derive(Clone, Debug, PartialEq)]
pub struct Footprint {
    /// Texel index `y·W + x`.
    pub texel: u32,
    /// Pieces, primary first (the triangle covering the texel centre, else the largest).
    pub pieces: Vec<Piece>,
    /// Total area (texels²).
    pub area: f64,
    /// UV chart of the primary triangle (see [`Atlas::build`]); dilation only crosses between
    /// texels of one chart.
    pub chart: u32,
}

impl Footprint {
    /// A point on the footprint, uniform by area, from three uniforms: `(triangle, texel-space
    /// point)`. `u[0]` picks the piece and its fan triangle, `u[1..]` the point in it.
    #[must_use]
    pub fn sample(&self, u: [f64; 3]) -> (u32, DVec2) {
        let mut target = u[0] * self.area;
        let last = self.pieces.len() - 1;
        for (k, p) in self.pieces.iter().enumerate() {
            if target < p.area || k == last {
                let poly = p.polygon();
                let fan = poly.len() - 2;
                for i in 0..fan {
                    let (a, b, c) = (poly[0], poly[i + 1], poly[i + 2]);
                    let area = 0.5 * (b - a).perp_dot(c - a).abs();
                    if target < area || i == fan - 1 {
                        let s = u[1].sqrt();
                        let (w1, w2) = (s * (1.0 - u[2]), s * u[2]);
                        return (p.tri, a + (b - a) * w1 + (c - a) * w2);
                    }
                    target -= area;
                }
            }
            target -= p.area;
        }
        unreachable!("a footprint has at least one piece")
    }
}

/// The rasterized atlas of one object.
#[derive(Clone, Debug)]
pub struct Atlas {
    /// Width in texels.
    pub width: u32,
    /// Height in texels.
    pub height: u32,
    /// Covered texels in index order.
    pub footprints: Vec<Footprint>,
}

/// The UV triangle of `tri` in texel space.
fn texel_space(geo: &SurfaceGeometry, tri: u32, w: u32, h: u32) -> [DVec2; 3] {
    let s = DVec2::new(f64::from(w), f64::from(h));
    geo.triangle(tri).expect("object triangle").uv.map(|p| p * s)
}

impl Atlas {
    /// Rasterizes the object's UV triangles conservatively (a texel is covered when a triangle
    /// overlaps its square with positive area, not only when it covers the centre) and checks
    /// them for overlap by area: within every texel, the pieces of every two triangles are
    /// intersected (convex clipping) and an intersection above [`UV_OVERLAP_AREA_TOLERANCE`]
    /// is an error. Only pieces sharing a texel are compared (sweep over their bounding
    /// boxes), so the cost grows with the pieces per texel, mostly 1-2.
    ///
    /// # Errors
    /// [`SurfaceError::UvOverlap`] naming the two faces and the first texel (in index order)
    /// where they overlap.
    pub fn build(geo: &SurfaceGeometry, object: usize, size: [u32; 2]) -> Result<Self, SurfaceError> {
        let [w, h] = size;
        let obj = &geo.objects()[object];
        let mut raw: Vec<(u32, Piece)> = Vec::new();
        for &tri in &obj.triangles {
            let q = texel_space(geo, tri, w, h);
            let lo = q[0].min(q[1]).min(q[2]);
            let hi = q[0].max(q[1]).max(q[2]);
            let x0 = (lo.x.floor().max(0.0)) as u32;
            let y0 = (lo.y.floor().max(0.0)) as u32;
            let x1 = (hi.x.ceil() as u32).min(w);
            let y1 = (hi.y.ceil() as u32).min(h);
            for y in y0..y1 {
                for x in x0..x1 {
                    let (poly, len) = clip_to_square(q, DVec2::new(f64::from(x), f64::from(y)));
                    if len < 3 {
                        continue;
                    }
                    let area = polygon_area(&poly[..len]);
                    if area > PIECE_MIN_AREA {
                        raw.push((y * w + x, Piece { tri, area, poly, len: len as u8 }));
                    }
                }
            }
        }
        raw.sort_by_key(|(t, _)| *t); // stable: triangle order within a texel
        let chart_of = charts(geo, obj);
        let mut footprints = Vec::new();
        let mut i = 0;
        while i < raw.len() {
            let texel = raw[i].0;
            let mut j = i;
            while j < raw.len() && raw[j].0 == texel {
                j += 1;
            }
            let group: Vec<Piece> = raw[i..j].iter().map(|(_, p)| *p).collect();
            let (x, y) = (texel % w, texel / w);
            if let Some((a, b)) = overlap_in_texel(&group, DVec2::new(f64::from(x), f64::from(y))) {
                let face = |t: u32| geo.triangle(t).expect("object triangle").face;
                return Err(SurfaceError::UvOverlap {
                    mesh: obj.name.clone(),
                    a: face(group[a].tri),
                    b: face(group[b].tri),
                    texel: [x, y],
                });
            }
            let mut fp = select(geo, texel, w, h, group);
            fp.chart = chart_of(fp.pieces[0].tri);
            footprints.push(fp);
            i = j;
        }
        Ok(Self { width: w, height: h, footprints })
    }
}

/// UV charts of an object: triangles joined by a shared UV edge (both endpoints bit-identical
/// UVs, either direction) are in one chart. Returns the chart of a scene triangle; charts are
/// numbered by their first triangle in face order.
fn charts(geo: &SurfaceGeometry, obj: &SurfaceObject) -> impl Fn(u32) -> u32 {
    fn find(parent: &mut [usize], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    let n = obj.triangles.len();
    let mut parent: Vec<usize> = (0..n).collect();
    /// A UV point by its bits.
    type Point = (u64, u64);
    let key = |p: DVec2| -> Point { (p.x.to_bits(), p.y.to_bits()) };
    let mut edges: std::collections::HashMap<(Point, Point), usize> = Default::default();
    for (i, &tri) in obj.triangles.iter().enumerate() {
        let uv = geo.triangle(tri).expect("object triangle").uv;
        for k in 0..3 {
            let (a, b) = (key(uv[k]), key(uv[(k + 1) % 3]));
            let e = if a <= b { (a, b) } else { (b, a) };
            match edges.entry(e) {
                std::collections::hash_map::Entry::Occupied(o) => {
                    let (ra, rb) = (find(&mut parent, i), find(&mut parent, *o.get()));
                    // The smaller root wins: numbering by first triangle, order independent.
                    let (lo, hi) = (ra.min(rb), ra.max(rb));
                    parent[hi] = lo;
                }
                std::collections::hash_map::Entry::Vacant(v) => {
                    v.insert(i);
                }
            }
        }
    }
    let index: std::collections::HashMap<u32, u32> =
        obj.triangles.iter().enumerate().map(|(i, &t)| (t, find(&mut parent, i) as u32)).collect();
    move |tri| index[&tri]
}

/// Orders a texel's pieces primary-first and drops those facing too differently.
fn select(geo: &SurfaceGeometry, texel: u32, w: u32, h: u32, mut group: Vec<Piece>) -> Footprint {
    let centre = DVec2::new(f64::from(texel % w) + 0.5, f64::from(texel / w) + 0.5);
    let primary = group
        .iter()
        .position(|p| inside_by(texel_space(geo, p.tri, w, h), centre) >= 0.0)
        .unwrap_or_else(|| {
            // Largest piece; ties to the earliest triangle.
            let mut best = 0;
            for (k, p) in group.iter().enumerate() {
                if p.area > group[best].area {
                    best = k;
                }
            }
            best
        });
    group.swap(0, primary);
    let n0: DVec3 = geo.geometric_normal(group[0].tri);
    let first = group[0];
    let mut pieces = vec![first];
    pieces.extend(
        group[1..].iter().copied().filter(|p| geo.geometric_normal(p.tri).dot(n0) >= FOOTPRINT_MIN_COS),
    );
    // Keep triangle order after the primary for determinism independent of the swap.
    pieces[1..].sort_by_key(|p| p.tri);
    let area = pieces.iter().map(|p| p.area).sum();
    Footprint { texel, pieces, area, chart: 0 }
}

/// Smallest signed distance (texels) of `c` inside the triangle `q` (either winding);
/// negative outside.
fn inside_by(q: [DVec2; 3], c: DVec2) -> f64 {
    let orient = (q[1] - q[0]).perp_dot(q[2] - q[0]).signum();
    (0..3)
        .map(|k| {
            let (a, b) = (q[k], q[(k + 1) % 3]);
            let e = b - a;
            orient * e.perp_dot(c - a) / e.length()
        })
        .fold(f64::INFINITY, f64::min)
}

/// The first pair `(i, j)`, `i < j`, of pieces of one texel (origin `origin`, pieces in
/// triangle order) whose intersection exceeds [`UV_OVERLAP_AREA_TOLERANCE`]; pairs are visited
/// in a fixed order (sweep by bounding box), so the answer is deterministic.
fn overlap_in_texel(group: &[Piece], origin: DVec2) -> Option<(usize, usize)> {
    if group.len() < 2 {
        return None;
    }
    let local: Vec<([DVec2; 7], usize, DVec2, DVec2)> = group
        .iter()
        .map(|p| {
            let mut poly = [DVec2::ZERO; 7];
            let len = usize::from(p.len);
            let (mut lo, mut hi) = (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY));
            for (d, s) in poly.iter_mut().zip(p.polygon()) {
                *d = *s - origin;
                lo = lo.min(*d);
                hi = hi.max(*d);
            }
            (poly, len, lo, hi)
        })
        .collect();
    let mut order: Vec<usize> = (0..group.len()).collect();
    order.sort_by(|&a, &b| local[a].2.x.total_cmp(&local[b].2.x).then(a.cmp(&b)));
    let mut found: Option<(usize, usize)> = None;
    for (k, &i) in order.iter().enumerate() {
        for &j in &order[k + 1..] {
            if local[j].2.x > local[i].3.x {
                break;
            }
            if local[j].2.y > local[i].3.y || local[i].2.y > local[j].3.y {
                continue;
            }
            let (pi, pj) = (&local[i].0[..local[i].1], &local[j].0[..local[j].1]);
            if convex_intersection_area(pi, pj) > UV_OVERLAP_AREA_TOLERANCE {
                let pair = (i.min(j), i.max(j));
                found = Some(found.map_or(pair, |f| f.min(pair)));
            }
        }
    }
    found
}

/// Area of the intersection of two convex polygons (either winding): `p` clipped by every
/// edge of `q` (Sutherland-Hodgman). At most 7 + 7 vertices.
fn convex_intersection_area(p: &[DVec2], q: &[DVec2]) -> f64 {
    const CAP: usize = 16;
    let orient = {
        let mut s = 0.0;
        for i in 0..q.len() {
            s += q[i].perp_dot(q[(i + 1) % q.len()]);
        }
        s.signum()
    };
    let mut buf = [DVec2::ZERO; CAP];
    buf[..p.len()].copy_from_slice(p);
    let mut len = p.len();
    for e in 0..q.len() {
        let (a, b) = (q[e], q[(e + 1) % q.len()]);
        let dist = |x: DVec2| orient * (b - a).perp_dot(x - a);
        let mut out = [DVec2::ZERO; CAP];
        let mut n = 0;
        for i in 0..len {
            let (c, d) = (buf[i], buf[(i + 1) % len]);
            let (dc, dd) = (dist(c), dist(d));
            if dc >= 0.0 && n < CAP {
                out[n] = c;
                n += 1;
            }
            if (dc >= 0.0) != (dd >= 0.0) && n < CAP {
                out[n] = c + (d - c) * (dc / (dc - dd));
                n += 1;
            }
        }
        buf = out;
        len = n;
        if len < 3 {
            return 0.0;
        }
    }
    polygon_area(&buf[..len])
}

/// Sutherland-Hodgman clipping of triangle `q` to the unit square at `origin`.
fn clip_to_square(q: [DVec2; 3], origin: DVec2) -> ([DVec2; 7], usize) {
    let mut buf = [DVec2::ZERO; 7];
    buf[..3].copy_from_slice(&q);
    let mut len = 3;
    // (axis, bound, keep the side >= bound?)
    let planes =
        [(0, origin.x, true), (0, origin.x + 1.0, false), (1, origin.y, true), (1, origin.y + 1.0, false)];
    for (axis, bound, keep_above) in planes {
        let mut out = [DVec2::ZERO; 7];
        let mut n = 0;
        let dist = |p: DVec2| if keep_above { p[axis] - bound } else { bound - p[axis] };
        for i in 0..len {
            let (a, b) = (buf[i], buf[(i + 1) % len]);
            let (da, db) = (dist(a), dist(b));
            // A triangle clipped by 4 half-planes has at most 7 vertices; `n < 7` only guards
            // against rounding producing an 8th.
            if da >= 0.0 && n < 7 {
                out[n] = a;
                n += 1;
            }
            if (da >= 0.0) != (db >= 0.0) {
                let t = da / (da - db);
                if n < 7 {
                    out[n] = a + (b - a) * t;
                    n += 1;
                }
            }
        }
        buf = out;
        len = n;
        if len < 3 {
            return (buf, len);
        }
    }
    (buf, len)
}

/// Area of a simple polygon (shoelace, either winding).
fn polygon_area(p: &[DVec2]) -> f64 {
    let mut s = 0.0;
    for i in 0..p.len() {
        s += p[i].perp_dot(p[(i + 1) % p.len()]);
    }
    0.5 * s.abs()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Clipped areas of one triangle over all texels sum to its area, and each texel's clipped
    /// area equals a fine point-count estimate (the slow reference).
    #[test]
    fn clipping_partitions_the_triangle() {
        const SUM_TOL: f64 = 1e-12; // exact up to rounding
        const COUNT_TOL: f64 = 2e-3; // 400² grid of points per texel: boundary error ~ perimeter/400
        let q = [DVec2::new(0.3, 0.2), DVec2::new(3.7, 1.1), DVec2::new(1.2, 2.9)];
        let total = 0.5 * (q[1] - q[0]).perp_dot(q[2] - q[0]).abs();
        let mut sum = 0.0;
        for y in 0..3 {
            for x in 0..4 {
                let o = DVec2::new(f64::from(x), f64::from(y));
                let (poly, len) = clip_to_square(q, o);
                let a = if len >= 3 { polygon_area(&poly[..len]) } else { 0.0 };
                sum += a;
                let n = 400;
                let mut inside = 0;
                for j in 0..n {
                    for i in 0..n {
                        let c = o + DVec2::new(
                            (f64::from(i) + 0.5) / f64::from(n),
                            (f64::from(j) + 0.5) / f64::from(n),
                        );
                        if inside_by(q, c) >= 0.0 {
                            inside += 1;
                        }
                    }
                }
                let est = f64::from(inside) / f64::from(n * n);
                assert!((a - est).abs() < COUNT_TOL, "texel {x},{y}: {a} vs {est}");
            }
        }
        assert!((sum - total).abs() < SUM_TOL);
    }

    /// The convex intersection area matches a point count (the slow reference) for pieces of
    /// crossing triangles, is zero for pieces that share only an edge, and is symmetric.
    #[test]
    fn convex_intersection_matches_point_count() {
        const COUNT_TOL: f64 = 3e-3; // 500² points per texel: boundary error ~ perimeter/500
        const SHARED_EDGE_TOL: f64 = 1e-14; // round-off only
        let inside = |poly: &[DVec2], c: DVec2| {
            let orient = (poly[1] - poly[0]).perp_dot(poly[2] - poly[0]).signum();
            (0..poly.len())
                .all(|k| orient * (poly[(k + 1) % poly.len()] - poly[k]).perp_dot(c - poly[k]) >= 0.0)
        };
        let cases = [
            (
                [DVec2::new(-0.4, 0.1), DVec2::new(1.3, 0.3), DVec2::new(0.2, 1.6)],
                [DVec2::new(0.9, -0.2), DVec2::new(0.7, 1.2), DVec2::new(-0.3, 0.5)],
            ),
            (
                [DVec2::new(0.1, 0.1), DVec2::new(0.9, 0.2), DVec2::new(0.5, 0.8)],
                [DVec2::new(0.3, 0.3), DVec2::new(0.4, 0.3), DVec2::new(0.3, 0.45)],
            ),
        ];
        for (t1, t2) in cases {
            let (p1, l1) = clip_to_square(t1, DVec2::ZERO);
            let (p2, l2) = clip_to_square(t2, DVec2::ZERO);
            let (p1, p2) = (&p1[..l1], &p2[..l2]);
            let a = convex_intersection_area(p1, p2);
            assert!((a - convex_intersection_area(p2, p1)).abs() < SHARED_EDGE_TOL);
            let n = 500;
            let mut count = 0;
            for j in 0..n {
                for i in 0..n {
                    let c =
                        DVec2::new((f64::from(i) + 0.5) / f64::from(n), (f64::from(j) + 0.5) / f64::from(n));
                    count += u32::from(inside(p1, c) && inside(p2, c));
                }
            }
            let est = f64::from(count) / f64::from(n * n);
            assert!(a > 1e-3 && (a - est).abs() < COUNT_TOL, "{a} vs {est}");
        }
        // Two halves of a texel split along its diagonal, and two triangles touching at a vertex.
        let lower = [DVec2::new(0.0, 0.0), DVec2::new(1.0, 0.0), DVec2::new(1.0, 1.0)];
        let upper = [DVec2::new(0.0, 0.0), DVec2::new(1.0, 1.0), DVec2::new(0.0, 1.0)];
        assert!(convex_intersection_area(&lower, &upper) < SHARED_EDGE_TOL);
        let touch = [DVec2::new(1.0, 1.0), DVec2::new(1.5, 1.0), DVec2::new(1.0, 1.5)];
        assert!(convex_intersection_area(&lower, &touch) < SHARED_EDGE_TOL);
    }

    /// Footprint sampling is uniform by area: the fraction of points per piece matches its
    /// share of the area.
    #[test]
    fn footprint_sampling_is_area_uniform() {
        const TOL: f64 = 0.01; // 4096 stratified points: error ~1/4096 per boundary crossing
        let q1 = [DVec2::new(0.0, 0.0), DVec2::new(1.0, 0.0), DVec2::new(0.0, 1.0)];
        let q2 = [DVec2::new(1.0, 0.0), DVec2::new(1.0, 1.0), DVec2::new(0.0, 1.0)];
        let pieces: Vec<Piece> = [(0, q1), (1, q2)]
            .iter()
            .map(|&(tri, q)| {
                let (poly, len) = clip_to_square(q, DVec2::ZERO);
                Piece { tri, area: polygon_area(&poly[..len]), poly, len: len as u8 }
            })
            .collect();
        let fp = Footprint { texel: 0, area: 1.0, pieces, chart: 0 };
        let h = lightvol_scene::qmc::Qmc::<3>::new(1, 2);
        let mut counts = [0u32; 2];
        let mut left = 0;
        for i in 0..4096 {
            let (tri, p) = fp.sample(h.point(i));
            counts[tri as usize] += 1;
            assert!((0.0..=1.0).contains(&p.x) && (0.0..=1.0).contains(&p.y));
            assert_eq!(tri == 0, p.x + p.y <= 1.0 + 1e-12, "{p}");
            left += u32::from(p.x < 0.5);
        }
        assert!((f64::from(counts[0]) / 4096.0 - 0.5).abs() < TOL);
        assert!((f64::from(left) / 4096.0 - 0.5).abs() < TOL);
    }
}
