//! `lightvol bake-surface`: coefficient maps for lightmapped, normal-mapped surfaces
//! (\[Ish11\] §2.2): per texel, incident radiance over the tangent-space hemisphere is path
//! traced, projected to SH, convolved with the clamped cosine and converted to a hemispherical
//! basis (lightvol-surface; the textures and their errors come from
//! `surface::storage`).
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

use lightvol_core::samples::{Samples, parse_samples, samples};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use anyhow::{Context, bail};
use clap::{Args, ValueEnum};
use lightvol_hemibasis::bc::BlockFormat;
use lightvol_scene::{Tracer, Transport};
use lightvol_surface::shard_io::{
    TexelSetError, TexelShardHeader, shard_fingerprint, texel_set_records, write_texels,
};
use lightvol_surface::storage::{Container, StorageError, StorageSettings, SurfaceBakeSummary, store_maps};
use lightvol_surface::{
    BasisChoice, InvalidTexels, Quantity, SurfaceGeometry, SurfaceSettings, UvSet, assemble_surface,
    bake_surface, bake_surface_texels, write_surface_exr,
};

use crate::imaging::write_atomic;
use crate::progress::with_bar;
use crate::setup::{SceneArgs, resolve_threads, shard_option, with_threads};

/// The texel records of basis `tag` from `--from-shards` (lightvol-surface's
/// `shard_io::texel_set_records`).
fn shard_records(
    files: &[PathBuf],
    tag: &str,
    fingerprint: &str,
) -> anyhow::Result<Vec<lightvol_surface::TexelRecord>> {
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
    texels_per_unit: f64,
    /// Fixed atlas size `W,H` for every object (overrides the density).
    #[arg(long, value_name = "W,H")]
    pub(crate) resolution: Option<String>,
    /// Lightmap UV set: 1 = TEXCOORD_1 (default), 0 = TEXCOORD_0.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u8).range(0..=1))]
    uv: u8,
    /// Also write 8-bit textures (Ishmukhametov 2011 §2.2.3 encoding).
    #[arg(long, value_enum)]
    encode: Option<EncodeFormat>,
    /// Block-compress the 8-bit textures (KTX2 containers; implies `--encode ktx2`); a
    /// comma-separated list writes and measures each.
    #[arg(long, value_enum, value_delimiter = ',')]
    compress: Vec<CompressFormat>,
    /// Range compression of the non-DC coefficients: `[-r, r]` maps to `[0, 1]`.
    #[arg(long, default_value_t = 0.75)]
    pub(crate) range: f64,
    /// Scale applied before 8-bit encoding (default: 1 / the largest DC value, or `range`
    /// / the largest |coefficient| for bases without a DC term).
    #[arg(long)]
    encode_scale: Option<f64>,
    /// What the maps hold: `irradiance` (`E`, a sky of radiance L gives π L) or `radiosity`
    /// (`E / π`, Ishmukhametov 2011 Eq. 2.3's normalised convolution).
    #[arg(long, value_parser = ["irradiance", "radiosity"], default_value = "irradiance")]
    pub(crate) quantity: String,
    /// SH bands of the intermediate hemisphere projection (Ishmukhametov 2011 §2.2.1 uses 3).
    #[arg(long, default_value_t = 3)]
    sh_bands: usize,
    /// Dilation passes into empty atlas texels around the charts.
    #[arg(long, default_value_t = 2)]
    gutter: u32,
    /// Keep invalid texels (sample points that see back faces) as they are: the ablation
    /// that shows the dark leak under intersecting geometry.
    #[arg(long)]
    no_invalid_fix: bool,
    /// In-domain path samples per texel.
    #[arg(long, value_parser = parse_samples, default_value_t = samples(256))]
    pub(crate) samples: Samples,
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

/// The storage options as lightvol-sampler's settings, checked, with the library's errors
/// named by their options.
fn storage_settings(args: &BakeSurfaceArgs) -> anyhow::Result<StorageSettings> {
    let settings = StorageSettings {
        range: args.range,
        encode_scale: args.encode_scale,
        container: args.encode.map(|e| match e {
            EncodeFormat::Png => Container::Png,
            EncodeFormat::Ktx2 => Container::Ktx2,
        }),
        compress: args.compress.iter().map(|c| c.block()).collect(),
    };
    settings.validate().map_err(|e| match e {
        StorageError::Range => anyhow::anyhow!("--range must be a positive finite number"),
        StorageError::Scale => anyhow::anyhow!("--encode-scale must be a positive finite number"),
        StorageError::CompressedPng => anyhow::anyhow!(
            "--compress writes block-compressed KTX2 files: use --encode ktx2 (or leave --encode out)"
        ),
        e => e.into(),
    })?;
    Ok(settings)
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
    let storage = storage_settings(args)?;
    let resolution = args.resolution.as_deref().map(parse_resolution).transpose()?;
    let quantity = Quantity::from_name(&args.quantity)
        .with_context(|| format!("--quantity: '{}' is neither irradiance nor radiosity", args.quantity))?;
    if args.output.exists() && !args.output.is_dir() {
        bail!("output {} exists and is not a directory", args.output.display());
    }
    let shard = shard_option(args.shard.as_deref(), args.shards)?;
    // A texel's samples are held while it is integrated: refuse counts that cannot fit
    // in half the available memory on the threads the bake runs, before anything loads.
    let threads = resolve_threads(args.threads)?.unwrap_or_else(rayon::current_num_threads);
    lightvol_sampler::scene_setup::check_sample_memory(
        u64::from(args.samples.get()),
        threads,
        lightvol_surface::texel::SAMPLE_BYTES,
        lightvol_sampler::scene_setup::memory_limit(None),
    )
    .map_err(|e| anyhow::anyhow!("{e} (lower --samples)"))?;
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
            let t0 = Instant::now();
            let fingerprint = shard_fingerprint(&loaded.scene, &settings, &ts);
            if let Some(shard) = shard {
                let part = with_bar(args.quiet, &basis.tag(), |control| -> anyhow::Result<_> {
                    let geo =
                        SurfaceGeometry::new(&loaded.scene, settings.uv_set).context("lightmap objects")?;
                    bake_surface_texels(&transport, &geo, &settings, control, shard)
                        .with_context(|| format!("baking {} shard {}/{}", basis.tag(), shard.0, shard.1))
                })?;
                let header = TexelShardHeader::new(&settings, fingerprint, &part, shard);
                std::fs::create_dir_all(&args.output)
                    .with_context(|| format!("creating {}", args.output.display()))?;
                let p = args.output.join(header.file_name());
                write_texels(&p, &part, &header).with_context(|| format!("writing {}", p.display()))?;
                if !args.quiet {
                    eprintln!("wrote {} ({} of {} texels)", p.display(), part.records.len(), part.total);
                }
                continue;
            }
            let out = with_bar(args.quiet, &basis.tag(), |control| -> anyhow::Result<_> {
                if args.from_shards.is_empty() {
                    return bake_surface(&transport, &settings, control)
                        .with_context(|| format!("baking {}", basis.tag()));
                }
                let records = shard_records(&args.from_shards, &basis.tag(), &fingerprint)?;
                let geo = SurfaceGeometry::new(&loaded.scene, settings.uv_set).context("lightmap objects")?;
                assemble_surface(&transport, &geo, &settings, &records)
                    .with_context(|| format!("assembling {} from its shards", basis.tag()))
            })?;
            bakes.push((settings, out, t0.elapsed().as_secs_f64()));
        }
        Ok(())
    })??;

    if shard.is_some() {
        return Ok(ExitCode::SUCCESS);
    }

    // Encode in memory, then write.
    let mut stored = Vec::with_capacity(bakes.len());
    let mut summaries = Vec::with_capacity(bakes.len());
    for (settings, out, seconds) in &bakes {
        let maps = store_maps(&settings.basis, &out.maps, &storage)
            .with_context(|| format!("storing {}", settings.basis.tag()))?;
        summaries.push(SurfaceBakeSummary::new(
            &loaded.label,
            settings,
            out,
            &maps,
            args.range,
            Some(*seconds),
        ));
        stored.push(maps);
    }

    std::fs::create_dir_all(&args.output).with_context(|| format!("creating {}", args.output.display()))?;
    for (((settings, out, _), s), maps) in bakes.iter().zip(&summaries).zip(&stored) {
        let tag = settings.basis.tag();
        let exr = args.output.join(format!("{tag}.exr"));
        write_surface_exr(&exr, &out.maps).with_context(|| format!("writing {}", exr.display()))?;
        let json = args.output.join(format!("{tag}.json"));
        // The file holds no timing: equal inputs write equal bytes.
        let file = SurfaceBakeSummary { seconds: None, ..s.clone() };
        write_atomic(&json, serde_json::to_string_pretty(&file)?.as_bytes())?;
        for (rel, bytes) in &maps.files {
            let path = args.output.join(rel);
            ensure_parent(&path)?;
            write_atomic(&path, bytes)?;
        }
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
                s.report.texels_covered,
                s.report.invalid_texels,
                s.report.moved,
                s.report.dilated,
                s.report.unfilled,
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
