//! The coefficient-map file: one multi-part OpenEXR file (f32, ZIP) per bake.
//!
//! ## Layout
//! - One part per object, named after it, `width × height` pixels, row 0 = `v ≈ 0` (the top
//!   row, as glTF images).
//! - Channels (f32): `cKK.R`, `cKK.G`, `cKK.B` for every coefficient `KK = 00, 01, …` of the
//!   basis (in the basis's own order, lightvol-hemibasis), and `valid` (1 baked, 0.5
//!   dilated, 0 empty).
//! - Part attributes: `lightvol.kind` = `"surface"`, `lightvol.version` (i32, [`VERSION`] =
//!   2), `lightvol.basis` (tag, e.g. `hbasis_mod6`), `lightvol.coefficients` (i32),
//!   `lightvol.texels_per_unit` (text, f64 decimal), `lightvol.quantity` (`irradiance` or
//!   `radiosity`), `lightvol.uv_set` (`TEXCOORD_1` or `TEXCOORD_0`), `lightvol.convention`
//!   ([`CONVENTION`]), and since version 2: `lightvol.lighting` (text, the
//!   [`lighting_fingerprint`](lightvol_scene::fingerprint::lighting_fingerprint) of the bake) and the object's
//!   [`super::InvalidCounts`] `lightvol.invalid_texels`, `lightvol.moved`,
//!   `lightvol.dilated`, `lightvol.unfilled` (each text, a u64 in decimal: exact beyond i32
//!   and f64 ranges).
//!
//! Each header lists the standard EXR attributes first and the `lightvol.*` ones after them,
//! sorted by name (`lightvol_volume::io::exr::canonical_attribute_order`), so equal maps give
//! byte-identical files.
//!
//! Written through a temporary file in the target directory and renamed. The reader checks
//! every header before decoding pixels and accepts only [`VERSION`] (a version-1 file lacks
//! the lighting and counters: re-bake it); a panic inside the `exr` decoder is caught and
//! reported as an error.

use std::io::Cursor;
use std::path::Path;

use exr::image::{AnyChannel, AnyChannels, Encoding as ExrEncoding, FlatSamples, Layer};
use exr::math::Vec2;
use exr::meta::attribute::{AttributeValue, Compression, IntegerBounds, SampleType, Text};
use exr::meta::header::{ImageAttributes, LayerAttributes};
use exr::prelude::SmallVec;

use super::map::{CoefficientMap, InvalidCounts};
use super::{Quantity, SurfaceError, UvSet};

/// File format version written to `lightvol.version`; the only one [`read_surface_exr`]
/// accepts. 1: first layout; 2: adds `lightvol.lighting` and the invalid-texel counters.
pub const VERSION: i32 = 2;

/// The [`InvalidCounts`](super::InvalidCounts) attributes, in field order.
const COUNT_KEYS: [&str; 4] =
    ["lightvol.invalid_texels", "lightvol.moved", "lightvol.dilated", "lightvol.unfilled"];

/// The tangent-space and SH conventions, stored in `lightvol.convention`.
pub const CONVENTION: &str = "tangent space x = tangent, y = w * (normal x tangent), z = normal (MikkTSpace); \
     SH real orthonormal, index l(l+1)+m, no Condon-Shortley phase (lightvol-sh)";

/// Largest file [`read_surface_exr`] accepts.
pub const MAX_FILE_BYTES: u64 = 8 << 30;

fn text(s: &str) -> Result<Text, String> {
    Text::new_or_none(s).ok_or_else(|| format!("{s:?} cannot be stored as EXR text"))
}

fn channel_name(k: usize, c: usize) -> String {
    format!("c{k:02}.{}", ["R", "G", "B"][c])
}

/// Serialises maps as a multi-part EXR in memory (layout in the module docs).
///
/// # Errors
/// A message for an empty list, a map whose sizes disagree, or a name EXR cannot store.
pub fn surface_exr_to_bytes(maps: &[CoefficientMap]) -> Result<Vec<u8>, String> {
    to_bytes(maps, VERSION)
}

