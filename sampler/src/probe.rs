//! `doi`'s probe: a node point-sampled where it stands when it is in the domain of interest,
//! at a point moved through its closest back face when it is not ([`crate::relocate`]), and
//! filled from its neighbours when neither is ([`ProbeCapture`]).

use glam::DVec3;
use lightvol_scene::bvh::{Hit, Tracer};
use lightvol_scene::qmc::Qmc;
use lightvol_scene::transport::{PathRng, Transport};
use lightvol_sh::lowdisc::hash2;
use lightvol_sh::sampling::sample_uniform_sphere;
use lightvol_volume::GridSpec;

use crate::relocate::{DDGI_BACKFACE_THRESHOLD, relocate_within, spacing};
use crate::settings::BakeSettings;
use crate::unit::{SampleOut, UnitOut, sample_terms};

/// `doi`: rays from the node before it counts as outside the domain of
/// interest, also the rays among which the closest back face is looked for.
pub const PROBE_SEARCH_RAYS: u64 = 16;

/// `doi`: each axis of a relocation's offset is clamped to this share of the grid
/// spacing. DDGI's [`DDGI_MAX_OFFSET`](crate::relocate::DDGI_MAX_OFFSET) (0.45) leaves a node at the middle
/// of a wall one cell thick inside it (half a cell from either face), so it would be filled
/// from the nodes on both sides of the wall; half a cell plus a tenth moves the middle node
/// out of any wall thinner than 1.1 cells, and the node's reach
/// ([`crate::reach::node_reach`]) then cuts it off from the side it was not moved to.
pub const PROBE_MAX_OFFSET: f64 = 0.55;

/// `doi`: a back face farther than one grid spacing along some axis (outside the
/// node's trilinear support) takes the node out of the domain of interest only when more
/// than this share of its directions meet one: the back-face share above which DDGI
/// relocates a probe and Unity APV invalidates one ([`crate::baselines`]). A node deep
/// inside a solid wider than two cells meets back faces in nearly every direction and is
/// still outside; a node in a room that sees the back of a single-sided panel, a window
/// frame or a blind across the room is not, and keeps its point sample (measured on the
/// Breakfast Room at 1024 samples: relative RMSE 0.151 to 0.119, see the crate README).
pub const PROBE_FAR_BACK_SHARE: f64 = DDGI_BACKFACE_THRESHOLD;

/// `doi`: a back face inside the node's trilinear support (the box of one grid spacing
/// around it) takes the node out of the domain of interest only when more than this share
/// of its directions meet one. A node inside a solid, or in the middle of a wall thinner
/// than a cell, meets near back faces in most directions (a share near 1). A node in open
/// space beside real, single-sided content meets them only through slivers: the open end
/// of a chair's tube, the gap under a skirting board. On the Breakfast Room's 8×6×10 grid
/// the largest such share, over 16,384 directions, was 0.8%, against 35% for the one node
/// inside the table top. Counting the first such back face (a share of 0) made the
/// classification grow with the sample count (13 nodes filled at 256 samples, 26 at 4,096:
/// a sliver of share `p` is found with probability `1 − (1 − p)^n`) and
/// moved the nodes under the table and chairs to brighter places. A share gives a
/// classification that converges: it changes with the sample count only where a node's
/// share is within sampling noise of this threshold. Five percent leaves a factor of six
/// over the slivers measured and a factor of seven under the node in the table top.
pub const PROBE_NEAR_BACK_SHARE: f64 = 0.05;

/// `doi`: a node outside the domain of interest spends at most this share of
/// `samples` on its relocated point.
pub const PROBE_OUTSIDE_SHARE: f64 = 0.5;

