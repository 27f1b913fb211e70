//! `lightvol render SCENE --surface DIR -o OUT`: \[Ish11\] Fig. 3.5. Every visible
//! lightmapped surface is shaded from the coefficient maps in `DIR` (one image per basis,
//! each map evaluated at the normal-mapped tangent-space normal), next to a path-traced
//! reference of the same quantity (`reference_surface_irradiance`: the same normal, light
//! from below the tangent-space hemisphere excluded, as the maps). With a modified H-basis
//! map present, its lower levels of detail (\[Ish11\] Listing 2.2's stop points) get images
//! of their own: `lightmap` (`H1` only, i.e. plain light mapping, on which the normal map
//! has no effect) and `lightmap4` (`H1 … H4`, the linear band). At the geometric normal
//! every level equals the full evaluation (`H2 … H6` vanish there); see
//! `lightvol_hemibasis::lod` for what that value is (the 3-band SH irradiance less
//! `sqrt(5)/(8 sqrt(π)) E_20`).
//!
//! The maps record what lit their bake (`lightvol_sampler::surface::lighting_fingerprint`:
//! environment, sun, punctual lights, emitters and the bounce count). The render refuses, with
//! one line and before writing anything, maps in `DIR` that disagree with each other (a stale
//! file) or with its own scene and lights under the maps' bounce count; the reference is
//! traced with that bounce count. `invalid_texels` is read from the EXR maps.
//!
//! `OUT/sheet.png` tiles the reference, the bases in file-name order, `lightmap` and
//! `lightmap4`, four per row. `OUT/report.json`:
//! `{"bases": {"<basis>": {"rel_rmse", "bytes_per_texel", "coefficients", "image"}},
//!   "invalid_texels", "reference": {"image", "samples"}, "pixels", "normal_map"}`.
//! `rel_rmse = sqrt(Σ (I_b - I_ref)²) / sqrt(Σ I_ref²)` over the lightmapped pixels and
//! the three channels of the shaded radiance (albedo × irradiance / π). `bytes_per_texel`
//! is the 8-bit storage of \[Ish11\] §2.2.3 as RGB8 (PNG): 3 bytes per coefficient (an
//! uncompressed RGBA8 KTX2 stores 4, BC7 1, BC1 0.5; see `bake-surface`'s summary).
//!
//! Normal maps (`--normal-map`): `procedural[:FREQ[:SLOPE]]` (default), the height field
//! `h = A sin(2π f u) sin(2π f v)` with `A 2π f = SLOPE` (default f = 4 cycles per UV unit,
//! slope 1, i.e. normals up to 45° from the surface normal) over the triangle's base texture
//! coordinates (the lightmap UVs for meshes without them); `flat`; or an 8-bit RGB PNG
//! tangent-space normal map (`n = 2 c - 1`, +Y up as in glTF), sampled bilinearly with
//! wrapping at the same coordinates.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{Context, bail};
use lightvol_hemibasis::lod::{Lod, eval_modified_h};
use lightvol_hemibasis::{BasisFamily, HemiBasis};
use lightvol_sampler::surface::{
    BasisChoice, CoefficientMap, LightingRecord, Quantity, SurfaceError, SurfaceGeometry,
    lighting_fingerprint, read_surface_exr, reference_surface_irradiance,
};
use lightvol_sampler::{DVec3, Tracer, Transport, TransportSettings};
use lightvol_sh::lowdisc::hash2;
use rayon::prelude::*;
use serde::Serialize;

use crate::cmd_render::{RenderArgs, resolve_camera};
use crate::imaging::{Rgb32, write_atomic, write_png_linear};
use crate::setup::with_threads;
use lightvol_sampler::view::Camera;

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

