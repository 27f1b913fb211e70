//! What one unit of a bake contributes: a node's point samples (Kontkanen & Laine 2006 Eq. 4,
//! `point_unit`), a node box's candidates under Algorithm 2 (`node_box_unit`), and a
//! cell's candidates weighted over the nodes' trilinear supports (Eq. 5-6, `cell_unit`,
//! with Algorithm 2 for `doi-paper`). `doi`'s unit, the probe, is [`crate::probe`].
//!
//! Every sample is one uniform direction from its origin and one path along it
//! (`sample_terms`), plus, with light sampling, one MIS-weighted light sample.

use std::f64::consts::PI;

use glam::DVec3;
use lightvol_scene::bvh::Hit;
use lightvol_scene::qmc::Qmc;
use lightvol_scene::transport::{PathRng, Transport};
use lightvol_sh::lowdisc::hash2;
use lightvol_sh::sampling::sample_uniform_sphere;
use lightvol_volume::GridSpec;

use crate::domain::{Candidate, Retest, classify_cell};
use crate::method::Method;
use crate::settings::BakeSettings;
use crate::stats::BakeStats;

/// One sample's contribution: trilinear weights of its origin for the unit's 8 nodes, and
/// up to two directional terms `(direction, radiance / pdf)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct SampleOut {
    pub(crate) weights: [f64; 8],
    pub(crate) terms: [(DVec3, [f64; 3]); 2],
    pub(crate) n_terms: u8,
}

/// One unit's (cell's or node's) samples and counters.
#[derive(Debug, Default)]
pub(crate) struct UnitOut {
    pub(crate) nodes: [usize; 8],
    pub(crate) samples: Vec<SampleOut>,
    pub(crate) rejected: Vec<[f64; 8]>,
    pub(crate) stats: BakeStats,
    /// [`Method::Doi`]: the point a node outside the domain was relocated to.
    pub(crate) relocated: Option<DVec3>,
    /// With light groups ([`Transport::groups`]): per sample, its terms' radiance / pdf
    /// split by group, `[sample][term][group]` (two terms per sample, the second zero
    /// when the sample has one); empty without groups.
    pub(crate) grouped: Vec<[f64; 3]>,
}

impl UnitOut {
    /// Each kept sample's value for the noise target ([`crate::noise::sample_value`]).
    pub(crate) fn sample_values(&self) -> Vec<f64> {
        self.samples
            .iter()
            .map(|s| {
                let terms: Vec<[f64; 3]> = s.terms[..usize::from(s.n_terms)].iter().map(|t| t.1).collect();
                crate::noise::sample_value(&terms)
            })
            .collect()
    }
}

/// Density of uniform sphere directions.
const UNIFORM_SPHERE_PDF: f64 = 1.0 / (4.0 * PI);

/// The light terms of one probe sample at `x` along `dir` with first hit `hit`. With light
/// groups, the terms split by group are appended to `grouped` (two terms' worth, see
/// [`UnitOut::grouped`]); the terms returned are the same, bit for bit, as without.
#[allow(clippy::too_many_arguments, reason = "one sample's inputs and its two outputs")]
pub(crate) fn sample_terms(
    t: &Transport<'_>,
    settings: &BakeSettings,
    x: DVec3,
    dir: DVec3,
    hit: Option<Hit>,
    rng: &mut PathRng,
    stats: &mut BakeStats,
    grouped: &mut Vec<[f64; 3]>,
) -> ([(DVec3, [f64; 3]); 2], u8) {
    let pdf = settings.light_sampling.then_some(UNIFORM_SPHERE_PDF);
    if let Some(groups) = t.groups() {
        let g = groups.len();
        let at = grouped.len();
        grouped.resize(at + 2 * g, [0.0; 3]);
        let l = t.radiance_from_hit_grouped(dir, hit, pdf, rng, &mut stats.rays, &mut grouped[at..at + g]);
        for v in &mut grouped[at..at + g] {
            *v = v.map(|c| c / UNIFORM_SPHERE_PDF);
        }
        let first = (dir, l.map(|v| v / UNIFORM_SPHERE_PDF));
        if settings.light_sampling {
            let u = rng.next3();
            if let Some((d, r, key, factor)) = t.light_sample_keyed(x, UNIFORM_SPHERE_PDF, u, &mut stats.rays)
            {
                t.split_light_sample(d, r, key, factor, &mut grouped[at + g..at + 2 * g]);
                return ([first, (d, r)], 2);
            }
        }
        return ([first, (DVec3::Z, [0.0; 3])], 1);
    }
    let l = t.radiance_from_hit(dir, hit, pdf, rng, &mut stats.rays);
    let first = (dir, l.map(|v| v / UNIFORM_SPHERE_PDF));
    if settings.light_sampling {
        let u = rng.next3();
        if let Some(second) = t.light_sample(x, UNIFORM_SPHERE_PDF, u, &mut stats.rays) {
            return ([first, second], 2);
        }
    }
    ([first, (DVec3::Z, [0.0; 3])], 1)
}

