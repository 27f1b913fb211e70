//! Which shard of a bake this process computes: `K/N` given directly, or taken from the
//! job scheduler's environment (`--shard auto`).
//!
//! A bake split into `N` shards computes units `⌊U·K/N⌋..⌊U·(K+1)/N⌋` of its `U` cells (or
//! nodes) in shard `K`; the shards' exact sums merge into the whole bake bit for bit
//! (`lightvol_volume::fixed`), so `K` only has to be dense (`0..N`) and unique per task.
//! [`shard_from_env`] maps each scheduler's array index to such a `K`:
//!
//! | source (in this order) | variables | `N` |
//! | --- | --- | --- |
//! | Slurm job arrays | `SLURM_ARRAY_TASK_ID`, `_MIN`, `_MAX`, `_STEP` | `(MAX − MIN) / STEP + 1`, so `--array=1-8:2` is shards 0..4 |
//! | Kubernetes Indexed Jobs | `JOB_COMPLETION_INDEX` | `--shards N` |
//! | AWS Batch array jobs | `AWS_BATCH_JOB_ARRAY_INDEX` | `--shards N` |
//! | anything else | `LIGHTVOL_SHARD=K/N` | from the value |

/// Why no shard could be determined.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ShardError {
    /// `K/N` is malformed or out of range.
    #[error("{0}")]
    Invalid(String),
    /// No variable applies.
    #[error(
        "--shard auto: no shard in the environment (looked for SLURM_ARRAY_TASK_ID with _MIN/_MAX/_STEP, JOB_COMPLETION_INDEX, AWS_BATCH_JOB_ARRAY_INDEX, LIGHTVOL_SHARD=K/N)"
    )]
    NotFound,
}

/// Parses `K/N` (`0 ≤ K < N`).
///
/// # Errors
/// [`ShardError::Invalid`] naming `what` and the problem.
pub fn parse_shard(what: &str, s: &str) -> Result<(u32, u32), ShardError> {
    let bad = |m: String| ShardError::Invalid(format!("{what}: {m}"));
    let (k, n) = s.split_once('/').ok_or_else(|| bad(format!("expected K/N, got '{s}'")))?;
    let k: u32 = k.trim().parse().map_err(|_| bad(format!("'{k}' is not a whole number")))?;
    let n: u32 = n.trim().parse().map_err(|_| bad(format!("'{n}' is not a whole number")))?;
    if n == 0 || k >= n {
        return Err(bad(format!("need 0 <= K < N, got {k}/{n}")));
    }
    Ok((k, n))
}

