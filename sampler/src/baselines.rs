//! The leak fixes engines ship with point-sampled probes, implemented from their published
//! behaviour so that the domain-of-interest bake (\[KL06\]) is compared with what users
//! would otherwise get, not only with naive point sampling.
//!
//! Every baseline point-samples the probe grid (\[KL06\] Eq. 4, the `point` bake's
//! estimator, [`crate::gradient_bake::point_projection`]) and differs in where it samples, what
//! it does with probes that see the inside of geometry, and how the result is read. A
//! probe's **back-face fraction** is the share of [`VALIDITY_RAYS`] uniform rays from it
//! whose first hit is a back face of a single-sided surface ([`lightvol_scene::Hit::back_face`]).
//!
//! | entry | capture point | invalid when the back-face fraction exceeds | invalid nodes | lookup |
//! | --- | --- | --- | --- | --- |
//! | `point+validity` ([`Baseline::Validity`]) | the node | [`VALIDITY_INVALID_FRACTION`] | dilated ([`dilate_apv`]) | plain trilinear |
//! | `point+apv` ([`Baseline::Apv`]) | virtual offset ([`apv_offset`]) | [`APV_INVALID_FRACTION`] (at the capture point) | dilated ([`dilate_apv`]) | validity-weighted |
//! | `point+vlm` ([`Baseline::Vlm`]) | the node | [`VLM_INVALID_FRACTION`] | mean of valid neighbours ([`fill_vlm`]) | plain trilinear |
//! | `point+ddgi` ([`Baseline::Ddgi`]) | relocated ([`ddgi_relocate`]) | — | — | plain trilinear |
//!
//! - **`point+validity`** — the simple validity fix (Blender EEVEE's light-probe volumes
//!   have one of this kind: `dilation_threshold` and `dilation_radius` of
//!   `bpy.types.LightProbeVolume`, Blender 4.2): invalidate probes that see too many back
//!   faces, dilate into them from valid probes within one cell with `1/d²` weights, read the
//!   volume like any other. It is `point+apv` without the virtual offset and without the
//!   run-time weighting, so the two show what those add.
//! - **`point+apv`** — Unity's Adaptive Probe Volumes: *virtual offset* moves a capture
//!   point that is inside geometry through the nearest back face found within
//!   [`APV_SEARCH`] × spacing, [`APV_BIAS`] × spacing beyond it; a probe whose back-face
//!   fraction at its capture point exceeds [`APV_INVALID_FRACTION`] is *invalid*;
//!   *dilation* fills invalid probes from valid ones within one cell with `1/d²` weights; the
//!   volume carries the validity mask ([`lightvol_volume::ValidityMask`]), so its lookups
//!   renormalise the trilinear weights over valid corners at run time
//!   ([`lightvol_volume::validity`]; the same lookups read the mask from a baked file).
//! - **`point+vlm`** — Unreal's volumetric lightmaps: a voxel whose back-face fraction
//!   exceeds [`VLM_INVALID_FRACTION`] is inside geometry and is overwritten with the mean of
//!   its valid 3×3×3 neighbours ([`fill_vlm`]).
//! - **`point+ddgi`** — DDGI / RTXGI probe relocation: a probe whose back-face fraction
//!   exceeds [`DDGI_BACKFACE_THRESHOLD`] moves through its closest back face, by at most
//!   [`DDGI_MAX_OFFSET`](crate::relocate::DDGI_MAX_OFFSET) × spacing per axis, and is point-sampled there.
//!
//! Every baseline's volume has weight 1 at valid nodes and 0 at invalid (filled) ones, as a
//! `doi` bake marks its filled nodes; only `point+apv` attaches a validity mask.

use std::time::{Duration, Instant};

use glam::DVec3;
use lightvol_sh::lowdisc::hash2;
use lightvol_sh::sampling::sample_uniform_sphere;
use lightvol_volume::{GridSpec, IrradianceVolume, ValidityMask};
use rayon::prelude::*;

use crate::error::BakeError;
use crate::method::Baseline;
use crate::relocate::{DDGI_BACKFACE_THRESHOLD, relocate_through, spacing};
use crate::settings::BakeSettings;
use lightvol_scene::bvh::Tracer;
use lightvol_scene::qmc::Qmc;
use lightvol_scene::stats::RayCounts;
use lightvol_scene::transport::Transport;