/// [`surface_exr_to_bytes`] with any `lightvol.version` (tests write foreign versions).
fn to_bytes(maps: &[CoefficientMap], version: i32) -> Result<Vec<u8>, String> {
    if maps.is_empty() {
        return Err("no maps to write".into());
    }
    let encoding = ExrEncoding { compression: Compression::ZIP16, ..ExrEncoding::SMALL_LOSSLESS };
    let mut layers = Vec::new();
    let mut names = std::collections::HashSet::new();
    let (mut max_w, mut max_h) = (1usize, 1usize);
    for m in maps {
        let n = m.width as usize * m.height as usize;
        if m.width == 0 || m.height == 0 || m.data.len() != n * m.coeffs || m.valid.len() != n {
            return Err(format!("map '{}' has inconsistent sizes", m.object));
        }
        if !names.insert(m.object.clone()) {
            return Err(format!("two maps are called '{}'", m.object));
        }
        max_w = max_w.max(m.width as usize);
        max_h = max_h.max(m.height as usize);
        let mut channels = Vec::with_capacity(3 * m.coeffs + 1);
        for k in 0..m.coeffs {
            for c in 0..3 {
                let vals = (0..n).map(|t| m.data[t * m.coeffs + k][c]).collect();
                channels.push(AnyChannel::new(channel_name(k, c).as_str(), FlatSamples::F32(vals)));
            }
        }
        channels.push(AnyChannel::new("valid", FlatSamples::F32(m.valid.clone())));
        let channels = AnyChannels::sort(SmallVec::from_vec(channels));
        let mut attrs = LayerAttributes::named(text(&m.object)?);
        let mut put = |k: &str, v: AttributeValue| -> Result<(), String> {
            attrs.other.insert(text(k)?, v);
            Ok(())
        };
        put("lightvol.kind", AttributeValue::Text(text("surface")?))?;
        put("lightvol.version", AttributeValue::I32(version))?;
        put("lightvol.basis", AttributeValue::Text(text(&m.basis.tag())?))?;
        put("lightvol.coefficients", AttributeValue::I32(m.coeffs as i32))?;
        put("lightvol.texels_per_unit", AttributeValue::Text(text(&format!("{:?}", m.texels_per_unit))?))?;
        put("lightvol.quantity", AttributeValue::Text(text(m.quantity.name())?))?;
        put("lightvol.uv_set", AttributeValue::Text(text(m.uv_set.attribute())?))?;
        put("lightvol.convention", AttributeValue::Text(text(CONVENTION)?))?;
        put("lightvol.lighting", AttributeValue::Text(text(&m.lighting)?))?;
        let c = m.invalid;
        for (key, v) in COUNT_KEYS.into_iter().zip([c.invalid_texels, c.moved, c.dilated, c.unfilled]) {
            put(key, AttributeValue::Text(text(&v.to_string())?))?;
        }
        layers.push(Layer::new(Vec2(m.width as usize, m.height as usize), attrs, encoding, channels));
    }
    let ia = ImageAttributes::new(IntegerBounds::from_dimensions(Vec2(max_w, max_h)));
    // Canonical attribute order: byte-reproducible files.
    lightvol_volume::io::exr::encode_image(ia, layers).map_err(|e| e.to_string())
}

/// Writes `maps` to `path` (temporary file in the same directory, then rename).
///
/// # Errors
/// [`SurfaceError::Exr`] for maps that cannot be stored, [`SurfaceError::Io`].
pub fn write_surface_exr(path: &Path, maps: &[CoefficientMap]) -> Result<(), SurfaceError> {
    let bytes =
        surface_exr_to_bytes(maps).map_err(|message| SurfaceError::Exr { path: path.to_owned(), message })?;
    lightvol_core::fs::write_atomic(path, &bytes)
        .map_err(|source| SurfaceError::Io { path: path.to_owned(), source })
}

/// Reads maps written by [`write_surface_exr`].
///
/// # Errors
/// [`SurfaceError::Io`] when the file cannot be read or is larger than [`MAX_FILE_BYTES`],
/// [`SurfaceError::Exr`] naming what is wrong otherwise (not EXR, not a lightvol surface
/// file, missing or mistyped attributes or channels, non-finite values).
pub fn read_surface_exr(path: &Path) -> Result<Vec<CoefficientMap>, SurfaceError> {
    let io = |source| SurfaceError::Io { path: path.to_owned(), source };
    let bytes = lightvol_core::fs::read_bounded(path, MAX_FILE_BYTES).map_err(io)?;
    surface_exr_from_bytes(&bytes).map_err(|message| SurfaceError::Exr { path: path.to_owned(), message })
}

