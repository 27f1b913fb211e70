//! Least-squares node values over the domain of interest: the consistent-mass variant of
//! Kontkanen & Laine 2006 Eq. 5-6.
//!
//! Eq. 6 gives each node the trilinear-weighted *average* of the radiance over its support
//! restricted to the domain of interest Δ:
//! `c_i = ∫_Δ b_i L / ∫_Δ b_i`. Reconstructing with the same trilinear functions then
//! filters the field twice (once by the weighting, once by the interpolation): features
//! smaller than two cells, such as a sun patch under a window, are smeared.
//!
//! The values that minimise the reconstruction error *over Δ*,
//! `min_c ∫_Δ (Σ_i c_i b_i(x) − L(x))² dx`, solve the normal equations `M c = r` with the
//! mass matrix `M_ij = ∫_Δ b_i b_j` and the same right-hand side `r_i = ∫_Δ b_i L` as Eq. 6.
//! Eq. 6 is the *lumped* version of this system (`M` replaced by its row sums
//! `m_i = Σ_j M_ij = ∫_Δ b_i`), which is why it blurs. Both `M` and `r` are estimated from
//! the very samples of the domain-of-interest bake (`M_ij ≈ Σ_s b_i(x_s) b_j(x_s)`, with the
//! same normalisation as the accumulator's sums), so no extra ray is traced.
//!
//! Near the boundary of Δ a node may see only a sliver of its support, and `M` becomes
//! ill-conditioned there; Monte Carlo noise is also amplified by the deconvolution. The
//! fit is therefore regularised toward Eq. 6:
//! `min_c ‖Σ c_i b_i − L‖²_Δ + λ Σ_i m_i (c_i − ĉ_i)²` with `ĉ_i = r_i / m_i`, i.e.
//! `(M + λ diag(m)) c = (1 + λ) r`. `λ → ∞` gives back Eq. 6 exactly; `λ = 0` is the pure
//! least-squares fit. The system is symmetric positive definite (for `λ > 0`) with at most
//! 27 non-zeros per row and is solved per coefficient by Jacobi-preconditioned conjugate
//! gradients, in a fixed order (deterministic for any thread count).

use lightvol_volume::FillReport;
use lightvol_volume::fixed::FixedSums;
use lightvol_volume::{Accumulator, GridSpec, IrradianceVolume};
use rayon::prelude::*;

use crate::bake::{BakeOutput, bake_with_sink};
use crate::error::BakeError;
use crate::method::Method;
use crate::settings::BakeSettings;
use crate::stats::BakeStats;
use crate::unit::UnitOut;
use lightvol_core::progress::BakeControl;
use lightvol_scene::transport::Transport;

/// Regularisation weight λ used by default. Chosen on the built-in scenes (see the sampler
/// README): small enough to sharpen sub-cell features, large enough that sliver nodes at
/// the boundary of the domain stay within the range of their neighbours.
pub const DEFAULT_LAMBDA: f64 = 0.25;

/// Relative residual at which conjugate gradients stop. The stored values are f32 (relative
/// precision 6e-8); 1e-9 leaves the solver error well below that.
const CG_TOLERANCE: f64 = 1e-9;

/// Iteration cap; the regularised system's condition number is at most `(1 + λ) / λ` times
/// that of Eq. 6's diagonal system scaled by the 27-point stencil, so convergence takes a
/// few dozen iterations; the cap only guards against a broken input.
const CG_MAX_ITERATIONS: usize = 500;

/// How node values are obtained from the accumulated sums.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Fit {
    /// Eq. 6: `c_i = r_i / m_i` (the paper).
    Average,
    /// Regularised least squares over the domain of interest with weight λ (see module docs).
    LeastSquares {
        /// Regularisation weight λ ≥ 0.
        lambda: f64,
    },
}

impl Default for Fit {
    fn default() -> Self {
        Self::LeastSquares { lambda: DEFAULT_LAMBDA }
    }
}

/// The name [`FromStr`](std::str::FromStr) accepts: `average` or `lsq:LAMBDA`.
impl std::fmt::Display for Fit {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Average => f.write_str("average"),
            Self::LeastSquares { lambda } => write!(f, "lsq:{lambda}"),
        }
    }
}

impl std::str::FromStr for Fit {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "average" => Ok(Self::Average),
            "lsq" => Ok(Self::default()),
            _ => match s.strip_prefix("lsq:").map(str::parse::<f64>) {
                Some(Ok(lambda)) if lambda >= 0.0 && lambda.is_finite() => Ok(Self::LeastSquares { lambda }),
                _ => Err(format!("unknown fit '{s}' (average, lsq or lsq:LAMBDA with LAMBDA >= 0)")),
            },
        }
    }
}

