//! The node grid of an irradiance volume and its trilinear weights.
//!
//! Kontkanen & Laine 2006, \[KL06\] §3: the SH coefficient functions `L_j(x)` are
//! discretised on a regular 3D grid and reconstructed by trilinear interpolation,
//! `L_j(x) ≈ Σ_{i∈B(x)} c_ij b_i(x)` (Eq. 2), with `b_i` the standard trilinear "tent"
//! weight of node `i` (Table 1). Nodes sit at the cell corners: node `i` along an axis with
//! `n` nodes lies at `min + i (max - min) / (n - 1)`.
//!
//! ## Coordinate frames
//! The box `[min, max]` lives in *grid space*. An optional affine [`Placement`] maps grid
//! space to world space (rotate, scale, shear, translate a baked volume into a level). All
//! index-space functions of [`GridSpec`] (`node_position`, `cell_bounds`, `trilinear`) work
//! in grid space; the `*_world` variants apply the placement. Without a placement the two
//! frames coincide. SH directions are always *world* directions: the placement moves the
//! box, it does not rotate the stored radiance (a baker shoots world-space rays).
//!
//! ## Clamping
//! Points outside the box are clamped to the nearest point of the box before weighting
//! (per axis, like GPU clamp-to-edge addressing), so a lookup outside the volume returns
//! the value on its boundary.

use crate::error::VolumeError;

/// The largest node count a grid may have (2^27 ≈ 134 million nodes, 14 GiB of 9-coefficient
/// RGB f32 data): a guard against absurd allocations from corrupt files or typos.
pub const MAX_NODES: usize = 1 << 27;

/// An affine map from grid space to world space: `world = A · grid + t`, stored row-major
/// as a 3×4 matrix `[A | t]`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Placement {
    to_world: [[f64; 4]; 3],
    to_grid: [[f64; 4]; 3],
}

impl Placement {
    /// Smallest |det A| accepted, relative to the product of the row norms (a measure of
    /// how close the rows are to linearly dependent); below it the inverse loses more than
    /// half of the f64 digits.
    const MIN_RELATIVE_DET: f64 = 1e-8;

    /// Builds a placement from the row-major 3×4 matrix `[A | t]`; errors if an entry is
    /// not finite or `A` is (nearly) singular.
    pub fn new(matrix: [[f64; 4]; 3]) -> Result<Self, VolumeError> {
        if matrix.iter().flatten().any(|v| !v.is_finite()) {
            return Err(VolumeError::InvalidGrid("placement matrix has a non-finite entry".into()));
        }
        let a = |r: usize, c: usize| matrix[r][c];
        let cof = [
            [
                a(1, 1) * a(2, 2) - a(1, 2) * a(2, 1),
                a(1, 2) * a(2, 0) - a(1, 0) * a(2, 2),
                a(1, 0) * a(2, 1) - a(1, 1) * a(2, 0),
            ],
            [
                a(0, 2) * a(2, 1) - a(0, 1) * a(2, 2),
                a(0, 0) * a(2, 2) - a(0, 2) * a(2, 0),
                a(0, 1) * a(2, 0) - a(0, 0) * a(2, 1),
            ],
            [
                a(0, 1) * a(1, 2) - a(0, 2) * a(1, 1),
                a(0, 2) * a(1, 0) - a(0, 0) * a(1, 2),
                a(0, 0) * a(1, 1) - a(0, 1) * a(1, 0),
            ],
        ];
        let det = a(0, 0) * cof[0][0] + a(0, 1) * cof[0][1] + a(0, 2) * cof[0][2];
        let row_norm = |r: usize| (a(r, 0).powi(2) + a(r, 1).powi(2) + a(r, 2).powi(2)).sqrt();
        let scale = row_norm(0) * row_norm(1) * row_norm(2);
        // `<=` alone would let a NaN determinant through.
        if det.is_nan() || det.abs() <= Self::MIN_RELATIVE_DET * scale {
            return Err(VolumeError::InvalidGrid(format!("placement matrix is singular (det = {det:e})")));
        }
        // inverse(A) = adj(A) / det, adj = transpose of the cofactor matrix.
        let mut to_grid = [[0.0; 4]; 3];
        for r in 0..3 {
            for c in 0..3 {
                to_grid[r][c] = cof[c][r] / det;
            }
        }
        for r in 0..3 {
            to_grid[r][3] = -(to_grid[r][0] * a(0, 3) + to_grid[r][1] * a(1, 3) + to_grid[r][2] * a(2, 3));
        }
        Ok(Self { to_world: matrix, to_grid })
    }