/// The shard from a scheduler's environment; `env` looks a variable up (use
/// `|k| std::env::var(k).ok()`), `shards` is `--shards N` where given.
///
/// # Errors
/// [`ShardError::NotFound`] when no variable applies; [`ShardError::Invalid`] for values
/// that do not form a dense shard (an array index off the array's step, `--shards`
/// disagreeing with the array's size, a missing `--shards` for Kubernetes or AWS).
pub fn shard_from_env(
    env: impl Fn(&str) -> Option<String>,
    shards: Option<u32>,
) -> Result<(u32, u32), ShardError> {
    let num = |k: &str| -> Result<Option<i64>, ShardError> {
        env(k)
            .map(|v| {
                v.trim().parse::<i64>().map_err(|_| ShardError::Invalid(format!("{k}={v} is not an integer")))
            })
            .transpose()
    };
    let check_n = |n: u32, from: &str| -> Result<(), ShardError> {
        match shards {
            Some(s) if s != n => {
                Err(ShardError::Invalid(format!("--shards {s} disagrees with {from}, which has {n} tasks")))
            }
            _ => Ok(()),
        }
    };
    if let Some(id) = num("SLURM_ARRAY_TASK_ID")? {
        let min = num("SLURM_ARRAY_TASK_MIN")?
            .ok_or_else(|| ShardError::Invalid("SLURM_ARRAY_TASK_ID without SLURM_ARRAY_TASK_MIN".into()))?;
        let max = num("SLURM_ARRAY_TASK_MAX")?
            .ok_or_else(|| ShardError::Invalid("SLURM_ARRAY_TASK_ID without SLURM_ARRAY_TASK_MAX".into()))?;
        let step = num("SLURM_ARRAY_TASK_STEP")?.unwrap_or(1);
        if step < 1 || max < min || id < min || id > max || (id - min) % step != 0 || (max - min) % step != 0
        {
            return Err(ShardError::Invalid(format!(
                "Slurm array task {id} is not on the arithmetic array {min}-{max}:{step} (use --array=A-B[:S])"
            )));
        }
        let n = (max - min) / step + 1;
        if let Some(count) = num("SLURM_ARRAY_TASK_COUNT")?
            && count != n
        {
            return Err(ShardError::Invalid(format!(
                "the Slurm array {min}-{max}:{step} has {count} tasks, not {n}: it is not arithmetic (use --array=A-B[:S])"
            )));
        }
        let n = u32::try_from(n).map_err(|_| ShardError::Invalid(format!("{n} array tasks")))?;
        check_n(n, "the Slurm array")?;
        return Ok((((id - min) / step) as u32, n));
    }
    for var in ["JOB_COMPLETION_INDEX", "AWS_BATCH_JOB_ARRAY_INDEX"] {
        if let Some(i) = num(var)? {
            let n = shards.ok_or_else(|| {
                ShardError::Invalid(format!("{var} is set: give the shard count with --shards N"))
            })?;
            let k = u32::try_from(i)
                .ok()
                .filter(|&k| k < n)
                .ok_or_else(|| ShardError::Invalid(format!("{var}={i} is not below --shards {n}")))?;
            return Ok((k, n));
        }
    }
    if let Some(v) = env("LIGHTVOL_SHARD") {
        let (k, n) = parse_shard("LIGHTVOL_SHARD", &v)?;
        check_n(n, "LIGHTVOL_SHARD")?;
        return Ok((k, n));
    }
    Err(ShardError::NotFound)
}

/// The shard a command runs: `--shard K/N`, `--shard auto` (from the scheduler's
/// environment, with `--shards N` where it needs one), or `(0, 1)` for a whole bake.
///
/// # Errors
/// As [`parse_shard`] and [`shard_from_env`], and [`ShardError::Invalid`] for `--shards`
/// without `--shard` or disagreeing with an explicit `K/N`.
pub fn resolve_shard(
    shard: Option<&str>,
    shards: Option<u32>,
    env: impl Fn(&str) -> Option<String>,
) -> Result<(u32, u32), ShardError> {
    match shard {
        None if shards.is_some() => Err(ShardError::Invalid(
            "--shards N needs --shard auto (or use `lightvol slurm` / `lightvol k8s`)".into(),
        )),
        None => Ok((0, 1)),
        Some("auto") => shard_from_env(env, shards),
        Some(s) => {
            let (k, n) = parse_shard("--shard", s)?;
            match shards {
                Some(m) if m != n => {
                    Err(ShardError::Invalid(format!("--shards {m} disagrees with --shard {s}")))
                }
                _ => Ok((k, n)),
            }
        }
    }
}

/// Largest JSON header a shard file may declare.
const MAX_SHARD_HEADER: usize = 1 << 20;

/// The framing every shard file shares (`.lvtex`, `.lvref`): a 6-byte magic, the version
/// (u16), the length of the JSON header (u32) and the header, the body, then the FNV-1a 64
/// of every preceding byte. Equal inputs give equal bytes.
#[must_use]
pub fn frame_shard_file(
    magic: &[u8; 6],
    version: u16,
    header: &impl serde::Serialize,
    body: &[u8],
) -> Vec<u8> {
    let json = serde_json::to_vec(header).expect("plain data");
    let mut out = Vec::with_capacity(12 + json.len() + body.len() + 8);
    out.extend_from_slice(magic);
    out.extend_from_slice(&version.to_le_bytes());
    out.extend_from_slice(&(json.len() as u32).to_le_bytes());
    out.extend_from_slice(&json);
    out.extend_from_slice(body);
    let sum = crate::hash::fnv1a(&out);
    out.extend_from_slice(&sum.to_le_bytes());
    out
}

