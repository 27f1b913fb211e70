//! `doi` against `point` at equal samples on the built-in city (its recommended grid):
//! wall time per bake; the ray counts are printed once (ratio of rays traced).

use lightvol_core::samples::samples;

use divan::Bencher;
use lightvol_core::progress::BakeControl;
use lightvol_sampler::{BakeSettings, Method, bake};
use lightvol_scene::{Tracer, Transport, TransportSettings, builtin};

fn main() {
    let c = builtin::city();
    let tracer = Tracer::new(&c.scene);
    let t = Transport::new(&c.scene, &tracer, TransportSettings::default());
    let mut rays = Vec::new();
    for m in [Method::Point, Method::Prefilter, Method::DoiPaper] {
        let s = BakeSettings { method: m, samples: samples(SAMPLES), ..Default::default() };
        let out = bake(&t, &c.grid, &s, &BakeControl::default()).unwrap();
        eprintln!("{m:?}: {}", out.stats);
        rays.push(out.stats.rays.total() as f64);
    }
    eprintln!("rays doi/point = {:.3}, prefilter/point = {:.3}", rays[2] / rays[0], rays[1] / rays[0]);
    divan::main();
}

/// Samples per cell (doi, prefilter) or per node (point).
const SAMPLES: u32 = 64;

#[divan::bench(args = ["point", "prefilter", "doi"], sample_count = 3, sample_size = 1)]
fn city(bencher: Bencher<'_, '_>, method: &str) {
    let c = builtin::city();
    let tracer = Tracer::new(&c.scene);
    let t = Transport::new(&c.scene, &tracer, TransportSettings::default());
    let s = BakeSettings { method: method.parse().unwrap(), samples: samples(SAMPLES), ..Default::default() };
    bencher.bench(|| bake(&t, &c.grid, &s, &BakeControl::default()).unwrap().stats.rays.total());
}
