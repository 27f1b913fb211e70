//! Two estimators of the per-node SH irradiance gradients that lightvol-volume's
//! [`VolumeGradients`] stores (Oat, *Irradiance Volumes for Games*, GDC 2005 — \[Oat05\],
//! slides "Spherical Harmonic Irradiance Gradients" and "Central Differencing").
//!
//! **(a) Central differencing** ([`central_difference_gradients`], \[Oat05\]): at every node
//! `x_i`, six extra point projections (\[KL06\] Eq. 4) at `x_i ± h e_a`
//! along the world axes, and `∂c/∂x_a ≈ (c(x_i + h e_a) − c(x_i − h e_a)) / 2h` per
//! coefficient. All seven projections of a node share one direction set and one path
//! random stream (common random numbers), so where the visible scene is the same from the
//! seven points the Monte Carlo noise cancels in the difference; without that the noise
//! of the difference would grow like `1/h`.
//!
//! *Choice of h* ([`DEFAULT_OFFSET_FRACTION`]): `h` is 1/16 of the shortest world cell edge.
//! The truncation error of the central difference is `h² f'''/6`; relative to the cell-scale
//! change the gradient has to describe it is `(h/Δ)² / 6 ≈ 7·10⁻⁴`, far below the noise of a
//! bake. Smaller `h` buys nothing in accuracy but lets visibility changes (an occluder edge
//! crossing a few sample directions between `x − h` and `x + h`) weigh `1/h` more, and
//! the offset points stay within a cell of their node, so near geometry no further outside
//! the node's neighbourhood than the bake itself looks. Point projections see solids'
//! insides like `point` bakes do (Kontkanen & Laine Fig. 6c); this estimator does not use
//! the domain of interest.
//!
//! **(b) Basis-gradient estimator** ([`BasisGradientAccumulator`], [`bake_with_gradients`]):
//! reuses the bake's own cell samples (origins `x_s`, per-sample estimates
//! `f_s = Σ_t L_t Y(ω_t) / pdf_t`), restricted to the domain of interest (only the samples the
//! `doi` bake keeps). Per node `i`, with the trilinear basis `b_i` and its gradient `∇b_i`
//! as test functions, it solves the 4×4 Petrov-Galerkin system
//!
//! `Σ_s w(x_s) [f_s − c − g · (x_s − x_i)] = 0` for `w ∈ {b_i, ∂b_i/∂u_x, ∂b_i/∂u_y, ∂b_i/∂u_z}`
//!
//! for the value `c` and gradient `g` of every coefficient (`u` cell-local coordinates).
//! The `b_i` row is the bake's Eq. 6 (weighted mean); over a full support with uniform
//! sample density the `∇b_i` rows are `−∫ ∇b_i f = ∫ b_i ∇f` (integration by parts), i.e. the
//! `b_i`-weighted mean gradient. The system is exact for fields linear in x on **any** sample
//! set that spans 3D, so cutting the support by the domain of interest (where the boundary
//! terms of the integration by parts no longer vanish) biases nothing for linear fields.
//! Like Eq. 6 itself it estimates a support average: for a curved field its bias is
//! `O(Δ²)` at interior nodes (symmetric support) and `O(Δ)` at boundary nodes.
//! Nodes whose system is singular (fewer than three independent directions of samples)
//! get a zero gradient and are counted in [`GradientReport::singular`].

use glam::DVec3;
use lightvol_sh::eval::eval_into;
use lightvol_sh::index::bands_of;
use lightvol_sh::lowdisc::hash2;
use lightvol_sh::sampling::sample_uniform_sphere;
use lightvol_volume::fixed::FixedSums;
use lightvol_volume::gradient::VolumeGradients;
use lightvol_volume::{Accumulator, GridSpec, IrradianceVolume};
use rayon::prelude::*;

use crate::bake::{BakeOutput, bake_with_sink};
use crate::error::BakeError;
use crate::method::Method;
use crate::settings::BakeSettings;
use crate::stats::BakeStats;
use crate::unit::{UnitOut, sample_terms};
use lightvol_core::progress::BakeControl;
use lightvol_scene::qmc::Qmc;
use lightvol_scene::transport::{PathRng, Transport};

/// Central-difference offset as a fraction of the shortest world cell edge (module docs).
pub const DEFAULT_OFFSET_FRACTION: f64 = 1.0 / 16.0;