/// Rays per probe for the back-face fraction and the offset search (Unity's and RTXGI's
/// defaults are of this order; the fraction's standard error at 25% is 0.054).
pub const VALIDITY_RAYS: u32 = 64;
/// `point+validity`: a probe is invalid when more than this share of its rays hit back
/// faces. Unity APV's default ([`APV_INVALID_FRACTION`]), so that `point+validity` and
/// `point+apv` differ only in the virtual offset and the run-time weighting. (Blender's
/// `dilation_threshold` defaults to a front-face share of 0.5, a looser test on the same
/// idea; one threshold for both entries keeps the comparison an ablation.)
pub const VALIDITY_INVALID_FRACTION: f64 = APV_INVALID_FRACTION;
/// Unity APV: a probe is invalid when more than this share of its rays hit back faces
/// (Unity SRP Core, `ProbeDilationSettings.dilationValidityThreshold`, default 0.25).
pub const APV_INVALID_FRACTION: f64 = 0.25;
/// Unity APV virtual offset: search distance, times the smallest node spacing (Unity SRP
/// Core, `VirtualOffsetSettings.searchMultiplier`, default 0.2).
pub const APV_SEARCH: f64 = 0.2;
/// Unity APV virtual offset: how far beyond the back face the capture point goes, times
/// the smallest node spacing (Unity SRP Core, `VirtualOffsetSettings.outOfGeoOffset`,
/// default 0.01).
pub const APV_BIAS: f64 = 0.01;
/// Unreal VLM: a voxel is inside geometry when more than this share of its rays hit back
/// faces (Unreal Lightmass, `VolumetricLightmap.cpp`: `BackfacingHitsFraction > .3f`).
pub const VLM_INVALID_FRACTION: f64 = 0.30;
/// Stream tag of the validity rays ("vald").
const VALIDITY_STREAM: u64 = 0x7661_6c64;

/// What [`probe_rays`] saw from one point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ProbeView {
    /// Share of the rays whose first hit is a back face.
    pub back_fraction: f64,
    /// The closest back-face hit: its direction and distance.
    pub closest_back: Option<(DVec3, f64)>,
}

/// [`VALIDITY_RAYS`] seeded uniform rays from `x` (stream `stream`).
#[must_use]
pub fn probe_rays(tracer: &Tracer, x: DVec3, seed: u64, stream: u64) -> ProbeView {
    let h = Qmc::<2>::new(seed, hash2(stream, VALIDITY_STREAM));
    let mut back = 0u32;
    let mut closest: Option<(DVec3, f64)> = None;
    for i in 0..u64::from(VALIDITY_RAYS) {
        let d = DVec3::from_array(sample_uniform_sphere(h.point(i)));
        if let Some(hit) = tracer.closest_hit(x, d, 0.0, f64::INFINITY)
            && hit.back_face
        {
            back += 1;
            if closest.is_none_or(|(_, t)| hit.t < t) {
                closest = Some((d, hit.t));
            }
        }
    }
    ProbeView { back_fraction: f64::from(back) / f64::from(VALIDITY_RAYS), closest_back: closest }
}

/// Smallest world node spacing of `grid`.
fn min_spacing(grid: &GridSpec) -> f64 {
    spacing(grid).into_iter().fold(f64::INFINITY, f64::min)
}

/// Unity APV's virtual offset of a capture point at `x` that sees `view`: through the
/// nearest back face within `search`, `bias` beyond it; `x` itself when no back face is that
/// close.
#[must_use]
pub fn apv_offset(x: DVec3, view: &ProbeView, search: f64, bias: f64) -> DVec3 {
    match view.closest_back {
        Some((d, t)) if t <= search => x + d * (t + bias),
        _ => x,
    }
}

