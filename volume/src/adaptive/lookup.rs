//! Lookups of an [`AdaptiveVolume`] (see [`crate::adaptive`] for the representation):
//! the f64 reference (binary search in each level's sorted keys), the f32 fast path (hash
//! index), irradiance and radiance from them (Kontkanen & Laine 2006 Eq. 3), and the
//! resampling to a uniform volume.

use rayon::prelude::*;

use crate::adaptive::{AdaptiveVolume, TO_UNIFORM_MAX_NODES, pack_key};
use crate::error::VolumeError;
use crate::grid::{GridSpec, corner_weights};
use crate::lookup::{expand, par_batch, shade_dyn};
use crate::lookup_params::{factors, weights8};
use crate::volume::IrradianceVolume;

impl AdaptiveVolume {
    /// Grid point in base cell units, clamped into the box (f64).
    fn base_units(&self, g: [f64; 3]) -> [f64; 3] {
        let (min, max) = self.base.spec().bounds();
        let res = self.base.spec().res();
        std::array::from_fn(|a| {
            let cells = f64::from(res[a] - 1);
            let u = ((g[a] - min[a]) / (max[a] - min[a]) * cells).clamp(0.0, cells);
            if u.is_nan() { 0.0 } else { u }
        })
    }

    /// The f64 field `Σ_{l < levels} I_l` at base-cell units `u0` (the reference sum; the
    /// builder uses it for surpluses).
    pub(crate) fn sum_levels_f64(&self, u0: [f64; 3], levels: u32, out: &mut [f64]) {
        let k = self.coeffs() * 3;
        out[..k].fill(0.0);
        let res0 = self.base.spec().res();
        for l in 0..levels {
            let s = f64::from(1u32 << l);
            let n = res0.map(|r| (r - 1) * (1 << l) + 1);
            let mut cell = [0u32; 3];
            let mut f = [0.0; 3];
            for a in 0..3 {
                let u = u0[a] * s;
                cell[a] = (u.floor() as u32).min(n[a] - 2);
                f[a] = (u - f64::from(cell[a])).clamp(0.0, 1.0);
            }
            let w = corner_weights(f);
            for (c, &wc) in w.iter().enumerate() {
                let node = [
                    cell[0] + (c as u32 & 1),
                    cell[1] + ((c as u32 >> 1) & 1),
                    cell[2] + ((c as u32 >> 2) & 1),
                ];
                let vals: Option<&[f32]> = if l == 0 {
                    Some(self.base.node(self.base.spec().node_index(node[0], node[1], node[2])))
                } else {
                    let t = &self.tables[l as usize - 1];
                    t.keys.binary_search(&pack_key(node)).ok().map(|i| &t.data[i * k..(i + 1) * k])
                };
                if let Some(v) = vals {
                    for (o, &x) in out[..k].iter_mut().zip(v) {
                        *o += wc * f64::from(x);
                    }
                }
            }
        }
    }

    /// The interpolated coefficients `[coeff][rgb]` at world point `p`: the f64 reference
    /// (binary search per corner and level).
    #[must_use]
    pub fn coeffs_at_reference(&self, p: [f64; 3]) -> Vec<f64> {
        let mut out = vec![0.0; self.coeffs() * 3];
        let u0 = self.base_units(self.base.spec().to_grid(p));
        self.sum_levels_f64(u0, self.params.max_level + 1, &mut out);
        out
    }

    /// The coefficients at a *grid-space* point (f64 reference).
    pub(crate) fn coeffs_at_grid_f64(&self, g: [f64; 3], out: &mut [f64]) {
        let u0 = self.base_units(g);
        self.sum_levels_f64(u0, self.params.max_level + 1, out);
    }

    /// Irradiance `E(x, n) = Σ_j A_j L_j(x) Y_j(n)` (Kontkanen & Laine 2006 Eq. 3) from
    /// [`Self::coeffs_at_reference`], in f64.
    #[must_use]
    pub fn irradiance_reference(&self, p: [f64; 3], n: [f64; 3]) -> [f64; 3] {
        expand(self.coeffs(), &self.coeffs_at_reference(p), n, true)
    }

