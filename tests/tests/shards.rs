//! Sharded bakes on a small scene: whatever the shard count, the order the shards are
//! merged in and the thread count, the merged volume is the whole bake bit for bit; `merge`
//! refuses incomplete and mixed sets in one line and writes nothing. (`--shard auto` and
//! the cluster verbs are tested with the binary in `bake-cli/tests/cluster.rs`.)

mod common;

use common::{ok, run, s};
use lightvol_volume::io::exr::read_exr;
use std::path::Path;

/// The small bake every case shares (maze, 6×6×3 nodes, 8 samples per cell).
const BAKE: [&str; 8] = ["--samples", "8", "--res", "6,6,3", "--seed", "3", "--quiet", "--bounces=1"];

fn bake(out: &Path, extra: &[&str]) {
    let mut a = vec!["bake", "builtin:maze", "-o", s(out)];
    a.extend_from_slice(&BAKE);
    a.extend_from_slice(extra);
    ok(&a);
}

/// The bake modes that shard, each with its own files: the default `doi`, the paper's
/// Eq. 6 average (`doi-paper`), the
/// least-squares fit (mass matrix in the shard files), both gradient estimators, and the
/// adaptive octree (level by level).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Mode {
    Doi,
    DoiPaper,
    Lsq,
    BasisGradients,
    CentralGradients,
    Adaptive,
}

const MODES: [Mode; 6] =
    [Mode::Doi, Mode::DoiPaper, Mode::Lsq, Mode::BasisGradients, Mode::CentralGradients, Mode::Adaptive];

/// The adaptive bake's finest level.
const MAX_LEVEL: u32 = 2;

fn mode_args(m: Mode) -> &'static [&'static str] {
    match m {
        Mode::Doi => &[],
        Mode::DoiPaper => &["--method", "doi-paper"],
        Mode::Lsq => &["--method", "doi-paper", "--fit", "lsq:0.25"],
        Mode::BasisGradients => &["--method", "doi-paper", "--gradients", "basis"],
        Mode::CentralGradients => &["--gradients", "central"],
        Mode::Adaptive => &["--adaptive", "--max-level", "2", "--depth-rays", "8"],
    }
}

fn bake_mode(out: &Path, m: Mode, extra: &[&str]) {
    let mut a = mode_args(m).to_vec();
    a.extend_from_slice(extra);
    bake(out, &a);
}

fn ok_owned(a: &[String]) {
    ok(&a.iter().map(String::as_str).collect::<Vec<_>>());
}

/// Bakes `n` shards of `m` (shard `k` on `threads[k % len]` threads), then merges them —
/// for an adaptive bake, level by level, each level's shards reading the lower levels'
/// files in `order` — and returns the merged volume's path.
fn sharded(d: &Path, m: Mode, n: u32, order: &[usize], threads: &[u32]) -> std::path::PathBuf {
    let tag = format!("{m:?}{n}");
    let t = |k: u32| threads[k as usize % threads.len()].to_string();
    let in_order = |files: &[std::path::PathBuf]| -> Vec<String> {
        order.iter().map(|&i| s(&files[i]).to_owned()).collect()
    };
    let merged = d.join(format!("{tag}-merged.exr"));
    let base: Vec<std::path::PathBuf> = (0..n)
        .map(|k| {
            let out = d.join(format!("{tag}-l0-{k}.exr"));
            bake_mode(&out, m, &["--shard", &format!("{k}/{n}"), "--threads", &t(k)]);
            out.with_extension("lvacc")
        })
        .collect();
    if m != Mode::Adaptive {
        let mut a = vec!["merge".to_owned(), "--keep-accumulator".to_owned()];
        a.extend(in_order(&base));
        a.extend(["-o".to_owned(), s(&merged).to_owned()]);
        ok_owned(&a);
        return merged;
    }
    let mut lower = in_order(&base);
    for level in 1..=MAX_LEVEL {
        let files: Vec<std::path::PathBuf> = (0..n)
            .map(|k| {
                let out = d.join(format!("{tag}-l{level}-{k}.exr"));
                let mut a: Vec<String> = ["bake", "builtin:maze", "-o", s(&out)].map(str::to_owned).to_vec();
                a.extend(BAKE.map(str::to_owned));
                a.extend(mode_args(m).iter().map(|x| (*x).to_owned()));
                let lv = level.to_string();
                a.extend(
                    ["--shard", &format!("{k}/{n}"), "--threads", &t(k + level), "--level", &lv]
                        .map(str::to_owned),
                );
                a.push("--from-shards".to_owned());
                a.extend(lower.iter().cloned());
                ok_owned(&a);
                out.with_extension("lvref")
            })
            .collect();
        lower.extend(in_order(&files));
    }
    let mut a: Vec<String> = ["bake", "builtin:maze", "-o", s(&merged)].map(str::to_owned).to_vec();
    a.extend(BAKE.map(str::to_owned));
    a.extend(mode_args(m).iter().map(|x| (*x).to_owned()));
    a.push("--from-shards".to_owned());
    a.extend(lower);
    ok_owned(&a);
    merged
}

