//! # A folder of surface bakes, checked before a view is shaded with it
//!
//! `bake-surface` writes one multi-part EXR per basis into a folder ([`super::exr`]). To
//! shade a view ([`super::shaded_view`]) every map set there must come from one bake of the
//! scene at hand: [`read_map_dir`] reads the sets (sorted by file name, skipping EXRs that
//! are not coefficient maps), [`check_lighting`] checks that they share one lighting record
//! and that it is the scene's own under the maps' bounce count (returning those path
//! settings, which the reference must use), and [`check_objects`] that they map the scene's
//! lightmap objects.

use std::path::{Path, PathBuf};

use super::shaded_view::MapSet;
use lightvol_scene::fingerprint::{LightingRecord, lighting_fingerprint};

use super::{SurfaceError, SurfaceGeometry, read_surface_exr};
use lightvol_scene::{Scene, TransportSettings};

/// The maps of one basis found in a folder.
pub struct BasisMaps {
    /// The EXR file they came from.
    pub path: PathBuf,
    /// The maps.
    pub set: MapSet,
}

/// The map sets of a folder.
pub struct MapDir {
    /// One set per basis, sorted by file name.
    pub sets: Vec<BasisMaps>,
    /// Invalid texels of the bakes, from the EXR files: the sum over objects, the largest
    /// over the bases (which share the geometry and sample points).
    pub invalid_texels: u64,
    /// EXR files that are not lightvol surface maps, left out.
    pub skipped: Vec<PathBuf>,
}

/// A folder of maps that cannot shade the view.
#[derive(Debug, thiserror::Error)]
pub enum MapDirError {
    /// The folder cannot be listed.
    #[error("reading {}", dir.display())]
    ReadDir {
        /// The folder.
        dir: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// A map file cannot be read.
    #[error("reading {}", path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: SurfaceError,
    },
    /// A map file names a basis this build does not know.
    #[error("{}", path.display())]
    Basis {
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: SurfaceError,
    },
    /// The objects of one file use different bases.
    #[error("{}: objects use different bases", .0.display())]
    MixedBases(PathBuf),
    /// Two files hold maps of the same basis.
    #[error("{}: a second set of {tag} maps in {}", path.display(), dir.display())]
    Duplicate {
        /// The second file.
        path: PathBuf,
        /// The basis.
        tag: String,
        /// The folder.
        dir: PathBuf,
    },
    /// No coefficient maps at all.
    #[error("no coefficient maps in {} (run lightvol bake-surface -o {} first)", .0.display(), .0.display())]
    Empty(PathBuf),
    /// Two map files were baked under different lighting.
    #[error(
        "the maps in {} were baked under different lighting ({} vs {}: {difference}); re-bake or remove the stale file",
        dir.display(),
        first.display(),
        other.display()
    )]
    MixedLighting {
        /// The folder.
        dir: PathBuf,
        /// The first file.
        first: PathBuf,
        /// A file that differs from it.
        other: PathBuf,
        /// How ([`lighting_difference`]).
        difference: String,
    },
    /// The lighting record has no bounce count.
    #[error("{}: the maps' lighting record has no bounce count ('{lighting}')", path.display())]
    NoBounces {
        /// The file.
        path: PathBuf,
        /// The record.
        lighting: String,
    },
    /// The maps were baked under other lighting than the scene's.
    #[error(
        "the maps in {} were baked under other lighting than this render's scene and lights ({difference}); pass the bake's --sky/--sun/--ground or re-bake",
        dir.display()
    )]
    OtherLighting {
        /// The folder.
        dir: PathBuf,
        /// How ([`lighting_difference`]).
        difference: String,
    },
    /// A set's objects, UV set or quantity are not the scene's.
    #[error("the {0} maps do not match the scene's lightmap objects (baked from another scene or UV set?)")]
    Objects(String),
}

impl MapDirError {
    /// Whether the error is about the folder as a whole (its listing, or no maps in it),
    /// rather than one file or the scene.
    #[must_use]
    pub fn is_folder_error(&self) -> bool {
        matches!(
            self,
            Self::ReadDir { .. } | Self::Empty(_) | Self::MixedLighting { .. } | Self::OtherLighting { .. }
        )
    }
}

