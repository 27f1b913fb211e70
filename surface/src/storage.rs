//! # Storage: coefficient maps as 8-bit and block-compressed textures, and what it costs
//!
//! Ishmukhametov 2011 (\[Ish11\] §2.2.3, Listing 2.2) stores a lightmap's coefficients one
//! 8-bit texture per coefficient: the DC coefficient through the sRGB curve, the others
//! range-compressed by `range` (0.75 in the text), optionally block-compressed (§2.2.4).
//! [`store_maps`] does that for every object of a bake, in memory, and measures each storage
//! against the f32 maps with the exact irradiance error over the hemisphere of normals
//! (`lightvol_hemibasis::map::map_error`, `Δcᵀ G Δc`), on the covered texels only.
//! [`SurfaceBakeSummary`] is the record of one basis's bake that `lightvol bake-surface`
//! writes beside its EXR.
//!
//! Nothing here touches the file system: the caller writes [`StoredMaps::files`].

use std::collections::BTreeMap;
use std::path::PathBuf;

use lightvol_hemibasis::HemiBasis;
use lightvol_hemibasis::bc::{self, BlockFormat, CompressedPlane};
use lightvol_hemibasis::encode::{ClampStats, DcTransfer, Encoding};
use lightvol_hemibasis::map::{CoeffMap, MapError, Plane, map_error};
use lightvol_hemibasis::plane_ktx2::{ktx2_compressed, ktx2_rgba8};
use rayon::prelude::*;
use serde::Serialize;

use super::{BasisChoice, CoefficientMap, SurfaceBake, SurfaceReport};
use lightvol_view::picture::png_rgb8;

/// 8-bit texture container.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Container {
    /// One RGB PNG per coefficient (DC plane sRGB-encoded).
    Png,
    /// One KTX2 per coefficient: RGBA8 (`R8G8B8A8_SRGB` for the DC plane, `_UNORM` else),
    /// or BC1/BC7 blocks when block compression is asked for.
    Ktx2,
}

/// How a bake's maps are stored besides the f32 EXR.
#[derive(Clone, Debug, PartialEq)]
pub struct StorageSettings {
    /// Range compression of the non-DC coefficients (\[Ish11\] §2.2.3: 0.75).
    pub range: f64,
    /// Scale applied before encoding; `None` picks [`default_encode_scale`].
    pub encode_scale: Option<f64>,
    /// Texture container, or `None` to measure the 8-bit error without writing textures.
    /// Block compression without a container means KTX2.
    pub container: Option<Container>,
    /// Block compressions to apply (each written and measured; duplicates are ignored).
    pub compress: Vec<BlockFormat>,
}

impl Default for StorageSettings {
    fn default() -> Self {
        Self { range: 0.75, encode_scale: None, container: None, compress: Vec::new() }
    }
}

/// A storage setting that cannot be honoured.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum StorageError {
    /// The range is not a positive finite number.
    #[error("the range compression factor must be a positive finite number")]
    Range,
    /// The encoding scale is not a positive finite number.
    #[error("the encoding scale must be a positive finite number")]
    Scale,
    /// Block compression asked for with the PNG container.
    #[error("block-compressed textures are KTX2 files, not PNG")]
    CompressedPng,
    /// A PNG could not be encoded.
    #[error("encoding {0}: {1}")]
    Png(String, String),
}

impl StorageSettings {
    /// Checks the settings.
    ///
    /// # Errors
    /// [`StorageError::Range`], [`StorageError::Scale`], [`StorageError::CompressedPng`].
    pub fn validate(&self) -> Result<(), StorageError> {
        if !(self.range.is_finite() && self.range > 0.0) {
            return Err(StorageError::Range);
        }
        if let Some(s) = self.encode_scale
            && !(s.is_finite() && s > 0.0)
        {
            return Err(StorageError::Scale);
        }
        if self.container == Some(Container::Png) && !self.compress.is_empty() {
            return Err(StorageError::CompressedPng);
        }
        Ok(())
    }

    /// The container textures are written in: the one asked for, KTX2 when only block
    /// compression was asked for, else none.
    #[must_use]
    pub fn effective_container(&self) -> Option<Container> {
        match (self.container, self.compress.is_empty()) {
            (None, false) => Some(Container::Ktx2),
            (c, _) => c,
        }
    }