    /// A pure translation.
    pub fn translation(t: [f64; 3]) -> Result<Self, VolumeError> {
        Self::new([[1.0, 0.0, 0.0, t[0]], [0.0, 1.0, 0.0, t[1]], [0.0, 0.0, 1.0, t[2]]])
    }

    /// The grid-to-world matrix `[A | t]`, row-major.
    #[must_use]
    pub fn to_world_matrix(&self) -> [[f64; 4]; 3] {
        self.to_world
    }

    /// The world-to-grid matrix (the inverse affine map), row-major.
    #[must_use]
    pub fn to_grid_matrix(&self) -> [[f64; 4]; 3] {
        self.to_grid
    }

    /// Maps a grid-space point to world space.
    #[must_use]
    pub fn to_world(&self, p: [f64; 3]) -> [f64; 3] {
        apply(&self.to_world, p)
    }

    /// Maps a world-space point to grid space.
    #[must_use]
    pub fn to_grid(&self, p: [f64; 3]) -> [f64; 3] {
        apply(&self.to_grid, p)
    }
}

fn apply(m: &[[f64; 4]; 3], p: [f64; 3]) -> [f64; 3] {
    std::array::from_fn(|r| m[r][0] * p[0] + m[r][1] * p[1] + m[r][2] * p[2] + m[r][3])
}

/// The geometry of an irradiance volume: a grid-space box, its node resolution and an
/// optional placement (Kontkanen & Laine 2006, §3 and Table 1).
///
/// Nodes are indexed x fastest: `node = i + nx (j + ny k)`; cells likewise with
/// `(nx-1, ny-1, nz-1)`. The 8 corners of a cell are numbered by the bits `(dx, dy, dz)` of
/// `c = dx + 2 dy + 4 dz`.
#[derive(Debug, Clone, PartialEq)]
pub struct GridSpec {
    min: [f64; 3],
    max: [f64; 3],
    res: [u32; 3],
    placement: Option<Placement>,
}

impl GridSpec {
    /// A grid over the box `[min, max]` with `res` nodes per axis (each at least 2).
    /// Errors on a non-finite or empty box, a resolution below 2, or more than
    /// [`MAX_NODES`] nodes.
    pub fn new(min: [f64; 3], max: [f64; 3], res: [u32; 3]) -> Result<Self, VolumeError> {
        for a in 0..3 {
            if !min[a].is_finite() || !max[a].is_finite() {
                return Err(VolumeError::InvalidGrid(format!("axis {a}: bounds must be finite")));
            }
            if max[a] <= min[a] {
                return Err(VolumeError::InvalidGrid(format!(
                    "axis {a}: max ({}) must exceed min ({})",
                    max[a], min[a]
                )));
            }
            if res[a] < 2 {
                return Err(VolumeError::InvalidGrid(format!(
                    "axis {a}: resolution {} (need at least 2 nodes)",
                    res[a]
                )));
            }
            // Node positions must be distinct in f64.
            let step = (max[a] - min[a]) / f64::from(res[a] - 1);
            if step <= 0.0 || min[a] + step == min[a] || max[a] - step == max[a] {
                return Err(VolumeError::InvalidGrid(format!("axis {a}: cell size underflows")));
            }
        }
        let count = res.iter().try_fold(1usize, |acc, &n| acc.checked_mul(n as usize));
        match count {
            Some(c) if c <= MAX_NODES => {}
            _ => {
                return Err(VolumeError::InvalidGrid(format!(
                    "{}x{}x{} nodes exceed the limit of {MAX_NODES}",
                    res[0], res[1], res[2]
                )));
            }
        }
        Ok(Self { min, max, res, placement: None })
    }

