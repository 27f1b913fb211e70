//! The JSON sidecar: a small human-readable description of a volume file.
//!
//! It states everything an engine needs to interpret the texels: the grid (box,
//! resolution, grid-to-world transform), the SH convention and order, the encoding, the
//! units, the texture layout and the bake metadata. The KTX2 export embeds it in its
//! key/value data (key [`crate::io::ktx2::KTX2_SIDECAR_KEY`]); DDS and Bevy exports, which
//! have no room for metadata, write it beside the texture. f64 values round-trip exactly
//! (serde_json with `float_roundtrip`).
//!
//! ```json
//! {
//!   "format": "lightvol-volume", "version": 1,
//!   "grid": { "min": [0,0,0], "max": [4,2,3], "res": [9,5,7], "to_world": null },
//!   "sh": { "coeffs": 9, "bands": 3, "quantity": "radiance", "convention": "..." },
//!   "encoding": { "kind": "f16" }, "units": "relative",
//!   "storage": { "file": "level.ktx2", "layout": "..." },
//!   "bake": { "method": "domain", "samples": 1000000, "seed": 1, ... }
//! }
//! ```
//!
//! A volume with a validity mask ([`crate::validity`]) adds a `validity` section (and is
//! written as version 2, [`format_version`]):
//!
//! ```json
//! "validity": { "invalid_nodes": 7, "layout": "...", "lookup": "...", "bits": "0502" }
//! ```
//!
//! `bits` is the mask packed one bit per node ([`crate::ValidityMask::to_hex`];
//! [`VALIDITY_LAYOUT`] in words) and `lookup` the run-time weighting it asks for
//! ([`VALIDITY_LOOKUP`]).
//!
//! A volume with a node reach ([`crate::reach`]) adds a `reach` section (version 4):
//!
//! ```json
//! "reach": { "limited_nodes": 12, "layout": "...", "lookup": "...", "values": "0000803e..." }
//! ```
//!
//! `values` holds every node's six reaches ([`crate::NodeReach::to_hex`]; [`REACH_LAYOUT`]
//! in words) and `lookup` the run-time test they are for ([`REACH_LOOKUP`]).

use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::encode::Encoding;
use crate::error::{FileFormat, VolumeError};
use crate::grid::{GridSpec, Placement};
use crate::io::util::{read_bounded, write_atomic};
use crate::metadata::{BakeMetadata, BakeRecord};
use crate::reach::NodeReach;
use crate::validity::ValidityMask;
use crate::volume::{IrradianceVolume, check_coeffs};

/// Value of the `format` field.
pub const FORMAT_NAME: &str = "lightvol-volume";
/// Newest sidecar / file-format version (the sidecar's `version`, the EXR's
/// `lightvol.version`); readers accept it and every older one. Version 2 added the validity
/// mask, version 3 the typed settings record ([`crate::BakeRecord`]), version 4 the node
/// reach ([`crate::reach`]), version 5 light groups in the EXR file
/// ([`crate::io::groups`]). Writers write the
/// oldest version that holds the volume ([`format_version`]), so a volume without a mask or
/// record gives the same bytes as before, and an older reader refuses a file with them as a
/// newer version instead of reading it without them.
pub const FORMAT_VERSION: u32 = 5;
/// The first version that can carry a validity mask.
pub const VALIDITY_VERSION: u32 = 2;
/// The first version that can carry the typed settings record.
pub const SETTINGS_VERSION: u32 = 3;
/// The first version that can carry a node reach.
pub const REACH_VERSION: u32 = 4;
/// The first version that can carry light groups ([`crate::io::groups`]).
pub const GROUPS_VERSION: u32 = 5;
/// The bit packing of the `validity.bits` field, in words ([`ValidityMask::to_hex`]).
pub const VALIDITY_LAYOUT: &str = "one bit per node, node i = x + nx*(y + ny*z) is bit i%8 (least significant \
                                   first) of byte i/8, 1 = valid; each byte as two lowercase hex digits";
/// The run-time weighting a validity mask asks for, in words ([`crate::validity`]).
pub const VALIDITY_LOOKUP: &str = "trilinear weights renormalised over the valid corners of the cell; plain \
                                   trilinear when every corner is valid or no valid corner has weight";

