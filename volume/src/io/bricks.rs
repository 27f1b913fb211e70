//! The brick export ([`crate::bricks`]): two KTX2 3D textures and their description.
//!
//! - `STEM.ktx2`, the **atlas** (RGBA16F): brick `i` sits in slot
//!   `(i mod ax, ⌊i/ax⌋ mod ay, ⌊i/(ax·ay)⌋)` of an `ax × ay × az` slot grid, each slot
//!   `P = B + 1` texels wide; coefficient `j` is a slab along z, so probe `(x, y, z)` of
//!   slot `(sx, sy, sz)` is texel `(sx·P + x, sy·P + y, j·az·P + sz·P + z)`, its RGB the
//!   coefficient and A 1. Bricks are stored by stream cell (the bricks under one level-0
//!   brick are contiguous), so an engine loads a cell by copying a range of slots.
//! - `STEM.indirection.ktx2` (RGBA8 unsigned): per indirection texel, the slot of its brick
//!   in RGB and the brick's level in A.
//! - The description ([`BrickSidecar`]) is embedded in the atlas under [`BRICKS_KEY`] and
//!   written beside it as `STEM.ktx2.json`: the grid, the brick list and stream cells, the
//!   affine map from the scene file's world positions to base-cell units (`world_to_units`)
//!   and the rotation from the file's directions to the SH frame (`normal_to_sh`), so that
//!   engines pass positions and normals in their own (the file's) frame.
//!
//! The values are the volume's half floats as they are, so a volume written and read back
//! ([`read_bricks`], also through [`crate::open`]) is equal bit for bit; the reader checks the
//! indirection texture, when present beside the atlas, against the brick list.

use std::path::{Path, PathBuf};

use ktx2::Format;
use serde::{Deserialize, Serialize};

use crate::bricks::{Brick, BrickVolume, INDIRECTION_TEXEL_BYTES};
use crate::error::{FileFormat, VolumeError};
use crate::grid::{GridSpec, Placement};
use crate::io::ktx2::{KTX2_WRITER, kvd_value, parse_ktx2};
use crate::io::sidecar::{GridJson, SH_CONVENTION};
use crate::io::util::{guard, read_bounded, write_atomic};
use crate::metadata::BakeMetadata;

/// Key of the brick description in the atlas's key/value data.
pub const BRICKS_KEY: &str = "lightvol.bricks";
/// The description's `format`.
pub const BRICKS_FORMAT: &str = "lightvol-bricks";
/// The description's version.
pub const BRICKS_VERSION: u32 = 1;
/// How a renderer reads the bricks, in words (the description's `lookup`).
pub const BRICKS_LOOKUP: &str = "u = world_to_units * (p, 1), clamped to [0, base_res - 1]; \
     t = min(floor(u * 2^finest_level / brick_cells), indirection_res - 1); \
     (sx, sy, sz, l) = indirection[t]; b = floor(t / 2^(finest_level - l)); \
     s = clamp(u * 2^l - b * brick_cells, 0, brick_cells); \
     coefficient j = trilinear over the brick's probes at s, from atlas texel \
     (sx*P + s.x, sy*P + s.y, j*az*P + sz*P + s.z) with P = brick_cells + 1; \
     irradiance = sum_j A_j c_j Y_j(normal_to_sh * n)";

/// The description of a brick export (module docs).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BrickSidecar {
    /// [`BRICKS_FORMAT`].
    pub format: String,
    /// [`BRICKS_VERSION`].
    pub version: u32,
    /// The base grid (the octree's level 0), in lightvol's internal frame.
    pub grid: GridJson,
    /// SH coefficients per channel.
    pub coeffs: usize,
    /// The SH convention ([`SH_CONVENTION`]).
    pub sh_convention: String,
    /// Cells per brick and axis (`B`); a brick stores `(B + 1)³` probes.
    pub brick_cells: u32,
    /// The finest brick level.
    pub finest_level: u32,
    /// Indirection texels per axis.
    pub indirection_res: [u32; 3],
    /// Atlas slots per axis `(ax, ay, az)`.
    pub atlas_slots: [u32; 3],
    /// The bricks in slot order, flattened as `level, bx, by, bz` per brick.
    pub bricks: Vec<u32>,
    /// The stream cells, flattened as `cx, cy, cz, first, count` per cell.
    pub cells: Vec<u32>,
    /// Row-major 3×4 matrix from the scene file's world positions to base-cell units.
    pub world_to_units: [[f64; 4]; 3],
    /// Row-major 3×3 rotation from the scene file's directions to the SH frame.
    pub normal_to_sh: [[f64; 3]; 3],
    /// How to read it ([`BRICKS_LOOKUP`]).
    pub lookup: String,
    /// The bake's metadata.
    pub metadata: BakeMetadata,
}