/// DDGI's relocation of a probe at `x` that sees `view`, on a grid of spacing `spacing`:
/// when the back-face fraction exceeds [`DDGI_BACKFACE_THRESHOLD`], through the closest back
/// face by 1% of the spacing beyond it, each axis of the offset clamped to
/// [`DDGI_MAX_OFFSET`](crate::relocate::DDGI_MAX_OFFSET) × spacing.
#[must_use]
pub fn ddgi_relocate(x: DVec3, view: &ProbeView, spacing: [f64; 3]) -> DVec3 {
    if view.back_fraction <= DDGI_BACKFACE_THRESHOLD {
        return x;
    }
    let Some((d, t)) = view.closest_back else { return x };
    relocate_through(x, d, t, spacing)
}

/// A baseline's volume: the point-sampled coefficients, the per-node validity (weight 1
/// valid, 0 invalid), the capture points, and the rays traced.
#[derive(Clone, Debug)]
pub struct BaselineBake {
    /// The volume (fills applied; weights hold validity; `point+apv`'s carries the
    /// validity mask, which its lookups then read).
    pub volume: IrradianceVolume,
    /// Per node, valid after the baseline's own test.
    pub valid: Vec<bool>,
    /// Where each node was point-sampled.
    pub capture: Vec<DVec3>,
    /// Invalid nodes the fill gave a value (the others keep their own point sample).
    pub filled: usize,
    /// Rays: the point samples' (all kinds) and the validity rays (as `query`).
    pub rays: RayCounts,
    /// Wall time of the bake.
    pub wall_time: Duration,
}

impl BaselineBake {
    /// Nodes the validity test rejected.
    #[must_use]
    pub fn invalid_nodes(&self) -> usize {
        self.valid.iter().filter(|v| !**v).count()
    }

    /// Nodes sampled elsewhere than at the node (virtual offset, relocation) on `grid`,
    /// the grid of the bake.
    #[must_use]
    pub fn moved_nodes(&self, grid: &GridSpec) -> usize {
        self.capture
            .iter()
            .enumerate()
            .filter(|(i, c)| {
                let [x, y, z] = grid.node_coords(*i);
                DVec3::from_array(grid.node_position_world(x, y, z)) != **c
            })
            .count()
    }
}

/// Bakes `grid` with `baseline` (module docs): validity rays per node, capture points, one
/// point projection per node at its capture point (`settings.samples` directions), then the
/// baseline's fill. Deterministic for any thread count.
///
/// # Errors
/// [`BakeError::Settings`] for an unsupported coefficient count.
pub fn bake_baseline(
    t: &Transport<'_>,
    grid: &GridSpec,
    settings: &BakeSettings,
    baseline: Baseline,
) -> Result<BaselineBake, BakeError> {
    let started = Instant::now();
    let tracer = t.tracer();
    let sp = spacing(grid);
    let min_sp = min_spacing(grid);
    let n = grid.node_count();
    let k = settings.coeffs * 3;
    let per_node: Vec<(DVec3, bool, Vec<f64>, RayCounts)> = (0..n)
        .into_par_iter()
        .map(|node| {
            let [i, j, l] = grid.node_coords(node);
            let x = DVec3::from_array(grid.node_position_world(i, j, l));
            let view = probe_rays(tracer, x, settings.seed, node as u64);
            let mut rays = RayCounts { query: u64::from(VALIDITY_RAYS), ..RayCounts::default() };
            let (capture, valid) = match baseline {
                Baseline::Validity => (x, view.back_fraction <= VALIDITY_INVALID_FRACTION),
                Baseline::Apv => {
                    let c = apv_offset(x, &view, APV_SEARCH * min_sp, APV_BIAS * min_sp);
                    let at = if c == x {
                        view
                    } else {
                        rays.query += u64::from(VALIDITY_RAYS);
                        probe_rays(tracer, c, settings.seed, node as u64)
                    };
                    (c, at.back_fraction <= APV_INVALID_FRACTION)
                }
                Baseline::Vlm => (x, view.back_fraction <= VLM_INVALID_FRACTION),
                Baseline::Ddgi => (ddgi_relocate(x, &view, sp), true),
            };
            let (c, st) = crate::gradient_bake::point_projection_counted(
                t,
                settings,
                capture,
                hash2(node as u64, 0x0070_6f69_6e74),
            );
            rays.add(&st.rays);
            (capture, valid, c, rays)
        })
        .collect();
    let mut rays = RayCounts::default();
    let mut data = vec![0.0f64; n * k];
    let mut valid = vec![false; n];
    let mut capture = Vec::with_capacity(n);
    for (node, (c, v, coeffs, r)) in per_node.into_iter().enumerate() {
        rays.add(&r);
        data[node * k..(node + 1) * k].copy_from_slice(&coeffs);
        valid[node] = v;
        capture.push(c);
    }
    let filled = match baseline {
        Baseline::Validity | Baseline::Apv => dilate_apv(grid, &mut data, &valid, k),
        Baseline::Vlm => fill_vlm(grid, &mut data, &valid, k),
        Baseline::Ddgi => 0,
    };
    let weights = valid.iter().map(|&v| f32::from(u8::from(v))).collect();
    let mut volume = IrradianceVolume::new(
        grid.clone(),
        settings.coeffs,
        data.iter().map(|&v| v as f32).collect(),
        weights,
    )
    .map_err(|e| BakeError::Volume(e.to_string()))?;
    if baseline.weights_lookups() {
        volume
            .set_validity(Some(ValidityMask::new(valid.clone())))
            .map_err(|e| BakeError::Volume(e.to_string()))?;
    }
    Ok(BaselineBake { volume, valid, capture, filled, rays, wall_time: started.elapsed() })
}

