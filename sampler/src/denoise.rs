//! Noise-weighted smoothing of a `doi` bake's node values, the first step of a fit for an
//! engine's lookup (the `target` module).
//!
//! ## Why
//!
//! The fit moves the bake's light into the engine's reconstruction: its data are the bake's
//! own reading, so a node's Monte Carlo noise reaches the engine's frame twice (in the
//! values the fit starts from and in the values it aims at). Where a scene is lit through
//! small openings (a window behind slats), a node's estimate at a few hundred samples is
//! off by tens of percent, while its neighbours, which see the same opening, are off in
//! other directions: the engine draws the noise as blotches. Smoothing every node alike
//! removes them but blurs the light wherever it is sharp and well sampled (a sunlit street
//! beside a shadow).
//!
//! ## The estimate
//!
//! Each node's own error is known: its samples' prefix estimate of the relative error of
//! their mean ([`crate::noise`], `ê_i`, from the bake). With `m_i` the luminance of node
//! `i`'s constant coefficient, `σ_i = ê_i m_i` is its estimate's standard error, and the
//! smoothed values are the maximum a posteriori estimate under a Gaussian smoothness prior
//! (a Gaussian Markov random field over the grid, \[RH05\] §3):
//!
//! `min_c Σ_i ‖c_i − ĉ_i‖² / σ̄_i² + Σ_(i,j) ‖c_i − c_j‖² / (τ m_ij)²`
//!
//! over the edges `(i, j)` between grid neighbours, `m_ij = (m̄_i + m̄_j) / 2`: neighbours are
//! expected to differ by a fraction `τ` of their light ([`DEFAULT_SMOOTHING`]). Where the
//! errors are small against `τ` the nodes keep their values; where they are large the nodes
//! take their neighbours'. The same weights serve every SH coefficient and colour channel
//! (uniform directions give every coefficient's estimate an error of the same order as the
//! constant one's).
//!
//! **Pooled over the neighbourhood.** `σ̄_i²` and `m̄_i` are the means of `σ_j²` and `m_j` over
//! node `i` and its six grid neighbours (those with samples; with a known error for
//! `σ̄`), not node `i`'s own. A node's own error estimate is largest exactly when its
//! samples caught a rare bright path, and its own light is lowest when they caught none:
//! weighting each node by its own estimates pulls the lucky nodes down toward their
//! neighbours and trusts the unlucky ones, and the smoothed light is darker than the bake's
//! (the smoothing keeps the `1/σ²`-weighted sum of the values, and those weights are then
//! smallest on the bright nodes; test `skewed_noise_keeps_its_mean`: 13.5% darker with
//! each node's own estimates, 1.6% with the pooled ones). On the Breakfast Room at 128
//! samples, read through the trilinear lookup, each node's own estimates left the plate 7%
//! too dark (bias −0.070, relative error 0.285 at τ = 0.3); the pooled ones give bias
//! +0.054 / 0.000 and relative error 0.259 / 0.257 (seeds 1 / 2, τ = 0.5; sampler README).
//!
//! **Which nodes and edges.** Only nodes with samples of their own (the validity mask the
//! fit takes) and a known, positive error and light are smoothed; the others keep their
//! values, and those with samples anchor their neighbours. An edge joins two such nodes
//! only where neither sees a surface along it (the node reach, [`lightvol_volume::reach`]:
//! both reach the full cell): light across a wall, a floor or an object's face may differ
//! by any amount, and it is exactly there that `doi` keeps each side's own light. Without
//! a reach every edge between nodes with samples counts.
//!
//! The system is symmetric positive definite (each unknown carries `1/σ_i² > 0`) and is
//! solved by conjugate gradients (the crate's `cg` module) in a fixed order, so the result is
//! bit-identical for any thread count.

use lightvol_scene::envmap::luminance;
use lightvol_volume::validity::ValidityMask;
use lightvol_volume::{GridSpec, IrradianceVolume};

use crate::error::BakeError;