pub(crate) fn point_unit(
    t: &Transport<'_>,
    grid: &GridSpec,
    settings: &BakeSettings,
    node: usize,
) -> UnitOut {
    let [i, j, k] = grid.node_coords(node);
    let x = DVec3::from_array(grid.node_position_world(i, j, k));
    let h = Qmc::<2>::new(settings.seed, hash2(node as u64, 0x0070_6f69_6e74));
    let mut out = UnitOut { nodes: [node; 8], ..Default::default() };
    let mut weights = [0.0; 8];
    weights[0] = 1.0;
    for s in 0..u64::from(settings.samples.get()) {
        let p = h.point(s);
        let dir = DVec3::from_array(sample_uniform_sphere(p));
        let mut rng = PathRng::new(settings.seed, hash2(node as u64, 0x0070_6f69_6e74), s);
        out.stats.rays.sampling += 1;
        let hit = t.tracer().closest_hit(x, dir, 0.0, f64::INFINITY);
        let (terms, n_terms) =
            sample_terms(t, settings, x, dir, hit, &mut rng, &mut out.stats, &mut out.grouped);
        out.samples.push(SampleOut { weights, terms, n_terms });
    }
    out.stats.units = 1;
    out.stats.candidates = u64::from(settings.samples.get());
    out.stats.samples_kept = u64::from(settings.samples.get());
    out
}

/// [`Method::DoiNode`]: `samples` candidates uniform in the node-centred box of one cell
/// (clamped to the grid), classified by Algorithm 2, the kept ones averaged with weight 1.
pub(crate) fn node_box_unit(
    t: &Transport<'_>,
    grid: &GridSpec,
    settings: &BakeSettings,
    node: usize,
) -> UnitOut {
    let [i, j, k] = grid.node_coords(node);
    let at = |a: usize, d: i64| neighbour_coordinate(grid, [i, j, k], a, d);
    // Half a cell each way, within the grid's box.
    let centre = DVec3::from_array(grid.node_position(i, j, k));
    let lo =
        DVec3::new(0.5 * (at(0, -1) + centre.x), 0.5 * (at(1, -1) + centre.y), 0.5 * (at(2, -1) + centre.z));
    let hi =
        DVec3::new(0.5 * (at(0, 1) + centre.x), 0.5 * (at(1, 1) + centre.y), 0.5 * (at(2, 1) + centre.z));
    let stream = hash2(node as u64, 0x6e6f_6465);
    let h = Qmc::<5>::new(settings.seed, stream);
    let mut out = UnitOut { nodes: [node; 8], ..Default::default() };
    let n = u64::from(settings.samples.get());
    let points: Vec<(DVec3, DVec3)> = (0..n)
        .map(|s| {
            let p = h.point(s);
            let g = lo + (hi - lo) * DVec3::new(p[0], p[1], p[2]);
            (
                DVec3::from_array(grid.to_world(g.to_array())),
                DVec3::from_array(sample_uniform_sphere([p[3], p[4]])),
            )
        })
        .collect();
    let back_face_points = kept_node_samples(t, settings, stream, &points, &mut out);
    out.stats.back_face_points = back_face_points;
    out.stats.cells_with_back_faces = u64::from(back_face_points > 0);
    out.stats.units = 1;
    out.stats.candidates = n;
    out
}

