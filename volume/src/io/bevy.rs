//! Export to Bevy's irradiance-volume layout (ambient cubes in an RGBA16F KTX2 3D texture).
//!
//! Bevy's irradiance volumes (`bevy_pbr::light_probe::irradiance_volume`) store Valve's
//! *ambient cube* (Mitchell 2006, "Shading in Valve's Source Engine", slide 28) per voxel:
//! six colours for the cardinal directions, blended by the squared normal,
//! `E(n) ≈ n_x² C[sign n_x, X] + n_y² C[sign n_y, Y] + n_z² C[sign n_z, Z]`.
//! We store `C[±, a] = E(±e_a)/π` of the SH volume (Kontkanen & Laine Eq. 1 at the node,
//! evaluated in f64 and rounded once to f16 or RGB9E5): Bevy's units, in which a white
//! Lambertian surface lit by the volume at `intensity = 1` reflects what lightvol predicts
//! (see [`bevy_to_bytes`]). The axes `e_a` are the scene file's (the export is written in
//! its frame, [`crate::frame`]), because Bevy's shader picks faces by the world normal.
//!
//! ## Texture layout (the authority is Bevy's shader `irradiance_volume.wgsl`)
//! Checked against `crates/bevy_pbr/src/light_probe/irradiance_volume.wgsl` (bevyengine/bevy
//! at commit 00620e1d, the version with `light_from_world` and `(unit_pos + 0.5) *
//! resolution`; older versions mapped world to voxel coordinates directly) and its `.wesl`
//! successor at 190a5aca (same sampling; the test `tests/tests/engine_bevy.rs` re-implements
//! it).
//! For a volume of `(Rx, Ry, Rz)` voxels the texture is `Rx × 2Ry × 3Rz`. The shader computes
//! `uvw` of the voxel inside the first block and samples face `a` at
//! `uvw + (0, neg_a ? 0.5 : 0, a/3)`. Hence the texel of voxel `(x, y, z)` and side `S`:
//!
//! - `s = x`;
//! - `t = y` for `S ∈ {+X, +Y, +Z}`, `t = y + Ry` for `S ∈ {-X, -Y, -Z}` (the shader's
//!   `neg_offset = 0.5` for `N < 0`; the module documentation of `irradiance_volume.rs`
//!   states the opposite, but its own table, "+X +Y +Z" above "-X -Y -Z", and the shader
//!   agree with this);
//! - `p = z + Rz · a`, `a = 0, 1, 2` for X, Y, Z.
//!
//! Bevy places voxel centres at `(i + 0.5)/R` of the light probe's unit cube
//! `[-0.5, 0.5]³` and clamps lookups to the outer voxel centres; our nodes lie on the box
//! corners. [`bevy_world_from_probe`] gives the probe transform that makes the two
//! coincide: the box grown by half a cell on every side (`size · R/(R-1)`), centred on
//! the box, then the volume's placement. Bevy's `Transform` holds translation, rotation
//! and scale only ([`bevy_transform`] decomposes the matrix, glam's `DQuat::from_mat3`); a sheared or mirrored
//! placement cannot be represented there and is refused.
//!
//! A validity mask ([`crate::validity`]) and a node reach ([`crate::reach`]) are not
//! exported: Bevy's shader interpolates its voxels plainly, so the ambient cubes are the
//! nodes' own (dilated) values, read through thin walls.

use std::path::Path;

use serde::{Deserialize, Serialize};

use lightvol_sh::eval::eval_into;
use lightvol_sh::index::sh_lm;
use lightvol_sh::irradiance::cosine_lobe_factor;

use crate::checksum::{fnv1a, from_hex, to_hex};
use crate::error::{FileFormat, VolumeError};
use crate::grid::GridSpec;
use crate::io::ktx2::{KTX2_WRITER, parse_ktx2};
use crate::io::util::{guard, read_bounded, write_atomic};
use crate::slab::f16_bytes;
use crate::volume::IrradianceVolume;

const F: FileFormat = FileFormat::Bevy;

/// Key of the embedded [`BevyInfo`] JSON in the KTX2 key/value data.
pub const BEVY_INFO_KEY: &str = "lightvol.bevy";

/// The six sides of an ambient cube.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Face {
    /// +X.
    PosX,
    /// -X.
    NegX,
    /// +Y.
    PosY,
    /// -Y.
    NegY,
    /// +Z.
    PosZ,
    /// -Z.
    NegZ,
}

