//! Node values chosen for the lookup an engine runs (`bake --target`).
//!
//! A bake's node values are free; what a user sees is the engine's reconstruction of them,
//! and the engines read a grid differently from lightvol (three.js half a cell along the
//! normal, Bevy through an ambient cube, Unity APV with biases and validity, most with
//! neither validity nor the node reach; [`lightvol_volume::engine_lookup`]). Kontkanen &
//! Laine 2006 (Eq. 5-6) choose each node's value from the light over its trilinear support
//! in the domain of interest; with the reconstruction known at bake time, the node values
//! can instead minimise the error of *the target's* reconstruction over the domain of
//! interest:
//!
//! `min_c Σ_s ‖R_X(c; p_s, n_s, v_s) − E_s‖² + λ Σ_i μ_i ‖c_i − ĉ_i‖²`
//!
//! with `R_X` the target lookup's linear form ([`EngineWeights`]), `ĉ` the bake's own
//! values and `μ_i = (π/4) Σ_s b_i(s)` (the row sum of the data term's weights on node
//! `i`'s constant coefficient, `(A_0 Y_0)² = π/4`, as in the consistent-mass fit of
//! [`crate::node_fit`]), so that coefficients the samples do not determine (the ambient
//! cube ignores three of nine) and nodes that samples reach only with small weights stay
//! at the bake's values (`Σ b ≥ Σ b²`: a sliver node is held harder than it is pulled). The normal equations are solved by Jacobi-preconditioned conjugate gradients,
//! all three colour channels in one pass, in a fixed order (bit-identical for any thread
//! count).
//!
//! **The samples.** From every node with samples of its own (not filled from its
//! neighbours), [`TARGET_RAYS_PER_NODE`] rays (Halton directions keyed by seed and node)
//! find the surfaces near it. The unobstructed part of each ray (up to the first surface or
//! [`TARGET_REACH_CELLS`] cells) gives [`TARGET_FREE_SAMPLES_PER_RAY`] *free-space samples*,
//! each at `∛u` of that part's length, so that they are uniform in the space around the
//! node (where a moving object may be), not crowded near it (uniform in distance, density
//! `∝ 1/r²`), where every lookup already reads the node itself. A front face met within
//! reach gives a *surface sample* (the point, its shading normal, viewed from the node).
//! Samples beyond the engines' box (half a cell past the outermost nodes) are left out
//! for every lookup: no engine is asked about the light there, and a clamped lookup (plain
//! trilinear, APV) would otherwise bend the border nodes toward light outside the volume
//! (the trilinear means fell from 0.791 / 0.802 to 0.780 / 0.793 without them, seeds 1 / 2;
//! sampler README). A node any of whose rays meets a back face gives none (it stands
//! inside a solid, or outside a room whose walls face inward: Kontkanen & Laine's test of
//! the domain of interest, on the node's rays). These are the points an engine shades and
//! a moving object passes through.
//!
//! A free sample's normal is uniform on the sphere for the plain trilinear lookup, and the
//! grid axis nearest to a uniform normal for three.js's, Bevy's and APV's. Bevy's ambient
//! cube stores six values, exact on the six axis normals and blended by `n²` in between:
//! fitted over all normals, the cube that is best on average reads an axis-facing surface
//! (a floor, a wall) a quarter of the up-down difference too bright or too dark (the 5/4 of
//! `bevys_cube_fitted_over_all_normals_overshoots_the_axis_by_five_quarters`), while the
//! blend between exact axis values is the cube's own. three.js reads half a cell along the
//! normal and APV a normal bias along it, so there a normal also chooses *where* the grid
//! is read: axis normals fit the reads along a grid axis that floors, walls and ceilings
//! make. (For the plain trilinear lookup, which reads SH9 at the point, axis normals gave a
//! worse mean: sampler README.)
//!
//! A sample's value `E_s` is the bake's irradiance read by lightvol's own lookup (validity
//! and node reach, [`IrradianceVolume::irradiance_reference`]), at the free point itself
//! and, for a surface sample, [`TARGET_SURFACE_READ_CELLS`] of a cell in front of the
//! surface. The fit moves the bake's light, estimated once, into the target's
//! reconstruction, and traces no light path: the rays above are its whole cost
//! ([`TargetReport::rays`]). The sampler README gives what each of these choices changed on
//! the README's method table.
//!
//! **Noise.** Given the bake's per-node error estimates, the bake's values are first
//! smoothed where they are noisy ([`crate::denoise`], `TargetSettings::smoothing`;
//! [`smooth_for_target`]), and `ĉ` and the samples' values above are then the smoothed
//! volume's. A bake in pieces carries the estimates in its sums
//! ([`crate::noise::attach_node_errors`]) and takes this step once the pieces are merged
//! ([`crate::merge::finish_merged_with`]): a shard set baked for lightvol's lookup in `merge`, a
//! checkpointed bake for any lookup (it has the scene for the fit's rays).
//!
//! **Lightvol's own lookup** ([`EngineLookup::Lightvol`]) needs no fit (the bake's values
//! are chosen for it), but its noise is drawn all the same: the target smooths and stops
//! there, traces no ray and keeps the node reach. On the README's method table (128
//! samples, eight scenes and the Breakfast Room's two camera views) it lowers `doi`'s mean
//! relative RMSE through lightvol's lookup from 0.72× to 0.63-0.65× the best engine fix's
//! (the Breakfast Room's plate 0.331 → 0.258, the interior's 0.240 → 0.203; sampler
//! README).

