//! Each encoding round-trips within its stated error bound.

mod common;

use lightvol_core::color::{srgb_decode, srgb_encode};
use lightvol_volume::encode::{
    DEFAULT_RANGE, Encoding, Payload, coefficient_error_bounds, encode, irradiance_error, srgb8_max_error,
};
use lightvol_volume::{GridSpec, IrradianceVolume};

const ENCODINGS: [Encoding; 5] =
    [Encoding::F32, Encoding::F16, Encoding::SRGB8, Encoding::Srgb8 { range: 0.5 }, Encoding::DcNormalized8];

#[test]
fn every_encoding_round_trips_within_its_stated_bound() {
    for coeffs in [4, 9, 16] {
        let vol = common::physical_volume(coeffs, [5, 4, 3], 40 + coeffs as u64);
        for enc in ENCODINGS {
            let e = encode(&vol, enc).unwrap();
            let dec = e.decode();
            assert_eq!(dec.weights(), vol.weights());
            let bounds = coefficient_error_bounds(&vol, enc);
            for (i, ((a, b), bound)) in vol.data().iter().zip(dec.data()).zip(&bounds).enumerate() {
                let err = (f64::from(*a) - f64::from(*b)).abs();
                assert!(err <= *bound, "{enc:?} coeffs {coeffs} element {i}: |{a} - {b}| = {err} > {bound}");
            }
            let report = irradiance_error(&vol, enc, 32, 9).unwrap();
            assert!(report.max_abs <= report.bound, "{report:?}");
            assert!(report.rms <= report.max_abs);
            assert_eq!(report.clamped, 0, "physical radiance must not clamp in {enc:?}");
            // The bounds are informative, not vacuous: relative to the largest irradiance,
            // f16 stays below 2^-9 and the 8-bit schemes below 5 %.
            let rel = report.bound / report.max_irradiance;
            match enc {
                Encoding::F32 => {
                    assert_eq!(report.max_abs, 0.0);
                    let bits =
                        |v: &IrradianceVolume| v.data().iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                    assert_eq!(bits(&dec), bits(&vol));
                }
                Encoding::F16 => assert!(rel < 2f64.powi(-9) && report.max_abs > 0.0, "{report:?}"),
                _ => assert!(rel < 0.05 && report.max_abs > 0.0, "{enc:?} {report:?}"),
            }
            assert_eq!(report.bytes, enc.bytes_per_node(coeffs) * vol.spec().node_count());
        }
    }
}

#[test]
fn clamping_is_counted_and_bounded() {
    // Non-physical data: L1 ten times the DC term.
    let spec = GridSpec::new([0.0; 3], [1.0; 3], [2, 2, 2]).unwrap();
    let vol = IrradianceVolume::from_fn(spec, 4, |x| {
        vec![[1.0, 0.5, 0.0], [10.0, -10.0, 0.5], [x[0], 0.0, 0.0], [-0.25, 0.0, -3.0]]
    })
    .unwrap();
    for enc in [Encoding::SRGB8, Encoding::DcNormalized8] {
        let e = encode(&vol, enc).unwrap();
        assert!(e.clamped() > 0, "{enc:?}");
        let dec = e.decode();
        let bounds = coefficient_error_bounds(&vol, enc);
        for ((a, b), bound) in vol.data().iter().zip(dec.data()).zip(&bounds) {
            assert!((f64::from(*a) - f64::from(*b)).abs() <= *bound);
        }
        let r = irradiance_error(&vol, enc, 16, 1).unwrap();
        assert!(r.max_abs <= r.bound && r.clamped == e.clamped());
    }
}

#[test]
fn srgb_curve_inverts_and_its_8bit_error_matches_the_slope() {
    for i in 0..=1000 {
        let x = f64::from(i) / 1000.0;
        assert!((srgb_decode(srgb_encode(x)) - x).abs() < 1e-15);
    }
    // Continuity at the piecewise joins (the standard's constants meet to ~1e-8 there).
    assert!((srgb_encode(0.003_130_8) - 0.040_45).abs() < 1e-6);
    // Second method: the largest decode error of 8-bit sRGB is about half a code step
    // times the steepest slope of the decode curve, d/dy ((y + 0.055)/1.055)^2.4 at y = 1,
    // which is 2.4/1.055.
    let slope_estimate = 0.5 / 255.0 * 2.4 / 1.055;
    let exact = srgb8_max_error();
    assert!((exact / slope_estimate - 1.0).abs() < 0.01, "{exact} vs {slope_estimate}");
}

#[test]
fn default_range_and_layouts() {
    assert_eq!(Encoding::SRGB8, Encoding::Srgb8 { range: DEFAULT_RANGE });
    let vol = common::physical_volume(9, [3, 3, 3], 1);
    match encode(&vol, Encoding::DcNormalized8).unwrap().payload() {
        Payload::DcNormalized8 { dc, ratios } => {
            assert_eq!(dc.len(), 27 * 3);
            assert_eq!(ratios.len(), 27 * 8 * 3);
        }
        p => panic!("wrong payload {p:?}"),
    }
    assert!(encode(&vol, Encoding::Srgb8 { range: 0.0 }).is_err());
    assert!(encode(&vol, Encoding::Srgb8 { range: f32::NAN }).is_err());
    let big = IrradianceVolume::from_fn(vol.spec().clone(), 4, |_| vec![[1e5, 0.0, 0.0]; 4]).unwrap();
    assert!(encode(&big, Encoding::F16).is_err());
}
