//! Irradiance error of every storage encoding on a smooth, physically valid 32³ volume.
//!
//! `cargo run --release -p lightvol-volume --example encoding_errors`
//!
//! Each node holds the SH projection of a non-negative radiance `L(ω) = a (1 + 0.6 ω·d) +
//! ωᵀQω` whose brightness `a`, dominant direction `d` and quadratic part vary smoothly over
//! the box (a bright region near one corner, a dim one near the other: a 25:1 range, like
//! an interior with a window). For each encoding the table gives the max and RMS
//! irradiance error over 64 random normals per node, the analytic bound, and the max error
//! relative to the largest irradiance and to each node's own mean irradiance.

use lightvol_sh::project::project_fn_dyn;
use lightvol_volume::encode::{Encoding, irradiance_error};
use lightvol_volume::{GridSpec, IrradianceVolume};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let spec = GridSpec::new([0.0; 3], [8.0, 4.0, 8.0], [32, 32, 32])?;
    let vol = IrradianceVolume::from_fn(spec, 9, |x| {
        let t = (x[0] + x[2]) / 16.0; // 0 at one corner, 1 at the other
        let a = 0.2 + 4.8 * t * t;
        let d = {
            let v = [1.0 - t, 0.5, t];
            let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
            v.map(|c| c / n)
        };
        let q = 0.05 * a * (x[1] / 4.0);
        let tint = [1.0, 0.9 - 0.2 * t, 0.7 + 0.2 * t];
        let f = |w: [f64; 3]| {
            a * (1.0 + 0.6 * (w[0] * d[0] + w[1] * d[1] + w[2] * d[2])) + q * (w[0] * w[0] - w[2] * w[2])
        };
        let sh = project_fn_dyn(f, 3, 2);
        (0..9).map(|j| tint.map(|c| c * sh.as_slice()[j])).collect()
    })?;
    println!("32^3 nodes, 9 coeffs RGB; irradiance error over 64 normals per node");
    println!(
        "{:<22} {:>10} {:>12} {:>12} {:>12} {:>9} {:>9} {:>8}",
        "encoding", "bytes/node", "max |dE|", "rms dE", "bound", "max/Emax", "max rel", "clamped"
    );
    for enc in [
        Encoding::F32,
        Encoding::F16,
        Encoding::SRGB8,
        Encoding::Srgb8 { range: 0.5 },
        Encoding::Srgb8 { range: 1.0 },
        Encoding::DcNormalized8,
    ] {
        let r = irradiance_error(&vol, enc, 64, 1)?;
        let label = match enc {
            Encoding::Srgb8 { range } => format!("srgb8 (range {range})"),
            e => e.name().to_string(),
        };
        println!(
            "{label:<22} {:>10} {:>12.3e} {:>12.3e} {:>12.3e} {:>8.3}% {:>8.3}% {:>8}",
            enc.bytes_per_node(9),
            r.max_abs,
            r.rms,
            r.bound,
            100.0 * r.max_abs / r.max_irradiance,
            100.0 * r.max_rel,
            r.clamped
        );
        assert!(r.max_abs <= r.bound);
    }
    Ok(())
}