use std::f64::consts::PI;

use glam::DVec3;
use lightvol_scene::qmc::Qmc;
use lightvol_scene::transport::Transport;
use lightvol_sh::lowdisc::hash2;
use lightvol_sh::sampling::sample_uniform_sphere;
use lightvol_volume::engine_lookup::EngineWeights;
use lightvol_volume::validity::ValidityMask;
use lightvol_volume::{Accumulator, EngineLookup, IrradianceVolume};
use rayon::prelude::*;

use crate::denoise::{DEFAULT_SMOOTHING, SmoothingReport, smooth_by_noise};
use crate::error::BakeError;

/// Rays traced from each node to find its samples: each gives a surface sample where it
/// meets one within reach and [`TARGET_FREE_SAMPLES_PER_RAY`] free-space points. Twelve
/// cost at most 5% of the rays of a 128-sample `doi` bake on every built-in and vendored
/// scene (whose probe samples each trace a path and a shadow ray; the living room, with the
/// shortest paths, is the dearest; test `target_fits_stay_within_their_ray_budget`).
/// Sixteen gave lower plate errors through three.js's lookup than eight on six of six
/// scenes, but cost 5.9% on the living room.
pub const TARGET_RAYS_PER_NODE: u32 = 12;

/// How far, in the largest cell size, a node's rays look for surfaces: two cells covers
/// the trilinear supports of the node's neighbours that a surface point there reads.
pub const TARGET_REACH_CELLS: f64 = 2.0;

/// Free-space samples taken along each ray's unobstructed part (each at its own `∛u` of
/// the part's length, with its own normal): the points cost no ray, and more of them
/// lowered the means through three.js's, Bevy's and the trilinear lookups on the README's
/// method table, by less each time (one → three → five; sampler README, "Fitting for an
/// engine's lookup").
pub const TARGET_FREE_SAMPLES_PER_RAY: u32 = 5;

/// Where a surface sample's value is read, in the smallest cell size in front of the
/// surface along its normal (module docs). lightvol's reading at the surface itself
/// carries the bake's error at contact (the corners and the floor under furniture, which
/// no grid resolves); read in front of it, the Breakfast Room's camera views of every
/// engine fit came 0.02-0.04 closer to the path tracer, at a cost to the floors of the
/// coarse built-in grids. A quarter of a cell gave a worse mean than a half, and three
/// quarters and a whole cell better and alike (sampler README).
pub const TARGET_SURFACE_READ_CELLS: f64 = 0.75;

/// Default λ for a lookup that reads the grid where the bake aimed, at the shading point
/// (Bevy's, plain trilinear): how strongly node values stay at the bake's. Measured on the
/// eight scenes of the README's method table (sampler README): with one free sample per ray
/// and surface values read at the surface, 0.5 of 0.1-2 gave the lowest means; with three
/// free samples per ray and surface values read half a cell out, 0.15 of 0.12-1 did (below
/// it, nodes that few samples reach swing: zdm2's plate); with three free samples and
/// three quarters of a cell, 0.1 and 0.15 gave the same means and 0.25 worse.
pub const TARGET_LAMBDA_AT_POINT: f64 = 0.15;

