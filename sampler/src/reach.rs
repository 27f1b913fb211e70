//! Baking the node reach of [`lightvol_volume::reach`]: six bundles of rays per node, one cell long,
//! along the grid axes ([`REACH_BUNDLE_RAYS`]).
//!
//! Node `i`'s reach along `±a` is `t / ℓ_a`, `t` the distance of the closest surface its
//! ray along the world image of that axis meets within one cell (`ℓ_a`, the cell's world
//! length along `a`), or 1 when the ray meets none. A ray that first meets a *back face*
//! (§5 of Kontkanen & Laine 2006: the node is inside a solid) also gives 1: such a node's
//! value was made for the points next to it (relocated or filled by the bake), so it must
//! not be left out of their lookups. The exception is a node the bake *relocated*: its
//! value is the light on the side it was moved to, so a back face met by a ray that points
//! away from that side (`(y − x)·d ≤ 0`, `y` the relocated point) limits the reach like a
//! front face, and the points beyond the solid on the far side do not read the node. Rays
//! that would leave the grid are not traced (no lookup reads a node from outside the
//! grid); they give 1 too.
//!
//! The rays depend only on the node's position and, for a relocated node, on the point it
//! was moved to (which depends on the seed like the node's samples do), so the reach is the
//! same for any thread count or shard count.

use glam::DVec3;
use lightvol_volume::GridSpec;
use lightvol_volume::reach::REACH_DIRECTIONS;

use lightvol_scene::bvh::Tracer;

/// Rays per direction of a node's reach, at most: one to the neighbour and four to points
/// a quarter of a cell beside it on the neighbour's side ([`REACH_BUNDLE_OFFSET`]); the
/// reach is their median (traced in order: the first ray, then a pair only where the earlier rays leave it open). A wall across the cell edge stops all of them
/// at the same share of their length (exactly, for a wall perpendicular to the axis); a
/// chair leg, a table leg or a lamp's cable stops one or two of them and leaves the reach a
/// full cell, where one ray along the edge would cut the node off from everything behind
/// the leg (measured on the Breakfast Room's 8×6×10 grid: 35 of 480 nodes limited by one
/// ray, 30 by the bundle, the rest walls, chair seats and backs and the table top).
pub const REACH_BUNDLE_RAYS: usize = 5;

/// How far beside the neighbour, in cells along each perpendicular grid axis, the
/// [`REACH_BUNDLE_RAYS`] end: a quarter cell keeps every ray inside the node's trilinear
/// support and spreads them over half a cell, wider than the legs and cables of furniture
/// at the grid spacings bakes use (a tenth to a half of a metre).
pub const REACH_BUNDLE_OFFSET: f64 = 0.25;

/// The lateral end offsets (in cells) of the bundle along grid axis `a`: none, then ±
/// [`REACH_BUNDLE_OFFSET`] along the next axis, then along the last one.
fn bundle_offsets(a: usize) -> [[f64; 3]; REACH_BUNDLE_RAYS] {
    let (b, c) = ((a + 1) % 3, (a + 2) % 3);
    let mut out = [[0.0; 3]; REACH_BUNDLE_RAYS];
    for (k, (axis, sign)) in [(b, 1.0), (b, -1.0), (c, 1.0), (c, -1.0)].into_iter().enumerate() {
        out[k + 1][axis] = sign * REACH_BUNDLE_OFFSET;
    }
    out
}

/// The reach of one bundle, `trace(k)` the share of ray `k`'s length before it is stopped
/// (1 when it is not), and the rays traced. The rays are traced in the order of
/// [`bundle_offsets`] and only as far as the median needs them: the centre ray alone when
/// it is not stopped (a wall across the edge would have stopped it); the median of the
/// first three when they agree on being stopped or not (a wall, or a leg that only the
/// centre ray meets); the median of all five otherwise. The result depends only on the
/// rays' outcomes, never on the order threads trace nodes in.
fn bundle_reach(mut trace: impl FnMut(usize) -> f32) -> (f32, u64) {
    let mut seen = [1.0f32; REACH_BUNDLE_RAYS];
    seen[0] = trace(0);
    if seen[0] >= 1.0 {
        return (1.0, 1);
    }
    seen[1] = trace(1);
    seen[2] = trace(2);
    let stopped = seen[1..3].iter().filter(|&&s| s < 1.0).count();
    let median = |v: &mut [f32]| {
        v.sort_by(f32::total_cmp);
        v[v.len() / 2]
    };
    match stopped {
        0 => (1.0, 3),
        2 => (median(&mut seen[..3]), 3),
        _ => {
            seen[3] = trace(3);
            seen[4] = trace(4);
            (median(&mut seen), 5)
        }
    }
}