/// Where `doi` took a node's value from.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ProbeCapture {
    /// The node is in the domain of interest: it meets back faces inside its trilinear
    /// support in at most [`PROBE_NEAR_BACK_SHARE`] of its directions, and far ones in at
    /// most [`PROBE_FAR_BACK_SHARE`];
    /// point-sampled there (Eq. 4).
    AtNode,
    /// The node is outside the domain of interest; this point, reached through the closest
    /// back face among the first [`PROBE_SEARCH_RAYS`] directions whose move keeps it in the
    /// grid's box (the closest of all when no move does: moved out of the box, the node
    /// would carry the light of a place that no lookup asks about, so a node in the middle
    /// of a wall on the grid's boundary moves to the side the lookups read), each axis of
    /// the move clamped to [`PROBE_MAX_OFFSET`] × spacing
    /// ([`relocate_within`]), is in the domain by the same test and was
    /// point-sampled.
    Relocated(DVec3),
    /// Neither the node nor its relocated point is in the domain: the node keeps no
    /// samples, its domain weight is 0, and the accumulator's fill
    /// ([`lightvol_volume::fill`]) gives it the inverse-square-distance mean of its 26
    /// neighbours' estimates, the way a node deep inside a solid is filled under Eq. 6.
    /// (Eq. 6's own average over the node's support was measured worse: with a wall
    /// inside the support it mixes the light of both sides, and at half the samples it is
    /// noisy; see the crate README.)
    Filled,
}

/// Where [`clean_directions`] stopped.
struct Stopped {
    /// Directions traced, the last one meeting the back face that stopped it.
    traced: u64,
    /// Every back face met, tolerated or not, as (direction index, direction, distance),
    /// in stream order.
    back_faces: Vec<(u64, DVec3, f64)>,
}

/// `doi`'s distance-limited back-face test of a point: back faces inside the
/// box of one grid spacing around the point (a node's trilinear support, \[KL06\] Eq. 6)
/// take it out of the domain of interest when more than [`PROBE_NEAR_BACK_SHARE`] of the
/// directions meet one; back faces beyond that box do when more than
/// [`PROBE_FAR_BACK_SHARE`] of the directions meet one.
struct BackFaceTest {
    /// Grid spacing per axis: the half-widths of the box.
    spacing: DVec3,
    /// Far back faces tolerated among the directions traced.
    far_allowed: u64,
    /// Near back faces (inside the box) tolerated among the directions traced.
    near_allowed: u64,
}

impl BackFaceTest {
    /// The test on a grid of `spacing` for a point traced along `count` directions.
    fn new(spacing: [f64; 3], count: u64) -> Self {
        Self {
            spacing: DVec3::from_array(spacing),
            far_allowed: (count as f64 * PROBE_FAR_BACK_SHARE).floor() as u64,
            near_allowed: (count as f64 * PROBE_NEAR_BACK_SHARE).floor() as u64,
        }
    }

    /// The back face met at distance `t` along the unit direction `dir` lies inside the box.
    fn near(&self, dir: DVec3, t: f64) -> bool {
        (dir * t).abs().cmple(self.spacing).all()
    }
}

/// One direction a point traced: its index in the stream, the direction and what it met.
type Traced = (u64, DVec3, Option<Hit>);

/// Bytes a unit holds per sample while it is traced (its [`Traced`] record): the unit of
/// the bake's check that its samples fit in memory.
pub(crate) const TRACED_BYTES: u128 = size_of::<Traced>() as u128;

/// The directions `first..first + count` of `h` traced from `x`, stopping at the first
/// back face that takes `x` out of the domain under `test`: every direction traced (those
/// meeting a tolerated far or near back face are kept, as `point` keeps them), or where
/// it stopped. `rays` counts the rays traced.
fn clean_directions(
    tracer: &Tracer,
    h: &Qmc<2>,
    x: DVec3,
    first: u64,
    count: u64,
    test: &BackFaceTest,
    rays: &mut u64,
) -> Result<Vec<Traced>, Stopped> {
    let mut hits = Vec::with_capacity(count as usize);
    let mut far = 0u64;
    let mut near = 0u64;
    let mut back_faces = Vec::new();
    for s in first..first + count {
        let dir = DVec3::from_array(sample_uniform_sphere(h.point(s)));
        *rays += 1;
        let hit = tracer.closest_hit(x, dir, 0.0, f64::INFINITY);
        if let Some(b) = hit.filter(|h| h.back_face) {
            back_faces.push((s, dir, b.t));
            let is_near = test.near(dir, b.t);
            if (is_near && near >= test.near_allowed) || (!is_near && far >= test.far_allowed) {
                return Err(Stopped { traced: s + 1 - first, back_faces });
            }
            if is_near { near += 1 } else { far += 1 }
        }
        hits.push((s, dir, hit));
    }
    Ok(hits)
}

