//! Lookup throughput of a 64³, 9-coefficient RGB volume (README, "Performance"), and a
//! roofline estimate measured in the same run.
//!
//! `cargo bench -p lightvol-volume` prints divan's table (lookups/s as items/s):
//! scalar vs batched, random vs coherent query order, batched on 1 and 2 rayon threads;
//! then a streaming copy (memory bandwidth) and an FMA-free multiply-add loop (arithmetic
//! peak of this build), and finally the roofline table: bytes and flops per lookup, the
//! bound each implies, and the fraction of the roofline each lookup variant reaches.

use std::hint::black_box;
use std::sync::OnceLock;
use std::time::Instant;

use divan::counter::{BytesCount, ItemsCount};
use lightvol_sh::lowdisc::SplitMix64;
use lightvol_sh::sampling::sample_uniform_sphere;
use lightvol_volume::{GridSpec, IrradianceVolume};

/// Queries per benchmark iteration.
const QUERIES: usize = 1 << 16;
/// Nodes per axis.
const RES: u32 = 64;
/// Bytes per node of a 9-coefficient RGB f32 volume.
const NODE_BYTES: usize = 9 * 3 * 4;
/// f32 elements in the bandwidth buffers (2 × 128 MiB, far beyond any cache).
const STREAM_LEN: usize = 32 << 20;

struct Fixture {
    vol: IrradianceVolume,
    random: (Vec<[f32; 3]>, Vec<[f32; 3]>),
    coherent: (Vec<[f32; 3]>, Vec<[f32; 3]>),
    pools: [rayon::ThreadPool; 2],
}

fn fixture() -> &'static Fixture {
    static F: OnceLock<Fixture> = OnceLock::new();
    F.get_or_init(|| {
        let spec = GridSpec::new([0.0; 3], [63.0; 3], [RES; 3]).unwrap();
        let mut rng = SplitMix64::new(1);
        let n = spec.node_count();
        let data = (0..n * 27).map(|_| rng.range(-1.0, 1.0) as f32).collect();
        let vol = IrradianceVolume::new(spec, 9, data, vec![1.0; n]).unwrap();
        let normals: Vec<[f32; 3]> = (0..QUERIES)
            .map(|_| sample_uniform_sphere([rng.next_f64(), rng.next_f64()]).map(|v| v as f32))
            .collect();
        let random_pts = (0..QUERIES).map(|_| std::array::from_fn(|_| rng.range(0.0, 63.0) as f32)).collect();
        // Coherent: a raster walk through a 64 × 32 × 32 block of sample points spaced half
        // a cell apart (a screen-space-like traversal).
        let coherent_pts = (0..QUERIES)
            .map(|q| {
                let (x, y, z) = (q % 64, (q / 64) % 32, q / (64 * 32));
                [0.5 * x as f32 + 0.25, 0.5 * y as f32 + 0.25, 0.5 * z as f32 + 0.25]
            })
            .collect();
        let pool = |t| rayon::ThreadPoolBuilder::new().num_threads(t).build().unwrap();
        Fixture {
            vol,
            random: (random_pts, normals.clone()),
            coherent: (coherent_pts, normals),
            pools: [pool(1), pool(2)],
        }
    })
}

fn queries(order: &str) -> &'static (Vec<[f32; 3]>, Vec<[f32; 3]>) {
    let f = fixture();
    if order == "random" { &f.random } else { &f.coherent }
}

fn scalar_pass(vol: &IrradianceVolume, q: &(Vec<[f32; 3]>, Vec<[f32; 3]>), out: &mut [[f32; 3]]) {
    for ((p, n), o) in q.0.iter().zip(&q.1).zip(out.iter_mut()) {
        *o = vol.irradiance(*p, *n);
    }
}

#[divan::bench(args = ["random", "coherent"], sample_count = 40)]
fn scalar(bencher: divan::Bencher<'_, '_>, order: &str) {
    let f = fixture();
    let q = queries(order);
    let mut out = vec![[0.0f32; 3]; QUERIES];
    bencher.counter(ItemsCount::new(QUERIES)).bench_local(|| {
        scalar_pass(&f.vol, q, &mut out);
        black_box(&out);
    });
}

#[divan::bench(args = ["random", "coherent"], sample_count = 40)]
fn batched_serial(bencher: divan::Bencher<'_, '_>, order: &str) {
    let f = fixture();
    let q = queries(order);
    let mut out = vec![[0.0f32; 3]; QUERIES];
    bencher.counter(ItemsCount::new(QUERIES)).bench_local(|| {
        f.vol.irradiance_batch_serial(&q.0, &q.1, &mut out).unwrap();
        black_box(&out);
    });
}

#[divan::bench(args = ["random/1", "random/2", "coherent/1", "coherent/2"], sample_count = 40)]
fn batched_rayon(bencher: divan::Bencher<'_, '_>, order_threads: &str) {
    let f = fixture();
    let (order, threads) = order_threads.split_once('/').unwrap();
    let q = queries(order);
    let pool = &f.pools[if threads == "1" { 0 } else { 1 }];
    let mut out = vec![[0.0f32; 3]; QUERIES];
    bencher.counter(ItemsCount::new(QUERIES)).bench_local(|| {
        pool.install(|| f.vol.irradiance_batch(&q.0, &q.1, &mut out).unwrap());
        black_box(&out);
    });
}

