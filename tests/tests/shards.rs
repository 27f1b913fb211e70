//! Sharded bakes on a small scene: whatever the shard count, the order the shards are
//! merged in and the thread count, the merged volume is the whole bake bit for bit; `merge`
//! refuses incomplete and mixed sets in one line and writes nothing. (`--shard auto` and
//! the cluster verbs are tested with the binary in `bake-cli/tests/cluster.rs`.)

mod common;

use common::{ok, run, s};
use lightvol_volume::exr_io::read_exr;
use std::path::Path;

/// The small bake every case shares (maze, 6×6×3 nodes, 8 samples per cell).
const BAKE: [&str; 8] = ["--samples", "8", "--res", "6,6,3", "--seed", "3", "--quiet", "--bounces=1"];

fn bake(out: &Path, extra: &[&str]) {
    let mut a = vec!["bake", "builtin:maze", "-o", s(out)];
    a.extend_from_slice(&BAKE);
    a.extend_from_slice(extra);
    ok(&a);
}

/// Whole bake = 1, 3 and 7 shards merged in forward, reverse and shuffled order = 1 and 2
/// threads: identical coefficients, weights and metadata.
#[test]
fn any_shard_count_order_and_thread_count_gives_the_whole_bake() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let whole = d.join("whole.exr");
    bake(&whole, &["--threads", "1"]);
    let w = read_exr(&whole).unwrap();
    let two = d.join("two.exr");
    bake(&two, &["--threads", "2"]);
    assert!(std::fs::read(&two).unwrap() == std::fs::read(&whole).unwrap(), "1 and 2 threads differ");
    for n in [1u32, 3, 7] {
        let mut shards = Vec::new();
        for k in 0..n {
            let out = d.join(format!("s{n}_{k}.exr"));
            let threads = if k % 2 == 0 { "1" } else { "2" };
            bake(&out, &["--shard", &format!("{k}/{n}"), "--threads", threads]);
            shards.push(out.with_extension("lvacc"));
        }
        let orders: Vec<Vec<usize>> = vec![
            (0..n as usize).collect(),
            (0..n as usize).rev().collect(),
            (0..n as usize).map(|i| (i * 5 + 2) % n as usize).collect(),
        ];
        for (o, order) in orders.iter().enumerate() {
            let merged = d.join(format!("m{n}_{o}.exr"));
            let mut a = vec!["merge".to_owned()];
            a.extend(order.iter().map(|&i| s(&shards[i]).to_owned()));
            a.extend(["-o".to_owned(), s(&merged).to_owned()]);
            ok(&a.iter().map(String::as_str).collect::<Vec<_>>());
            let m = read_exr(&merged).unwrap();
            assert!(
                std::fs::read(&merged).unwrap() == std::fs::read(&whole).unwrap(),
                "{n} shards, order {order:?}: the files differ"
            );
            assert_eq!(m.data(), w.data(), "{n} shards, order {order:?}");
            assert_eq!(m.weights(), w.weights());
            assert_eq!((m.metadata().shard_index, m.metadata().shard_count), (0, 1));
            assert_eq!(m.metadata().samples, w.metadata().samples);
        }
    }
}

proptest::proptest! {
    #![proptest_config(proptest::test_runner::Config {
        cases: 12,
        rng_seed: proptest::test_runner::RngSeed::Fixed(17),
        failure_persistence: None,
        ..proptest::test_runner::Config::default()
    })]

    /// As a property: for any shard count 1..=7, any merge order and any thread count per
    /// shard, with either node fit, the merged file is the whole bake's file.
    #[test]
    fn merged_file_is_the_whole_file_for_any_split(
        n in 1u32..=7,
        order_seed in proptest::prelude::any::<u64>(),
        threads in proptest::collection::vec(1u32..=2, 7),
        lsq in proptest::prelude::any::<bool>(),
    ) {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let fit: &[&str] = if lsq { &["--fit", "lsq:0.25"] } else { &[] };
        let whole = d.join("whole.exr");
        bake(&whole, fit);
        let mut shards: Vec<std::path::PathBuf> = (0..n)
            .map(|k| {
                let out = d.join(format!("s{k}.exr"));
                let t = threads[k as usize].to_string();
                let mut extra = vec!["--shard".to_owned(), format!("{k}/{n}"), "--threads".to_owned(), t];
                extra.extend(fit.iter().map(|x| (*x).to_owned()));
                bake(&out, &extra.iter().map(String::as_str).collect::<Vec<_>>());
                out.with_extension("lvacc")
            })
            .collect();
        // A seeded shuffle of the merge order.
        let mut state = order_seed | 1;
        for i in (1..shards.len()).rev() {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            shards.swap(i, (state % (i as u64 + 1)) as usize);
        }
        let merged = d.join("merged.exr");
        let mut a = vec!["merge".to_owned()];
        a.extend(shards.iter().map(|p| s(p).to_owned()));
        a.extend(["-o".to_owned(), s(&merged).to_owned()]);
        ok(&a.iter().map(String::as_str).collect::<Vec<_>>());
        proptest::prop_assert!(std::fs::read(&merged).unwrap() == std::fs::read(&whole).unwrap(), "{n} shards, lsq {lsq}");
    }
}

/// `--fit lsq`: the shards carry the exact mass matrix, and `merge` solves the fit over the
/// whole set, giving the whole least-squares bake bit for bit, for 3 shards in any order.
#[test]
fn least_squares_shards_merge_to_the_whole_fit() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let whole = d.join("whole.exr");
    bake(&whole, &["--fit", "lsq:0.25"]);
    let w = read_exr(&whole).unwrap();
    let shards: Vec<_> = (0..3)
        .map(|k| {
            let out = d.join(format!("l{k}.exr"));
            bake(
                &out,
                &[
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
    bake(&whole, &["--gradients", "basis"]);
    let shards: Vec<_> = (0..3)
        .map(|k| {
            let out = d.join(format!("g{k}.exr"));
            bake(&out, &["--gradients", "basis", "--shard", &format!("{k}/3")]);
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
    let (_, g) = lightvol_volume::exr_io::read_exr_with_gradients(&merged).unwrap();
    let g = g.expect("gradients in the merged file");
    let nodes = 6 * 6 * 3;
    let per_node = g.data().len() / nodes;
    for third in 0..3 {
        let r = lightvol_sampler::shard::shard_range(nodes, (third, 3));
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