/// Stream tag of the gradient point projections ("grad"), distinct from the bake's.
const GRADIENT_STREAM: u64 = 0x6772_6164;

/// Smallest pivot of the 4×4 system, relative to its largest entry, accepted as
/// non-singular. The system is dimensionless (cell-local coordinates), so entries are
/// `O(Σ b)`; a pivot 1e-9 of that means the samples span (nearly) no volume along one axis.
const MIN_RELATIVE_PIVOT: f64 = 1e-9;

/// World lengths of the three cell edges.
fn cell_edges(grid: &GridSpec) -> [DVec3; 3] {
    let size = grid.cell_size();
    let o = DVec3::from_array(grid.to_world([0.0; 3]));
    std::array::from_fn(|a| {
        let mut e = [0.0; 3];
        e[a] = size[a];
        DVec3::from_array(grid.to_world(e)) - o
    })
}

/// [`DEFAULT_OFFSET_FRACTION`] times the shortest world cell edge.
#[must_use]
pub fn default_offset(grid: &GridSpec) -> f64 {
    DEFAULT_OFFSET_FRACTION * cell_edges(grid).iter().map(|e| e.length()).fold(f64::INFINITY, f64::min)
}

/// \[Oat05\]'s central differencing with any point projector: `project(node, x)` returns the
/// `3 · coeffs` coefficients `[coeff][rgb]` at world point `x` (it should use the same random
/// numbers for all calls with the same `node`). Returns the gradient array
/// `[node][coeff][rgb][xyz]`, nodes in parallel, bit-identical for any thread count.
pub fn central_differences(
    grid: &GridSpec,
    coeffs: usize,
    h: f64,
    project: impl Fn(usize, DVec3) -> Vec<f64> + Sync,
) -> Vec<f32> {
    central_differences_of(grid, coeffs, h, 0..grid.node_count(), project)
}

/// [`central_differences`] for the nodes in `nodes` only (a shard's); the other nodes'
/// gradients are zero. Each node's gradient depends on nothing but the node, so the union
/// of disjoint ranges is the whole array bit for bit.
pub fn central_differences_of(
    grid: &GridSpec,
    coeffs: usize,
    h: f64,
    nodes: std::ops::Range<usize>,
    project: impl Fn(usize, DVec3) -> Vec<f64> + Sync,
) -> Vec<f32> {
    let k = coeffs * 3;
    let all = grid.node_count();
    let nodes = nodes.start.min(all)..nodes.end.min(all);
    let (before, after) = (nodes.start * k * 3, (all - nodes.end) * k * 3);
    let per_node: Vec<Vec<f32>> = nodes
        .into_par_iter()
        .map(|node| {
            let [i, j, l] = grid.node_coords(node);
            let x = DVec3::from_array(grid.node_position_world(i, j, l));
            let mut g = vec![0.0f32; k * 3];
            for a in 0..3 {
                let e = DVec3::from_array(std::array::from_fn(|b| if a == b { h } else { 0.0 }));
                let (p, m) = (project(node, x + e), project(node, x - e));
                for c in 0..k {
                    g[3 * c + a] = ((p[c] - m[c]) / (2.0 * h)) as f32;
                }
            }
            g
        })
        .collect();
    let mut out = vec![0.0f32; before];
    out.extend(per_node.concat());
    out.resize(out.len() + after, 0.0);
    out
}

/// Eq. 4 of Kontkanen & Laine 2006 at world point `x`: `settings.samples` uniform
/// directions (an Owen-scrambled Halton stream chosen by `stream`), one path each (plus one
/// light sample when `settings.light_sampling`), exactly as the `point` bake does at a node.
/// Returns `3 · coeffs` coefficients `[coeff][rgb]`.
#[must_use]
pub fn point_projection(t: &Transport<'_>, settings: &BakeSettings, x: DVec3, stream: u64) -> Vec<f64> {
    point_projection_counted(t, settings, x, stream).0
}