impl Face {
    /// All six, in the order `+X, -X, +Y, -Y, +Z, -Z`.
    pub const ALL: [Face; 6] = [Face::PosX, Face::NegX, Face::PosY, Face::NegY, Face::PosZ, Face::NegZ];

    /// Axis index (0, 1, 2 for X, Y, Z).
    #[must_use]
    pub fn axis(self) -> usize {
        match self {
            Face::PosX | Face::NegX => 0,
            Face::PosY | Face::NegY => 1,
            Face::PosZ | Face::NegZ => 2,
        }
    }

    /// Whether the side faces the negative axis.
    #[must_use]
    pub fn negative(self) -> bool {
        matches!(self, Face::NegX | Face::NegY | Face::NegZ)
    }

    /// The unit direction of the side.
    #[must_use]
    pub fn dir(self) -> [f64; 3] {
        let mut d = [0.0; 3];
        d[self.axis()] = if self.negative() { -1.0 } else { 1.0 };
        d
    }

    /// Texel `(s, t, p)` of this side of voxel `(x, y, z)` in a volume of `res` voxels
    /// (module docs, after Bevy's `irradiance_volume.wgsl`).
    #[must_use]
    pub fn texel(self, voxel: [u32; 3], res: [u32; 3]) -> [u32; 3] {
        let t = voxel[1] + if self.negative() { res[1] } else { 0 };
        let p = voxel[2] + res[2] * self.axis() as u32;
        [voxel[0], t, p]
    }
}

/// Texel format of a Bevy export.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum BevyFormat {
    /// `VK_FORMAT_R16G16B16A16_SFLOAT` (vkFormat 97), alpha 1.
    #[default]
    Rgba16f,
    /// `VK_FORMAT_E5B9G9R9_UFLOAT_PACK32` (vkFormat 123), the format of Bevy's own example
    /// volume: half the memory; negative irradiance (SH ringing) is clamped to 0.
    Rgb9e5,
}

/// A Bevy `Transform` (translation, rotation, scale), as the light probe's entity needs it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct BevyTransform {
    /// `Transform::translation`.
    pub translation: [f64; 3],
    /// `Transform::rotation` as a unit quaternion `[x, y, z, w]` (`Quat::from_xyzw`).
    pub rotation: [f64; 4],
    /// `Transform::scale`.
    pub scale: [f64; 3],
}

impl BevyTransform {
    /// The 3×4 matrix `T · R · S` Bevy builds from it (`Transform::compute_affine`).
    #[must_use]
    pub fn matrix(&self) -> [[f64; 4]; 3] {
        let [x, y, z, w] = self.rotation;
        let r = glam::DMat3::from_quat(glam::DQuat::from_xyzw(x, y, z, w));
        std::array::from_fn(|i| {
            let mut row = [0.0; 4];
            for j in 0..3 {
                row[j] = r.col(j)[i] * self.scale[j];
            }
            row[3] = self.translation[i];
            row
        })
    }
}

/// Tolerance of the rotation test in [`bevy_transform`]: the columns of the linear part,
/// each divided by its length, must be orthonormal to this (f64 rounding of a placement
/// built from a rotation is ~1e-16; a shear visible to a user is far larger).
const ORTHONORMAL_TOLERANCE: f64 = 1e-9;