/// Parses maps from memory (see [`read_surface_exr`]).
///
/// # Errors
/// A message naming the problem.
pub fn surface_exr_from_bytes(bytes: &[u8]) -> Result<Vec<CoefficientMap>, String> {
    match std::panic::catch_unwind(|| parse(bytes)) {
        Ok(r) => r,
        Err(_) => Err("the EXR decoder rejected the data (internal panic caught)".into()),
    }
}

struct Declared {
    object: String,
    width: u32,
    height: u32,
    basis: super::BasisChoice,
    coeffs: usize,
    texels_per_unit: f64,
    quantity: Quantity,
    uv_set: UvSet,
    lighting: String,
    invalid: InvalidCounts,
}

fn declared(h: &exr::meta::header::Header) -> Result<Declared, String> {
    let object = h.own_attributes.layer_name.as_ref().map(ToString::to_string).ok_or("a part has no name")?;
    let get = |key: &str| -> Result<&AttributeValue, String> {
        h.own_attributes
            .other
            .iter()
            .chain(h.shared_attributes.other.iter())
            .find(|(k, _)| k.as_slice() == key.as_bytes())
            .map(|(_, v)| v)
            .ok_or_else(|| format!("part '{object}': missing attribute {key}"))
    };
    let txt = |key: &str| -> Result<String, String> {
        match get(key)? {
            AttributeValue::Text(t) => Ok(t.to_string()),
            _ => Err(format!("part '{object}': {key} is not text")),
        }
    };
    let int = |key: &str| -> Result<i32, String> {
        match get(key)? {
            AttributeValue::I32(v) => Ok(*v),
            _ => Err(format!("part '{object}': {key} is not an i32")),
        }
    };
    if txt("lightvol.kind")? != "surface" {
        return Err(format!("part '{object}' is not a lightvol surface map"));
    }
    let version = int("lightvol.version")?;
    if version != VERSION {
        return Err(format!(
            "part '{object}': lightvol.version {version} is not supported; this build reads version \
             {VERSION} only (re-bake the maps)"
        ));
    }
    let coeffs = usize::try_from(int("lightvol.coefficients")?).map_err(|_| "negative coefficient count")?;
    let basis = txt("lightvol.basis")?;
    let choice = super::BasisChoice::parse(&basis).map_err(|e| e.to_string())?;
    if choice.coeffs() != coeffs {
        return Err(format!("part '{object}': basis {basis} does not have {coeffs} coefficients"));
    }
    let tpu = txt("lightvol.texels_per_unit")?;
    let texels_per_unit = tpu.parse::<f64>().map_err(|_| format!("lightvol.texels_per_unit {tpu:?}"))?;
    let q = txt("lightvol.quantity")?;
    let quantity = Quantity::from_name(&q).ok_or_else(|| format!("unknown quantity {q:?}"))?;
    let u = txt("lightvol.uv_set")?;
    let uv_set = UvSet::from_attribute(&u).ok_or_else(|| format!("unknown UV set {u:?}"))?;
    if txt("lightvol.convention")? != CONVENTION {
        return Err(format!("part '{object}': convention differs from this version's"));
    }
    let lighting = txt("lightvol.lighting")?;
    let mut counts = [0u64; 4];
    for (slot, key) in counts.iter_mut().zip(COUNT_KEYS) {
        let v = txt(key)?;
        *slot = v.parse::<u64>().map_err(|_| format!("part '{object}': {key} {v:?} is not a count"))?;
    }
    let [invalid_texels, moved, dilated, unfilled] = counts;
    let invalid = InvalidCounts { invalid_texels, moved, dilated, unfilled };
    if h.deep {
        return Err(format!("part '{object}' is deep data"));
    }
    let Vec2(w, hgt) = h.layer_size;
    let (width, height) = (u32::try_from(w).map_err(|_| "width")?, u32::try_from(hgt).map_err(|_| "height")?);
    if width == 0 || height == 0 || width > super::MAX_ATLAS_SIZE || height > super::MAX_ATLAS_SIZE {
        return Err(format!("part '{object}' is {width}×{height}"));
    }
    let mut want: Vec<String> = (0..coeffs).flat_map(|k| (0..3).map(move |c| channel_name(k, c))).collect();
    want.push("valid".into());
    want.sort();
    let got: Vec<String> = h.channels.list.iter().map(|c| c.name.to_string()).collect();
    if got != want || h.channels.list.iter().any(|c| c.sample_type != SampleType::F32) {
        return Err(format!("part '{object}' has channels {got:?}; expected f32 {want:?}"));
    }
    Ok(Declared {
        object,
        width,
        height,
        basis: choice,
        coeffs,
        texels_per_unit,
        quantity,
        uv_set,
        lighting,
        invalid,
    })
}

