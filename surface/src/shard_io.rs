//! Surface-bake shard files (`.lvtex`): the [`TexelRecord`]s one shard integrated, so that
//! shards baked on other machines are assembled into the whole bake's maps.
//!
//! ## Format (little-endian)
//! | bytes | content |
//! | --- | --- |
//! | 8 | magic `LVTEX\0`, then the version as u16 (1) |
//! | 4 | length `h` of the JSON header |
//! | h | JSON header ([`TexelShardHeader`]) |
//! | … | records: index u64, flags u8 (bit 0: coefficients present, bit 1: invalid), rays 4 × u64 (sampling, query, bounce, shadow), then `coeffs × 3` f32 if present |
//! | 8 | FNV-1a 64 of every preceding byte |
//!
//! The reader checks the checksum first, then every length against the header before it
//! allocates; equal shards give equal files (no time or host in them).

use std::path::Path;

use lightvol_volume::io::util::{read_bounded, write_atomic};
use serde::{Deserialize, Serialize};

use super::SurfaceError;
use super::bake::{SurfaceSettings, SurfaceTexels, TexelRecord};
use super::key::surface_key;
use lightvol_scene::fingerprint::scene_hash;
use lightvol_scene::stats::RayCounts;
use lightvol_scene::{Scene, TransportSettings};

const MAGIC: &[u8; 6] = b"LVTEX\0";
const VERSION: u16 = 1;

/// What a shard file says about its bake.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct TexelShardHeader {
    /// This shard's index.
    pub shard_index: u32,
    /// Shards of the bake.
    pub shard_count: u32,
    /// Footprints of the whole bake.
    pub total: u64,
    /// Basis coefficients per texel.
    pub coeffs: usize,
    /// The basis tag (e.g. `hbasis_mod6`).
    pub basis: String,
    /// Identifies the scene, lighting and settings (shards of one bake share it).
    pub fingerprint: String,
    /// Records in the file.
    pub records: u64,
}

impl TexelShardHeader {
    /// The header of shard `shard` (`(k, n)`) of a surface bake with `settings`, whose
    /// texels are `part` and whose scene, lighting and settings have the fingerprint
    /// `fingerprint` ([`shard_fingerprint`]).
    #[must_use]
    pub fn new(
        settings: &SurfaceSettings,
        fingerprint: String,
        part: &SurfaceTexels,
        shard: (u32, u32),
    ) -> Self {
        Self {
            shard_index: shard.0,
            shard_count: shard.1,
            total: part.total,
            coeffs: settings.basis.coeffs(),
            basis: settings.basis.tag(),
            fingerprint,
            records: part.records.len() as u64,
        }
    }

    /// The shard's file name, `texels-BASIS-K-of-N.lvtex` ([`TEXEL_SHARD_EXTENSION`]): the
    /// shards of every basis of a bake can share one folder.
    #[must_use]
    pub fn file_name(&self) -> String {
        format!("texels-{}-{}-of-{}.{TEXEL_SHARD_EXTENSION}", self.basis, self.shard_index, self.shard_count)
    }
}

/// The extension of a texel shard file (`.lvtex`).
pub const TEXEL_SHARD_EXTENSION: &str = "lvtex";

/// What the shards of one surface bake share, and the shards of another bake do not: the
/// scene's geometry ([`scene_hash`]) with its lighting, every setting and the lightvol
/// version ([`surface_key`]).
#[must_use]
pub fn shard_fingerprint(scene: &Scene, settings: &SurfaceSettings, transport: &TransportSettings) -> String {
    scene_hash(scene, &surface_key(scene, settings, transport))
}

fn err(m: String) -> SurfaceError {
    SurfaceError::Settings(m)
}

/// Serialises a shard.
#[must_use]
pub fn texels_to_bytes(t: &SurfaceTexels, header: &TexelShardHeader) -> Vec<u8> {
    let mut out = Vec::new();
    for r in &t.records {
        out.extend_from_slice(&r.index.to_le_bytes());
        out.push(u8::from(r.coeffs.is_some()) | (u8::from(r.invalid) << 1));
        for v in [r.rays.sampling, r.rays.query, r.rays.bounce, r.rays.shadow] {
            out.extend_from_slice(&v.to_le_bytes());
        }
        for c in r.coeffs.iter().flatten() {
            for x in c {
                out.extend_from_slice(&x.to_le_bytes());
            }
        }
    }
    lightvol_core::shard::frame_shard_file(MAGIC, VERSION, header, &out)
}