/// Decomposes the probe matrix ([`bevy_world_from_probe`]) into translation, rotation and
/// per-axis scale.
///
/// # Errors
/// [`VolumeError::InvalidGrid`] when the placement shears or mirrors the grid: Bevy's
/// `Transform` cannot hold either.
pub fn bevy_transform(spec: &GridSpec) -> Result<BevyTransform, VolumeError> {
    let m = bevy_world_from_probe(spec);
    let col = |j: usize| [m[0][j], m[1][j], m[2][j]];
    let scale: [f64; 3] = std::array::from_fn(|j| col(j).iter().map(|v| v * v).sum::<f64>().sqrt());
    let r: [[f64; 3]; 3] = std::array::from_fn(|i| std::array::from_fn(|j| m[i][j] / scale[j]));
    for a in 0..3 {
        for b in 0..3 {
            let dot: f64 = (0..3).map(|i| r[i][a] * r[i][b]).sum();
            if (dot - f64::from(u8::from(a == b))).abs() > ORTHONORMAL_TOLERANCE {
                return Err(VolumeError::InvalidGrid(
                    "the volume's placement shears the grid; a Bevy Transform holds translation, rotation and scale only"
                        .into(),
                ));
            }
        }
    }
    let det = r[0][0] * (r[1][1] * r[2][2] - r[1][2] * r[2][1])
        - r[0][1] * (r[1][0] * r[2][2] - r[1][2] * r[2][0])
        + r[0][2] * (r[1][0] * r[2][1] - r[1][1] * r[2][0]);
    if det < 0.0 {
        return Err(VolumeError::InvalidGrid(
            "the volume's placement mirrors the grid; a Bevy Transform cannot hold a reflection".into(),
        ));
    }
    let q = glam::DQuat::from_mat3(&glam::DMat3::from_cols_array_2d(&std::array::from_fn(|c| {
        std::array::from_fn(|row| r[row][c])
    })))
    .to_array();
    // Canonical sign (w ≥ 0) so equal inputs give equal files.
    let q = if q[3] < 0.0 { q.map(|v| -v) } else { q };
    Ok(BevyTransform { translation: [m[0][3], m[1][3], m[2][3]], rotation: q, scale })
}

/// What the embedded JSON (and the `.json` beside the file) says about a Bevy export.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BevyInfo {
    /// Voxels per axis `(Rx, Ry, Rz)`.
    pub res: [u32; 3],
    /// The light probe's `Transform`: with it, every voxel centre lies on its node.
    pub transform: BevyTransform,
    /// `IrradianceVolume::intensity` to use: 1 (the texels are already in Bevy's units;
    /// Bevy's default intensity is 0, which shows nothing).
    pub intensity: f64,
    /// Row-major 3×4 world-from-probe matrix, the transform's matrix (maps the unit cube
    /// `[-0.5, 0.5]³` so that voxel centres land on the volume's nodes).
    pub world_from_probe: [[f64; 4]; 3],
    /// The texel format.
    pub format: BevyFormat,
    /// The frame of positions and face directions: the scene file's (`y-up` or `z-up`).
    pub frame: crate::up_axis::UpAxis,
    /// The stored quantity.
    pub quantity: String,
    /// The unit of the texels.
    pub units: String,
    /// FNV-1a checksum (16 hex digits) of the level data.
    pub texel_checksum: String,
    /// The engine lookup the file is meant for: `bevy` (Bevy's ambient cube).
    #[serde(default = "bevy_lookup")]
    pub lookup: String,
}

/// The lookup a Bevy export is meant for ([`crate::engine_lookup::EngineLookup::Bevy`]).
fn bevy_lookup() -> String {
    "bevy".into()
}

/// What the texels hold (see [`bevy_to_bytes`]).
pub const BEVY_QUANTITY: &str = "E(+-axis)/pi ambient cube: the exitant radiance of a white Lambertian surface facing each axis (Bevy irradiance volume)";

/// The grid-to-world-consistent probe transform of the module docs (row-major 3×4).
#[must_use]
pub fn bevy_world_from_probe(spec: &GridSpec) -> [[f64; 4]; 3] {
    let (min, max) = spec.bounds();
    let res = spec.res();
    // Grid space from probe space: scale by the grown box size, translate to the centre.
    let mut g = [[0.0; 4]; 3];
    for a in 0..3 {
        let size = (max[a] - min[a]) * f64::from(res[a]) / f64::from(res[a] - 1);
        g[a][a] = size;
        g[a][3] = 0.5 * (min[a] + max[a]);
    }
    match spec.placement() {
        None => g,
        Some(p) => {
            let w = p.to_world_matrix();
            let mut out = [[0.0; 4]; 3];
            for r in 0..3 {
                for c in 0..4 {
                    out[r][c] =
                        (0..3).map(|k| w[r][k] * g[k][c]).sum::<f64>() + if c == 3 { w[r][3] } else { 0.0 };
                }
            }
            out
        }
    }
}