fn parse(bytes: &[u8]) -> Result<Vec<CoefficientMap>, String> {
    let meta =
        exr::meta::MetaData::read_from_buffered(Cursor::new(bytes), true).map_err(|e| e.to_string())?;
    let decl: Vec<Declared> = meta.headers.iter().map(declared).collect::<Result<_, _>>()?;
    if decl.is_empty() {
        return Err("no parts".into());
    }
    let image = lightvol_volume::io::exr::decode_image(bytes).map_err(|e| e.to_string())?;
    if image.layer_data.len() != decl.len() {
        return Err("part count changed between header and pixels".into());
    }
    let mut maps = Vec::new();
    for (layer, d) in image.layer_data.iter().zip(decl) {
        let n = d.width as usize * d.height as usize;
        let mut data = vec![[0.0f32; 3]; n * d.coeffs];
        let mut valid = vec![0.0f32; n];
        for ch in &layer.channel_data.list {
            let vals: Vec<f32> = ch.sample_data.values_as_f32().collect();
            if vals.len() != n || vals.iter().any(|v| !v.is_finite()) {
                return Err(format!("part '{}': channel {} has bad samples", d.object, ch.name));
            }
            let name = ch.name.to_string();
            if name == "valid" {
                valid = vals;
                continue;
            }
            let (k, c) = (0..d.coeffs)
                .flat_map(|k| (0..3).map(move |c| (k, c)))
                .find(|&(k, c)| channel_name(k, c) == name)
                .ok_or_else(|| format!("unexpected channel {name}"))?;
            for (t, v) in vals.into_iter().enumerate() {
                data[t * d.coeffs + k][c] = v;
            }
        }
        maps.push(CoefficientMap {
            object: d.object,
            width: d.width,
            height: d.height,
            basis: d.basis,
            coeffs: d.coeffs,
            texels_per_unit: d.texels_per_unit,
            quantity: d.quantity,
            uv_set: d.uv_set,
            data,
            valid,
            lighting: d.lighting,
            invalid: d.invalid,
        });
    }
    Ok(maps)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample_map(name: &str, w: u32, h: u32) -> CoefficientMap {
        let n = (w * h) as usize;
        CoefficientMap {
            object: name.into(),
            width: w,
            height: h,
            basis: crate::BasisChoice::parse("hbasis_mod6").unwrap(),
            coeffs: 6,
            texels_per_unit: 12.5,
            quantity: Quantity::Radiosity,
            uv_set: UvSet::Base,
            data: (0..n * 6).map(|i| [i as f32 * 0.25, -(i as f32), 1.0 / (1.0 + i as f32)]).collect(),
            valid: (0..n).map(|i| [1.0, 0.5, 0.0][i % 3]).collect(),
            lighting: format!("lighting=1; environment=black; sun=none; punctual=0; object {name}"),
            invalid: InvalidCounts {
                invalid_texels: 7 + u64::from(w),
                moved: 3,
                dilated: 4,
                unfilled: u64::from(h),
            },
        }
    }

    /// Two parts of different sizes round-trip bit-exactly with their attributes; bad input
    /// gives errors, not panics, and leaves no temporary file behind.
    #[test]
    fn round_trip_and_errors() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("maps.exr");
        let maps = vec![sample_map("floor", 5, 3), sample_map("wall#2", 2, 7)];
        write_surface_exr(&p, &maps).unwrap();
        let back = read_surface_exr(&p).unwrap();
        assert_eq!(back, maps);
        let leftovers = std::fs::read_dir(dir.path()).unwrap().count();
        assert_eq!(leftovers, 1);
        // Not an EXR; truncated; missing file; duplicate names; a foreign EXR part.
        std::fs::write(&p, b"not an exr").unwrap();
        assert!(matches!(read_surface_exr(&p), Err(SurfaceError::Exr { .. })));
        let bytes = surface_exr_to_bytes(&maps).unwrap();
        for cut in [8, bytes.len() / 3, bytes.len() - 5] {
            assert!(surface_exr_from_bytes(&bytes[..cut]).is_err(), "cut {cut}");
        }
        assert!(matches!(read_surface_exr(&dir.path().join("none.exr")), Err(SurfaceError::Io { .. })));
        assert!(surface_exr_to_bytes(&[sample_map("a", 1, 1), sample_map("a", 1, 1)]).is_err());
        let mut wrong = sample_map("x", 2, 2);
        wrong.coeffs = 4;
        assert!(surface_exr_to_bytes(&[wrong]).is_err());
        let mut renamed = sample_map("x", 2, 2);
        renamed.basis = crate::BasisChoice::parse("sh4").unwrap(); // 6 channels declared as a 4-coefficient basis
        let b = surface_exr_to_bytes(&[renamed]).unwrap();
        assert!(surface_exr_from_bytes(&b).unwrap_err().contains("does not have"));
    }

    /// Writing the same maps again gives the same bytes (each write builds new, differently
    /// seeded attribute maps inside the exr crate), with every part's `lightvol.*`
    /// attributes after the standard ones and sorted by name.
    #[test]
    fn repeated_writes_are_byte_identical() {
        let maps = vec![sample_map("floor", 4, 3), sample_map("wall", 2, 5)];
        let first = surface_exr_to_bytes(&maps).unwrap();
        for _ in 0..5 {
            assert!(surface_exr_to_bytes(&maps).unwrap() == first, "a repeated write differs");
        }
        let headers = lightvol_volume::io::exr::header_attribute_names(&first).unwrap();
        assert_eq!(headers.len(), 2);
        for names in &headers {
            let from = names.iter().position(|n| n.starts_with("lightvol.")).unwrap();
            let custom = &names[from..];
            assert_eq!(custom.len(), 13, "{names:?}");
            assert!(custom.windows(2).all(|w| w[0] < w[1] && w[1].starts_with("lightvol.")), "{custom:?}");
        }
        assert_eq!(surface_exr_from_bytes(&first).unwrap(), maps);
    }

    /// Version 2 stores the lighting fingerprint and the invalid-texel counters (u64, beyond
    /// i32 and f64's exact range too); files of any other version are refused with a message
    /// naming the version.
    #[test]
    fn lighting_counts_and_version() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("v.exr");
        let mut m = sample_map("floor", 3, 2);
        m.invalid = InvalidCounts { invalid_texels: u64::MAX, moved: (1 << 53) + 1, dilated: 0, unfilled: 1 };
        m.lighting = "lighting=1; environment=map 4x2 fnv1a64=0123456789abcdef; bounces=3".into();
        write_surface_exr(&p, std::slice::from_ref(&m)).unwrap();
        let back = read_surface_exr(&p).unwrap();
        assert_eq!(back[0].lighting, m.lighting);
        assert_eq!(back[0].invalid, m.invalid);
        assert_eq!(back, vec![m.clone()]);
        for v in [1, 3] {
            std::fs::write(&p, to_bytes(std::slice::from_ref(&m), v).unwrap()).unwrap();
            let e = read_surface_exr(&p).unwrap_err();
            let text = e.to_string();
            assert!(matches!(e, SurfaceError::Exr { .. }), "{text}");
            assert!(
                text.contains(&format!("lightvol.version {v} is not supported")) && text.contains("re-bake")
            );
        }
    }
}