    /// The same grid placed in the world by `placement`.
    #[must_use]
    pub fn with_placement(mut self, placement: Placement) -> Self {
        self.placement = Some(placement);
        self
    }

    /// The placement (grid to world), if any.
    #[must_use]
    pub fn placement(&self) -> Option<&Placement> {
        self.placement.as_ref()
    }

    /// Nodes per axis `(nx, ny, nz)`.
    #[must_use]
    pub fn res(&self) -> [u32; 3] {
        self.res
    }

    /// The grid-space box `(min, max)`.
    #[must_use]
    pub fn bounds(&self) -> ([f64; 3], [f64; 3]) {
        (self.min, self.max)
    }

    /// `nx · ny · nz`.
    #[must_use]
    pub fn node_count(&self) -> usize {
        self.res.iter().map(|&n| n as usize).product()
    }

    /// `(nx-1)(ny-1)(nz-1)`.
    #[must_use]
    pub fn cell_count(&self) -> usize {
        self.res.iter().map(|&n| n as usize - 1).product()
    }

    /// Cell edge lengths `(max - min) / (n - 1)` in grid space.
    #[must_use]
    pub fn cell_size(&self) -> [f64; 3] {
        std::array::from_fn(|a| (self.max[a] - self.min[a]) / f64::from(self.res[a] - 1))
    }

    /// Flat index of node `(i, j, k)`, x fastest. Indices must be below `res`.
    #[must_use]
    #[inline]
    pub fn node_index(&self, i: u32, j: u32, k: u32) -> usize {
        debug_assert!(i < self.res[0] && j < self.res[1] && k < self.res[2]);
        let [nx, ny, _] = self.res.map(|n| n as usize);
        i as usize + nx * (j as usize + ny * k as usize)
    }

    /// The `(i, j, k)` of a flat node index.
    #[must_use]
    pub fn node_coords(&self, node: usize) -> [u32; 3] {
        let [nx, ny, _] = self.res.map(|n| n as usize);
        [(node % nx) as u32, ((node / nx) % ny) as u32, (node / (nx * ny)) as u32]
    }

    /// Grid-space position of node `(i, j, k)`: `min + i (max - min) / (n - 1)` per axis
    /// (the last node is exactly `max`).
    #[must_use]
    pub fn node_position(&self, i: u32, j: u32, k: u32) -> [f64; 3] {
        let idx = [i, j, k];
        std::array::from_fn(|a| {
            if idx[a] == self.res[a] - 1 {
                self.max[a]
            } else {
                self.min[a] + f64::from(idx[a]) * (self.max[a] - self.min[a]) / f64::from(self.res[a] - 1)
            }
        })
    }

    /// World-space position of node `(i, j, k)` (the placement applied).
    #[must_use]
    pub fn node_position_world(&self, i: u32, j: u32, k: u32) -> [f64; 3] {
        self.to_world(self.node_position(i, j, k))
    }

    /// Flat index of cell `(i, j, k)` (its min corner is node `(i, j, k)`), x fastest.
    #[must_use]
    #[inline]
    pub fn cell_index(&self, i: u32, j: u32, k: u32) -> usize {
        let [cx, cy, _] = self.res.map(|n| n as usize - 1);
        i as usize + cx * (j as usize + cy * k as usize)
    }

    /// The `(i, j, k)` of a flat cell index.
    #[must_use]
    pub fn cell_coords(&self, cell: usize) -> [u32; 3] {
        let [cx, cy, _] = self.res.map(|n| n as usize - 1);
        [(cell % cx) as u32, ((cell / cx) % cy) as u32, (cell / (cx * cy)) as u32]
    }

    /// Grid-space box of a cell.
    #[must_use]
    pub fn cell_bounds(&self, cell: usize) -> ([f64; 3], [f64; 3]) {
        let [i, j, k] = self.cell_coords(cell);
        (self.node_position(i, j, k), self.node_position(i + 1, j + 1, k + 1))
    }