/// Default λ for a lookup that reads the grid away from the shading point (three.js half a
/// cell along the normal, Unity APV by its normal and view biases): there the bake's own
/// values are not what the lookup should read, and the fit needs the freedom to move them.
/// Measured at 0.05, 0.1, 0.2 and 0.5 (sampler README): 0.1 gave the lowest means through
/// both lookups, on two seeds.
pub const TARGET_LAMBDA_OFFSET: f64 = 0.1;

/// The default λ of a fit for `lookup` ([`TARGET_LAMBDA_OFFSET`] for the lookups that read
/// away from the shading point, [`TARGET_LAMBDA_AT_POINT`] for the others).
#[must_use]
pub const fn default_target_lambda(lookup: EngineLookup) -> f64 {
    match lookup {
        EngineLookup::Three | EngineLookup::Apv => TARGET_LAMBDA_OFFSET,
        EngineLookup::Lightvol | EngineLookup::Trilinear | EngineLookup::Bevy => TARGET_LAMBDA_AT_POINT,
    }
}

/// `(A_0 Y_0)²`: the squared factor of the constant coefficient in the irradiance
/// expansion, `(π · 1/(2√π))² = π/4`.
const DC_FACTOR_SQUARED: f64 = PI / 4.0;

/// What the fit aims at and how hard it holds on to the bake.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TargetSettings {
    /// The engine lookup the node values are chosen for.
    pub lookup: EngineLookup,
    /// λ ≥ 0 (module docs).
    pub lambda: f64,
    /// Rays per node that find the samples.
    pub rays_per_node: u32,
    /// Seed of the rays' directions.
    pub seed: u64,
    /// With the bake's per-node error estimates: the noise-weighted smoothing's `τ`
    /// ([`crate::denoise`]) applied to the bake's values before the fit; `None`: none.
    pub smoothing: Option<f64>,
}

impl TargetSettings {
    /// The fit for `lookup` with its default λ ([`default_target_lambda`]) and rays, seeded
    /// by `seed`.
    #[must_use]
    pub fn new(lookup: EngineLookup, seed: u64) -> Self {
        Self {
            lookup,
            lambda: default_target_lambda(lookup),
            rays_per_node: TARGET_RAYS_PER_NODE,
            seed,
            smoothing: Some(DEFAULT_SMOOTHING),
        }
    }
}

/// What the fit did.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TargetReport {
    /// Surface samples.
    pub surface_samples: usize,
    /// Free-space samples.
    pub free_samples: usize,
    /// Samples left out: beyond the engines' box (half a cell past the outermost nodes,
    /// [`IrradianceVolume::outside_engine_box`]), where no engine is asked about the light
    /// and a clamped lookup would bend the border nodes toward light outside the volume, or
    /// unlit by the target lookup (three.js reading outside its box).
    pub unlit_samples: usize,
    /// Rays traced to find the samples.
    pub rays: u64,
    /// Nodes whose values the fit chose (the others keep the bake's).
    pub nodes_fitted: usize,
    /// Conjugate-gradient iterations (the slowest channel).
    pub iterations: usize,
    /// Relative RMS difference over the samples between the target lookup and the samples'
    /// values, with the bake's node values.
    pub relative_rms_before: f64,
    /// The same with the fitted values.
    pub relative_rms_after: f64,
    /// The noise-weighted smoothing before the fit, where there was one.
    pub smoothing: Option<SmoothingReport>,
}

/// One sample: where the engine is asked (`p`, with normal `n` and towards-the-eye `v`),
/// and where lightvol's lookup is read for what it should answer (`read`, with normal `n`).
#[derive(Clone, Copy, Debug)]
struct Sample {
    p: [f64; 3],
    n: [f64; 3],
    v: [f64; 3],
    read: [f64; 3],
    surface: bool,
}

