//! Engine export for three.js's `LightProbeGrid` (r187, `LightProbeGridWebGL`): the probe
//! atlas as an RGBA16F 3D KTX2 that three's own `KTX2Loader` reads, in the scene file's axes.
//!
//! ## What three expects (three.js r187)
//! - `src/renderers/shaders/ShaderChunk/lightprobes_pars_fragment.glsl.js` lines 28-89
//!   (`getLightProbeGridIrradiance`): probes at the centres of the `resolution` cells of the
//!   grid's `boundingBox`, sampled at `p + n ⊙ spacing / 2` (`spacing = size / resolution`),
//!   `uvw` clamped to the outermost probe centres, hardware trilinear filtering, then
//!   `E(n) = Σ_j Â_j c_j Y_j(n)` with lightvol's basis order and constants (`0.886227 = π
//!   Y_00`, `2 · 0.511664 = (2π/3) · 0.488603`, …), clamped at zero; lines 15-26:
//!   a fragment whose sample point lies outside the box (grown by 1% of a cell) is not lit.
//! - `examples/jsm/lighting/LightProbeGridWebGL.js` lines 59-81 and 713-727: one atlas of
//!   depth `7 · (nz + 2)`: the 27 floats of a probe (`c0.rgb, c1.rgb, …, c8.rgb`) packed
//!   four to a texel into seven sub-volumes (the last texel's alpha 0), each sub-volume
//!   `nz` data slices between two padding slices that copy its first and last data slice.
//!
//! So lightvol's nodes are three's probes when the box extends half a cell beyond the
//! outermost nodes, and the coefficients go in unscaled. The KTX2 key/value data holds the
//! placement ([`ThreeInfo`]) under [`THREE_INFO_KEY`], and `PATH.json` beside the texture
//! holds the same. A client adds two lines to what the loader gives it: linear filtering
//! (the loader sets nearest for uncompressed textures) and `updateBoundingBox()` after
//! placing the grid (docs/ENGINES.md).

use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::checksum::{fnv1a, from_hex, to_hex};
use crate::encode::Encoding;
use crate::error::{FileFormat, VolumeError};
use crate::grid::GridSpec;
use crate::io::ktx2::{KTX2_WRITER, ktx2_rgba16f_bytes, kvd_value, parse_ktx2_rgba16f};
use crate::io::sidecar::{Sidecar, sidecar_path};
use crate::io::util::{guard, read_bounded, write_atomic};
use crate::slab::f16_bytes;
use crate::up_axis::UpAxis;
use crate::volume::IrradianceVolume;

/// Key of the placement in the KTX2 key/value data.
pub const THREE_INFO_KEY: &str = "lightvol.three";
/// Texels per probe: 27 floats, four to an RGBA texel.
pub const THREE_SUBVOLUMES: u32 = 7;
/// Padding slices at each end of a sub-volume.
pub const THREE_PADDING: u32 = 1;
/// The lookup a three.js export is meant for, as `--lookup` names it (three.js's own,
/// `EngineLookup::Three`).
pub const THREE_LOOKUP: &str = "three";
/// SH coefficients per channel of three's grid (L2).
pub const THREE_COEFFS: usize = 9;

/// Where three places the grid, and what the texels hold.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ThreeInfo {
    /// Probes per axis: `LightProbeGridWebGL`'s `widthProbes, heightProbes, depthProbes`.
    pub resolution: [u32; 3],
    /// Centre of the box: the grid's `position`.
    pub position: [f64; 3],
    /// Size of the box: `width, height, depth` (half a cell beyond the outermost probes).
    pub size: [f64; 3],
    /// The box's corners (`boundingBox` after `updateBoundingBox()`).
    pub bounds: [[f64; 3]; 2],
    /// The first and the last probe's centres: lightvol's grid bounds, exactly (the box
    /// is half a cell beyond them; recomputing them from it would round).
    pub probes: [[f64; 3]; 2],
    /// The frame of positions and SH directions: the scene file's.
    pub frame: UpAxis,
    /// The lookup the file is meant for.
    pub lookup: String,
    /// What the texels hold.
    pub quantity: String,
    /// The unit of the coefficients.
    pub units: String,
    /// FNV-1a checksum (16 hex digits) of the level data.
    pub texel_checksum: String,
}

/// The placement three needs for `vol` (already in the file's frame and unplaced): the box
/// half a cell beyond the outermost nodes.
fn placement(spec: &GridSpec) -> ([f64; 3], [f64; 3], [[f64; 3]; 2]) {
    let (lo, hi) = spec.bounds();
    let h = spec.cell_size();
    let min: [f64; 3] = std::array::from_fn(|a| lo[a] - h[a] / 2.0);
    let max: [f64; 3] = std::array::from_fn(|a| hi[a] + h[a] / 2.0);
    (std::array::from_fn(|a| (min[a] + max[a]) / 2.0), std::array::from_fn(|a| max[a] - min[a]), [min, max])
}