/// For every mode: whole bake on 1 thread = on 2 threads = 1, 3 and 7 shards merged in
/// forward, reverse and shuffled order with shards on 1 and 2 threads, byte for byte — the
/// volume and, for the uniform modes, the exact accumulator (`--keep-accumulator`).
#[test]
fn any_shard_count_order_and_thread_count_gives_the_whole_bake() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    for m in MODES {
        let whole = d.join(format!("{m:?}-whole.exr"));
        let keep: &[&str] = if m == Mode::Adaptive { &[] } else { &["--keep-accumulator"] };
        bake_mode(&whole, m, &[&["--threads", "1"][..], keep].concat());
        let whole_acc = (!keep.is_empty()).then(|| std::fs::read(whole.with_extension("lvacc")).unwrap());
        let two = d.join(format!("{m:?}-two.exr"));
        bake_mode(&two, m, &["--threads", "2"]);
        let w = std::fs::read(&whole).unwrap();
        assert!(std::fs::read(&two).unwrap() == w, "{m:?}: 1 and 2 threads differ");
        for n in [1u32, 3, 7] {
            let orders: Vec<Vec<usize>> = vec![
                (0..n as usize).collect(),
                (0..n as usize).rev().collect(),
                (0..n as usize).map(|i| (i * 5 + 2) % n as usize).collect(),
            ];
            for (o, order) in orders.iter().enumerate() {
                let sub = d.join(format!("{m:?}-{n}-{o}"));
                std::fs::create_dir(&sub).unwrap();
                let merged = sharded(&sub, m, n, order, &[1, 2]);
                assert!(
                    std::fs::read(&merged).unwrap() == w,
                    "{m:?}, {n} shards, order {order:?}: the files differ"
                );
                // The merged exact sums are the whole bake's accumulator file, too.
                if let Some(acc) = &whole_acc {
                    assert!(
                        std::fs::read(merged.with_extension("lvacc")).unwrap() == *acc,
                        "{m:?}, {n} shards, order {order:?}: the .lvacc files differ"
                    );
                }
            }
        }
        if m == Mode::Doi {
            let (a, b) =
                (read_exr(&whole).unwrap(), read_exr(&d.join("Doi-7-2").join("Doi7-merged.exr")).unwrap());
            assert_eq!(a.data(), b.data());
            assert_eq!((b.metadata().shard_index, b.metadata().shard_count), (0, 1));
            assert_eq!(b.metadata().sampling_rays, a.metadata().sampling_rays);
        }
    }
}