/// [`point_projection`] with the rays it traced.
#[must_use]
pub fn point_projection_counted(
    t: &Transport<'_>,
    settings: &BakeSettings,
    x: DVec3,
    stream: u64,
) -> (Vec<f64>, BakeStats) {
    let bands = bands_of(settings.coeffs).unwrap_or(3);
    let h = Qmc::<2>::new(settings.seed, stream);
    let mut y = vec![0.0; settings.coeffs];
    let mut out = vec![0.0; settings.coeffs * 3];
    let mut stats = BakeStats::default();
    for s in 0..u64::from(settings.samples.get()) {
        let dir = DVec3::from_array(sample_uniform_sphere(h.point(s)));
        let mut rng = PathRng::new(settings.seed, stream, s);
        let hit = t.tracer().closest_hit(x, dir, 0.0, f64::INFINITY);
        // Gradient bakes are not split by light group (refused by the request).
        let (terms, n) = sample_terms(t, settings, x, dir, hit, &mut rng, &mut stats, &mut Vec::new());
        for (d, r) in &terms[..usize::from(n)] {
            eval_into(bands, d.to_array(), &mut y);
            for (j, yj) in y.iter().enumerate() {
                for ch in 0..3 {
                    out[3 * j + ch] += r[ch] * yj;
                }
            }
        }
    }
    let inv = 1.0 / f64::from(settings.samples.get());
    out.iter_mut().for_each(|v| *v *= inv);
    stats.rays.sampling += u64::from(settings.samples.get());
    (out, stats)
}

/// Estimator (a) on a scene: central differences of [`point_projection`]s at offset `h`
/// (world units; [`default_offset`] is the documented choice), common random numbers per
/// node. Uses `settings.samples` directions per projection, so `7 · samples` per node
/// counting the node's own.
///
/// # Errors
/// [`BakeError::Settings`] for a non-positive `h` or an unsupported
/// coefficient count, [`BakeError::Volume`] if `volume` is not on `grid`.
pub fn central_difference_gradients(
    t: &Transport<'_>,
    grid: &GridSpec,
    settings: &BakeSettings,
    h: f64,
    volume: &IrradianceVolume,
) -> Result<VolumeGradients, BakeError> {
    if !volume.spec().same_nodes(grid) || volume.coeffs() != settings.coeffs {
        return Err(BakeError::Volume("volume does not match the grid and coefficient count".into()));
    }
    let data = central_difference_data(t, grid, settings, h, 0..grid.node_count())?;
    VolumeGradients::new(volume, data).map_err(|e| BakeError::Volume(e.to_string()))
}

/// The raw gradient array `[node][coeff][rgb][xyz]` of [`central_difference_gradients`] for
/// the nodes in `nodes` (zero elsewhere): what one shard of a sharded bake computes
/// ([`lightvol_core::shard::shard_range`] over the nodes). Store it with [`attach_central`].
///
/// # Errors
/// As [`central_difference_gradients`].
pub fn central_difference_data(
    t: &Transport<'_>,
    grid: &GridSpec,
    settings: &BakeSettings,
    h: f64,
    nodes: std::ops::Range<usize>,
) -> Result<Vec<f32>, BakeError> {
    if !(h > 0.0) || bands_of(settings.coeffs).is_none() {
        return Err(BakeError::Settings(format!(
            "central differences need h > 0 (got {h}), 4/9/16 coeffs (got {})",
            settings.coeffs
        )));
    }
    Ok(central_differences_of(grid, settings.coeffs, h, nodes, |node, x| {
        point_projection(t, settings, x, hash2(node as u64, GRADIENT_STREAM))
    }))
}

/// Name of the central-difference gradients among an accumulator's auxiliary sums.
pub const CENTRAL_AUX: &str = "central-gradient-f32";

/// Stores a shard's central-difference gradients ([`central_difference_data`]) in `acc`'s
/// auxiliary sums: each f32's bit pattern as an integer (`0..2^32`). A node's gradient is
/// computed by exactly one shard and is zero in the others, so the exact integer sum of a
/// complete set is that shard's bit pattern: merging is lossless in any order.
pub fn attach_central(data: &[f32], acc: &mut Accumulator) {
    let raw = data.iter().map(|v| i128::from(v.to_bits())).collect();
    acc.set_aux(CENTRAL_AUX, FixedSums::from_raw(raw));
}

/// The gradients a sharded bake carries in its (merged) accumulator.
#[derive(Clone, Debug, PartialEq)]
pub enum ShardGradients {
    /// The basis estimator's exact sums, solved on the merged volume (boxed: they are
    /// much larger than the enum's other variant).
    Basis(Box<BasisGradientAccumulator>),
    /// The central-difference gradients, `[node][coeff][rgb][xyz]`.
    Central(Vec<f32>),
}

