//! The entries a comparison can bake and read: the three bakes of Kontkanen & Laine 2006
//! (\[KL06\] §4-6) read by trilinear interpolation, the same bakes finalized with another
//! node fit ([`lightvol_sampler::node_fit`]), read through one of Oat 2005's gradient lookups (\[Oat05\],
//! "Spherical Harmonic Irradiance Gradients"), \[Oat05\]'s adaptive octree, and the engines'
//! leak fixes ([`lightvol_sampler::baselines`]), and the lowest plate error any node values
//! reach through a lookup ([`Entry::Bound`]).
//!
//! Every entry has a name, which [`parse_entry`] reads and [`Entry`]'s `Display` writes:
//!
//! | name | entry |
//! | --- | --- |
//! | `point`, `prefilter`, `doi`, `doi-paper`, `doi-node` | [`Entry::Uniform`] |
//! | `BASE+average`, `BASE+lsq`, `BASE+lsq:λ` | [`Entry::Fitted`] |
//! | `BASE+taylor`, `BASE+gtrilinear`, `BASE+hermite` | [`Entry::Gradient`] |
//! | `BASE+three`, `BASE+bevy`, `BASE+trilinear`, `BASE+apv`, `BASE+lightvol` | [`Entry::Targeted`] |
//! | `BASE+relit`, `BASE+relit2`, `BASE+relit4` | [`Entry::Relit`] |
//! | `BASE+skyocc` | [`Entry::SkyOcclusion`] |
//! | `adaptive` (= `adaptive2`), `adaptive1`, `adaptive3` | [`Entry::Adaptive`] |
//! | `bricks`, `bricksN` | [`Entry::Bricks`] |
//! | `point+validity`, `point+apv`, `point+vlm`, `point+ddgi` | [`Entry::Baseline`] |
//! | `bound+three`, `bound+bevy`, `bound+trilinear`, `bound+apv`, `bound+lightvol` | [`Entry::Bound`] |
//!
//! **Memory.** Every entry reports the run-time bytes of what a renderer would keep: for a
//! uniform grid \[Oat05\]'s accounting ("GPU Memory Requirements"), the RGB SH floats per
//! node, ×4 with gradients, f32, bake weights not counted ([`uniform_memory_bytes`]); for
//! the octree `AdaptiveVolume::memory_bytes` (coefficients, base weights, an 8-byte key per
//! fine node, split bitmaps); `point+apv` adds its validity mask, one byte per node
//! (`ValidityMask::memory_bytes`); the brick export its atlas's probes and indirection
//! texture (`BrickVolume::probe_bytes`, `indirection_bytes`).
//!
//! **Equal memory.** The `adaptive[L]` entry is baked (doi, the comparison's samples per
//! cell at every level) with level 0 on the compared grid with its cell counts scaled by
//! [`ADAPTIVE_BASE_SCALE`], down to level `L` (`adaptive` is [`ADAPTIVE_MAX_LEVEL`] = 2;
//! level 1 has the compared grid's cell size, level 2 half of it), the sampler's default
//! heuristics and culling, under a memory budget equal to the uniform `doi` entry's bytes
//! (its coefficients and node reach, [`uniform_doi_memory_bytes`]; in the memory sweep, the
//! uniform series' bytes). The octree's own count includes its weights and index, which the
//! uniform count leaves out, so the octree never gets more memory than the uniform grid it
//! is compared with.

use std::fmt;
use std::str::FromStr;

use lightvol_volume::gradient::GradientLookup;
use lightvol_volume::{EngineLookup, GridSpec};

use crate::error::EvalError;
use lightvol_sampler::method::Baseline;
use lightvol_sampler::method::Method;
use lightvol_sampler::node_fit::Fit;

