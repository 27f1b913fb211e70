//! Lookups of a [`BrickVolume`] (module docs of [`crate::bricks`]): the f32 fast path
//! through the indirection grid and the f64 reference that searches the brick list.

use crate::bricks::{BrickVolume, texel_index};
use crate::grid::corner_weights;
use crate::lookup::{expand, shade_dyn};
use crate::lookup_params::{factors, weights8};

impl BrickVolume {
    /// A world point in base-cell units, clamped into the box (f32, the order of operations
    /// of the octree's fast path and of the generated shader code).
    pub(crate) fn units_f32(&self, p: [f32; 3]) -> [f32; 3] {
        let spec = &self.spec;
        let (min, max) = spec.bounds();
        let res0 = spec.res();
        let g: [f32; 3] = match spec.placement() {
            None => p,
            Some(pl) => {
                let m = pl.to_grid_matrix().map(|r| r.map(|v| v as f32));
                std::array::from_fn(|r| m[r][0] * p[0] + m[r][1] * p[1] + m[r][2] * p[2] + m[r][3])
            }
        };
        std::array::from_fn(|a| {
            let cells = (res0[a] - 1) as f32;
            let scale = (f64::from(res0[a] - 1) / (max[a] - min[a])) as f32;
            // max/min (not clamp) so that NaN maps to 0.
            ((g[a] - min[a] as f32) * scale).max(0.0).min(cells)
        })
    }

    /// A world point in base-cell units, clamped into the box (f64).
    pub(crate) fn units_f64(&self, p: [f64; 3]) -> [f64; 3] {
        let g = self.spec.to_grid(p);
        let (min, max) = self.spec.bounds();
        let res = self.spec.res();
        std::array::from_fn(|a| {
            let cells = f64::from(res[a] - 1);
            let u = ((g[a] - min[a]) / (max[a] - min[a]) * cells).clamp(0.0, cells);
            if u.is_nan() { 0.0 } else { u }
        })
    }

    /// The interpolated coefficients at world point `p` into `out[..3·coeffs]`
    /// (`[coeff][rgb]`): the f32 fast path (indirection texel, brick, trilinear over its
    /// probes, corners in order `c = dx + 2dy + 4dz`).
    ///
    /// # Panics
    /// If `out` is shorter than `3 · coeffs`.
    pub fn coeffs_at(&self, p: [f32; 3], out: &mut [f32]) {
        let u = self.units_f32(p);
        self.coeffs_at_units(u, out);
    }

    /// [`Self::coeffs_at`] at base-cell units `u` (inside the box).
    pub(crate) fn coeffs_at_units(&self, u: [f32; 3], out: &mut [f32]) {
        let k = self.coeffs * 3;
        let out = &mut out[..k];
        out.fill(0.0);
        let res = self.indirection_res;
        let to_texel = (1u32 << self.finest) as f32 / self.cells as f32;
        let t: [u32; 3] = std::array::from_fn(|a| ((u[a] * to_texel) as u32).min(res[a] - 1));
        let bi = self.indirection[texel_index(res, t)] as usize;
        let b = self.bricks[bi];
        let scale = (1u32 << b.level) as f32;
        let cells = self.cells;
        let mut cell = [0u32; 3];
        let mut f = [0.0f32; 3];
        for a in 0..3 {
            let s = (u[a] * scale - (b.coords[a] * cells) as f32).max(0.0).min(cells as f32);
            cell[a] = (s as u32).min(cells - 1);
            f[a] = s - cell[a] as f32;
        }
        let w = weights8(f[0], f[1], f[2]);
        let data = self.brick_data(bi);
        let p = (cells + 1) as usize;
        for (c, &wc) in w.iter().enumerate() {
            let q =
                [cell[0] as usize + (c & 1), cell[1] as usize + ((c >> 1) & 1), cell[2] as usize + (c >> 2)];
            let at = (q[0] + p * (q[1] + p * q[2])) * k;
            for (o, &v) in out.iter_mut().zip(&data[at..at + k]) {
                *o += wc * v;
            }
        }
    }

    /// The interpolated coefficients at world point `p` (f64 reference): the brick is found
    /// by searching the brick list for the one whose texel range holds the point's texel,
    /// not through the indirection grid.
    ///
    /// # Panics
    /// Never for a volume built by [`Self::from_parts`] (its bricks cover every texel).
    #[must_use]
    pub fn coeffs_at_reference(&self, p: [f64; 3]) -> Vec<f64> {
        let u = self.units_f64(p);
        self.coeffs_at_units_f64(u)
    }

    /// [`Self::coeffs_at_reference`] at base-cell units `u`.
    pub(crate) fn coeffs_at_units_f64(&self, u: [f64; 3]) -> Vec<f64> {
        let k = self.coeffs * 3;
        let res = self.indirection_res;
        let t: [u32; 3] = std::array::from_fn(|a| {
            ((u[a] * f64::from(1u32 << self.finest) / f64::from(self.cells)).floor() as u32).min(res[a] - 1)
        });
        let (bi, b) = self
            .bricks
            .iter()
            .enumerate()
            .find(|(_, b)| {
                let span = 1u32 << (self.finest - b.level);
                (0..3).all(|a| t[a] / span == b.coords[a])
            })
            .expect("the bricks cover every texel");
        let cells = f64::from(self.cells);
        let scale = f64::from(1u32 << b.level);
        let mut cell = [0usize; 3];
        let mut f = [0.0f64; 3];
        for a in 0..3 {
            let s = (u[a] * scale - f64::from(b.coords[a] * self.cells)).clamp(0.0, cells);
            cell[a] = (s.floor() as usize).min(self.cells as usize - 1);
            f[a] = s - cell[a] as f64;
        }
        let w = corner_weights(f);
        let data = self.brick_data(bi);
        let p = self.cells as usize + 1;
        let mut out = vec![0.0; k];
        for (c, &wc) in w.iter().enumerate() {
            let q = [cell[0] + (c & 1), cell[1] + ((c >> 1) & 1), cell[2] + (c >> 2)];
            let at = (q[0] + p * (q[1] + p * q[2])) * k;
            for (o, &v) in out.iter_mut().zip(&data[at..at + k]) {
                *o += wc * f64::from(v);
            }
        }
        out
    }

    /// Irradiance `E(x, n) = Σ_j A_j L_j(x) Y_j(n)` (Kontkanen & Laine 2006 Eq. 3) from
    /// [`Self::coeffs_at`].
    #[must_use]
    pub fn irradiance(&self, p: [f32; 3], n: [f32; 3]) -> [f32; 3] {
        self.shade(p, n, true)
    }

    /// Radiance `L(x, ω) = Σ_j L_j(x) Y_j(ω)` from [`Self::coeffs_at`].
    #[must_use]
    pub fn radiance(&self, p: [f32; 3], dir: [f32; 3]) -> [f32; 3] {
        self.shade(p, dir, false)
    }

    fn shade(&self, p: [f32; 3], n: [f32; 3], irr: bool) -> [f32; 3] {
        let mut c = [0.0f32; 48];
        self.coeffs_at(p, &mut c);
        shade_dyn(self.coeffs, &c, &factors(self.coeffs, irr), n)
    }

    /// Irradiance in f64 from [`Self::coeffs_at_reference`].
    #[must_use]
    pub fn irradiance_reference(&self, p: [f64; 3], n: [f64; 3]) -> [f64; 3] {
        expand(self.coeffs, &self.coeffs_at_reference(p), n, true)
    }
}
