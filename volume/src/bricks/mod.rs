//! Sparse brick volumes: an adaptive octree ([`crate::adaptive`]) resampled into bricks of
//! `B³` cells (`(B + 1)³` probes) behind one indirection grid, the layout an engine samples
//! with hardware trilinear filtering and streams cell by cell. The layout follows Unreal's
//! volumetric lightmaps (bricks of 4³ cells padded to 5³ probes behind an indirection
//! texture, refined near detail, stitched to coarser neighbours, bricks dropped by usefulness
//! under a memory budget) with the octree's refinement factor of 2 per level (\[Oat05\],
//! "Adaptive Octree Subdivision").
//!
//! ## Layout
//! The box is the octree's base grid (`n` nodes per axis, `n − 1` cells). A brick of level
//! `l` covers `B` cells of the level-`l` grid per axis, from level-`l` cell `b·B` (its
//! *brick coordinates* `b`), and stores the `(B + 1)³` probes at its level-`l` nodes: the
//! last probe of a brick repeats the first of the next (the padding that lets a GPU filter
//! inside a brick without reading a neighbour). Bricks of level 0 tile the box (the last ones
//! overhang it: their probes beyond the box hold the value at the box face, the clamp every
//! lookup applies). The *indirection grid* has `⌈(n − 1)·2^L / B⌉` texels per axis, `L` the
//! finest brick level: texel `t` covers `B` cells of level `L` and names the one brick that
//! covers it; a level-`l` brick covers `2^(L−l)` texels per axis.
//!
//! ## Lookup (\[KL06\] Eq. 2 inside a brick)
//! With `u` the point in base-cell units (clamped into the box): texel
//! `t = min(⌊u·2^L / B⌋, T − 1)`, its brick `(l, b)`, local coordinate
//! `s = clamp(u·2^l − b·B, 0, B)`, and the trilinear interpolation of the brick's probes
//! at `s`. [`BrickVolume::coeffs_at`] is the f32 fast path through the indirection;
//! [`BrickVolume::coeffs_at_reference`] finds the brick by searching the brick list in f64.
//!
//! ## Probe values
//! A brick of level `l` stores the octree's field summed over levels `0..=l`
//! (`Σ_{m≤l} I_m`, see [`crate::adaptive`]): the nodes' values prefiltered at the brick's
//! own level. A brick is refined into its 8 children when a stored octree node of a finer
//! level lies in its closed box. Where a brick meets a coarser one, its probes on the
//! shared boundary take the coarser brick's interpolated value (*stitching*, coarse to
//! fine), so the field stays continuous across level changes, as Oat's lookups across
//! octree levels do.
//!
//! ## Memory and the budget
//! A probe is `coeffs` RGBA16F texels (8 bytes each, RGB the coefficient, A 1); a brick
//! is `(B + 1)³` probes ([`BrickVolume::probe_bytes`]); the indirection is 4 bytes per texel.
//! Groups of 8 sibling leaf bricks are merged into their parent, least useful first, while
//! a merge loses at most [`BrickParams::merge_tolerance`] and then, under a budget
//! ([`BrickParams::max_probe_bytes`]), until the bricks fit: usefulness is the largest
//! [`surplus_measure`](crate::adaptive::surplus_measure) of the difference between a child's
//! probe and the parent's interpolation there (the irradiance the merge loses), so the
//! bricks that carry the least detail go first ([`BrickReport`] says what was dropped).
//! Probe values are rounded to half floats when the bricks are built, so the exported
//! texture holds exactly what the CPU lookup reads.

mod build;
mod lookup;

pub use build::{BrickReport, bricks_from_octree};

use crate::error::VolumeError;
use crate::grid::GridSpec;
use crate::metadata::BakeMetadata;

/// Bytes of one probe coefficient texel in the atlas (RGBA16F).
pub const ATLAS_TEXEL_BYTES: usize = 8;
/// Bytes of one indirection texel (RGBA8 unsigned: the brick's atlas slot and its level).
pub const INDIRECTION_TEXEL_BYTES: usize = 4;
/// Brick sizes accepted, in cells per axis (Unreal's and Unity APV's bricks are 4 and 3).
pub const BRICK_CELLS: std::ops::RangeInclusive<u32> = 2..=8;
/// The default brick size: 4³ cells, 5³ probes.
pub const DEFAULT_BRICK_CELLS: u32 = 4;

/// How to resample an octree into bricks.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BrickParams {
    /// Cells per brick and axis ([`BRICK_CELLS`]).
    pub cells: u32,
    /// Cap on [`BrickVolume::probe_bytes`] (`None`: no cap).
    pub max_probe_bytes: Option<usize>,
    /// Sibling bricks whose merge loses at most this much irradiance (relative to the
    /// octree's value scale, the measure of its culling) are merged whatever the budget.
    pub merge_tolerance: f64,
}

