//! The surface bake: every lightmap object's atlas, texel by texel (\[Ish11\] §2.2).
//!
//! **Determinism.** Each texel's random streams depend only on `(seed, object, texel)`;
//! texels are integrated in parallel in chunks and their results stored by index, and the
//! dilation passes run in index order, so any thread count gives bit-identical maps.

use lightvol_core::samples::{Samples, samples};
use std::time::{Duration, Instant};

use lightvol_hemibasis::convert::sh_to_basis_matrix;
use lightvol_sh::irradiance::cosine_lobe_factor;
use rayon::prelude::*;

use super::atlas::{Atlas, atlas_size};
use super::geometry::SurfaceGeometry;
use super::map::{CoefficientMap, InvalidCounts, TexelKey, TexelState, dilate};
use super::texel::{TexelJob, TexelOut};
use super::{BasisChoice, InvalidTexels, Quantity, SurfaceError, UvSet};
use lightvol_core::progress::{BakeControl, Progress};
use lightvol_scene::fingerprint::lighting_fingerprint;
use lightvol_scene::stats::RayCounts;
use lightvol_scene::transport::Transport;

/// Surface bake settings.
#[derive(Clone, Debug, PartialEq)]
pub struct SurfaceSettings {
    /// The basis the maps store.
    pub basis: BasisChoice,
    /// Which UV set holds the lightmap coordinates.
    pub uv_set: UvSet,
    /// Texel density `D` (texels per world unit), see [`atlas_size`].
    pub texels_per_unit: f64,
    /// Overrides the atlas size of every object.
    pub resolution: Option<[u32; 2]>,
    /// In-domain samples (paths) per texel.
    pub samples: Samples,
    /// At most `max_candidates_factor × samples` candidate points are drawn per texel while
    /// looking for valid ones.
    pub max_candidates_factor: u32,
    /// SH bands of the intermediate projection (3 = 9 coefficients, \[Ish11\] §2.2.1).
    pub sh_bands: usize,
    /// Irradiance or radiosity.
    pub quantity: Quantity,
    /// Domain-of-interest treatment of invalid texels, or none.
    pub invalid: InvalidTexels,
    /// One light sample per path sample (next-event estimation, MIS).
    pub light_sampling: bool,
    /// Passes of dilation into empty texels around the charts (0 = none).
    pub gutter: u32,
    /// Seed of every random stream.
    pub seed: u64,
    /// Texels per parallel chunk (progress and cancellation granularity).
    pub chunk: usize,
}

impl Default for SurfaceSettings {
    fn default() -> Self {
        Self {
            basis: BasisChoice::parse("sh9").expect("SH is always compiled"),
            uv_set: UvSet::Lightmap,
            texels_per_unit: 32.0,
            resolution: None,
            samples: samples(256),
            max_candidates_factor: 4,
            sh_bands: 3,
            quantity: Quantity::Irradiance,
            invalid: InvalidTexels::Fix,
            light_sampling: true,
            gutter: 2,
            seed: 0,
            chunk: 1024,
        }
    }
}

/// Largest SH band count of the intermediate projection.
pub const MAX_SH_BANDS: usize = 8;

/// Counters of a surface bake. Serialised (in a bake's summary) without `objects` and
/// `wall_time`, which the summary gives in its own terms.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct SurfaceReport {
    /// Objects baked.
    #[serde(skip)]
    pub objects: usize,
    /// Texels covered by some triangle.
    pub texels_covered: u64,
    /// Covered texels with at least one sample point that saw a back face.
    pub invalid_texels: u64,
    /// Invalid texels whose samples were all taken in the valid part of the footprint
    /// ([`InvalidTexels::Fix`]).
    pub moved: u64,
    /// Invalid texels with no valid point, filled from valid neighbours.
    pub dilated: u64,
    /// Invalid texels with no valid point that no dilation reached (left 0, `valid` = 0).
    pub unfilled: u64,
    /// Empty texels filled by the gutter dilation.
    pub gutter_texels: u64,
    /// Rays traced.
    pub rays: RayCounts,
    /// Wall-clock time.
    #[serde(skip)]
    pub wall_time: Duration,
}