impl ShardGradients {
    /// The gradients attached to `acc` ([`BasisGradientAccumulator::attach_to`],
    /// [`attach_central`]), `Ok(None)` when it carries none.
    ///
    /// # Errors
    /// [`BakeError::Volume`] for central gradients whose merged values are not f32 bit
    /// patterns (the same node counted by two shards) or of the wrong length.
    pub fn from_accumulator(acc: &Accumulator) -> Result<Option<Self>, BakeError> {
        if let Some(b) = BasisGradientAccumulator::from_accumulator(acc) {
            return Ok(Some(Self::Basis(Box::new(b))));
        }
        let Some((name, all)) = acc.aux() else { return Ok(None) };
        if name != CENTRAL_AUX {
            return Ok(None);
        }
        let n = acc.spec().node_count() * acc.coeffs() * 9;
        if all.len() != n || all.first_poisoned().is_some() {
            return Err(BakeError::Volume(format!(
                "central gradients of {} values, expected {n}",
                all.len()
            )));
        }
        let data = all
            .raw()
            .iter()
            .map(|&v| u32::try_from(v).map(f32::from_bits))
            .collect::<Result<Vec<f32>, _>>()
            .map_err(|_| BakeError::Volume("central gradients counted twice for a node".into()))?;
        Ok(Some(Self::Central(data)))
    }

    /// Stores the gradients in `acc`'s auxiliary sums (for a shard file).
    pub fn attach_to(&self, acc: &mut Accumulator) {
        match self {
            Self::Basis(b) => b.attach_to(acc),
            Self::Central(data) => attach_central(data, acc),
        }
    }

    /// The gradients of `volume` (the merged bake's), with the basis solve's report (all
    /// nodes "solved" for central).
    ///
    /// # Errors
    /// [`BakeError::Volume`] when the gradients do not fit `volume`.
    pub fn finish(&self, volume: &IrradianceVolume) -> Result<(VolumeGradients, GradientReport), BakeError> {
        match self {
            Self::Basis(b) => b.finish(volume),
            Self::Central(data) => {
                let g = VolumeGradients::new(volume, data.clone())
                    .map_err(|e| BakeError::Volume(e.to_string()))?;
                Ok((g, GradientReport { solved: volume.spec().node_count(), singular: 0 }))
            }
        }
    }
}

/// How the basis-gradient solve went.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct GradientReport {
    /// Nodes whose 4×4 system was solved.
    pub solved: usize,
    /// Nodes with a singular system (no or too flat a sample cloud): zero gradient.
    pub singular: usize,
}

/// Estimator (b): the per-node sums of the Petrov-Galerkin system in the module docs,
/// `M_i = Σ_s w(x_s) [1, u_s − u_i]` (4×4) and `R_i = Σ_s w(x_s) f_sᵀ` (4 × 3·coeffs), with
/// `u` cell-local coordinates and `w = (b_i, ∂b_i/∂u)`. Sums over disjoint sample sets merge
/// by addition.
#[derive(Clone, Debug, PartialEq)]
pub struct BasisGradientAccumulator {
    grid: GridSpec,
    k: usize,
    /// Per node, the 4×4 system matrix (row-major), exact fixed-point sums.
    m: FixedSums,
    /// Per node, the 4 × k right-hand sides, exact fixed-point sums.
    r: FixedSums,
}

/// Name of the basis-gradient sums among an accumulator's auxiliary sums (shard files).
pub const GRADIENT_AUX: &str = "basis-gradient-4x4";

impl BasisGradientAccumulator {
    /// Empty sums for `grid` and `coeffs` SH coefficients per channel.
    #[must_use]
    pub fn new(grid: &GridSpec, coeffs: usize) -> Self {
        let n = grid.node_count();
        Self {
            grid: grid.clone(),
            k: coeffs * 3,
            m: FixedSums::zeros(n * 16),
            r: FixedSums::zeros(n * 4 * coeffs * 3),
        }
    }

    /// Stores the sums in `acc`'s auxiliary sums (for a shard file): every node's 16 matrix
    /// entries, then every node's `4k` right-hand sides.
    pub fn attach_to(&self, acc: &mut Accumulator) {
        let mut all = self.m.clone();
        all.extend_zeros(self.r.len());
        let at = self.m.len();
        for (i, &v) in self.r.raw().iter().enumerate() {
            all.add_raw(at + i, v);
        }
        if let Some(i) = self.r.first_poisoned() {
            all.add(at + i, f64::NAN);
        }
        acc.set_aux(GRADIENT_AUX, all);
    }

