//! `lightvol bake-surface`: coefficient maps for lightmapped, normal-mapped surfaces
//! (\[Ish11\] §2.2): per texel, incident radiance over the tangent-space hemisphere is path
//! traced, projected to SH, convolved with the clamped cosine and converted to a hemispherical
//! basis (lightvol-sampler's `surface` module).
//!
//! Output in `DIR` (created after the bake succeeded; nothing is written when anything
//! fails):
//! - `<basis>.exr`: one part per lightmap object, f32 coefficients and a validity channel;
//! - `<basis>.json`: the summary printed by `--json` (texel counts, invalid texels, the
//!   irradiance error of each storage encoding, bytes per texel, files);
//! - with `--encode png|ktx2` (and/or `--compress bc1|bc7`): `<basis>/<object>_cKK.png|ktx2`,
//!   one 8-bit texture per coefficient as \[Ish11\] Listing 2.2 samples them: the DC
//!   coefficient through the sRGB curve (KTX2: an `_SRGB` format, decoded by the sampler),
//!   the others range-compressed by `--range` (0.75, §2.2.3). Coefficients are scaled by
//!   `encode_scale` first (recorded in the JSON and in each KTX2 file's `lightvol.plane`
//!   entry; a shader multiplies the decoded sum by `1 / encode_scale`).

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use anyhow::{Context, bail};
use clap::{Args, ValueEnum};
use lightvol_hemibasis::HemiBasis;
use lightvol_hemibasis::bc::{self, BlockFormat, CompressedPlane};
use lightvol_hemibasis::encode::{ClampStats, DcTransfer, Encoding};
use lightvol_hemibasis::map::{CoeffMap, MapError, Plane, map_error};
use lightvol_hemibasis::plane_ktx2::{ktx2_compressed, ktx2_rgba8};
use lightvol_sampler::surface::{
    BasisChoice, CoefficientMap, InvalidTexels, Quantity, SurfaceGeometry, SurfaceReport, SurfaceSettings,
    UvSet, assemble_surface, bake_surface, bake_surface_texels, write_surface_exr,
};
use lightvol_sampler::{BakeControl, Progress, Tracer, Transport, TransportSettings};
use rayon::prelude::*;
use serde::Serialize;

use crate::imaging::{write_atomic, write_png_rgb8};
use crate::progress::progress_bar;
use crate::report_parts::RaysJson;
use crate::setup::{SceneArgs, with_threads};
use lightvol_sampler::surface::shard_io::{TexelSetError, TexelShardHeader, texel_set_records, write_texels};

/// What shards of one surface bake share: the scene's geometry and lighting, every setting
/// and the lightvol version.
fn shard_fingerprint(
    loaded: &crate::setup::LoadedScene,
    settings: &SurfaceSettings,
    ts: &TransportSettings,
) -> String {
    use lightvol_sampler::provenance::{scene_hash, surface_key};
    scene_hash(&loaded.scene, &surface_key(&loaded.scene, settings, ts))
}

/// The texel records of basis `tag` from `--from-shards` (lightvol-sampler's
/// `surface::shard_io::texel_set_records`).
fn shard_records(
    files: &[PathBuf],
    tag: &str,
    fingerprint: &str,
) -> anyhow::Result<Vec<lightvol_sampler::surface::TexelRecord>> {
    texel_set_records(files, tag, fingerprint).map_err(|e| match e {
        TexelSetError::NoShards(tag) => {
            anyhow::anyhow!("no texel shard of basis {tag} among the --from-shards files")
        }
        e => e.into(),
    })
}

/// 8-bit texture container for `--encode`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub(crate) enum EncodeFormat {
    /// One RGB PNG per coefficient (DC plane sRGB-encoded).
    Png,
    /// One KTX2 per coefficient: RGBA8 (`R8G8B8A8_SRGB` for the DC plane, `_UNORM` else),
    /// or BC1/BC7 blocks with `--compress`.
    Ktx2,
}