/// What one compared entry bakes and how it is read (module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Entry {
    /// A uniform bake, finalized with the comparison's node fit, read by trilinear
    /// interpolation (\[KL06\] Fig. 6).
    Uniform(Method),
    /// A uniform bake with per-node gradients, read by a gradient lookup (\[Oat05\]).
    Gradient(Method, GradientLookup),
    /// A uniform bake finalized with this node fit instead of the comparison's.
    Fitted(Method, Fit),
    /// \[Oat05\]'s adaptive octree at the uniform grid's memory, with this finest level
    /// (module docs).
    Adaptive(u32),
    /// An octree (doi, level 0 at [`BRICKS_BASE_SCALE`] of the grid's cell counts, finest
    /// level [`BRICKS_MAX_LEVEL`], the `adaptive` entry's memory budget) resampled into the
    /// brick export (`lightvol_volume::bricks`), with its probes' memory capped at `1/N` of the uniform
    /// grid's in the same texel format ([`uniform_probe_bytes`]) when `N > 0`
    /// (`bricksN`), by the default merge tolerance only when `N = 0` (`bricks`).
    Bricks(u32),
    /// Point sampling with an engine's leak fix: validity and dilation, Unity APV, Unreal
    /// VLM or DDGI relocation ([`lightvol_sampler::baselines`]).
    Baseline(Baseline),
    /// A uniform bake whose node values are then fitted for an engine's lookup
    /// ([`lightvol_sampler::target`]).
    Targeted(Method, EngineLookup),
    /// A uniform bake with a sky transfer of this SH order (2-4; `BASE+relit` is order 3,
    /// `BASE+relitN` order N) under the comparison's `relight_from` sky, relit to the
    /// comparison's own sky ([`crate::relight::run_relit`]): what relighting gives where a
    /// fresh bake would be made.
    Relit(Method, u32),
    /// Unity APV's sky occlusion with this method, baked under the comparison's
    /// `relight_from` sky and relit to its own ([`crate::relight::run_sky_occlusion`]): the
    /// baseline of `BASE+relit`.
    SkyOcclusion(Method),
    /// Not a bake: the node values that fit the plate's path-traced reference best through
    /// this lookup ([`lightvol_sampler::target::best_for_points`]), so its plate error is
    /// the lowest any bake reaches on this grid read that way. Always read through its
    /// own lookup.
    Bound(EngineLookup),
}

/// The sky transfer's SH order of `BASE+relit` (9 coefficients).
pub const DEFAULT_RELIT_ORDER: u32 = 3;

/// Level 0 of the `adaptive` entry: the compared grid's cell counts times this.
pub const ADAPTIVE_BASE_SCALE: f64 = 0.5;

/// Finest level of the `adaptive` entry: level 1 has the compared grid's cell size, level 2
/// half of it. Measured with the memory sweep (128 samples per cell, 64-point plate, the
/// octree then baked with doi-paper): at every memory from 35 kB to 1.5 MB the level-2
/// octree has the lowest error on both `city` (e.g. rel_rmse 0.1826 against the uniform
/// grid's 0.1862 at 193.5 kB) and `interior` (0.5884 against 0.8273 at 587 kB), while
/// `adaptive1` ties with the uniform grid on `city` (0.1864) and is barely better on
/// `interior` (0.8248). Baked with doi within the uniform doi grid's bytes (now), `city`
/// at plate height 1.0, 128 samples: 0.1347 / 0.1322 (seeds 1 / 2) against uniform doi's
/// 0.1712 / 0.1708, both at 236.5 kB.
pub const ADAPTIVE_MAX_LEVEL: u32 = 2;

/// Level 0 of the `bricks` entry's octree: the compared grid's cell counts times this. The
/// level-0 bricks alone hold `(B + 1)³ / B³ ≈ 2` times the probes of their grid (B = 4), so
/// a base of half the grid's cell counts would take a quarter of its memory before any
/// refinement; a quarter takes 3%.
pub const BRICKS_BASE_SCALE: f64 = 0.25;