    /// The sums of a shard file (see [`Self::attach_to`]), or `None` when `acc` has none.
    #[must_use]
    pub fn from_accumulator(acc: &Accumulator) -> Option<Self> {
        let (name, all) = acc.aux()?;
        let n = acc.spec().node_count();
        let k = acc.coeffs() * 3;
        if name != GRADIENT_AUX || all.len() != n * 16 + n * 4 * k {
            return None;
        }
        let m = all.gather(0..n * 16);
        let r = all.gather(n * 16..all.len());
        Some(Self { grid: acc.spec().clone(), k, m, r })
    }

    /// Adds one cell sample: the cell's 8 corner nodes (corner `c = dx + 2dy + 4dz`), the
    /// sample's trilinear weights (from which its cell-local position is recovered, as
    /// `u_a = Σ_{c: bit a} b_c`) and its estimate `f` (`3 · coeffs` values `[coeff][rgb]`).
    pub fn add_sample(&mut self, nodes: [usize; 8], weights: [f64; 8], f: &[f64]) {
        let u: [f64; 3] =
            std::array::from_fn(|a| (0..8).filter(|c| (c >> a) & 1 == 1).map(|c| weights[c]).sum());
        let lin = |bit: usize, t: f64| if bit == 1 { t } else { 1.0 - t };
        for c in 0..8 {
            let bit = [c & 1, (c >> 1) & 1, (c >> 2) & 1];
            let l = [0, 1, 2].map(|a| lin(bit[a], u[a]));
            let s = [0, 1, 2].map(|a| if bit[a] == 1 { 1.0 } else { -1.0 });
            let w = [l[0] * l[1] * l[2], s[0] * l[1] * l[2], l[0] * s[1] * l[2], l[0] * l[1] * s[2]];
            // Position relative to this corner in cell units.
            let d = [1.0, u[0] - bit[0] as f64, u[1] - bit[1] as f64, u[2] - bit[2] as f64];
            let node = nodes[c];
            for (row, wr) in w.iter().enumerate() {
                for (col, dc) in d.iter().enumerate() {
                    self.m.add(node * 16 + 4 * row + col, wr * dc);
                }
            }
            let base = node * 4 * self.k;
            for (row, wr) in w.iter().enumerate() {
                for (j, fv) in f.iter().enumerate().take(self.k) {
                    self.r.add(base + row * self.k + j, wr * fv);
                }
            }
        }
    }

    /// Adds every kept sample of a bake unit (cells only).
    pub(crate) fn add_unit(&mut self, out: &UnitOut, bands: usize, y: &mut [f64], f: &mut [f64]) {
        for s in &out.samples {
            f.iter_mut().for_each(|v| *v = 0.0);
            for (d, r) in &s.terms[..usize::from(s.n_terms)] {
                eval_into(bands, d.to_array(), y);
                for (j, yj) in y.iter().enumerate() {
                    for ch in 0..3 {
                        f[3 * j + ch] += r[ch] * yj;
                    }
                }
            }
            self.add_sample(out.nodes, s.weights, f);
        }
    }

    /// Adds another accumulator's sums (same grid and coefficient count, else an error).
    ///
    /// # Errors
    /// [`BakeError::Volume`] on a grid or coefficient mismatch.
    pub fn merge(&mut self, other: &Self) -> Result<(), BakeError> {
        if other.grid != self.grid || other.k != self.k {
            return Err(BakeError::Volume("gradient accumulators of different grids".into()));
        }
        self.m.merge(&other.m);
        self.r.merge(&other.r);
        Ok(())
    }

