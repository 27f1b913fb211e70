//! Evaluation and conversion speed of the hemispherical bases, relative to SH in the same run.
//!
//! `cargo bench -p lightvol-hemibasis`

use divan::{Bencher, black_box};
use lightvol_hemibasis::by_name;
use lightvol_hemibasis::imse::table_bases;

fn main() {
    divan::main();
}

const NAMES: &[(&str, usize)] =
    &[("sh", 9), ("hl2", 3), ("hsh", 9), ("makhotkin", 9), ("zernike", 6), ("hbasis", 6), ("hbasis_mod", 6)];

fn dirs() -> Vec<[f32; 3]> {
    (0..256)
        .map(|i| {
            let z = (i as f32 + 0.5) / 256.0;
            let phi = i as f32 * 2.399_963;
            let s = (1.0 - z * z).sqrt();
            [s * phi.cos(), s * phi.sin(), z]
        })
        .collect()
}

/// Evaluates 256 directions (f32), the per-pixel shader work.
#[divan::bench(args = NAMES.iter().map(|(n, k)| format!("{n}{k}")))]
fn eval_f32(bencher: Bencher<'_, '_>, tag: &str) {
    let Some(b) = NAMES.iter().find(|(n, k)| format!("{n}{k}") == tag).and_then(|(n, k)| by_name(n, *k))
    else {
        return;
    };
    let d = dirs();
    let mut out = vec![0.0f32; b.len()];
    bencher.bench_local(|| {
        for dir in &d {
            b.eval_f32(black_box(*dir), &mut out);
            black_box(&out);
        }
    });
}

/// Derives the SH-irradiance conversion matrices of every table basis (done once per bake).
#[divan::bench]
fn conversion_matrices() -> usize {
    table_bases().iter().map(|b| b.sh_irradiance_matrix(3).rows()).sum()
}

/// Encodes a 64 × 64 SH9 map to 8-bit planes ([Ish11] §2.2.3).
#[divan::bench]
fn encode_map_64(bencher: Bencher<'_, '_>) {
    let basis = lightvol_hemibasis::ShBasis::new(3);
    let map = lightvol_hemibasis::map::sky_test_map(&basis, 64, 64, 0.8);
    let enc = lightvol_hemibasis::encode::Encoding::default();
    bencher.bench_local(|| black_box(enc.encode_map(&basis, black_box(&map))));
}

/// Block-compresses one 64 × 64 plane, BC1 against BC7 in the same run.
#[cfg(feature = "bc")]
#[divan::bench(args = ["bc1", "bc7"])]
fn compress_plane_64(bencher: Bencher<'_, '_>, format: &str) {
    use lightvol_hemibasis::bc::{BlockFormat, compress};
    let basis = lightvol_hemibasis::ShBasis::new(3);
    let map = lightvol_hemibasis::map::sky_test_map(&basis, 64, 64, 0.8);
    let (planes, _) = lightvol_hemibasis::encode::Encoding::default().encode_map(&basis, &map);
    let f = if format == "bc1" { BlockFormat::Bc1 } else { BlockFormat::Bc7 };
    bencher.bench_local(|| black_box(compress(black_box(&planes[1]), f)));
}
