//! Geometry diagnostics for domain-of-interest baking (Kontkanen & Laine 2006 §7: reversed
//! polygons and cracks make back faces visible from the domain of interest).
//!
//! - [`back_face_report`]: per-triangle counts of back-face hits seen from sample points
//!   that are otherwise in the domain (most of their rays meet front faces). A reversed
//!   polygon in open space collects many such hits; the insides of solids, which see back
//!   faces in every direction, are not counted.
//! - [`winding_report`]: edge-adjacent triangles that traverse their shared edge in the
//!   same direction (inconsistent orientation). In a closed, consistently wound mesh every
//!   interior edge is traversed once in each direction; a flipped triangle has all three
//!   of its edges inconsistent.
//!
//! Both return suspects ranked by score, with positions, for an editor to highlight.

use std::collections::HashMap;

use crate::qmc::Qmc;
use glam::DVec3;
use lightvol_sh::sampling::sample_uniform_sphere;
use rayon::prelude::*;

use crate::bvh::Tracer;
use crate::scene::Scene;

/// A triangle flagged by a diagnostic.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Suspect {
    /// Scene triangle index.
    pub triangle: u32,
    /// Where to look: mean back-face hit position, or the centroid.
    pub position: DVec3,
    /// Back-face hits counted, or inconsistent edges (1-3).
    pub score: u32,
}

/// Settings of [`back_face_report`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BackFaceSettings {
    /// Rays per sample point.
    pub dirs: u32,
    /// A point counts as "otherwise in the domain" when at most this fraction of its rays
    /// meet back faces (inside a solid the fraction is 1).
    pub max_back_fraction: f64,
    /// Seed of the direction streams.
    pub seed: u64,
}

impl Default for BackFaceSettings {
    fn default() -> Self {
        Self { dirs: 128, max_back_fraction: 0.25, seed: 0 }
    }
}

/// Result of [`back_face_report`].
#[derive(Clone, Debug, Default, PartialEq)]
pub struct BackFaceReport {
    /// Suspects, highest score first (ties by triangle index).
    pub suspects: Vec<Suspect>,
    /// Sample points that saw no back face.
    pub clean_points: usize,
    /// Points that saw a few back faces (their hits were counted).
    pub counted_points: usize,
    /// Points that saw mostly back faces (inside solids; ignored).
    pub solid_points: usize,
}

/// Counts back-face hits per triangle from `points` (e.g. bake sample origins or a
/// lattice over the grid) that are otherwise in the domain of interest.
#[must_use]
pub fn back_face_report(tracer: &Tracer, points: &[DVec3], settings: &BackFaceSettings) -> BackFaceReport {
    let per_point: Vec<(u8, Vec<(u32, DVec3)>)> = points
        .par_iter()
        .enumerate()
        .map(|(i, &x)| {
            let h = Qmc::<2>::new(settings.seed, i as u64);
            let mut hits = Vec::new();
            for k in 0..u64::from(settings.dirs) {
                let d = DVec3::from_array(sample_uniform_sphere(h.point(k)));
                if let Some(hit) = tracer.closest_hit(x, d, 0.0, f64::INFINITY)
                    && hit.back_face
                {
                    hits.push((hit.triangle, x + d * hit.t));
                }
            }
            let frac = hits.len() as f64 / f64::from(settings.dirs.max(1));
            let class = if hits.is_empty() {
                0
            } else if frac <= settings.max_back_fraction {
                1
            } else {
                2
            };
            (class, if class == 1 { hits } else { Vec::new() })
        })
        .collect();
    let mut report = BackFaceReport::default();
    let mut acc: HashMap<u32, (u32, DVec3)> = HashMap::new();
    for (class, hits) in per_point {
        match class {
            0 => report.clean_points += 1,
            1 => report.counted_points += 1,
            _ => report.solid_points += 1,
        }
        for (tri, p) in hits {
            let e = acc.entry(tri).or_insert((0, DVec3::ZERO));
            e.0 += 1;
            e.1 += p;
        }
    }
    report.suspects = acc
        .into_iter()
        .map(|(triangle, (n, sum))| Suspect { triangle, position: sum / f64::from(n), score: n })
        .collect();
    report.suspects.sort_by(|a, b| b.score.cmp(&a.score).then(a.triangle.cmp(&b.triangle)));
    report
}

/// Sample points for [`back_face_report`]: `per_cell` Halton points in each cell of a box
/// lattice `[lo, hi]` with `res` cells per axis.
#[must_use]
pub fn lattice_points(lo: DVec3, hi: DVec3, res: [u32; 3], per_cell: u32, seed: u64) -> Vec<DVec3> {
    let size = (hi - lo) / DVec3::new(f64::from(res[0]), f64::from(res[1]), f64::from(res[2]));
    let mut out = Vec::new();
    let mut cell = 0u64;
    for k in 0..res[2] {
        for j in 0..res[1] {
            for i in 0..res[0] {
                let h = Qmc::<3>::new(seed, cell);
                cell += 1;
                let c0 = lo + size * DVec3::new(f64::from(i), f64::from(j), f64::from(k));
                for s in 0..u64::from(per_cell) {
                    out.push(c0 + size * DVec3::from_array(h.point(s)));
                }
            }
        }
    }
    out
}