/// Index of the neighbour offset `d ∈ {-1,0,1}³` in a row of [`MassMatrix`].
fn offset_slot(d: [i64; 3]) -> usize {
    ((d[0] + 1) * 9 + (d[1] + 1) * 3 + (d[2] + 1)) as usize
}

/// The sampled mass matrix `M_ij = Σ_s b_i(x_s) b_j(x_s)`: for every node, the 27 entries of
/// its neighbours (offsets in `{-1,0,1}³`, slot `9(dx+1) + 3(dy+1) + (dz+1)`). The sums are
/// exact fixed-point integers (`lightvol_volume::fixed`), like the accumulator's, so the
/// matrices of shards merge into the whole bake's bit for bit.
#[derive(Clone, Debug, PartialEq)]
pub struct MassMatrix {
    res: [usize; 3],
    sums: FixedSums,
}

/// Integer grid coordinates of flat node index `node` (x fastest), as
/// `GridSpec::node_coords` gives them, for the matrices that keep only the resolution.
fn node_coords(res: [usize; 3], node: usize) -> [i64; 3] {
    let i = node % res[0];
    let j = (node / res[0]) % res[1];
    let k = node / (res[0] * res[1]);
    [i as i64, j as i64, k as i64]
}

/// Name of the mass matrix among an accumulator's auxiliary sums (shard files).
pub const MASS_AUX: &str = "lsq-mass-27";

impl MassMatrix {
    /// An all-zero matrix for `grid`'s nodes.
    #[must_use]
    pub fn new(grid: &GridSpec) -> Self {
        let r = grid.res();
        Self { res: r.map(|v| v as usize), sums: FixedSums::zeros(grid.node_count() * 27) }
    }

    /// The matrix of a shard file: the auxiliary sums of `acc` named [`MASS_AUX`], or
    /// `None` when it has none (or they do not fit its grid).
    #[must_use]
    pub fn from_accumulator(acc: &Accumulator) -> Option<Self> {
        let (name, sums) = acc.aux()?;
        let r = acc.spec().res();
        (name == MASS_AUX && sums.len() == acc.spec().node_count() * 27)
            .then(|| Self { res: r.map(|v| v as usize), sums: sums.clone() })
    }

    /// Stores the matrix in `acc`'s auxiliary sums (for a shard file).
    pub fn attach_to(&self, acc: &mut Accumulator) {
        acc.set_aux(MASS_AUX, self.sums.clone());
    }

    /// Row `node`: its 27 neighbour entries as f64.
    #[must_use]
    pub fn row(&self, node: usize) -> [f64; 27] {
        std::array::from_fn(|j| self.sums.get(node * 27 + j))
    }

    fn node_count(&self) -> usize {
        self.sums.len() / 27
    }

    fn coords(&self, node: usize) -> [i64; 3] {
        node_coords(self.res, node)
    }

    /// Adds one kept sample with the trilinear weights `w` of the 8 corners `nodes` of its
    /// cell.
    pub fn add_sample(&mut self, nodes: &[usize; 8], w: &[f64; 8]) {
        for a in 0..8 {
            if w[a] <= 0.0 {
                continue;
            }
            let ca = self.coords(nodes[a]);
            for b in 0..8 {
                if w[b] <= 0.0 {
                    continue;
                }
                let cb = self.coords(nodes[b]);
                let slot = offset_slot([cb[0] - ca[0], cb[1] - ca[1], cb[2] - ca[2]]);
                self.sums.add(nodes[a] * 27 + slot, w[a] * w[b]);
            }
        }
    }

    pub(crate) fn add_unit(&mut self, out: &UnitOut) {
        for s in &out.samples {
            self.add_sample(&out.nodes, &s.weights);
        }
    }

    /// Adds another shard's matrix (same grid).
    ///
    /// # Errors
    /// [`BakeError::Settings`] if the grids differ.
    pub fn merge(&mut self, other: &Self) -> Result<(), BakeError> {
        if self.res != other.res {
            return Err(BakeError::Settings("cannot merge mass matrices of different grids".into()));
        }
        self.sums.merge(&other.sums);
        Ok(())
    }

    /// Row sum `m_i = Σ_j M_ij` (equals Eq. 6's denominator, since the trilinear weights of
    /// a point sum to one).
    #[must_use]
    pub fn row_sum(&self, node: usize) -> f64 {
        self.row(node).iter().sum()
    }

    /// Every row as f64, for the solver's matrix-vector products.
    fn dense(&self) -> DenseMass {
        DenseMass { res: self.res, rows: (0..self.node_count()).map(|i| self.row(i)).collect() }
    }
}

/// The mass matrix converted once to f64 for the conjugate-gradient iterations.
struct DenseMass {
    res: [usize; 3],
    rows: Vec<[f64; 27]>,
}