/// The samples of node `node` (module docs): none when any of its rays meets a back face
/// (the node stands inside a solid, or outside a room whose walls face inward: not where
/// an engine shades).
fn node_samples(
    t: &Transport<'_>,
    vol: &IrradianceVolume,
    settings: &TargetSettings,
    node: usize,
) -> (Vec<Sample>, u64) {
    let spec = vol.spec();
    let [i, j, k] = spec.node_coords(node);
    let x = DVec3::from_array(spec.node_position_world(i, j, k));
    let cell = spec.cell_size();
    let reach = TARGET_REACH_CELLS * cell.into_iter().fold(0.0, f64::max);
    let read_offset = TARGET_SURFACE_READ_CELLS * cell.into_iter().fold(f64::INFINITY, f64::min);
    let dirs = Qmc::<2>::new(settings.seed, hash2(node as u64, 0x7461_7267_6574));
    let free = Qmc::<3>::new(settings.seed, hash2(node as u64, 0x6672_6565));
    let per_ray = u64::from(TARGET_FREE_SAMPLES_PER_RAY);
    let eps = t.epsilon();
    let mut out = Vec::with_capacity(((per_ray + 1) * u64::from(settings.rays_per_node)) as usize);
    for s in 0..u64::from(settings.rays_per_node) {
        let q = dirs.point(s);
        let dir = DVec3::from_array(sample_uniform_sphere([q[0], q[1]]));
        let hit = t.tracer().closest_hit(x, dir, 0.0, f64::INFINITY);
        if hit.is_some_and(|h| h.back_face) {
            return (Vec::new(), s + 1);
        }
        let end = hit.map_or(reach, |h| h.t.min(reach));
        for f in 0..per_ray {
            let u = free.point(s * per_ray + f);
            let n = free_normal(settings.lookup, sample_uniform_sphere([u[1], u[2]]));
            // Uniform in the ball the unobstructed rays sweep (distance ∝ ∛u), not in distance.
            let p = (x + dir * (u[0].cbrt() * end)).to_array();
            out.push(Sample { p, n, v: n, read: p, surface: false });
        }
        if let Some(h) = hit.filter(|h| h.t <= reach) {
            // The face the node sees, and the engine's shading normal on that side.
            let face = if h.from_behind { -h.normal } else { h.normal };
            let shading = t.scene().shading_normal(h.triangle, h.bary[0], h.bary[1]).unwrap_or(face);
            let n = if shading.dot(face) < 0.0 { -shading } else { shading };
            let p = x + dir * h.t + face * eps;
            let read = (p + n * read_offset).to_array();
            out.push(Sample { p: p.to_array(), n: n.to_array(), v: (-dir).to_array(), read, surface: true });
        }
    }
    (out, u64::from(settings.rays_per_node))
}

/// A free-space sample's normal for `lookup`, from the uniform normal `n`: for three.js's,
/// Bevy's and APV's lookups the grid axis nearest to `n` (each of the six with probability
/// 1/6; module docs), for the others `n` itself.
fn free_normal(lookup: EngineLookup, n: [f64; 3]) -> [f64; 3] {
    if !matches!(lookup, EngineLookup::Three | EngineLookup::Bevy | EngineLookup::Apv) {
        return n;
    }
    nearest_axis(n)
}

/// The signed grid axis nearest to the unit vector `n` (the largest component's, the first
/// on a tie).
fn nearest_axis(n: [f64; 3]) -> [f64; 3] {
    let a = (1..3).fold(0, |best, a| if n[a].abs() > n[best].abs() { a } else { best });
    let mut axis = [0.0; 3];
    axis[a] = if n[a] < 0.0 { -1.0 } else { 1.0 };
    axis
}

/// A sample's row: the target's linear form and the value it should give.
struct Row {
    w: EngineWeights,
    value: [f64; 3],
}

impl Row {
    /// The row's non-zero entries: the index of each (node, coefficient) pair's red value
    /// in `[node][coeff][rgb]` (`coeffs` per channel) and its weight.
    fn entries(&self, coeffs: usize) -> impl Iterator<Item = (usize, f64)> + '_ {
        (0..8).filter(move |&c| self.w.corner[c] != 0.0).flat_map(move |c| {
            let base = self.w.nodes[c] * 3 * coeffs;
            (0..coeffs).map(move |j| (base + 3 * j, self.w.corner[c] * self.w.basis[j]))
        })
    }

    /// The row applied to node values `x` (`[node][coeff][rgb]`, `coeffs` per channel).
    fn dot(&self, x: &[f64], coeffs: usize) -> [f64; 3] {
        let mut e = [0.0; 3];
        for (i, a) in self.entries(coeffs) {
            for ch in 0..3 {
                e[ch] += a * x[i + ch];
            }
        }
        e
    }

    /// Adds the transposed row times `e` to `y` (the twin of [`Self::dot`]).
    fn scatter(&self, e: [f64; 3], y: &mut [f64], coeffs: usize) {
        for (i, a) in self.entries(coeffs) {
            for ch in 0..3 {
                y[i + ch] += a * e[ch];
            }
        }
    }
}