/// The maps (one per object, in [`SurfaceGeometry::objects`] order) and the report.
#[derive(Clone, Debug)]
pub struct SurfaceBake {
    /// One coefficient map per object.
    pub maps: Vec<CoefficientMap>,
    /// Counters.
    pub report: SurfaceReport,
}

/// Bakes the coefficient maps of every lightmap object of the transport's scene.
///
/// # Errors
/// Scene and UV errors of [`SurfaceGeometry::new`] and [`Atlas::build`],
/// [`SurfaceError::Settings`], [`SurfaceError::AtlasTooLarge`], [`SurfaceError::Cancelled`].
pub fn bake_surface(
    transport: &Transport<'_>,
    settings: &SurfaceSettings,
    control: &BakeControl<'_>,
) -> Result<SurfaceBake, SurfaceError> {
    let geo = SurfaceGeometry::new(transport.scene(), settings.uv_set)?;
    bake_surface_with(transport, &geo, settings, control)
}

/// [`bake_surface`] with a prepared [`SurfaceGeometry`] (built for `settings.uv_set`): all
/// texels ([`bake_surface_texels`] over the whole range), then [`assemble_surface`].
///
/// # Errors
/// As [`bake_surface`].
pub fn bake_surface_with(
    transport: &Transport<'_>,
    geo: &SurfaceGeometry,
    settings: &SurfaceSettings,
    control: &BakeControl<'_>,
) -> Result<SurfaceBake, SurfaceError> {
    let start = Instant::now();
    let texels = bake_surface_texels(transport, geo, settings, control, (0, 1))?;
    let mut bake = assemble_surface(transport, geo, settings, &texels.records)?;
    bake.report.wall_time = start.elapsed();
    Ok(bake)
}

/// The integrated result of one covered texel, before dilation: what a shard of a surface
/// bake computes and a merge assembles.
#[derive(Clone, Debug, PartialEq)]
pub struct TexelRecord {
    /// Index of the texel's footprint among all objects' footprints (object by object, in
    /// atlas order): the bake's unit of work.
    pub index: u64,
    /// The texel's basis coefficients (RGB, as stored in the map), `None` when no sample
    /// point was valid (the texel is filled by dilation).
    pub coeffs: Option<Vec<[f32; 3]>>,
    /// At least one candidate point saw a back face.
    pub invalid: bool,
    /// Rays traced for the texel.
    pub rays: RayCounts,
}

/// The texels of one shard of a surface bake.
#[derive(Clone, Debug, PartialEq)]
pub struct SurfaceTexels {
    /// Footprints of the whole bake (every object).
    pub total: u64,
    /// The shard's records, ascending by index.
    pub records: Vec<TexelRecord>,
}

/// What the surface bake derives from the geometry and settings before any tracing.
struct Prepared {
    atlases: Vec<Atlas>,
    matrix: lightvol_hemibasis::Matrix,
    factors: Vec<f64>,
    max_candidates: u32,
}

fn prepare(geo: &SurfaceGeometry, settings: &SurfaceSettings) -> Result<Prepared, SurfaceError> {
    if settings.max_candidates_factor == 0 {
        return Err(SurfaceError::Settings("max_candidates_factor must be positive".into()));
    }
    if !(1..=MAX_SH_BANDS).contains(&settings.sh_bands) {
        return Err(SurfaceError::Settings(format!("sh_bands must be 1..={MAX_SH_BANDS}")));
    }
    if geo.uv_set() != settings.uv_set {
        return Err(SurfaceError::Settings("geometry was built for another UV set".into()));
    }
    if let Some([w, h]) = settings.resolution
        && (w == 0 || h == 0 || w > super::MAX_ATLAS_SIZE || h > super::MAX_ATLAS_SIZE)
    {
        return Err(SurfaceError::Settings(format!("resolution {w}×{h}")));
    }
    let bands = settings.sh_bands;
    let basis = settings.basis.basis();
    let matrix = sh_to_basis_matrix(basis.as_ref(), bands);
    let factors: Vec<f64> = (0..bands * bands)
        .map(|j| cosine_lobe_factor(j.isqrt() as u32) * settings.quantity.scale())
        .collect();
    let max_candidates = match settings.invalid {
        InvalidTexels::Fix => settings.samples.get().saturating_mul(settings.max_candidates_factor),
        InvalidTexels::Keep => settings.samples.get(),
    };
    // Atlases first (all UV errors before any tracing).
    let mut atlases = Vec::new();
    for (o, obj) in geo.objects().iter().enumerate() {
        let size = match settings.resolution {
            Some(r) => r,
            None => atlas_size(obj, settings.texels_per_unit)?,
        };
        atlases.push(Atlas::build(geo, o, size)?);
    }
    Ok(Prepared { atlases, matrix, factors, max_candidates })
}

