//! Shard bakes merged into one volume: each shard's exact sums sit in an accumulator file
//! beside its volume ([`accumulator_path`], [`shard_accumulator`]); the files are read and
//! checked as one set and their sums added as fixed-point integers, so any order gives the
//! same bits ([`merge_shards`]); the merged sums are finalized as the unsharded bake
//! finalizes its own ([`finish_merged`]), which makes the result that bake's volume, bit for
//! bit.
//!
//! The shards of an octree bake are not merged here: their levels are assembled
//! ([`crate::adaptive_shard::ShardSet`]).

use std::path::{Path, PathBuf};

use lightvol_volume::io::accumulator::{
    ACC_EXTENSION, ShardSetError, check_shard_set, merge_accumulator_file, read_accumulator_metadata,
};
use lightvol_volume::{
    Accumulator, BakeMetadata, FillReport, FitRecord, IrradianceVolume, VolumeError, VolumeGradients,
};

use crate::adaptive_shard::{BASE_SUFFIX, LEVEL_EXTENSION};
use crate::error::BakeError;
use crate::gradient_bake::{GradientReport, ShardGradients};
use crate::node_fit::{Fit, FitReport, MassMatrix, finalize_least_squares, solve_least_squares};
use crate::noise::node_errors_of;
use crate::target::{TargetReport, TargetSettings, fit_for_lookup, own_samples_mask, smooth_for_target};
use lightvol_scene::transport::Transport;
use lightvol_volume::EngineLookup;

/// The accumulator file beside the volume file `volume` (its path with the extension
/// [`ACC_EXTENSION`]): where a shard or a kept accumulator is written, and where a merge
/// finds the sums of a volume file it is given.
#[must_use]
pub fn accumulator_path(volume: &Path) -> PathBuf {
    volume.with_extension(ACC_EXTENSION)
}

/// Why a file given to a merge has no sums to merge.
#[derive(Debug, thiserror::Error)]
pub enum ShardInputError {
    /// A refinement level of a sharded octree bake (assembled, not merged).
    #[error("{} is a refinement level of a sharded octree bake, which is assembled, not merged", .0.display())]
    LevelFile(PathBuf),
    /// An octree volume.
    #[error("{} is an octree volume; only uniform shard bakes are merged", .0.display())]
    Octree(PathBuf),
    /// A volume file without an accumulator beside it.
    #[error("{} has no accumulator beside it ({})", volume.display(), accumulator.display())]
    NoAccumulator {
        /// The volume file.
        volume: PathBuf,
        /// Where its accumulator would be.
        accumulator: PathBuf,
    },
    /// No such file.
    #[error("{}: no such file", .0.display())]
    Missing(PathBuf),
}

/// The accumulator file of a merge input `p`: `p` itself when it is one (extension
/// [`ACC_EXTENSION`]), else the one beside the volume file `p` ([`accumulator_path`]).
///
/// # Errors
/// [`ShardInputError`]: a level file ([`LEVEL_EXTENSION`]), an octree volume, a volume
/// without an accumulator beside it, or no file at all.
pub fn shard_accumulator(p: &Path) -> Result<PathBuf, ShardInputError> {
    if p.extension().is_some_and(|e| e == ACC_EXTENSION) {
        return Ok(p.to_owned());
    }
    if p.extension().is_some_and(|e| e == LEVEL_EXTENSION) {
        return Err(ShardInputError::LevelFile(p.to_owned()));
    }
    if lightvol_volume::io::adaptive::is_adaptive_exr(p).unwrap_or(false) {
        return Err(ShardInputError::Octree(p.to_owned()));
    }
    let sibling = accumulator_path(p);
    if sibling.is_file() {
        Ok(sibling)
    } else if p.is_file() {
        Err(ShardInputError::NoAccumulator { volume: p.to_owned(), accumulator: sibling })
    } else {
        Err(ShardInputError::Missing(p.to_owned()))
    }
}

/// The summed accumulators of a shard set ([`merge_shards`]).
pub struct MergedShards {
    /// The merged exact sums.
    pub accumulator: Accumulator,
    /// The set's metadata: the first shard's, with every shard's sampling rays, and shard
    /// `(0, 1)` when the set is complete.
    pub metadata: BakeMetadata,
    /// The shard indices merged, ascending.
    pub merged: Vec<u32>,
    /// The shard indices missing, ascending (empty for a complete set).
    pub missing: Vec<u32>,
}

