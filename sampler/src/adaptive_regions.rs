//! The placement boxes of an adaptive bake (density, exclusion and walkable volumes,
//! [`AdaptiveSettings::regions`](crate::adaptive::AdaptiveSettings)) applied to the split
//! scores of [`crate::adaptive`]'s heuristics.

use glam::DVec3;
use lightvol_volume::{GridSpec, OctreeRegion, RegionKind};

/// The placement boxes of [`AdaptiveSettings::regions`](crate::adaptive::AdaptiveSettings) in the base grid's space (the
/// bounding box of each box's corners mapped there).
pub(crate) struct GridRegions {
    boxes: Vec<(RegionKind, DVec3, DVec3)>,
    walkable: bool,
}

impl GridRegions {
    pub(crate) fn new(base: &GridSpec, regions: &[OctreeRegion]) -> Self {
        let boxes = regions
            .iter()
            .map(|r| {
                let corners = (0..8).map(|q: usize| {
                    let p: [f64; 3] =
                        std::array::from_fn(|a| if q >> a & 1 == 0 { r.min[a] } else { r.max[a] });
                    DVec3::from_array(base.to_grid(p))
                });
                let (lo, hi) = corners
                    .fold((DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)), |(lo, hi), p| {
                        (lo.min(p), hi.max(p))
                    });
                (r.kind, lo, hi)
            })
            .collect::<Vec<_>>();
        let walkable = boxes.iter().any(|b| b.0 == RegionKind::Walkable);
        Self { boxes, walkable }
    }

    /// The score of cell `c` of `level` (grid `g`) with the boxes applied to the heuristics'
    /// `score`, in this order: outside every walkable box (when there are some) or inside an
    /// exclusion box, no split; overlapping a density box finer than `level`, a forced split
    /// (`+∞`, which also keeps its nodes from culling).
    pub(crate) fn score(&self, level: u32, g: &GridSpec, c: [u32; 3], score: f64) -> f64 {
        if self.boxes.is_empty() {
            return score;
        }
        let lo = DVec3::from_array(g.node_position(c[0], c[1], c[2]));
        let hi = DVec3::from_array(g.node_position(c[0] + 1, c[1] + 1, c[2] + 1));
        let overlaps = |a: DVec3, b: DVec3| lo.cmplt(b).all() && hi.cmpgt(a).all();
        let inside = |a: DVec3, b: DVec3| lo.cmpge(a).all() && hi.cmple(b).all();
        let mut s = score;
        if self.walkable && !self.boxes.iter().any(|&(k, a, b)| k == RegionKind::Walkable && overlaps(a, b)) {
            s = 0.0;
        }
        if self.boxes.iter().any(|&(k, a, b)| k == RegionKind::Exclude && inside(a, b)) {
            s = 0.0;
        }
        if self
            .boxes
            .iter()
            .any(|&(k, a, b)| matches!(k, RegionKind::Density(d) if d > level) && overlaps(a, b))
        {
            s = f64::INFINITY;
        }
        s
    }
}