impl DenseMass {
    fn coords(&self, node: usize) -> [i64; 3] {
        node_coords(self.res, node)
    }

    fn row_sum(&self, node: usize) -> f64 {
        self.rows[node].iter().sum()
    }

    /// `y = (M + λ diag(m)) x` restricted to `active` nodes (others read as 0).
    fn apply(&self, lambda: f64, active: &[bool], x: &[f64], y: &mut [f64]) {
        let [nx, ny, nz] = self.res.map(|v| v as i64);
        for (node, out) in y.iter_mut().enumerate() {
            if !active[node] {
                *out = 0.0;
                continue;
            }
            let c = self.coords(node);
            let row = &self.rows[node];
            let mut acc = 0.0;
            let mut sum = 0.0;
            for dx in -1..=1 {
                for dy in -1..=1 {
                    for dz in -1..=1 {
                        let m = row[offset_slot([dx, dy, dz])];
                        sum += m;
                        if m == 0.0 {
                            continue;
                        }
                        let (i, j, k) = (c[0] + dx, c[1] + dy, c[2] + dz);
                        if i < 0 || j < 0 || k < 0 || i >= nx || j >= ny || k >= nz {
                            continue;
                        }
                        let n = (i + nx * (j + ny * k)) as usize;
                        acc += m * x[n];
                    }
                }
            }
            *out = acc + lambda * sum * x[node];
        }
    }
}

/// What the least-squares solve did.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FitReport {
    /// Nodes solved for (a positive, finite Eq. 6 denominator and finite sums).
    pub active_nodes: usize,
    /// Largest number of conjugate-gradient iterations over the coefficient channels.
    pub max_iterations: usize,
    /// Largest final relative residual over the channels.
    pub max_relative_residual: f64,
}