/// `doi`'s classification of one node: where its value comes from, and the directions
/// traced from there (none when it is filled).
pub(crate) struct NodeClass {
    /// Where the node's value comes from.
    pub capture: ProbeCapture,
    /// The directions kept, traced from the node or from its relocated point.
    pub kept: Vec<Traced>,
    /// Rays traced, kept or not.
    pub rays: u64,
    /// Where the directions start: the node, or for a node outside the domain the point it
    /// was moved to, kept (relocated) or not (filled, with no directions kept).
    pub from: DVec3,
}

/// Classifies node `node` of `grid` with `samples` directions of `point`'s stream under
/// `seed` (the rays of [`probe_samples`], without the light they carry).
pub(crate) fn classify_node(
    tracer: &Tracer,
    grid: &GridSpec,
    seed: u64,
    samples: u64,
    node: usize,
) -> NodeClass {
    let [i, j, k] = grid.node_coords(node);
    let x = DVec3::from_array(grid.node_position_world(i, j, k));
    let h = Qmc::<2>::new(seed, point_stream(node));
    let n = samples;
    let mut rays = 0u64;
    let spacing = spacing(grid);
    let at_node = BackFaceTest::new(spacing, n);
    let (mut used, met) = match clean_directions(tracer, &h, x, 0, n, &at_node, &mut rays) {
        Ok(kept) => return NodeClass { capture: ProbeCapture::AtNode, kept, rays, from: x },
        Err(e) => (e.traced, e.back_faces),
    };
    let (lo, hi) = grid.bounds();
    // A back face met at `dist` along `dir`: where the node moves through it, and whether
    // that point stays in the grid's box.
    let candidate = |(dir, dist): (DVec3, f64)| {
        let y = relocate_within(x, dir, dist, spacing, PROBE_MAX_OFFSET);
        let g = grid.to_grid(y.to_array());
        (dist, y, (0..3).all(|a| (lo[a]..=hi[a]).contains(&g[a])))
    };
    // The best back face among the first PROBE_SEARCH_RAYS directions, or up to the first
    // back face met when none of those meets one: one whose move stays in the box beats one
    // whose move leaves it; otherwise the closer one wins. The window does not depend on
    // the sample count (the stream's directions do not), so neither does the point.
    let rank = |(dist, _, in_box): (f64, DVec3, bool)| (!in_box, dist);
    let window = PROBE_SEARCH_RAYS.min(n).max(met[0].0 + 1);
    let mut best: Option<(f64, DVec3, bool)> = None;
    let mut consider = |dir: DVec3, dist: f64| {
        let c = candidate((dir, dist));
        if best.is_none_or(|b| rank(c) < rank(b)) {
            best = Some(c);
        }
    };
    for &(_, dir, dist) in met.iter().take_while(|m| m.0 < window) {
        consider(dir, dist);
    }
    while used < window {
        let dir = DVec3::from_array(sample_uniform_sphere(h.point(used)));
        rays += 1;
        used += 1;
        if let Some(b) = tracer.closest_hit(x, dir, 0.0, f64::INFINITY).filter(|h| h.back_face) {
            consider(dir, b.t);
        }
    }
    let left = n.saturating_sub(used).min((n as f64 * PROBE_OUTSIDE_SHARE).ceil() as u64);
    let y = best.expect("the first back face met is in the window").1;
    if left > 0 {
        let at_y = BackFaceTest::new(spacing, left);
        if let Ok(kept) = clean_directions(tracer, &h, y, n, left, &at_y, &mut rays) {
            return NodeClass { capture: ProbeCapture::Relocated(y), kept, rays, from: y };
        }
    }
    NodeClass { capture: ProbeCapture::Filled, kept: Vec::new(), rays, from: y }
}

