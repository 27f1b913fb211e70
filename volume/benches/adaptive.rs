//! Lookup cost of an adaptive octree volume against a uniform volume ([Oat05], "Adaptive
//! Octree Subdivision").
//!
//! `cargo bench -p lightvol-volume --bench adaptive` prints divan's table: the f32 hashed
//! lookup (`AdaptiveVolume::irradiance`), the f64 reference, and the uniform lookup of the
//! same field resampled at the finest level (`to_uniform`) as the baseline, all on the same
//! random queries. The volume: a 17³ base over a step field, refined to level 2 along the
//! step (9 coefficients).

use std::hint::black_box;
use std::sync::OnceLock;

use divan::counter::ItemsCount;
use lightvol_sh::lowdisc::SplitMix64;
use lightvol_volume::adaptive::level_grid;
use lightvol_volume::{
    AdaptiveVolume, GridSpec, IrradianceVolume, LevelSamples, OctreeParams, build_adaptive,
};

/// Queries per iteration.
const QUERIES: usize = 1 << 14;

struct Fixture {
    adaptive: AdaptiveVolume,
    uniform: IrradianceVolume,
    points: Vec<[f32; 3]>,
}

fn field(x: [f64; 3]) -> f64 {
    1.0 + 0.05 * x[0] + if x[0] + 0.5 * x[1] > 20.0 { 1.0 } else { 0.0 }
}

fn fixture() -> &'static Fixture {
    static F: OnceLock<Fixture> = OnceLock::new();
    F.get_or_init(|| {
        let spec = GridSpec::new([0.0; 3], [32.0; 3], [17; 3]).unwrap();
        let base = IrradianceVolume::from_fn(spec.clone(), 9, |x| vec![[field(x); 3]; 9]).unwrap();
        let params = OctreeParams { max_level: 2, ..OctreeParams::default() };
        let adaptive = build_adaptive(
            base,
            &params,
            |c| {
                Ok::<_, std::convert::Infallible>(
                    (0..c.cells().len()).map(|i| c.corner_change(i) / 0.1).collect(),
                )
            },
            |level, nodes| {
                let g = level_grid(&spec, level).unwrap();
                let mut s = LevelSamples::default();
                for n in nodes {
                    s.values.extend(std::iter::repeat_n(field(g.node_position(n[0], n[1], n[2])), 27));
                    s.weights.push(1.0);
                }
                Ok(s)
            },
        )
        .unwrap();
        let uniform = adaptive.to_uniform(None).unwrap();
        let mut rng = SplitMix64::new(2);
        let points = (0..QUERIES).map(|_| std::array::from_fn(|_| rng.range(0.0, 32.0) as f32)).collect();
        Fixture { adaptive, uniform, points }
    })
}

#[divan::bench(sample_count = 30)]
fn adaptive_f32(bencher: divan::Bencher<'_, '_>) {
    let f = fixture();
    bencher.counter(ItemsCount::new(QUERIES)).bench(|| {
        for p in &f.points {
            black_box(f.adaptive.irradiance(*p, [0.0, 0.0, 1.0]));
        }
    });
}

#[divan::bench(sample_count = 10)]
fn adaptive_f64_reference(bencher: divan::Bencher<'_, '_>) {
    let f = fixture();
    bencher.counter(ItemsCount::new(QUERIES)).bench(|| {
        for p in &f.points {
            black_box(f.adaptive.irradiance_reference(p.map(f64::from), [0.0, 0.0, 1.0]));
        }
    });
}

#[divan::bench(sample_count = 30)]
fn uniform_finest_baseline(bencher: divan::Bencher<'_, '_>) {
    let f = fixture();
    bencher.counter(ItemsCount::new(QUERIES)).bench(|| {
        for p in &f.points {
            black_box(f.uniform.irradiance(*p, [0.0, 0.0, 1.0]));
        }
    });
}

fn main() {
    let f = fixture();
    eprintln!(
        "adaptive: {} stored nodes, {} bytes (+{} index); uniform finest: {} nodes, {} bytes",
        f.adaptive.stored_nodes(),
        f.adaptive.memory_bytes(),
        f.adaptive.index_bytes(),
        f.uniform.spec().node_count(),
        f.uniform.memory_bytes()
    );
    divan::main();
}