    /// The interpolated coefficients at world point `p` into `out[..3·coeffs]`
    /// (`[coeff][rgb]`): the f32 fast path (hash index, levels accumulated coarse to fine,
    /// corners in order `c = dx + 2dy + 4dz`).
    ///
    /// # Panics
    /// If `out` is shorter than `3 · coeffs`.
    pub fn coeffs_at(&self, p: [f32; 3], out: &mut [f32]) {
        let k = self.coeffs() * 3;
        let out = &mut out[..k];
        out.fill(0.0);
        let spec = self.base.spec();
        let (min, max) = spec.bounds();
        let res0 = spec.res();
        let g: [f32; 3] = match spec.placement() {
            None => p,
            Some(pl) => {
                let m = pl.to_grid_matrix().map(|r| r.map(|v| v as f32));
                std::array::from_fn(|r| m[r][0] * p[0] + m[r][1] * p[1] + m[r][2] * p[2] + m[r][3])
            }
        };
        let u0: [f32; 3] = std::array::from_fn(|a| {
            let cells = (res0[a] - 1) as f32;
            let scale = (f64::from(res0[a] - 1) / (max[a] - min[a])) as f32;
            // max/min (not clamp) so that NaN maps to 0.
            ((g[a] - min[a] as f32) * scale).max(0.0).min(cells)
        });
        let data0 = self.base.data();
        let [nx, ny, _] = res0.map(|v| v as usize);
        for l in 0..=self.params.max_level {
            let s = (1u32 << l) as f32;
            let mut cell = [0u32; 3];
            let mut f = [0.0f32; 3];
            for a in 0..3 {
                let u = u0[a] * s;
                let n = (res0[a] - 1) * (1 << l) + 1;
                cell[a] = (u as u32).min(n - 2);
                f[a] = (u - cell[a] as f32).clamp(0.0, 1.0);
            }
            let w = weights8(f[0], f[1], f[2]);
            for (c, &wc) in w.iter().enumerate() {
                let node = [
                    cell[0] + (c as u32 & 1),
                    cell[1] + ((c as u32 >> 1) & 1),
                    cell[2] + ((c as u32 >> 2) & 1),
                ];
                let vals = if l == 0 {
                    let i = node[0] as usize + nx * (node[1] as usize + ny * node[2] as usize);
                    &data0[i * k..(i + 1) * k]
                } else {
                    let t = &self.tables[l as usize - 1];
                    match self.index[l as usize - 1].get(&pack_key(node)) {
                        Some(&i) => &t.data[i as usize * k..(i as usize + 1) * k],
                        None => continue,
                    }
                };
                for (o, &x) in out.iter_mut().zip(vals) {
                    *o += wc * x;
                }
            }
        }
    }

    /// Irradiance (Kontkanen & Laine 2006 Eq. 3) at world point `p` for the unit normal `n`,
    /// f32 path.
    #[must_use]
    pub fn irradiance(&self, p: [f32; 3], n: [f32; 3]) -> [f32; 3] {
        self.shade(p, n, true)
    }

    /// Radiance arriving at `p` from direction `dir` (no `A_l`), f32 path.
    #[must_use]
    pub fn radiance(&self, p: [f32; 3], dir: [f32; 3]) -> [f32; 3] {
        self.shade(p, dir, false)
    }

    fn shade(&self, p: [f32; 3], n: [f32; 3], irr: bool) -> [f32; 3] {
        let mut c = [0.0f32; 48];
        self.coeffs_at(p, &mut c);
        shade_dyn(self.coeffs(), &c, &factors(self.coeffs(), irr), n)
    }

    /// Batched irradiance, parallel over rayon's pool, bit-identical to
    /// [`Self::irradiance`] per query. Errors if the slice lengths differ.
    pub fn irradiance_batch(
        &self,
        points: &[[f32; 3]],
        normals: &[[f32; 3]],
        out: &mut [[f32; 3]],
    ) -> Result<(), VolumeError> {
        par_batch(points, normals, out, "normals", |p, n, o| {
            for ((e, p), n) in o.iter_mut().zip(p).zip(n) {
                *e = self.irradiance(*p, *n);
            }
        })
    }

    /// Resamples to a uniform volume of `res` nodes per axis (default: [`Self::finest_res`])
    /// over the same box and placement, for formats that cannot hold an octree (KTX2, DDS,
    /// Bevy). Node values are the f64 reference lookup at the nodes, rounded to f32; weights
    /// are 1; metadata is copied. At the finest resolution this is exact at every node of
    /// the finest level. Errors above [`TO_UNIFORM_MAX_NODES`] nodes.
    pub fn to_uniform(&self, res: Option<[u32; 3]>) -> Result<IrradianceVolume, VolumeError> {
        let res = res.unwrap_or_else(|| self.finest_res());
        let count = res.iter().try_fold(1usize, |a, &n| a.checked_mul(n as usize));
        if count.is_none_or(|c| c > TO_UNIFORM_MAX_NODES) {
            return Err(VolumeError::InvalidGrid(format!(
                "to_uniform: {}x{}x{} nodes exceed the export limit of {TO_UNIFORM_MAX_NODES}; pass a smaller resolution",
                res[0], res[1], res[2]
            )));
        }
        let (min, max) = self.base.spec().bounds();
        let mut spec = GridSpec::new(min, max, res)?;
        if let Some(p) = self.base.spec().placement() {
            spec = spec.with_placement(*p);
        }
        let k = self.coeffs() * 3;
        let mut data = vec![0.0f32; spec.node_count() * k];
        data.par_chunks_mut(k).enumerate().for_each(|(node, d)| {
            let [i, j, kk] = spec.node_coords(node);
            let mut v = [0.0f64; 48];
            self.coeffs_at_grid_f64(spec.node_position(i, j, kk), &mut v);
            for (o, x) in d.iter_mut().zip(v) {
                *o = x as f32;
            }
        });
        let n = spec.node_count();
        Ok(IrradianceVolume::new(spec, self.coeffs(), data, vec![1.0; n])?
            .with_metadata(self.metadata().clone()))
    }
}