/// The default [`BrickParams::merge_tolerance`]: the octree's default cull tolerance, so
/// that bricks keep the detail the octree kept nodes for.
pub const DEFAULT_MERGE_TOLERANCE: f64 = 0.01;

impl Default for BrickParams {
    fn default() -> Self {
        Self { cells: DEFAULT_BRICK_CELLS, max_probe_bytes: None, merge_tolerance: DEFAULT_MERGE_TOLERANCE }
    }
}

/// One brick: its level and brick coordinates (module docs).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct Brick {
    /// The octree level whose nodes its probes sit on.
    pub level: u32,
    /// Brick coordinates at that level: the brick starts at level-`level` cell `b·B`.
    pub coords: [u32; 3],
}

/// A group of bricks an engine loads together: the bricks under one level-0 brick, stored
/// contiguously.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct StreamCell {
    /// The level-0 brick coordinates of the cell.
    pub coords: [u32; 3],
    /// Index of its first brick.
    pub first: u32,
    /// Number of its bricks.
    pub count: u32,
}

/// A sparse brick volume (module docs).
#[derive(Clone, PartialEq)]
pub struct BrickVolume {
    pub(crate) spec: GridSpec,
    pub(crate) coeffs: usize,
    pub(crate) cells: u32,
    pub(crate) finest: u32,
    pub(crate) bricks: Vec<Brick>,
    /// `[brick][probe (x fastest)][coeff][rgb]`, half-float values.
    pub(crate) data: Vec<f32>,
    pub(crate) metadata: BakeMetadata,
    /// Derived from `bricks`: the brick index of every indirection texel (x fastest).
    pub(crate) indirection: Vec<u32>,
    pub(crate) indirection_res: [u32; 3],
}

/// A summary.
impl std::fmt::Debug for BrickVolume {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("BrickVolume")
            .field("spec", &self.spec)
            .field("coeffs", &self.coeffs)
            .field("cells", &self.cells)
            .field("finest", &self.finest)
            .field("bricks", &self.bricks.len())
            .finish_non_exhaustive()
    }
}

/// The indirection grid's texels per axis: `⌈(n − 1)·2^finest / cells⌉`.
#[must_use]
pub fn indirection_res(spec: &GridSpec, cells: u32, finest: u32) -> [u32; 3] {
    spec.res().map(|n| ((n - 1) << finest).div_ceil(cells))
}

/// Level-`level` bricks per axis that own at least one indirection texel.
#[must_use]
pub fn bricks_per_axis(spec: &GridSpec, cells: u32, finest: u32, level: u32) -> [u32; 3] {
    indirection_res(spec, cells, finest).map(|t| t.div_ceil(1 << (finest - level)))
}

impl BrickVolume {
    /// Assembles a volume from checked parts (builder and reader): bricks that tile the
    /// indirection grid exactly once, `data` of the right length and finite.
    ///
    /// # Errors
    /// [`VolumeError::InvalidData`] naming the first problem.
    pub fn from_parts(
        spec: GridSpec,
        coeffs: usize,
        cells: u32,
        finest: u32,
        bricks: Vec<Brick>,
        data: Vec<f32>,
        metadata: BakeMetadata,
    ) -> Result<Self, VolumeError> {
        let bad = |m: String| Err(VolumeError::InvalidData(format!("brick volume: {m}")));
        if !BRICK_CELLS.contains(&cells) {
            return bad(format!("{cells} cells per brick (accepted: {BRICK_CELLS:?})"));
        }
        if finest > crate::adaptive::MAX_LEVEL {
            return bad(format!("finest level {finest} above {}", crate::adaptive::MAX_LEVEL));
        }
        if ![4, 9, 16].contains(&coeffs) {
            return bad(format!("{coeffs} coefficients per channel"));
        }
        let per = ((cells + 1) as usize).pow(3) * coeffs * 3;
        if bricks.len().checked_mul(per) != Some(data.len()) {
            return bad(format!("{} values for {} bricks of {per}", data.len(), bricks.len()));
        }
        crate::error::check_finite("brick probes", &data)?;
        if u32::try_from(bricks.len()).is_err() {
            return bad("more than 2^32 bricks".into());
        }
        let res = indirection_res(&spec, cells, finest);
        let texels = res.iter().map(|&r| r as usize).product::<usize>();
        let mut indirection = vec![u32::MAX; texels];
        for (i, b) in bricks.iter().enumerate() {
            if b.level > finest {
                return bad(format!("brick {i} of level {} above the finest {finest}", b.level));
            }
            let span = 1u32 << (finest - b.level);
            let lo = b.coords.map(|c| c.saturating_mul(span));
            if (0..3).any(|a| lo[a] >= res[a]) {
                return bad(format!("brick {i} {:?} of level {} outside the grid", b.coords, b.level));
            }
            let hi: [u32; 3] = std::array::from_fn(|a| (lo[a] + span).min(res[a]));
            for z in lo[2]..hi[2] {
                for y in lo[1]..hi[1] {
                    for x in lo[0]..hi[0] {
                        let t = &mut indirection[texel_index(res, [x, y, z])];
                        if *t != u32::MAX {
                            return bad(format!("bricks {} and {i} overlap", *t));
                        }
                        *t = i as u32;
                    }
                }
            }
        }
        if let Some(t) = indirection.iter().position(|&t| t == u32::MAX) {
            return bad(format!("indirection texel {t} is covered by no brick"));
        }
        Ok(Self { spec, coeffs, cells, finest, bricks, data, metadata, indirection, indirection_res: res })
    }

