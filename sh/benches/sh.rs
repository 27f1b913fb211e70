//! lightvol-sh benchmarks (divan). Run: `cargo bench -p lightvol-sh`.
//!
//! Each group has a baseline measured in the same run (the textbook reference for
//! evaluation, the quadrature build for rotation), so results can be read as ratios.

use divan::{Bencher, black_box};
use glam::DQuat;
use lightvol_sh::coeffs::Sh;
use lightvol_sh::eval::{eval_basis, eval_recurrence};
use lightvol_sh::lowdisc::SplitMix64;
use lightvol_sh::project::ProjectionAccumulator;
use lightvol_sh::reference::sh_reference_all;
use lightvol_sh::rotate::ShRotation;
use lightvol_sh::sampling::sample_uniform_sphere;

fn main() {
    divan::main();
}

/// 1024 random unit directions, so that each iteration is not a constant.
fn dirs<T: Copy>(conv: impl Fn(f64) -> T) -> Vec<[T; 3]> {
    let mut r = SplitMix64::new(1);
    (0..1024).map(|_| sample_uniform_sphere([r.next_f64(), r.next_f64()]).map(&conv)).collect()
}

const PER_ITER: usize = 1024;

#[divan::bench(consts = [9, 16, 36, 64], counter = divan::counter::ItemsCount::new(PER_ITER))]
fn eval_f32<const N: usize>(b: Bencher<'_, '_>) {
    let d = dirs(|v| v as f32);
    b.bench_local(|| {
        let mut acc = 0.0f32;
        for &dir in &d {
            let y: [f32; N] = eval_basis(black_box(dir));
            acc += y[N - 1];
        }
        acc
    });
}

#[divan::bench(consts = [9, 16, 36, 64], counter = divan::counter::ItemsCount::new(PER_ITER))]
fn eval_f64<const N: usize>(b: Bencher<'_, '_>) {
    let d = dirs(|v| v);
    b.bench_local(|| {
        let mut acc = 0.0f64;
        for &dir in &d {
            let y: [f64; N] = eval_basis(black_box(dir));
            acc += y[N - 1];
        }
        acc
    });
}

/// Baseline: the same values by the runtime recurrence loop.
#[divan::bench(consts = [9, 64], counter = divan::counter::ItemsCount::new(PER_ITER))]
fn eval_f64_recurrence_loop<const N: usize>(b: Bencher<'_, '_>) {
    let d = dirs(|v| v);
    b.bench_local(|| {
        let mut acc = 0.0f64;
        let mut y = [0.0f64; N];
        for &dir in &d {
            eval_recurrence(N.isqrt(), black_box(dir), &mut y);
            acc += y[N - 1];
        }
        acc
    });
}

/// Baseline: the textbook reference (angles, factorials, Legendre recurrences).
#[divan::bench(consts = [9], counter = divan::counter::ItemsCount::new(PER_ITER))]
fn eval_f64_reference<const N: usize>(b: Bencher<'_, '_>) {
    let d = dirs(|v| v);
    b.bench_local(|| {
        let mut acc = 0.0f64;
        for &dir in &d {
            acc += sh_reference_all(N.isqrt(), black_box(dir))[N - 1];
        }
        acc
    });
}

#[divan::bench(consts = [9, 16, 36])]
fn rotation_apply_f32<const N: usize>(b: Bencher<'_, '_>) {
    let rot = ShRotation::from_quat(N.isqrt(), DQuat::from_euler(glam::EulerRot::ZYX, 0.3, 1.1, -0.7));
    let mut r = SplitMix64::new(2);
    let f = Sh::<f32, N>(core::array::from_fn(|_| r.next_f64() as f32));
    b.bench_local(|| rot.apply(black_box(&f)));
}

#[divan::bench(consts = [9, 16, 36])]
fn rotation_apply_f64<const N: usize>(b: Bencher<'_, '_>) {
    let rot = ShRotation::from_quat(N.isqrt(), DQuat::from_euler(glam::EulerRot::ZYX, 0.3, 1.1, -0.7));
    let mut r = SplitMix64::new(2);
    let f = Sh::<f64, N>(core::array::from_fn(|_| r.next_f64()));
    b.bench_local(|| rot.apply(black_box(&f)));
}

#[divan::bench(consts = [9, 16, 36])]
fn rotation_build<const N: usize>(b: Bencher<'_, '_>) {
    let q = DQuat::from_euler(glam::EulerRot::ZYX, 0.3, 1.1, -0.7);
    b.bench_local(|| ShRotation::from_quat(N.isqrt(), black_box(q)));
}

/// Projection throughput: RGB samples into 9 and 16 coefficients (f64 accumulation).
#[divan::bench(consts = [9, 16], counter = divan::counter::ItemsCount::new(PER_ITER))]
fn project_samples<const N: usize>(b: Bencher<'_, '_>) {
    let d = dirs(|v| v);
    b.bench_local(|| {
        let mut acc = ProjectionAccumulator::<N>::new();
        for &dir in &d {
            acc.add(dir, [1.0, 0.5, 0.25], 2.0);
        }
        acc.finish()
    });
}
