//! Kernel 1: batched irradiance-volume lookup on the GPU (Kontkanen & Laine 2006, Eq. 1-3
//! and Algorithm 1), shader `shaders/lookup.wgsl`.
//!
//! # Buffer layout
//! All bindings are storage buffers of 4-byte elements, `@group(0)`:
//!
//! | binding | contents | elements |
//! |---|---|---|
//! | 0 | parameters ([`PARAM_WORDS`] words, below) | f32 / u32 |
//! | 1 | coefficients `[node][coeff][rgb]`, f32: exactly [`IrradianceVolume::data`] | `nodes · coeffs · 3` |
//! | 2 | query points, world space, packed `xyz` triples (no padding) | `3 n` f32 |
//! | 3 | query normals (irradiance) or directions (radiance), unit, packed `xyz` | `3 n` f32 |
//! | 4 | results, packed RGB triples | `3 n` f32 |
//! | 5 | the validity mask: node `i` is bit `i % 32` of word `i / 32`, 1 valid (one word of zeros without a mask) | `⌈nodes / 32⌉` u32 |
//! | 6 | the node reach, six f32 per node in `lightvol_volume::reach::REACH_DIRECTIONS` order (one 0 without a reach) | `6 nodes` f32 |
//!
//! Parameter words (each `vec4` is 4 consecutive words):
//!
//! | words | field |
//! |---|---|
//! | 0-11 | rows of the world-to-grid affine map (used only when word 30 is 1) |
//! | 12-14 | grid-space box minimum; 15: the node reach's test-point offset along the normal (`lightvol_volume::lookup::reach_bias`) |
//! | 16-18 | `(n - 1) / (max - min)` per axis; 19: the reach's edge limit, `1 + REACH_EDGE_TOLERANCE` |
//! | 20-22 | `n - 1` per axis as f32 (23: unused) |
//! | 24-26 | `n - 2` per axis, u32; 27: flags, [`FLAG_VALIDITY`], [`FLAG_REACH`], [`FLAG_IRRADIANCE`] |
//! | 28-31 | `nx`, `nx · ny`, 1 if the volume is placed (else 0), query count (u32) |
//! | 32-47 | per-coefficient factor `f_j`: `A_l(j)` for irradiance, 1 for radiance |
//! | 48-63, 64-79 | SH recurrence constants `a(l, m)`, `b(l, m)` at `l (l + 1) + m` |
//! | 80-83 | `Q_m^m`, m = 0..3 |
//!
//! The f32 constants are derived from the [`GridSpec`] exactly as lightvol-volume's f32
//! lookup derives them (f64 arithmetic, one rounding), and the shader repeats that path's
//! operations in the same order, so GPU and CPU agree to f32 rounding (a driver may fuse
//! multiply-adds; see the tests for the measured agreement).
//!
//! # Validity and node reach
//! A volume with a validity mask (`point+apv`) or a node reach (`doi`) is looked up as
//! lightvol-volume's CPU lookup does: the trilinear weights renormalised over the valid
//! corners, then over the corners whose reach sees the query (tested at the point moved
//! along the normal for irradiance, at the point itself for radiance), in the same order
//! and f32 arithmetic.
//!
//! # Clamping and edge cases
//! As on the CPU: points outside the box clamp to its boundary (per axis), a NaN
//! coordinate maps to the box minimum on that axis. Normals are not normalised.

use lightvol_sh::index::sh_lm;
use lightvol_sh::irradiance::cosine_lobe_factor;
use lightvol_sh::recurrence::RecurrenceF32;
use lightvol_volume::reach::REACH_EDGE_TOLERANCE;
use lightvol_volume::{GridSpec, IrradianceVolume};

use crate::buffer::GpuBuffer;
use crate::context::GpuContext;
use crate::error::GpuError;
use crate::pipeline::{ComputePipeline, DispatchStats, groups_for};
use crate::shaders;

/// Number of 4-byte words in the parameter buffer (binding 0).
pub const PARAM_WORDS: usize = 84;

/// Parameter word 27: the volume's validity mask weights the corners.
pub const FLAG_VALIDITY: u32 = 1;
/// Parameter word 27: the volume's node reach weights the corners.
pub const FLAG_REACH: u32 = 2;
/// Parameter word 27: an irradiance lookup (the reach is tested at the point moved along
/// the normal).
pub const FLAG_IRRADIANCE: u32 = 4;

