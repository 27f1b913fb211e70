//! Checkpointed bakes that can be resumed: a uniform bake split into pieces (the shards of
//! [`BakeRequest::shard`], baked one after another in this process), whose exact sums are
//! saved after every piece, so that a bake killed part-way (a signal, a reboot, an
//! out-of-memory kill) resumes from the pieces it finished and writes the same bytes as an
//! uninterrupted bake.
//!
//! ## Files in the checkpoint directory
//! - `sums-K.lvacc`: the merged exact sums of the first `K` pieces finished (the shard file
//!   format, [`lightvol_volume::io::accumulator`]), with the first piece's metadata and the
//!   finished pieces' sampling rays;
//! - `checkpoint.json` ([`CheckpointState`]): the bake's key (scene, grid and settings,
//!   [`BakeRequest::key`]), the piece count, the pieces finished, the sums file that holds
//!   them and the rays they traced.
//!
//! Each piece writes its sums file first (by temporary file and rename), then the state
//! that names it, then removes the previous sums file: a kill at any point leaves a state
//! whose sums file is whole and holds exactly the pieces it lists, so no piece is counted
//! twice or lost. The fixed-point sums add as integers in any grouping
//! ([`lightvol_volume::Accumulator::merge`]), so the finished volume
//! ([`crate::merge::finish_merged`]) is the unsharded bake's, bit for bit, however often the
//! bake was interrupted. A targeted bake's pieces carry `doi`'s per-node error estimates
//! in their sums, and the target's step (smoothing, and an engine's fit with its rays)
//! runs once, on the finished sums ([`crate::merge::finish_merged_with`]).

use std::path::{Path, PathBuf};

use lightvol_core::progress::BakeControl;
use lightvol_scene::Scene;
use lightvol_scene::stats::RayCounts;
use lightvol_scene::transport::Transport;
use lightvol_volume::io::accumulator::{read_accumulator, write_accumulator};
use lightvol_volume::{Accumulator, BakeMetadata, GridSpec, VolumeError};

use crate::merge::{MergeError, MergedVolume, finish_merged_with};
use crate::request::{BakeRequest, Provenance, UniformBakeError, bake_uniform};

/// Pieces of a checkpointed bake unless asked otherwise: a kill loses at most a
/// sixteenth of the work, and the sums are written sixteen times.
pub const DEFAULT_PIECES: u32 = 16;

/// The state file's name in the checkpoint directory.
pub const STATE_FILE: &str = "checkpoint.json";

/// What `checkpoint.json` records (module docs).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct CheckpointState {
    /// The bake's key ([`checkpoint_key`]): a checkpoint resumes only the same bake.
    pub key: String,
    /// Pieces of the bake.
    pub pieces: u32,
    /// The pieces finished, in the order they were baked.
    pub done: Vec<u32>,
    /// The sums file (in the directory) holding exactly the pieces finished.
    pub sums: String,
    /// Rays the finished pieces traced.
    pub rays: u64,
}

/// A finished checkpointed bake.
pub struct CheckpointedBake {
    /// The volume, as `merge` finishes a whole shard set.
    pub merged: MergedVolume,
    /// The merged exact sums and their metadata (for `--keep-accumulator`).
    pub accumulator: Accumulator,
    /// The merged metadata (shard `(0, 1)`, every piece's sampling rays).
    pub metadata: BakeMetadata,
    /// Pieces found finished in the checkpoint when the bake started.
    pub resumed: Vec<u32>,
    /// Rays this run traced (the pieces it baked).
    pub rays_this_run: RayCounts,
    /// Rays every piece traced, this run's and the resumed pieces'.
    pub rays_total: u64,
}