impl NormalMap {
    /// Parses `procedural[:FREQ[:SLOPE]]`, `flat`, or a PNG path.
    pub fn parse(s: &str) -> anyhow::Result<Self> {
        if s == "flat" {
            return Ok(Self::Flat);
        }
        if let Some(rest) = s.strip_prefix("procedural") {
            let mut parts = rest.split(':').skip(1);
            let num = |what: &str, v: Option<&str>, d: f64| -> anyhow::Result<f64> {
                let x = match v {
                    Some(t) => t
                        .trim()
                        .parse::<f64>()
                        .with_context(|| format!("--normal-map: {what} '{t}' is not a number"))?,
                    None => d,
                };
                if !(x.is_finite() && x >= 0.0) {
                    bail!("--normal-map: {what} must be finite and non-negative");
                }
                Ok(x)
            };
            if !rest.is_empty() && !rest.starts_with(':') {
                bail!("--normal-map: expected procedural[:FREQ[:SLOPE]], flat, or a PNG file, got '{s}'");
            }
            let frequency = num("frequency", parts.next(), 4.0)?;
            let slope = num("slope", parts.next(), 1.0)?;
            return Ok(Self::Procedural { frequency, slope });
        }
        let path = Path::new(s);
        let img =
            image::open(path).with_context(|| format!("--normal-map: reading {}", path.display()))?.to_rgb8();
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
        // The maps hold the upper hemisphere only.
        if n.z < MIN_Z {
            let xy = DVec3::new(n.x, n.y, 0.0).try_normalize().unwrap_or(DVec3::X);
            n = xy * (1.0 - MIN_Z * MIN_Z).sqrt() + DVec3::Z * MIN_Z;
        }
        n.to_array()
    }
}

/// Smallest `z` of a shading normal: normal-map texels that point below the surface are
/// pulled up to 1° above the tangent plane.
const MIN_Z: f64 = 0.017_452_406_437_283_51; // sin(1°)

/// One basis's entry in `report.json`.
#[derive(Debug, Serialize)]
pub struct BasisReport {
    /// Relative RMSE against the path-traced reference.
    pub rel_rmse: f64,
    /// 8-bit storage per texel as RGB8 (PNG): 3 bytes per coefficient (RGBA8 KTX2 stores 4).
    pub bytes_per_texel: usize,
    /// Coefficients per channel.
    pub coefficients: usize,
    /// The image, relative to the output directory.
    pub image: String,
}

/// The reference's entry in `report.json`.
#[derive(Debug, Serialize)]
pub struct ReferenceReport {
    /// The image.
    pub image: String,
    /// Path-traced samples per pixel.
    pub samples: u32,
}

/// `report.json`.
#[derive(Debug, Serialize)]
pub struct SurfaceRenderReport {
    /// Per basis (and `lightmap` / `lightmap4`, the modified H-basis's lower levels of detail).
    pub bases: BTreeMap<String, BasisReport>,
    /// Invalid texels of the bakes, read from the EXR maps (sum over objects; largest over
    /// the bases, which share the geometry and sample points).
    pub invalid_texels: u64,
    /// The reference.
    pub reference: ReferenceReport,
    /// Pixels showing lightmapped surfaces (those the RMSE runs over).
    pub pixels: usize,
    /// The normal map used.
    pub normal_map: String,
}

/// The maps of one basis found in the directory.
struct BasisMaps {
    /// The EXR file they came from.
    path: PathBuf,
    tag: BasisChoice,
    basis: Box<dyn HemiBasis>,
    maps: Vec<CoefficientMap>,
}

/// Reads every lightvol surface EXR in `dir` (sorted by file name), with the invalid texel
/// count of the bakes (taken from the EXR files: the sum over objects, the largest over the
/// bases, which share the geometry and sample points).
fn read_dir_maps(dir: &Path) -> anyhow::Result<(Vec<BasisMaps>, u64)> {
    let mut paths: Vec<PathBuf> = std::fs::read_dir(dir)
        .with_context(|| format!("--surface: reading {}", dir.display()))?
        .filter_map(Result::ok)
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|e| e.eq_ignore_ascii_case("exr")))
        .collect();
    paths.sort();
    let mut out: Vec<BasisMaps> = Vec::new();
    let mut invalid = 0u64;
    for p in paths {
        let maps = match read_surface_exr(&p) {
            Ok(m) => m,
            Err(SurfaceError::Exr { .. }) => {
                eprintln!("note: skipping {} (not a lightvol surface EXR)", p.display());
                continue;
            }
            Err(e) => return Err(e).with_context(|| format!("reading {}", p.display())),
        };
        let Some(first) = maps.first() else { continue };
        let tag = first.basis;
        let basis = first.basis().with_context(|| format!("{}", p.display()))?;
        if maps.iter().any(|m| m.basis != tag) {
            bail!("{}: objects use different bases", p.display());
        }
        if out.iter().any(|b| b.tag == tag) {
            bail!("{}: a second set of {tag} maps in {}", p.display(), dir.display());
        }
        invalid = invalid.max(maps.iter().map(|m| m.invalid.invalid_texels).sum());
        out.push(BasisMaps { path: p, tag, basis, maps });
    }
    if out.is_empty() {
        bail!(
            "--surface: no coefficient maps in {} (run lightvol bake-surface -o {} first)",
            dir.display(),
            dir.display()
        );
    }
    Ok((out, invalid))
}