/// Atlas slots per axis for `n` bricks: `ax = ay = ⌈∛n⌉`, `az = ⌈n / (ax·ay)⌉` (at least 1).
#[must_use]
pub fn atlas_slots(n: usize) -> [u32; 3] {
    let n = n.max(1);
    let mut a = (n as f64).cbrt().ceil() as usize;
    while a > 1 && (a - 1).pow(3) >= n {
        a -= 1;
    }
    while a.pow(3) < n {
        a += 1;
    }
    let az = n.div_ceil(a * a);
    [a as u32, a as u32, az as u32]
}

/// The indirection texture beside an atlas `out`: `STEM.indirection.ktx2`.
#[must_use]
pub fn indirection_path(out: &Path) -> PathBuf {
    let stem = out.file_stem().map_or_else(|| "volume".into(), |s| s.to_string_lossy().into_owned());
    out.with_file_name(format!("{stem}.indirection.ktx2"))
}

/// The affine map from file-frame world positions to base-cell units, and the rotation from
/// file-frame directions to the SH (internal) frame.
fn frame_maps(spec: &GridSpec, meta: &BakeMetadata) -> ([[f64; 4]; 3], [[f64; 3]; 3]) {
    let up = meta.frame;
    let (min, max) = spec.bounds();
    let res = spec.res();
    let units = |pf: [f64; 3]| -> [f64; 3] {
        let g = spec.to_grid(up.to_world(pf));
        std::array::from_fn(|a| (g[a] - min[a]) / (max[a] - min[a]) * f64::from(res[a] - 1))
    };
    let o = units([0.0; 3]);
    let cols: [[f64; 3]; 3] = std::array::from_fn(|c| {
        let e: [f64; 3] = std::array::from_fn(|i| f64::from(u8::from(i == c)));
        let u = units(e);
        std::array::from_fn(|a| u[a] - o[a])
    });
    let m = std::array::from_fn(|r| [cols[0][r], cols[1][r], cols[2][r], o[r]]);
    let rot_cols: [[f64; 3]; 3] = std::array::from_fn(|c| {
        let e: [f64; 3] = std::array::from_fn(|i| f64::from(u8::from(i == c)));
        up.to_world(e)
    });
    let rot = std::array::from_fn(|r| [rot_cols[0][r], rot_cols[1][r], rot_cols[2][r]]);
    (m, rot)
}

/// The description of `vol`.
#[must_use]
pub fn describe(vol: &BrickVolume) -> BrickSidecar {
    let spec = vol.spec();
    let (min, max) = spec.bounds();
    let (world_to_units, normal_to_sh) = frame_maps(spec, vol.metadata());
    BrickSidecar {
        format: BRICKS_FORMAT.into(),
        version: BRICKS_VERSION,
        grid: GridJson {
            min,
            max,
            res: spec.res(),
            to_world: spec.placement().map(Placement::to_world_matrix),
        },
        coeffs: vol.coeffs(),
        sh_convention: SH_CONVENTION.into(),
        brick_cells: vol.brick_cells(),
        finest_level: vol.finest_level(),
        indirection_res: vol.indirection_res(),
        atlas_slots: atlas_slots(vol.bricks().len()),
        bricks: vol.bricks().iter().flat_map(|b| [b.level, b.coords[0], b.coords[1], b.coords[2]]).collect(),
        cells: vol
            .stream_cells()
            .iter()
            .flat_map(|c| [c.coords[0], c.coords[1], c.coords[2], c.first, c.count])
            .collect(),
        world_to_units,
        normal_to_sh,
        lookup: BRICKS_LOOKUP.into(),
        metadata: vol.metadata().clone(),
    }
}