/// The nodes with samples of their own in a bake's sums (a positive Eq. 6 denominator):
/// the mask [`fit_for_lookup`] takes, since the others were filled from their neighbours.
#[must_use]
pub fn own_samples_mask(acc: &Accumulator) -> ValidityMask {
    ValidityMask::new(acc.denominator().iter().map(|&d| d > 0.0).collect())
}

/// Chooses node values for `settings.lookup` (module docs) from the baked `volume` (read
/// through lightvol's lookup for the samples' values), over `transport`'s scene. The result
/// has the bake's grid and metadata, no node reach (no engine reads one) and, for
/// [`EngineLookup::Apv`], the validity mask `valid` (APV's lookup renormalises over the
/// valid nodes; `None`: every node valid). With the bake's per-node error
/// estimates `node_error` ([`crate::bake::BakeOutput::node_error`]) and
/// `settings.smoothing`, the bake's values are first smoothed where they are noisy
/// ([`smooth_by_noise`]), and the fit starts from and aims at the smoothed values.
/// [`EngineLookup::Lightvol`] fits nothing (the bake is already chosen for lightvol's
/// lookup) and traces no ray: it returns the smoothed volume, reach and all, or the volume
/// as it is without error estimates or smoothing.
///
/// # Errors
/// [`BakeError::Settings`] for a negative or non-finite λ, a mask or error list of the
/// wrong size, a bad smoothing `τ`, or a grid with a placement transform.
pub fn fit_for_lookup(
    transport: &Transport<'_>,
    volume: &IrradianceVolume,
    settings: &TargetSettings,
    valid: Option<ValidityMask>,
    node_error: Option<&[f32]>,
) -> Result<(IrradianceVolume, TargetReport), BakeError> {
    if !(settings.lambda >= 0.0 && settings.lambda.is_finite()) {
        return Err(BakeError::Settings(format!("target λ must be >= 0 (got {})", settings.lambda)));
    }
    let nodes = volume.spec().node_count();
    if valid.as_ref().is_some_and(|m| m.len() != nodes) {
        return Err(BakeError::Settings(format!(
            "a validity mask of {} nodes for {nodes}",
            valid.map_or(0, |m| m.len())
        )));
    }
    let (smoothed, smoothing) = smooth_for_target(volume, valid.as_ref(), node_error, settings.smoothing)?;
    let volume = smoothed.as_ref().unwrap_or(volume);
    if settings.lookup == EngineLookup::Lightvol {
        // The bake's values are already chosen for lightvol's lookup: smoothed, no fit.
        return Ok((volume.clone(), TargetReport { smoothing, ..TargetReport::default() }));
    }
    // Nodes without samples of their own (filled from their neighbours) shoot no rays.
    let shoots = |node: usize| valid.as_ref().is_none_or(|m| m.is_valid(node));
    let per_node: Vec<(Vec<Sample>, u64)> = (0..nodes)
        .into_par_iter()
        .map(
            |node| {
                if shoots(node) { node_samples(transport, volume, settings, node) } else { (Vec::new(), 0) }
            },
        )
        .collect();
    let mut fitted = as_read_by(volume, settings.lookup, valid)?;
    let mut report =
        TargetReport { rays: per_node.iter().map(|(_, r)| r).sum(), smoothing, ..TargetReport::default() };
    let samples: Vec<Sample> = per_node.into_iter().flat_map(|(s, _)| s).collect();
    report.surface_samples = samples.iter().filter(|s| s.surface).count();
    report.free_samples = samples.len() - report.surface_samples;
    let rows: Vec<Row> = samples
        .into_par_iter()
        .filter(|s| !fitted.outside_engine_box(s.p, 0.0))
        .filter_map(|s| {
            let w = fitted.engine_weights(settings.lookup, s.p, s.n, s.v);
            w.lit().then(|| Row { w, value: volume.irradiance_reference(s.read, s.n) })
        })
        .collect();
    report.unlit_samples = report.surface_samples + report.free_samples - rows.len();
    report.relative_rms_before = relative_rms(&fitted, &rows);
    (report.nodes_fitted, report.iterations) = solve_into(&mut fitted, &rows, settings.lambda)?;
    report.relative_rms_after = relative_rms(&fitted, &rows);
    Ok((fitted, report))
}