/// Streaming copy: reads and writes `STREAM_LEN` f32 (bytes counted: read + write).
#[divan::bench(sample_count = 10)]
fn stream_copy(bencher: divan::Bencher<'_, '_>) {
    let src = vec![1.0f32; STREAM_LEN];
    let mut dst = vec![0.0f32; STREAM_LEN];
    bencher.counter(BytesCount::new(2 * 4 * STREAM_LEN)).bench_local(|| {
        dst.copy_from_slice(black_box(&src));
        black_box(&dst);
    });
}

/// Flops per iteration of [`peak_kernel`]: 64 lanes × (mul + add) × 4096 steps.
const PEAK_FLOPS: usize = 64 * 2 * 4096;

/// Independent multiply-adds on 64 f32 lanes (vectorisable, no FMA contraction, as in the
/// lookup itself): the attainable arithmetic peak of this build on one core.
fn peak_kernel(a: f32, b: f32) -> [f32; 64] {
    let mut acc = [0.0f32; 64];
    for (i, v) in acc.iter_mut().enumerate() {
        *v = i as f32;
    }
    for _ in 0..4096 {
        for v in acc.iter_mut() {
            *v = *v * a + b;
        }
    }
    acc
}

#[divan::bench(sample_count = 20)]
fn arithmetic_peak(bencher: divan::Bencher<'_, '_>) {
    bencher
        .counter(ItemsCount::new(PEAK_FLOPS))
        .bench_local(|| black_box(peak_kernel(black_box(0.999), black_box(0.001))));
}

/// Fastest of `reps` runs of `f`, in seconds (the build machine is shared, so the
/// minimum is the least disturbed estimate of both bandwidth and lookup rate).
fn time(reps: usize, mut f: impl FnMut()) -> f64 {
    f();
    (0..reps)
        .map(|_| {
            let s = Instant::now();
            f();
            s.elapsed().as_secs_f64()
        })
        .fold(f64::INFINITY, f64::min)
}

/// Bytes a lookup touches: 8 corner nodes of 108 bytes, the query (point + normal, 24 B)
/// and the result (12 B), with no reuse between lookups (the random-order worst case).
const BYTES_PER_LOOKUP: f64 = (8 * NODE_BYTES + 24 + 12) as f64;
/// Flops of one 9-coefficient lookup in our implementation: grid coordinates and
/// fractions (3 × 4), 8 trilinear weights (3 × 2 + 8 × 2), interpolation of 27 floats over
/// 8 corners (27 + 7 × 27 × 2), the 9-term basis (about 20), and shading (9 × 7).
const FLOPS_PER_LOOKUP: f64 = (12 + 22 + 27 + 7 * 27 * 2 + 20 + 9 * 7) as f64;

fn roofline() {
    let f = fixture();
    let src = vec![1.0f32; STREAM_LEN];
    let mut dst = vec![0.0f32; STREAM_LEN];
    // black_box on the destination too: otherwise the copy is a dead store and vanishes.
    let bw = (2 * 4 * STREAM_LEN) as f64
        / time(5, || {
            dst.copy_from_slice(black_box(&src));
            black_box(&mut dst);
        });
    let peak = PEAK_FLOPS as f64
        / time(11, || {
            black_box(peak_kernel(black_box(0.999), black_box(0.001)));
        });
    let mut out = vec![[0.0f32; 3]; QUERIES];
    println!();
    println!("roofline ({QUERIES} lookups per run, 64^3 nodes, 9 coeffs RGB, f32)");
    println!("  streaming copy bandwidth : {:8.2} GB/s", bw / 1e9);
    println!("  multiply-add peak (1 core): {:8.2} GFLOP/s", peak / 1e9);
    println!("  bytes / lookup (no reuse) : {BYTES_PER_LOOKUP:.0}   flops / lookup: {FLOPS_PER_LOOKUP:.0}");
    let mem_bound = bw / BYTES_PER_LOOKUP;
    println!(
        "  bounds: memory {:.2} M/s, compute {:.2} M/s per core",
        mem_bound / 1e6,
        peak / FLOPS_PER_LOOKUP / 1e6
    );
    println!("  variant                      Mlookups/s  roofline  fraction");
    for (name, order, threads) in [
        ("scalar random", "random", 0),
        ("scalar coherent", "coherent", 0),
        ("batched random 1 thread", "random", 1),
        ("batched coherent 1 thread", "coherent", 1),
        ("batched random 2 threads", "random", 2),
        ("batched coherent 2 threads", "coherent", 2),
    ] {
        let q = queries(order);
        let secs = if threads == 0 {
            time(11, || scalar_pass(&f.vol, q, &mut out))
        } else {
            let pool = &f.pools[threads - 1];
            time(11, || pool.install(|| f.vol.irradiance_batch(&q.0, &q.1, &mut out).unwrap()))
        };
        let rate = QUERIES as f64 / secs;
        let cores = threads.max(1) as f64;
        // Memory bandwidth is shared by the cores; arithmetic peak scales with them.
        let bound = mem_bound.min(cores * peak / FLOPS_PER_LOOKUP);
        println!("  {name:<28} {:10.2} {:9.2} {:8.1}%", rate / 1e6, bound / 1e6, 100.0 * rate / bound);
    }
}

fn main() {
    divan::main();
    roofline();
}
