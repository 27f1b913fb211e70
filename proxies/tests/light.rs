//! Baked light as the source: the lightvol-volume adapter returns the volume's local
//! radiance SH, and a uniform volume shades like the distant light it holds.

use lightvol_proxies::accumulate::{ExpMethod, IndirectMethod, ShadeOptions, shade_receiver};
use lightvol_proxies::light::{DistantLight, LightField, SkySun, VolumeLight};
use lightvol_proxies::proxy::SphereProxy;
use lightvol_volume::{GridSpec, IrradianceVolume};

/// f32 storage of the volume's coefficients (values of order 1-4).
const F32_STORAGE: f64 = 1e-6;

#[test]
fn volume_light_matches_distant_light() {
    let sky =
        SkySun { sun_dir: [0.6, 0.0, 0.8], sun: [3.0, 2.6, 2.0], sky: [0.3, 0.45, 0.7], ground: [0.1; 3] };
    let l = sky.sh::<9>();
    let spec = GridSpec::new([-2.0, -2.0, -1.0], [2.0, 2.0, 3.0], [3, 3, 3]).unwrap();
    let vol = IrradianceVolume::from_fn(spec, 9, |_| {
        (0..9).map(|j| [l.0[0].0[j], l.0[1].0[j], l.0[2].0[j]]).collect()
    })
    .unwrap();
    let vl = VolumeLight(&vol);
    let got: lightvol_sh::coeffs::ShRgb<f64, 16> = vl.radiance_at([0.3, -0.7, 1.1]);
    for c in 0..3 {
        for j in 0..9 {
            assert!((got.0[c].0[j] - l.0[c].0[j]).abs() < F32_STORAGE * 4.0);
        }
        for j in 9..16 {
            assert_eq!(got.0[c].0[j], 0.0);
        }
    }
    // Shading with the volume equals shading with the distant light it stores.
    let proxies = [SphereProxy::new([0.2, 0.1, 0.9], 0.4, [0.7, 0.5, 0.3])];
    let opts = ShadeOptions { indirect: IndirectMethod::Averaged, exp: ExpMethod::Hyb, ..Default::default() };
    let a = shade_receiver::<9>([0.0; 3], [0.0, 0.0, 1.0], &proxies, &vl, &opts);
    let b = shade_receiver::<9>([0.0; 3], [0.0, 0.0, 1.0], &proxies, &DistantLight(l), &opts);
    for c in 0..3 {
        assert!((a.total()[c] - b.total()[c]).abs() < 1e-5 * b.total()[c]);
    }
}

/// The pipeline under a uniform baked volume renders like under the distant light it holds.
#[test]
fn pipeline_with_volume_light() {
    use lightvol_proxies::compare::{CompareConfig, render_variants};
    use lightvol_proxies::receiver_scene::Scene;
    let scene = Scene::default_scene();
    let l = scene.light.sh::<9>();
    let spec = GridSpec::new([-4.0, -4.0, -1.0], [4.0, 4.0, 4.0], [2, 2, 2]).unwrap();
    let vol = IrradianceVolume::from_fn(spec, 9, |_| {
        (0..9).map(|j| [l.0[0].0[j], l.0[1].0[j], l.0[2].0[j]]).collect()
    })
    .unwrap();
    let mut cfg = CompareConfig::derived::<9>(48, 36, 1.0 / 256.0);
    cfg.tile = 8;
    let a = render_variants::<9>(&scene, &cfg, &VolumeLight(&vol));
    let b = render_variants::<9>(&scene, &cfg, &DistantLight(l));
    let worst = a
        .shadows_indirect
        .iter()
        .zip(&b.shadows_indirect)
        .flat_map(|(x, y)| (0..3).map(move |c| (x[c] - y[c]).abs() / y[c].abs().max(1e-3)))
        .fold(0.0f32, f32::max);
    // f32 storage of the volume and f32 trilinear weights.
    assert!(worst < 1e-4, "{worst}");
}
