//! The domain of interest (Kontkanen & Laine 2006 §5-6): all space from which no back face
//! of the scene is visible.
//!
//! - [`classify_point`]: the naive classifier (many rays from one point), used for ground
//!   truth masks and tests.
//! - [`classify_cell`]: Algorithm 2's per-cell rejection sampler with a back-face-point list
//!   and query rays. The paper's pseudo-code re-tests earlier samples with
//!   `dot(isect2.normal, ray.direction) > 0`; the direction meant is the *query* ray's
//!   (`gray.direction`), which is what we use (the test
//!   `retest_uses_the_query_direction` shows the difference).

use glam::DVec3;
use lightvol_scene::qmc::Qmc;
use lightvol_sh::sampling::sample_uniform_sphere;

use lightvol_scene::bvh::{Hit, Tracer};
use lightvol_scene::stats::RayCounts;

/// Directions used by [`classify_point`] by default: with 256 directions a back face that
/// covers more than ~1/50 of the sphere is found with certainty (the Halton directions are
/// stratified), and smaller ones with probability ∝ their solid angle.
pub const DEFAULT_CLASSIFY_DIRECTIONS: u32 = 256;

/// Result of classifying one point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PointClass {
    /// True when no traced ray met a back face: `x` is in the domain of interest.
    pub inside: bool,
    /// A back-face hit that proves `x` outside (triangle, position).
    pub witness: Option<(u32, DVec3)>,
    /// Rays traced.
    pub rays: u64,
}

/// Classifies `x` by tracing `dirs` scrambled-Halton uniform directions (stream `seed`);
/// stops at the first back-face hit.
#[must_use]
pub fn classify_point(tracer: &Tracer, x: DVec3, dirs: u32, seed: u64) -> PointClass {
    let h = Qmc::<2>::new(seed, 0);
    for i in 0..u64::from(dirs) {
        let d = DVec3::from_array(sample_uniform_sphere(h.point(i)));
        if let Some(hit) = tracer.closest_hit(x, d, 0.0, f64::INFINITY)
            && hit.back_face
        {
            return PointClass { inside: false, witness: Some((hit.triangle, x + d * hit.t)), rays: i + 1 };
        }
    }
    PointClass { inside: true, witness: None, rays: u64::from(dirs) }
}

/// Classifies many points in parallel (point `i` uses direction stream `seed + i`), e.g.
/// to mask evaluation plates: `true` = inside the domain of interest.
#[must_use]
pub fn classify_points(tracer: &Tracer, points: &[DVec3], dirs: u32, seed: u64) -> Vec<bool> {
    use rayon::prelude::*;
    points
        .par_iter()
        .enumerate()
        .map(|(i, &x)| classify_point(tracer, x, dirs, seed.wrapping_add(i as u64)).inside)
        .collect()
}

/// A sampling ray of Algorithm 2 with its first hit (reused for lighting).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Candidate {
    /// Index of the candidate in the cell's sequence.
    pub index: u64,
    /// Ray origin (world space).
    pub origin: DVec3,
    /// Unit direction.
    pub dir: DVec3,
    /// First hit of the sampling ray (`None`: it escaped).
    pub hit: Option<Hit>,
}

/// A back-face point found while classifying a cell.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BackFacePoint {
    /// Location on the back face.
    pub position: DVec3,
    /// Triangle hit.
    pub triangle: u32,
    /// Candidate whose sampling ray found it.
    pub found_by: u64,
}

/// Outcome of Algorithm 2 on one cell.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct CellClassification {
    /// Samples whose origins are in the domain of interest, in candidate order.
    pub kept: Vec<Candidate>,
    /// Origins of rejected candidates with their candidate index, in rejection order.
    pub rejected: Vec<(u64, DVec3)>,
    /// Back-face points, in discovery order.
    pub back_face_points: Vec<BackFacePoint>,
    /// Rays traced (sampling and query).
    pub rays: RayCounts,
}

/// Which direction the re-test of earlier samples against a new back-face point uses.
/// Only for demonstrating the pseudo-code's slip; bakes use [`Retest::QueryDirection`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Retest {
    /// `dot(isect2.normal, gray.direction) > 0` (what the paper means).
    #[default]
    QueryDirection,
    /// `dot(isect2.normal, ray.direction) > 0` (the pseudo-code as printed).
    AsPrinted,
}