    /// The block formats in order, consecutive duplicates removed.
    fn formats(&self) -> Vec<BlockFormat> {
        let mut f = self.compress.clone();
        f.dedup();
        f
    }
}

/// Error of one storage encoding, measured on the covered texels.
#[derive(Debug, Serialize, Clone, PartialEq)]
pub struct EncodingSummary {
    /// Relative RMS irradiance error over covered texels, channels and the hemisphere of
    /// normals (exact, `Δcᵀ G Δc`), against the f32 maps.
    pub rel_rms: f64,
    /// The same, absolute (in the maps' units, before `encode_scale`).
    pub rms: f64,
    /// Largest coefficient error (after `encode_scale`, i.e. in stored units).
    pub max_coeff_error: f64,
    /// Values clamped: DC outside `[0, 1]`, others outside `[-range, range]`.
    pub clamped: [usize; 2],
    /// Bytes per texel of this storage (all coefficients), as named by [`Self::storage`].
    pub bytes_per_texel: f64,
    /// The storage `bytes_per_texel` counts: `"RGB8 PNG"` (3 bytes per coefficient; also
    /// given when no textures were written), `"RGBA8 KTX2"` (4 bytes per coefficient: the
    /// alpha byte is stored), `"BC1 KTX2"` (0.5) or `"BC7 KTX2"` (1).
    pub storage: String,
}

impl EncodingSummary {
    fn new(e: &MapError, c: &ClampStats, bytes_per_texel: f64, storage: &str) -> Self {
        Self {
            storage: storage.to_owned(),
            rel_rms: e.rel_rms,
            rms: e.rms,
            max_coeff_error: e.max_coeff_error,
            clamped: [c.dc_clamped, c.ac_clamped],
            bytes_per_texel,
        }
    }
}