proptest::proptest! {
    #![proptest_config(proptest::test_runner::Config {
        cases: 16,
        rng_seed: proptest::test_runner::RngSeed::Fixed(17),
        failure_persistence: None,
        ..proptest::test_runner::Config::default()
    })]

    /// As a property: for any mode, any shard count 1..=7, any merge order and any thread
    /// count per shard, the merged file is the whole bake's file.
    #[test]
    fn merged_file_is_the_whole_file_for_any_split(
        mode in 0usize..MODES.len(),
        n in 1u32..=7,
        order_seed in proptest::prelude::any::<u64>(),
        threads in proptest::collection::vec(1u32..=2, 7),
    ) {
        let m = MODES[mode];
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let whole = d.join("whole.exr");
        bake_mode(&whole, m, &[]);
        // A seeded shuffle of the merge order.
        let mut order: Vec<usize> = (0..n as usize).collect();
        let mut state = order_seed | 1;
        for i in (1..order.len()).rev() {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            order.swap(i, (state % (i as u64 + 1)) as usize);
        }
        let merged = sharded(d, m, n, &order, &threads);
        proptest::prop_assert!(std::fs::read(&merged).unwrap() == std::fs::read(&whole).unwrap(), "{m:?}, {n} shards, order {order:?}");
    }
}

/// `--fit lsq`: the shards carry the exact mass matrix, and `merge` solves the fit over the
/// whole set, giving the whole least-squares bake bit for bit, for 3 shards in any order.
#[test]
fn least_squares_shards_merge_to_the_whole_fit() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let whole = d.join("whole.exr");
    bake(&whole, &["--method", "doi-paper", "--fit", "lsq:0.25"]);
    let w = read_exr(&whole).unwrap();
    let shards: Vec<_> = (0..3)
        .map(|k| {
            let out = d.join(format!("l{k}.exr"));
            bake(
                &out,
                &[
                    "--method",
                    "doi-paper",
                    "--fit",
                    "lsq:0.25",
                    "--shard",
                    &format!("{k}/3"),
                    "--threads",
                    if k == 1 { "2" } else { "1" },
                ],
            );
            out.with_extension("lvacc")
        })
        .collect();
    for order in [[0, 1, 2], [2, 0, 1]] {
        let merged = d.join("m.exr");
        ok(&["merge", s(&shards[order[0]]), s(&shards[order[1]]), s(&shards[order[2]]), "-o", s(&merged)]);
        let m = read_exr(&merged).unwrap();
        assert!(
            std::fs::read(&merged).unwrap() == std::fs::read(&whole).unwrap(),
            "order {order:?}: the files differ"
        );
        assert_eq!(m.data(), w.data(), "order {order:?}");
        assert_eq!(m.weights(), w.weights());
        assert_eq!(m.metadata().method, w.metadata().method);
    }
    // The fit changes the values: the merge really solved (it is not Eq. 6's average).
    let avg = d.join("avg.exr");
    bake(&avg, &[]);
    assert_ne!(read_exr(&avg).unwrap().data(), w.data());
    // A least-squares shard and an average shard are different bakes.
    let other = d.join("a1.exr");
    bake(&other, &["--shard", "1/3"]);
    let e = run(&[
        "merge",
        s(&shards[0]),
        s(&other.with_extension("lvacc")),
        s(&shards[2]),
        "-o",
        s(&d.join("x.exr")),
    ])
    .unwrap_err();
    assert!(e.contains("same bake"), "{e}");
}

/// `--gradients basis`: the shards carry the exact gradient systems, and `merge` solves
/// them on the merged volume: the whole gradient bake's file, byte for byte. The central
/// estimator is refused with --shard in one line.
#[test]
fn basis_gradient_shards_merge_to_the_whole_bake() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let whole = d.join("whole.exr");
    bake(&whole, &["--method", "doi-paper", "--gradients", "basis"]);
    let shards: Vec<_> = (0..3)
        .map(|k| {
            let out = d.join(format!("g{k}.exr"));
            bake(&out, &["--method", "doi-paper", "--gradients", "basis", "--shard", &format!("{k}/3")]);
            out.with_extension("lvacc")
        })
        .collect();
    let merged = d.join("m.exr");
    ok(&["merge", s(&shards[2]), s(&shards[0]), s(&shards[1]), "-o", s(&merged)]);
    assert!(
        std::fs::read(&merged).unwrap() == std::fs::read(&whole).unwrap(),
        "merged gradient bake differs from the whole"
    );
}