/// Default `τ`: the relative difference between neighbouring nodes' light the prior
/// expects. Measured on the eight scenes of the README's method table at 128 samples
/// through three.js's, Bevy's and a plain trilinear lookup, with the pooled errors, at
/// τ = 0.2, 0.3, 0.5 and 0.7 (sampler README, "Noisy nodes first"): 0.2 blurs the sharp
/// light of the interior (its plate error rose from 0.20 to 0.27), 0.7 leaves more of the
/// Breakfast Room's noise; 0.5 gave the lowest means through Bevy's and the trilinear
/// lookup, and three.js's within 0.3% of 0.3's.
pub const DEFAULT_SMOOTHING: f64 = 0.5;

/// What the smoothing did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SmoothingReport {
    /// Nodes whose values were smoothed (the unknowns).
    pub nodes: usize,
    /// Edges between neighbours that the prior joins.
    pub edges: usize,
    /// Conjugate-gradient iterations.
    pub iterations: usize,
    /// The median of the smoothed nodes' estimated relative errors `ê_i`.
    pub median_error: f64,
}

/// The luminance of a node's constant coefficient (`[coeff][rgb]` values), the quantity
/// whose relative error the bake estimates ([`crate::noise`]).
fn light_of(values: &[f32]) -> f64 {
    luminance([0, 1, 2].map(|ch| f64::from(values[ch])))
}

/// The mean of `value` over node `i` and its six grid neighbours (fewer at the grid's
/// faces), over those where it is `Some`; `value(i)` must be `Some`.
fn neighbourhood_mean(spec: &GridSpec, i: usize, value: impl Fn(usize) -> Option<f64>) -> f64 {
    let at = spec.node_coords(i);
    let res = spec.res();
    let (mut sum, mut n) = (0.0, 0.0);
    let mut add = |node: usize| {
        if let Some(v) = value(node) {
            sum += v;
            n += 1.0;
        }
    };
    add(i);
    for a in 0..3 {
        if at[a] > 0 {
            let mut c = at;
            c[a] -= 1;
            add(spec.node_index(c[0], c[1], c[2]));
        }
        if at[a] + 1 < res[a] {
            let mut c = at;
            c[a] += 1;
            add(spec.node_index(c[0], c[1], c[2]));
        }
    }
    sum / n
}

