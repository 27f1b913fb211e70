//! A camera view of lightmapped surfaces shaded from coefficient maps (Iwanicki & Sloan,
//! Ishtar 2011 Fig. 3.5), beside a path-traced reference of the same quantity
//! ([`reference_surface_irradiance`]: the same normal, light from below the tangent-space
//! hemisphere excluded, as the maps).
//!
//! Every visible lightmapped surface is shaded once per map set, each map evaluated at the
//! normal-mapped tangent-space normal ([`NormalMap`]). With a modified H-basis set present,
//! its lower levels of detail (Ishtar 2011 Listing 2.2's stop points) get images of their
//! own: `lightmap` (`H1` only, plain light mapping, on which the normal map has no effect)
//! and `lightmap4` (`H1 … H4`, the linear band).
//!
//! Shaded radiance is that of a Lambertian surface: `albedo · E / π` for irradiance maps,
//! `albedo · B` for radiosity maps. Each image's error is [`lightvol_core::metric`]'s
//! relative RMSE over the lightmapped pixels and the three channels.
//!
//! Normal maps: `procedural[:FREQ[:SLOPE]]`, the height field
//! `h = A sin(2π f u) sin(2π f v)` with `A 2π f = SLOPE` (default f = 4 cycles per UV unit,
//! slope 1, normals up to 45° from the surface normal) over the triangle's base texture
//! coordinates (the lightmap UVs for meshes without them); `flat`; or an 8-bit RGB PNG
//! tangent-space normal map (`n = 2 c - 1`, +Y up as in glTF), sampled bilinearly with
//! wrapping at the same coordinates.

use lightvol_core::samples::Samples;
use std::collections::BTreeMap;
use std::convert::Infallible;
use std::path::{Path, PathBuf};

use lightvol_core::metric::RelRmse;
use lightvol_hemibasis::lod::{Lod, eval_modified_h};
use lightvol_hemibasis::{BasisFamily, HemiBasis};
use lightvol_sh::lowdisc::hash2;

use super::{BasisChoice, CoefficientMap, Quantity, SurfaceGeometry, reference_surface_irradiance};
use lightvol_core::progress::Progress;
use lightvol_scene::{DVec3, Scene, Tracer, Transport, TransportSettings};
use lightvol_view::Camera;
use lightvol_view::picture::auto_exposure_of;
use lightvol_view::render::par_map_reporting;
use serde::Serialize;

/// Smallest `z` of a shading normal: normal-map texels that point below the surface are
/// pulled up to 1° above the tangent plane (the maps hold the upper hemisphere only).
pub const MIN_Z: f64 = 0.017_452_406_437_283_51; // sin(1°)

/// A tangent-space normal map.
#[derive(Clone, Debug)]
pub enum NormalMap {
    /// No perturbation.
    Flat,
    /// `h = A sin(2π f u) sin(2π f v)`, `A 2π f = slope`.
    Procedural {
        /// Cycles per UV unit.
        frequency: f64,
        /// Largest slope of the height field.
        slope: f64,
    },
    /// An RGB8 image (`n = 2c - 1`).
    Image {
        /// Width.
        width: usize,
        /// Height.
        height: usize,
        /// Decoded unit normals, row-major, top row first.
        normals: Vec<[f64; 3]>,
    },
}