/// Where brick `i`'s values go in an atlas of `slots` slots of `p` probes per axis and
/// `coeffs` coefficient slabs (module docs): for every probe (x fastest) and coefficient
/// `j`, the index of the coefficient's RGB in the brick's values (`[probe][coeff][rgb]`)
/// and the byte offset of its RGBA16F texel.
fn atlas_offsets(slots: [u32; 3], p: u32, coeffs: u32, i: usize) -> impl Iterator<Item = (usize, usize)> {
    let slot = slot_of(slots, i);
    let dims = [slots[0] * p, slots[1] * p];
    (0..p * p * p).flat_map(move |q| {
        let (x, y, z) = (q % p, (q / p) % p, q / (p * p));
        (0..coeffs).map(move |j| {
            let t = [slot[0] * p + x, slot[1] * p + y, j * slots[2] * p + slot[2] * p + z];
            let texel = t[0] as usize + dims[0] as usize * (t[1] as usize + dims[1] as usize * t[2] as usize);
            ((q * coeffs + j) as usize * 3, texel * 8)
        })
    })
}

/// The slot of brick `i`.
fn slot_of(slots: [u32; 3], i: usize) -> [u32; 3] {
    let i = i as u32;
    [i % slots[0], (i / slots[0]) % slots[1], i / (slots[0] * slots[1])]
}

/// `(atlas dimensions, atlas texels, indirection texels)` ([`brick_texels`]).
pub type BrickTexels = ([u32; 3], Vec<u8>, Vec<u8>);

/// The atlas's texels as the KTX2 level stores them (RGBA16F, little-endian; module docs),
/// its dimensions, and the indirection's texels (RGBA8 unsigned): what an engine uploads.
///
/// # Errors
/// An atlas with more than 256 slots along an axis (the indirection's 8-bit slot
/// coordinates).
pub fn brick_texels(vol: &BrickVolume) -> Result<BrickTexels, VolumeError> {
    let slots = atlas_slots(vol.bricks().len());
    if slots.iter().any(|&s| s > 256) {
        return Err(VolumeError::InvalidData(format!(
            "{} bricks need {slots:?} atlas slots, more than the 256 per axis the indirection texture addresses; raise the brick size or lower the finest level",
            vol.bricks().len()
        )));
    }
    let p = vol.brick_probes();
    let coeffs = vol.coeffs() as u32;
    let dims = [slots[0] * p, slots[1] * p, coeffs * slots[2] * p];
    let texels = dims.iter().map(|&d| d as usize).product::<usize>();
    let mut atlas = vec![0u8; texels * 8];
    let one = half::f16::ONE.to_le_bytes();
    for i in 0..vol.bricks().len() {
        let d = vol.brick_data(i);
        for (v, o) in atlas_offsets(slots, p, coeffs, i) {
            for ch in 0..3 {
                atlas[o + 2 * ch..o + 2 * ch + 2]
                    .copy_from_slice(&half::f16::from_f32(d[v + ch]).to_le_bytes());
            }
            atlas[o + 6..o + 8].copy_from_slice(&one);
        }
    }
    Ok((dims, atlas, indirection_texels(vol, slots)))
}

/// The indirection texture's texels (RGBA8 unsigned: the brick's slot in an atlas of
/// `slots` slots, and its level).
fn indirection_texels(vol: &BrickVolume, slots: [u32; 3]) -> Vec<u8> {
    let mut ind = Vec::with_capacity(vol.indirection().len() * INDIRECTION_TEXEL_BYTES);
    for &b in vol.indirection() {
        let s = slot_of(slots, b as usize);
        ind.extend([s[0] as u8, s[1] as u8, s[2] as u8, vol.bricks()[b as usize].level as u8]);
    }
    ind
}

/// The atlas and indirection textures of `vol`, as KTX2 files in memory.
///
/// # Errors
/// As [`brick_texels`].
pub fn bricks_to_bytes(vol: &BrickVolume) -> Result<(Vec<u8>, Vec<u8>), VolumeError> {
    let (dims, atlas, ind) = brick_texels(vol)?;
    let json = serde_json::to_string(&describe(vol)).map_err(|e| VolumeError::InvalidData(e.to_string()))?;
    let atlas = lightvol_core::ktx2::container_bytes(
        Format::R16G16B16A16_SFLOAT,
        dims,
        &atlas,
        &[("KTXwriter", KTX2_WRITER), (BRICKS_KEY, &json)],
        8,
    );
    let indirection = lightvol_core::ktx2::container_bytes(
        Format::R8G8B8A8_UINT,
        vol.indirection_res(),
        &ind,
        &[("KTXwriter", KTX2_WRITER)],
        4,
    );
    Ok((atlas, indirection))
}