    /// The 8 node indices of a cell, corner `c = dx + 2 dy + 4 dz`.
    #[must_use]
    pub fn cell_corners(&self, cell: usize) -> [usize; 8] {
        let [i, j, k] = self.cell_coords(cell);
        std::array::from_fn(|c| {
            let (dx, dy, dz) = ((c & 1) as u32, ((c >> 1) & 1) as u32, ((c >> 2) & 1) as u32);
            self.node_index(i + dx, j + dy, k + dz)
        })
    }

    /// The cell containing grid-space point `p` (clamped into the box) and the point's
    /// fractional position `(dx, dy, dz) ∈ [0, 1]³` inside it.
    #[must_use]
    pub fn locate(&self, p: [f64; 3]) -> ([u32; 3], [f64; 3]) {
        let mut cell = [0u32; 3];
        let mut frac = [0.0; 3];
        for a in 0..3 {
            let cells = f64::from(self.res[a] - 1);
            let u = ((p[a] - self.min[a]) / (self.max[a] - self.min[a]) * cells).clamp(0.0, cells);
            // NaN coordinates clamp to the min corner (clamp keeps NaN; max() drops it).
            let u = if u.is_nan() { 0.0 } else { u };
            let i = (u.floor() as u32).min(self.res[a] - 2);
            cell[a] = i;
            frac[a] = (u - f64::from(i)).clamp(0.0, 1.0);
        }
        (cell, frac)
    }

    /// The 8 nodes around grid-space point `p` and their trilinear weights
    /// `b_i(p) = Π (1 - |d|)` (Kontkanen & Laine 2006, Table 1 and Eq. 2), with `p` clamped
    /// into the box first. The weights are non-negative and sum to 1 (to rounding).
    #[must_use]
    pub fn trilinear(&self, p: [f64; 3]) -> ([usize; 8], [f64; 8]) {
        let (cell, f) = self.locate(p);
        let nodes = self.cell_corners(self.cell_index(cell[0], cell[1], cell[2]));
        (nodes, corner_weights(f))
    }

    /// [`Self::trilinear`] for a world-space point.
    #[must_use]
    pub fn trilinear_world(&self, p: [f64; 3]) -> ([usize; 8], [f64; 8]) {
        self.trilinear(self.to_grid(p))
    }

    /// Maps a grid-space point to world space (identity without a placement).
    #[must_use]
    pub fn to_world(&self, p: [f64; 3]) -> [f64; 3] {
        self.placement.map_or(p, |pl| pl.to_world(p))
    }

    /// Maps a world-space point to grid space (identity without a placement).
    #[must_use]
    pub fn to_grid(&self, p: [f64; 3]) -> [f64; 3] {
        self.placement.map_or(p, |pl| pl.to_grid(p))
    }

    /// Whether two grids have the same nodes (box, resolution and placement).
    #[must_use]
    pub fn same_nodes(&self, other: &Self) -> bool {
        self == other
    }
}

/// Trilinear corner weights for the fractional position `f`, corner `c = dx + 2dy + 4dz`.
#[must_use]
#[inline]
pub fn corner_weights(f: [f64; 3]) -> [f64; 8] {
    let w = |bit: usize, a: usize| if bit == 1 { f[a] } else { 1.0 - f[a] };
    std::array::from_fn(|c| w(c & 1, 0) * w((c >> 1) & 1, 1) * w((c >> 2) & 1, 2))
}

#[cfg(test)]
mod tests {
    use super::*;
    use lightvol_sh::lowdisc::SplitMix64;

    /// Rounding slack for sums of 8 products of numbers in [0, 1] (a few ulps of 1).
    const WEIGHT_SUM_TOL: f64 = 8.0 * f64::EPSILON;

    fn spec() -> GridSpec {
        GridSpec::new([-1.0, 0.0, 2.0], [3.0, 1.5, 5.0], [5, 4, 3]).unwrap()
    }

    #[test]
    fn rejects_bad_grids() {
        assert!(GridSpec::new([0.0; 3], [1.0; 3], [1, 2, 2]).is_err());
        assert!(GridSpec::new([0.0; 3], [0.0, 1.0, 1.0], [2; 3]).is_err());
        assert!(GridSpec::new([0.0; 3], [f64::NAN, 1.0, 1.0], [2; 3]).is_err());
        assert!(GridSpec::new([0.0; 3], [1.0; 3], [u32::MAX; 3]).is_err());
        assert!(GridSpec::new([1e300; 3], [1e300 * (1.0 + f64::EPSILON); 3], [1000; 3]).is_err());
        assert!(Placement::new([[1.0, 0.0, 0.0, 0.0], [2.0, 0.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0]]).is_err());
    }

