//! Kernel 2: proxy accumulation and exponentiation on the GPU (Sloan, Govindaraju,
//! Nowrouzezahrai & Snyder 2007, \[SGNS07\] §4), two dispatches per frame:
//!
//! - **2a, accumulation** (`shaders/accumulate.wgsl`, Eq. 4, 8, 12, 15): the GPU twin of
//!   [`lightvol_proxies::pipeline::accumulate_pass`]. One invocation per receiver of a
//!   [`ReceiverBuffer`] sums the proxies binned into its screen tile ([`TileBins`], binned
//!   on the host by [`lightvol_proxies::pipeline::bin_proxies`]) into an [`Accum`].
//! - **2b, exponentiation** (`shaders/exponentiate.wgsl`, Eq. 9 by HYB, Eq. 12): the twin of
//!   [`lightvol_proxies::pipeline::exponentiate_pass`], reading 2a's output on the device
//!   and writing the receiver's [`Incident`] radiance (shadowed light and indirect light).
//!
//! - **2c, bilateral upsampling** (`shaders/upsample.wgsl`, §4.2 Eq. 11): the twin of
//!   [`lightvol_proxies::upsample::bilateral_upsample`] applied to `O * L + I`, reading
//!   2b's output on the device; display pixels with no matching coarse receiver are
//!   flagged and computed on the host by the caller's fallback, as on the CPU.
//!
//! # Buffer layout of 2a
//! All bindings are storage buffers of 4-byte elements in `@group(0)`:
//!
//! | binding | contents |
//! |---|---|
//! | 0 | parameters: width, height, tile, tiles per row; table entries, indirect flag, tile count; `α` thresholds; SH recurrence constants (see `shaders/accumulate.wgsl`) |
//! | 1 | receivers, 8 f32 each: position xyz, valid (1/0), normal xyz, unused |
//! | 2 | proxies, `4 + 3N` f32 each: centre xyz, radius, exit radiance `[rgb][N]` ([`PreparedProxy`]) |
//! | 3 | tables of `E` entries: `O^log` `[E][4]`, `V` `[E][4]`, `D` `[E][4]`, `ω` `[E]` |
//! | 4 | tile lists (u32), CSR: offsets `[tiles + 1]`, then proxy indices |
//! | 5 | output, `N + 29` f32 per receiver: log visibility `[N]`, indirect `[rgb][9]`, `ω`, count |
//!
//! # Buffer layout of 2b
//!
//! | binding | contents |
//! |---|---|
//! | 0 | parameters: receivers, schedule lengths, OL samples; HYB threshold, OL spacing, `sqrt(4π)` |
//! | 1, 2 | 2a's bindings 1 (receivers) and 5 (accumulators) |
//! | 3 | light `L(p)` per receiver, `[rgb][N]` f32 |
//! | 4 | Gaunt schedules, 4 words per entry `(i, j, k, value)`: squaring, then product (`k < 9`) |
//! | 5 | OL coefficients `(a·sqrt(4π), b)` on a uniform grid of norms over `[0, HYB threshold]` |
//! | 6 | output, 54 f32 per receiver: shadowed `O * L` `[rgb][9]`, indirect `ξ Ĩ` `[rgb][9]` |
//!
//! # Buffer layout of 2c
//! Parameters (coarse and display sizes, size ratios, `DEPTH_EPS_REL`, `WEIGHT_FLOOR`),
//! coarse geometry (normal xyz, eye depth per receiver), 2b's output, display geometry
//! (same form), and the output: 27 values and a fallback flag per display pixel.
//!
//! The tables are the CPU kernel's own ([`Kernel::tables`]): each ZH entry scaled by
//! `sqrt(4π/(2l+1))` (Eq. 8) and the smooth-clamp weight of its `α`, so the two evaluators
//! read the same numbers.

use lightvol_proxies::accumulate::shared_ol_table;
use lightvol_proxies::kernel::{Accum, Incident, Kernel, KernelIndirect, PreparedProxy, Rgb9, light_f32};
use lightvol_proxies::light::LightField;
use lightvol_proxies::pipeline::TileBins;
use lightvol_proxies::receiver_scene::ReceiverBuffer;
use lightvol_proxies::tables::{SQRT_4PI, TABLE_ENTRIES};
use lightvol_proxies::upsample::{DEPTH_EPS_REL, WEIGHT_FLOOR};
use lightvol_sh::gaunt::GauntTable;
use lightvol_sh::shexp::HYB_NORM_THRESHOLD;