/// The first part in which two lighting fingerprints differ (`LightingRecord::diff`,
/// prefixed `"LA vs LB: "`), or both whole texts if either does not read as a record.
fn lighting_difference(a: &str, b: &str, la: &str, lb: &str) -> String {
    match (a.parse::<LightingRecord>(), b.parse::<LightingRecord>()) {
        (Ok(ra), Ok(rb)) => format!("{la} vs {lb}: {}", ra.diff(&rb).unwrap_or_else(|| "equal".into())),
        _ => format!("{la}: {a}, {lb}: {b}"),
    }
}

fn file_name(p: &Path) -> String {
    p.file_name().map_or_else(|| p.display().to_string(), |f| f.to_string_lossy().into_owned())
}

/// Checks that every map in `sets` was baked under one lighting, and that it is the lighting
/// of `scene` with the maps' bounce count; returns that bounce count (for the reference).
fn check_lighting(
    sets: &[BasisMaps],
    dir: &Path,
    scene: &lightvol_sampler::Scene,
) -> anyhow::Result<TransportSettings> {
    let first = &sets[0];
    let lighting = &first.maps[0].lighting;
    for s in sets {
        if let Some(m) = s.maps.iter().find(|m| &m.lighting != lighting) {
            bail!(
                "--surface: the maps in {} were baked under different lighting ({} vs {}: {}); re-bake or remove the stale file",
                dir.display(),
                first.path.display(),
                s.path.display(),
                lighting_difference(lighting, &m.lighting, &file_name(&first.path), &file_name(&s.path))
            );
        }
    }
    let bounces = lighting.parse::<LightingRecord>().ok().and_then(|r| r.transport()).with_context(|| {
        format!("{}: the maps' lighting record has no bounce count ('{lighting}')", first.path.display())
    })?;
    let own = lighting_fingerprint(scene, &bounces);
    if &own != lighting {
        bail!(
            "--surface: the maps in {} were baked under other lighting than this render's scene and lights ({}); pass the bake's --sky/--sun/--ground or re-bake",
            dir.display(),
            lighting_difference(lighting, &own, "maps", "render")
        );
    }
    Ok(bounces)
}

/// Equally sized images side by side (4 columns, 2-pixel black gaps), row by row.
fn sheet(images: &[&Rgb32]) -> Rgb32 {
    const COLS: usize = 4;
    const GAP: usize = 2;
    let (w, h) = (images[0].width, images[0].height);
    let cols = COLS.min(images.len());
    let rows = images.len().div_ceil(COLS);
    let mut out = Rgb32::new(cols * w + (cols - 1) * GAP, rows * h + (rows - 1) * GAP);
    for (k, img) in images.iter().enumerate() {
        let (ox, oy) = ((k % COLS) * (w + GAP), (k / COLS) * (h + GAP));
        for y in 0..h {
            for x in 0..w {
                out.set(ox + x, oy + y, img.pixels[y * w + x]);
            }
        }
    }
    out
}

/// What a camera ray sees.
enum PixelHit {
    /// Sky or a surface that is not lightmapped: its final colour.
    Other([f32; 3]),
    /// A lightmapped surface.
    Lightmapped { tri: u32, bary: [f64; 2], object: usize, uv: [f64; 2], n_t: [f64; 3], albedo: [f64; 3] },
}