/// Block compression for `--compress`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub(crate) enum CompressFormat {
    /// BC1 (DXT1), 0.5 bytes per texel and coefficient (Ishmukhametov 2011 §2.2.4).
    Bc1,
    /// BC7, 1 byte per texel and coefficient.
    Bc7,
}

impl CompressFormat {
    fn block(self) -> BlockFormat {
        match self {
            Self::Bc1 => BlockFormat::Bc1,
            Self::Bc7 => BlockFormat::Bc7,
        }
    }
}

/// `lightvol bake-surface`.
#[derive(Debug, Args)]
pub(crate) struct BakeSurfaceArgs {
    /// Scene (a glTF file: lightmap objects are its mesh instances) and lights.
    #[command(flatten)]
    pub(crate) scene: SceneArgs,
    /// Basis, or a comma-separated list baked one after another with the same seed: sh4,
    /// sh9, hl2, hsh4, hsh9, makhotkin4, makhotkin9, zernike3, zernike6, hbasis4, hbasis6,
    /// hbasis_mod4, hbasis_mod6 (those whose lightvol-hemibasis feature is enabled).
    #[arg(long, default_value = "hbasis_mod6")]
    pub(crate) basis: String,
    /// Texel density D: every triangle gets at least D texels per world unit.
    #[arg(long, default_value_t = 32.0)]
    pub(crate) texels_per_unit: f64,
    /// Fixed atlas size `W,H` for every object (overrides the density).
    #[arg(long, value_name = "W,H")]
    pub(crate) resolution: Option<String>,
    /// Lightmap UV set: 1 = TEXCOORD_1 (default), 0 = TEXCOORD_0.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u8).range(0..=1))]
    pub(crate) uv: u8,
    /// Also write 8-bit textures (Ishmukhametov 2011 §2.2.3 encoding).
    #[arg(long, value_enum)]
    pub(crate) encode: Option<EncodeFormat>,
    /// Block-compress the 8-bit textures (KTX2 containers; implies `--encode ktx2`); a
    /// comma-separated list writes and measures each.
    #[arg(long, value_enum, value_delimiter = ',')]
    pub(crate) compress: Vec<CompressFormat>,
    /// Range compression of the non-DC coefficients: `[-r, r]` maps to `[0, 1]`.
    #[arg(long, default_value_t = 0.75)]
    pub(crate) range: f64,
    /// Scale applied before 8-bit encoding (default: 1 / the largest DC value, or `range`
    /// / the largest |coefficient| for bases without a DC term).
    #[arg(long)]
    pub(crate) encode_scale: Option<f64>,
    /// What the maps hold: `irradiance` (`E`, a sky of radiance L gives π L) or `radiosity`
    /// (`E / π`, Ishmukhametov 2011 Eq. 2.3's normalised convolution).
    #[arg(long, value_parser = ["irradiance", "radiosity"], default_value = "irradiance")]
    pub(crate) quantity: String,
    /// SH bands of the intermediate hemisphere projection (Ishmukhametov 2011 §2.2.1 uses 3).
    #[arg(long, default_value_t = 3)]
    pub(crate) sh_bands: usize,
    /// Dilation passes into empty atlas texels around the charts.
    #[arg(long, default_value_t = 2)]
    pub(crate) gutter: u32,
    /// Keep invalid texels (sample points that see back faces) as they are: the ablation
    /// that shows the dark leak under intersecting geometry.
    #[arg(long)]
    pub(crate) no_invalid_fix: bool,
    /// In-domain path samples per texel.
    #[arg(long, default_value_t = 256)]
    pub(crate) samples: u32,
    /// Path length and direct light.
    #[command(flatten)]
    pub(crate) path: crate::setup::PathArgs,
    /// Seed of every random stream (results are bit-identical for a seed).
    #[arg(long, default_value_t = 1)]
    pub(crate) seed: u64,
    /// Worker threads (default: all cores). Results do not depend on it.
    #[arg(long)]
    pub(crate) threads: Option<usize>,
    /// Output directory.
    #[arg(short, long, default_value = "surface")]
    pub(crate) output: PathBuf,
    /// Integrate only shard K of N of every basis's texels (or `auto`, from the scheduler,
    /// as `bake --shard auto`) and write them to `OUT/texels-BASIS-K-of-N.lvtex`; no maps.
    /// `--from-shards` assembles the maps from all shards, equal to the whole bake's.
    #[arg(long, value_name = "K/N|auto", conflicts_with = "from_shards")]
    pub(crate) shard: Option<String>,
    /// Number of shards for `--shard auto` with Kubernetes or AWS Batch indices.
    #[arg(long, value_name = "N")]
    pub(crate) shards: Option<u32>,
    /// Assemble the maps from these texel shard files (every shard of every basis, baked
    /// with the same scene and options) instead of tracing.
    #[arg(long, value_name = "FILE.lvtex", num_args = 1..)]
    pub(crate) from_shards: Vec<PathBuf>,
    /// Print the summary as JSON on stdout.
    #[arg(long)]
    pub(crate) json: bool,
    /// No progress bar.
    #[arg(long)]
    pub(crate) quiet: bool,
}