/// Parses a shard.
///
/// # Errors
/// [`SurfaceError::Settings`] naming what is damaged.
pub fn texels_from_bytes(bytes: &[u8]) -> Result<(SurfaceTexels, TexelShardHeader), SurfaceError> {
    let (header, data): (TexelShardHeader, &[u8]) =
        lightvol_core::shard::unframe_shard_file(bytes, MAGIC, VERSION, "texel shard").map_err(err)?;
    if header.shard_count == 0
        || header.shard_index >= header.shard_count
        || header.coeffs == 0
        || header.coeffs > 64
    {
        return Err(err(format!(
            "texel shard {} of {} with {} coefficients",
            header.shard_index, header.shard_count, header.coeffs
        )));
    }
    let mut at = 0;
    let take = |at: &mut usize, n: usize| -> Result<&[u8], SurfaceError> {
        let s = data.get(*at..*at + n).ok_or_else(|| err("texel shard records run past the file".into()))?;
        *at += n;
        Ok(s)
    };
    let u64_at = |b: &[u8]| u64::from_le_bytes(b.try_into().expect("8 bytes"));
    // Each record has at least 41 bytes: the count cannot ask for more than the file holds.
    if header.records > (data.len() - at) as u64 / 41 {
        return Err(err(format!("texel shard claims {} records", header.records)));
    }
    let mut records = Vec::with_capacity(header.records as usize);
    for _ in 0..header.records {
        let index = u64_at(take(&mut at, 8)?);
        let flags = take(&mut at, 1)?[0];
        let r: Vec<u64> = (0..4).map(|_| take(&mut at, 8).map(u64_at)).collect::<Result<_, _>>()?;
        let coeffs = if flags & 1 == 1 {
            let b = take(&mut at, header.coeffs * 12)?;
            Some(
                b.chunks_exact(12)
                    .map(|c| {
                        std::array::from_fn(|i| {
                            f32::from_le_bytes(c[4 * i..4 * i + 4].try_into().expect("4 bytes"))
                        })
                    })
                    .collect(),
            )
        } else {
            None
        };
        records.push(TexelRecord {
            index,
            coeffs,
            invalid: flags & 2 == 2,
            rays: RayCounts { sampling: r[0], query: r[1], bounce: r[2], shadow: r[3] },
        });
    }
    if at != data.len() {
        return Err(err(format!("{} trailing bytes after the texel records", data.len() - at)));
    }
    Ok((SurfaceTexels { total: header.total, records }, header))
}

/// Writes a shard atomically.
///
/// # Errors
/// The I/O error, as [`SurfaceError::Settings`] naming the file.
pub fn write_texels(path: &Path, t: &SurfaceTexels, header: &TexelShardHeader) -> Result<(), SurfaceError> {
    write_atomic(path, &texels_to_bytes(t, header)).map_err(|e| err(e.to_string()))
}

/// Reads a shard.
///
/// # Errors
/// As [`texels_from_bytes`], or the I/O error.
pub fn read_texels(path: &Path) -> Result<(SurfaceTexels, TexelShardHeader), SurfaceError> {
    let bytes = read_bounded(path).map_err(|e| err(e.to_string()))?;
    texels_from_bytes(&bytes).map_err(|e| err(format!("{}: {e}", path.display())))
}

/// Why the texel shards of one basis do not make one surface bake.
#[derive(Debug, thiserror::Error)]
pub enum TexelSetError {
    /// A shard file could not be read.
    #[error("reading {}", path.display())]
    Read {
        /// The file.
        path: std::path::PathBuf,
        /// Why.
        #[source]
        source: SurfaceError,
    },
    /// A shard of another scene or other settings.
    #[error("{} was baked from another scene or other options (fingerprint {got} vs {want})", path.display())]
    OtherBake {
        /// The file.
        path: std::path::PathBuf,
        /// Its fingerprint.
        got: String,
        /// This bake's.
        want: String,
    },
    /// Shards of different counts.
    #[error("{} is shard {index} of {count}, the others are of {others}", path.display())]
    MixedCount {
        /// The file.
        path: std::path::PathBuf,
        /// Its index.
        index: u32,
        /// Its count.
        count: u32,
        /// The others' count.
        others: u32,
    },
    /// A shard index given twice.
    #[error("shard {index} of {tag} given twice ({})", path.display())]
    Twice {
        /// The index.
        index: u32,
        /// The basis tag.
        tag: String,
        /// The second file.
        path: std::path::PathBuf,
    },
    /// No shard of the basis among the files.
    #[error("no texel shard of basis {0} among the shard files")]
    NoShards(String),
    /// Shards are missing.
    #[error("incomplete set: shards {missing} of {count} of {tag} are missing; nothing written")]
    Incomplete {
        /// The missing indices, `0, 3`.
        missing: String,
        /// The count.
        count: u32,
        /// The basis tag.
        tag: String,
    },
}