use crate::buffer::GpuBuffer;
use crate::context::GpuContext;
use crate::error::GpuError;
use crate::lookup::ShRecurrence;
use crate::pipeline::{ComputePipeline, DispatchStats, groups_for};
use crate::shaders;

/// Words of 2a's parameter buffer (binding 0).
const PARAM_WORDS: usize = 48;

/// Samples of the OL coefficients over `[0, HYB_NORM_THRESHOLD]` for 2b. lightvol-sh's OL
/// table is piecewise linear with about a dozen breakpoints in that range; a 4096-interval
/// grid reproduces it up to the intervals holding a breakpoint, where the difference is at
/// most a quarter of the slope change times the spacing (2.4e-5 of the norm range).
pub const OL_SAMPLES: usize = 4097;

/// The Gaunt schedules of 2b (as `Kernel::new` builds them): squaring entries `i <= j`
/// (value doubled off the diagonal), then product entries with `k < 9`; 4 words each.
/// Returns the words and the two entry counts.
#[must_use]
pub fn gaunt_schedules<const N: usize>() -> (Vec<u32>, u32, u32) {
    let entries = GauntTable::cached(N.isqrt()).entries();
    let mut square = Vec::new();
    let mut prod9 = Vec::new();
    for e in entries {
        let ijk = [u32::from(e.i), u32::from(e.j), u32::from(e.k)];
        if e.i <= e.j {
            let v = if e.i == e.j { e.value } else { 2.0 * e.value };
            square.extend(ijk);
            square.push((v as f32).to_bits());
        }
        if e.k < 9 {
            prod9.extend(ijk);
            prod9.push((e.value as f32).to_bits());
        }
    }
    let (ns, np) = ((square.len() / 4) as u32, (prod9.len() / 4) as u32);
    square.extend(prod9);
    (square, ns, np)
}

/// `(a·sqrt(4π), b)` of the shared OL table at [`OL_SAMPLES`] norms `s · spacing`, and the
/// spacing.
#[must_use]
pub fn ol_samples<const N: usize>() -> (Vec<f32>, f32) {
    let ol = shared_ol_table::<N>();
    let step = HYB_NORM_THRESHOLD / (OL_SAMPLES - 1) as f64;
    let mut out = Vec::with_capacity(2 * OL_SAMPLES);
    for s in 0..OL_SAMPLES {
        let (a, b) = ol.coefficients(s as f64 * step);
        out.extend([(a * SQRT_4PI) as f32, b as f32]);
    }
    (out, step as f32)
}

/// The smallest f32 strictly above `t`: `x > t` (in f64) equals `x >= next_above(t)` for
/// every f32 `x`, which lets the shader repeat the CPU's f64 threshold test in f32.
fn next_f32_above(t: f64) -> f32 {
    let r = t as f32;
    if f64::from(r) > t { r } else { f32::from_bits(r.to_bits() + 1) }
}

/// The f32 tables of the accumulation pass, in the layout of binding 3: the CPU kernel's own
/// tables ([`Kernel::tables`]), `O^log`, `V` and `D` (4 floats per entry each), then `ω`.
#[must_use]
pub fn kernel_tables<const N: usize>(
    eta_shadow: f64,
    eta_indirect: f64,
    indirect: KernelIndirect,
) -> Vec<f32> {
    let kernel = Kernel::<N>::new(eta_shadow, eta_indirect, indirect);
    let (olog, vis, omega, d) = kernel.tables();
    let mut out = Vec::with_capacity(13 * TABLE_ENTRIES);
    for table in [olog, vis, d] {
        out.extend(table.iter().flatten());
    }
    out.extend_from_slice(omega);
    debug_assert_eq!(out.len(), 13 * TABLE_ENTRIES);
    out
}

/// The accumulation and exponentiation passes for `N` (9 or 16) shadow coefficients, with
/// their tables resident.
#[derive(Debug)]
pub struct ProxyShading<const N: usize> {
    ctx: GpuContext,
    pipeline: ComputePipeline,
    exp_pipeline: ComputePipeline,
    up_pipeline: ComputePipeline,
    tables: GpuBuffer,
    schedule: GpuBuffer,
    ol: GpuBuffer,
    schedule_len: (u32, u32),
    ol_step: f32,
    alpha_shadow: f32,
    alpha_indirect: f32,
    indirect: bool,
}