/// A normal-map spec that does not read.
#[derive(Debug, thiserror::Error)]
pub enum NormalMapError {
    /// A number of the procedural spec.
    #[error("{what} '{text}' is not a number")]
    NotANumber {
        /// `frequency` or `slope`.
        what: &'static str,
        /// The text.
        text: String,
    },
    /// A negative or non-finite number.
    #[error("{0} must be finite and non-negative")]
    Negative(&'static str),
    /// Neither spec form.
    #[error("expected procedural[:FREQ[:SLOPE]], flat, or a PNG file, got '{0}'")]
    Spec(String),
    /// The image could not be read.
    #[error("reading {}", path.display())]
    Image {
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: image::ImageError,
    },
}

impl NormalMap {
    /// Parses `procedural[:FREQ[:SLOPE]]`, `flat`, or a PNG path (module docs).
    ///
    /// # Errors
    /// [`NormalMapError`].
    pub fn parse(s: &str) -> Result<Self, NormalMapError> {
        if s == "flat" {
            return Ok(Self::Flat);
        }
        if let Some(rest) = s.strip_prefix("procedural") {
            let mut parts = rest.split(':').skip(1);
            let num = |what: &'static str, v: Option<&str>, d: f64| -> Result<f64, NormalMapError> {
                let x = match v {
                    Some(t) => t
                        .trim()
                        .parse::<f64>()
                        .map_err(|_| NormalMapError::NotANumber { what, text: t.to_owned() })?,
                    None => d,
                };
                if !(x.is_finite() && x >= 0.0) {
                    return Err(NormalMapError::Negative(what));
                }
                Ok(x)
            };
            if !rest.is_empty() && !rest.starts_with(':') {
                return Err(NormalMapError::Spec(s.to_owned()));
            }
            let frequency = num("frequency", parts.next(), 4.0)?;
            let slope = num("slope", parts.next(), 1.0)?;
            return Ok(Self::Procedural { frequency, slope });
        }
        let path = Path::new(s);
        let img = image::open(path)
            .map_err(|source| NormalMapError::Image { path: path.to_owned(), source })?
            .to_rgb8();
        let (width, height) = (img.width() as usize, img.height() as usize);
        let normals = img
            .pixels()
            .map(|p| {
                let n = DVec3::new(
                    f64::from(p[0]) / 127.5 - 1.0,
                    f64::from(p[1]) / 127.5 - 1.0,
                    f64::from(p[2]) / 127.5 - 1.0,
                );
                n.try_normalize().unwrap_or(DVec3::Z).to_array()
            })
            .collect();
        Ok(Self::Image { width, height, normals })
    }

    /// The unit tangent-space normal at texture coordinates `uv` (`z >= MIN_Z`).
    #[must_use]
    pub fn normal(&self, uv: [f64; 2]) -> [f64; 3] {
        let n = match self {
            Self::Flat => DVec3::Z,
            Self::Procedural { frequency, slope } => {
                let w = 2.0 * std::f64::consts::PI * frequency;
                let (su, cu) = (w * uv[0]).sin_cos();
                let (sv, cv) = (w * uv[1]).sin_cos();
                DVec3::new(-slope * cu * sv, -slope * su * cv, 1.0)
            }
            Self::Image { width, height, normals } => {
                let (w, h) = (*width as i64, *height as i64);
                let x = uv[0] * w as f64 - 0.5;
                let y = uv[1] * h as f64 - 0.5;
                let (x0, y0) = (x.floor(), y.floor());
                let (fx, fy) = (x - x0, y - y0);
                let at = |i: i64, j: i64| {
                    DVec3::from_array(normals[(j.rem_euclid(h) * w + i.rem_euclid(w)) as usize])
                };
                let (i, j) = (x0 as i64, y0 as i64);
                (at(i, j) * (1.0 - fx) + at(i + 1, j) * fx) * (1.0 - fy)
                    + (at(i, j + 1) * (1.0 - fx) + at(i + 1, j + 1) * fx) * fy
            }
        };
        let mut n = n.try_normalize().unwrap_or(DVec3::Z);
        if n.z < MIN_Z {
            let xy = DVec3::new(n.x, n.y, 0.0).try_normalize().unwrap_or(DVec3::X);
            n = xy * (1.0 - MIN_Z * MIN_Z).sqrt() + DVec3::Z * MIN_Z;
        }
        n.to_array()
    }
}

/// The coefficient maps of one basis: one map per lightmap object, in the geometry's order.
pub struct MapSet {
    /// The basis choice the maps store.
    pub tag: BasisChoice,
    /// The basis.
    pub basis: Box<dyn HemiBasis>,
    /// The maps.
    pub maps: Vec<CoefficientMap>,
}

