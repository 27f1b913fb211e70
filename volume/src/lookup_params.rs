//! The f32 constants of the fast lookup paths ([`crate::lookup`], the octree's in
//! [`crate::adaptive`]), derived once from a [`GridSpec`] and kept with the volume: the
//! world-to-cell map, the corner offsets, the trilinear corner weights `b_i(x)` and the
//! clamped-cosine factors `A_j` of Kontkanen & Laine 2006 Eq. 3 (Ramamoorthi & Hanrahan
//! 2001).

use lightvol_sh::index::sh_lm;
use lightvol_sh::irradiance::cosine_lobe_factor;

use crate::grid::GridSpec;
use crate::reach::reach_bias;

/// The f32 constants of the fast lookup, derived once from a [`GridSpec`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct LookupParams {
    /// World-to-grid affine map (row-major 3×4), if the grid is placed.
    pub(crate) to_grid: Option<[[f32; 4]; 3]>,
    pub(crate) min: [f32; 3],
    /// `(n - 1) / (max - min)`: grid-space units to cell units.
    pub(crate) scale: [f32; 3],
    /// `n - 1` as f32 (clamp limit in cell units).
    pub(crate) cells: [f32; 3],
    /// `n - 2`: the largest cell index.
    pub(crate) max_cell: [u32; 3],
    /// Node index offsets of the 8 corners, `c = dx + 2 dy + 4 dz`.
    pub(crate) offsets: [usize; 8],
    /// `A_l(j)` per coefficient (irradiance), and all ones (radiance).
    pub(crate) factors: [[f32; 16]; 2],
    /// The node reach's normal offset of the test point, world units
    /// ([`crate::reach::REACH_NORMAL_BIAS`] times the smallest world-space cell edge).
    pub(crate) reach_bias: f32,
}

impl LookupParams {
    pub(crate) fn new(spec: &GridSpec, coeffs: usize) -> Self {
        let (min, max) = spec.bounds();
        let res = spec.res();
        let (nx, nxy) = (res[0] as usize, res[0] as usize * res[1] as usize);
        Self {
            to_grid: spec.placement().map(|p| p.to_grid_matrix().map(|row| row.map(|v| v as f32))),
            min: min.map(|v| v as f32),
            scale: std::array::from_fn(|a| (f64::from(res[a] - 1) / (max[a] - min[a])) as f32),
            cells: std::array::from_fn(|a| (res[a] - 1) as f32),
            max_cell: std::array::from_fn(|a| res[a] - 2),
            offsets: [0, 1, nx, nx + 1, nxy, nxy + 1, nxy + nx, nxy + nx + 1],
            factors: [factors(coeffs, true), factors(coeffs, false)],
            reach_bias: reach_bias(spec) as f32,
        }
    }

    /// Grid-space point of a world-space point.
    #[inline(always)]
    pub(crate) fn grid_point(&self, p: [f32; 3]) -> [f32; 3] {
        match &self.to_grid {
            None => p,
            Some(m) => std::array::from_fn(|r| m[r][0] * p[0] + m[r][1] * p[1] + m[r][2] * p[2] + m[r][3]),
        }
    }

    /// Cell coordinate and fraction along axis `a` of grid-space coordinate `x`.
    #[inline(always)]
    pub(crate) fn axis(&self, a: usize, x: f32) -> (u32, f32) {
        // max/min (not clamp) so that NaN maps to 0.
        let u = ((x - self.min[a]) * self.scale[a]).max(0.0).min(self.cells[a]);
        let i = (u as u32).min(self.max_cell[a]);
        (i, u - i as f32)
    }

    /// Base node index and trilinear corner weights of a world-space point.
    #[inline(always)]
    pub(crate) fn locate(&self, nx: usize, nxy: usize, p: [f32; 3]) -> (usize, [f32; 8]) {
        let g = self.grid_point(p);
        let (i, fx) = self.axis(0, g[0]);
        let (j, fy) = self.axis(1, g[1]);
        let (k, fz) = self.axis(2, g[2]);
        (i as usize + nx * j as usize + nxy * k as usize, weights8(fx, fy, fz))
    }
}

/// Corner weights `Π (1-f | f)` in corner order `c = dx + 2dy + 4dz`, each product formed
/// as `(wx · wy) · wz`.
#[inline(always)]
pub(crate) fn weights8(fx: f32, fy: f32, fz: f32) -> [f32; 8] {
    let (gx, gy, gz) = (1.0 - fx, 1.0 - fy, 1.0 - fz);
    [
        gx * gy * gz,
        fx * gy * gz,
        gx * fy * gz,
        fx * fy * gz,
        gx * gy * fz,
        fx * gy * fz,
        gx * fy * fz,
        fx * fy * fz,
    ]
}

/// Per-coefficient factors: `A_l(j)` for irradiance, 1 for radiance.
pub(crate) fn factors(coeffs: usize, irradiance: bool) -> [f32; 16] {
    std::array::from_fn(|j| {
        if j >= coeffs {
            0.0
        } else if irradiance {
            cosine_lobe_factor(sh_lm(j).0) as f32
        } else {
            1.0
        }
    })
}