/// The packing of the `reach.values` field, in words ([`NodeReach::to_hex`]).
pub const REACH_LAYOUT: &str = "six f32 per node, node i = x + nx*(y + ny*z), in the order +x -x +y -y +z -z of the \
                                grid axes: how far the node sees along that axis, in cells, capped at 1; each \
                                value's bits little-endian, each byte as two lowercase hex digits";
/// The run-time test a node reach asks for, in words ([`crate::reach`]).
pub const REACH_LOOKUP: &str = "a corner is left out of the trilinear weights when the query (moved a tenth of the \
                                smallest cell edge along the surface normal) lies beyond its reach on an axis \
                                whose cell edge both end nodes see blocked (their reaches along it sum to at most \
                                one cell); the other weights renormalised; plain trilinear when every corner sees \
                                the query or none with weight does";

/// The version a file holding `vol` is written as: [`REACH_VERSION`] when it has a node
/// reach, else [`SETTINGS_VERSION`] when its metadata has the typed settings record, else
/// [`VALIDITY_VERSION`] when it has a validity mask, else 1.
#[must_use]
pub fn format_version(vol: &IrradianceVolume) -> u32 {
    if vol.reach().is_some() {
        REACH_VERSION
    } else if vol.metadata().settings.is_some() {
        SETTINGS_VERSION
    } else if vol.validity().is_some() {
        VALIDITY_VERSION
    } else {
        1
    }
}
/// The SH convention every lightvol file uses (lightvol-sh's); readers reject others.
pub const SH_CONVENTION: &str = "real orthonormal SH; flat index l*(l+1)+m; no Condon-Shortley phase; \
                                 +z polar axis; world-space directions";
/// What the coefficients represent.
pub const QUANTITY: &str = "radiance";

/// The grid section.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GridJson {
    /// Grid-space box minimum.
    pub min: [f64; 3],
    /// Grid-space box maximum.
    pub max: [f64; 3],
    /// Nodes per axis.
    pub res: [u32; 3],
    /// Row-major 3×4 grid-to-world matrix, or null for identity.
    pub to_world: Option<[[f64; 4]; 3]>,
}

/// The SH section.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ShJson {
    /// Coefficients per colour channel.
    pub coeffs: usize,
    /// Bands (`sqrt(coeffs)`).
    pub bands: usize,
    /// What the coefficients represent ([`QUANTITY`]).
    pub quantity: String,
    /// The basis convention ([`SH_CONVENTION`]).
    pub convention: String,
}

/// Where and how the texels are stored.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StorageJson {
    /// The described file's name, if the sidecar sits beside one.
    pub file: Option<String>,
    /// The texel layout, in words.
    pub layout: String,
}

/// The bake section (everything of [`BakeMetadata`] except the units).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BakeJson {
    /// Sampling method.
    pub method: String,
    /// Samples used.
    pub samples: u64,
    /// Random seed.
    pub seed: u64,
    /// Shard index.
    pub shard_index: u32,
    /// Shard count.
    pub shard_count: u32,
    /// Scene/settings hash.
    pub scene_hash: String,
    /// The method and settings as a typed record, when the bake wrote one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub settings: Option<BakeRecord>,
}

/// The validity section: the mask of [`crate::validity`], packed.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct ValidityJson {
    /// Nodes marked invalid (checked against `bits`).
    pub invalid_nodes: usize,
    /// The packing of `bits` ([`VALIDITY_LAYOUT`]).
    pub layout: String,
    /// The lookup the mask is for ([`VALIDITY_LOOKUP`]).
    pub lookup: String,
    /// The packed mask ([`ValidityMask::to_hex`]).
    pub bits: String,
}

impl ValidityJson {
    /// The section describing `mask`.
    #[must_use]
    pub fn of(mask: &ValidityMask) -> Self {
        Self {
            invalid_nodes: mask.invalid_count(),
            layout: VALIDITY_LAYOUT.into(),
            lookup: VALIDITY_LOOKUP.into(),
            bits: mask.to_hex(),
        }
    }