/// Integrates the covered texels of shard `K` of `N` of a surface bake: footprints
/// `⌊T·K/N⌋..⌊T·(K+1)/N⌋` of the `T` footprints of every object. Each texel's result
/// depends only on `(seed, object, texel)`, so shards computed anywhere, merged by
/// [`assemble_surface`], give the whole bake's maps bit for bit.
///
/// # Errors
/// As [`bake_surface`], and [`SurfaceError::Settings`] for an invalid shard.
pub fn bake_surface_texels(
    transport: &Transport<'_>,
    geo: &SurfaceGeometry,
    settings: &SurfaceSettings,
    control: &BakeControl<'_>,
    shard: (u32, u32),
) -> Result<SurfaceTexels, SurfaceError> {
    let (k, n) = shard;
    if n == 0 || k >= n {
        return Err(SurfaceError::Settings(format!("shard {k} of {n}")));
    }
    let prep = prepare(geo, settings)?;
    let total: u64 = prep.atlases.iter().map(|a| a.footprints.len() as u64).sum();
    let (lo, hi) = (total * u64::from(k) / u64::from(n), total * (u64::from(k) + 1) / u64::from(n));
    let mut records = Vec::with_capacity((hi - lo) as usize);
    let chunk = settings.chunk.max(1);
    let mut first = 0u64;
    let mut done = 0usize;
    for (o, atlas) in prep.atlases.iter().enumerate() {
        let count = atlas.footprints.len() as u64;
        let (a, b) = (lo.max(first).min(first + count), hi.max(first).min(first + count));
        if a < b {
            let job = TexelJob {
                transport,
                geo,
                size: [atlas.width, atlas.height],
                object: o as u32,
                seed: settings.seed,
                samples: settings.samples,
                max_candidates: prep.max_candidates,
                light_sampling: settings.light_sampling,
                invalid: settings.invalid,
                bands: settings.sh_bands,
                factors: prep.factors.clone(),
                matrix: &prep.matrix,
            };
            let fps = &atlas.footprints[(a - first) as usize..(b - first) as usize];
            for (c, part) in fps.chunks(chunk).enumerate() {
                let outs: Vec<Option<TexelOut>> = part
                    .par_iter()
                    .map(|fp| {
                        if control.cancelled() {
                            return None;
                        }
                        Some(job.run(fp))
                    })
                    .collect();
                if control.cancelled() || outs.iter().any(Option::is_none) {
                    return Err(SurfaceError::Cancelled);
                }
                for (j, out) in outs.into_iter().flatten().enumerate() {
                    records.push(TexelRecord {
                        index: a + (c * chunk + j) as u64,
                        coeffs: out.coeffs.map(|cs| cs.iter().map(|v| v.map(|x| x as f32)).collect()),
                        invalid: out.invalid_points > 0,
                        rays: out.rays,
                    });
                }
                done += part.len();
                control.report(Progress { done, total: (hi - lo) as usize });
            }
        }
        first += count;
    }
    Ok(SurfaceTexels { total, records })
}