/// The first step of every target ([`fit_for_lookup`]): `volume`'s values smoothed under
/// their estimated errors `node_error` with `τ = smoothing` ([`smooth_by_noise`], over the
/// nodes of `valid`, every node without it), or `None` (and no report) without errors or
/// smoothing. A merged shard set runs the same step on its merged estimates
/// ([`crate::merge::finish_merged`]).
///
/// # Errors
/// [`BakeError::Settings`] for an error list of the wrong size or a bad `τ`.
pub fn smooth_for_target(
    volume: &IrradianceVolume,
    valid: Option<&ValidityMask>,
    node_error: Option<&[f32]>,
    smoothing: Option<f64>,
) -> Result<(Option<IrradianceVolume>, Option<SmoothingReport>), BakeError> {
    let (Some(errors), Some(tau)) = (node_error, smoothing) else {
        return Ok((None, None));
    };
    let all;
    let valid = match valid {
        Some(m) => m,
        None => {
            all = ValidityMask::new(vec![true; volume.spec().node_count()]);
            &all
        }
    };
    let (v, r) = smooth_by_noise(volume, valid, errors, tau)?;
    Ok((Some(v), Some(r)))
}

/// `volume` with what `lookup` reads besides the node values: lightvol's own lookup keeps
/// the volume's validity and node reach; the engines' read neither, except APV's validity,
/// which is `valid`.
fn as_read_by(
    volume: &IrradianceVolume,
    lookup: EngineLookup,
    valid: Option<ValidityMask>,
) -> Result<IrradianceVolume, BakeError> {
    let mut vol = volume.clone();
    if lookup != EngineLookup::Lightvol {
        vol.set_reach(None).map_err(|e| BakeError::Settings(e.to_string()))?;
        let mask = if lookup == EngineLookup::Apv { valid } else { None };
        vol.set_validity(mask).map_err(|e| BakeError::Settings(e.to_string()))?;
    }
    Ok(vol)
}

/// Solves the fit of `rows` ([`solve`]) and stores the node values in `vol`: returns the
/// nodes solved for and the iterations.
fn solve_into(vol: &mut IrradianceVolume, rows: &[Row], lambda: f64) -> Result<(usize, usize), BakeError> {
    let (values, nodes_fitted, iterations) = solve(vol, rows, lambda);
    let k = 3 * vol.coeffs();
    for node in 0..vol.spec().node_count() {
        let v: Vec<f32> = values[node * k..(node + 1) * k].iter().map(|&x| x as f32).collect();
        vol.set_node(node, &v).map_err(|e| BakeError::Settings(e.to_string()))?;
    }
    Ok((nodes_fitted, iterations))
}

/// A point where the lookup is asked, and the irradiance it should answer there.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct KnownPoint {
    /// Where the engine shades, in the volume's frame.
    pub p: [f64; 3],
    /// The shading normal (unit).
    pub n: [f64; 3],
    /// Towards the eye (unit; APV's view bias).
    pub to_eye: [f64; 3],
    /// The irradiance wanted, RGB.
    pub value: [f64; 3],
}

/// λ of [`best_for_points`]: small enough that the data decide every coefficient they
/// reach (it adds `λ μ`, a millionth of the data's own weight on a node's constant
/// coefficient, to the normal equations), large enough that coefficients no point
/// determines stay at the volume's values.
pub const BOUND_LAMBDA: f64 = 1e-6;