/// The atlas depth for `nz` probes along z.
#[must_use]
pub fn atlas_depth(nz: u32) -> u32 {
    THREE_SUBVOLUMES * (nz + 2 * THREE_PADDING)
}

/// Serialises the three.js export of `vol` in memory: the volume in its scene file's frame
/// ([`crate::frame::to_file_frame`]), order-2 coefficients zero-padded to L2.
///
/// # Errors
/// A grid that three cannot place (a rotated or otherwise placed grid: three's box is
/// axis-aligned), more than 9 coefficients, or a value beyond f16.
pub fn three_to_bytes(vol: &IrradianceVolume) -> Result<Vec<u8>, VolumeError> {
    encode(vol).map(|(_, _, bytes)| bytes)
}

/// The three.js export of `vol`: its placement, the volume in the file's frame it was
/// laid out from, and the KTX2 bytes ([`three_to_bytes`]).
fn encode(vol: &IrradianceVolume) -> Result<(ThreeInfo, IrradianceVolume, Vec<u8>), VolumeError> {
    let frame = vol.metadata().frame;
    if vol.spec().placement().is_some() {
        return Err(VolumeError::InvalidData(
            "three.js places probe grids in axis-aligned boxes; this volume's grid has a placement transform (bake it without --transform)".into(),
        ));
    }
    if vol.coeffs() > THREE_COEFFS {
        return Err(VolumeError::InvalidData(format!(
            "three.js's probe grid holds {THREE_COEFFS} SH coefficients per channel (order 3); this volume has {} (bake with --order 3)",
            vol.coeffs()
        )));
    }
    let file_vol = crate::frame::to_file_frame(vol, frame)?;
    let vol = &file_vol;
    let spec = vol.spec();
    let [nx, ny, nz] = spec.res();
    let depth = atlas_depth(nz);
    let padded = nz + 2 * THREE_PADDING;
    let (rx, ry) = (nx as usize, ny as usize);
    let mut texels = vec![0u8; rx * ry * depth as usize * 8];
    let coeffs = vol.coeffs();
    for z in 0..padded {
        // Padding slices copy the nearest data slice.
        let zd = z.saturating_sub(THREE_PADDING).min(nz - 1);
        for y in 0..ny {
            for x in 0..nx {
                let node = vol.node(spec.node_index(x, y, zd));
                let mut floats = [0.0f32; 28];
                floats[..3 * coeffs].copy_from_slice(node);
                for t in 0..THREE_SUBVOLUMES {
                    let slice = t * padded + z;
                    let at = ((slice as usize * ry + y as usize) * rx + x as usize) * 8;
                    for k in 0..4 {
                        let v = floats[4 * t as usize + k];
                        texels[at + 2 * k..at + 2 * k + 2].copy_from_slice(&f16_bytes(v, "SH coefficient")?);
                    }
                }
            }
        }
    }
    let (position, size, bounds) = placement(spec);
    let info = ThreeInfo {
        resolution: [nx, ny, nz],
        position,
        size,
        bounds,
        probes: {
            let (lo, hi) = spec.bounds();
            [lo, hi]
        },
        frame,
        lookup: THREE_LOOKUP.into(),
        quantity:
            "incident radiance SH, lightvol's basis order and normalisation (three.js LightProbeGrid's)"
                .into(),
        units: vol.metadata().units.clone(),
        texel_checksum: to_hex(fnv1a(&texels)),
    };
    let json = serde_json::to_string(&info).map_err(|e| VolumeError::InvalidData(e.to_string()))?;
    let bytes =
        ktx2_rgba16f_bytes([nx, ny, depth], &texels, &[("KTXwriter", KTX2_WRITER), (THREE_INFO_KEY, &json)]);
    Ok((info, file_vol, bytes))
}

/// The JSON beside a three.js export: the usual description of the texture (grid and
/// `file_grid` in the file's frame, `lookup: "three"`) and three's placement under `three`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ThreeSidecar {
    /// What every texture's sidecar says ([`Sidecar`]).
    #[serde(flatten)]
    pub description: Sidecar,
    /// The placement a client passes to `LightProbeGrid` (the same as the KTX2 entry).
    pub three: ThreeInfo,
}

/// Writes the three.js export and its JSON description beside it (`PATH.json`,
/// [`ThreeSidecar`]), each by temporary file and rename.
///
/// # Errors
/// As [`three_to_bytes`], and I/O errors.
pub fn write_three(path: &Path, vol: &IrradianceVolume) -> Result<(), VolumeError> {
    let (info, file_vol, bytes) = encode(vol)?;
    let frame = info.frame;
    let file = path.file_name().map(|n| n.to_string_lossy().into_owned());
    let mut description =
        Sidecar::describe(&file_vol, Encoding::F16, file, "three-probe-atlas").in_frame(frame);
    description.lookup = info.lookup.clone();
    // The atlas holds the coefficients only: three interpolates plainly.
    description.validity = None;
    description.reach = None;
    let mut json = serde_json::to_string_pretty(&ThreeSidecar { description, three: info })
        .map_err(|e| VolumeError::InvalidData(e.to_string()))?;
    json.push('\n');
    write_atomic(path, &bytes)?;
    write_atomic(&sidecar_path(path), json.as_bytes())
}

