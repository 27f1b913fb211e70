//! Per-node reach: how far each node sees along its grid axes, and the lookup that leaves a
//! node out of the interpolation where the query point lies beyond what the node sees.
//!
//! ## Why
//!
//! A wall thinner than a cell between two lit regions (a room and the street outside it,
//! two rooms) leaves nodes on both sides in the domain of interest (Kontkanen & Laine 2006
//! §5: they see no back faces), and the trilinear lookup (Eq. 2) of a point just inside
//! the room reads the node outside through the wall: the rim of the room comes out as
//! bright as the street, and the street next to the wall as dark as the room. No single
//! value per node can serve both sides of the wall. Renderers with ray-traced probes answer
//! at run time with a per-probe depth test (\[Maj19\]: a Chebyshev test of the query's
//! distance against the probe's mean and mean-square ray distance in the query's
//! direction). A [`NodeReach`] is the smallest such
//! record that removes the thin-wall leak: six distances per node, each the free distance
//! from the node along one grid axis, in cells, capped at one cell (a lookup never reads a
//! node from farther than one cell along an axis).
//!
//! ## The lookup
//!
//! For a query at `x` in the cell with base corner `(i, j, k)`, let `f = x_grid - (i, j, k)`
//! be its position in cells relative to that corner, taken at the *test point* (below).
//! Corner `c = dx + 2dy + 4dz` is `s_a = f_a` cells from `x` along `+a` when `d_a = 0` and
//! `s_a = 1 - f_a` cells along `-a` when `d_a = 1`. The corner is *cut off* from the query
//! on axis `a` when the query lies beyond its reach there, `s_a > r_c(±a)`, and the cell
//! edge from `c` along `a` is blocked from both ends: `r_c(±a) + r_c'(∓a) ≤ 1` (up to
//! [`REACH_EDGE_TOLERANCE`]), `c' = c xor 2^a` the corner across the edge. A corner cut off
//! on no axis *sees* the query. The second condition tells a wall across the edge (both
//! nodes see it, from its two sides) from a surface only one end of the edge sees: the top
//! of a wall under a node whose neighbour below is inside the wall, the floor under a node
//! whose neighbour is under the floor. Those neighbours reach a full cell (a back face
//! gives 1), so the node above keeps lighting the points beside the wall, which it sees
//! past the wall's top. The weights are then renormalised over the corners
//! that see the query exactly as over valid corners ([`crate::validity`]): all seeing, or
//! none seeing with weight, leaves the plain trilinear weights.
//!
//! The test is exact for walls perpendicular to a grid axis that cross the whole cell (the
//! common case in buildings and in the grids fitted to them) and approximate for slanted
//! ones and for walls that end inside the cell.
//!
//! **Test point.** A surface query (irradiance at a point on a wall, with the wall's
//! normal `n`) lies exactly at the distance the nodes in front of the wall measured, and a
//! node behind a two-sided wall measured the same distance from the other side. The test
//! point is therefore `x + n · REACH_NORMAL_BIAS · h`, `h` the smallest world-space cell
//! edge: a little in front of the surface, so that the nodes in front see it and the nodes
//! behind do not (\[Maj19\]'s normal bias, for the same reason). Only
//! the test point moves; the trilinear weights stay those of `x`. Radiance lookups and
//! coefficient lookups have no normal and test `x` itself.
//!
//! The trilinear CPU lookups ([`crate::lookup`]) and the gradient lookups
//! ([`crate::gradient`]) read the reach, like the validity mask, and so do lightvol-gpu's
//! Vulkan evaluator and engine shader code (`lightvol_irradiance_reach`); the adaptive
//! octree does not (its bakes record none), and the Bevy export drops it. It
//! travels with the volume through the native EXR ([`crate::io::exr`]), the KTX2/DDS
//! sidecar ([`crate::io::sidecar`]) and shard files ([`crate::accumulator`]).
//!
//! A reach of 1 on every axis (the value of a node that sees nothing within a cell, and of
//! a node inside a solid, whose rays meet back faces and whose value the bake filled for
//! the very points next to it) never leaves a corner out, so a volume whose nodes all reach
//! one cell is looked up bit for bit like the same volume without a reach.