/// Checks a [`frame_shard_file`] framing (checksum first, then magic, version and header
/// length) and returns its header and body; `what` names the file kind in the messages.
///
/// # Errors
/// A one-line message naming what is damaged.
pub fn unframe_shard_file<'a, H: serde::de::DeserializeOwned>(
    bytes: &'a [u8],
    magic: &[u8; 6],
    version: u16,
    what: &str,
) -> Result<(H, &'a [u8]), String> {
    if bytes.len() < 20 {
        return Err(format!("{what} of {} bytes is too short", bytes.len()));
    }
    let (body, tail) = bytes.split_at(bytes.len() - 8);
    if crate::hash::fnv1a(body) != u64::from_le_bytes(tail.try_into().expect("8 bytes")) {
        return Err(format!("{what} checksum mismatch: the file is damaged or truncated"));
    }
    if &body[..6] != magic {
        return Err(format!("not a lightvol {what} (bad magic)"));
    }
    let v = u16::from_le_bytes([body[6], body[7]]);
    if v != version {
        return Err(format!("{what} version {v} (this lightvol reads {version})"));
    }
    let h = u32::from_le_bytes(body[8..12].try_into().expect("4 bytes")) as usize;
    if h > MAX_SHARD_HEADER || 12 + h > body.len() {
        return Err(format!("{what} header length {h} does not fit the file"));
    }
    let header = serde_json::from_slice(&body[12..12 + h]).map_err(|e| format!("{what} header: {e}"))?;
    Ok((header, &body[12 + h..]))
}

/// The contiguous range of `units` (cells, nodes, texels, ...) that shard `k` of `n` takes:
/// `units·k/n .. units·(k+1)/n`. The ranges of `0..n` tile `0..units` in order.
#[must_use]
pub fn shard_range(units: usize, (k, n): (u32, u32)) -> std::ops::Range<usize> {
    let (k, n) = (k as u128, n.max(1) as u128);
    let u = units as u128;
    (u * k / n) as usize..(u * (k + 1) / n) as usize
}