/// The node values that reproduce known irradiance at `points` best through `lookup`:
/// the least-squares fit of the module docs with the points' values as data and a
/// vanishing regulariser ([`BOUND_LAMBDA`]) toward `volume`'s values, so the result's
/// error at those points is the lowest any node values on this grid reach through this
/// lookup (with `valid` as APV's validity mask; lightvol's lookup keeps the volume's own
/// validity and node reach). With a path-traced reference as the values this bounds
/// every bake from below at those points: no choice of node values, and so no bake
/// method, does better there on this grid.
///
/// # Errors
/// [`BakeError::Settings`] for a mask of the wrong size.
pub fn best_for_points(
    volume: &IrradianceVolume,
    lookup: EngineLookup,
    valid: Option<ValidityMask>,
    points: &[KnownPoint],
) -> Result<IrradianceVolume, BakeError> {
    let mut fitted = as_read_by(volume, lookup, valid)?;
    let rows: Vec<Row> = points
        .par_iter()
        .filter_map(|k| {
            let w = fitted.engine_weights(lookup, k.p, k.n, k.to_eye);
            w.lit().then_some(Row { w, value: k.value })
        })
        .collect();
    solve_into(&mut fitted, &rows, BOUND_LAMBDA)?;
    Ok(fitted)
}

/// RMS of `R_X(c; s) − E_s` over the rows and channels, over the RMS of `E_s`.
fn relative_rms(vol: &IrradianceVolume, rows: &[Row]) -> f64 {
    let (err, norm) = rows
        .iter()
        .map(|r| {
            let e = r.w.apply(vol);
            (0..3).fold((0.0, 0.0), |(a, b), ch| (a + (e[ch] - r.value[ch]).powi(2), b + r.value[ch].powi(2)))
        })
        .fold((0.0, 0.0), |(a, b), (c, d)| (a + c, b + d));
    if norm > 0.0 { (err / norm).sqrt() } else { 0.0 }
}

/// Solves the normal equations (module docs) over the nodes some row weighs: returns every
/// node's values (`[node][coeff][rgb]`, the bake's where no row reaches), the nodes solved
/// for and the iterations.
fn solve(vol: &IrradianceVolume, rows: &[Row], lambda: f64) -> (Vec<f64>, usize, usize) {
    let coeffs = vol.coeffs();
    let nodes = vol.spec().node_count();
    let k = coeffs * 3;
    let x0: Vec<f64> = (0..nodes).flat_map(|i| vol.node(i).iter().map(|&v| f64::from(v))).collect();
    // μ_i and the Jacobi diagonal of AᵀA, per node and coefficient.
    let mut mu = vec![0.0; nodes];
    let mut diag = vec![0.0; nodes * coeffs];
    for r in rows {
        for c in 0..8 {
            let b = r.w.corner[c];
            if b == 0.0 {
                continue;
            }
            let node = r.w.nodes[c];
            mu[node] += DC_FACTOR_SQUARED * b;
            for j in 0..coeffs {
                diag[node * coeffs + j] += (b * r.w.basis[j]).powi(2);
            }
        }
    }
    let active: Vec<bool> = mu.iter().map(|&m| m > 0.0).collect();
    let fitted = active.iter().filter(|&&a| a).count();
    let reg: Vec<f64> = mu.iter().map(|m| lambda * m).collect();
    // `y = (AᵀA + λM) x` on the active unknowns (a node no row weighs has no row entry).
    let apply = |x: &[f64], y: &mut [f64]| {
        y.iter_mut().for_each(|v| *v = 0.0);
        for r in rows {
            let e = r.dot(x, coeffs);
            r.scatter(e, y, coeffs);
        }
        for node in 0..nodes {
            if active[node] {
                for i in node * k..(node + 1) * k {
                    y[i] += reg[node] * x[i];
                }
            }
        }
    };
    // Right-hand side Aᵀ(E − A x⁰): the unknown is the change from the bake, δ = x − x⁰.
    // A node no row weighs has μ = 0 and appears in no row, so it stays at x⁰.
    let mut b = vec![0.0; nodes * k];
    for r in rows {
        let e = r.dot(&x0, coeffs);
        r.scatter(std::array::from_fn(|ch| r.value[ch] - e[ch]), &mut b, coeffs);
    }
    let precond: Vec<f64> = (0..nodes * k)
        .map(|i| {
            let node = i / k;
            let d = diag[node * coeffs + (i % k) / 3] + reg[node];
            if active[node] && d > 0.0 { 1.0 / d } else { 0.0 }
        })
        .collect();
    let (delta, iterations) = crate::cg::conjugate_gradient_rgb(apply, &b, &precond);
    let x = x0.iter().zip(&delta).map(|(a, d)| a + d).collect();
    (x, fitted, iterations)
}

#[cfg(test)]
#[path = "target_tests.rs"]
mod tests;