use crate::error::VolumeError;
use crate::grid::GridSpec;
use crate::validity::{hex_digit, renormalise};

/// The test point's offset along the surface normal, in units of the smallest world-space
/// cell edge (module docs). A tenth of a cell: large enough to separate the two sides of a
/// wall after the f32 rounding of the lookup (~1e-7 of the grid's extent), small against
/// the cell so that the nodes in front of a surface still see points a tenth of a cell
/// from a perpendicular wall.
pub const REACH_NORMAL_BIAS: f64 = 0.1;

/// How far past one cell the two reaches along a cell edge may sum and still count as
/// meeting the same surface (module docs): a two-sided wall of zero thickness gives
/// `t / ℓ + (ℓ - t) / ℓ = 1` in exact arithmetic, and each reach carries one f32 rounding
/// (6e-8 at most below 1) from its f64 ray distance.
pub const REACH_EDGE_TOLERANCE: f64 = 1e-6;

/// Direction order of a node's six reaches: `+x, -x, +y, -y, +z, -z` (grid axes).
pub const REACH_DIRECTIONS: [[i8; 3]; 6] =
    [[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]];

/// The node reach's test-point offset along a surface normal, in world units
/// (module docs): [`REACH_NORMAL_BIAS`] times the smallest world-space
/// cell edge (grid-space cell size times the placement's stretch of that axis).
#[must_use]
pub fn reach_bias(spec: &GridSpec) -> f64 {
    let cell = spec.cell_size();
    let stretch = |a: usize| {
        spec.placement().map_or(1.0, |p| {
            let m = p.to_world_matrix();
            (m[0][a] * m[0][a] + m[1][a] * m[1][a] + m[2][a] * m[2][a]).sqrt()
        })
    };
    let h = (0..3).map(|a| cell[a] * stretch(a)).fold(f64::INFINITY, f64::min);
    REACH_NORMAL_BIAS * h
}

/// How far each node sees along its grid axes, in cells, capped at 1 (module docs).
#[derive(Clone, PartialEq)]
pub struct NodeReach {
    reach: Vec<[f32; 6]>,
}

/// A summary: the node count and how many nodes are limited in some direction.
impl std::fmt::Debug for NodeReach {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "NodeReach({} nodes, {} limited)", self.reach.len(), self.limited_count())
    }
}

impl NodeReach {
    /// The reach `reach[i]` of node `i` in [`REACH_DIRECTIONS`] order.
    ///
    /// # Errors
    /// [`VolumeError::Mismatch`] for a value that is not in `[0, 1]` (NaN included).
    pub fn new(reach: Vec<[f32; 6]>) -> Result<Self, VolumeError> {
        if let Some((i, r)) =
            reach.iter().enumerate().find(|(_, r)| r.iter().any(|v| !(0.0..=1.0).contains(v)))
        {
            return Err(VolumeError::Mismatch(format!("node {i}: reach {r:?} outside [0, 1] cells")));
        }
        Ok(Self { reach })
    }

    /// Nodes covered.
    #[must_use]
    pub fn len(&self) -> usize {
        self.reach.len()
    }