/// Kontkanen & Laine 2006 Algorithm 2 for one cell: `n` candidates `(origin, direction)`
/// from `candidate(i)`; a candidate that sees a known back-face point through a query ray
/// is dropped without tracing its sampling ray; a sampling ray that meets a back face
/// creates a new back-face point, is dropped, and every kept sample is re-tested with a
/// query ray towards the new point. Escaped sampling rays are kept.
pub fn classify_cell(
    tracer: &Tracer,
    n: u64,
    mut candidate: impl FnMut(u64) -> (DVec3, DVec3),
    retest: Retest,
) -> CellClassification {
    let mut out = CellClassification::default();
    // A query ray from `o` towards `target`: its first hit, with `back_face` judged against
    // the query ray's own direction.
    let query = |o: DVec3, target: DVec3, rays: &mut RayCounts| -> Option<Hit> {
        let q = target - o;
        let len = q.length();
        if !(len > 0.0) {
            return None;
        }
        let qd = q / len;
        rays.query += 1;
        tracer.closest_hit(o, qd, 0.0, f64::INFINITY)
    };
    for i in 0..n {
        let (o, d) = candidate(i);
        let sees_known = out
            .back_face_points
            .iter()
            .any(|bp| query(o, bp.position, &mut out.rays).is_some_and(|h| h.back_face));
        if sees_known {
            out.rejected.push((i, o));
            continue;
        }
        out.rays.sampling += 1;
        let hit = tracer.closest_hit(o, d, 0.0, f64::INFINITY);
        match hit {
            Some(h) if h.back_face => {
                let p = o + d * h.t;
                out.back_face_points.push(BackFacePoint { position: p, triangle: h.triangle, found_by: i });
                out.rejected.push((i, o));
                let mut kept = Vec::with_capacity(out.kept.len());
                for s in std::mem::take(&mut out.kept) {
                    let sees = query(s.origin, p, &mut out.rays).is_some_and(|h2| match retest {
                        Retest::QueryDirection => h2.back_face,
                        Retest::AsPrinted => h2.single_sided && h2.normal.dot(d) > 0.0,
                    });
                    if sees {
                        out.rejected.push((s.index, s.origin));
                    } else {
                        kept.push(s);
                    }
                }
                out.kept = kept;
            }
            _ => out.kept.push(Candidate { index: i, origin: o, dir: d, hit }),
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use lightvol_scene::builder::SceneBuilder;
    use lightvol_scene::material::Material;
    use lightvol_scene::scene::Scene;
    use lightvol_scene::{LoadOptions, load_scene};

    fn solid_box(lo: DVec3, hi: DVec3, open_top: bool) -> Scene {
        let mut b = SceneBuilder::new("box");
        let m = b.add_material(Material::diffuse("m", [0.5; 3])).unwrap();
        b.add_box(lo, hi, m, true, false).unwrap();
        let mut s = b.build().unwrap();
        if open_top {
            // Drop the two +Z triangles.
            s.triangles.retain(|t| t.normal().z < 0.5);
        }
        s
    }

    /// \[KL06\] Fig. 3 (a)-(d): a kept sample outside a solid survives the re-test, a
    /// candidate inside is dropped and creates a back-face point, a later candidate inside is
    /// rejected by a query ray without tracing its sampling ray.
    #[test]
    fn fig3_sequence() {
        let s = solid_box(DVec3::ZERO, DVec3::ONE, false);
        let tr = Tracer::new(&s);
        let cands = [
            (DVec3::new(-0.5, 0.5, 0.5), DVec3::new(-1.0, 0.1, 0.0).normalize()), // (a) outside, escapes
            (DVec3::new(0.5, 0.5, 0.5), DVec3::new(0.3, 1.0, 0.2).normalize()),   // (b) inside: back face
            (DVec3::new(0.6, 0.4, 0.5), DVec3::new(0.0, 0.0, 1.0)),               // inside: rejected by query
            (DVec3::new(-0.2, 0.3, 0.6), DVec3::new(0.0, -1.0, 0.1).normalize()), // (c) outside
        ];
        let c = classify_cell(&tr, 4, |i| cands[i as usize], Retest::QueryDirection);
        assert_eq!(c.kept.iter().map(|k| k.index).collect::<Vec<_>>(), vec![0, 3]);
        assert_eq!(c.rejected.iter().map(|r| r.0).collect::<Vec<_>>(), vec![1, 2]);
        assert_eq!(c.back_face_points.len(), 1);
        assert_eq!(c.back_face_points[0].found_by, 1);
        // Sampling rays for 0, 1, 3; query rays: re-test of 0, test of 2, test of 3.
        assert_eq!((c.rays.sampling, c.rays.query), (3, 3));
    }

    /// \[KL06\] Alg. 2: an earlier sample whose own ray escaped is removed when a later
    /// back-face point is visible from it (inside an open-topped box).
    #[test]
    fn earlier_samples_are_retested() {
        let s = solid_box(DVec3::ZERO, DVec3::ONE, true);
        let tr = Tracer::new(&s);
        let cands = [
            (DVec3::new(0.5, 0.5, 0.5), DVec3::Z), // escapes through the open top: kept for now
            (DVec3::new(0.4, 0.3, 0.6), DVec3::X), // hits the +X wall from inside: back face
            (DVec3::new(3.0, 0.5, 0.5), DVec3::Z), // beside: the query ray meets the wall's outer face
        ];
        let c = classify_cell(&tr, 3, |i| cands[i as usize], Retest::QueryDirection);
        assert_eq!(c.kept.iter().map(|k| k.index).collect::<Vec<_>>(), vec![2]);
        assert_eq!(c.rejected.iter().map(|r| r.0).collect::<Vec<_>>(), vec![1, 0]);
    }

    /// A cell that sees no back face traces no query rays at all (\[KL06\] §6).
    #[test]
    fn clean_cells_trace_no_query_rays() {
        let s = solid_box(DVec3::ZERO, DVec3::ONE, false);
        let tr = Tracer::new(&s);
        let h = Qmc::<5>::new(4, 0);
        let c = classify_cell(
            &tr,
            200,
            |i| {
                let p = h.point(i);
                (DVec3::new(2.0 + p[0], p[1], p[2]), DVec3::from_array(sample_uniform_sphere([p[3], p[4]])))
            },
            Retest::QueryDirection,
        );
        assert_eq!((c.kept.len(), c.rays.query, c.rays.sampling), (200, 0, 200));
        assert!(c.kept.iter().any(|k| k.hit.is_some()), "some rays must hit the box");
    }

    /// The printed pseudo-code re-tests with the sampling ray's direction and wrongly drops
    /// a sample outside the solid; the query direction keeps it.
    #[test]
    fn retest_uses_the_query_direction() {
        let s = solid_box(DVec3::ZERO, DVec3::ONE, false);
        let tr = Tracer::new(&s);
        let cands = [
            (DVec3::new(-0.5, 0.4, 0.5), DVec3::new(-1.0, 0.0, 0.2).normalize()),
            // Off the quads' diagonals (a ray along one would meet two triangles at once).
            (DVec3::new(0.5, 0.3, 0.6), -DVec3::X),
        ];
        let right = classify_cell(&tr, 2, |i| cands[i as usize], Retest::QueryDirection);
        let printed = classify_cell(&tr, 2, |i| cands[i as usize], Retest::AsPrinted);
        assert_eq!(right.kept.len(), 1);
        assert_eq!(printed.kept.len(), 0);
    }

    /// Point classification (\[KL06\] §5): inside closed boxes and behind single-sided walls is outside the
    /// domain; open space is inside. On the real Cornell box: the room is inside, the blocks
    /// and the space behind the walls are outside.
    #[test]
    fn point_classifier() {
        let s = solid_box(DVec3::ZERO, DVec3::ONE, false);
        let tr = Tracer::new(&s);
        assert!(!classify_point(&tr, DVec3::splat(0.5), 64, 1).inside);
        assert!(classify_point(&tr, DVec3::new(3.0, 0.5, 0.5), 64, 1).inside);

        let p = std::path::Path::new(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../data/scenes/cornell_box/cornell_box.obj"
        ));
        let s = load_scene(p, &LoadOptions::default()).unwrap();
        let tr = Tracer::new(&s);
        // World = file (x, y, z) -> (x, -z, y). Room centre, file (278, 274, 280).
        let w = |x: f64, y: f64, z: f64| DVec3::new(x, -z, y);
        let n = DEFAULT_CLASSIFY_DIRECTIONS;
        assert!(classify_point(&tr, w(278.0, 274.0, 280.0), n, 2).inside);
        assert!(classify_point(&tr, w(150.0, 450.0, 150.0), n, 3).inside);
        // Inside the short block (file x 82..290, z 65..296, y 0..165) and the tall block.
        assert!(!classify_point(&tr, w(186.0, 80.0, 170.0), n, 4).inside);
        assert!(!classify_point(&tr, w(370.0, 200.0, 350.0), n, 5).inside);
        // Behind the back wall, left of the green wall, above the ceiling.
        assert!(!classify_point(&tr, w(278.0, 274.0, 700.0), n, 6).inside);
        assert!(!classify_point(&tr, w(-100.0, 274.0, 280.0), n, 7).inside);
        assert!(!classify_point(&tr, w(278.0, 700.0, 280.0), n, 8).inside);
    }
}