/// The six irradiances `E(±e_a)` at every node, `[node][face in Face::ALL order][rgb]`, in
/// f64 (Kontkanen & Laine Eq. 1 with the node's coefficients).
#[must_use]
pub fn ambient_cubes(vol: &IrradianceVolume) -> Vec<[[f64; 3]; 6]> {
    let coeffs = vol.coeffs();
    let factors: Vec<Vec<f64>> = Face::ALL
        .iter()
        .map(|f| {
            let mut y = vec![0.0; coeffs];
            eval_into(vol.bands(), f.dir(), &mut y);
            (0..coeffs).map(|j| cosine_lobe_factor(sh_lm(j).0) * y[j]).collect()
        })
        .collect();
    (0..vol.spec().node_count())
        .map(|node| {
            let c = vol.node(node);
            std::array::from_fn(|face| {
                std::array::from_fn(|ch| {
                    (0..coeffs).map(|j| factors[face][j] * f64::from(c[3 * j + ch])).sum()
                })
            })
        })
        .collect()
}

/// Serialises the Bevy export of `vol` in memory: the volume in its scene file's frame
/// ([`crate::frame::to_file_frame`]; Bevy's shader picks faces by the world normal and
/// never rotates it into probe space, so the faces must be the file's axes), each face
/// holding `E(±e_a)/π`. Bevy adds `volume × diffuse_color × intensity` with no further
/// `1/π` (`pbr_functions.wesl`), while its own lights give a white Lambertian surface the
/// radiance `E/π`; with these texels and `intensity = 1` the volume lights like them.
///
/// # Errors
/// A placement Bevy's `Transform` cannot hold, or (RGBA16F) a value beyond f16.
pub fn bevy_to_bytes(vol: &IrradianceVolume, format: BevyFormat) -> Result<Vec<u8>, VolumeError> {
    let frame = vol.metadata().frame;
    let vol = &crate::frame::to_file_frame(vol, frame)?;
    let spec = vol.spec();
    let res = spec.res();
    let transform = bevy_transform(spec)?;
    let [rx, ry, rz] = res.map(|v| v as usize);
    let dims = [res[0], 2 * res[1], 3 * res[2]];
    let (vk, tb) = match format {
        BevyFormat::Rgba16f => (ktx2::Format::R16G16B16A16_SFLOAT, 8),
        BevyFormat::Rgb9e5 => (ktx2::Format::E5B9G9R9_UFLOAT_PACK32, 4),
    };
    let mut texels = vec![0u8; rx * 2 * ry * 3 * rz * tb];
    let inv_pi = 1.0 / std::f64::consts::PI;
    for (node, cube) in ambient_cubes(vol).iter().enumerate() {
        let voxel = spec.node_coords(node);
        for (fi, face) in Face::ALL.iter().enumerate() {
            let [s, t, p] = face.texel(voxel, res).map(|v| v as usize);
            let at = ((p * 2 * ry + t) * rx + s) * tb;
            let c = cube[fi].map(|v| v * inv_pi);
            match format {
                BevyFormat::Rgba16f => {
                    for (i, v) in [c[0] as f32, c[1] as f32, c[2] as f32, 1.0].into_iter().enumerate() {
                        texels[at + 2 * i..at + 2 * i + 2]
                            .copy_from_slice(&f16_bytes(v, "ambient-cube irradiance")?);
                    }
                }
                BevyFormat::Rgb9e5 => {
                    texels[at..at + 4].copy_from_slice(&crate::rgb9e5::pack(c).to_le_bytes());
                }
            }
        }
    }
    let info = BevyInfo {
        res,
        transform,
        intensity: 1.0,
        world_from_probe: transform.matrix(),
        format,
        frame,
        quantity: BEVY_QUANTITY.into(),
        units: format!("({}) (radiance of a white Lambertian surface)", vol.metadata().units),
        texel_checksum: to_hex(fnv1a(&texels)),
        lookup: bevy_lookup(),
    };
    let json = serde_json::to_string(&info).expect("plain data");
    Ok(crate::io::ktx2::ktx2_bytes(vk, dims, &texels, &[("KTXwriter", KTX2_WRITER), (BEVY_INFO_KEY, &json)]))
}

/// Writes the Bevy export and its JSON description beside it (`PATH.json`: the transform,
/// the intensity, the frame), each by temporary file and rename.
///
/// # Errors
/// As [`bevy_to_bytes`], and I/O errors.
pub fn write_bevy(path: &Path, vol: &IrradianceVolume, format: BevyFormat) -> Result<(), VolumeError> {
    let bytes = bevy_to_bytes(vol, format)?;
    let info = bevy_from_bytes(&bytes)?.info;
    write_atomic(path, &bytes)?;
    let mut json = serde_json::to_string_pretty(&info).expect("plain data");
    json.push('\n');
    write_atomic(&crate::io::sidecar::sidecar_path(path), json.as_bytes())
}

