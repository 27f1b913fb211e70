//! Shared test volumes.
#![allow(dead_code, reason = "each test binary uses a subset")]

use lightvol_sh::lowdisc::{SplitMix64, hash2};
use lightvol_sh::project::project_fn_dyn;
use lightvol_volume::{BakeMetadata, GridSpec, IrradianceVolume, Placement};

/// A volume of physically valid (non-negative) radiance: at each node and channel
/// `L(ω) = a + b·ω + ωᵀQω` with `|b| ≤ 0.4 a` and `|Q| ≤ 0.1 a` entrywise (so `L ≥ 0.1 a`),
/// projected exactly (quadrature exact for the degree) onto `coeffs` SH coefficients.
pub fn physical_volume(coeffs: usize, res: [u32; 3], seed: u64) -> IrradianceVolume {
    let spec = GridSpec::new([-1.0, 0.0, 2.0], [1.0, 1.5, 3.0], res).unwrap();
    let bands = coeffs.isqrt();
    let mut vol = IrradianceVolume::from_fn(spec, coeffs, |_| vec![[0.0; 3]; coeffs]).unwrap();
    for node in 0..vol.spec().node_count() {
        let mut rng = SplitMix64::new(hash2(seed, node as u64));
        let mut vals = vec![0.0f32; coeffs * 3];
        for ch in 0..3 {
            let a = rng.range(0.2, 3.0);
            let b: [f64; 3] = std::array::from_fn(|_| rng.range(-0.4, 0.4) * a / 3f64.sqrt());
            let q: [[f64; 3]; 3] = {
                let mut q = [[0.0; 3]; 3];
                for r in 0..3 {
                    for c in r..3 {
                        let v = rng.range(-0.1, 0.1) * a / 3.0;
                        q[r][c] = v;
                        q[c][r] = v;
                    }
                }
                q
            };
            let f = |w: [f64; 3]| {
                let mut v = a + b[0] * w[0] + b[1] * w[1] + b[2] * w[2];
                for r in 0..3 {
                    for c in 0..3 {
                        v += w[r] * q[r][c] * w[c];
                    }
                }
                v
            };
            let sh = project_fn_dyn(f, bands, 2);
            for j in 0..coeffs {
                vals[3 * j + ch] = sh.as_slice()[j] as f32;
            }
        }
        vol.set_node(node, &vals).unwrap();
    }
    vol
}

/// A volume with random coefficients in [-1, 1], varied weights, a placement and metadata:
/// exercises every field of the file formats.
pub fn random_volume(coeffs: usize, res: [u32; 3], seed: u64) -> IrradianceVolume {
    let spec = GridSpec::new([-1.25, 0.5, 2.0], [3.0, 1.5, 7.125], res).unwrap().with_placement(
        Placement::new([[0.0, -1.0, 0.0, 10.5], [1.0, 0.0, 0.0, -3.0], [0.0, 0.0, 2.0, 0.1]]).unwrap(),
    );
    let mut rng = SplitMix64::new(seed);
    let n = spec.node_count();
    let data = (0..n * coeffs * 3).map(|_| rng.range(-1.0, 1.0) as f32).collect();
    let weights = (0..n).map(|i| if i % 7 == 3 { 0.0 } else { rng.next_f64() as f32 }).collect();
    IrradianceVolume::new(spec, coeffs, data, weights).unwrap().with_metadata(BakeMetadata {
        method: "domain".into(),
        sampling_rays: 123_456_789_012,
        seed: u64::MAX - 5,
        shard_index: 2,
        shard_count: 7,
        scene_hash: "a1b2c3d4e5f60718".into(),
        units: "W sr^-1 m^-2".into(),
        frame: lightvol_volume::frame::UpAxis::Z,
        // A typed record with every kind of field, so that the round trips carry all of it.
        settings: Some(lightvol_volume::BakeRecord {
            method: "doi-paper".into(),
            samples_per_unit: 256,
            coeffs,
            fit: lightvol_volume::FitRecord::LeastSquares { lambda: 0.1 },
            gradients: Some("basis".into()),
            bounces: 2,
            russian_roulette: true,
            direct_light: "sky+indirect".into(),
            octree: Some(lightvol_volume::OctreeSettings {
                depth_ratio_threshold: None,
                memory_budget: Some(1 << 20),
                ..lightvol_volume::OctreeSettings::default()
            }),
            target: Some(lightvol_volume::TargetRecord {
                lookup: "three".into(),
                lambda: 0.05,
                smoothing: Some(0.3),
            }),
            noise: Some(lightvol_volume::NoiseRecord { relative_error: 0.01, max_samples: 4096 }),
        }),
    })
}