/// The texel records of basis `tag` from the shard `files` (files of other bases are
/// skipped): every shard of one bake exactly once, each with the fingerprint `fingerprint`
/// of the current scene and settings
/// ([`shard_fingerprint`]).
///
/// # Errors
/// [`TexelSetError`] for the first problem found.
pub fn texel_set_records(
    files: &[std::path::PathBuf],
    tag: &str,
    fingerprint: &str,
) -> Result<Vec<TexelRecord>, TexelSetError> {
    let mut records = Vec::new();
    let mut have: Vec<u32> = Vec::new();
    let mut count: Option<u32> = None;
    for f in files {
        let (t, h) = read_texels(f).map_err(|source| TexelSetError::Read { path: f.clone(), source })?;
        if h.basis != tag {
            continue;
        }
        if h.fingerprint != fingerprint {
            return Err(TexelSetError::OtherBake {
                path: f.clone(),
                got: h.fingerprint,
                want: fingerprint.to_owned(),
            });
        }
        if let Some(c) = count.filter(|&c| c != h.shard_count) {
            return Err(TexelSetError::MixedCount {
                path: f.clone(),
                index: h.shard_index,
                count: h.shard_count,
                others: c,
            });
        }
        count = Some(h.shard_count);
        if have.contains(&h.shard_index) {
            return Err(TexelSetError::Twice { index: h.shard_index, tag: tag.to_owned(), path: f.clone() });
        }
        have.push(h.shard_index);
        records.extend(t.records);
    }
    let Some(n) = count else { return Err(TexelSetError::NoShards(tag.to_owned())) };
    let missing: Vec<String> = (0..n).filter(|k| !have.contains(k)).map(|k| k.to_string()).collect();
    if !missing.is_empty() {
        return Err(TexelSetError::Incomplete { missing: missing.join(", "), count: n, tag: tag.to_owned() });
    }
    Ok(records)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::BasisChoice;

    fn settings(basis: &str, seed: u64) -> SurfaceSettings {
        SurfaceSettings { basis: BasisChoice::parse(basis).unwrap(), seed, ..SurfaceSettings::default() }
    }

    #[test]
    fn a_shard_header_names_its_bake_and_file() {
        let record = |index| TexelRecord { index, coeffs: None, invalid: false, rays: RayCounts::default() };
        let part = SurfaceTexels { total: 40, records: vec![record(3), record(4), record(5)] };
        let h = TexelShardHeader::new(&settings("sh9", 1), "00ff".into(), &part, (1, 3));
        let want = TexelShardHeader {
            shard_index: 1,
            shard_count: 3,
            total: 40,
            coeffs: 9,
            basis: "sh9".into(),
            fingerprint: "00ff".into(),
            records: 3,
        };
        assert_eq!(h, want);
        assert_eq!(h.file_name(), "texels-sh9-1-of-3.lvtex");
        let (back, header) = texels_from_bytes(&texels_to_bytes(&part, &h)).unwrap();
        assert_eq!((back.records.len(), header), (3, want));
    }

    #[test]
    fn shards_of_one_bake_share_the_fingerprint() {
        let maze = lightvol_scene::builtin("maze").unwrap().scene;
        let t = TransportSettings::default();
        let f = shard_fingerprint(&maze, &settings("sh9", 1), &t);
        assert_eq!(f, scene_hash(&maze, &surface_key(&maze, &settings("sh9", 1), &t)));
        assert_eq!(f.len(), 16, "{f}");
        assert!(f.chars().all(|c| c.is_ascii_hexdigit()), "{f}");
        assert_eq!(shard_fingerprint(&maze, &settings("sh9", 1), &t), f);
        assert_ne!(shard_fingerprint(&maze, &settings("sh9", 2), &t), f);
        assert_ne!(shard_fingerprint(&maze, &settings("sh4", 1), &t), f);
        let two_bounces = TransportSettings { bounces: 2, russian_roulette: false, ..t };
        assert_ne!(shard_fingerprint(&maze, &settings("sh9", 1), &two_bounces), f);
    }
}