/// Why a checkpointed bake stopped.
#[derive(Debug, thiserror::Error)]
pub enum CheckpointError {
    /// The directory holds a checkpoint and resuming was not asked for.
    #[error("{} holds a checkpoint of a bake ({} of {} pieces done): add --resume to finish it, or use an empty directory", .dir.display(), .done, .pieces)]
    Exists {
        /// The directory.
        dir: PathBuf,
        /// Pieces finished.
        done: usize,
        /// Pieces of the bake.
        pieces: u32,
    },
    /// Resuming was asked for but there is no checkpoint.
    #[error("{} holds no checkpoint to resume ({STATE_FILE} is missing)", .0.display())]
    Missing(PathBuf),
    /// The checkpoint is of another bake or piece count.
    #[error("the checkpoint in {} is of another bake (scene, grid, settings or piece count differ); use another directory", .0.display())]
    OtherBake(PathBuf),
    /// A piece count of zero or one larger than the bake's units.
    #[error("a checkpointed bake needs at least one piece (got {0})")]
    Pieces(u32),
    /// The checkpoint files could not be read or written.
    #[error("checkpoint file {}", .0.display())]
    File(PathBuf, #[source] std::io::Error),
    /// The state file is damaged.
    #[error("checkpoint file {} is damaged: {}", .0.display(), .1)]
    Damaged(PathBuf, String),
    /// The sums could not be read, written or added.
    #[error("checkpoint sums {}", .0.display())]
    Sums(PathBuf, #[source] VolumeError),
    /// A piece's bake failed.
    #[error("piece {0}")]
    Bake(u32, #[source] Box<UniformBakeError>),
    /// The merged sums could not be finished.
    #[error(transparent)]
    Finish(#[from] MergeError),
}

/// The key a checkpoint is resumed under: the bake's key ([`BakeRequest::key`]: scene,
/// lighting, grid, method label, samples) and a hash of every setting of the request (the
/// seed, the fit, the noise target, …) and of the light groups' names, so that only the
/// very same bake resumes it.
#[must_use]
pub fn checkpoint_key(bake_key: &str, request: &BakeRequest, transport: &Transport<'_>) -> String {
    let whole = BakeRequest { shard: None, keep_accumulator: false, ..request.clone() };
    let groups = transport.groups().map(|g| g.names().join(",")).unwrap_or_default();
    let settings = lightvol_core::hash::fnv1a(format!("{whole:?}|{groups}").as_bytes());
    format!("{bake_key} settings={settings:016x}")
}

/// Reads the checkpoint state of `dir`, if there is one.
///
/// # Errors
/// An unreadable or damaged state file.
pub fn read_state(dir: &Path) -> Result<Option<CheckpointState>, CheckpointError> {
    let path = dir.join(STATE_FILE);
    match std::fs::read_to_string(&path) {
        Ok(text) => {
            serde_json::from_str(&text).map(Some).map_err(|e| CheckpointError::Damaged(path, e.to_string()))
        }
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
        Err(e) => Err(CheckpointError::File(path, e)),
    }
}

fn write_state(dir: &Path, state: &CheckpointState) -> Result<(), CheckpointError> {
    let path = dir.join(STATE_FILE);
    let text = serde_json::to_string_pretty(state)
        .map_err(|e| CheckpointError::Damaged(path.clone(), e.to_string()))?;
    lightvol_core::fs::write_atomic(&path, text.as_bytes()).map_err(|e| CheckpointError::File(path, e))
}

/// Bakes `request` (a uniform bake, whole: no shard of its own) on `grid` in `pieces`
/// pieces, checkpointing into `dir` after each (module docs). With `resume`, the pieces an
/// earlier run of the same bake finished are read from `dir` instead of baked; without it,
/// a checkpoint in `dir` is refused. `on_piece(done, pieces)` is called after each piece.
/// The checkpoint files are removed once the bake is finished.
///
/// # Errors
/// [`CheckpointError`]; the request's own refusals come from the first piece's bake.
#[allow(clippy::too_many_arguments, reason = "a bake's inputs and the checkpoint's")]
pub fn bake_checkpointed(
    transport: &Transport<'_>,
    scene: &Scene,
    grid: &GridSpec,
    request: &BakeRequest,
    provenance: Provenance<'_>,
    dir: &Path,
    pieces: u32,
    resume: bool,
    control: &BakeControl<'_>,
    mut on_piece: impl FnMut(usize, u32),
) -> Result<CheckpointedBake, CheckpointError> {
    if pieces == 0 {
        return Err(CheckpointError::Pieces(pieces));
    }
    std::fs::create_dir_all(dir).map_err(|e| CheckpointError::File(dir.to_path_buf(), e))?;
    let key = checkpoint_key(provenance.key, request, transport);
    let (mut state, mut sums) = match (read_state(dir)?, resume) {
        (Some(s), false) => {
            return Err(CheckpointError::Exists {
                dir: dir.to_path_buf(),
                done: s.done.len(),
                pieces: s.pieces,
            });
        }
        (None, true) => return Err(CheckpointError::Missing(dir.to_path_buf())),
        (None, false) => {
            (CheckpointState { key, pieces, done: Vec::new(), sums: String::new(), rays: 0 }, None)
        }
        (Some(s), true) => {
            if s.key != key || s.pieces != pieces || s.done.iter().any(|&k| k >= pieces) {
                return Err(CheckpointError::OtherBake(dir.to_path_buf()));
            }
            let sums = if s.done.is_empty() {
                None
            } else {
                let p = dir.join(&s.sums);
                Some(read_accumulator(&p).map_err(|e| CheckpointError::Sums(p, e))?)
            };
            (s, sums)
        }
    };
    let resumed = state.done.clone();
    request.validate().map_err(|e| CheckpointError::Bake(0, Box::new(e.into())))?;
    let target = request.effective_target();
    let mut rays_this_run = RayCounts::default();
    for k in 0..pieces {
        if state.done.contains(&k) {
            continue;
        }
        // A piece is a shard of the whole bake without its target step, which runs on the
        // finished sums (below): the pieces carry `doi`'s per-node errors for it.
        let piece = BakeRequest {
            shard: Some((k, pieces)),
            keep_accumulator: false,
            target: None,
            ..request.clone()
        };
        let mut bake = bake_uniform(transport, scene, grid, &piece, provenance, control)
            .map_err(|e| CheckpointError::Bake(k, Box::new(e)))?;
        if target.is_some() {
            bake.output.keep_node_errors(grid, (k, pieces));
        }
        rays_this_run.add(&bake.output.stats.rays);
        let meta = bake.volume.metadata();
        sums = Some(match sums.take() {
            None => (bake.output.accumulator, meta.clone()),
            Some((mut acc, mut m)) => {
                acc.merge(&bake.output.accumulator)
                    .map_err(|e| CheckpointError::Sums(dir.join(&state.sums), e))?;
                m.sampling_rays += meta.sampling_rays;
                (acc, m)
            }
        });
        let (acc, m) = sums.as_ref().expect("set above");
        state.done.push(k);
        state.rays += bake.output.stats.rays.total();
        let previous = std::mem::replace(&mut state.sums, format!("sums-{}.lvacc", state.done.len()));
        let path = dir.join(&state.sums);
        write_accumulator(&path, acc, m).map_err(|e| CheckpointError::Sums(path, e))?;
        write_state(dir, &state)?;
        if !previous.is_empty() {
            let _ = std::fs::remove_file(dir.join(previous));
        }
        on_piece(state.done.len(), pieces);
    }
    let (accumulator, mut metadata) = sums.ok_or(CheckpointError::Pieces(pieces))?;
    metadata.shard_index = 0;
    metadata.shard_count = 1;
    if target.is_some() {
        // The whole bake's metadata: its label and record name the target.
        metadata = request.metadata(scene, provenance.frame, provenance.key, metadata.sampling_rays);
    }
    let merged = finish_merged_with(&accumulator, metadata.clone(), target.as_ref().map(|t| (transport, t)))?;
    // The target's rays (an engine's fit) are traced on every run that finishes the bake.
    if let Some(r) = &merged.target {
        rays_this_run.query += r.rays;
        state.rays += r.rays;
    }
    for f in [STATE_FILE, state.sums.as_str()] {
        let _ = std::fs::remove_file(dir.join(f));
    }
    Ok(CheckpointedBake { merged, accumulator, metadata, resumed, rays_this_run, rays_total: state.rays })
}