/// Worker threads from the scheduler: `SLURM_CPUS_PER_TASK` when set to a positive number.
#[must_use]
pub fn threads_from_env(env: impl Fn(&str) -> Option<String>) -> Option<usize> {
    env("SLURM_CPUS_PER_TASK").and_then(|v| v.trim().parse::<usize>().ok()).filter(|&n| n > 0)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The shard ranges tile the units in order, each of size ⌊units/n⌋ or ⌈units/n⌉.
    #[test]
    fn shard_ranges_tile_the_units() {
        for units in [0usize, 1, 7, 64, 1000] {
            for n in 1u32..=9 {
                let mut next = 0;
                for k in 0..n {
                    let r = shard_range(units, (k, n));
                    assert_eq!(r.start, next);
                    assert!(r.len() == units / n as usize || r.len() == units.div_ceil(n as usize));
                    next = r.end;
                }
                assert_eq!(next, units);
            }
        }
    }
    use std::collections::HashMap;

    fn env(pairs: &[(&str, &str)]) -> impl Fn(&str) -> Option<String> {
        let m: HashMap<String, String> =
            pairs.iter().map(|(k, v)| ((*k).to_owned(), (*v).to_owned())).collect();
        move |k| m.get(k).cloned()
    }

    fn slurm(id: i64, min: i64, max: i64, step: i64) -> Vec<(String, String)> {
        let count = (max - min) / step + 1;
        [
            ("SLURM_ARRAY_TASK_ID", id),
            ("SLURM_ARRAY_TASK_MIN", min),
            ("SLURM_ARRAY_TASK_MAX", max),
            ("SLURM_ARRAY_TASK_STEP", step),
            ("SLURM_ARRAY_TASK_COUNT", count),
        ]
        .iter()
        .map(|(k, v)| ((*k).to_owned(), v.to_string()))
        .collect()
    }

    fn e(v: &[(String, String)]) -> impl Fn(&str) -> Option<String> + '_ {
        move |k| v.iter().find(|(a, _)| a == k).map(|(_, b)| b.clone())
    }

    /// Every task of an arithmetic array maps to a distinct dense index: `--array=1-8:2` is
    /// tasks 1, 3, 5, 7 → shards 0..4 of 4; `0-15:2` → 0..8 of 8; `0-3` → 0..4 of 4.
    #[test]
    fn slurm_arrays_map_to_dense_shards() {
        for (min, max, step, n) in [(1, 7, 2, 4), (0, 14, 2, 8), (0, 3, 1, 4), (5, 5, 1, 1)] {
            let mut seen = Vec::new();
            let mut id = min;
            while id <= max {
                let v = slurm(id, min, max, step);
                let (k, got_n) = shard_from_env(e(&v), None).unwrap();
                assert_eq!(got_n, n);
                seen.push(k);
                id += step;
            }
            assert_eq!(seen, (0..n).collect::<Vec<_>>());
        }
        // Off-step task, disagreeing --shards, non-arithmetic count.
        let v = slurm(2, 1, 7, 2);
        assert!(matches!(shard_from_env(e(&v), None), Err(ShardError::Invalid(_))));
        let v = slurm(3, 1, 7, 2);
        assert!(shard_from_env(e(&v), Some(5)).unwrap_err().to_string().contains("disagrees"));
        assert_eq!(shard_from_env(e(&v), Some(4)).unwrap(), (1, 4));
        let mut v = slurm(3, 1, 7, 1);
        v[4].1 = "3".into(); // --array=1,3,7: min 1, max 7, 3 tasks
        assert!(shard_from_env(e(&v), None).unwrap_err().to_string().contains("not arithmetic"));
    }

    #[test]
    fn resolve_covers_whole_explicit_and_auto() {
        let none = env(&[]);
        assert_eq!(resolve_shard(None, None, &none).unwrap(), (0, 1));
        assert!(resolve_shard(None, Some(3), &none).unwrap_err().to_string().contains("--shard auto"));
        assert_eq!(resolve_shard(Some("1/3"), Some(3), &none).unwrap(), (1, 3));
        assert!(resolve_shard(Some("1/3"), Some(4), &none).unwrap_err().to_string().contains("disagrees"));
        assert_eq!(resolve_shard(Some("auto"), None, env(&[("LIGHTVOL_SHARD", "2/5")])).unwrap(), (2, 5));
    }

    #[test]
    fn kubernetes_aws_and_explicit() {
        assert_eq!(shard_from_env(env(&[("JOB_COMPLETION_INDEX", "3")]), Some(8)).unwrap(), (3, 8));
        assert!(
            shard_from_env(env(&[("JOB_COMPLETION_INDEX", "3")]), None)
                .unwrap_err()
                .to_string()
                .contains("--shards N")
        );
        assert!(shard_from_env(env(&[("JOB_COMPLETION_INDEX", "8")]), Some(8)).is_err());
        assert_eq!(shard_from_env(env(&[("AWS_BATCH_JOB_ARRAY_INDEX", "0")]), Some(2)).unwrap(), (0, 2));
        assert_eq!(shard_from_env(env(&[("LIGHTVOL_SHARD", "2/5")]), None).unwrap(), (2, 5));
        assert!(shard_from_env(env(&[("LIGHTVOL_SHARD", "5/5")]), None).is_err());
        // Slurm wins over the others.
        let mut v = slurm(1, 0, 1, 1);
        v.push(("LIGHTVOL_SHARD".into(), "0/3".into()));
        assert_eq!(shard_from_env(e(&v), None).unwrap(), (1, 2));
        let none = shard_from_env(env(&[]), None).unwrap_err().to_string();
        assert!(
            none.contains("SLURM_ARRAY_TASK_ID")
                && none.contains("JOB_COMPLETION_INDEX")
                && none.contains("LIGHTVOL_SHARD"),
            "{none}"
        );
        assert_eq!(threads_from_env(env(&[("SLURM_CPUS_PER_TASK", "4")])), Some(4));
        assert_eq!(threads_from_env(env(&[("SLURM_CPUS_PER_TASK", "0")])), None);
    }
}