    /// The mask for a grid of `nodes` nodes; errors on another layout or lookup, bits that
    /// do not parse ([`ValidityMask::from_hex`]) or an invalid count that differs.
    pub fn mask(&self, nodes: usize) -> Result<ValidityMask, VolumeError> {
        let f = FileFormat::Sidecar;
        if self.layout != VALIDITY_LAYOUT {
            return Err(VolumeError::unsupported(f, format!("validity layout {:?}", self.layout)));
        }
        if self.lookup != VALIDITY_LOOKUP {
            return Err(VolumeError::unsupported(f, format!("validity lookup {:?}", self.lookup)));
        }
        let mask = ValidityMask::from_hex(&self.bits, nodes)
            .map_err(|e| VolumeError::malformed(f, e.to_string()))?;
        if mask.invalid_count() != self.invalid_nodes {
            return Err(VolumeError::malformed(
                f,
                format!(
                    "validity says {} invalid nodes, its bits mark {}",
                    self.invalid_nodes,
                    mask.invalid_count()
                ),
            ));
        }
        Ok(mask)
    }
}

/// The reach section: the node reach of [`crate::reach`], packed.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct ReachJson {
    /// Nodes that see less than a cell in some direction (checked against `values`).
    pub limited_nodes: usize,
    /// The packing of `values` ([`REACH_LAYOUT`]).
    pub layout: String,
    /// The lookup the reach is for ([`REACH_LOOKUP`]).
    pub lookup: String,
    /// The packed reach ([`NodeReach::to_hex`]).
    pub values: String,
}

impl ReachJson {
    /// The section describing `reach`.
    #[must_use]
    pub fn of(reach: &NodeReach) -> Self {
        Self {
            limited_nodes: reach.limited_count(),
            layout: REACH_LAYOUT.into(),
            lookup: REACH_LOOKUP.into(),
            values: reach.to_hex(),
        }
    }

    /// The reach for a grid of `nodes` nodes; errors on another layout or lookup, values
    /// that do not parse ([`NodeReach::from_hex`]) or a limited count that differs.
    pub fn reach(&self, nodes: usize) -> Result<NodeReach, VolumeError> {
        let f = FileFormat::Sidecar;
        if self.layout != REACH_LAYOUT {
            return Err(VolumeError::unsupported(f, format!("reach layout {:?}", self.layout)));
        }
        if self.lookup != REACH_LOOKUP {
            return Err(VolumeError::unsupported(f, format!("reach lookup {:?}", self.lookup)));
        }
        let reach =
            NodeReach::from_hex(&self.values, nodes).map_err(|e| VolumeError::malformed(f, e.to_string()))?;
        if reach.limited_count() != self.limited_nodes {
            return Err(VolumeError::malformed(
                f,
                format!(
                    "reach says {} limited nodes, its values limit {}",
                    self.limited_nodes,
                    reach.limited_count()
                ),
            ));
        }
        Ok(reach)
    }
}

/// The whole sidecar document.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Sidecar {
    /// Always [`FORMAT_NAME`].
    pub format: String,
    /// Format version ([`FORMAT_VERSION`]).
    pub version: u32,
    /// Grid.
    pub grid: GridJson,
    /// SH order and convention.
    pub sh: ShJson,
    /// How the texels encode the coefficients.
    pub encoding: Encoding,
    /// Radiometric unit of the coefficients.
    pub units: String,
    /// Texel layout.
    pub storage: StorageJson,
    /// The validity mask, when the volume has one (version 2 and later).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub validity: Option<ValidityJson>,
    /// The node reach, when the volume has one (version 4 and later).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reach: Option<ReachJson>,
    /// Bake metadata.
    pub bake: BakeJson,
    /// The frame of the described file's data (`y-up` or `z-up`): its world positions
    /// (`grid.to_world`) and SH directions are in it. Engine exports are in the scene
    /// file's frame; the native EXR is in lightvol's internal `z-up` frame.
    #[serde(default = "internal_frame")]
    pub frame: crate::up_axis::UpAxis,
    /// The frame of the scene file the volume was baked from.
    #[serde(default = "internal_frame")]
    pub source_frame: crate::up_axis::UpAxis,
    /// The grid along the scene file's axes and in its frame, exactly as `lightvol info`
    /// prints it (`res` and `bounds` that give the same grid back to a bake). For the
    /// engine exports it is `grid` itself; for the native file, whose data stays in the
    /// internal frame, it is `grid` rotated into the file's frame.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub file_grid: Option<crate::frame::FileGrid>,
    /// FNV-1a checksum (16 hex digits) of the volume as the described file decodes to
    /// ([`crate::checksum::volume_checksum`]); written by the KTX2 and DDS exports and
    /// required by their readers.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub checksum: Option<String>,
    /// The engine lookup the described file is meant for (`lightvol`, `three`, `bevy`:
    /// [`crate::engine_lookup::EngineLookup`]); files written before it was recorded are
    /// read as `lightvol`.
    #[serde(default = "lightvol_lookup")]
    pub lookup: String,
}