/// Runs `lightvol render --surface`.
pub fn run(args: &RenderArgs, dir: &Path, normal_map: &str) -> anyhow::Result<ExitCode> {
    args.size(None)?;
    if args.reference_samples == 0 {
        bail!("--reference-samples must be at least 1");
    }
    let nmap = NormalMap::parse(normal_map)?;
    // Default `-o` of the volume render is a file name; a surface render writes a folder.
    let out_dir = if args.output == Path::new("render.png") {
        PathBuf::from("surface_render")
    } else {
        args.output.clone()
    };
    if out_dir.exists() && !out_dir.is_dir() {
        bail!("output {} exists and is not a directory", out_dir.display());
    }
    let (sets, invalid_texels) = read_dir_maps(dir)?;
    let loaded = args.scene.load_flattened()?;
    // The reference is traced with the maps' bounce count, under the same lighting.
    let bounces = check_lighting(&sets, dir, &loaded.scene)?;
    let uv_set = sets[0].maps[0].uv_set;
    let quantity = sets[0].maps[0].quantity;
    let geo = SurfaceGeometry::new(&loaded.scene, uv_set).context("lightmap objects of the scene")?;
    for s in &sets {
        if s.maps.len() != geo.objects().len()
            || s.maps.iter().zip(geo.objects()).any(|(m, o)| m.object != o.name)
            || s.maps.iter().any(|m| m.uv_set != uv_set || m.quantity != quantity)
        {
            bail!(
                "the {} maps do not match the scene's lightmap objects (baked from another scene or UV set?)",
                s.tag
            );
        }
    }
    let (cam, aspect) = match &args.camera {
        Some(c) => resolve_camera(c, &loaded.scene, loaded.frame)?,
        None => {
            let (lo, hi) = loaded.scene.bounds();
            (Camera::overview(lo, hi)?, None)
        }
    };
    let (w, h) = args.size(aspect)?;
    // Radiance leaving a Lambertian surface: albedo · E / π (irradiance maps) or albedo · B.
    let to_radiance = match quantity {
        Quantity::Irradiance => std::f64::consts::FRAC_1_PI,
        Quantity::Radiosity => 1.0,
    };
    let lightmap_set = sets.iter().position(|s| s.tag.family() == BasisFamily::HBasisMod);
    // With a modified H-basis map: its lowest levels of detail (Listing 2.2's stop points),
    // `lightmap` (H1) and `lightmap4` (H1-H4).
    let lods: &[(&str, Lod)] =
        if lightmap_set.is_some() { &[("lightmap", Lod::Lightmap), ("lightmap4", Lod::Linear)] } else { &[] };
    let n_images = sets.len() + lods.len();
    // Per pixel: reference colour, then one colour per image; lightmapped flag.
    let rows = with_threads(args.threads, || -> Vec<(bool, [f32; 3], Vec<[f32; 3]>)> {
        let tracer = Tracer::new(&loaded.scene);
        let transport = Transport::new(&loaded.scene, &tracer, bounces);
        let scene = &loaded.scene;
        (0..w * h)
            .into_par_iter()
            .map(|i| {
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
                                let nm_uv =
                                    if t.uv.iter().all(|u| *u == t.uv[0]) { uv } else { base.to_array() };
                                PixelHit::Lightmapped {
                                    tri,
                                    bary: hit.bary,
                                    object,
                                    uv,
                                    n_t: nmap.normal(nm_uv),
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
                            &geo,
                            tri,
                            bary,
                            n_t,
                            quantity,
                            args.reference_samples,
                            args.seed,
                            hash2(0x5eed_5a7f, u64::from(i)),
                        );
                        let mut cols: Vec<[f32; 3]> = sets
                            .iter()
                            .map(|s| shade(s.maps[object].shade(s.basis.as_ref(), uv, n_t)))
                            .collect();
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
            .collect()
    })?;

    // Errors over lightmapped pixels.
    let mut names: Vec<(String, usize)> = sets.iter().map(|s| (s.tag.tag(), s.basis.len())).collect();
    names.extend(lods.iter().map(|&(name, lod)| (name.to_owned(), lod.coefficients())));
    let mut err2 = vec![0.0f64; n_images];
    let mut ref2 = 0.0f64;
    let mut pixels = 0usize;
    for (lm, r, cols) in &rows {
        if !lm {
            continue;
        }
        pixels += 1;
        for c in 0..3 {
            ref2 += f64::from(r[c]).powi(2);
            for (e, col) in err2.iter_mut().zip(cols) {
                *e += f64::from(col[c] - r[c]).powi(2);
            }
        }
    }
    if pixels == 0 {
        bail!("no lightmapped surface is visible from the camera (use --camera)");
    }
    let mut reference = Rgb32::new(w as usize, h as usize);
    let mut images: Vec<Rgb32> = (0..n_images).map(|_| Rgb32::new(w as usize, h as usize)).collect();
    for (i, (_, r, cols)) in rows.iter().enumerate() {
        reference.pixels[i] = *r;
        for (img, c) in images.iter_mut().zip(cols) {
            img.pixels[i] = *c;
        }
    }
    let exposure = args.exposure.unwrap_or_else(|| {
        let mean: f64 =
            rows.iter().filter(|r| r.0).map(|r| f64::from(r.1[0] + r.1[1] + r.1[2]) / 3.0).sum::<f64>()
                / pixels as f64;
        if mean > 0.0 { (0.35 / mean) as f32 } else { 1.0 }
    });
    let mut bases = BTreeMap::new();
    for ((name, k), e) in names.iter().zip(&err2) {
        let rel_rmse = if ref2 > 0.0 { (e / ref2).sqrt() } else { 0.0 };
        bases.insert(
            name.clone(),
            BasisReport { rel_rmse, bytes_per_texel: 3 * k, coefficients: *k, image: format!("{name}.png") },
        );
    }
    let report = SurfaceRenderReport {
        bases,
        invalid_texels,
        reference: ReferenceReport { image: "reference.png".into(), samples: args.reference_samples },
        pixels,
        normal_map: normal_map.to_owned(),
    };
    std::fs::create_dir_all(&out_dir).with_context(|| format!("creating {}", out_dir.display()))?;
    write_png_linear(&out_dir.join("reference.png"), &reference, exposure)?;
    for ((name, _), img) in names.iter().zip(&images) {
        write_png_linear(&out_dir.join(format!("{name}.png")), img, exposure)?;
    }
    let mut tiles = vec![&reference];
    tiles.extend(images.iter());
    write_png_linear(&out_dir.join("sheet.png"), &sheet(&tiles), exposure)?;
    write_atomic(&out_dir.join("report.json"), serde_json::to_string_pretty(&report)?.as_bytes())?;
    for (name, b) in &report.bases {
        eprintln!("{name:>12}: rel RMSE {:.4} ({} bytes/texel)", b.rel_rmse, b.bytes_per_texel);
    }
    eprintln!(
        "wrote {} ({} lightmapped pixels, {} invalid texels)",
        out_dir.display(),
        pixels,
        invalid_texels
    );
    Ok(ExitCode::SUCCESS)
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
        let dir = std::env::temp_dir().join(format!("lightvol-nm-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("n.png");
        // 2 × 1: left texel flat (128, 128, 255), right texel tilted towards +x.
        let tilted = DVec3::new(0.6, 0.0, 0.8);
        let enc = |v: f64| ((v + 1.0) * 127.5).round() as u8;
        let rgb = [128, 128, 255, enc(tilted.x), enc(tilted.y), enc(tilted.z)];
        image::save_buffer(&path, &rgb, 2, 1, image::ExtendedColorType::Rgb8).unwrap();
        let nm = NormalMap::parse(path.to_str().unwrap()).unwrap();
        std::fs::remove_dir_all(&dir).unwrap();
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
        assert!(NormalMap::parse("procedural:x").is_err());
        assert!(NormalMap::parse("procedural:2:-1").is_err());
        assert!(NormalMap::parse("proceduralx").is_err());
        let e = NormalMap::parse("/nonexistent/normals.png").unwrap_err();
        assert!(format!("{e:#}").contains("normals.png"));
    }
}