/// How a view is taken.
#[derive(Clone, Debug)]
pub struct ShadedViewSettings {
    /// The camera.
    pub camera: Camera,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Path-traced samples per pixel of the reference.
    pub reference_samples: Samples,
    /// Seed of the reference's random streams.
    pub seed: u64,
    /// The path settings of the reference (the maps' own).
    pub transport: TransportSettings,
}

/// One image of a view: a map set's, or a level of detail's.
pub struct ShadedImage {
    /// The basis tag, or `lightmap` / `lightmap4`.
    pub name: String,
    /// Coefficients per channel it uses.
    pub coefficients: usize,
    /// Linear RGB, row-major.
    pub pixels: Vec<[f32; 3]>,
    /// Relative RMSE against the reference over the lightmapped pixels.
    pub rel_rmse: f64,
}

/// A shaded view and its reference.
pub struct ShadedView {
    /// The reference, linear RGB, row-major.
    pub reference: Vec<[f32; 3]>,
    /// Which pixels show a lightmapped surface.
    pub lightmapped: Vec<bool>,
    /// The images: one per map set in order, then the levels of detail.
    pub images: Vec<ShadedImage>,
    /// Lightmapped pixels (those the errors run over).
    pub pixels: usize,
}

impl ShadedView {
    /// The exposure that maps the mean lightmapped pixel of the reference to
    /// lightvol-view's `AUTO_EXPOSURE_MEAN` ([`auto_exposure_of`]): one exposure for every
    /// image of the view, so that they compare.
    #[must_use]
    pub fn auto_exposure(&self) -> f32 {
        auto_exposure_of(self.reference.iter().zip(&self.lightmapped).filter(|(_, lm)| **lm).map(|(r, _)| r))
    }
}

/// The file name of a shaded view's image `name` (a basis tag, `lightmap`, `lightmap4`).
#[must_use]
pub fn image_file(name: &str) -> String {
    format!("{name}.png")
}

/// The file name of a shaded view's reference image.
pub const REFERENCE_IMAGE: &str = "reference.png";

/// One image's entry in a [`ShadedViewReport`].
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ShadedImageReport {
    /// Relative RMSE against the path-traced reference.
    pub rel_rmse: f64,
    /// 8-bit storage per texel as RGB8 (PNG): 3 bytes per coefficient (\[Ish11\] §2.2.3;
    /// an RGBA8 KTX2 stores 4).
    pub bytes_per_texel: usize,
    /// Coefficients per channel.
    pub coefficients: usize,
    /// Its file ([`image_file`]).
    pub image: String,
}

/// The reference's entry in a [`ShadedViewReport`].
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct ReferenceImageReport {
    /// Its file ([`REFERENCE_IMAGE`]).
    pub image: String,
    /// Path-traced samples per pixel.
    pub samples: u32,
}

/// What a shaded view reports: each image's error and storage, the reference, the pixels
/// compared and the normal map (`lightvol render --surface` writes it as `report.json`).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ShadedViewReport {
    /// Per basis (and `lightmap` / `lightmap4`, the modified H-basis's lower levels of
    /// detail), by name.
    pub bases: BTreeMap<String, ShadedImageReport>,
    /// Invalid texels of the maps' bakes.
    pub invalid_texels: u64,
    /// The reference.
    pub reference: ReferenceImageReport,
    /// Pixels showing lightmapped surfaces (those the errors run over).
    pub pixels: usize,
    /// The normal map's spec ([`NormalMap::parse`]).
    pub normal_map: String,
}