/// `point`'s random stream for node `node`, which `doi` shares so that a node in the
/// domain is `point`'s bit for bit.
fn point_stream(node: usize) -> u64 {
    hash2(node as u64, 0x0070_6f69_6e74)
}

/// `doi` for one node: the samples and where they were taken, with the classification's
/// rays.
pub(crate) fn probe_unit(
    t: &Transport<'_>,
    grid: &GridSpec,
    settings: &BakeSettings,
    node: usize,
) -> (UnitOut, ProbeCapture) {
    let class = classify_node(t.tracer(), grid, settings.seed, u64::from(settings.samples.get()), node);
    let mut out = probe_samples(t, settings, node, &class, class.kept.len(), None);
    out.stats.rays.sampling += class.rays;
    (out, class.capture)
}

impl NodeClass {
    /// How many of the kept directions a round of `n` samples takes when the node was
    /// classified with more directions (a bake until converged, [`crate::noise`]): those of
    /// index below `n` at the node, as a bake of `n` samples would keep; for a relocated
    /// node the first `⌈n · PROBE_OUTSIDE_SHARE⌉`, the most a bake of `n` would keep there.
    pub(crate) fn take(&self, n: u64) -> usize {
        match self.capture {
            ProbeCapture::AtNode => self.kept.partition_point(|k| k.0 < n),
            ProbeCapture::Relocated(_) => {
                self.kept.len().min((n as f64 * PROBE_OUTSIDE_SHARE).ceil() as usize)
            }
            ProbeCapture::Filled => 0,
        }
    }
}

/// The light of `node`'s first `take` kept directions of `class` (the point sample of
/// Eq. 4 at the node, or at its relocated point), without the classification's rays. The
/// first samples are taken from `earlier` where it has them: a sample is a function of
/// where the directions start, its direction and first hit and its own path stream, so a
/// round of a bake until converged that extends an earlier round of the same
/// classification gets that round's samples bit for bit, and their bounces need no
/// tracing again (their rays were counted with that round). Their light-group terms, if
/// any, come along.
pub(crate) fn probe_samples(
    t: &Transport<'_>,
    settings: &BakeSettings,
    node: usize,
    class: &NodeClass,
    take: usize,
    earlier: Option<&UnitOut>,
) -> UnitOut {
    let mut out = UnitOut { nodes: [node; 8], ..Default::default() };
    out.stats.units = 1;
    out.stats.candidates = u64::from(settings.samples.get());
    let x = class.from;
    if class.capture != ProbeCapture::AtNode {
        out.stats.back_face_points = 1;
        out.stats.cells_with_back_faces = 1;
    }
    let stream = point_stream(node);
    let one = {
        let mut w = [0.0; 8];
        w[0] = 1.0;
        w
    };
    let per_sample = 2 * t.groups().map_or(0, |g| g.len());
    out.samples.reserve(take);
    for (i, &(s, dir, hit)) in class.kept[..take].iter().enumerate() {
        if let Some(e) = earlier.filter(|e| i < e.samples.len()) {
            out.samples.push(e.samples[i]);
            out.grouped.extend_from_slice(&e.grouped[i * per_sample..(i + 1) * per_sample]);
            continue;
        }
        let mut rng = PathRng::new(settings.seed, stream, s);
        let (terms, n_terms) =
            sample_terms(t, settings, x, dir, hit, &mut rng, &mut out.stats, &mut out.grouped);
        out.samples.push(SampleOut { weights: one, terms, n_terms });
    }
    out.stats.samples_kept = out.samples.len() as u64;
    if let ProbeCapture::Relocated(y) = class.capture {
        out.relocated = Some(y);
    }
    out
}

#[cfg(test)]
#[path = "probe_tests.rs"]
mod tests;