/// One frame resident on the device: receivers, proxies, bins, light, accumulators and
/// incident radiance.
#[derive(Debug)]
pub struct ProxyFrame {
    params: GpuBuffer,
    exp_params: GpuBuffer,
    receivers: GpuBuffer,
    proxies: GpuBuffer,
    bins: GpuBuffer,
    light: GpuBuffer,
    out: GpuBuffer,
    incident: GpuBuffer,
    geometry: GpuBuffer,
    size: (usize, usize),
    len: usize,
}

/// A display-resolution target for the upsampling pass (see [`ProxyShading::target`]).
#[derive(Debug)]
pub struct UpsampleTarget {
    geometry: GpuBuffer,
    out: GpuBuffer,
    size: (usize, usize),
}

/// Normal xyz and eye depth per pixel: the geometry buffers of 2c.
fn geometry_words(b: &ReceiverBuffer) -> Vec<f32> {
    (0..b.width * b.height)
        .flat_map(|i| [b.normal[i][0], b.normal[i][1], b.normal[i][2], b.depth[i]])
        .collect()
}

impl<const N: usize> ProxyShading<N> {
    /// Builds the tables (as `Kernel::<N>::new(eta_shadow, eta_indirect, indirect)` does)
    /// and the pipelines.
    pub fn new(
        ctx: &GpuContext,
        eta_shadow: f64,
        eta_indirect: f64,
        indirect: KernelIndirect,
    ) -> Result<Self, GpuError> {
        let (acc, exp) = match N {
            9 => (shaders::ACCUMULATE[0], shaders::EXPONENTIATE[0]),
            16 => (shaders::ACCUMULATE[1], shaders::EXPONENTIATE[1]),
            _ => {
                return Err(GpuError::Invalid(format!("proxy shading needs 9 or 16 coefficients, not {N}")));
            }
        };
        let tables = ctx.upload(&kernel_tables::<N>(eta_shadow, eta_indirect, indirect))?;
        let pipeline = ComputePipeline::new(ctx, acc.name, &acc.words()?, 6)?;
        let exp_pipeline = ComputePipeline::new(ctx, exp.name, &exp.words()?, 7)?;
        let up = shaders::UPSAMPLE;
        let up_pipeline = ComputePipeline::new(ctx, up.name, &up.words()?, 5)?;
        let (sched, ns, np) = gaunt_schedules::<N>();
        let (ol, ol_step) = ol_samples::<N>();
        Ok(Self {
            ctx: ctx.clone(),
            pipeline,
            exp_pipeline,
            up_pipeline,
            tables,
            schedule: ctx.upload(&sched)?,
            ol: ctx.upload(&ol)?,
            schedule_len: (ns, np),
            ol_step,
            alpha_shadow: (1.0 / eta_shadow) as f32,
            alpha_indirect: (1.0 / eta_indirect) as f32,
            indirect: indirect != KernelIndirect::None,
        })
    }

