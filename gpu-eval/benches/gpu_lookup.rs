//! Volume lookups: GPU dispatch (upload excluded, wait included) against the CPU batch
//! lookup on the same volume and queries, measured in the same run.
//!
//! `cargo bench -p lightvol-gpu --bench gpu_lookup`. Without a Vulkan device the GPU
//! benchmarks print the skip line and measure nothing. On lavapipe the GPU figures are a
//! functional check only; `examples/lookup_throughput.rs` reports GPU-timestamp rates.

use std::sync::LazyLock;

use divan::Bencher;
use divan::counter::ItemsCount;
use lightvol_gpu::lookup::Quantity;
use lightvol_gpu::synthetic::{random_queries, smooth_random_volume};
use lightvol_gpu::{GpuContext, VolumeLookup, gpu_or_skip};
use lightvol_volume::{GridSpec, IrradianceVolume};

const SIZES: [usize; 2] = [4096, 65536];

static VOLUME: LazyLock<IrradianceVolume> = LazyLock::new(|| {
    let spec = GridSpec::new([0.0; 3], [1.0; 3], [32; 3]).expect("valid grid");
    smooth_random_volume(spec, 9, 1).expect("valid volume")
});

static GPU: LazyLock<Option<GpuContext>> = LazyLock::new(gpu_or_skip);

fn queries(n: usize) -> (Vec<[f32; 3]>, Vec<[f32; 3]>) {
    random_queries(VOLUME.spec(), n, 0.0, 3)
}

#[divan::bench(args = SIZES)]
fn gpu_dispatch(bencher: Bencher<'_, '_>, n: usize) {
    let Some(ctx) = GPU.as_ref() else { return };
    let lookup = VolumeLookup::new(ctx, &VOLUME).expect("upload");
    let (p, d) = queries(n);
    let mut batch = lookup.batch(&p, &d).expect("batch");
    bencher
        .counter(ItemsCount::new(n))
        .bench_local(|| lookup.run(&mut batch, Quantity::Irradiance, 1).expect("dispatch"));
}

#[divan::bench(args = SIZES)]
fn cpu_batch(bencher: Bencher<'_, '_>, n: usize) {
    let (p, d) = queries(n);
    let mut out = vec![[0.0f32; 3]; n];
    bencher
        .counter(ItemsCount::new(n))
        .bench_local(|| VOLUME.irradiance_batch(&p, &d, &mut out).expect("lookup"));
}

fn main() {
    divan::main();
}