/// Result of [`winding_report`].
#[derive(Clone, Debug, Default, PartialEq)]
pub struct WindingReport {
    /// Triangles with inconsistently oriented shared edges, most inconsistent first.
    pub suspects: Vec<Suspect>,
    /// Shared edges traversed twice in the same direction.
    pub inconsistent_edges: usize,
    /// Edges used by one triangle only (open borders; cracks show up here).
    pub boundary_edges: usize,
    /// Edges used by more than two triangles (not checked).
    pub non_manifold_edges: usize,
}

/// Checks orientation consistency across shared edges. Vertices closer than `weld` (in
/// scene units, per axis) are treated as one (positions are snapped to a `weld` lattice).
#[must_use]
pub fn winding_report(scene: &Scene, weld: f64) -> WindingReport {
    let key = |p: DVec3| -> [i64; 3] { [p.x, p.y, p.z].map(|c| (c / weld).round() as i64) };
    // Undirected edge → list of (triangle, traversed from smaller to larger key).
    type EdgeKey = ([i64; 3], [i64; 3]);
    let mut edges: HashMap<EdgeKey, Vec<(u32, bool)>> = HashMap::new();
    for (t, tri) in scene.world_triangles().enumerate() {
        let k = tri.v.map(key);
        for e in 0..3 {
            let (a, b) = (k[e], k[(e + 1) % 3]);
            if a == b {
                continue;
            }
            let forward = a < b;
            let id = if forward { (a, b) } else { (b, a) };
            edges.entry(id).or_default().push((t as u32, forward));
        }
    }
    let mut report = WindingReport::default();
    let mut score: HashMap<u32, u32> = HashMap::new();
    for uses in edges.values() {
        match uses.len() {
            1 => report.boundary_edges += 1,
            2 => {
                if uses[0].1 == uses[1].1 {
                    report.inconsistent_edges += 1;
                    for &(t, _) in uses {
                        *score.entry(t).or_default() += 1;
                    }
                }
            }
            _ => report.non_manifold_edges += 1,
        }
    }
    report.suspects = score
        .into_iter()
        .map(|(triangle, s)| Suspect { triangle, position: scene.triangle(triangle).centroid(), score: s })
        .collect();
    report.suspects.sort_by(|a, b| b.score.cmp(&a.score).then(a.triangle.cmp(&b.triangle)));
    report
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::builder::SceneBuilder;
    use crate::material::Material;

    fn boxes(flip: Option<usize>) -> Scene {
        let mut b = SceneBuilder::new("boxes");
        let m = b.add_material(Material::diffuse("m", [0.5; 3])).unwrap();
        b.add_box(DVec3::ZERO, DVec3::new(2.0, 1.0, 1.5), m, true, false).unwrap();
        b.add_box(DVec3::new(4.0, 0.0, 0.0), DVec3::new(5.0, 1.0, 1.0), m, true, false).unwrap();
        let mut s = b.build().unwrap();
        if let Some(f) = flip {
            s.triangles[f].v.swap(1, 2);
            s.triangles[f].uv.swap(1, 2);
        }
        s
    }

    /// One flipped triangle in otherwise closed meshes is the top suspect of
    /// both diagnostics; the clean scene yields no suspects.
    #[test]
    fn flipped_triangle_is_reported_by_both() {
        let pts = lattice_points(DVec3::new(-1.0, -1.0, -0.5), DVec3::new(6.0, 2.0, 2.5), [7, 3, 3], 2, 1);
        let clean = boxes(None);
        assert!(winding_report(&clean, 1e-6).suspects.is_empty());
        let r = back_face_report(&Tracer::new(&clean), &pts, &BackFaceSettings::default());
        assert!(r.suspects.is_empty() && r.solid_points > 0 && r.clean_points > 0, "{r:?}");

        for flip in [3, 17] {
            let s = boxes(Some(flip));
            let w = winding_report(&s, 1e-6);
            assert_eq!((w.suspects[0].triangle, w.suspects[0].score), (flip as u32, 3));
            assert_eq!(w.inconsistent_edges, 3);
            assert!(w.suspects[1..].iter().all(|x| x.score == 1));
            assert_eq!(w.boundary_edges, 0);
            let r = back_face_report(&Tracer::new(&s), &pts, &BackFaceSettings::default());
            assert_eq!(r.suspects[0].triangle, flip as u32, "{r:?}");
            // Only the flipped triangle is seen from outside.
            assert_eq!(r.suspects.len(), 1);
            let c = s.triangles[flip].centroid();
            assert!((r.suspects[0].position - c).length() < 1.5);
        }
    }
}