/// The lookup of files that name none: lightvol's own.
fn lightvol_lookup() -> String {
    LIGHTVOL_LOOKUP.into()
}

/// Name of lightvol's own lookup (validity and node reach), as `--lookup` spells it.
pub const LIGHTVOL_LOOKUP: &str = "lightvol";

impl Sidecar {
    /// The same description with the data in `frame` (an export converted by
    /// [`crate::frame::to_file_frame`]).
    #[must_use]
    pub fn in_frame(mut self, frame: crate::up_axis::UpAxis) -> Self {
        self.frame = frame;
        self.file_grid = Some(crate::frame::FileGrid {
            res: self.grid.res,
            bounds: [self.grid.min, self.grid.max],
            frame,
        });
        self
    }

    /// Describes `vol` stored with `encoding` in the given `layout`, its data in the
    /// internal frame (see [`Self::in_frame`] for exports in the file's frame).
    #[must_use]
    pub fn describe(vol: &IrradianceVolume, encoding: Encoding, file: Option<String>, layout: &str) -> Self {
        let spec = vol.spec();
        let (min, max) = spec.bounds();
        let m = vol.metadata();
        Self {
            format: FORMAT_NAME.into(),
            version: format_version(vol),
            grid: GridJson {
                min,
                max,
                res: spec.res(),
                to_world: spec.placement().map(Placement::to_world_matrix),
            },
            sh: ShJson {
                coeffs: vol.coeffs(),
                bands: vol.bands(),
                quantity: QUANTITY.into(),
                convention: SH_CONVENTION.into(),
            },
            encoding,
            units: m.units.clone(),
            storage: StorageJson { file, layout: layout.into() },
            validity: vol.validity().map(ValidityJson::of),
            reach: vol.reach().map(ReachJson::of),
            bake: BakeJson {
                method: m.method.clone(),
                samples: m.sampling_rays,
                seed: m.seed,
                shard_index: m.shard_index,
                shard_count: m.shard_count,
                scene_hash: m.scene_hash.clone(),
                settings: m.settings.clone(),
            },
            frame: crate::up_axis::UpAxis::INTERNAL,
            source_frame: m.frame,
            file_grid: Some(crate::frame::FileGrid::of(spec, m.frame)),
            checksum: None,
            lookup: LIGHTVOL_LOOKUP.into(),
        }
    }