    /// Uploads one frame: receivers, proxies, tile bins, and the light at each receiver.
    pub fn frame(
        &self,
        buffer: &ReceiverBuffer,
        bins: &TileBins,
        proxies: &[PreparedProxy<N>],
        light: &impl LightField<N>,
    ) -> Result<ProxyFrame, GpuError> {
        let (w, h) = (buffer.width, buffer.height);
        let len = w * h;
        if buffer.position.len() != len || buffer.normal.len() != len || buffer.depth.len() != len {
            return Err(GpuError::Invalid("receiver buffer arrays do not match width x height".into()));
        }
        if bins.tile == 0
            || bins.tiles_x != w.div_ceil(bins.tile)
            || bins.lists.len() != bins.tiles_x * h.div_ceil(bins.tile)
        {
            return Err(GpuError::Invalid("tile bins do not match the receiver buffer".into()));
        }
        let too_big = |what: &str| GpuError::Limit(format!("{what} exceed the shader's 32-bit indexing"));
        if len.checked_mul(N + 29).is_none_or(|words| u32::try_from(words).is_err()) {
            return Err(too_big("receivers"));
        }
        let mut rec = Vec::with_capacity(8 * len);
        for i in 0..len {
            let (p, n) = (buffer.position[i], buffer.normal[i]);
            rec.extend([p[0], p[1], p[2], if buffer.valid(i) { 1.0 } else { 0.0 }, n[0], n[1], n[2], 0.0]);
        }
        let mut prox = Vec::with_capacity((4 + 3 * N) * proxies.len());
        for p in proxies {
            prox.extend(p.center);
            prox.push(p.radius);
            for c in 0..3 {
                prox.extend(p.exit[c]);
            }
        }
        let mut csr =
            Vec::with_capacity(bins.lists.len() + 1 + bins.lists.iter().map(Vec::len).sum::<usize>());
        let mut at = 0u32;
        csr.push(0);
        for l in &bins.lists {
            at = at.checked_add(l.len() as u32).ok_or_else(|| too_big("tile lists"))?;
            csr.push(at);
        }
        for l in &bins.lists {
            if let Some(&bad) = l.iter().find(|&&i| i as usize >= proxies.len()) {
                return Err(GpuError::Invalid(format!("tile list names proxy {bad} of {}", proxies.len())));
            }
            csr.extend(l);
        }
        let sh = ShRecurrence::new();
        let mut words = [0u32; PARAM_WORDS];
        words[..4].copy_from_slice(&[w as u32, h as u32, bins.tile as u32, bins.tiles_x as u32]);
        words[4..7].copy_from_slice(&[
            TABLE_ENTRIES as u32,
            u32::from(self.indirect),
            bins.lists.len() as u32,
        ]);
        words[8] = self.alpha_shadow.to_bits();
        words[9] = self.alpha_indirect.to_bits();
        for j in 0..16 {
            words[12 + j] = sh.a[j].to_bits();
            words[28 + j] = sh.b[j].to_bits();
        }
        for m in 0..4 {
            words[44 + m] = sh.diag[m].to_bits();
        }
        let mut lights: Vec<f32> = Vec::with_capacity(3 * N * len);
        for i in 0..len {
            if buffer.valid(i) {
                lights.extend_from_slice(light_f32(light, buffer.position[i]).as_flattened());
            } else {
                lights.resize(lights.len() + 3 * N, 0.0);
            }
        }
        let (ns, np) = self.schedule_len;
        let mut exp_words = [0u32; 8];
        exp_words[..4].copy_from_slice(&[len as u32, ns, np, OL_SAMPLES as u32]);
        exp_words[4] = next_f32_above(HYB_NORM_THRESHOLD).to_bits();
        exp_words[5] = self.ol_step.to_bits();
        exp_words[6] = (SQRT_4PI as f32).to_bits();
        Ok(ProxyFrame {
            params: self.ctx.upload(&words)?,
            exp_params: self.ctx.upload(&exp_words)?,
            receivers: self.ctx.upload(&rec)?,
            proxies: self.ctx.upload(&prox)?,
            bins: self.ctx.upload(&csr)?,
            light: self.ctx.upload(&lights)?,
            out: self.ctx.zeroed_buffer((4 * len * (N + 29)) as u64)?,
            incident: self.ctx.zeroed_buffer((4 * len * 54) as u64)?,
            geometry: self.ctx.upload(&geometry_words(buffer))?,
            size: (w, h),
            len,
        })
    }

    /// Runs the exponentiation pass (2b) on a frame whose accumulators 2a wrote.
    pub fn run_exponentiate(&self, frame: &ProxyFrame, repeats: u32) -> Result<DispatchStats, GpuError> {
        let max_x = self.ctx.shared.limits.max_compute_work_group_count[0];
        self.exp_pipeline.dispatch(
            &[
                &frame.exp_params,
                &frame.receivers,
                &frame.out,
                &frame.light,
                &self.schedule,
                &self.ol,
                &frame.incident,
            ],
            groups_for(frame.len as u64, max_x),
            repeats,
        )
    }

    /// Uploads a display-resolution receiver buffer as an upsampling target.
    pub fn target(&self, fine: &ReceiverBuffer) -> Result<UpsampleTarget, GpuError> {
        let n = fine.width * fine.height;
        if fine.normal.len() != n || fine.depth.len() != n || n == 0 {
            return Err(GpuError::Invalid("display buffer arrays do not match width x height".into()));
        }
        if u32::try_from(28 * n).is_err() {
            return Err(GpuError::Limit("display buffer exceeds the shader's 32-bit indexing".into()));
        }
        Ok(UpsampleTarget {
            geometry: self.ctx.upload(&geometry_words(fine))?,
            out: self.ctx.zeroed_buffer((4 * 28 * n) as u64)?,
            size: (fine.width, fine.height),
        })
    }

