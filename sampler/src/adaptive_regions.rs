//! The placement boxes of an adaptive bake (density, exclusion and walkable volumes,
//! [`AdaptiveSettings::regions`](crate::adaptive::AdaptiveSettings)): boxes from the scene's
//! meshes and materials ([`mesh_regions`]), and their effect on the split scores of
//! [`crate::adaptive`]'s heuristics (`GridRegions`).

use std::collections::{HashMap, HashSet};

use glam::DVec3;
use lightvol_scene::Scene;
use lightvol_volume::adaptive::pack_key;
use lightvol_volume::{GridSpec, OctreeRegion, RegionKind};

/// Boxes of `kind` from the geometry named `name`: every placement of an instanced mesh of
/// that name (its world bounds), and every triangle whose material has that name (its
/// bounds). For [`RegionKind::Walkable`] each box is raised by `height` above its top along
/// the internal up axis (+Z), the space a player standing on it occupies. `None` when
/// nothing has that name.
#[must_use]
pub fn mesh_regions(scene: &Scene, name: &str, kind: RegionKind, height: f64) -> Option<Vec<OctreeRegion>> {
    let raise = if kind == RegionKind::Walkable { height } else { 0.0 };
    let make = |lo: DVec3, hi: DVec3| OctreeRegion {
        kind,
        min: lo.to_array(),
        max: (hi + DVec3::new(0.0, 0.0, raise)).to_array(),
    };
    let mut out: Vec<OctreeRegion> = scene
        .instances
        .iter()
        .filter(|i| scene.prototypes.get(i.prototype as usize).is_some_and(|p| p.name == name))
        .map(|i| make(i.bounds.0, i.bounds.1))
        .collect();
    let materials: Vec<usize> =
        scene.materials.iter().enumerate().filter(|(_, m)| m.name == name).map(|(k, _)| k).collect();
    if !materials.is_empty() {
        out.extend(scene.world_triangles().filter(|t| materials.contains(&(t.material as usize))).map(|t| {
            let lo = t.v[0].min(t.v[1]).min(t.v[2]);
            let hi = t.v[0].max(t.v[1]).max(t.v[2]);
            make(lo, hi)
        }));
    }
    (!out.is_empty()).then_some(out)
}

/// The placement boxes in the base grid's space (the bounding box of each box's corners
/// mapped there), with the cells that overlap a walkable box found once per level.
pub(crate) struct GridRegions {
    boxes: Vec<(RegionKind, DVec3, DVec3)>,
    walkable: bool,
    /// Per level, the cells that overlap a walkable box (packed keys).
    walkable_cells: HashMap<u32, HashSet<u64>>,
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
        Self { boxes, walkable, walkable_cells: HashMap::new() }
    }

    /// The cells of the level grid `g` (of `level`) that overlap a walkable box: each box's
    /// cell range, from the cells' positions (an open overlap, as [`Self::score`]'s).
    fn walkable_cells(&mut self, level: u32, g: &GridSpec) -> &HashSet<u64> {
        let boxes = &self.boxes;
        self.walkable_cells.entry(level).or_insert_with(|| {
            let (min, max) = g.bounds();
            let res = g.res();
            let mut set = HashSet::new();
            for &(_, lo, hi) in boxes.iter().filter(|b| b.0 == RegionKind::Walkable) {
                let range: [(u32, u32); 3] = std::array::from_fn(|a| {
                    let cells = f64::from(res[a] - 1);
                    let to_u = |x: f64| (x - min[a]) / (max[a] - min[a]) * cells;
                    // Cells c with c < u(hi) and c + 1 > u(lo).
                    let first = (to_u(lo[a]).floor().max(0.0)) as u32;
                    let end = (to_u(hi[a]).ceil().clamp(0.0, cells)) as u32;
                    (first, end)
                });
                for z in range[2].0..range[2].1 {
                    for y in range[1].0..range[1].1 {
                        for x in range[0].0..range[0].1 {
                            set.insert(pack_key([x, y, z]));
                        }
                    }
                }
            }
            set
        })
    }

    /// The score of cell `c` of `level` (grid `g`) with the boxes applied to the heuristics'
    /// `score`, in this order: outside every walkable box (when there are some) or inside an
    /// exclusion box, no split; overlapping a density box finer than `level`, a forced split
    /// (`+∞`, which also keeps its nodes from culling).
    pub(crate) fn score(&mut self, level: u32, g: &GridSpec, c: [u32; 3], score: f64) -> f64 {
        if self.boxes.is_empty() {
            return score;
        }
        let lo = DVec3::from_array(g.node_position(c[0], c[1], c[2]));
        let hi = DVec3::from_array(g.node_position(c[0] + 1, c[1] + 1, c[2] + 1));
        let overlaps = |a: DVec3, b: DVec3| lo.cmplt(b).all() && hi.cmpgt(a).all();
        let inside = |a: DVec3, b: DVec3| lo.cmpge(a).all() && hi.cmple(b).all();
        let mut s = score;
        if self.walkable && !self.walkable_cells(level, g).contains(&pack_key(c)) {
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