    /// The base grid (the octree's level 0): the box, its node count and placement.
    #[must_use]
    pub fn spec(&self) -> &GridSpec {
        &self.spec
    }

    /// SH coefficients per colour channel.
    #[must_use]
    pub fn coeffs(&self) -> usize {
        self.coeffs
    }

    /// Cells per brick and axis (`B`).
    #[must_use]
    pub fn brick_cells(&self) -> u32 {
        self.cells
    }

    /// Probes per brick and axis (`B + 1`).
    #[must_use]
    pub fn brick_probes(&self) -> u32 {
        self.cells + 1
    }

    /// The finest brick level (`L`).
    #[must_use]
    pub fn finest_level(&self) -> u32 {
        self.finest
    }

    /// The bricks, grouped by [`StreamCell`] (coarse to fine within a cell).
    #[must_use]
    pub fn bricks(&self) -> &[Brick] {
        &self.bricks
    }

    /// The probe values of brick `i`, `[probe (x fastest)][coeff][rgb]`.
    ///
    /// # Panics
    /// If `i` is out of range.
    #[must_use]
    pub fn brick_data(&self, i: usize) -> &[f32] {
        let per = self.brick_values();
        &self.data[i * per..(i + 1) * per]
    }

    /// Values per brick: `(B + 1)³ · coeffs · 3`.
    #[must_use]
    pub fn brick_values(&self) -> usize {
        (self.brick_probes() as usize).pow(3) * self.coeffs * 3
    }

    /// Indirection texels per axis.
    #[must_use]
    pub fn indirection_res(&self) -> [u32; 3] {
        self.indirection_res
    }

    /// The brick index of every indirection texel (x fastest).
    #[must_use]
    pub fn indirection(&self) -> &[u32] {
        &self.indirection
    }

    /// The streaming cells: the bricks under each level-0 brick, in brick order.
    #[must_use]
    pub fn stream_cells(&self) -> Vec<StreamCell> {
        let mut out: Vec<StreamCell> = Vec::new();
        for (i, b) in self.bricks.iter().enumerate() {
            let root = b.coords.map(|c| c >> b.level);
            match out.last_mut() {
                Some(c) if c.coords == root => c.count += 1,
                _ => out.push(StreamCell { coords: root, first: i as u32, count: 1 }),
            }
        }
        out
    }

    /// Bricks per level, index = level `0..=finest`.
    #[must_use]
    pub fn bricks_per_level(&self) -> Vec<usize> {
        let mut n = vec![0; self.finest as usize + 1];
        for b in &self.bricks {
            n[b.level as usize] += 1;
        }
        n
    }

    /// Probes stored: `bricks · (B + 1)³`.
    #[must_use]
    pub fn probe_count(&self) -> usize {
        self.bricks.len() * (self.brick_probes() as usize).pow(3)
    }

    /// Bytes of the bricks' probes: `bricks · (B + 1)³ · coeffs ·` [`ATLAS_TEXEL_BYTES`].
    #[must_use]
    pub fn probe_bytes(&self) -> usize {
        probe_bytes(self.bricks.len(), self.cells, self.coeffs)
    }

    /// Bytes of the indirection texture ([`INDIRECTION_TEXEL_BYTES`] per texel).
    #[must_use]
    pub fn indirection_bytes(&self) -> usize {
        self.indirection.len() * INDIRECTION_TEXEL_BYTES
    }

    /// The bake metadata (the octree's).
    #[must_use]
    pub fn metadata(&self) -> &BakeMetadata {
        &self.metadata
    }
}

/// Bytes of `bricks` bricks of `cells³` cells and `coeffs` coefficients in the atlas.
#[must_use]
pub fn probe_bytes(bricks: usize, cells: u32, coeffs: usize) -> usize {
    bricks * ((cells + 1) as usize).pow(3) * coeffs * ATLAS_TEXEL_BYTES
}

/// Flat index of texel `t` in a grid of `res` texels, x fastest.
#[must_use]
pub(crate) fn texel_index(res: [u32; 3], t: [u32; 3]) -> usize {
    t[0] as usize + res[0] as usize * (t[1] as usize + res[1] as usize * t[2] as usize)
}

#[cfg(test)]
mod tests;