/// Writes the atlas to `path`, the indirection texture to [`indirection_path`] and the
/// description to `PATH.json`, each whole or not at all.
///
/// # Errors
/// As [`bricks_to_bytes`], and I/O errors.
pub fn write_bricks(path: &Path, vol: &BrickVolume) -> Result<Vec<PathBuf>, VolumeError> {
    let (atlas, indirection) = bricks_to_bytes(vol)?;
    let json =
        serde_json::to_string_pretty(&describe(vol)).map_err(|e| VolumeError::InvalidData(e.to_string()))?;
    let ind = indirection_path(path);
    let side = crate::io::sidecar::sidecar_path(path);
    write_atomic(&ind, &indirection)?;
    write_atomic(&side, json.as_bytes())?;
    write_atomic(path, &atlas)?;
    Ok(vec![path.to_path_buf(), ind, side])
}

/// Whether KTX2 bytes are a brick atlas (they carry [`BRICKS_KEY`]).
#[must_use]
pub fn is_bricks(bytes: &[u8]) -> bool {
    ktx2::Reader::new(bytes).is_ok_and(|r| r.key_value_data().any(|(k, _)| k == BRICKS_KEY))
}

/// Reads a brick export from its atlas `path` (and checks the indirection texture beside
/// it, when there is one).
///
/// # Errors
/// Unreadable or inconsistent files, naming the problem.
pub fn read_bricks(path: &Path) -> Result<BrickVolume, VolumeError> {
    let vol = bricks_from_bytes(&read_bounded(path)?)?;
    let ind = indirection_path(path);
    if ind.is_file() {
        let f = FileFormat::Ktx2;
        let bytes = read_bounded(&ind)?;
        let (_, (dims, _, data)) = guard(f, || parse_ktx2(&bytes, f, &[Format::R8G8B8A8_UINT]))?;
        let want = indirection_texels(&vol, atlas_slots(vol.bricks().len()));
        if dims != vol.indirection_res() || data != want {
            return Err(VolumeError::malformed(
                f,
                format!("{} does not match the atlas's brick list", ind.display()),
            ));
        }
    }
    Ok(vol)
}