/// Node `node`'s reach in [`REACH_DIRECTIONS`] order (module docs), and the rays traced;
/// `relocated` is where the bake moved the node's capture point, if it did.
#[must_use]
pub fn node_reach(
    tracer: &Tracer,
    grid: &GridSpec,
    node: usize,
    relocated: Option<DVec3>,
) -> ([f32; 6], u64) {
    let res = grid.res();
    let ijk = grid.node_coords(node);
    let g = grid.node_position(ijk[0], ijk[1], ijk[2]);
    let x = DVec3::from_array(grid.to_world(g));
    let cell = grid.cell_size();
    let mut reach = [1.0f32; 6];
    let mut rays = 0;
    for (d, step) in REACH_DIRECTIONS.iter().enumerate() {
        let a = d / 2;
        let to = i64::from(ijk[a]) + i64::from(step[a]);
        if to < 0 || to >= i64::from(res[a]) {
            continue;
        }
        let mut end = g;
        end[a] += f64::from(step[a]) * cell[a];
        let offsets = bundle_offsets(a);
        let (r, traced) = bundle_reach(|k| {
            let mut h = end;
            for b in 0..3 {
                h[b] += offsets[k][b] * cell[b];
            }
            let span = DVec3::from_array(grid.to_world(h)) - x;
            let len = span.length();
            // A ray to a point on the neighbour's cell face: the share of its length before
            // a hit is the share of the axial cell length before it.
            match tracer.closest_hit(x, span / len, 0.0, len) {
                Some(hit) if !hit.back_face || relocated.is_some_and(|y| (y - x).dot(span) <= 0.0) => {
                    ((hit.t / len) as f32).clamp(0.0, 1.0)
                }
                _ => 1.0,
            }
        });
        reach[d] = r;
        rays += traced;
    }
    (reach, rays)
}

#[cfg(test)]
mod tests {
    use super::*;
    use lightvol_scene::builder::SceneBuilder;
    use lightvol_scene::material::Material;

    /// A closed slab `0.3 ≤ x ≤ 0.4` across a 3×3×3 grid over [0, 2]³ (cells of 1): the
    /// nodes at x = 0 reach 0.3 cells along +x, those at x = 1 reach 0.6 along -x, and
    /// nothing else is limited.
    #[test]
    fn a_wall_limits_the_nodes_on_both_sides() {
        let mut b = SceneBuilder::new("slab");
        let m = b.add_material(Material::diffuse("grey", [0.5; 3])).unwrap();
        b.add_box(DVec3::new(0.3, -1.0, -1.0), DVec3::new(0.4, 3.0, 3.0), m, true, false).unwrap();
        let tracer = Tracer::new(&b.build().unwrap());
        let grid = GridSpec::new([0.0; 3], [2.0; 3], [3, 3, 3]).unwrap();
        let per_node: Vec<([f32; 6], u64)> =
            (0..grid.node_count()).map(|node| node_reach(&tracer, &grid, node, None)).collect();
        let rays: u64 = per_node.iter().map(|p| p.1).sum();
        let reach = lightvol_volume::NodeReach::new(per_node.into_iter().map(|p| p.0).collect()).unwrap();
        // 27 nodes × 6 directions, less the 9 × 6 that would leave the grid: one ray each,
        // and two more for each of the 18 directions the wall stops (all three agree).
        assert_eq!(rays, 27 * 6 - 54 + 18 * 2);
        for node in 0..grid.node_count() {
            let [i, _, _] = grid.node_coords(node);
            let r = reach.node(node);
            let want_plus_x = if i == 0 { 0.3 } else { 1.0 };
            let want_minus_x = if i == 1 { 0.6 } else { 1.0 };
            // f64 ray distances of O(1) rounded to f32.
            assert!((r[0] - want_plus_x).abs() < 1e-6, "node {node}: {r:?}");
            assert!((r[1] - want_minus_x).abs() < 1e-6, "node {node}: {r:?}");
            assert_eq!(&r[2..], &[1.0; 4], "node {node}");
        }
        assert_eq!(reach.limited_count(), 18);
    }