/// Finest level of the `bricks` entry's octree: level 2 has the compared grid's cell size,
/// so that the bricks refine to the uniform grid's resolution and coarsen from there.
pub const BRICKS_MAX_LEVEL: u32 = 2;

/// Largest `N` accepted in `bricksN`.
pub const BRICKS_DIVISOR_MAX: u32 = 1024;

/// Largest `L` accepted in `adaptiveL`.
pub const ADAPTIVE_LEVELS_MAX: u32 = 3;

/// The three gradient lookups, in the order the memory sweep reports them.
pub const LOOKUPS: [GradientLookup; 3] =
    [GradientLookup::Taylor, GradientLookup::GradientTrilinear, GradientLookup::Hermite];

impl Entry {
    /// The entry's bake records the node reach ([`lightvol_sampler::reach`]): a uniform `doi` bake,
    /// whatever its fit or lookup.
    #[must_use]
    pub fn records_node_reach(&self) -> bool {
        matches!(
            self,
            Self::Uniform(Method::Doi)
                | Self::Gradient(Method::Doi, _)
                | Self::Fitted(Method::Doi, _)
                | Self::Relit(Method::Doi, _)
                | Self::SkyOcclusion(Method::Doi)
        )
    }
}

/// Parses an entry name (module docs).
///
/// # Errors
/// An unknown method or lookup, an invalid fit, `adaptiveL` with `L` outside
/// `1..=ADAPTIVE_LEVELS_MAX`.
pub fn parse_entry(s: &str) -> Result<Entry, EvalError> {
    if s == "adaptive" {
        return Ok(Entry::Adaptive(ADAPTIVE_MAX_LEVEL));
    }
    if let Some(l) = s.strip_prefix("adaptive") {
        return match l.parse::<u32>() {
            Ok(l) if (1..=ADAPTIVE_LEVELS_MAX).contains(&l) => Ok(Entry::Adaptive(l)),
            _ => Err(EvalError::AdaptiveLevel { name: s.to_owned(), max: ADAPTIVE_LEVELS_MAX }),
        };
    }
    if s == "bricks" {
        return Ok(Entry::Bricks(0));
    }
    if let Some(n) = s.strip_prefix("bricks") {
        return match n.parse::<u32>() {
            Ok(n) if (1..=BRICKS_DIVISOR_MAX).contains(&n) => Ok(Entry::Bricks(n)),
            _ => {
                Err(EvalError::UnknownMethod(format!("{s} (bricksN needs N from 1 to {BRICKS_DIVISOR_MAX})")))
            }
        };
    }
    if let Some(b) = Baseline::from_name(s) {
        return Ok(Entry::Baseline(b));
    }
    if let Some(l) = s.strip_prefix("bound+") {
        return EngineLookup::parse(l)
            .map(Entry::Bound)
            .ok_or_else(|| EvalError::UnknownEngineLookup(l.to_owned()));
    }
    if let Some((base, order)) = s.rsplit_once("+relit") {
        let order = match order {
            "" => DEFAULT_RELIT_ORDER,
            "2" => 2,
            "3" => 3,
            "4" => 4,
            _ => return Err(EvalError::UnknownMethod(s.to_owned())),
        };
        return Ok(Entry::Relit(parse_method(base)?, order));
    }
    if let Some(base) = s.strip_suffix("+skyocc") {
        return Ok(Entry::SkyOcclusion(parse_method(base)?));
    }
    match s.split_once('+') {
        None => Ok(Entry::Uniform(parse_method(s)?)),
        Some((base, fit)) if fit == "average" || fit.starts_with("lsq") => Ok(Entry::Fitted(
            parse_method(base)?,
            fit.parse::<Fit>().map_err(|message| EvalError::Fit { entry: s.to_owned(), message })?,
        )),
        Some((base, lookup)) => match EngineLookup::parse(lookup) {
            Some(engine) => Ok(Entry::Targeted(parse_method(base)?, engine)),
            _ => Ok(Entry::Gradient(parse_method(base)?, parse_lookup(lookup)?)),
        },
    }
}