/// The valid neighbours of `node` within one cell (the 26 around it), with their grid
/// offsets.
fn neighbours(grid: &GridSpec, node: usize) -> impl Iterator<Item = (usize, [i64; 3])> + '_ {
    let [i, j, l] = grid.node_coords(node).map(i64::from);
    let r = grid.res().map(i64::from);
    (0..27).filter(|&q| q != 13).filter_map(move |q| {
        let d = [q % 3 - 1, (q / 3) % 3 - 1, q / 9 - 1];
        let p = [i + d[0], j + d[1], l + d[2]];
        (0..3)
            .all(|a| p[a] >= 0 && p[a] < r[a])
            .then(|| (grid.node_index(p[0] as u32, p[1] as u32, p[2] as u32), d))
    })
}

/// Unity APV dilation: every invalid node takes the `1/d²`-weighted mean of its valid
/// neighbours within one cell (`d` in world units); one with none keeps its value. Unity SRP
/// Core's defaults: `ProbeDilationSettings.dilationDistance` 1 (probe spacing), one
/// iteration, `squaredDistWeighting` on. Returns the nodes it filled.
pub fn dilate_apv(grid: &GridSpec, data: &mut [f64], valid: &[bool], k: usize) -> usize {
    let sp = spacing(grid);
    let src = data.to_vec();
    let mut filled = 0;
    for node in (0..valid.len()).filter(|&n| !valid[n]) {
        let mut acc = vec![0.0; k];
        let mut wsum = 0.0;
        for (m, d) in neighbours(grid, node).filter(|&(m, _)| valid[m]) {
            let d2: f64 = (0..3).map(|a| (d[a] as f64 * sp[a]).powi(2)).sum();
            let w = 1.0 / d2;
            wsum += w;
            for c in 0..k {
                acc[c] += w * src[m * k + c];
            }
        }
        if wsum > 0.0 {
            filled += 1;
            for c in 0..k {
                data[node * k + c] = acc[c] / wsum;
            }
        }
    }
    filled
}

/// Unreal VLM: every invalid node becomes the plain mean of its valid 3×3×3 neighbours; one
/// with none keeps its value. Returns the nodes it filled.
pub fn fill_vlm(grid: &GridSpec, data: &mut [f64], valid: &[bool], k: usize) -> usize {
    let src = data.to_vec();
    let mut filled = 0;
    for node in (0..valid.len()).filter(|&n| !valid[n]) {
        let ns: Vec<usize> = neighbours(grid, node).filter(|&(m, _)| valid[m]).map(|(m, _)| m).collect();
        if ns.is_empty() {
            continue;
        }
        filled += 1;
        for c in 0..k {
            data[node * k + c] = ns.iter().map(|&m| src[m * k + c]).sum::<f64>() / ns.len() as f64;
        }
    }
    filled
}

#[cfg(test)]
#[path = "baselines_tests.rs"]
mod tests;