/// Error of one storage encoding, measured on the covered texels.
#[derive(Debug, Serialize, Clone)]
pub(crate) struct EncodingJson {
    /// Relative RMS irradiance error over covered texels, channels and the hemisphere of
    /// normals (exact, `Δcᵀ G Δc`), against the f32 maps.
    pub(crate) rel_rms: f64,
    /// The same, absolute (in the maps' units, before `encode_scale`).
    pub(crate) rms: f64,
    /// Largest coefficient error (after `encode_scale`, i.e. in stored units).
    pub(crate) max_coeff_error: f64,
    /// Values clamped: DC outside `[0, 1]`, others outside `[-range, range]`.
    pub(crate) clamped: [usize; 2],
    /// Bytes per texel of this storage (all coefficients), as named by [`Self::storage`].
    pub(crate) bytes_per_texel: f64,
    /// The storage `bytes_per_texel` counts: `"RGB8 PNG"` (3 bytes per coefficient; also
    /// given when no textures were written), `"RGBA8 KTX2"` (4 bytes per coefficient: the
    /// alpha byte is stored), `"BC1 KTX2"` (0.5) or `"BC7 KTX2"` (1).
    pub(crate) storage: String,
}

/// One object's map in the summary.
#[derive(Debug, Serialize, Clone)]
pub(crate) struct ObjectJson {
    /// Object (mesh instance) name.
    pub(crate) name: String,
    /// Atlas width.
    pub(crate) width: u32,
    /// Atlas height.
    pub(crate) height: u32,
}

/// The summary of one basis's bake (`<basis>.json`, `--json`).
#[derive(Debug, Serialize, Clone)]
pub(crate) struct SurfaceBakeJson {
    /// Scene label.
    pub(crate) scene: String,
    /// Basis tag.
    pub(crate) basis: String,
    /// Coefficients per channel.
    pub(crate) coefficients: usize,
    /// Lightmap UV set.
    pub(crate) uv_set: String,
    /// Texel density.
    pub(crate) texels_per_unit: f64,
    /// Samples per texel.
    pub(crate) samples: u32,
    /// Seed.
    pub(crate) seed: u64,
    /// `"irradiance"` or `"radiosity"`.
    pub(crate) quantity: String,
    /// What lit the bake (`lightvol_sampler::surface::lighting_fingerprint`, also stored in
    /// the EXR; `render --surface` refuses maps whose lighting differs from its own).
    pub(crate) lighting: String,
    /// Whether invalid texels were fixed (domain of interest + dilation).
    pub(crate) invalid_fix: bool,
    /// Objects and their atlas sizes.
    pub(crate) objects: Vec<ObjectJson>,
    /// Texels covered by geometry.
    pub(crate) texels_covered: u64,
    /// Covered texels whose sample points saw back faces.
    pub(crate) invalid_texels: u64,
    /// … of which re-sampled inside the valid part of the footprint.
    pub(crate) moved: u64,
    /// … of which dilated from valid neighbours.
    pub(crate) dilated: u64,
    /// … of which no valid neighbour reached.
    pub(crate) unfilled: u64,
    /// Empty texels filled by the gutter dilation.
    pub(crate) gutter_texels: u64,
    /// Rays traced.
    pub(crate) rays: RaysJson,
    /// Bake wall time: in the `--json` output only, left out of `<basis>.json` (a timing
    /// would make two bakes of the same input write different files).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub(crate) seconds: Option<f64>,
    /// Scale applied before 8-bit encoding.
    pub(crate) encode_scale: f64,
    /// Range compression factor.
    pub(crate) range: f64,
    /// Irradiance error per storage: `rgb8` always, `bc1`/`bc7` when compressed.
    pub(crate) encodings: std::collections::BTreeMap<String, EncodingJson>,
    /// Bytes per texel of the f32 EXR coefficients (all coefficients, RGB).
    pub(crate) f32_bytes_per_texel: usize,
    /// Files written, relative to the output directory.
    pub(crate) files: Vec<String>,
}