    /// Pretty-printed JSON.
    #[must_use]
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).expect("the sidecar is plain data")
    }

    /// Parses and validates a sidecar: format name, version, SH convention and quantity,
    /// coefficient count, and the grid (via [`Self::grid_spec`]).
    pub fn from_json(text: &str) -> Result<Self, VolumeError> {
        let s: Sidecar = serde_json::from_str(text)
            .map_err(|e| VolumeError::malformed(FileFormat::Sidecar, e.to_string()))?;
        s.validate()?;
        Ok(s)
    }

    /// Checks every field that a reader relies on.
    pub fn validate(&self) -> Result<(), VolumeError> {
        let f = FileFormat::Sidecar;
        if self.format != FORMAT_NAME {
            return Err(VolumeError::malformed(
                f,
                format!("format is {:?}, expected {FORMAT_NAME:?}", self.format),
            ));
        }
        if self.version == 0 || self.version > FORMAT_VERSION {
            return Err(VolumeError::unsupported(
                f,
                format!("version {} (this reader supports 1..={FORMAT_VERSION})", self.version),
            ));
        }
        if self.sh.convention != SH_CONVENTION {
            return Err(VolumeError::unsupported(f, format!("SH convention {:?}", self.sh.convention)));
        }
        if self.sh.quantity != QUANTITY {
            return Err(VolumeError::unsupported(f, format!("quantity {:?}", self.sh.quantity)));
        }
        check_coeffs(self.sh.coeffs)?;
        if self.sh.bands * self.sh.bands != self.sh.coeffs {
            return Err(VolumeError::malformed(
                f,
                format!("{} bands but {} coeffs", self.sh.bands, self.sh.coeffs),
            ));
        }
        if self.bake.shard_count == 0 || self.bake.shard_index >= self.bake.shard_count {
            return Err(VolumeError::malformed(
                f,
                format!("shard {} of {}", self.bake.shard_index, self.bake.shard_count),
            ));
        }
        if self.bake.settings.is_some() && self.version < SETTINGS_VERSION {
            return Err(VolumeError::malformed(
                f,
                format!("version {} has no settings record (from version {SETTINGS_VERSION})", self.version),
            ));
        }
        let spec = self.grid_spec()?;
        if self.validity.is_some() && self.version < VALIDITY_VERSION {
            return Err(VolumeError::malformed(
                f,
                format!("version {} has no validity section (from version {VALIDITY_VERSION})", self.version),
            ));
        }
        self.validity_mask_for(&spec)?;
        if self.reach.is_some() && self.version < REACH_VERSION {
            return Err(VolumeError::malformed(
                f,
                format!("version {} has no reach section (from version {REACH_VERSION})", self.version),
            ));
        }
        self.node_reach_for(&spec)?;
        Ok(())
    }

    /// The node reach the sidecar describes, if any (checked as in [`Self::validate`]).
    pub fn node_reach(&self) -> Result<Option<NodeReach>, VolumeError> {
        self.node_reach_for(&self.grid_spec()?)
    }

    fn node_reach_for(&self, spec: &GridSpec) -> Result<Option<NodeReach>, VolumeError> {
        self.reach.as_ref().map(|r| r.reach(spec.node_count())).transpose()
    }

    /// The validity mask the sidecar describes, if any (checked as in [`Self::validate`]).
    pub fn validity_mask(&self) -> Result<Option<ValidityMask>, VolumeError> {
        self.validity_mask_for(&self.grid_spec()?)
    }

    fn validity_mask_for(&self, spec: &GridSpec) -> Result<Option<ValidityMask>, VolumeError> {
        self.validity.as_ref().map(|v| v.mask(spec.node_count())).transpose()
    }

    /// The validated grid.
    pub fn grid_spec(&self) -> Result<GridSpec, VolumeError> {
        let g = GridSpec::new(self.grid.min, self.grid.max, self.grid.res)?;
        Ok(match self.grid.to_world {
            Some(m) => g.with_placement(Placement::new(m)?),
            None => g,
        })
    }

    /// The bake metadata (with the units).
    #[must_use]
    pub fn metadata(&self) -> BakeMetadata {
        BakeMetadata {
            method: self.bake.method.clone(),
            sampling_rays: self.bake.samples,
            seed: self.bake.seed,
            shard_index: self.bake.shard_index,
            shard_count: self.bake.shard_count,
            scene_hash: self.bake.scene_hash.clone(),
            units: self.units.clone(),
            frame: self.source_frame,
            settings: self.bake.settings.clone(),
        }
    }
}

fn internal_frame() -> crate::up_axis::UpAxis {
    crate::up_axis::UpAxis::INTERNAL
}

/// Writes a sidecar atomically (temporary file and rename).
pub fn write_sidecar(path: &Path, sidecar: &Sidecar) -> Result<(), VolumeError> {
    write_atomic(path, sidecar.to_json().as_bytes())
}

/// Reads and validates a sidecar.
pub fn read_sidecar(path: &Path) -> Result<Sidecar, VolumeError> {
    let bytes = read_bounded(path)?;
    let text = std::str::from_utf8(&bytes)
        .map_err(|e| VolumeError::malformed(FileFormat::Sidecar, e.to_string()))?;
    Sidecar::from_json(text)
}