impl ShadedViewReport {
    /// The report of `view`, whose reference traced `reference_samples` paths per pixel, of
    /// maps whose bakes left `invalid_texels` invalid texels, under the normal map of the
    /// spec `normal_map`.
    #[must_use]
    pub fn new(view: &ShadedView, invalid_texels: u64, reference_samples: Samples, normal_map: &str) -> Self {
        let bases = view
            .images
            .iter()
            .map(|i| {
                let entry = ShadedImageReport {
                    rel_rmse: i.rel_rmse,
                    bytes_per_texel: 3 * i.coefficients,
                    coefficients: i.coefficients,
                    image: image_file(&i.name),
                };
                (i.name.clone(), entry)
            })
            .collect();
        Self {
            bases,
            invalid_texels,
            reference: ReferenceImageReport {
                image: REFERENCE_IMAGE.to_owned(),
                samples: reference_samples.get(),
            },
            pixels: view.pixels,
            normal_map: normal_map.to_owned(),
        }
    }
}

/// One pixel: whether it shows a lightmapped surface, the reference's colour, and each
/// image's colour.
type PixelColours = (bool, [f32; 3], Vec<[f32; 3]>);

/// What a camera ray sees.
enum PixelHit {
    /// Sky or a surface that is not lightmapped: its final colour.
    Other([f32; 3]),
    /// A lightmapped surface.
    Lightmapped { tri: u32, bary: [f64; 2], object: usize, uv: [f64; 2], n_t: [f64; 3], albedo: [f64; 3] },
}