/// Parses `W,H`.
fn parse_resolution(s: &str) -> anyhow::Result<[u32; 2]> {
    let (w, h) = s.split_once(',').with_context(|| format!("--resolution: expected W,H, got '{s}'"))?;
    let p = |t: &str| -> anyhow::Result<u32> {
        let v: u32 =
            t.trim().parse().with_context(|| format!("--resolution: '{t}' is not a whole number"))?;
        if v == 0 {
            bail!("--resolution: sizes must be positive");
        }
        Ok(v)
    };
    Ok([p(w)?, p(h)?])
}

/// The covered texels (`valid > 0`) of `maps` as one `N × 1` [`CoeffMap`], and the same
/// texels of `decoded` (per object, in the same order).
fn covered(maps: &[CoefficientMap], decoded: &[CoeffMap]) -> (CoeffMap, CoeffMap) {
    let k = maps[0].coeffs;
    let (mut a, mut b) = (Vec::new(), Vec::new());
    for (m, d) in maps.iter().zip(decoded) {
        for (i, &v) in m.valid.iter().enumerate() {
            if v > 0.0 {
                a.extend_from_slice(&m.data[i * k..(i + 1) * k]);
                b.extend_from_slice(&d.data[i * k..(i + 1) * k]);
            }
        }
    }
    let n = a.len() / k.max(1);
    (CoeffMap { width: n, height: 1, len: k, data: a }, CoeffMap { width: n, height: 1, len: k, data: b })
}

/// `map` scaled by `s`, as a hemibasis [`CoeffMap`].
pub(crate) fn scaled_map(map: &CoefficientMap, s: f64) -> CoeffMap {
    CoeffMap {
        width: map.width as usize,
        height: map.height as usize,
        len: map.coeffs,
        data: map.data.iter().map(|c| c.map(|v| (f64::from(v) * s) as f32)).collect(),
    }
}

/// The default encoding scale: `1 / max DC` over covered texels, or `range / max |c|` for
/// bases without a DC term (Half-Life 2), or 1 for an all-zero map.
pub(crate) fn default_encode_scale(basis: &dyn HemiBasis, maps: &[CoefficientMap], range: f64) -> f64 {
    let k = basis.len();
    let mut peak: f64 = 0.0;
    for m in maps {
        for (i, &v) in m.valid.iter().enumerate() {
            if v <= 0.0 {
                continue;
            }
            let t = &m.data[i * k..(i + 1) * k];
            peak = match basis.dc_index() {
                Some(dc) => t[dc].iter().fold(peak, |p, &c| p.max(f64::from(c))),
                None => t.iter().flatten().fold(peak, |p, &c| p.max(f64::from(c).abs() / range)),
            };
        }
    }
    if peak > 0.0 { 1.0 / peak } else { 1.0 }
}