/// The conventional sidecar path for a texture file: `name.ext` → `name.ext.json`.
#[must_use]
pub fn sidecar_path(texture: &Path) -> std::path::PathBuf {
    let mut s = texture.as_os_str().to_owned();
    s.push(".json");
    s.into()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn vol() -> IrradianceVolume {
        let spec = GridSpec::new([0.1, -0.3, 1.0 / 3.0], [4.0, 2.0, 3.0], [9, 5, 7])
            .unwrap()
            .with_placement(Placement::translation([1e-17, 2.5, -7.0]).unwrap());
        IrradianceVolume::zeros(spec, 9).unwrap()
    }

    #[test]
    fn round_trips_exactly() {
        let v = vol();
        let s = Sidecar::describe(&v, Encoding::SRGB8, Some("x.dds".into()), "test layout");
        let back = Sidecar::from_json(&s.to_json()).unwrap();
        assert_eq!(back, s);
        assert_eq!(&back.grid_spec().unwrap(), v.spec());
        assert_eq!(back.metadata(), *v.metadata());
        assert!(s.to_json().contains("\"kind\": \"srgb8\""));
    }

    #[test]
    fn rejects_wrong_fields() {
        let s = Sidecar::describe(&vol(), Encoding::F32, None, "");
        let bad = |edit: &dyn Fn(&mut Sidecar)| {
            let mut t = s.clone();
            edit(&mut t);
            Sidecar::from_json(&t.to_json()).is_err()
        };
        assert!(bad(&|t| t.format = "other".into()));
        assert!(bad(&|t| t.version = FORMAT_VERSION + 1));
        assert!(bad(&|t| t.validity = Some(ValidityJson::of(&ValidityMask::new(vec![true; 9 * 5 * 7])))));
        assert!(bad(&|t| t.sh.convention = "Condon-Shortley".into()));
        assert!(bad(&|t| t.sh.coeffs = 8));
        assert!(bad(&|t| t.sh.bands = 2));
        assert!(bad(&|t| t.grid.res = [1, 5, 7]));
        assert!(bad(&|t| t.grid.to_world = Some([[0.0; 4]; 3])));
        assert!(bad(&|t| t.bake.shard_count = 0));
        assert!(Sidecar::from_json("{").is_err());
        assert!(Sidecar::from_json("[]").is_err());
    }

    /// A volume without a mask is described as version 1 with no `validity` field (the
    /// text of a version-1 sidecar); with a mask as version 2, and the mask reads back. A
    /// damaged section is refused, naming what is wrong.
    #[test]
    fn validity_section_round_trips_and_is_checked() {
        let plain = Sidecar::describe(&vol(), Encoding::F16, None, "l");
        assert_eq!(plain.version, 1);
        assert!(!plain.to_json().contains("validity"));
        assert_eq!(Sidecar::from_json(&plain.to_json()).unwrap().validity_mask().unwrap(), None);
        let n = 9 * 5 * 7;
        let mask = ValidityMask::new((0..n).map(|i| i % 5 != 2).collect());
        let masked = vol().with_validity(mask.clone()).unwrap();
        let s = Sidecar::describe(&masked, Encoding::F16, None, "l");
        assert_eq!(s.version, VALIDITY_VERSION);
        let back = Sidecar::from_json(&s.to_json()).unwrap();
        assert_eq!(back, s);
        assert_eq!(back.validity_mask().unwrap(), Some(mask));
        let err = |edit: &dyn Fn(&mut ValidityJson)| {
            let mut t = s.clone();
            edit(t.validity.as_mut().unwrap());
            Sidecar::from_json(&t.to_json()).unwrap_err().to_string()
        };
        assert_eq!(
            err(&|v| v.invalid_nodes += 1),
            "malformed JSON sidecar data: validity says 64 invalid nodes, its bits mark 63"
        );
        assert!(err(&|v| v.bits.pop().map_or((), drop)).contains("hex digits"));
        assert!(
            err(&|v| v.layout = "bytes".into())
                .starts_with("unsupported JSON sidecar content: validity layout")
        );
        assert!(err(&|v| v.lookup = "nearest".into()).contains("validity lookup"));
    }

    #[test]
    fn file_round_trip_and_path() {
        let dir = tempfile::tempdir().unwrap();
        let p = sidecar_path(&dir.path().join("v.dds"));
        assert!(p.to_string_lossy().ends_with("v.dds.json"));
        let s = Sidecar::describe(&vol(), Encoding::F16, Some("v.dds".into()), "l");
        write_sidecar(&p, &s).unwrap();
        assert_eq!(read_sidecar(&p).unwrap(), s);
    }
}