impl FromStr for Entry {
    type Err = EvalError;
    fn from_str(s: &str) -> Result<Self, EvalError> {
        parse_entry(s)
    }
}

/// The name [`parse_entry`] reads back (`adaptive2` is written `adaptive`).
impl fmt::Display for Entry {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Self::Uniform(m) => f.write_str(m.name()),
            Self::Gradient(m, l) => write!(f, "{}+{}", m.name(), lookup_name(l)),
            Self::Fitted(m, fit) => write!(f, "{}+{fit}", m.name()),
            Self::Adaptive(ADAPTIVE_MAX_LEVEL) => f.write_str("adaptive"),
            Self::Adaptive(l) => write!(f, "adaptive{l}"),
            Self::Bricks(0) => f.write_str("bricks"),
            Self::Bricks(n) => write!(f, "bricks{n}"),
            Self::Baseline(b) => f.write_str(b.name()),
            Self::Targeted(m, l) => write!(f, "{}+{l}", m.name()),
            Self::Bound(l) => write!(f, "bound+{l}"),
            Self::Relit(m, DEFAULT_RELIT_ORDER) => write!(f, "{}+relit", m.name()),
            Self::Relit(m, order) => write!(f, "{}+relit{order}", m.name()),
            Self::SkyOcclusion(m) => write!(f, "{}+skyocc", m.name()),
        }
    }
}

/// An entry with the name it is reported under (the report's key, the label of its bake,
/// the name of its panels).
#[derive(Clone, Debug, PartialEq)]
pub struct NamedEntry {
    /// The name: as given, trimmed.
    pub name: String,
    /// The entry.
    pub entry: Entry,
}

impl NamedEntry {
    /// `entry` under its canonical name (its `Display`).
    #[must_use]
    pub fn new(entry: Entry) -> Self {
        Self { name: entry.to_string(), entry }
    }

    /// Parses `s` (trimmed), which stays the entry's name.
    ///
    /// # Errors
    /// As [`parse_entry`].
    pub fn parse(s: &str) -> Result<Self, EvalError> {
        let name = s.trim();
        Ok(Self { name: name.to_owned(), entry: parse_entry(name)? })
    }
}

impl From<Entry> for NamedEntry {
    fn from(entry: Entry) -> Self {
        Self::new(entry)
    }
}

/// Parses a bake method: `point`, `prefilter` or `doi`.
///
/// # Errors
/// [`EvalError::UnknownMethod`].
pub fn parse_method(s: &str) -> Result<Method, EvalError> {
    s.parse::<Method>().map_err(EvalError::UnknownMethod)
}

/// Parses a lookup name: `taylor` (\[Oat05\]'s first-order Taylor expansion from the nearest
/// node), `gtrilinear` (each corner extrapolated, then trilinear) or `hermite` (tricubic
/// Hermite from values and gradients).
///
/// # Errors
/// [`EvalError::UnknownLookup`].
pub fn parse_lookup(s: &str) -> Result<GradientLookup, EvalError> {
    match s {
        "taylor" => Ok(GradientLookup::Taylor),
        "gtrilinear" => Ok(GradientLookup::GradientTrilinear),
        "hermite" => Ok(GradientLookup::Hermite),
        _ => Err(EvalError::UnknownLookup(s.to_owned())),
    }
}

/// The name [`parse_lookup`] reads.
#[must_use]
pub fn lookup_name(l: GradientLookup) -> &'static str {
    match l {
        GradientLookup::Taylor => "taylor",
        GradientLookup::GradientTrilinear => "gtrilinear",
        GradientLookup::Hermite => "hermite",
    }
}

/// SH bands of `coeffs` coefficients per channel (`coeffs = bands²`).
#[must_use]
pub fn bands_of_coeffs(coeffs: usize) -> usize {
    (coeffs as f64).sqrt().round() as usize
}