    /// Solves every node's system and converts the cell-local gradient to world units
    /// (`∇_x f = Σ_a (∂f/∂u_a) ∇u_a`, `∇u_a` the rows of the inverse cell-edge matrix).
    ///
    /// # Errors
    /// [`BakeError::Volume`] if `volume` is not on this grid with this coefficient count.
    pub fn finish(&self, volume: &IrradianceVolume) -> Result<(VolumeGradients, GradientReport), BakeError> {
        if !volume.spec().same_nodes(&self.grid) || volume.coeffs() * 3 != self.k {
            return Err(BakeError::Volume("volume does not match the gradient accumulator".into()));
        }
        let inv = inverse3(cell_edges(&self.grid));
        let k = self.k;
        let nodes = self.m.len() / 16;
        let mut data = vec![0.0f32; nodes * k * 3];
        let mut report = GradientReport::default();
        for node in 0..nodes {
            let r: Vec<f64> = (node * 4 * k..(node + 1) * 4 * k).map(|i| self.r.get(i)).collect();
            let m: [f64; 16] = std::array::from_fn(|j| self.m.get(node * 16 + j));
            let Some(x) = solve4(m, &r, k) else {
                report.singular += 1;
                continue;
            };
            report.solved += 1;
            for c in 0..k {
                let gu = [x[k + c], x[2 * k + c], x[3 * k + c]];
                for a in 0..3 {
                    let g = gu[0] * inv[0][a] + gu[1] * inv[1][a] + gu[2] * inv[2][a];
                    data[(node * k + c) * 3 + a] = g as f32;
                }
            }
        }
        let grads = VolumeGradients::new(volume, data).map_err(|e| BakeError::Volume(e.to_string()))?;
        Ok((grads, report))
    }
}

/// Inverse of the matrix whose columns are `e[0], e[1], e[2]`; row `a` is `∇u_a`.
fn inverse3(e: [DVec3; 3]) -> [[f64; 3]; 3] {
    let m = glam::DMat3::from_cols(e[0], e[1], e[2]).inverse();
    // m.row(a) = ∇u_a.
    std::array::from_fn(|a| m.row(a).to_array())
}

/// Solves `M X = R` (M 4×4 row-major, R 4 × k row-major) by Gaussian elimination with
/// partial pivoting; `None` when a pivot falls below [`MIN_RELATIVE_PIVOT`].
fn solve4(mut m: [f64; 16], r: &[f64], k: usize) -> Option<Vec<f64>> {
    let mut x = r.to_vec();
    let scale = m.iter().fold(0.0f64, |s, v| s.max(v.abs()));
    if !(scale > 0.0) {
        return None;
    }
    for col in 0..4 {
        let p = (col..4).max_by(|&a, &b| m[4 * a + col].abs().total_cmp(&m[4 * b + col].abs()))?;
        if !(m[4 * p + col].abs() > MIN_RELATIVE_PIVOT * scale) {
            return None;
        }
        if p != col {
            for j in 0..4 {
                m.swap(4 * p + j, 4 * col + j);
            }
            for j in 0..k {
                x.swap(p * k + j, col * k + j);
            }
        }
        for row in 0..4 {
            if row == col {
                continue;
            }
            let f = m[4 * row + col] / m[4 * col + col];
            if f == 0.0 {
                continue;
            }
            for j in col..4 {
                m[4 * row + j] -= f * m[4 * col + j];
            }
            for j in 0..k {
                x[row * k + j] -= f * x[col * k + j];
            }
        }
    }
    for row in 0..4 {
        let d = m[4 * row + row];
        x[row * k..(row + 1) * k].iter_mut().for_each(|v| *v /= d);
    }
    Some(x)
}

/// A cell bake (`prefilter` or `doi`) that also fills a [`BasisGradientAccumulator`] from the
/// same kept samples, in the bake's unit order (deterministic like the bake).
///
/// # Errors
/// Those of [`crate::bake()`]; [`BakeError::Settings`] for [`Method::Point`] (point samples sit
/// on the nodes and span no volume).
pub fn bake_with_gradients(
    t: &Transport<'_>,
    grid: &GridSpec,
    settings: &BakeSettings,
    control: &BakeControl<'_>,
) -> Result<(BakeOutput, BasisGradientAccumulator), BakeError> {
    if matches!(settings.method, Method::Point | Method::DoiNode | Method::Doi) {
        return Err(BakeError::Settings(
            "the basis-gradient estimator needs cell samples (prefilter, doi)".into(),
        ));
    }
    let bands = bands_of(settings.coeffs)
        .ok_or_else(|| BakeError::Settings(format!("{} coefficients", settings.coeffs)))?;
    let mut acc = BasisGradientAccumulator::new(grid, settings.coeffs);
    let mut y = vec![0.0; settings.coeffs];
    let mut f = vec![0.0; settings.coeffs * 3];
    let out = bake_with_sink(t, grid, settings, control, |u| acc.add_unit(u, bands, &mut y, &mut f))?;
    Ok((out, acc))
}