    /// Runs the upsampling pass (2c) from a frame whose incident radiance 2b wrote.
    pub fn run_upsample(
        &self,
        frame: &ProxyFrame,
        target: &UpsampleTarget,
        repeats: u32,
    ) -> Result<DispatchStats, GpuError> {
        let ((cw, ch), (fw, fh)) = (frame.size, target.size);
        if cw == 0 || ch == 0 {
            return Err(GpuError::Invalid("empty receiver buffer".into()));
        }
        let mut words = [0u32; 12];
        words[..4].copy_from_slice(&[cw as u32, ch as u32, fw as u32, fh as u32]);
        words[4] = (cw as f32 / fw as f32).to_bits();
        words[5] = (ch as f32 / fh as f32).to_bits();
        words[6] = DEPTH_EPS_REL.to_bits();
        words[7] = WEIGHT_FLOOR.to_bits();
        words[8] = f32::MIN_POSITIVE.to_bits();
        let params = self.ctx.upload(&words)?;
        let max_x = self.ctx.shared.limits.max_compute_work_group_count[0];
        self.up_pipeline.dispatch(
            &[&params, &frame.geometry, &frame.incident, &target.geometry, &target.out],
            groups_for((fw * fh) as u64, max_x),
            repeats,
        )
    }

    /// Reads the upsampled `O * L + I` back, computing flagged pixels with `fallback`
    /// (as `bilateral_upsample` does); returns the values and the number of fallbacks.
    pub fn read_upsampled(
        &self,
        target: &UpsampleTarget,
        fallback: impl Fn(usize) -> Rgb9,
    ) -> Result<(Vec<Rgb9>, usize), GpuError> {
        let flat: Vec<f32> = target.out.read(0, 28 * target.size.0 * target.size.1)?;
        let mut fallbacks = 0;
        let values = flat
            .chunks_exact(28)
            .enumerate()
            .map(|(i, c)| {
                if c[27] != 0.0 {
                    fallbacks += 1;
                    fallback(i)
                } else {
                    std::array::from_fn(|k| c[k])
                }
            })
            .collect();
        Ok((values, fallbacks))
    }

    /// Reads a frame's incident radiance back (after [`Self::run_exponentiate`]).
    pub fn read_incident(&self, frame: &ProxyFrame) -> Result<Vec<Incident>, GpuError> {
        let flat: Vec<f32> = frame.incident.read(0, frame.len * 54)?;
        Ok(flat
            .chunks_exact(54)
            .map(|c| Incident {
                shadowed: std::array::from_fn(|j| c[j]),
                indirect: std::array::from_fn(|j| c[27 + j]),
            })
            .collect())
    }

    /// Uploads, accumulates, exponentiates and reads back: the GPU `accumulate_pass`
    /// followed by `exponentiate_pass`. Returns both outputs.
    pub fn shade(
        &self,
        buffer: &ReceiverBuffer,
        bins: &TileBins,
        proxies: &[PreparedProxy<N>],
        light: &impl LightField<N>,
    ) -> Result<(Vec<Accum<N>>, Vec<Incident>), GpuError> {
        let frame = self.frame(buffer, bins, proxies, light)?;
        self.run(&frame, 1)?;
        self.run_exponentiate(&frame, 1)?;
        Ok((self.read(&frame)?, self.read_incident(&frame)?))
    }

    /// Runs the accumulation pass (2a) on a resident frame, `repeats` times back to back.
    pub fn run(&self, frame: &ProxyFrame, repeats: u32) -> Result<DispatchStats, GpuError> {
        let max_x = self.ctx.shared.limits.max_compute_work_group_count[0];
        self.pipeline.dispatch(
            &[&frame.params, &frame.receivers, &frame.proxies, &self.tables, &frame.bins, &frame.out],
            groups_for(frame.len as u64, max_x),
            repeats,
        )
    }

    /// Reads a frame's accumulators back (after [`Self::run`]).
    pub fn read(&self, frame: &ProxyFrame) -> Result<Vec<Accum<N>>, GpuError> {
        let flat: Vec<f32> = frame.out.read(0, frame.len * (N + 29))?;
        Ok(flat
            .chunks_exact(N + 29)
            .map(|c| Accum {
                log_vis: std::array::from_fn(|j| c[j]),
                indirect: std::array::from_fn(|j| c[N + j]),
                omega: c[N + 27],
                count: c[N + 28] as u32,
            })
            .collect())
    }
}

impl ProxyFrame {
    /// Number of receivers.
    #[must_use]
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether the frame has no receivers.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }
}