/// Run-time bytes of a uniform grid in \[Oat05\]'s accounting ("GPU Memory Requirements"):
/// the RGB SH floats of every node of order `bands` (`3 n²`, `4 · 3 n²` with gradients), f32,
/// as `lightvol_volume::gradient::sample_bytes` counts them. The bake weights are not counted
/// (a renderer does not read them).
#[must_use]
pub fn uniform_memory_bytes(grid: &GridSpec, bands: usize, gradients: bool) -> usize {
    lightvol_volume::gradient::sample_bytes(grid.node_count(), bands, gradients)
}

/// Bytes of the uniform grid `grid`'s probes in the engine exports' texel format (one RGBA16F
/// texel per coefficient, `lightvol_volume::bricks::ATLAS_TEXEL_BYTES`): what the brick
/// export's probe memory is measured against.
#[must_use]
pub fn uniform_probe_bytes(grid: &GridSpec, coeffs: usize) -> usize {
    grid.node_count() * coeffs * lightvol_volume::bricks::ATLAS_TEXEL_BYTES
}

/// Run-time bytes of the uniform `doi` entry on `grid`: [`uniform_memory_bytes`] and its
/// node reach, six f32 per node (`NodeReach::memory_bytes`); the `adaptive` entry's budget.
#[must_use]
pub fn uniform_doi_memory_bytes(grid: &GridSpec, bands: usize) -> usize {
    uniform_memory_bytes(grid, bands, false) + grid.node_count() * size_of::<[f32; 6]>()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn entries_parse() {
        assert_eq!(parse_entry("doi").unwrap(), Entry::Uniform(Method::Doi));
        assert_eq!(parse_entry("doi-paper").unwrap(), Entry::Uniform(Method::DoiPaper));
        assert_eq!(
            parse_entry("doi-paper+taylor").unwrap(),
            Entry::Gradient(Method::DoiPaper, GradientLookup::Taylor)
        );
        assert_eq!(
            parse_entry("point+hermite").unwrap(),
            Entry::Gradient(Method::Point, GradientLookup::Hermite)
        );
        assert_eq!(parse_entry("adaptive").unwrap(), Entry::Adaptive(2));
        assert_eq!(parse_entry("doi-paper+lsq").unwrap(), Entry::Fitted(Method::DoiPaper, Fit::default()));
        assert_eq!(
            parse_entry("prefilter+lsq:0.5").unwrap(),
            Entry::Fitted(Method::Prefilter, Fit::LeastSquares { lambda: 0.5 })
        );
        assert_eq!(parse_entry("doi-paper+average").unwrap(), Entry::Fitted(Method::DoiPaper, Fit::Average));
        assert_eq!(parse_entry("point+ddgi").unwrap(), Entry::Baseline(Baseline::Ddgi));
        assert_eq!(parse_entry("point+validity").unwrap(), Entry::Baseline(Baseline::Validity));
        assert_eq!(parse_entry("point+apv").unwrap(), Entry::Baseline(Baseline::Apv));
        assert_eq!(parse_entry("doi+apv").unwrap(), Entry::Targeted(Method::Doi, EngineLookup::Apv));
        assert_eq!(parse_entry("doi+relit").unwrap(), Entry::Relit(Method::Doi, 3));
        assert_eq!(parse_entry("doi+relit4").unwrap(), Entry::Relit(Method::Doi, 4));
        assert_eq!(Entry::Relit(Method::Point, 3).to_string(), "point+relit");
        assert_eq!(Entry::Relit(Method::Doi, 2).to_string(), "doi+relit2");
        assert!(parse_entry("doi+relit5").is_err());
        assert_eq!(parse_entry("doi+skyocc").unwrap(), Entry::SkyOcclusion(Method::Doi));
        assert_eq!(Entry::SkyOcclusion(Method::Point).to_string(), "point+skyocc");
        assert_eq!(parse_entry("doi+three").unwrap(), Entry::Targeted(Method::Doi, EngineLookup::Three));
        assert_eq!(
            parse_entry("doi+lightvol").unwrap(),
            Entry::Targeted(Method::Doi, EngineLookup::Lightvol)
        );
        assert_eq!(parse_entry("bound+three").unwrap(), Entry::Bound(EngineLookup::Three));
        assert_eq!(parse_entry("bound+lightvol").unwrap(), Entry::Bound(EngineLookup::Lightvol));
        assert_eq!(Entry::Bound(EngineLookup::Apv).to_string(), "bound+apv");
        assert!(parse_entry("bound+unity").unwrap_err().to_string().contains("'unity'"));
        assert_eq!(Entry::Targeted(Method::Doi, EngineLookup::Lightvol).to_string(), "doi+lightvol");
        assert_eq!(parse_entry("point+vlm").unwrap(), Entry::Baseline(Baseline::Vlm));
        assert!(parse_entry("doi+lsq:-2").is_err());
        assert_eq!(parse_entry("adaptive1").unwrap(), Entry::Adaptive(1));
        assert_eq!(parse_entry("bricks").unwrap(), Entry::Bricks(0));
        assert_eq!(parse_entry("bricks8").unwrap(), Entry::Bricks(8));
        assert_eq!(Entry::Bricks(8).to_string(), "bricks8");
        assert!(parse_entry("bricks0").is_err() && parse_entry("bricksx").is_err());
        assert_eq!(parse_entry("adaptive2").unwrap(), Entry::Adaptive(2));
        assert!(parse_entry("adaptive0").is_err());
        assert!(parse_entry("adaptive9").is_err());
        assert!(parse_entry("doi+cubic").is_err());
        assert!(parse_entry("bogus+taylor").is_err());
        assert_eq!(
            parse_entry("doi+cubic").unwrap_err().to_string(),
            "unknown gradient lookup 'cubic' (taylor, gtrilinear, hermite)"
        );
        assert_eq!(
            parse_entry("adaptive9").unwrap_err().to_string(),
            "'adaptive9': adaptiveL needs a finest level L from 1 to 3"
        );
        assert_eq!(NamedEntry::parse(" doi+lsq:0.5 ").unwrap().name, "doi+lsq:0.5");
    }

    /// Every entry's name parses back to the entry.
    #[test]
    fn names_round_trip() {
        let mut entries = vec![Entry::Adaptive(1), Entry::Adaptive(2), Entry::Adaptive(3)];
        for m in [Method::Point, Method::Prefilter, Method::DoiPaper] {
            entries.push(Entry::Uniform(m));
            entries.extend(LOOKUPS.map(|l| Entry::Gradient(m, l)));
            entries.push(Entry::Fitted(m, Fit::Average));
            entries.push(Entry::Fitted(m, Fit::LeastSquares { lambda: 0.125 }));
        }
        entries.extend(Baseline::ALL.map(Entry::Baseline));
        for e in entries {
            assert_eq!(parse_entry(&e.to_string()).unwrap(), e, "{e}");
        }
        assert_eq!(NamedEntry::new(Entry::Adaptive(2)).name, "adaptive");
        for l in LOOKUPS {
            assert_eq!(parse_lookup(lookup_name(l)).unwrap(), l);
        }
        assert!(parse_lookup("cubic").is_err());
    }

    /// \[Oat05\]'s accounting for a 16×16×7 order-3 grid: 27 floats × 4 bytes per node, 108
    /// with gradients.
    #[test]
    fn uniform_memory_is_27_floats_per_node() {
        let g = GridSpec::new([0.0; 3], [1.0; 3], [16, 16, 7]).unwrap();
        assert_eq!(uniform_memory_bytes(&g, bands_of_coeffs(9), false), 16 * 16 * 7 * 27 * 4);
        assert_eq!(uniform_memory_bytes(&g, 3, true), 16 * 16 * 7 * 108 * 4);
    }
}