/// `--gradients central`: each shard computes the central differences of its own nodes and
/// carries them in its shard file; the merge is the whole bake's file byte for byte, and
/// its gradients are not all zero (every shard's nodes arrived).
#[test]
fn central_gradient_shards_merge_to_the_whole_bake() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let whole = d.join("whole.exr");
    let central = ["--gradients", "central", "--method", "point"];
    bake(&whole, &central);
    let shards: Vec<_> = (0..3)
        .map(|k| {
            let out = d.join(format!("c{k}.exr"));
            let mut a = central.to_vec();
            let sh = format!("{k}/3");
            a.extend(["--shard", &sh]);
            bake(&out, &a);
            out.with_extension("lvacc")
        })
        .collect();
    let merged = d.join("m.exr");
    ok(&["merge", s(&shards[1]), s(&shards[2]), s(&shards[0]), "-o", s(&merged)]);
    assert!(
        std::fs::read(&merged).unwrap() == std::fs::read(&whole).unwrap(),
        "merged central-gradient bake differs from the whole"
    );
    let (_, g) = lightvol_volume::io::exr::read_exr_with_gradients(&merged).unwrap();
    let g = g.expect("gradients in the merged file");
    let nodes = 6 * 6 * 3;
    let per_node = g.data().len() / nodes;
    for third in 0..3 {
        let r = lightvol_core::shard::shard_range(nodes, (third, 3));
        assert!(
            g.data()[r.start * per_node..r.end * per_node].iter().any(|&v| v != 0.0),
            "shard {third}'s gradients are all zero"
        );
    }
    // Two shards that both claim a node's gradient (a mixed set) cannot pass as one.
    let e = run(&["merge", s(&shards[0]), s(&shards[0]), "-o", s(&d.join("x.exr"))]).unwrap_err();
    assert!(e.contains("twice"), "{e}");
}

/// An incomplete set lists the missing shards and writes nothing; a shard of another bake
/// (other seed) is refused; `--allow-partial` merges what is there.
#[test]
fn incomplete_and_mixed_sets_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    for k in [0, 2, 3] {
        bake(&d.join(format!("p{k}.exr")), &["--shard", &format!("{k}/5")]);
    }
    let out = d.join("out.exr");
    let p = |k: u32| d.join(format!("p{k}.lvacc"));
    let e = run(&["merge", s(&p(0)), s(&p(2)), s(&p(3)), "-o", s(&out)]).unwrap_err();
    assert!(e.contains("shards 1, 4 of 5 are missing"), "{e}");
    assert!(!out.exists() && !out.with_extension("exr.partial").exists());
    let other = d.join("other.exr");
    let mut a = vec!["bake", "builtin:maze", "-o", s(&other), "--shard", "1/5"];
    a.extend_from_slice(&["--samples", "8", "--res", "6,6,3", "--seed", "4", "--quiet", "--bounces=1"]);
    ok(&a);
    let e = run(&["merge", s(&p(0)), s(&other.with_extension("lvacc")), "-o", s(&out)]).unwrap_err();
    assert!(e.contains("does not belong to the same bake"), "{e}");
    assert!(!out.exists());
    ok(&["merge", s(&p(0)), s(&p(2)), "--allow-partial", "-o", s(&out)]);
    assert!(out.exists());
}

/// The same shard file twice (or an unsharded bake merged with itself) would count its
/// samples twice: refused, as is keeping the accumulator of a partial merge.
#[test]
fn the_same_samples_are_never_merged_twice() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let one = d.join("one.exr");
    bake(&one, &["--keep-accumulator"]);
    let out = d.join("out.exr");
    let e = run(&["merge", s(&one.with_extension("lvacc")), s(&one), "-o", s(&out)]).unwrap_err();
    assert!(e.contains("given twice"), "{e}");
    let p0 = d.join("p0.exr");
    bake(&p0, &["--shard", "0/2"]);
    let e = run(&[
        "merge",
        s(&p0.with_extension("lvacc")),
        "--allow-partial",
        "--keep-accumulator",
        "-o",
        s(&out),
    ])
    .unwrap_err();
    assert!(e.contains("--allow-partial"), "{e}");
    assert!(!out.exists());
}