/// Bindings of the lookup shader (module docs).
const BINDINGS: u32 = 7;

/// What a lookup evaluates.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Quantity {
    /// Irradiance `E(x, n) = Σ_j A_j L_j(x) Y_j(n)` (Kontkanen & Laine 2006, Eq. 3).
    Irradiance,
    /// Radiance `L(x, ω) = Σ_j L_j(x) Y_j(ω)` (Eq. 2 with the SH expansion).
    Radiance,
}

/// The SH recurrence constants the shader uses, for up to 4 bands: lightvol-sh's f32 table of
/// its closed forms ([`RecurrenceF32`]), laid out at flat indices `l (l + 1) + m` as the
/// shader reads them.
///
/// `Q_l^m = a(l,m) z Q_{l-1}^m + b(l,m) Q_{l-2}^m`, `Q_m^m = diag[m]`;
/// `Y_{l,±m} = Q_l^m · (Re | Im)(x + i y)^m` (no Condon-Shortley phase).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ShRecurrence {
    /// `Q_m^m`, m = 0..3.
    pub diag: [f32; 4],
    /// `a(l, m)` at flat index `l (l + 1) + m` (m ≥ 0; other entries 0).
    pub a: [f32; 16],
    /// `b(l, m)` at flat index `l (l + 1) + m` (0 where `l < m + 2`).
    pub b: [f32; 16],
}

impl ShRecurrence {
    /// The constants for 4 bands (lower band counts use a prefix).
    #[must_use]
    pub fn new() -> Self {
        const BANDS: usize = 4;
        let t = RecurrenceF32::<BANDS>::new();
        let mut r = Self { diag: t.diag, a: [0.0; 16], b: [0.0; 16] };
        for l in 0..BANDS {
            for m in 0..=l {
                r.a[l * (l + 1) + m] = t.a[l][m];
                r.b[l * (l + 1) + m] = t.b[l][m];
            }
        }
        r
    }

    /// The basis at unit vector `n` by the shader's f32 recurrence, in the shader's
    /// operation order (a host mirror of `sh_basis` in `lookup.wgsl`, for tests). A
    /// deliberate twin of lightvol-sh's `eval::eval_recurrence` (the f64 reference it is
    /// tested against), kept separate to follow the shader's f32 order and tables.
    #[must_use]
    pub fn eval<const N: usize>(&self, n: [f32; 3]) -> [f32; N] {
        let bands = N.isqrt();
        let mut y = [0.0f32; N];
        let (mut c, mut s) = (1.0f32, 0.0f32);
        for m in 0..bands {
            if m > 0 {
                let cn = n[0] * c - n[1] * s;
                let sn = n[0] * s + n[1] * c;
                c = cn;
                s = sn;
            }
            let (mut q_prev2, mut q_prev) = (0.0f32, self.diag[m]);
            for l in m..bands {
                let mut q = q_prev;
                if l > m {
                    let idx = l * (l + 1) + m;
                    q = self.a[idx] * n[2] * q_prev + self.b[idx] * q_prev2;
                    q_prev2 = q_prev;
                    q_prev = q;
                }
                let base = l * (l + 1);
                if m == 0 {
                    y[base] = q;
                } else {
                    y[base + m] = q * c;
                    y[base - m] = q * s;
                }
            }
        }
        y
    }
}

impl Default for ShRecurrence {
    fn default() -> Self {
        Self::new()
    }
}

/// The per-coefficient factors `f_j` of `quantity` for `coeffs` coefficients (0 beyond).
#[must_use]
pub fn factors(coeffs: usize, quantity: Quantity) -> [f32; 16] {
    std::array::from_fn(|j| match (j < coeffs, quantity) {
        (false, _) => 0.0,
        (true, Quantity::Irradiance) => cosine_lobe_factor(sh_lm(j).0) as f32,
        (true, Quantity::Radiance) => 1.0,
    })
}