/// The stored textures of one basis's maps and the error of each storage.
#[derive(Debug, Clone)]
pub struct StoredMaps {
    /// Scale applied before encoding.
    pub encode_scale: f64,
    /// Irradiance error per storage: `rgb8` always, `bc1`/`bc7` when compressed.
    pub encodings: BTreeMap<String, EncodingSummary>,
    /// Texture files, relative to the output directory (`<basis>/<object>_cKK.png|ktx2`, or
    /// `…_cKK.bc1.ktx2` per block format), with their bytes, in object and coefficient order.
    pub files: Vec<(PathBuf, Vec<u8>)>,
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
#[must_use]
pub fn scaled_map(map: &CoefficientMap, s: f64) -> CoeffMap {
    CoeffMap {
        width: map.width as usize,
        height: map.height as usize,
        len: map.coeffs,
        data: map.data.iter().map(|c| c.map(|v| (f64::from(v) * s) as f32)).collect(),
    }
}

/// The default encoding scale: `1 / max DC` over covered texels, or `range / max |c|` for
/// bases without a DC term (Half-Life 2), or 1 for an all-zero map.
#[must_use]
pub fn default_encode_scale(basis: &dyn HemiBasis, maps: &[CoefficientMap], range: f64) -> f64 {
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

/// A file name fragment safe on every file system.
#[must_use]
pub fn safe_name(s: &str) -> String {
    s.chars()
        .map(|c| if c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.') { c } else { '_' })
        .collect()
}

/// Encodes every object's maps (scaled by the encoding scale) into 8-bit planes with the DC
/// coefficient through the exact sRGB curve (what `_SRGB` formats and PNG viewers decode),
/// block-compresses them to each asked format (planes in parallel: BC7 runs at about
/// 0.2 Mtexel/s per core), measures every storage on the covered texels in the maps' own
/// units, and builds the texture files of the container.
///
/// Each KTX2 file carries a `lightvol.plane` description: basis, object, coefficient,
/// `encode_scale`, `range` and the decode formula a shader applies.
///
/// # Errors
/// [`StorageSettings::validate`]'s, and [`StorageError::Png`].
pub fn store_maps(
    choice: &BasisChoice,
    maps: &[CoefficientMap],
    settings: &StorageSettings,
) -> Result<StoredMaps, StorageError> {
    settings.validate()?;
    let basis = choice.basis();
    let basis = basis.as_ref();
    let tag = choice.tag();
    let range = settings.range;
    let scale = settings.encode_scale.unwrap_or_else(|| default_encode_scale(basis, maps, range));
    let formats = settings.formats();
    let container = settings.effective_container();
    let enc = Encoding { range, dc: DcTransfer::Srgb, quantize_8bit: true };
    let k = basis.len();

    let mut clamped = ClampStats::default();
    let mut planes: Vec<Vec<Plane>> = Vec::with_capacity(maps.len());
    for m in maps {
        let (p, c) = enc.encode_map(basis, &scaled_map(m, scale));
        clamped.dc_clamped += c.dc_clamped;
        clamped.ac_clamped += c.ac_clamped;
        planes.push(p);
    }
    let error = |decoded: &[CoeffMap]| -> MapError {
        if maps.is_empty() {
            return MapError { rms: 0.0, rel_rms: 0.0, max_coeff_error: 0.0 };
        }
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
    let rgb8 = error(&decoded);
    let blocks: Vec<(BlockFormat, Vec<Vec<CompressedPlane>>, MapError)> = formats
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

    // The 8-bit error is the same for PNG and KTX2; the bytes are those of the file kind
    // written (uncompressed KTX2 is RGBA8).
    let (rgb8_storage, rgb8_bytes) = if container == Some(Container::Ktx2) && formats.is_empty() {
        ("RGBA8 KTX2", 4.0)
    } else {
        ("RGB8 PNG", 3.0)
    };
    let mut encodings = BTreeMap::new();
    encodings.insert(
        "rgb8".to_owned(),
        EncodingSummary::new(&rgb8, &clamped, rgb8_bytes * k as f64, rgb8_storage),
    );
    for (f, _, e) in &blocks {
        let storage = format!("{} KTX2", f.name().to_uppercase());
        encodings.insert(
            f.name().to_owned(),
            EncodingSummary::new(e, &clamped, f.bytes_per_texel() * k as f64, &storage),
        );
    }

    let mut files = Vec::new();
    if let Some(container) = container {
        let sub = PathBuf::from(safe_name(&tag));
        for (oi, (m, planes)) in maps.iter().zip(&planes).enumerate() {
            for (j, plane) in planes.iter().enumerate() {
                let dc = basis.dc_index() == Some(j);
                let stem = format!("{}_c{j:02}", safe_name(&m.object));
                let desc = serde_json::json!({
                    "basis": tag, "object": m.object, "coefficient": j, "coefficients": k,
                    "encode_scale": scale, "range": range,
                    "transfer": if dc { "srgb" } else { "range" },
                    "decode": if dc { "c = srgb_decode(v) / encode_scale" } else { "c = (2 range v - range) / encode_scale" },
                })
                .to_string();
                match container {
                    Container::Png => {
                        let rel = sub.join(format!("{stem}.png"));
                        let bytes = png_rgb8(plane.width, plane.height, &plane.rgb_bytes())
                            .map_err(|e| StorageError::Png(rel.display().to_string(), e.to_string()))?;
                        files.push((rel, bytes));
                    }
                    Container::Ktx2 if blocks.is_empty() => {
                        files.push((sub.join(format!("{stem}.ktx2")), ktx2_rgba8(plane, dc, &desc)));
                    }
                    Container::Ktx2 => {
                        for (f, compressed, _) in &blocks {
                            let rel = sub.join(format!("{stem}.{}.ktx2", f.name()));
                            files.push((rel, ktx2_compressed(&compressed[oi][j], dc, &desc)));
                        }
                    }
                }
            }
        }
    }
    Ok(StoredMaps { encode_scale: scale, encodings, files })
}

/// One object's map in a [`SurfaceBakeSummary`].
#[derive(Debug, Serialize, Clone, PartialEq, Eq)]
pub struct ObjectSummary {
    /// Object (mesh instance) name.
    pub name: String,
    /// Atlas width.
    pub width: u32,
    /// Atlas height.
    pub height: u32,
}

/// The record of one basis's surface bake: what was baked, how many texels were invalid and
/// how each was fixed, the rays, and the error of each storage.
#[derive(Debug, Serialize, Clone, PartialEq)]
pub struct SurfaceBakeSummary {
    /// Scene label.
    pub scene: String,
    /// Basis tag.
    pub basis: String,
    /// Coefficients per channel.
    pub coefficients: usize,
    /// Lightmap UV set.
    pub uv_set: String,
    /// Texel density.
    pub texels_per_unit: f64,
    /// Samples per texel.
    pub samples: u32,
    /// Seed.
    pub seed: u64,
    /// `"irradiance"` or `"radiosity"`.
    pub quantity: String,
    /// What lit the bake ([`lightvol_scene::fingerprint::lighting_fingerprint`], also stored in the EXR; a
    /// surface render refuses maps whose lighting differs from its own).
    pub lighting: String,
    /// Whether invalid texels were fixed (domain of interest + dilation).
    pub invalid_fix: bool,
    /// Objects and their atlas sizes.
    pub objects: Vec<ObjectSummary>,
    /// Texels covered, invalid texels and how each was fixed, gutter texels and rays
    /// (`texels_covered`, `invalid_texels`, `moved`, `dilated`, `unfilled`,
    /// `gutter_texels`, `rays`).
    #[serde(flatten)]
    pub report: SurfaceReport,
    /// Bake wall time, or `None` where the record must not depend on timing (a file: two
    /// bakes of the same input write the same bytes).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub seconds: Option<f64>,
    /// Scale applied before 8-bit encoding.
    pub encode_scale: f64,
    /// Range compression factor.
    pub range: f64,
    /// Irradiance error per storage: `rgb8` always, `bc1`/`bc7` when compressed.
    pub encodings: BTreeMap<String, EncodingSummary>,
    /// Bytes per texel of the f32 EXR coefficients (all coefficients, RGB).
    pub f32_bytes_per_texel: usize,
    /// Files written, relative to the output directory.
    pub files: Vec<String>,
}

impl SurfaceBakeSummary {
    /// The record of `bake`, baked with `settings`, stored as `stored`. `files` lists
    /// `<basis>.exr`, `<basis>.json` and then the texture files.
    #[must_use]
    pub fn new(
        scene: &str,
        settings: &super::SurfaceSettings,
        bake: &SurfaceBake,
        stored: &StoredMaps,
        range: f64,
        seconds: Option<f64>,
    ) -> Self {
        let choice = &settings.basis;
        let tag = choice.tag();
        let maps = &bake.maps;
        let r = &bake.report;
        let mut files = vec![format!("{tag}.exr"), format!("{tag}.json")];
        files.extend(stored.files.iter().map(|(p, _)| p.display().to_string()));
        Self {
            scene: scene.to_owned(),
            basis: tag.clone(),
            coefficients: choice.coeffs(),
            uv_set: maps.first().map_or_else(|| "TEXCOORD_1".to_owned(), |m| m.uv_set.attribute().to_owned()),
            texels_per_unit: settings.texels_per_unit,
            samples: settings.samples.get(),
            seed: settings.seed,
            quantity: maps.first().map_or("irradiance", |m| m.quantity.name()).to_owned(),
            lighting: maps.first().map(|m| m.lighting.clone()).unwrap_or_default(),
            invalid_fix: settings.invalid == super::InvalidTexels::Fix,
            objects: maps
                .iter()
                .map(|m| ObjectSummary { name: m.object.clone(), width: m.width, height: m.height })
                .collect(),
            report: r.clone(),
            seconds,
            encode_scale: stored.encode_scale,
            range,
            encodings: stored.encodings.clone(),
            f32_bytes_per_texel: choice.coeffs() * 12,
            files,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn settings_are_checked() {
        let ok = StorageSettings::default();
        assert_eq!(ok.validate(), Ok(()));
        assert_eq!(StorageSettings { range: 0.0, ..ok.clone() }.validate(), Err(StorageError::Range));
        assert_eq!(StorageSettings { range: f64::NAN, ..ok.clone() }.validate(), Err(StorageError::Range));
        assert_eq!(
            StorageSettings { encode_scale: Some(-1.0), ..ok.clone() }.validate(),
            Err(StorageError::Scale)
        );
        let png_bc1 = StorageSettings {
            container: Some(Container::Png),
            compress: vec![BlockFormat::Bc1],
            ..ok.clone()
        };
        assert_eq!(png_bc1.validate(), Err(StorageError::CompressedPng));
        let bc7 = StorageSettings { compress: vec![BlockFormat::Bc7], ..ok.clone() };
        assert_eq!(bc7.effective_container(), Some(Container::Ktx2));
        assert_eq!(ok.effective_container(), None);
    }

    #[test]
    fn safe_names_keep_only_portable_characters() {
        assert_eq!(safe_name("wall/left:1.a-b_c"), "wall_left_1.a-b_c");
    }
}