    /// No nodes.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.reach.is_empty()
    }

    /// Node `i`'s reach in [`REACH_DIRECTIONS`] order.
    #[must_use]
    pub fn node(&self, i: usize) -> [f32; 6] {
        self.reach[i]
    }

    /// Nodes that see less than a cell in some direction.
    #[must_use]
    pub fn limited_count(&self) -> usize {
        self.reach.iter().filter(|r| r.iter().any(|&v| v < 1.0)).count()
    }

    /// Bytes held: 24 per node.
    #[must_use]
    pub fn memory_bytes(&self) -> usize {
        self.reach.len() * size_of::<[f32; 6]>()
    }

    /// The reach as text: every node's six values in [`REACH_DIRECTIONS`] order, each as
    /// its f32 bits little-endian, two lowercase hex digits per byte (48 per node).
    #[must_use]
    pub fn to_hex(&self) -> String {
        use std::fmt::Write;
        let mut s = String::with_capacity(self.reach.len() * 48);
        for r in &self.reach {
            for v in r {
                for b in v.to_bits().to_le_bytes() {
                    write!(s, "{b:02x}").expect("writing to a String");
                }
            }
        }
        s
    }

    /// Parses [`Self::to_hex`] for `nodes` nodes; errors on another length, a character
    /// that is not a lowercase hex digit, or a value outside `[0, 1]`.
    pub fn from_hex(text: &str, nodes: usize) -> Result<Self, VolumeError> {
        let bytes = text.as_bytes();
        if bytes.len() != nodes * 48 {
            return Err(VolumeError::Mismatch(format!(
                "node reach of {} hex digits for {nodes} nodes (48 per node)",
                bytes.len()
            )));
        }
        let digit = |c: u8| {
            hex_digit(c).ok_or_else(|| {
                VolumeError::Mismatch(format!("{:?} is not a lowercase hex digit", char::from(c)))
            })
        };
        let mut reach = Vec::with_capacity(nodes);
        for node in bytes.chunks_exact(48) {
            let mut r = [0.0f32; 6];
            for (d, v) in node.chunks_exact(8).enumerate() {
                let mut b = [0u8; 4];
                for (i, pair) in v.chunks_exact(2).enumerate() {
                    b[i] = digit(pair[0])? << 4 | digit(pair[1])?;
                }
                r[d] = f32::from_bits(u32::from_le_bytes(b));
            }
            reach.push(r);
        }
        Self::new(reach)
    }

    /// Which corners of a cell see a query at `f` cells from the cell's base corner (the
    /// test point's position, module docs), corner `c` being node `nodes(c)`.
    #[must_use]
    pub fn sees(&self, nodes: impl Fn(usize) -> usize, f: [f64; 3]) -> [bool; 8] {
        std::array::from_fn(|c| {
            let r = self.reach[nodes(c)];
            (0..3).all(|a| {
                let d = (c >> a) & 1;
                let s = if d == 0 { f[a] } else { 1.0 - f[a] };
                let (here, there) =
                    (f64::from(r[2 * a + d]), f64::from(self.reach[nodes(c ^ (1 << a))][2 * a + 1 - d]));
                s <= here || here + there > 1.0 + REACH_EDGE_TOLERANCE
            })
        })
    }

    /// Renormalises the f32 weights `w` over the corners that see `f` (module docs).
    #[inline]
    pub fn reweight_f32(&self, nodes: impl Fn(usize) -> usize, f: [f64; 3], w: &mut [f32; 8]) {
        renormalise(self.sees(nodes, f), w);
    }

    /// [`Self::reweight_f32`] in f64 (the reference lookups).
    #[inline]
    pub fn reweight_f64(&self, nodes: impl Fn(usize) -> usize, f: [f64; 3], w: &mut [f64; 8]) {
        renormalise(self.sees(nodes, f), w);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::IrradianceVolume;

    fn all_ones(n: usize) -> NodeReach {
        NodeReach::new(vec![[1.0; 6]; n]).unwrap()
    }

    #[test]
    fn full_reach_sees_everything_in_the_cell() {
        let r = all_ones(8);
        for f in [[0.0, 0.0, 0.0], [1.0, 1.0, 1.0], [0.3, 0.9, 0.5]] {
            assert_eq!(r.sees(|c| c, f), [true; 8]);
        }
    }

    /// A wall perpendicular to x at 0.4 cells from the cell's base corners: corners with
    /// `dx = 0` reach 0.4 along +x, those with `dx = 1` reach 0.6 along -x. A point at
    /// x = 0.3 is seen only by the `dx = 0` corners, one at x = 0.5 only by the others.
    #[test]
    fn a_wall_splits_the_cell_between_its_sides() {
        let reach: Vec<[f32; 6]> = (0..8)
            .map(|c| if c & 1 == 0 { [0.4, 1.0, 1.0, 1.0, 1.0, 1.0] } else { [1.0, 0.6, 1.0, 1.0, 1.0, 1.0] })
            .collect();
        let r = NodeReach::new(reach).unwrap();
        let near = r.sees(|c| c, [0.3, 0.5, 0.5]);
        let far = r.sees(|c| c, [0.5, 0.5, 0.5]);
        for c in 0..8 {
            assert_eq!(near[c], c & 1 == 0, "corner {c} at x = 0.3");
            assert_eq!(far[c], c & 1 == 1, "corner {c} at x = 0.5");
        }
        let mut w = [0.125f64; 8];
        r.reweight_f64(|c| c, [0.3, 0.5, 0.5], &mut w);
        for c in 0..8 {
            assert_eq!(w[c], if c & 1 == 0 { 0.25 } else { 0.0 });
        }
    }

    /// One cell over [0, 1]³, 4 coefficients, corner `c`'s DC coefficient `1 + c` (others
    /// 0), with the wall of [`a_wall_splits_the_cell_between_its_sides`] at x = 0.4.
    fn walled_cell() -> (IrradianceVolume, IrradianceVolume) {
        let grid = GridSpec::new([0.0; 3], [1.0; 3], [2, 2, 2]).unwrap();
        let mut data = vec![0.0f32; 8 * 12];
        for c in 0..8 {
            for ch in 0..3 {
                data[c * 12 + ch] = 1.0 + c as f32;
            }
        }
        let plain = IrradianceVolume::new(grid, 4, data, vec![1.0; 8]).unwrap();
        let reach: Vec<[f32; 6]> = (0..8)
            .map(|c| if c & 1 == 0 { [0.4, 1.0, 1.0, 1.0, 1.0, 1.0] } else { [1.0, 0.6, 1.0, 1.0, 1.0, 1.0] })
            .collect();
        let walled = plain.clone().with_reach(NodeReach::new(reach).unwrap()).unwrap();
        (plain, walled)
    }

    /// The irradiance the corners `side` (`dx` = 0 or 1) give at `p`: their own irradiance
    /// (the plain volume at the corner), weighted by their renormalised trilinear weights.
    fn side_only(plain: &IrradianceVolume, p: [f64; 3], n: [f64; 3], side: usize) -> [f64; 3] {
        let (nodes, w) = plain.spec().trilinear_world(p);
        let s: f64 = (0..8).filter(|c| c & 1 == side).map(|c| w[c]).sum();
        let mut out = [0.0; 3];
        for c in (0..8).filter(|c| c & 1 == side) {
            let ijk = plain.spec().node_coords(nodes[c]);
            let e = plain.irradiance_reference(plain.spec().node_position_world(ijk[0], ijk[1], ijk[2]), n);
            for ch in 0..3 {
                out[ch] += w[c] / s * e[ch];
            }
        }
        out
    }

    /// Every lookup of a walled volume reads only the corners on the query's side of the
    /// wall; on the wall itself the normal picks the side; a reach of one cell everywhere
    /// changes no bit.
    #[test]
    fn lookups_read_only_the_corners_on_the_query_side() {
        let (plain, walled) = walled_cell();
        let up = [0.0, 0.0, 1.0];
        let cases = [
            ([0.3, 0.45, 0.7], up, 0),
            ([0.55, 0.2, 0.35], up, 1),
            ([0.4, 0.5, 0.5], [-1.0, 0.0, 0.0], 0),
            ([0.4, 0.5, 0.5], [1.0, 0.0, 0.0], 1),
        ];
        for (p, n, side) in cases {
            let want = side_only(&plain, p, n, side);
            let reference = walled.irradiance_reference(p, n);
            let fast = walled.irradiance(p.map(|v| v as f32), n.map(|v| v as f32));
            let mut batch = [[0.0f32; 3]];
            walled.irradiance_batch(&[p.map(|v| v as f32)], &[n.map(|v| v as f32)], &mut batch).unwrap();
            for ch in 0..3 {
                // Sums of 8 products of O(1) values in another order: a few ulps of ~10.
                assert!((reference[ch] - want[ch]).abs() < 1e-12, "{p:?} {n:?}: {reference:?} vs {want:?}");
                // f32 weights and coefficients of O(1), 8-term sums.
                assert!((f64::from(fast[ch]) - want[ch]).abs() < 1e-5, "{p:?} {n:?}: {fast:?} vs {want:?}");
                assert_eq!(fast[ch].to_bits(), batch[0][ch].to_bits(), "batched and scalar paths differ");
            }
        }
        let open = plain.clone().with_reach(NodeReach::new(vec![[1.0; 6]; 8]).unwrap()).unwrap();
        for p in [[0.3f32, 0.45, 0.7], [0.55, 0.2, 0.35]] {
            assert_eq!(open.irradiance(p, [0.0, 0.0, 1.0]), plain.irradiance(p, [0.0, 0.0, 1.0]));
        }
    }

    /// A surface only one end of a cell edge sees (the top of a wall under node 0, whose
    /// neighbour across the edge reaches a full cell because it is inside the wall) does
    /// not cut node 0 off from the points beside the wall.
    #[test]
    fn a_surface_seen_from_one_end_of_the_edge_cuts_nothing_off() {
        let mut reach = vec![[1.0f32; 6]; 8];
        reach[0][0] = 0.2;
        let r = NodeReach::new(reach.clone()).unwrap();
        assert_eq!(r.sees(|c| c, [0.5, 0.5, 0.5]), [true; 8]);
        // The same hit seen from the other end as well is a wall across the edge.
        reach[1][1] = 0.8;
        let r = NodeReach::new(reach).unwrap();
        let seen = r.sees(|c| c, [0.5, 0.5, 0.5]);
        assert!(!seen[0] && seen[1..].iter().all(|&s| s), "{seen:?}");
    }

    #[test]
    fn hex_round_trips_and_is_checked() {
        let r = NodeReach::new(vec![[0.25, 1.0, 0.0, 0.5, 0.75, 1.0], [1.0; 6]]).unwrap();
        let hex = r.to_hex();
        assert_eq!(hex.len(), 96);
        // 0.25 = 0x3e800000, little-endian.
        assert_eq!(&hex[..8], "0000803e");
        assert_eq!(NodeReach::from_hex(&hex, 2).unwrap(), r);
        assert!(NodeReach::from_hex(&hex, 3).is_err());
        assert!(NodeReach::from_hex(&hex.replace('e', "E"), 2).is_err());
        // 2.0 = 0x40000000 is outside one cell.
        assert!(NodeReach::from_hex(&hex.replacen("0000803e", "00000040", 1), 2).is_err());
    }

    #[test]
    fn values_outside_one_cell_are_refused() {
        assert!(NodeReach::new(vec![[1.0, 1.0, 1.0, 1.0, 1.0, 1.5]]).is_err());
        assert!(NodeReach::new(vec![[f32::NAN, 1.0, 1.0, 1.0, 1.0, 1.0]]).is_err());
        assert!(NodeReach::new(vec![[-0.1, 1.0, 1.0, 1.0, 1.0, 1.0]]).is_err());
        assert_eq!(all_ones(3).limited_count(), 0);
    }
}
