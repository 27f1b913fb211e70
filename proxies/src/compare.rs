//! Renders a scene with the pipeline in three variants — no proxies, shadows, shadows plus
//! indirect — and with the path-traced reference, and measures each variant's relative RMSE
//! against the reference on the receivers (the `proxies` command and `tests/compare.rs`).

use lightvol_core::samples::{Samples, samples};
use rayon::prelude::*;

use crate::kernel::{Kernel, KernelIndirect, Rgb9, light_f32, prepare};
use crate::light::DistantLight;
use crate::light::LightField;
use crate::oracle::{indirect_eta, shadow_eta};
use crate::pipeline::{
    accumulate_pass, bin_proxies, exponentiate_pass, shade_display, shade_from_scratch, total,
};
use crate::receiver_scene::{ReceiverBuffer, Scene};
use crate::reference::{PathTracer, inside_any, intersect};

/// Settings of a comparison.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CompareConfig {
    /// Display width.
    pub width: usize,
    /// Display height.
    pub height: usize,
    /// Receiver-buffer downsampling factor per axis (2 or 4 in the paper).
    pub factor: usize,
    /// Expansion factor for shadows.
    pub eta_shadow: f64,
    /// Expansion factor for indirect light.
    pub eta_indirect: f64,
    /// Path-traced samples per display pixel.
    pub samples: Samples,
    /// Seed of the reference.
    pub seed: u64,
    /// Screen tile edge for binning.
    pub tile: usize,
}

impl CompareConfig {
    /// Expansion factors derived by [`crate::oracle`] for a shading tolerance at `N`
    /// coefficients (shadows) and 9 (indirect).
    #[must_use]
    pub fn derived<const N: usize>(width: usize, height: usize, tolerance: f64) -> Self {
        Self {
            width,
            height,
            factor: 2,
            eta_shadow: shadow_eta::<N>(tolerance).eta,
            eta_indirect: indirect_eta::<9>(tolerance).eta,
            samples: samples(256),
            seed: 1,
            tile: 16,
        }
    }
}

/// Relative RMSEs of the three variants.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Errors {
    /// Without proxies.
    pub none: f64,
    /// With shadows.
    pub shadows: f64,
    /// With shadows and indirect light.
    pub shadows_indirect: f64,
}

/// Images (display resolution, receiver outgoing radiance, linear RGB) and errors.
#[derive(Clone, Debug, PartialEq)]
pub struct Comparison {
    /// Display size.
    pub size: [usize; 2],
    /// Receiver-buffer size.
    pub receivers: [usize; 2],
    /// Without proxies.
    pub none: Vec<[f32; 3]>,
    /// With shadows.
    pub shadows: Vec<[f32; 3]>,
    /// With shadows and indirect light.
    pub shadows_indirect: Vec<[f32; 3]>,
    /// Path-traced reference.
    pub reference: Vec<[f32; 3]>,
    /// Pixels compared: a receiver is seen, not hidden by a sphere and not inside one.
    pub mask: Vec<bool>,
    /// Relative RMSEs against the reference over the mask.
    pub errors: Errors,
    /// Display pixels shaded by the upsampling fallback (total over the three variants).
    pub fallbacks: usize,
}

/// The relative RMSE (`lightvol_core::metric`: `sqrt(mean((x - r)²)) / mean(r)`) over the
/// masked pixels' channels.
#[must_use]
pub fn rel_rmse(x: &[[f32; 3]], r: &[[f32; 3]], mask: &[bool]) -> f64 {
    lightvol_core::metric::rel_rmse(
        (0..x.len())
            .filter(|&i| mask[i])
            .flat_map(|i| (0..3).map(move |c| (f64::from(x[i][c]), f64::from(r[i][c])))),
    )
}

/// The three pipeline variants of a scene under any light (e.g. a baked volume), at display
/// resolution, with the character's spheres drawn over them.
#[derive(Clone, Debug, PartialEq)]
pub struct Variants {
    /// Display size.
    pub size: [usize; 2],
    /// Receiver-buffer size.
    pub receivers: [usize; 2],
    /// Without proxies.
    pub none: Vec<[f32; 3]>,
    /// With shadows.
    pub shadows: Vec<[f32; 3]>,
    /// With shadows and indirect light.
    pub shadows_indirect: Vec<[f32; 3]>,
    /// Per pixel, the shading of a character sphere in front of the receivers (if any).
    pub overlay: Vec<Option<[f32; 3]>>,
    /// The display receiver buffer.
    pub fine: ReceiverBuffer,
    /// Display pixels shaded by the upsampling fallback (total over the three variants).
    pub fallbacks: usize,
}