/// Why a set of shard files was not merged (nothing is merged before the whole set is
/// checked).
#[derive(Debug, thiserror::Error)]
pub enum MergeShardsError {
    /// An input has no sums to merge.
    #[error(transparent)]
    Input(#[from] ShardInputError),
    /// No input.
    #[error("no inputs")]
    NoInputs,
    /// One accumulator given twice.
    #[error("{} is given twice (its samples would count twice)", .0.display())]
    Twice(PathBuf),
    /// An accumulator's header could not be read.
    #[error("reading {}", path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: VolumeError,
    },
    /// The files are not the shards of one bake, each once.
    #[error(transparent)]
    Set(#[from] ShardSetError),
    /// A level-0 shard of an octree bake (its volume needs the refinement levels).
    #[error("{} is a level-0 shard of an octree bake, which is assembled with its levels", .0.display())]
    OctreeBase(PathBuf),
    /// Shards are missing and a partial merge was not asked for.
    #[error("incomplete set: shards {missing:?} of {count} are missing (have {merged:?})")]
    Incomplete {
        /// The missing indices.
        missing: Vec<u32>,
        /// Shards of the bake.
        count: u32,
        /// The indices given.
        merged: Vec<u32>,
    },
    /// An accumulator's sums could not be read or added.
    #[error("merging {}", path.display())]
    Merge {
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: VolumeError,
    },
}

/// Reads the accumulators of the merge inputs `inputs` ([`shard_accumulator`]), checks that
/// they are the shards of one uniform bake, each once ([`check_shard_set`]), and complete
/// unless `allow_partial`, then adds their sums, one file at a time (one accumulator in
/// memory whatever the number of shards).
///
/// # Errors
/// [`MergeShardsError`], for the first problem found, in that order.
pub fn merge_shards(inputs: &[PathBuf], allow_partial: bool) -> Result<MergedShards, MergeShardsError> {
    let mut parts: Vec<(BakeMetadata, PathBuf)> = Vec::new();
    let mut seen: Vec<PathBuf> = Vec::new();
    for p in inputs {
        let ap = shard_accumulator(p)?;
        let canon = std::fs::canonicalize(&ap).unwrap_or_else(|_| ap.clone());
        if seen.contains(&canon) {
            return Err(MergeShardsError::Twice(ap));
        }
        seen.push(canon);
        let meta = read_accumulator_metadata(&ap)
            .map_err(|source| MergeShardsError::Read { path: ap.clone(), source })?;
        parts.push((meta, ap));
    }
    if parts.is_empty() {
        return Err(MergeShardsError::NoInputs);
    }
    let missing = check_shard_set(&mut parts)?;
    let (first, p0) = (&parts[0].0, &parts[0].1);
    if first.method.ends_with(BASE_SUFFIX) {
        return Err(MergeShardsError::OctreeBase(p0.clone()));
    }
    let merged: Vec<u32> = parts.iter().map(|(m, _)| m.shard_index).collect();
    if !missing.is_empty() && !allow_partial {
        return Err(MergeShardsError::Incomplete { missing, count: first.shard_count, merged });
    }
    let mut acc = None;
    let mut metadata = first.clone();
    metadata.sampling_rays = 0;
    for (m, p) in &parts {
        let (a, _) = merge_accumulator_file(acc.take(), p)
            .map_err(|source| MergeShardsError::Merge { path: p.clone(), source })?;
        acc = Some(a);
        metadata.sampling_rays += m.sampling_rays;
    }
    let accumulator = acc.ok_or(MergeShardsError::NoInputs)?;
    if missing.is_empty() {
        metadata.shard_index = 0;
        metadata.shard_count = 1;
    }
    Ok(MergedShards { accumulator, metadata, merged, missing })
}

/// λ of a least-squares bake whose files carry `meta`: from the typed settings record, or,
/// in files written before it, from the method label `METHOD fit=lsq:λ`.
#[must_use]
pub fn recorded_lambda(meta: &BakeMetadata) -> Option<f64> {
    if let Some(record) = &meta.settings {
        return match record.fit {
            FitRecord::LeastSquares { lambda } => Some(lambda),
            FitRecord::Average => None,
        };
    }
    let fit: Fit = meta.method.split_whitespace().find_map(|w| w.strip_prefix("fit="))?.parse().ok()?;
    match fit {
        Fit::LeastSquares { lambda } => Some(lambda),
        Fit::Average => None,
    }
}

/// A volume finalized from merged shard sums ([`finish_merged`]).
pub struct MergedVolume {
    /// The volume (Eq. 6, or the least-squares fit), with `meta`.
    pub volume: IrradianceVolume,
    /// Zero-weight nodes filled from neighbours.
    pub fill: FillReport,
    /// The gradients the shards carried, solved or restored, with their report.
    pub gradients: Option<(VolumeGradients, GradientReport)>,
    /// The least-squares fit's weight λ and solve, when the shards carry a mass matrix.
    pub least_squares: Option<(f64, FitReport)>,
    /// The volume split by light group, when the shards carry groups.
    pub groups: Option<lightvol_volume::GroupedVolume>,
    /// The target step, when the set was baked for a target lookup (`bake --target`).
    pub target: Option<TargetReport>,
}

/// Why merged sums could not be finalized.
#[derive(Debug, thiserror::Error)]
pub enum MergeError {
    /// The shards carry a mass matrix but their metadata names no least-squares fit.
    #[error("the shards carry a mass matrix but their method '{0}' names no least-squares fit")]
    NoLambda(String),
    /// The auxiliary gradient sums could not be read.
    #[error("reading the shards' gradients")]
    GradientSums(#[source] BakeError),
    /// The least-squares node fit.
    #[error("least-squares node fit")]
    LeastSquares(#[source] BakeError),
    /// The basis-gradient systems.
    #[error("solving the basis-gradient systems")]
    Gradients(#[source] BakeError),
    /// The light groups the shards carry.
    #[error("finalizing the light groups")]
    Groups(#[source] VolumeError),
    /// The set was baked for an engine's lookup, whose fit traces rays in the scene.
    #[error(
        "the shards were baked for {0}'s lookup, whose fit traces rays in the scene; a merge can only finish sets baked without --target or with --target lightvol"
    )]
    TargetNeedsScene(String),
    /// The set asks for the noise-weighted smoothing but carries no per-node errors.
    #[error(
        "the shards ask for the noise-weighted smoothing but carry no per-node error estimates (written by an older lightvol?); rebake them"
    )]
    NoNodeErrors,
    /// The target step itself.
    #[error("the target lookup's step")]
    Target(#[source] BakeError),
}

/// Finalizes the merged sums of a whole shard set (the same bits as the unsharded bake
/// gives, [`crate::request::bake_uniform`]) under `meta`: the least-squares fit over the
/// whole set where the shards carry its mass matrix (λ the set's recorded fit,
/// [`recorded_lambda`]), the gradients the shards carry (the basis estimator's systems
/// solved on the merged volume, or the central differences restored), and, for a set
/// baked with `--target lightvol`, the noise-weighted smoothing under the per-node errors
/// the shards carry ([`crate::noise::node_errors_of`], [`smooth_for_target`]).
///
/// # Errors
/// [`MergeError`]; [`MergeError::TargetNeedsScene`] for a set baked for an engine's lookup
/// (see [`finish_merged_with`]).
pub fn finish_merged(acc: &Accumulator, meta: BakeMetadata) -> Result<MergedVolume, MergeError> {
    finish_merged_with(acc, meta, None)
}

/// [`finish_merged`], with the scene's light transport and the target's settings for a set
/// baked for an engine's lookup (whose fit traces rays: [`fit_for_lookup`]); a checkpointed
/// bake, which has both, finishes its pieces so.
///
/// # Errors
/// [`MergeError`].
pub fn finish_merged_with(
    acc: &Accumulator,
    meta: BakeMetadata,
    fit: Option<(&Transport<'_>, &TargetSettings)>,
) -> Result<MergedVolume, MergeError> {
    let record = meta.settings.as_ref().and_then(|s| s.target.clone());
    let grad_sums = ShardGradients::from_accumulator(acc).map_err(MergeError::GradientSums)?;
    let (volume, fill, least_squares) = match MassMatrix::from_accumulator(acc) {
        None => {
            let (v, fill) = acc.finalize();
            (v, fill, None)
        }
        Some(mass) => {
            let lambda = recorded_lambda(&meta).ok_or_else(|| MergeError::NoLambda(meta.method.clone()))?;
            let (values, solve) =
                solve_least_squares(&mass, acc, lambda).map_err(MergeError::LeastSquares)?;
            let (v, fill) = finalize_least_squares(acc, values);
            (v, fill, Some((lambda, solve)))
        }
    };
    let volume = volume.with_metadata(meta);
    let gradients = match grad_sums {
        None => None,
        Some(g) => Some(g.finish(&volume).map_err(MergeError::Gradients)?),
    };
    let (volume, target) = match record {
        None => (volume, None),
        Some(record) => {
            // As the whole bake: the nodes with samples of their own, the merged estimates.
            let valid = own_samples_mask(acc);
            let errors = node_errors_of(acc);
            let smoothing = fit.map_or(record.smoothing, |(_, t)| t.smoothing);
            if smoothing.is_some() && errors.is_none() {
                return Err(MergeError::NoNodeErrors);
            }
            match fit {
                Some((transport, t)) => {
                    let (v, r) = fit_for_lookup(transport, &volume, t, Some(valid), errors.as_deref())
                        .map_err(MergeError::Target)?;
                    (v, Some(r))
                }
                None if record.lookup == EngineLookup::Lightvol.name() => {
                    let (smoothed, r) =
                        smooth_for_target(&volume, Some(&valid), errors.as_deref(), smoothing)
                            .map_err(MergeError::Target)?;
                    (
                        smoothed.unwrap_or(volume),
                        Some(TargetReport { smoothing: r, ..TargetReport::default() }),
                    )
                }
                None => return Err(MergeError::TargetNeedsScene(record.lookup)),
            }
        }
    };
    let groups = acc.finalize_grouped(&volume).transpose().map_err(MergeError::Groups)?;
    Ok(MergedVolume { volume, fill, gradients, least_squares, groups, target })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::method::{BakeMethod, Method};
    use crate::request::{BakeRequest, Provenance, UniformBake, bake_uniform};
    use lightvol_core::progress::BakeControl;
    use lightvol_core::samples::samples;
    use lightvol_scene::{Tracer, Transport};
    use lightvol_volume::GridSpec;
    use lightvol_volume::io::accumulator::write_accumulator;

    /// `request` on the maze's 4 × 4 × 3 grid.
    fn maze_bake(request: &BakeRequest) -> UniformBake {
        let maze = lightvol_scene::builtin("maze").unwrap();
        let (lo, hi) = maze.grid.bounds();
        let grid = GridSpec::new(lo, hi, [4, 4, 3]).unwrap();
        let tracer = Tracer::new(&maze.scene);
        let t = Transport::new(&maze.scene, &tracer, Default::default());
        let p = Provenance { frame: lightvol_scene::UpAxis::Z, key: "maze" };
        bake_uniform(&t, &maze.scene, &grid, request, p, &BakeControl::default()).unwrap()
    }

    /// The maze, doi-paper at 4 samples per cell, whole (`None`) or one shard.
    fn bake(shard: Option<(u32, u32)>) -> UniformBake {
        maze_bake(&BakeRequest { shard, ..BakeRequest::new(BakeMethod::Grid(Method::DoiPaper), samples(4)) })
    }

    #[test]
    fn merged_shards_are_the_whole_bake() {
        let dir = tempfile::tempdir().unwrap();
        let volume = |k: u32| dir.path().join(format!("part{k}.exr"));
        let mut sampling = 0;
        for k in 0..3 {
            let b = bake(Some((k, 3)));
            sampling += b.output.stats.rays.sampling;
            write_accumulator(&accumulator_path(&volume(k)), &b.output.accumulator, b.volume.metadata())
                .unwrap();
        }
        // Volume files stand for their accumulators; any order.
        std::fs::write(volume(2), b"not read").unwrap();
        let inputs = [volume(2), accumulator_path(&volume(0)), accumulator_path(&volume(1))];
        let m = merge_shards(&inputs, false).unwrap();
        assert_eq!((m.merged, m.missing), (vec![0, 1, 2], vec![]));
        assert_eq!(
            (m.metadata.shard_index, m.metadata.shard_count, m.metadata.sampling_rays),
            (0, 1, sampling)
        );
        let whole = bake(None);
        assert_eq!(&m.metadata, whole.volume.metadata());
        let v = finish_merged(&m.accumulator, m.metadata).unwrap();
        assert_eq!(v.volume.data(), whole.volume.data());
        assert_eq!(v.volume.weights(), whole.volume.weights());
        assert_eq!(
            (v.fill.filled, v.gradients.is_none(), v.least_squares.is_none()),
            (whole.fill.filled, true, true)
        );

        // Two of three: refused, or merged as a part when asked.
        let two = [accumulator_path(&volume(2)), accumulator_path(&volume(0))];
        match merge_shards(&two, false) {
            Err(MergeShardsError::Incomplete { missing, count, merged }) => {
                assert_eq!((missing, count, merged), (vec![1], 3, vec![0, 2]));
            }
            other => panic!("{:?}", other.err()),
        }
        let part = merge_shards(&two, true).unwrap();
        assert_eq!((part.merged, part.missing), (vec![0, 2], vec![1]));
        assert_eq!((part.metadata.shard_index, part.metadata.shard_count), (0, 3));
        let twice = [accumulator_path(&volume(0)), accumulator_path(&volume(0))];
        assert!(matches!(merge_shards(&twice, false), Err(MergeShardsError::Twice(p)) if p == twice[0]));
    }

    /// The maze, `doi --target lightvol` at 16 samples, whole or one shard.
    fn smoothed(shard: Option<(u32, u32)>) -> UniformBake {
        maze_bake(&BakeRequest {
            shard,
            target: Some(TargetSettings::new(EngineLookup::Lightvol, 1)),
            ..BakeRequest::new(BakeMethod::Grid(Method::Doi), samples(16))
        })
    }

    #[test]
    fn merged_shards_are_smoothed_as_the_whole_bake() {
        let whole = smoothed(None);
        let r = whole.target.as_ref().and_then(|t| t.smoothing).expect("the whole bake smooths");
        assert!(r.nodes > 0, "{r:?}");
        // The shards merged in reverse order, as `merge` and a checkpoint add them.
        let (b1, b0) = (smoothed(Some((1, 2))), smoothed(Some((0, 2))));
        assert!(b1.target.is_none() && b0.target.is_none(), "a shard leaves the smoothing to the merge");
        let mut acc = b1.output.accumulator.clone();
        acc.merge(&b0.output.accumulator).unwrap();
        let mut meta = b1.volume.metadata().clone();
        meta.sampling_rays += b0.volume.metadata().sampling_rays;
        (meta.shard_index, meta.shard_count) = (0, 1);
        assert_eq!(&meta, whole.volume.metadata());
        let v = finish_merged(&acc, meta.clone()).unwrap();
        assert_eq!(v.volume.data(), whole.volume.data(), "smoothed bit for bit as the whole bake");
        assert_eq!(v.volume.reach(), whole.volume.reach());
        assert_eq!(v.target.and_then(|t| t.smoothing), Some(r));
        // An engine's lookup needs the scene; sums without the estimates cannot smooth.
        let mut engine = meta.clone();
        engine.settings.as_mut().and_then(|s| s.target.as_mut()).unwrap().lookup = "three".into();
        assert!(matches!(finish_merged(&acc, engine), Err(MergeError::TargetNeedsScene(l)) if l == "three"));
        let mut bare = acc.clone();
        bare.set_aux("unrelated", lightvol_volume::fixed::FixedSums::zeros(1));
        assert!(matches!(finish_merged(&bare, meta), Err(MergeError::NoNodeErrors)));
    }

    #[test]
    fn inputs_without_sums_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        assert_eq!(shard_accumulator(&d.join("a.lvacc")).unwrap(), d.join("a.lvacc"));
        let e = |p: &Path| shard_accumulator(p).unwrap_err();
        assert!(
            matches!(e(&d.join("l1-0.lvref")), ShardInputError::LevelFile(p) if p == d.join("l1-0.lvref"))
        );
        assert!(matches!(e(&d.join("none.exr")), ShardInputError::Missing(p) if p == d.join("none.exr")));
        std::fs::write(d.join("v.exr"), b"a volume without sums").unwrap();
        match e(&d.join("v.exr")) {
            ShardInputError::NoAccumulator { volume, accumulator } => {
                assert_eq!((volume, accumulator), (d.join("v.exr"), d.join("v.lvacc")));
            }
            other => panic!("{other}"),
        }
        std::fs::write(d.join("v.lvacc"), b"").unwrap();
        assert_eq!(shard_accumulator(&d.join("v.exr")).unwrap(), d.join("v.lvacc"));
        // An octree's level-0 shard is assembled with its levels, not merged.
        let b = bake(Some((0, 1)));
        let mut meta = b.volume.metadata().clone();
        meta.method = crate::adaptive_shard::base_label(&meta.method);
        write_accumulator(&d.join("base.lvacc"), &b.output.accumulator, &meta).unwrap();
        let r = merge_shards(&[d.join("base.lvacc")], false);
        assert!(matches!(r, Err(MergeShardsError::OctreeBase(p)) if p == d.join("base.lvacc")));
        assert!(matches!(merge_shards(&[], false), Err(MergeShardsError::NoInputs)));
    }

    #[test]
    fn lambda_comes_from_the_record_or_the_label() {
        let b = bake(None);
        let mut meta = b.volume.metadata().clone();
        assert_eq!(recorded_lambda(&meta), None);
        meta.settings.as_mut().unwrap().fit = FitRecord::LeastSquares { lambda: 0.25 };
        assert_eq!(recorded_lambda(&meta), Some(0.25));
        meta.settings = None;
        meta.method = "doi-paper fit=lsq:0.5".into();
        assert_eq!(recorded_lambda(&meta), Some(0.5));
        meta.method = "doi-paper".into();
        assert_eq!(recorded_lambda(&meta), None);
    }
}