/// `volume`'s node values smoothed under their estimated errors `node_error` (one per node,
/// NaN where unknown; module docs) with the prior's relative difference `tau`, over the
/// nodes `valid` marks as having samples of their own. Everything but the node values
/// (grid, metadata, validity, reach) is kept.
///
/// # Errors
/// [`BakeError::Settings`] for a `tau` that is not positive and finite, or an error list
/// or mask of the wrong length.
pub fn smooth_by_noise(
    volume: &IrradianceVolume,
    valid: &ValidityMask,
    node_error: &[f32],
    tau: f64,
) -> Result<(IrradianceVolume, SmoothingReport), BakeError> {
    let spec = volume.spec();
    let nodes = spec.node_count();
    if !(tau > 0.0 && tau.is_finite()) {
        return Err(BakeError::Settings(format!("the smoothing τ must be positive (got {tau})")));
    }
    if node_error.len() != nodes || valid.len() != nodes {
        return Err(BakeError::Settings(format!(
            "{} node errors and a mask of {} nodes for {nodes} nodes",
            node_error.len(),
            valid.len()
        )));
    }
    let k = 3 * volume.coeffs();
    let light: Vec<f64> = (0..nodes).map(|i| light_of(volume.node(i))).collect();
    let anchored = |i: usize| valid.is_valid(i) && light[i] > 0.0;
    // Each node's own variance σ_i², where known.
    let own_var: Vec<Option<f64>> = (0..nodes)
        .map(|i| {
            let e = f64::from(node_error[i]);
            (anchored(i) && e > 0.0 && e.is_finite()).then(|| (e * light[i]).powi(2))
        })
        .collect();
    // Inverse pooled variances 1/σ̄_i² of the unknowns; 0 for the nodes kept as they are.
    let inv_var: Vec<f64> = (0..nodes)
        .map(|i| match own_var[i] {
            Some(_) => 1.0 / neighbourhood_mean(spec, i, |j| own_var[j]),
            None => 0.0,
        })
        .collect();
    let free = |i: usize| inv_var[i] > 0.0;
    // Pooled light m̄_i of the nodes with samples and light (the prior's scale).
    let pooled_light: Vec<f64> =
        (0..nodes)
            .map(|i| {
                if anchored(i) {
                    neighbourhood_mean(spec, i, |j| anchored(j).then_some(light[j]))
                } else {
                    0.0
                }
            })
            .collect();
    // Edges (i, j, γ_ij) with at least one end free, both ends with samples and light, and
    // no surface along the edge.
    let res = spec.res();
    let reach = volume.reach();
    let mut edges = Vec::new();
    for i in 0..nodes {
        let at = spec.node_coords(i);
        for a in 0..3 {
            if at[a] + 1 >= res[a] {
                continue;
            }
            let mut next = at;
            next[a] += 1;
            let j = spec.node_index(next[0], next[1], next[2]);
            if !(anchored(i) && anchored(j)) || !(free(i) || free(j)) {
                continue;
            }
            if reach.is_some_and(|r| r.node(i)[2 * a] < 1.0 || r.node(j)[2 * a + 1] < 1.0) {
                continue;
            }
            let m = 0.5 * (pooled_light[i] + pooled_light[j]);
            edges.push((i, j, 1.0 / (tau * m).powi(2)));
        }
    }
    let x0: Vec<f64> = (0..nodes).flat_map(|i| volume.node(i).iter().map(|&v| f64::from(v))).collect();
    // Unknown δ = c − ĉ (zero on kept nodes): (W + L_γ) δ = −L_γ ĉ.
    let apply = |x: &[f64], y: &mut [f64]| {
        for (node, (yn, xn)) in y.chunks_exact_mut(k).zip(x.chunks_exact(k)).enumerate() {
            for (a, b) in yn.iter_mut().zip(xn) {
                *a = inv_var[node] * b;
            }
        }
        // A kept node's unknown stays 0 (its preconditioner and right-hand side are 0).
        for &(i, j, g) in &edges {
            for c in 0..k {
                let d = g * (x[i * k + c] - x[j * k + c]);
                if free(i) {
                    y[i * k + c] += d;
                }
                if free(j) {
                    y[j * k + c] -= d;
                }
            }
        }
    };
    let mut b = vec![0.0; nodes * k];
    let mut diag = inv_var.clone();
    for &(i, j, g) in &edges {
        for c in 0..k {
            let d = g * (x0[i * k + c] - x0[j * k + c]);
            b[i * k + c] -= d;
            b[j * k + c] += d;
        }
        diag[i] += g;
        diag[j] += g;
    }
    for (node, bn) in b.chunks_exact_mut(k).enumerate() {
        if !free(node) {
            bn.fill(0.0);
        }
    }
    let precond: Vec<f64> =
        (0..nodes * k).map(|i| if free(i / k) { 1.0 / diag[i / k] } else { 0.0 }).collect();
    let (delta, iterations) = crate::cg::conjugate_gradient_rgb(apply, &b, &precond);
    let mut out = volume.clone();
    for node in (0..nodes).filter(|&n| free(n)) {
        let v: Vec<f32> = (0..k).map(|c| (x0[node * k + c] + delta[node * k + c]) as f32).collect();
        out.set_node(node, &v).map_err(|e| BakeError::Settings(e.to_string()))?;
    }
    let mut errors: Vec<f64> = (0..nodes).filter(|&n| free(n)).map(|n| f64::from(node_error[n])).collect();
    errors.sort_by(f64::total_cmp);
    let report = SmoothingReport {
        nodes: errors.len(),
        edges: edges.len(),
        iterations,
        median_error: errors.get(errors.len() / 2).copied().unwrap_or(0.0),
    };
    Ok((out, report))
}

#[cfg(test)]
#[path = "denoise_tests.rs"]
mod tests;