/// Solves `(M + λ diag(m)) c = (1 + λ) r` for every coefficient channel of `acc`, returning
/// the node values (`[node][coeff][rgb]`, zero at inactive nodes) and the solver report.
///
/// # Errors
/// [`BakeError::Settings`] if the matrix and accumulator grids differ or λ is negative.
pub fn solve_least_squares(
    mass: &MassMatrix,
    acc: &Accumulator,
    lambda: f64,
) -> Result<(Vec<f64>, FitReport), BakeError> {
    let n = acc.spec().node_count();
    if mass.node_count() != n {
        return Err(BakeError::Settings("mass matrix and accumulator grids differ".into()));
    }
    if !(lambda >= 0.0 && lambda.is_finite()) {
        return Err(BakeError::Settings(format!("least-squares λ must be >= 0 (got {lambda})")));
    }
    let k = acc.coeffs() * 3;
    let den = acc.denominator();
    let num = acc.numerator();
    let active = active_nodes(acc);
    let dense = mass.dense();
    let diag: Vec<f64> =
        (0..n)
            .map(|i| {
                if active[i] {
                    dense.rows[i][offset_slot([0, 0, 0])] + lambda * dense.row_sum(i)
                } else {
                    1.0
                }
            })
            .collect();
    let columns: Vec<(Vec<f64>, usize, f64)> = (0..k)
        .into_par_iter()
        .map(|ch| {
            let b: Vec<f64> =
                (0..n).map(|i| if active[i] { (1.0 + lambda) * num[i * k + ch] } else { 0.0 }).collect();
            // Start from Eq. 6.
            let x0: Vec<f64> =
                (0..n).map(|i| if active[i] { num[i * k + ch] / den[i] } else { 0.0 }).collect();
            conjugate_gradient(&dense, lambda, &active, &diag, &b, x0)
        })
        .collect();
    let mut values = vec![0.0; n * k];
    let mut report =
        FitReport { active_nodes: active.iter().filter(|&&a| a).count(), ..FitReport::default() };
    for (ch, (x, it, res)) in columns.into_iter().enumerate() {
        for i in 0..n {
            values[i * k + ch] = x[i];
        }
        report.max_iterations = report.max_iterations.max(it);
        report.max_relative_residual = report.max_relative_residual.max(res);
    }
    Ok((values, report))
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// Jacobi-preconditioned conjugate gradients; returns `(x, iterations, relative residual)`.
fn conjugate_gradient(
    mass: &DenseMass,
    lambda: f64,
    active: &[bool],
    diag: &[f64],
    b: &[f64],
    mut x: Vec<f64>,
) -> (Vec<f64>, usize, f64) {
    let n = b.len();
    let b_norm = dot(b, b).sqrt();
    if b_norm == 0.0 {
        return (vec![0.0; n], 0, 0.0);
    }
    let mut ax = vec![0.0; n];
    mass.apply(lambda, active, &x, &mut ax);
    let mut r: Vec<f64> = b.iter().zip(&ax).map(|(b, a)| b - a).collect();
    let mut z: Vec<f64> = r.iter().zip(diag).map(|(r, d)| r / d).collect();
    let mut p = z.clone();
    let mut rz = dot(&r, &z);
    let mut ap = vec![0.0; n];
    let mut it = 0;
    let mut res = dot(&r, &r).sqrt() / b_norm;
    while res > CG_TOLERANCE && it < CG_MAX_ITERATIONS {
        mass.apply(lambda, active, &p, &mut ap);
        let pap = dot(&p, &ap);
        if !(pap > 0.0) {
            break;
        }
        let alpha = rz / pap;
        for i in 0..n {
            x[i] += alpha * p[i];
            r[i] -= alpha * ap[i];
        }
        for i in 0..n {
            z[i] = r[i] / diag[i];
        }
        let rz_new = dot(&r, &z);
        let beta = rz_new / rz;
        rz = rz_new;
        for i in 0..n {
            p[i] = z[i] + beta * p[i];
        }
        it += 1;
        res = dot(&r, &r).sqrt() / b_norm;
    }
    (x, it, res)
}

/// The nodes the least-squares system solves for: a positive, finite Eq. 6 denominator and
/// finite sums (a NaN radiance from a broken scene must not spread through the solve).
fn active_nodes(acc: &Accumulator) -> Vec<bool> {
    let k = acc.coeffs() * 3;
    let (den, num) = (acc.denominator(), acc.numerator());
    (0..den.len())
        .map(|i| den[i] > 0.0 && den[i].is_finite() && num[i * k..(i + 1) * k].iter().all(|v| v.is_finite()))
        .collect()
}

/// Turns the least-squares node values into a volume exactly as
/// [`Accumulator::finalize`] does for Eq. 6 (same weights, same zeroing of non-finite
/// values, same fill of nodes without an estimate). Nodes left out of the solve keep their
/// Eq. 6 values, so a NaN sum is zeroed and counted as it would be there.
#[must_use]
pub fn finalize_least_squares(acc: &Accumulator, mut values: Vec<f64>) -> (IrradianceVolume, FillReport) {
    let (average, weights, non_finite) = acc.estimates();
    let k = acc.coeffs() * 3;
    for (i, active) in active_nodes(acc).into_iter().enumerate() {
        if !active {
            values[i * k..(i + 1) * k].copy_from_slice(&average[i * k..(i + 1) * k]);
        }
    }
    acc.volume_from(values, &weights, non_finite)
}

/// A whole or sharded bake that also accumulates the [`MassMatrix`] of its kept samples
/// (the input of [`solve_least_squares`]); the accumulator is exactly [`crate::bake()`]'s.
///
/// # Errors
/// As [`crate::bake()`].
pub fn bake_with_mass(
    transport: &Transport<'_>,
    grid: &GridSpec,
    settings: &BakeSettings,
    control: &BakeControl<'_>,
) -> Result<(BakeOutput, MassMatrix), BakeError> {
    let mut mass = MassMatrix::new(grid);
    let out = bake_with_sink(transport, grid, settings, control, |u| mass.add_unit(u))?;
    Ok((out, mass))
}

/// A whole (unsharded) bake with the chosen [`Fit`]. For [`Method::Point`] or
/// [`Fit::Average`] this is [`crate::bake()`] followed by `finish` (a [`Method::Doi`] volume carries the node reach the
/// bake recorded, [`crate::reach`]).
///
/// # Errors
/// As [`crate::bake()`]; [`BakeError::Settings`] for least squares with
/// [`Method::DoiNode`] (its samples do not spread over a cell's corners).
pub fn bake_fitted(
    transport: &Transport<'_>,
    grid: &GridSpec,
    settings: &BakeSettings,
    control: &BakeControl<'_>,
    fit: Fit,
) -> Result<(IrradianceVolume, BakeStats, Option<FitReport>), BakeError> {
    match (settings.method, fit) {
        (Method::DoiNode | Method::Doi, Fit::LeastSquares { .. }) => Err(BakeError::Settings(
            "least-squares fits need cell samples (prefilter, doi-paper); doi and doi-node sample per node"
                .into(),
        )),
        (Method::Point, _) | (_, Fit::Average) => {
            let (v, s) = crate::bake::bake(transport, grid, settings, control)?.finish();
            Ok((v, s, None))
        }
        (_, Fit::LeastSquares { lambda }) => {
            let (out, mass) = bake_with_mass(transport, grid, settings, control)?;
            let (values, report) = solve_least_squares(&mass, &out.accumulator, lambda)?;
            let (volume, _) = finalize_least_squares(&out.accumulator, values);
            let (_, stats) = out.finish();
            Ok((volume, stats, Some(report)))
        }
    }
}

#[cfg(test)]
#[path = "node_fit_tests.rs"]
mod tests;