/// The parameter words (binding 0) for `spec`, `quantity`, `coeffs` and `count` queries,
/// with the flags of a volume with a validity mask (`validity`) and a node reach (`reach`).
#[must_use]
pub fn param_words(
    spec: &GridSpec,
    coeffs: usize,
    quantity: Quantity,
    count: u32,
    validity: bool,
    reach: bool,
) -> [u32; PARAM_WORDS] {
    let mut w = [0u32; PARAM_WORDS];
    let mut put_f = |i: usize, v: f32| w[i] = v.to_bits();
    let to_grid = spec
        .placement()
        .map_or([[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0]], |p| p.to_grid_matrix());
    for r in 0..3 {
        for c in 0..4 {
            put_f(4 * r + c, to_grid[r][c] as f32);
        }
    }
    let (min, max) = spec.bounds();
    let res = spec.res();
    for a in 0..3 {
        put_f(12 + a, min[a] as f32);
        put_f(16 + a, (f64::from(res[a] - 1) / (max[a] - min[a])) as f32);
        put_f(20 + a, (res[a] - 1) as f32);
    }
    let f = factors(coeffs, quantity);
    let sh = ShRecurrence::new();
    for j in 0..16 {
        put_f(32 + j, f[j]);
        put_f(48 + j, sh.a[j]);
        put_f(64 + j, sh.b[j]);
    }
    for m in 0..4 {
        put_f(80 + m, sh.diag[m]);
    }
    put_f(15, lightvol_volume::lookup::reach_bias(spec) as f32);
    put_f(19, (1.0 + REACH_EDGE_TOLERANCE) as f32);
    for a in 0..3 {
        w[24 + a] = res[a] - 2;
    }
    w[27] = if validity { FLAG_VALIDITY } else { 0 }
        | if reach { FLAG_REACH } else { 0 }
        | if quantity == Quantity::Irradiance { FLAG_IRRADIANCE } else { 0 };
    w[28] = res[0];
    w[29] = res[0] * res[1];
    w[30] = u32::from(spec.placement().is_some());
    w[31] = count;
    w
}

/// The validity flags `valid` (node order) packed for binding 5: node `i` is bit `i % 32` of
/// word `i / 32`.
#[must_use]
pub fn validity_words(valid: &[bool]) -> Vec<u32> {
    valid.chunks(32).map(|c| c.iter().enumerate().map(|(b, &v)| u32::from(v) << b).sum()).collect()
}

/// A volume resident on the GPU with the lookup pipeline for its coefficient count.
///
/// Upload once with [`VolumeLookup::new`], then evaluate batches with
/// [`VolumeLookup::irradiance`] / [`VolumeLookup::radiance`], or keep queries resident with
/// [`VolumeLookup::batch`] and [`VolumeLookup::run`] (benchmarks).
#[derive(Debug)]
pub struct VolumeLookup {
    ctx: GpuContext,
    pipeline: ComputePipeline,
    coeff_buffer: GpuBuffer,
    validity_buffer: GpuBuffer,
    reach_buffer: GpuBuffer,
    has_validity: bool,
    has_reach: bool,
    spec: GridSpec,
    coeffs: usize,
}

/// Queries and results resident on the device (see [`VolumeLookup::batch`]).
#[derive(Debug)]
pub struct LookupBatch {
    params: GpuBuffer,
    points: GpuBuffer,
    dirs: GpuBuffer,
    out: GpuBuffer,
    len: usize,
}

impl LookupBatch {
    /// Number of queries.
    #[must_use]
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether the batch has no queries.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Reads the results of the last [`VolumeLookup::run`] (zeros before the first).
    pub fn read(&self) -> Result<Vec<[f32; 3]>, GpuError> {
        let flat: Vec<f32> = self.out.read(0, 3 * self.len)?;
        Ok(flat.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect())
    }

    /// Bytes the device reads and writes per query outside the volume: point, direction,
    /// result (for bandwidth figures).
    pub const QUERY_BYTES: usize = 9 * size_of::<f32>();
}