/// Reads every lightvol surface EXR in `dir`, sorted by file name.
///
/// # Errors
/// [`MapDirError::ReadDir`], [`MapDirError::Read`] (other than a file that is not a surface
/// EXR, which is skipped), [`MapDirError::Basis`], [`MapDirError::MixedBases`],
/// [`MapDirError::Duplicate`], [`MapDirError::Empty`].
pub fn read_map_dir(dir: &Path) -> Result<MapDir, MapDirError> {
    let mut paths: Vec<PathBuf> = std::fs::read_dir(dir)
        .map_err(|source| MapDirError::ReadDir { dir: dir.to_owned(), source })?
        .filter_map(Result::ok)
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|e| e.eq_ignore_ascii_case("exr")))
        .collect();
    paths.sort();
    let mut sets: Vec<BasisMaps> = Vec::new();
    let mut skipped = Vec::new();
    let mut invalid = 0u64;
    for p in paths {
        let maps = match read_surface_exr(&p) {
            Ok(m) => m,
            Err(SurfaceError::Exr { .. }) => {
                skipped.push(p);
                continue;
            }
            Err(source) => return Err(MapDirError::Read { path: p, source }),
        };
        let Some(first) = maps.first() else { continue };
        let tag = first.basis;
        let basis = first.basis().map_err(|source| MapDirError::Basis { path: p.clone(), source })?;
        if maps.iter().any(|m| m.basis != tag) {
            return Err(MapDirError::MixedBases(p));
        }
        if sets.iter().any(|b| b.set.tag == tag) {
            return Err(MapDirError::Duplicate { path: p, tag: tag.to_string(), dir: dir.to_owned() });
        }
        invalid = invalid.max(maps.iter().map(|m| m.invalid.invalid_texels).sum());
        sets.push(BasisMaps { path: p, set: MapSet { tag, basis, maps } });
    }
    if sets.is_empty() {
        return Err(MapDirError::Empty(dir.to_owned()));
    }
    Ok(MapDir { sets, invalid_texels: invalid, skipped })
}

/// The first part in which two lighting fingerprints differ ([`LightingRecord::diff`],
/// prefixed `"LA vs LB: "`), or both whole texts if either does not read as a record.
#[must_use]
pub fn lighting_difference(a: &str, b: &str, la: &str, lb: &str) -> String {
    match (a.parse::<LightingRecord>(), b.parse::<LightingRecord>()) {
        (Ok(ra), Ok(rb)) => format!("{la} vs {lb}: {}", ra.diff(&rb).unwrap_or_else(|| "equal".into())),
        _ => format!("{la}: {a}, {lb}: {b}"),
    }
}

fn file_name(p: &Path) -> String {
    p.file_name().map_or_else(|| p.display().to_string(), |f| f.to_string_lossy().into_owned())
}

/// Checks that every map of `maps` (read from the folder `maps_dir`) was baked under one
/// lighting, and that it is the lighting of `scene` with the maps' bounce count; returns
/// those path settings (for the reference).
///
/// # Errors
/// [`MapDirError::MixedLighting`], [`MapDirError::NoBounces`],
/// [`MapDirError::OtherLighting`]; [`MapDirError::Empty`] for no sets.
pub fn check_lighting(
    maps: &MapDir,
    maps_dir: &Path,
    scene: &Scene,
) -> Result<TransportSettings, MapDirError> {
    let sets = &maps.sets;
    let Some(first) = sets.first().filter(|s| !s.set.maps.is_empty()) else {
        return Err(MapDirError::Empty(maps_dir.to_owned()));
    };
    let lighting = &first.set.maps[0].lighting;
    for s in sets {
        if let Some(m) = s.set.maps.iter().find(|m| &m.lighting != lighting) {
            return Err(MapDirError::MixedLighting {
                dir: maps_dir.to_owned(),
                first: first.path.clone(),
                other: s.path.clone(),
                difference: lighting_difference(
                    lighting,
                    &m.lighting,
                    &file_name(&first.path),
                    &file_name(&s.path),
                ),
            });
        }
    }
    let bounces = lighting
        .parse::<LightingRecord>()
        .ok()
        .and_then(|r| r.transport())
        .ok_or_else(|| MapDirError::NoBounces { path: first.path.clone(), lighting: lighting.clone() })?;
    let own = lighting_fingerprint(scene, &bounces);
    if &own != lighting {
        return Err(MapDirError::OtherLighting {
            dir: maps_dir.to_owned(),
            difference: lighting_difference(lighting, &own, "maps", "render"),
        });
    }
    Ok(bounces)
}

/// Checks that every set maps the lightmap objects of `geo`, in order, with the first map's
/// UV set and quantity.
///
/// # Errors
/// [`MapDirError::Objects`] naming the first set that does not.
pub fn check_objects(maps: &MapDir, geo: &SurfaceGeometry) -> Result<(), MapDirError> {
    let Some(first) = maps.sets.first().and_then(|s| s.set.maps.first()) else { return Ok(()) };
    let (uv_set, quantity) = (first.uv_set, first.quantity);
    for s in &maps.sets {
        let m = &s.set.maps;
        if m.len() != geo.objects().len()
            || m.iter().zip(geo.objects()).any(|(m, o)| m.object != o.name)
            || m.iter().any(|m| m.uv_set != uv_set || m.quantity != quantity)
        {
            return Err(MapDirError::Objects(s.set.tag.to_string()));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_empty_folder_is_refused_with_the_command_that_fills_it() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("notes.txt"), "x").unwrap();
        let e = read_map_dir(dir.path()).err().unwrap();
        assert!(matches!(e, MapDirError::Empty(_)));
        assert!(e.to_string().contains("run lightvol bake-surface -o"), "{e}");
    }

    #[test]
    fn a_missing_folder_is_a_read_error() {
        let e = read_map_dir(Path::new("/nonexistent/lightvol-maps")).err().unwrap();
        assert!(matches!(e, MapDirError::ReadDir { .. }));
    }

    #[test]
    fn texts_that_are_not_records_are_shown_whole() {
        assert_eq!(lighting_difference("a", "b", "x", "y"), "x: a, y: b");
    }
}