/// Whether KTX2 bytes are a three.js export (they carry [`THREE_INFO_KEY`]).
#[must_use]
pub fn is_three(bytes: &[u8]) -> bool {
    // The key/value data alone: the reader that follows parses and checks the rest.
    ktx2::Reader::new(bytes).is_ok_and(|r| r.key_value_data().any(|(k, _)| k == THREE_INFO_KEY))
}

/// Parses a three.js export: its placement and the volume it holds, on the grid of its
/// probes in the file's frame (f16-rounded coefficients, weights 1), turned back into
/// lightvol's internal frame.
///
/// # Errors
/// A damaged or foreign file: header, dimensions against the placement, padding slices
/// that do not copy their data slice, the checksum, non-finite texels.
pub fn three_from_bytes(bytes: &[u8]) -> Result<(ThreeInfo, IrradianceVolume), VolumeError> {
    let f = FileFormat::Ktx2;
    guard(f, || {
        let (dims, kvd, data) = parse_ktx2_rgba16f(bytes, f)?;
        let raw = kvd_value(&kvd, THREE_INFO_KEY, f)?;
        let info: ThreeInfo =
            serde_json::from_slice(raw).map_err(|e| VolumeError::malformed(f, e.to_string()))?;
        let [nx, ny, nz] = info.resolution;
        if nx < 2 || ny < 2 || nz < 2 || dims != [nx, ny, atlas_depth(nz)] {
            return Err(VolumeError::malformed(
                f,
                format!("texture {dims:?} does not fit {:?} probes", info.resolution),
            ));
        }
        if from_hex(&info.texel_checksum) != Some(fnv1a(&data)) {
            return Err(VolumeError::malformed(f, "texel checksum mismatch: the file is damaged"));
        }
        let padded = nz + 2 * THREE_PADDING;
        let (rx, ry) = (nx as usize, ny as usize);
        let texel = |slice: u32, x: u32, y: u32| -> [u8; 8] {
            let at = ((slice as usize * ry + y as usize) * rx + x as usize) * 8;
            data[at..at + 8].try_into().expect("8 bytes")
        };
        // The probes sit half a cell inside the box (to rounding).
        for a in 0..3 {
            let h = info.size[a] / f64::from(info.resolution[a]);
            let slack = 1e-9 * info.size[a].abs().max(1.0);
            if (info.probes[0][a] - (info.bounds[0][a] + h / 2.0)).abs() > slack
                || (info.probes[1][a] - (info.bounds[1][a] - h / 2.0)).abs() > slack
            {
                return Err(VolumeError::malformed(
                    f,
                    format!("axis {a}: the probes do not sit half a cell inside the box"),
                ));
            }
        }
        let spec = GridSpec::new(info.probes[0], info.probes[1], info.resolution)?;
        let mut values = Vec::with_capacity(spec.node_count() * 3 * THREE_COEFFS);
        for z in 0..nz {
            for y in 0..ny {
                for x in 0..nx {
                    let mut floats = [0.0f32; 28];
                    for t in 0..THREE_SUBVOLUMES {
                        let slice = t * padded + z + THREE_PADDING;
                        let tx = texel(slice, x, y);
                        for pad in [t * padded, t * padded + padded - 1] {
                            let copy = if pad == t * padded { 0 } else { nz - 1 };
                            if z == copy && texel(pad, x, y) != tx {
                                return Err(VolumeError::malformed(
                                    f,
                                    "a padding slice differs from its data slice",
                                ));
                            }
                        }
                        for k in 0..4 {
                            floats[4 * t as usize + k] =
                                half::f16::from_le_bytes([tx[2 * k], tx[2 * k + 1]]).to_f32();
                        }
                    }
                    if floats.iter().any(|v| !v.is_finite()) {
                        return Err(VolumeError::NonFinite {
                            what: "three.js texel",
                            index: spec.node_index(x, y, z),
                        });
                    }
                    values.extend_from_slice(&floats[..27]);
                }
            }
        }
        let meta = crate::metadata::BakeMetadata {
            frame: info.frame,
            units: info.units.clone(),
            ..Default::default()
        };
        let vol = IrradianceVolume::new(spec, THREE_COEFFS, values, vec![1.0; (nx * ny * nz) as usize])?
            .with_metadata(meta);
        let vol = crate::frame::to_internal_frame(&vol, info.frame)?;
        Ok((info, vol))
    })
}

/// Reads a three.js export from a file ([`three_from_bytes`]).
///
/// # Errors
/// As [`three_from_bytes`], and I/O errors.
pub fn read_three(path: &Path) -> Result<(ThreeInfo, IrradianceVolume), VolumeError> {
    three_from_bytes(&read_bounded(path)?)
}