/// Algorithm 2 over one node's candidates `(origin, direction)` (stream `stream`): the kept
/// ones become samples of weight 1 for the node, the rejected ones its outside weight.
/// Returns the back-face points found.
pub(crate) fn kept_node_samples(
    t: &Transport<'_>,
    settings: &BakeSettings,
    stream: u64,
    points: &[(DVec3, DVec3)],
    out: &mut UnitOut,
) -> u64 {
    let c = classify_cell(t.tracer(), points.len() as u64, |s| points[s as usize], Retest::QueryDirection);
    out.stats.rays.add(&c.rays);
    out.stats.samples_rejected = c.rejected.len() as u64;
    let mut one = [0.0; 8];
    one[0] = 1.0;
    out.rejected = vec![one; c.rejected.len()];
    for cand in &c.kept {
        let mut rng = PathRng::new(settings.seed, stream, cand.index);
        let (terms, n_terms) = sample_terms(
            t,
            settings,
            cand.origin,
            cand.dir,
            cand.hit,
            &mut rng,
            &mut out.stats,
            &mut out.grouped,
        );
        out.samples.push(SampleOut { weights: one, terms, n_terms });
    }
    out.stats.samples_kept = c.kept.len() as u64;
    c.back_face_points.len() as u64
}

/// Grid coordinate along axis `a` of the node `d` steps from `node` on that axis, clamped to
/// the grid (a boundary node's neighbour outside is itself).
pub(crate) fn neighbour_coordinate(grid: &GridSpec, node: [u32; 3], a: usize, d: i64) -> f64 {
    let m = i64::from(grid.res()[a]) - 1;
    let mut c = node;
    c[a] = (i64::from(c[a]) + d).clamp(0, m) as u32;
    grid.node_position(c[0], c[1], c[2])[a]
}

pub(crate) fn cell_unit(t: &Transport<'_>, grid: &GridSpec, settings: &BakeSettings, cell: usize) -> UnitOut {
    let (lo, hi) = grid.cell_bounds(cell);
    let (lo, hi) = (DVec3::from_array(lo), DVec3::from_array(hi));
    let h = Qmc::<5>::new(settings.seed, cell as u64);
    let mut out = UnitOut { nodes: grid.cell_corners(cell), ..Default::default() };
    let n = u64::from(settings.samples.get());
    // Grid-space origin (for the weights) and world-space ray, computed once per candidate.
    let points: Vec<(DVec3, DVec3, DVec3)> = (0..n)
        .map(|i| {
            let p = h.point(i);
            let g = lo + (hi - lo) * DVec3::new(p[0], p[1], p[2]);
            let w = DVec3::from_array(grid.to_world(g.to_array()));
            (g, w, DVec3::from_array(sample_uniform_sphere([p[3], p[4]])))
        })
        .collect();
    let candidate_at = |i: u64| points[i as usize];
    let weights_of = |g: DVec3| -> [f64; 8] {
        let f = (g - lo) / (hi - lo);
        lightvol_volume::grid::corner_weights([f.x, f.y, f.z].map(|v| v.clamp(0.0, 1.0)))
    };
    let candidates: Vec<Candidate> = match settings.method {
        Method::DoiPaper => {
            let c = classify_cell(
                t.tracer(),
                n,
                |i| {
                    let (_, w, d) = candidate_at(i);
                    (w, d)
                },
                Retest::QueryDirection,
            );
            out.stats.rays.add(&c.rays);
            out.stats.back_face_points = c.back_face_points.len() as u64;
            out.stats.cells_with_back_faces = u64::from(!c.back_face_points.is_empty());
            out.stats.samples_rejected = c.rejected.len() as u64;
            out.rejected = c.rejected.iter().map(|&(i, _)| weights_of(candidate_at(i).0)).collect();
            c.kept
        }
        _ => (0..n)
            .map(|i| {
                let (_, w, d) = candidate_at(i);
                out.stats.rays.sampling += 1;
                let hit = t.tracer().closest_hit(w, d, 0.0, f64::INFINITY);
                Candidate { index: i, origin: w, dir: d, hit }
            })
            .collect(),
    };
    for c in &candidates {
        let mut rng = PathRng::new(settings.seed, cell as u64, c.index);
        let (terms, n_terms) =
            sample_terms(t, settings, c.origin, c.dir, c.hit, &mut rng, &mut out.stats, &mut out.grouped);
        out.samples.push(SampleOut { weights: weights_of(candidate_at(c.index).0), terms, n_terms });
    }
    out.stats.units = 1;
    out.stats.candidates = n;
    out.stats.samples_kept = candidates.len() as u64;
    out
}