/// A Bevy irradiance volume read back: its info and the six f16-rounded colours per voxel.
#[derive(Debug, Clone, PartialEq)]
pub struct BevyVolume {
    /// The embedded info.
    pub info: BevyInfo,
    /// `[voxel][face in Face::ALL order][rgb]`, voxel index x fastest.
    pub cubes: Vec<[[f32; 3]; 6]>,
}

impl BevyVolume {
    /// Valve's ambient-cube evaluation at a voxel, as Bevy's shader does it:
    /// `Σ_a n_a² C[sign n_a, a]` (the shader selects the negative side for `n_a < 0`).
    #[must_use]
    pub fn shade(&self, voxel: usize, n: [f32; 3]) -> [f32; 3] {
        let cube = &self.cubes[voxel];
        let mut out = [0.0f32; 3];
        for a in 0..3 {
            let face = 2 * a + usize::from(n[a] < 0.0);
            for ch in 0..3 {
                out[ch] += n[a] * n[a] * cube[face][ch];
            }
        }
        out
    }
}

/// Parses a Bevy export (validating the KTX2 header, dimensions against the embedded info,
/// and finiteness).
pub fn bevy_from_bytes(bytes: &[u8]) -> Result<BevyVolume, VolumeError> {
    guard(F, || {
        let (vk, (dims, kvd, data)) =
            parse_ktx2(bytes, F, &[ktx2::Format::R16G16B16A16_SFLOAT, ktx2::Format::E5B9G9R9_UFLOAT_PACK32])?;
        let raw = crate::io::ktx2::kvd_value(&kvd, BEVY_INFO_KEY, F)?;
        let info: BevyInfo =
            serde_json::from_slice(raw).map_err(|e| VolumeError::malformed(F, e.to_string()))?;
        let res = info.res;
        if res.contains(&0)
            || [u64::from(dims[0]), u64::from(dims[1]), u64::from(dims[2])]
                != [u64::from(res[0]), 2 * u64::from(res[1]), 3 * u64::from(res[2])]
        {
            return Err(VolumeError::malformed(F, format!("texture {dims:?} does not fit {res:?} voxels")));
        }
        let want = match info.format {
            BevyFormat::Rgba16f => ktx2::Format::R16G16B16A16_SFLOAT,
            BevyFormat::Rgb9e5 => ktx2::Format::E5B9G9R9_UFLOAT_PACK32,
        };
        if vk != want {
            return Err(VolumeError::malformed(
                F,
                format!("texels are {vk:?} but the info says {:?}", info.format),
            ));
        }
        let tb = crate::io::ktx2::texel_bytes(vk);
        if from_hex(&info.texel_checksum) != Some(fnv1a(&data)) {
            return Err(VolumeError::malformed(F, "texel checksum mismatch: the file is damaged"));
        }
        let [rx, ry, rz] = res.map(|v| v as usize);
        let mut cubes = vec![[[0.0f32; 3]; 6]; rx * ry * rz];
        for (vi, cube) in cubes.iter_mut().enumerate() {
            let voxel = [(vi % rx) as u32, ((vi / rx) % ry) as u32, (vi / (rx * ry)) as u32];
            for (fi, face) in Face::ALL.iter().enumerate() {
                let [s, t, p] = face.texel(voxel, res).map(|v| v as usize);
                let at = ((p * 2 * ry + t) * rx + s) * tb;
                let rgb: [f32; 3] = match info.format {
                    BevyFormat::Rgba16f => std::array::from_fn(|ch| {
                        half::f16::from_le_bytes([data[at + 2 * ch], data[at + 2 * ch + 1]]).to_f32()
                    }),
                    BevyFormat::Rgb9e5 => crate::rgb9e5::unpack(u32::from_le_bytes(
                        data[at..at + 4].try_into().expect("4 bytes"),
                    ))
                    .map(|v| v as f32),
                };
                if rgb.iter().any(|v| !v.is_finite()) {
                    return Err(VolumeError::NonFinite { what: "Bevy texel", index: at / tb });
                }
                cube[fi] = rgb;
            }
        }
        Ok(BevyVolume { info, cubes })
    })
}

/// Reads a Bevy export from a file.
pub fn read_bevy(path: &Path) -> Result<BevyVolume, VolumeError> {
    bevy_from_bytes(&read_bounded(path)?)
}