/// An analytic radiance field `L(x, ω)` (world point, unit direction) -> RGB.
pub trait RadianceField: Sync {
    /// Radiance arriving at `x` from direction `dir`.
    fn radiance(&self, x: DVec3, dir: DVec3) -> [f64; 3];
}

impl<F: Fn(DVec3, DVec3) -> [f64; 3] + Sync> RadianceField for F {
    fn radiance(&self, x: DVec3, dir: DVec3) -> [f64; 3] {
        self(x, dir)
    }
}

/// [`point_projection`] of an analytic field (validation): `samples` uniform directions of
/// the stream `stream`, `3 · coeffs` coefficients `[coeff][rgb]`.
#[must_use]
pub fn point_projection_field(
    field: &impl RadianceField,
    x: DVec3,
    coeffs: usize,
    samples: u32,
    seed: u64,
    stream: u64,
) -> Vec<f64> {
    let bands = bands_of(coeffs).unwrap_or(3);
    let h = Qmc::<2>::new(seed, stream);
    let mut y = vec![0.0; coeffs];
    let mut out = vec![0.0; coeffs * 3];
    for s in 0..u64::from(samples) {
        let dir = DVec3::from_array(sample_uniform_sphere(h.point(s)));
        let l = field.radiance(x, dir);
        eval_into(bands, dir.to_array(), &mut y);
        for (j, yj) in y.iter().enumerate() {
            for ch in 0..3 {
                out[3 * j + ch] += 4.0 * std::f64::consts::PI * l[ch] * yj;
            }
        }
    }
    out.iter_mut().for_each(|v| *v /= f64::from(samples));
    out
}

/// A `prefilter` bake (Eq. 5-6, no domain test) of an analytic field with the bake's sample
/// layout (per cell one 5-D scrambled Halton stream: 3 position, 2 direction dimensions),
/// filling both the Eq. 6 accumulator and a [`BasisGradientAccumulator`] (validation).
///
/// # Errors
/// [`BakeError::Volume`] for an unsupported coefficient count.
pub fn bake_field_with_gradients(
    field: &impl RadianceField,
    grid: &GridSpec,
    coeffs: usize,
    samples: u32,
    seed: u64,
) -> Result<(Accumulator, BasisGradientAccumulator), BakeError> {
    let mut acc = Accumulator::new(grid.clone(), coeffs).map_err(|e| BakeError::Volume(e.to_string()))?;
    let mut gacc = BasisGradientAccumulator::new(grid, coeffs);
    let bands = bands_of(coeffs).unwrap_or(3);
    type Sample = ([f64; 8], [f64; 3], Vec<f64>);
    let units: Vec<Vec<Sample>> = (0..grid.cell_count())
        .into_par_iter()
        .map(|cell| {
            let (lo, hi) = grid.cell_bounds(cell);
            let h = Qmc::<5>::new(seed, cell as u64);
            let mut y = vec![0.0; coeffs];
            (0..u64::from(samples))
                .map(|s| {
                    let p = h.point(s);
                    let g: [f64; 3] = std::array::from_fn(|a| lo[a] + (hi[a] - lo[a]) * p[a]);
                    let w = lightvol_volume::grid::corner_weights([p[0], p[1], p[2]]);
                    let dir = DVec3::from_array(sample_uniform_sphere([p[3], p[4]]));
                    let l = field.radiance(DVec3::from_array(grid.to_world(g)), dir);
                    eval_into(bands, dir.to_array(), &mut y);
                    (w, l.map(|v| 4.0 * std::f64::consts::PI * v), y.clone())
                })
                .collect()
        })
        .collect();
    for (cell, samples) in units.iter().enumerate() {
        let nodes = grid.cell_corners(cell);
        for (w, r, y) in samples {
            for c in 0..8 {
                if w[c] > 0.0 {
                    acc.add(nodes[c], w[c], *r, y);
                }
            }
            let f: Vec<f64> = (0..coeffs * 3).map(|m| r[m % 3] * y[m / 3]).collect();
            gacc.add_sample(nodes, *w, &f);
        }
    }
    Ok((acc, gacc))
}

#[cfg(test)]
#[path = "gradient_bake_tests.rs"]
mod tests;
