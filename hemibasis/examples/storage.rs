//! Measures the irradiance error that 8-bit encoding ([Ish11] §2.2.3), BC1 and BC7 add to
//! a realistic coefficient map, for every basis of Table 3.1 that is compiled in.
//!
//! ```text
//! cargo run --release -p lightvol-hemibasis --example storage -- [--size 64] [--dc-peak 0.8] [--srgb]
//! ```

use lightvol_hemibasis::bc::{BlockFormat, stored_map_error};
use lightvol_hemibasis::encode::{DcTransfer, Encoding};
use lightvol_hemibasis::map::sky_test_map;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let value = |flag: &str, default: f64| {
        args.iter()
            .position(|a| a == flag)
            .and_then(|i| args.get(i + 1))
            .map_or(default, |v| v.parse().unwrap_or_else(|_| panic!("{flag} needs a number, got {v}")))
    };
    let size = value("--size", 64.0) as usize;
    let dc_peak = value("--dc-peak", 0.8);
    let dc = if args.iter().any(|a| a == "--srgb") { DcTransfer::Srgb } else { DcTransfer::Gamma22 };
    let enc = Encoding { dc, ..Encoding::default() };
    println!("map {size}x{size}, DC peak {dc_peak}, DC transfer {dc:?}, range {}", enc.range);
    println!("| basis | clamped (DC/AC) | 8-bit rel RMS | BC1 rel RMS | BC7 rel RMS |");
    println!("| --- | --- | --- | --- | --- |");
    for (family, count) in lightvol_hemibasis::LIGHTMAP_BASES {
        let Some(basis) = lightvol_hemibasis::by_family(family, count) else { continue };
        let map = sky_test_map(basis.as_ref(), size, size, dc_peak);
        let (e8, clamped) = stored_map_error(basis.as_ref(), &map, &enc, None);
        let (e1, _) = stored_map_error(basis.as_ref(), &map, &enc, Some(BlockFormat::Bc1));
        let (e7, _) = stored_map_error(basis.as_ref(), &map, &enc, Some(BlockFormat::Bc7));
        println!(
            "| {} | {}/{} | {:.3}% | {:.2}% | {:.3}% |",
            basis.tag(),
            clamped.dc_clamped,
            clamped.ac_clamped,
            100.0 * e8.rel_rms,
            100.0 * e1.rel_rms,
            100.0 * e7.rel_rms
        );
    }
}