/// 8-bit planes of every object (one per coefficient), their block-compressed versions
/// (when asked), and the irradiance error of each storage against the f32 maps.
struct Stored {
    /// `[object][coefficient]` RGBA8 planes.
    planes: Vec<Vec<Plane>>,
    /// Error and clamp counts of the 8-bit storage.
    rgb8: (MapError, ClampStats),
    /// Per `--compress` format: `[object][coefficient]` blocks and the error of that storage
    /// (the 8-bit step included).
    blocks: Vec<(BlockFormat, Vec<Vec<CompressedPlane>>, MapError)>,
}

/// Encodes `maps` (scaled by `scale`) into 8-bit planes, block-compresses them to each of
/// `formats` (planes in parallel: BC7 runs at ~0.2 Mtexel/s per core), and measures every
/// storage on the covered texels, in the maps' own units.
fn store(
    basis: &dyn HemiBasis,
    maps: &[CoefficientMap],
    enc: &Encoding,
    scale: f64,
    formats: &[BlockFormat],
) -> Stored {
    let mut clamped = ClampStats::default();
    let mut planes = Vec::with_capacity(maps.len());
    for m in maps {
        let (p, c) = enc.encode_map(basis, &scaled_map(m, scale));
        clamped.dc_clamped += c.dc_clamped;
        clamped.ac_clamped += c.ac_clamped;
        planes.push(p);
    }
    let error = |decoded: &[CoeffMap]| -> MapError {
        let (orig, back) = covered(maps, decoded);
        if orig.width == 0 {
            return MapError { rms: 0.0, rel_rms: 0.0, max_coeff_error: 0.0 };
        }
        // `back` is in scaled units: compare with the scaled originals, report rms unscaled.
        let orig = CoeffMap {
            data: orig.data.iter().map(|c| c.map(|v| (f64::from(v) * scale) as f32)).collect(),
            ..orig
        };
        let mut e = map_error(basis, &orig, &back);
        e.rms /= scale;
        e
    };
    let decoded: Vec<CoeffMap> = planes.iter().map(|p| enc.decode_map(basis, p)).collect();
    let rgb8 = (error(&decoded), clamped);
    let blocks = formats
        .iter()
        .map(|&f| {
            let compressed: Vec<Vec<CompressedPlane>> =
                planes.iter().map(|ps| ps.par_iter().map(|p| bc::compress(p, f)).collect()).collect();
            let decoded: Vec<CoeffMap> = compressed
                .iter()
                .map(|cs| enc.decode_map(basis, &cs.iter().map(bc::decompress).collect::<Vec<_>>()))
                .collect();
            let e = error(&decoded);
            (f, compressed, e)
        })
        .collect();
    Stored { planes, rgb8, blocks }
}