    #[test]
    fn indices_round_trip() {
        let s = spec();
        assert_eq!(s.node_count(), 60);
        assert_eq!(s.cell_count(), 4 * 3 * 2);
        for node in 0..s.node_count() {
            let [i, j, k] = s.node_coords(node);
            assert_eq!(s.node_index(i, j, k), node);
        }
        for cell in 0..s.cell_count() {
            let [i, j, k] = s.cell_coords(cell);
            assert_eq!(s.cell_index(i, j, k), cell);
            let (lo, hi) = s.cell_bounds(cell);
            let corners = s.cell_corners(cell);
            let [ci, cj, ck] = s.node_coords(corners[7]);
            assert_eq!(s.node_position(ci, cj, ck), hi);
            let [ci, cj, ck] = s.node_coords(corners[0]);
            assert_eq!(s.node_position(ci, cj, ck), lo);
        }
        assert_eq!(s.node_position(4, 3, 2), [3.0, 1.5, 5.0]);
        assert_eq!(s.node_position(1, 1, 1), [0.0, 0.5, 3.5]);
    }

    #[test]
    fn trilinear_weights_sum_to_one_and_reproduce_position() {
        let s = spec();
        let mut rng = SplitMix64::new(7);
        for _ in 0..2000 {
            // Include points outside the box: they clamp.
            let p = [rng.range(-2.0, 4.0), rng.range(-0.5, 2.0), rng.range(1.0, 6.0)];
            let (nodes, w) = s.trilinear(p);
            let sum: f64 = w.iter().sum();
            assert!((sum - 1.0).abs() <= WEIGHT_SUM_TOL, "sum {sum}");
            assert!(w.iter().all(|&x| (0.0..=1.0).contains(&x)));
            // Linear precision: Σ b_i x_i equals the clamped point.
            let (lo, hi) = s.bounds();
            for a in 0..3 {
                let rec: f64 = (0..8)
                    .map(|c| {
                        let [i, j, k] = s.node_coords(nodes[c]);
                        w[c] * s.node_position(i, j, k)[a]
                    })
                    .sum();
                let want = p[a].clamp(lo[a], hi[a]);
                assert!((rec - want).abs() <= 1e-12 * (1.0 + want.abs()), "axis {a}: {rec} vs {want}");
            }
        }
    }

    #[test]
    fn weight_is_one_at_nodes() {
        let s = spec();
        for node in 0..s.node_count() {
            let [i, j, k] = s.node_coords(node);
            let (nodes, w) = s.trilinear(s.node_position(i, j, k));
            let hit: f64 = (0..8).filter(|&c| nodes[c] == node).map(|c| w[c]).sum();
            assert!((hit - 1.0).abs() <= WEIGHT_SUM_TOL);
        }
    }

    #[test]
    fn placement_inverts() {
        let m = [[0.0, -2.0, 0.0, 1.0], [1.0, 0.0, 0.5, -3.0], [0.0, 0.0, 3.0, 7.0]];
        let pl = Placement::new(m).unwrap();
        let mut rng = SplitMix64::new(3);
        for _ in 0..100 {
            let p = [rng.range(-5.0, 5.0), rng.range(-5.0, 5.0), rng.range(-5.0, 5.0)];
            let q = pl.to_grid(pl.to_world(p));
            for a in 0..3 {
                assert!((q[a] - p[a]).abs() < 1e-13 * 10.0);
            }
        }
        let s = spec().with_placement(pl);
        let w = s.node_position_world(1, 1, 1);
        let (nodes, wt) = s.trilinear_world(w);
        let c = (0..8).find(|&c| nodes[c] == s.node_index(1, 1, 1)).unwrap();
        assert!((wt[c] - 1.0).abs() < 1e-12);
    }
}