/// Parses a brick atlas from memory.
///
/// # Errors
/// A texture or description that is malformed or inconsistent.
pub fn bricks_from_bytes(bytes: &[u8]) -> Result<BrickVolume, VolumeError> {
    let f = FileFormat::Ktx2;
    guard(f, || {
        let (_, (dims, kvd, data)) = parse_ktx2(bytes, f, &[Format::R16G16B16A16_SFLOAT])?;
        let raw = kvd_value(&kvd, BRICKS_KEY, f)?;
        let s: BrickSidecar =
            serde_json::from_slice(raw).map_err(|e| VolumeError::malformed(f, e.to_string()))?;
        if s.format != BRICKS_FORMAT || s.version != BRICKS_VERSION || s.sh_convention != SH_CONVENTION {
            return Err(VolumeError::unsupported(
                f,
                format!("brick description {} version {} ({})", s.format, s.version, s.sh_convention),
            ));
        }
        let g = GridSpec::new(s.grid.min, s.grid.max, s.grid.res)?;
        let spec = match s.grid.to_world {
            Some(m) => g.with_placement(Placement::new(m)?),
            None => g,
        };
        if !s.bricks.len().is_multiple_of(4)
            || s.coeffs > 16
            || !crate::bricks::BRICK_CELLS.contains(&s.brick_cells)
        {
            return Err(VolumeError::malformed(f, "brick list, coefficient count or brick size"));
        }
        let bricks: Vec<Brick> =
            s.bricks.chunks_exact(4).map(|c| Brick { level: c[0], coords: [c[1], c[2], c[3]] }).collect();
        let slots = s.atlas_slots;
        let p = s.brick_cells + 1;
        let coeffs = s.coeffs as u32;
        let want = [
            slots[0].checked_mul(p),
            slots[1].checked_mul(p),
            slots[2].checked_mul(p).and_then(|d| d.checked_mul(coeffs)),
        ];
        if want != dims.map(Some) || slots != atlas_slots(bricks.len()) {
            return Err(VolumeError::malformed(f, format!("atlas of {dims:?} texels for slots {slots:?}")));
        }
        let k = s.coeffs * 3;
        let per = (p as usize).pow(3) * k;
        let mut values = vec![0.0f32; bricks.len() * per];
        for (i, d) in values.chunks_exact_mut(per).enumerate() {
            for (v, o) in atlas_offsets(slots, p, coeffs, i) {
                for ch in 0..3 {
                    d[v + ch] = half::f16::from_le_bytes([data[o + 2 * ch], data[o + 2 * ch + 1]]).to_f32();
                }
            }
        }
        let vol = BrickVolume::from_parts(
            spec,
            s.coeffs,
            s.brick_cells,
            s.finest_level,
            bricks,
            values,
            s.metadata.clone(),
        )?;
        if describe(&vol) != s {
            return Err(VolumeError::malformed(f, "the brick description does not match its bricks"));
        }
        Ok(vol)
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::adaptive::tests::step_volume;
    use crate::bricks::{BrickParams, bricks_from_octree};
    use crate::up_axis::UpAxis;

    fn bricks(frame: UpAxis) -> BrickVolume {
        let mut oct = step_volume();
        let meta = BakeMetadata { frame, ..oct.metadata().clone() };
        oct.set_metadata(meta);
        bricks_from_octree(&oct, &BrickParams { cells: 2, max_probe_bytes: None, merge_tolerance: 0.0 })
            .unwrap()
            .0
    }

    #[test]
    fn round_trips_bit_for_bit_through_open() {
        let dir = tempfile::tempdir().unwrap();
        for frame in [UpAxis::Y, UpAxis::Z] {
            let b = bricks(frame);
            let path = dir.path().join(format!("v{}.ktx2", frame.name()));
            let files = write_bricks(&path, &b).unwrap();
            assert_eq!(files.len(), 3);
            let crate::AnyVolume::Bricks(r) = crate::open(&path).unwrap() else { panic!("not bricks") };
            assert_eq!(r, b);
            assert!(r.data.iter().zip(&b.data).all(|(x, y)| x.to_bits() == y.to_bits()));
            // The description beside the atlas is the embedded one.
            let side: BrickSidecar =
                serde_json::from_slice(&std::fs::read(crate::io::sidecar::sidecar_path(&path)).unwrap())
                    .unwrap();
            assert_eq!(side, describe(&b));
        }
    }

    #[test]
    fn the_file_frame_maps_give_the_internal_lookup() {
        let b = bricks(UpAxis::Y);
        let s = describe(&b);
        let m = s.world_to_units;
        let (lo, hi) = b.spec().bounds();
        for i in 0..50 {
            let t = f64::from(i) / 49.0;
            let p_int: [f64; 3] = std::array::from_fn(|a| {
                lo[a] + (hi[a] - lo[a]) * (0.1 + 0.8 * (t * (a as f64 + 1.0)).fract())
            });
            let p_file = UpAxis::Y.to_file(p_int);
            let u: [f64; 3] = std::array::from_fn(|r| {
                m[r][0] * p_file[0] + m[r][1] * p_file[1] + m[r][2] * p_file[2] + m[r][3]
            });
            let want = b.units_f64(p_int);
            for a in 0..3 {
                assert!((u[a] - want[a]).abs() < 1e-12, "{u:?} vs {want:?}");
            }
            // Directions: the file's +y (up) is the internal +z.
            let n = s.normal_to_sh;
            assert_eq!([n[0][1], n[1][1], n[2][1]], [0.0, 0.0, 1.0]);
        }
    }

    #[test]
    fn damaged_files_are_refused_with_a_reason() {
        let dir = tempfile::tempdir().unwrap();
        let b = bricks(UpAxis::Z);
        let path = dir.path().join("v.ktx2");
        write_bricks(&path, &b).unwrap();
        // An indirection texture that names another brick.
        let ind = indirection_path(&path);
        let mut bytes = std::fs::read(&ind).unwrap();
        let n = bytes.len();
        bytes[n - 4] ^= 1;
        std::fs::write(&ind, &bytes).unwrap();
        let e = crate::open(&path).unwrap_err().to_string();
        assert!(e.contains("does not match"), "{e}");
        std::fs::remove_file(&ind).unwrap();
        assert!(crate::open(&path).is_ok());
        // A truncated atlas.
        let atlas = std::fs::read(&path).unwrap();
        for cut in [atlas.len() / 2, atlas.len() - 8, 200] {
            std::fs::write(&path, &atlas[..cut]).unwrap();
            assert!(crate::open(&path).is_err());
        }
    }

    #[test]
    fn atlas_slots_hold_every_brick_nearly_tightly() {
        for n in [1usize, 2, 7, 8, 9, 26, 27, 28, 1000, 1001, 54321] {
            let s = atlas_slots(n);
            let cap = s.iter().map(|&v| v as usize).product::<usize>();
            assert!(cap >= n && cap < n + (s[0] * s[1]) as usize, "{n}: {s:?}");
        }
    }
}