/// A file name fragment safe on every file system.
fn safe_name(s: &str) -> String {
    s.chars()
        .map(|c| if c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.') { c } else { '_' })
        .collect()
}

/// Runs `lightvol bake-surface`.
pub(crate) fn run(args: &BakeSurfaceArgs) -> anyhow::Result<ExitCode> {
    // Every option is checked before any work.
    let bases: Vec<BasisChoice> = args
        .basis
        .split(',')
        .map(|b| BasisChoice::parse(b.trim()))
        .collect::<Result<_, _>>()
        .context("--basis")?;
    if !(args.texels_per_unit.is_finite() && args.texels_per_unit > 0.0) {
        bail!("--texels-per-unit must be a positive finite number");
    }
    if args.samples == 0 {
        bail!("--samples must be at least 1");
    }
    if !(args.range.is_finite() && args.range > 0.0) {
        bail!("--range must be a positive finite number");
    }
    if let Some(s) = args.encode_scale
        && !(s.is_finite() && s > 0.0)
    {
        bail!("--encode-scale must be a positive finite number");
    }
    let encode = match (args.encode, args.compress.is_empty()) {
        (Some(EncodeFormat::Png), false) => {
            bail!("--compress writes block-compressed KTX2 files: use --encode ktx2 (or leave --encode out)")
        }
        (None, false) => Some(EncodeFormat::Ktx2),
        (e, _) => e,
    };
    let mut formats: Vec<BlockFormat> = args.compress.iter().map(|c| c.block()).collect();
    formats.dedup();
    let resolution = args.resolution.as_deref().map(parse_resolution).transpose()?;
    let quantity = Quantity::from_name(&args.quantity)
        .with_context(|| format!("--quantity: '{}' is neither irradiance nor radiosity", args.quantity))?;
    if args.output.exists() && !args.output.is_dir() {
        bail!("output {} exists and is not a directory", args.output.display());
    }
    let shard = match lightvol_sampler::shard::resolve_shard(args.shard.as_deref(), args.shards, |k| {
        std::env::var(k).ok()
    })? {
        (0, 1) if args.shard.is_none() => None,
        s => Some(s),
    };
    let loaded = args.scene.load_flattened()?;
    let uv_set = if args.uv == 0 { UvSet::Base } else { UvSet::Lightmap };
    let ts = args.path.transport();

    // Bake every basis (nothing is written until all succeeded).
    let mut bakes = Vec::with_capacity(bases.len());
    with_threads(args.threads, || -> anyhow::Result<()> {
        let tracer = Tracer::new(&loaded.scene);
        let transport = Transport::new(&loaded.scene, &tracer, ts);
        for basis in &bases {
            let settings = SurfaceSettings {
                basis: *basis,
                uv_set,
                texels_per_unit: args.texels_per_unit,
                resolution,
                samples: args.samples,
                invalid: if args.no_invalid_fix { InvalidTexels::Keep } else { InvalidTexels::Fix },
                quantity,
                sh_bands: args.sh_bands,
                gutter: args.gutter,
                seed: args.seed,
                ..SurfaceSettings::default()
            };
            let pb = progress_bar(args.quiet, 0, &basis.tag());
            let report = |p: Progress| {
                pb.set_length(p.total as u64);
                pb.set_position(p.done as u64);
            };
            let control = BakeControl { progress: Some(&report), cancel: None };
            let t0 = Instant::now();
            let fingerprint = shard_fingerprint(&loaded, &settings, &ts);
            if let Some(shard) = shard {
                let geo = SurfaceGeometry::new(&loaded.scene, settings.uv_set).context("lightmap objects")?;
                let part = bake_surface_texels(&transport, &geo, &settings, &control, shard)
                    .with_context(|| format!("baking {} shard {}/{}", basis.tag(), shard.0, shard.1))?;
                pb.finish_and_clear();
                let header = TexelShardHeader {
                    shard_index: shard.0,
                    shard_count: shard.1,
                    total: part.total,
                    coeffs: basis.coeffs(),
                    basis: basis.tag().to_owned(),
                    fingerprint,
                    records: part.records.len() as u64,
                };
                std::fs::create_dir_all(&args.output)
                    .with_context(|| format!("creating {}", args.output.display()))?;
                let p = args.output.join(format!("texels-{}-{}-of-{}.lvtex", basis.tag(), shard.0, shard.1));
                write_texels(&p, &part, &header).with_context(|| format!("writing {}", p.display()))?;
                if !args.quiet {
                    eprintln!("wrote {} ({} of {} texels)", p.display(), part.records.len(), part.total);
                }
                continue;
            }
            let out = if args.from_shards.is_empty() {
                bake_surface(&transport, &settings, &control)
                    .with_context(|| format!("baking {}", basis.tag()))?
            } else {
                let records = shard_records(&args.from_shards, &basis.tag(), &fingerprint)?;
                let geo = SurfaceGeometry::new(&loaded.scene, settings.uv_set).context("lightmap objects")?;
                assemble_surface(&transport, &geo, &settings, &records)
                    .with_context(|| format!("assembling {} from its shards", basis.tag()))?
            };
            pb.finish_and_clear();
            bakes.push((*basis, out, t0.elapsed().as_secs_f64()));
        }
        Ok(())
    })??;

    if shard.is_some() {
        return Ok(ExitCode::SUCCESS);
    }

    // Encode in memory, then write.
    let mut outputs: Vec<(PathBuf, Vec<u8>)> = Vec::new();
    let mut pngs: Vec<(PathBuf, usize, usize, Vec<u8>)> = Vec::new();
    let mut summaries = Vec::with_capacity(bakes.len());
    for (choice, out, seconds) in &bakes {
        let basis = choice.basis();
        let tag = choice.tag().to_owned();
        let scale =
            args.encode_scale.unwrap_or_else(|| default_encode_scale(basis.as_ref(), &out.maps, args.range));
        // DC through the exact sRGB curve: what `_SRGB` formats and PNG viewers decode.
        let enc = Encoding { range: args.range, dc: DcTransfer::Srgb, quantize_8bit: true };
        let k = basis.len();
        let mut encodings = std::collections::BTreeMap::new();
        let stored = store(basis.as_ref(), &out.maps, &enc, scale, &formats);
        // The 8-bit error is the same for PNG and KTX2; the bytes are those of the file kind
        // written (uncompressed KTX2 is RGBA8).
        let (rgb8_storage, rgb8_bytes) = if encode == Some(EncodeFormat::Ktx2) && formats.is_empty() {
            ("RGBA8 KTX2", 4.0)
        } else {
            ("RGB8 PNG", 3.0)
        };
        encodings.insert(
            "rgb8".to_owned(),
            json_of(&stored.rgb8.0, &stored.rgb8.1, rgb8_bytes * k as f64, rgb8_storage),
        );
        for (f, _, e) in &stored.blocks {
            let storage = format!("{} KTX2", f.name().to_uppercase());
            encodings.insert(
                f.name().to_owned(),
                json_of(e, &stored.rgb8.1, f.bytes_per_texel() * k as f64, &storage),
            );
        }
        let mut files = vec![format!("{tag}.exr"), format!("{tag}.json")];
        if let Some(format) = encode {
            let sub = PathBuf::from(safe_name(&tag));
            for (oi, (m, planes)) in out.maps.iter().zip(&stored.planes).enumerate() {
                for (j, plane) in planes.iter().enumerate() {
                    let dc = basis.dc_index() == Some(j);
                    let stem = format!("{}_c{j:02}", safe_name(&m.object));
                    let desc = serde_json::json!({
                        "basis": tag, "object": m.object, "coefficient": j, "coefficients": k,
                        "encode_scale": scale, "range": args.range,
                        "transfer": if dc { "srgb" } else { "range" },
                        "decode": if dc { "c = srgb_decode(v) / encode_scale" } else { "c = (2 range v - range) / encode_scale" },
                    })
                    .to_string();
                    match format {
                        EncodeFormat::Png => {
                            let rel = sub.join(format!("{stem}.png"));
                            pngs.push((rel.clone(), plane.width, plane.height, plane.rgb_bytes()));
                            files.push(rel.display().to_string());
                        }
                        EncodeFormat::Ktx2 if stored.blocks.is_empty() => {
                            let rel = sub.join(format!("{stem}.ktx2"));
                            outputs.push((rel.clone(), ktx2_rgba8(plane, dc, &desc)));
                            files.push(rel.display().to_string());
                        }
                        EncodeFormat::Ktx2 => {
                            for (f, compressed, _) in &stored.blocks {
                                let rel = sub.join(format!("{stem}.{}.ktx2", f.name()));
                                outputs.push((rel.clone(), ktx2_compressed(&compressed[oi][j], dc, &desc)));
                                files.push(rel.display().to_string());
                            }
                        }
                    }
                }
            }
        }
        summaries.push(summary(
            args,
            &loaded.label,
            choice,
            &out.maps,
            &out.report,
            *seconds,
            scale,
            encodings,
            files,
        ));
    }

    std::fs::create_dir_all(&args.output).with_context(|| format!("creating {}", args.output.display()))?;
    for ((choice, out, _), s) in bakes.iter().zip(&summaries) {
        let tag = choice.tag();
        let exr = args.output.join(format!("{tag}.exr"));
        write_surface_exr(&exr, &out.maps).with_context(|| format!("writing {}", exr.display()))?;
        let json = args.output.join(format!("{tag}.json"));
        // The file holds no timing: equal inputs write equal bytes.
        let file = SurfaceBakeJson { seconds: None, ..s.clone() };
        write_atomic(&json, serde_json::to_string_pretty(&file)?.as_bytes())?;
    }
    for (rel, bytes) in &outputs {
        let path = args.output.join(rel);
        ensure_parent(&path)?;
        write_atomic(&path, bytes)?;
    }
    for (rel, w, h, rgb) in &pngs {
        let path = args.output.join(rel);
        ensure_parent(&path)?;
        write_png_rgb8(&path, *w, *h, rgb)?;
    }
    if args.json {
        let v = if summaries.len() == 1 {
            serde_json::to_value(&summaries[0])?
        } else {
            serde_json::to_value(&summaries)?
        };
        println!("{}", serde_json::to_string_pretty(&v)?);
    } else {
        for s in &summaries {
            let e8 = &s.encodings["rgb8"];
            eprintln!(
                "baked {} ({}): {} objects, {} texels covered, {} invalid ({} moved, {} dilated, {} unfilled) in {:.2} s; 8-bit rel error {:.3}%{}",
                s.scene,
                s.basis,
                s.objects.len(),
                s.texels_covered,
                s.invalid_texels,
                s.moved,
                s.dilated,
                s.unfilled,
                s.seconds.unwrap_or_default(),
                100.0 * e8.rel_rms,
                s.encodings
                    .iter()
                    .filter(|(k, _)| k.as_str() != "rgb8")
                    .map(|(k, e)| format!(", {k} {:.3}%", 100.0 * e.rel_rms))
                    .collect::<String>()
            );
        }
        eprintln!("wrote {}", args.output.display());
    }
    Ok(ExitCode::SUCCESS)
}

fn ensure_parent(path: &Path) -> anyhow::Result<()> {
    if let Some(p) = path.parent() {
        std::fs::create_dir_all(p).with_context(|| format!("creating {}", p.display()))?;
    }
    Ok(())
}

fn json_of(e: &MapError, c: &ClampStats, bytes_per_texel: f64, storage: &str) -> EncodingJson {
    EncodingJson {
        storage: storage.to_owned(),
        rel_rms: e.rel_rms,
        rms: e.rms,
        max_coeff_error: e.max_coeff_error,
        clamped: [c.dc_clamped, c.ac_clamped],
        bytes_per_texel,
    }
}

#[allow(clippy::too_many_arguments, reason = "one summary from the bake's parts")]
fn summary(
    args: &BakeSurfaceArgs,
    label: &str,
    choice: &BasisChoice,
    maps: &[CoefficientMap],
    r: &SurfaceReport,
    seconds: f64,
    scale: f64,
    encodings: std::collections::BTreeMap<String, EncodingJson>,
    files: Vec<String>,
) -> SurfaceBakeJson {
    SurfaceBakeJson {
        scene: label.to_owned(),
        basis: choice.tag().to_owned(),
        coefficients: choice.coeffs(),
        uv_set: maps.first().map_or_else(|| "TEXCOORD_1".to_owned(), |m| m.uv_set.attribute().to_owned()),
        texels_per_unit: args.texels_per_unit,
        samples: args.samples,
        seed: args.seed,
        quantity: maps.first().map_or("irradiance", |m| m.quantity.name()).to_owned(),
        lighting: maps.first().map(|m| m.lighting.clone()).unwrap_or_default(),
        invalid_fix: !args.no_invalid_fix,
        objects: maps
            .iter()
            .map(|m| ObjectJson { name: m.object.clone(), width: m.width, height: m.height })
            .collect(),
        texels_covered: r.texels_covered,
        invalid_texels: r.invalid_texels,
        moved: r.moved,
        dilated: r.dilated,
        unfilled: r.unfilled,
        gutter_texels: r.gutter_texels,
        rays: RaysJson::of(&r.rays),
        seconds: Some(seconds),
        encode_scale: scale,
        range: args.range,
        encodings,
        f32_bytes_per_texel: choice.coeffs() * 12,
        files,
    }
}
