//! Shard merging, as a property: for any split of a sample set into shards and any merge
//! order, merging the shards' accumulators equals accumulating all samples at once, bit for
//! bit (the sums are fixed-point integers), and the exact sums agree with plain f64 sums to
//! f64 rounding.

use lightvol_sh::eval::eval_basis;
use lightvol_sh::lowdisc::{SplitMix64, hash2};
use lightvol_sh::sampling::sample_uniform_sphere;
use lightvol_volume::{Accumulator, GridSpec};
use proptest::prelude::*;
use proptest::test_runner::{Config, RngSeed};

/// Two f64 sums of the same ≤ 400 terms in different orders differ by at most a few
/// hundred ulps of the largest partial sum; 1e-12 of the largest sum leaves room for that.
const MERGE_REL_TOL: f64 = 1e-12;

fn spec() -> GridSpec {
    GridSpec::new([-1.0, 0.0, 0.0], [1.0, 1.0, 2.0], [3, 3, 4]).unwrap()
}

/// Deterministic sample `s`: position, radiance / pdf, 9 basis values.
fn sample(s: u64) -> ([f64; 3], [f64; 3], [f64; 9]) {
    let mut r = SplitMix64::new(hash2(99, s));
    let p = [r.range(-1.0, 1.0), r.range(0.0, 1.0), r.range(0.0, 2.0)];
    let d = sample_uniform_sphere([r.next_f64(), r.next_f64()]);
    let l = [r.range(0.0, 5.0), r.range(0.0, 5.0), r.range(0.0, 5.0)].map(|v| 4.0 * std::f64::consts::PI * v);
    (p, l, eval_basis(d))
}

proptest! {
    #![proptest_config(Config { cases: 48, rng_seed: RngSeed::Fixed(5), failure_persistence: None, ..Config::default() })]

    #[test]
    fn any_shard_split_merges_to_the_whole(
        shard_of in prop::collection::vec(0usize..4, 1..400),
        order in Just((0..4usize).collect::<Vec<_>>()).prop_shuffle(),
    ) {
        let mut whole = Accumulator::new(spec(), 9).unwrap();
        let mut shards: Vec<Accumulator> = (0..4).map(|_| Accumulator::new(spec(), 9).unwrap()).collect();
        for (s, &k) in shard_of.iter().enumerate() {
            let (p, l, y) = sample(s as u64);
            whole.add_sample(p, l, &y);
            shards[k].add_sample(p, l, &y);
            if s % 5 == 0 {
                whole.add_outside(s % spec().node_count(), 0.25);
                shards[k].add_outside(s % spec().node_count(), 0.25);
            }
        }
        let mut merged = shards[order[0]].clone();
        for &k in &order[1..] {
            merged.merge(&shards[k]).unwrap();
        }
        // Exact: the merge in any order is the whole, bit for bit.
        prop_assert_eq!(&merged, &whole);
        // And the exact sums are the f64 sums to rounding.
        let mut plain = vec![0.0f64; whole.numerator().len()];
        for (s, _) in shard_of.iter().enumerate() {
            let (p, l, y) = sample(s as u64);
            let (nodes, w) = spec().trilinear(p);
            for c in 0..8 {
                if w[c] > 0.0 {
                    for j in 0..9 {
                        for ch in 0..3 {
                            plain[nodes[c] * 27 + 3 * j + ch] += w[c] * l[ch] * y[j];
                        }
                    }
                }
            }
        }
        let num = whole.numerator();
        let scale = num.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        for (a, b) in num.iter().zip(&plain) {
            prop_assert!((a - b).abs() <= MERGE_REL_TOL * scale);
        }
        prop_assert_eq!(merged.contributions(), whole.contributions());
        // Commutative, bit for bit.
        let mut ab = shards[1].clone();
        ab.merge(&shards[2]).unwrap();
        let mut ba = shards[2].clone();
        ba.merge(&shards[1]).unwrap();
        prop_assert_eq!(ab, ba);
    }
}