impl VolumeLookup {
    /// Uploads `vol`'s coefficients, validity mask and node reach and builds the pipeline
    /// for its coefficient count. Errors if the volume exceeds the device's storage-buffer
    /// range or 32-bit indexing.
    pub fn new(ctx: &GpuContext, vol: &IrradianceVolume) -> Result<Self, GpuError> {
        let coeffs = vol.coeffs();
        let shader = match coeffs {
            4 => shaders::LOOKUP[0],
            9 => shaders::LOOKUP[1],
            16 => shaders::LOOKUP[2],
            c => return Err(GpuError::Invalid(format!("unsupported coefficient count {c}"))),
        };
        if u32::try_from(vol.data().len()).is_err() {
            return Err(GpuError::Limit(format!(
                "{} coefficient floats exceed the shader's 32-bit indexing",
                vol.data().len()
            )));
        }
        let coeff_buffer = ctx.upload(vol.data())?;
        let words = vol.validity().map_or_else(|| vec![0u32], |m| validity_words(m.as_slice()));
        let reach: Vec<f32> =
            vol.reach().map_or_else(|| vec![0.0], |r| (0..r.len()).flat_map(|i| r.node(i)).collect());
        let pipeline = ComputePipeline::new(ctx, shader.name, &shader.words()?, BINDINGS)?;
        Ok(Self {
            ctx: ctx.clone(),
            pipeline,
            coeff_buffer,
            validity_buffer: ctx.upload(&words)?,
            reach_buffer: ctx.upload(&reach)?,
            has_validity: vol.validity().is_some(),
            has_reach: vol.reach().is_some(),
            spec: vol.spec().clone(),
            coeffs,
        })
    }

    /// SH coefficients per channel of the resident volume.
    #[must_use]
    pub fn coeffs(&self) -> usize {
        self.coeffs
    }

    /// The resident volume's grid.
    #[must_use]
    pub fn spec(&self) -> &GridSpec {
        &self.spec
    }

    /// Bytes of coefficient data on the device.
    #[must_use]
    pub fn volume_bytes(&self) -> u64 {
        self.coeff_buffer.size()
    }

    /// Irradiance at each `(points[q], normals[q])` (Kontkanen & Laine 2006, Eq. 3).
    pub fn irradiance(&self, points: &[[f32; 3]], normals: &[[f32; 3]]) -> Result<Vec<[f32; 3]>, GpuError> {
        self.evaluate(Quantity::Irradiance, points, normals)
    }

    /// Radiance arriving at each `points[q]` from direction `dirs[q]`.
    pub fn radiance(&self, points: &[[f32; 3]], dirs: &[[f32; 3]]) -> Result<Vec<[f32; 3]>, GpuError> {
        self.evaluate(Quantity::Radiance, points, dirs)
    }

    /// Uploads, dispatches once and reads back.
    pub fn evaluate(
        &self,
        quantity: Quantity,
        points: &[[f32; 3]],
        dirs: &[[f32; 3]],
    ) -> Result<Vec<[f32; 3]>, GpuError> {
        if points.is_empty() && dirs.is_empty() {
            return Ok(Vec::new());
        }
        let mut batch = self.batch(points, dirs)?;
        self.run(&mut batch, quantity, 1)?;
        batch.read()
    }

    /// Uploads queries into device buffers for repeated [`Self::run`]s.
    pub fn batch(&self, points: &[[f32; 3]], dirs: &[[f32; 3]]) -> Result<LookupBatch, GpuError> {
        if points.len() != dirs.len() {
            return Err(GpuError::Invalid(format!("{} points but {} directions", points.len(), dirs.len())));
        }
        let n = points.len();
        if u32::try_from(3 * n as u64).is_err() {
            return Err(GpuError::Limit(format!("{n} queries exceed the shader's 32-bit indexing")));
        }
        Ok(LookupBatch {
            params: self.ctx.zeroed_buffer((PARAM_WORDS * 4) as u64)?,
            points: self.ctx.upload(points.as_flattened())?,
            dirs: self.ctx.upload(dirs.as_flattened())?,
            out: self.ctx.zeroed_buffer(12 * n as u64)?,
            len: n,
        })
    }