/// Renders the lightmapped surfaces of `scene` (lightmap objects `geo`) from `settings`'
/// camera with each of `sets`, and the path-traced reference (module docs). The maps'
/// quantity is that of the first map. `progress`, when given, hears the pixels done from the
/// calling thread; the images do not depend on it or on the thread count.
#[must_use]
pub fn render_shaded_view(
    scene: &Scene,
    geo: &SurfaceGeometry,
    sets: &[MapSet],
    normal_map: &NormalMap,
    settings: &ShadedViewSettings,
    progress: Option<&(dyn Fn(Progress) + Sync)>,
) -> ShadedView {
    let (w, h) = (settings.width, settings.height);
    let cam = &settings.camera;
    let quantity = sets.first().and_then(|s| s.maps.first()).map_or(Quantity::Irradiance, |m| m.quantity);
    let to_radiance = match quantity {
        Quantity::Irradiance => std::f64::consts::FRAC_1_PI,
        Quantity::Radiosity => 1.0,
    };
    let lightmap_set = sets.iter().position(|s| s.tag.family() == BasisFamily::HBasisMod);
    let lods: &[(&str, Lod)] =
        if lightmap_set.is_some() { &[("lightmap", Lod::Lightmap), ("lightmap4", Lod::Linear)] } else { &[] };
    let n_images = sets.len() + lods.len();
    let tracer = Tracer::new(scene);
    let transport = Transport::new(scene, &tracer, settings.transport);
    let pixel = |k: usize| -> Result<PixelColours, Infallible> {
        // `k < w · h`, a u32.
        let i = k as u32;
        Ok({
            let (x, y) = (i % w, i / w);
            let d = cam.ray(x, y, w, h);
            let hit = match tracer.closest_hit(cam.eye(), d, 0.0, f64::INFINITY) {
                None => PixelHit::Other(scene.environment.radiance(d).map(|v| v as f32)),
                Some(hit) => {
                    let tri = hit.triangle;
                    let emission = scene.material_of(tri).emission;
                    let albedo = scene.albedo(tri, hit.bary[0], hit.bary[1]);
                    match (geo.object_of(tri), geo.lightmap_uv(tri, hit.bary)) {
                        (Some(object), Some(uv)) if !hit.from_behind && emission == [0.0; 3] => {
                            let t = &scene.triangles[tri as usize];
                            let base = t.uv_at(hit.bary[0], hit.bary[1]);
                            let nm_uv = if t.uv.iter().all(|u| *u == t.uv[0]) { uv } else { base.to_array() };
                            PixelHit::Lightmapped {
                                tri,
                                bary: hit.bary,
                                object,
                                uv,
                                n_t: normal_map.normal(nm_uv),
                                albedo,
                            }
                        }
                        _ => PixelHit::Other(emission.map(|v| v as f32)),
                    }
                }
            };
            match hit {
                PixelHit::Other(c) => (false, c, vec![c; n_images]),
                PixelHit::Lightmapped { tri, bary, object, uv, n_t, albedo } => {
                    let shade = |e: [f64; 3]| -> [f32; 3] {
                        core::array::from_fn(|c| (albedo[c] * e[c] * to_radiance) as f32)
                    };
                    let (e_ref, _) = reference_surface_irradiance(
                        &transport,
                        geo,
                        tri,
                        bary,
                        n_t,
                        quantity,
                        settings.reference_samples,
                        settings.seed,
                        hash2(0x5eed_5a7f, u64::from(i)),
                    );
                    let mut cols: Vec<[f32; 3]> =
                        sets.iter().map(|s| shade(s.maps[object].shade(s.basis.as_ref(), uv, n_t))).collect();
                    if let Some(k) = lightmap_set {
                        let c = sets[k].maps[object].lookup(uv);
                        for &(_, lod) in lods {
                            cols.push(shade(eval_modified_h(&c, n_t, lod)));
                        }
                    }
                    (true, shade(e_ref), cols)
                }
            }
        })
    };
    let Ok(rows) = par_map_reporting(w as usize * h as usize, progress, pixel);
    let mut names: Vec<(String, usize)> = sets.iter().map(|s| (s.tag.tag(), s.basis.len())).collect();
    names.extend(lods.iter().map(|&(name, lod)| (name.to_owned(), lod.coefficients())));
    let mut errors = vec![RelRmse::default(); n_images];
    for (lm, r, cols) in &rows {
        if *lm {
            for c in 0..3 {
                for (e, col) in errors.iter_mut().zip(cols) {
                    e.add(f64::from(col[c]), f64::from(r[c]));
                }
            }
        }
    }
    let pixels = rows.iter().filter(|r| r.0).count();
    let images = names
        .into_iter()
        .zip(&errors)
        .enumerate()
        .map(|(k, ((name, coefficients), e))| ShadedImage {
            name,
            coefficients,
            pixels: rows.iter().map(|r| r.2[k]).collect(),
            rel_rmse: e.value(),
        })
        .collect();
    ShadedView {
        reference: rows.iter().map(|r| r.1).collect(),
        lightmapped: rows.iter().map(|r| r.0).collect(),
        images,
        pixels,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Central differences with step 1e-6 on an O(1) smooth height field: truncation
    /// ~1e-12 × f''', rounding ~1e-16 / 1e-6 = 1e-10.
    const FD_TOL: f64 = 1e-8;

    #[test]
    fn procedural_normal_is_the_height_fields_normal() {
        let (frequency, slope) = (3.0, 1.5);
        let nm = NormalMap::parse(&format!("procedural:{frequency}:{slope}")).unwrap();
        let a = slope / (2.0 * std::f64::consts::PI * frequency);
        let h = |u: f64, v: f64| {
            a * (2.0 * std::f64::consts::PI * frequency * u).sin()
                * (2.0 * std::f64::consts::PI * frequency * v).sin()
        };
        let step = 1e-6;
        for &(u, v) in &[(0.1, 0.2), (0.37, 0.81), (0.5, 0.5), (0.9, 0.03)] {
            let hu = (h(u + step, v) - h(u - step, v)) / (2.0 * step);
            let hv = (h(u, v + step) - h(u, v - step)) / (2.0 * step);
            let want = DVec3::new(-hu, -hv, 1.0).normalize();
            let got = DVec3::from_array(nm.normal([u, v]));
            assert!((got - want).length() < FD_TOL, "{got} vs {want}");
        }
        assert_eq!(NormalMap::parse("flat").unwrap().normal([0.3, 0.3]), [0.0, 0.0, 1.0]);
        assert!(
            matches!(NormalMap::parse("procedural").unwrap(), NormalMap::Procedural { frequency, slope } if frequency == 4.0 && slope == 1.0)
        );
    }

    #[test]
    fn a_view_reports_its_images_and_exposure() {
        let image = |name: &str, coefficients, rel_rmse| ShadedImage {
            name: name.into(),
            coefficients,
            pixels: vec![[0.5; 3]; 3],
            rel_rmse,
        };
        let view = ShadedView {
            reference: vec![[0.3; 3], [0.9; 3], [10.0; 3]],
            lightmapped: vec![true, true, false],
            images: vec![image("lightmap", 1, 0.25), image("hbasis_mod6", 6, 0.0625)],
            pixels: 2,
        };
        // The sky pixel (10) is left out: mean 0.6.
        assert!(
            (f64::from(view.auto_exposure()) - lightvol_view::picture::AUTO_EXPOSURE_MEAN / 0.6).abs() < 1e-6
        );
        let r = ShadedViewReport::new(&view, 7, lightvol_core::samples::samples(64), "procedural:4");
        let want = serde_json::json!({
            "bases": {
                "hbasis_mod6": {"rel_rmse": 0.0625, "bytes_per_texel": 18, "coefficients": 6, "image": "hbasis_mod6.png"},
                "lightmap": {"rel_rmse": 0.25, "bytes_per_texel": 3, "coefficients": 1, "image": "lightmap.png"},
            },
            "invalid_texels": 7,
            "reference": {"image": "reference.png", "samples": 64},
            "pixels": 2,
            "normal_map": "procedural:4",
        });
        assert_eq!(serde_json::to_value(&r).unwrap(), want);
        let keys: Vec<&String> = r.bases.keys().collect();
        assert_eq!(keys, ["hbasis_mod6", "lightmap"]);
    }

    #[test]
    fn normals_below_the_surface_are_pulled_up() {
        let nm = NormalMap::Image { width: 1, height: 1, normals: vec![[1.0, 0.0, -0.2]] };
        let n = nm.normal([0.5, 0.5]);
        assert!((n[2] - MIN_Z).abs() < 1e-12 && (DVec3::from_array(n).length() - 1.0).abs() < 1e-12);
        assert!((MIN_Z - 1f64.to_radians().sin()).abs() < 1e-17);
    }

    /// 8-bit normal-map texels decode within half a code: 0.5 / 127.5 per component.
    const TEXEL_TOL: f64 = 0.5 / 127.5;

    #[test]
    fn png_normal_maps_decode_and_wrap() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("n.png");
        // 2 × 1: left texel flat (128, 128, 255), right texel tilted towards +x.
        let tilted = DVec3::new(0.6, 0.0, 0.8);
        let enc = |v: f64| ((v + 1.0) * 127.5).round() as u8;
        let rgb = [128, 128, 255, enc(tilted.x), enc(tilted.y), enc(tilted.z)];
        image::save_buffer(&path, &rgb, 2, 1, image::ExtendedColorType::Rgb8).unwrap();
        let nm = NormalMap::parse(path.to_str().unwrap()).unwrap();
        // Texel centres at u = 0.25 and 0.75; u = 1.25 wraps to 0.25.
        for (u, want) in [(0.25, DVec3::Z), (0.75, tilted), (1.25, DVec3::Z)] {
            let n = DVec3::from_array(nm.normal([u, 0.5]));
            assert!((n - want).abs().max_element() < 2.0 * TEXEL_TOL, "u={u}: {n} vs {want}");
        }
        // Halfway between the two: the bilinear blend, renormalised.
        let mid = DVec3::from_array(nm.normal([0.5, 0.5]));
        assert!((mid - (DVec3::Z + tilted).normalize()).abs().max_element() < 2.0 * TEXEL_TOL);
    }

    #[test]
    fn bad_normal_map_specs_are_errors() {
        assert!(matches!(NormalMap::parse("procedural:x"), Err(NormalMapError::NotANumber { .. })));
        assert!(matches!(NormalMap::parse("procedural:2:-1"), Err(NormalMapError::Negative("slope"))));
        assert!(matches!(NormalMap::parse("proceduralx"), Err(NormalMapError::Spec(_))));
        let e = NormalMap::parse("/nonexistent/normals.png").unwrap_err();
        assert!(e.to_string().contains("normals.png"));
    }
}