    /// A node inside a closed slab `0.8 ≤ x ≤ 1.4` (the grid's x = 1 node) sees its back
    /// faces at 0.4 cells along +x and 0.2 along -x. Not relocated, or relocated to +x, it
    /// reaches a full cell along +x; relocated to +x it reaches only 0.2 along -x, where the
    /// far side of the slab begins.
    #[test]
    fn a_relocated_node_inside_a_wall_reaches_only_the_side_it_was_moved_to() {
        let mut b = SceneBuilder::new("thick slab");
        let m = b.add_material(Material::diffuse("grey", [0.5; 3])).unwrap();
        // Off-centre in y and z, so that no ray runs along a quad's diagonal.
        b.add_box(DVec3::new(0.8, -1.3, -1.1), DVec3::new(1.4, 3.2, 3.1), m, true, false).unwrap();
        let tracer = Tracer::new(&b.build().unwrap());
        let grid = GridSpec::new([0.0; 3], [2.0; 3], [3, 3, 3]).unwrap();
        let node = grid.node_index(1, 1, 1);
        // f64 ray distances of O(1) rounded to f32.
        let close = |a: f32, b: f32| (a - b).abs() < 1e-6;
        let (r, rays) = node_reach(&tracer, &grid, node, None);
        assert_eq!(rays, 6, "a back face is not a stop: only the centre rays are traced");
        assert_eq!(r, [1.0; 6], "not relocated: every back face gives a full cell");
        let (r, _) = node_reach(&tracer, &grid, node, Some(DVec3::new(1.41, 1.0, 1.0)));
        assert_eq!(r[0], 1.0, "{r:?}");
        assert!(close(r[1], 0.2), "{r:?}");
        assert_eq!(&r[2..], &[1.0; 4], "along the slab no ray meets a face");
        let (r, _) = node_reach(&tracer, &grid, node, Some(DVec3::new(0.79, 1.0, 1.0)));
        assert!(close(r[0], 0.4), "{r:?}");
        assert_eq!(r[1], 1.0, "{r:?}");
    }

    /// The bundle's rule on given ray outcomes: how many rays it traces and which median it
    /// takes, against the median of all five where it stops early.
    #[test]
    fn the_bundle_traces_only_what_its_median_needs() {
        let run = |outcomes: [f32; REACH_BUNDLE_RAYS]| {
            let mut asked = Vec::new();
            let (r, n) = bundle_reach(|k| {
                asked.push(k);
                outcomes[k]
            });
            assert_eq!(asked, (0..n as usize).collect::<Vec<_>>(), "rays in order, each once");
            (r, n)
        };
        assert_eq!(run([1.0, 0.1, 0.1, 0.1, 0.1]), (1.0, 1), "centre free: a full cell");
        assert_eq!(run([0.2, 1.0, 1.0, 0.1, 0.1]), (1.0, 3), "a leg on the centre line only");
        assert_eq!(run([0.4, 0.3, 0.5, 1.0, 1.0]), (0.4, 3), "a wall: the middle of three");
        assert_eq!(run([0.4, 0.3, 1.0, 1.0, 0.2]), (0.4, 5), "split: the median of five");
        assert_eq!(run([0.4, 0.3, 1.0, 1.0, 1.0]), (1.0, 5), "split, then free: a full cell");
    }

    /// A thin post standing on the edge between two nodes stops the centre ray only: the
    /// node still reaches its neighbour, after three rays.
    #[test]
    fn a_post_on_the_edge_does_not_limit_the_reach() {
        let mut b = SceneBuilder::new("post");
        let m = b.add_material(Material::diffuse("grey", [0.5; 3])).unwrap();
        // Along z, 0.1 wide in x and y around the edge from node (0, 1, 1) to node (1, 1, 1);
        // the bundle's first pair ends 0.25 beside the neighbour along y and passes it.
        b.add_box(DVec3::new(0.45, 0.95, -1.0), DVec3::new(0.55, 1.05, 3.0), m, true, false).unwrap();
        let tracer = Tracer::new(&b.build().unwrap());
        let grid = GridSpec::new([0.0; 3], [2.0; 3], [3, 3, 3]).unwrap();
        let (r, rays) = node_reach(&tracer, &grid, grid.node_index(0, 1, 1), None);
        assert_eq!(r, [1.0; 6]);
        // +x: the centre ray and one pair; ±y, ±z: the centre ray; -x leaves the grid.
        assert_eq!(rays, 3 + 4);
    }
}