/// Renders the three variants with the pipeline under `light` (`N` = 9 or 16 coefficients
/// for shadows). The images do not yet have the character drawn in (see [`Variants::overlay`]).
#[must_use]
pub fn render_variants<const N: usize>(
    scene: &Scene,
    cfg: &CompareConfig,
    light: &impl LightField<N>,
) -> Variants {
    let fine = ReceiverBuffer::render(scene, cfg.width, cfg.height);
    let coarse = ReceiverBuffer::render(scene, cfg.width / cfg.factor, cfg.height / cfg.factor);
    let kernel = Kernel::<N>::new(cfg.eta_shadow, cfg.eta_indirect, KernelIndirect::Averaged);
    let prepared = prepare(&scene.proxies, light);
    let cam = scene.camera.frame();
    let eta = cfg.eta_shadow.max(cfg.eta_indirect);
    let bins = bin_proxies(&cam, coarse.width, coarse.height, &scene.proxies, eta, cfg.tile);
    let acc = accumulate_pass(&kernel, &coarse, &bins, &prepared);
    let inc = exponentiate_pass(&kernel, &coarse, &acc, light);

    let unshadowed = |b: &ReceiverBuffer, i: usize| -> Rgb9 {
        let l = light_f32(light, b.position[i]);
        core::array::from_fn(|j| l[j / 9][j % 9])
    };
    let none_in: Vec<Rgb9> = (0..inc.len()).map(|i| unshadowed(&coarse, i)).collect();
    let shadow_in: Vec<Rgb9> = inc.iter().map(|x| x.shadowed).collect();
    let total_in: Vec<Rgb9> = inc.iter().map(total).collect();
    let scratch = |i: usize| shade_from_scratch(&kernel, &fine, i, &prepared, light);
    let (none, f0) = shade_display(&coarse, &none_in, &fine, |i| unshadowed(&fine, i));
    let (shadows, f1) = shade_display(&coarse, &shadow_in, &fine, |i| scratch(i).shadowed);
    let (shadows_indirect, f2) = shade_display(&coarse, &total_in, &fine, |i| total(&scratch(i)));

    // The character itself, drawn as spheres with their unshadowed diffuse shading; receivers
    // behind it are not compared.
    let overlay: Vec<Option<[f32; 3]>> = (0..fine.width * fine.height)
        .map(|i| {
            let d = cam.ray(i % fine.width, i / fine.width, fine.width, fine.height);
            let (t, k) = intersect(&scene.proxies, cam.eye, d)?;
            if fine.valid(i) && f64::from(fine.depth[i]) < t * crate::receiver_scene::dot(d, cam.forward) {
                return None;
            }
            let s = &scene.proxies[k];
            let m: [f64; 3] = core::array::from_fn(|c| (cam.eye[c] + t * d[c] - s.center[c]) / s.radius);
            let l = light.radiance_at(s.center);
            let e = lightvol_sh::irradiance::irradiance_rgb(&l, m);
            Some(core::array::from_fn(|c| (e[c] * s.albedo[c] / std::f64::consts::PI) as f32))
        })
        .collect();
    Variants {
        size: [fine.width, fine.height],
        receivers: [coarse.width, coarse.height],
        none,
        shadows,
        shadows_indirect,
        overlay,
        fine,
        fallbacks: f0 + f1 + f2,
    }
}

impl Variants {
    /// Draws the character's spheres over an image.
    #[must_use]
    pub fn draw(&self, mut img: Vec<[f32; 3]>) -> Vec<[f32; 3]> {
        for (p, o) in img.iter_mut().zip(&self.overlay) {
            if let Some(o) = o {
                *p = *o;
            }
        }
        img
    }
}

/// Runs the comparison with `N` (9 or 16) coefficients for shadows: the variants under the
/// scene's sky/sun light and the path-traced reference.
#[must_use]
pub fn compare<const N: usize>(scene: &Scene, cfg: &CompareConfig) -> Comparison {
    let light = DistantLight(scene.light.sh::<N>());
    let v = render_variants(scene, cfg, &light);
    let (fine, overlay) = (&v.fine, &v.overlay);
    let pt =
        PathTracer { spheres: &scene.proxies, light: &scene.light, samples: cfg.samples, seed: cfg.seed };
    let mask: Vec<bool> = (0..fine.width * fine.height)
        .map(|i| {
            fine.valid(i)
                && overlay[i].is_none()
                && !inside_any(&scene.proxies, fine.position[i].map(f64::from))
        })
        .collect();
    let reference: Vec<[f32; 3]> = (0..mask.len())
        .into_par_iter()
        .map(|i| {
            if !mask[i] {
                return [0.0; 3];
            }
            let e = pt.irradiance(fine.position[i].map(f64::from), fine.normal[i].map(f64::from), i as u64);
            core::array::from_fn(|c| (e[c] / std::f64::consts::PI) as f32 * fine.albedo[i][c])
        })
        .collect();
    let (none, shadows, shadows_indirect, reference) = (
        v.draw(v.none.clone()),
        v.draw(v.shadows.clone()),
        v.draw(v.shadows_indirect.clone()),
        v.draw(reference),
    );
    let errors = Errors {
        none: rel_rmse(&none, &reference, &mask),
        shadows: rel_rmse(&shadows, &reference, &mask),
        shadows_indirect: rel_rmse(&shadows_indirect, &reference, &mask),
    };
    Comparison {
        size: v.size,
        receivers: v.receivers,
        none,
        shadows,
        shadows_indirect,
        reference,
        mask,
        errors,
        fallbacks: v.fallbacks,
    }
}