/// Builds the maps from texel records (of one whole bake, or of every shard of one, in
/// any order): stores each texel, then runs the dilation passes per object in index order
/// exactly as the whole bake does.
///
/// # Errors
/// As [`bake_surface`] before tracing, and [`SurfaceError::Settings`] when the records do
/// not cover every footprint exactly once.
pub fn assemble_surface(
    transport: &Transport<'_>,
    geo: &SurfaceGeometry,
    settings: &SurfaceSettings,
    records: &[TexelRecord],
) -> Result<SurfaceBake, SurfaceError> {
    let prep = prepare(geo, settings)?;
    let total: u64 = prep.atlases.iter().map(|a| a.footprints.len() as u64).sum();
    let mut by_index: Vec<Option<&TexelRecord>> = vec![None; total as usize];
    for r in records {
        let slot = by_index.get_mut(r.index as usize).ok_or_else(|| {
            SurfaceError::Settings(format!("texel record {} of {total} footprints", r.index))
        })?;
        if slot.replace(r).is_some() {
            return Err(SurfaceError::Settings(format!("texel {} is given twice", r.index)));
        }
    }
    if let Some(missing) = by_index.iter().position(Option::is_none) {
        let count = by_index.iter().filter(|r| r.is_none()).count();
        return Err(SurfaceError::Settings(format!(
            "{count} of {total} texels are missing (first: {missing})"
        )));
    }
    let k = settings.basis.basis().len();
    let lighting = lighting_fingerprint(transport.scene(), transport.settings());
    let mut report = SurfaceReport { objects: prep.atlases.len(), ..SurfaceReport::default() };
    let mut maps = Vec::new();
    let mut first = 0usize;
    for (o, atlas) in prep.atlases.iter().enumerate() {
        let n = atlas.width as usize * atlas.height as usize;
        let mut data = vec![[0.0f32; 3]; n * k];
        let mut state = vec![TexelState::Empty; n];
        let mut keys: Vec<Option<TexelKey>> = vec![None; n];
        for fp in &atlas.footprints {
            let normal = geo.geometric_normal(fp.pieces[0].tri);
            keys[fp.texel as usize] = Some(TexelKey { chart: fp.chart, normal });
        }
        let mut invalid = InvalidCounts::default();
        for (j, fp) in atlas.footprints.iter().enumerate() {
            let out = by_index[first + j].expect("checked above");
            let t = fp.texel as usize;
            report.texels_covered += 1;
            report.rays.add(&out.rays);
            if out.invalid {
                invalid.invalid_texels += 1;
            }
            match &out.coeffs {
                Some(c) => {
                    if c.len() != k {
                        return Err(SurfaceError::Settings(format!(
                            "texel {} has {} coefficients, the basis {k}",
                            out.index,
                            c.len()
                        )));
                    }
                    data[t * k..(t + 1) * k].copy_from_slice(c);
                    state[t] = TexelState::Baked;
                    if out.invalid && settings.invalid == InvalidTexels::Fix {
                        invalid.moved += 1;
                    }
                }
                None => state[t] = TexelState::NeedsFill,
            }
        }
        first += atlas.footprints.len();
        let d = dilate(&mut data, &mut state, &mut keys, [atlas.width, atlas.height], k, settings.gutter);
        invalid.dilated = d.dilated;
        invalid.unfilled = d.unfilled;
        report.invalid_texels += invalid.invalid_texels;
        report.moved += invalid.moved;
        report.dilated += invalid.dilated;
        report.unfilled += invalid.unfilled;
        report.gutter_texels += d.gutter;
        let valid = state.iter().map(|s| s.valid_value()).collect();
        maps.push(CoefficientMap {
            object: geo.objects()[o].name.clone(),
            width: atlas.width,
            height: atlas.height,
            basis: settings.basis,
            coeffs: k,
            texels_per_unit: settings.texels_per_unit,
            quantity: settings.quantity,
            uv_set: settings.uv_set,
            data,
            valid,
            lighting: lighting.clone(),
            invalid,
        });
    }
    Ok(SurfaceBake { maps, report })
}