    /// Evaluates `batch` for `quantity`, `repeats` times back to back in one submission
    /// (each repeat recomputes every query; the GPU time covers all of them).
    pub fn run(
        &self,
        batch: &mut LookupBatch,
        quantity: Quantity,
        repeats: u32,
    ) -> Result<DispatchStats, GpuError> {
        let words = param_words(
            &self.spec,
            self.coeffs,
            quantity,
            batch.len as u32,
            self.has_validity,
            self.has_reach,
        );
        batch.params.write(0, &words)?;
        let max_x = self.ctx.shared.limits.max_compute_work_group_count[0];
        let groups = groups_for(batch.len as u64, max_x);
        self.pipeline.dispatch(
            &[
                &batch.params,
                &self.coeff_buffer,
                &batch.points,
                &batch.dirs,
                &batch.out,
                &self.validity_buffer,
                &self.reach_buffer,
            ],
            groups,
            repeats,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use lightvol_sh::eval::eval_basis;
    use lightvol_sh::lowdisc::SplitMix64;

    /// The shader's recurrence against lightvol-sh's generated f32 code: same mathematics,
    /// constants rounded once from f64 each; a few f32 ulps of the largest basis value
    /// (|Y| < 1.1 for l <= 3) cover the rounding of a four-step recurrence.
    const RECURRENCE_TOL: f32 = 8.0 * f32::EPSILON;

    fn unit(rng: &mut SplitMix64) -> [f32; 3] {
        loop {
            let v = [rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), rng.range(-1.0, 1.0)];
            let r2: f64 = v.iter().map(|x| x * x).sum();
            if r2 > 1e-4 && r2 <= 1.0 {
                let r = r2.sqrt();
                return v.map(|x| (x / r) as f32);
            }
        }
    }

    #[test]
    fn shader_recurrence_matches_lightvol_sh() {
        let rec = ShRecurrence::new();
        let mut rng = SplitMix64::new(11);
        let mut max_err = 0.0f32;
        for _ in 0..2000 {
            let n = unit(&mut rng);
            let got: [f32; 16] = rec.eval(n);
            let want: [f32; 16] = eval_basis(n);
            for j in 0..16 {
                max_err = max_err.max((got[j] - want[j]).abs());
            }
            // Lower band counts are prefixes.
            let got9: [f32; 9] = rec.eval(n);
            assert_eq!(got9[..], got[..9]);
        }
        assert!(max_err <= RECURRENCE_TOL, "max |shader - lightvol-sh| = {max_err:e}");
    }

    #[test]
    fn factors_are_cosine_lobe() {
        let f = factors(9, Quantity::Irradiance);
        assert_eq!(f[0], std::f32::consts::PI);
        assert_eq!(f[1], (2.0 * std::f64::consts::PI / 3.0) as f32);
        assert_eq!(f[8], std::f32::consts::FRAC_PI_4);
        assert_eq!(f[9], 0.0);
        assert_eq!(factors(4, Quantity::Radiance), std::array::from_fn(|j| if j < 4 { 1.0 } else { 0.0 }));
    }

    #[test]
    fn param_words_layout() {
        let spec = GridSpec::new([-1.0, 0.0, 2.0], [3.0, 1.5, 5.0], [5, 4, 3]).unwrap();
        let w = param_words(&spec, 9, Quantity::Irradiance, 77, false, true);
        let f = |i: usize| f32::from_bits(w[i]);
        // Identity placement.
        assert_eq!((f(0), f(5), f(10), f(3), f(1)), (1.0, 1.0, 1.0, 0.0, 0.0));
        assert_eq!((f(12), f(13), f(14)), (-1.0, 0.0, 2.0));
        assert_eq!((f(16), f(17), f(18)), (1.0, 2.0, 2.0 / 3.0_f64 as f32));
        assert_eq!((f(20), f(21), f(22)), (4.0, 3.0, 2.0));
        assert_eq!((w[24], w[25], w[26], w[27]), (3, 2, 1, FLAG_REACH | FLAG_IRRADIANCE));
        // A tenth of the smallest cell edge (x 4 / 4, y 1.5 / 3, z 3 / 2: 0.5), one cell plus 1e-6.
        assert_eq!(f(15), 0.05);
        assert_eq!(f(19), 1.000_001);
        assert_eq!(param_words(&spec, 9, Quantity::Radiance, 77, true, false)[27], FLAG_VALIDITY);
        assert_eq!((w[28], w[29], w[30], w[31]), (5, 20, 0, 77));
        assert_eq!(f(32), std::f32::consts::PI);
        assert_eq!(f(80), (0.25 / std::f64::consts::PI).sqrt() as f32);
    }
}
