//! `lightvol render`: a pinhole view in which every visible surface is shaded by the
//! volume (irradiance at the hit point and normal, times albedo / π), or by path tracing
//! with `--reference`. This is the "helicopter" view of Kontkanen & Laine 2006 Fig. 1: it
//! shows leaking where a person can see it.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{Context, bail};
use clap::Args;
use lightvol_sampler::{DVec3, Tracer, Transport, reference_irradiance};
use lightvol_sh::lowdisc::hash2;
use lightvol_volume::exr_io::read_exr;
use rayon::prelude::*;

use crate::imaging::Rgb32;
use crate::setup::{SceneArgs, with_threads};

/// `lightvol render`.
#[derive(Debug, Args)]
pub struct RenderArgs {
    /// Scene and lights (must match the volume's bake).
    #[command(flatten)]
    pub scene: SceneArgs,
    /// The baked volume to shade with (required unless --reference).
    #[arg(long)]
    pub volume: Option<PathBuf>,
    /// Camera `EYE_X,EYE_Y,EYE_Z:TARGET_X,TARGET_Y,TARGET_Z[:FOV_DEG]` in the scene file's
    /// frame (glTF +Y up, OBJ per --up), or `gltf:NAME` /
    /// `gltf:INDEX` for a camera of the scene file (its yfov, and its aspect ratio unless
    /// --height is given; `lightvol inspect` lists them). Default: a view from above one
    /// corner of the scene bounds, looking at their centre.
    #[arg(long, allow_hyphen_values = true)]
    pub camera: Option<String>,
    /// Image width.
    #[arg(long, default_value_t = 480)]
    pub width: u32,
    /// Image height (default 320, or width / aspect ratio of a file camera that has one).
    #[arg(long)]
    pub height: Option<u32>,
    /// Shade by path tracing instead of the volume (the ground truth for the same view).
    #[arg(long)]
    pub reference: bool,
    /// Path-traced irradiance samples per pixel with --reference.
    #[arg(long, default_value_t = 64)]
    pub reference_samples: u32,
    /// Exposure multiplier (default: maps the mean pixel to 0.35).
    #[arg(long)]
    pub exposure: Option<f32>,
    /// Seed of the reference's streams.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Worker threads.
    #[arg(long)]
    pub threads: Option<usize>,
    /// Output image: `.png` (sRGB, scaled by --exposure) or `.exr` (linear HDR, unscaled, for
    /// numeric comparison in other tools) (with --surface: output directory, default
    /// `surface_render`).
    #[arg(short, long, default_value = "render.png")]
    pub output: PathBuf,
    /// What a pixel holds: `shaded` (emission + albedo · E / π, what a camera sees),
    /// `radiosity` (albedo · E / π, the reflected light alone) or `irradiance` (E at the
    /// surface point and normal).
    #[arg(long, default_value = "shaded", value_parser = ["shaded", "radiosity", "irradiance"])]
    pub quantity: String,
    /// Path length and direct light of the path-traced view (--reference), as for `bake`.
    #[command(flatten)]
    pub path: crate::setup::PathArgs,
    /// Shade lightmapped surfaces from the coefficient maps that `bake-surface` wrote to this
    /// directory, one image per basis next to a path-traced reference, with `report.json`
    /// (Ishmukhametov 2011 Fig. 3.5).
    #[arg(long, value_name = "DIR", conflicts_with_all = ["volume", "reference"])]
    pub surface: Option<PathBuf>,
    /// Normal map for --surface: `procedural[:FREQ[:SLOPE]]` (default), `flat` or an RGB PNG.
    #[arg(long, requires = "surface")]
    pub normal_map: Option<String>,
}

/// A pinhole camera.
#[derive(Clone, Copy, Debug)]
pub struct Camera {
    eye: DVec3,
    forward: DVec3,
    right: DVec3,
    up: DVec3,
    tan_half: f64,
}

/// Default image height when neither --height nor a file camera's aspect ratio sets it.
pub const DEFAULT_HEIGHT: u32 = 320;

impl RenderArgs {
    /// The image size: `--width`, and `--height`, else `width / aspect` rounded (and at
    /// least one pixel) for a camera with an aspect ratio, else [`DEFAULT_HEIGHT`]. Refuses
    /// empty images and images over 64 Mpixels.
    pub fn size(&self, aspect: Option<f64>) -> anyhow::Result<(u32, u32)> {
        let h = match (self.height, aspect) {
            (Some(h), _) => h,
            (None, Some(a)) => ((f64::from(self.width) / a).round() as u32).max(1),
            (None, None) => DEFAULT_HEIGHT,
        };
        if self.width == 0 || h == 0 || u64::from(self.width) * u64::from(h) > 64 << 20 {
            bail!("image size {}x{h} must be positive and at most 64 Mpixels", self.width);
        }
        Ok((self.width, h))
    }
}

impl Camera {
    /// A camera of the scene file (`SceneCamera`, already in the internal frame).
    pub fn from_scene(c: &lightvol_sampler::SceneCamera) -> anyhow::Result<Self> {
        let forward = c.forward.try_normalize().context("file camera has no view direction")?;
        let right =
            forward.cross(c.up).try_normalize().context("file camera's up is parallel to its view")?;
        let up = right.cross(forward);
        Ok(Self { eye: c.position, forward, right, up, tan_half: (c.yfov / 2.0).tan() })
    }

    /// Resolves `--camera`: `gltf:NAME|INDEX` against the scene's cameras, else
    /// [`parse`](Self::parse). Returns the camera and the file camera's aspect ratio.
    /// `EYE:TARGET` are in the scene file's frame `frame` (glTF +Y up, OBJ per `--up`).
    pub fn resolve(
        s: &str,
        scene: &lightvol_sampler::Scene,
        frame: lightvol_sampler::UpAxis,
    ) -> anyhow::Result<(Self, Option<f64>)> {
        let Some(key) = s.strip_prefix("gltf:") else { return Ok((Self::parse(s, frame)?, None)) };
        let found = match key.parse::<usize>() {
            Ok(i) => scene.cameras.get(i),
            Err(_) => scene.cameras.iter().find(|c| c.name == key),
        };
        let Some(c) = found else {
            let names: Vec<String> =
                scene.cameras.iter().enumerate().map(|(i, c)| format!("{i} '{}'", c.name)).collect();
            if names.is_empty() {
                bail!("--camera {s}: the scene file has no perspective camera");
            }
            bail!("--camera {s}: no such camera (the file has {})", names.join(", "));
        };
        Ok((Self::from_scene(c)?, c.aspect))
    }

    /// Looks from `eye` at `target` with vertical field of view `fov_deg`, +Z up.
    pub fn look_at(eye: DVec3, target: DVec3, fov_deg: f64) -> anyhow::Result<Self> {
        let forward = (target - eye).try_normalize().context("camera eye and target coincide")?;
        let right = forward.cross(DVec3::Z).try_normalize().unwrap_or(DVec3::X);
        let up = right.cross(forward);
        if !(1.0..179.0).contains(&fov_deg) {
            bail!("camera field of view must be in [1, 179] degrees, got {fov_deg}");
        }
        Ok(Self { eye, forward, right, up, tan_half: (fov_deg.to_radians() / 2.0).tan() })
    }

    /// The default view: above a corner of the bounds, looking at their centre.
    pub fn overview(lo: DVec3, hi: DVec3) -> anyhow::Result<Self> {
        let c = (lo + hi) * 0.5;
        let ext = hi - lo;
        let eye = DVec3::new(c.x - 0.55 * ext.x, c.y - 0.85 * ext.y, hi.z + 0.6 * ext.x.max(ext.y));
        Self::look_at(eye, DVec3::new(c.x, c.y, lo.z + 0.15 * ext.z), 50.0)
    }

    /// Parses `EYE:TARGET[:FOV]`, points in the file frame `frame`.
    pub fn parse(s: &str, frame: lightvol_sampler::UpAxis) -> anyhow::Result<Self> {
        let parts: Vec<&str> = s.split(':').collect();
        if !(2..=3).contains(&parts.len()) {
            bail!("--camera: expected EYE_X,EYE_Y,EYE_Z:TARGET_X,TARGET_Y,TARGET_Z[:FOV_DEG]");
        }
        let v = |t: &str| -> anyhow::Result<DVec3> {
            let x: Vec<f64> = t
                .split(',')
                .map(|c| c.trim().parse::<f64>().with_context(|| format!("--camera: '{c}' is not a number")))
                .collect::<anyhow::Result<_>>()?;
            if x.len() != 3 || x.iter().any(|v| !v.is_finite()) {
                bail!("--camera: '{t}' is not three finite numbers");
            }
            Ok(DVec3::from_array(frame.to_world([x[0], x[1], x[2]])))
        };
        let fov = match parts.get(2) {
            Some(f) => f.trim().parse::<f64>().context("--camera: field of view is not a number")?,
            None => 50.0,
        };
        Self::look_at(v(parts[0])?, v(parts[1])?, fov)
    }

    /// The camera position.
    #[must_use]
    pub fn eye(&self) -> DVec3 {
        self.eye
    }

    /// The unit ray direction through pixel `(x, y)` of a `w × h` image.
    #[must_use]
    pub fn ray(&self, x: u32, y: u32, w: u32, h: u32) -> DVec3 {
        let aspect = f64::from(w) / f64::from(h);
        let sx = (2.0 * (f64::from(x) + 0.5) / f64::from(w) - 1.0) * self.tan_half * aspect;
        let sy = (1.0 - 2.0 * (f64::from(y) + 0.5) / f64::from(h)) * self.tan_half;
        (self.forward + self.right * sx + self.up * sy).normalize()
    }
}

/// A uniform or an adaptive (octree) volume, shaded alike.
enum AnyVolume {
    Uniform(lightvol_volume::IrradianceVolume),
    Adaptive(lightvol_volume::AdaptiveVolume),
}

impl AnyVolume {
    fn spec(&self) -> &lightvol_volume::GridSpec {
        match self {
            Self::Uniform(v) => v.spec(),
            Self::Adaptive(v) => v.base().spec(),
        }
    }

    fn irradiance(&self, p: [f32; 3], n: [f32; 3]) -> [f32; 3] {
        match self {
            Self::Uniform(v) => v.irradiance(p, n),
            Self::Adaptive(v) => v.irradiance(p, n),
        }
    }
}

/// Runs `lightvol render`.
pub fn run(args: &RenderArgs) -> anyhow::Result<ExitCode> {
    if let Some(dir) = &args.surface {
        if args.quantity != "shaded" || !args.path.is_default() {
            anyhow::bail!(
                "--quantity, --bounces and --light do not apply to --surface (its maps record their own lighting)"
            );
        }
        return crate::cmd_render_surface::run(args, dir, args.normal_map.as_deref().unwrap_or("procedural"));
    }
    args.size(None)?;
    let loaded = args.scene.load()?;
    let vol = match (&args.volume, args.reference) {
        (Some(p), _) if crate::adaptive_files::is_adaptive(p) => {
            Some(AnyVolume::Adaptive(crate::adaptive_files::read(p)?))
        }
        (Some(p), _) => {
            Some(AnyVolume::Uniform(read_exr(p).with_context(|| format!("reading {}", p.display()))?))
        }
        (None, true) => None,
        (None, false) => bail!("render needs --volume V.exr (or --reference for the path-traced view)"),
    };
    let (cam, aspect) = match &args.camera {
        Some(c) => Camera::resolve(c, &loaded.scene, loaded.frame)?,
        None => {
            // Frame the volume (or the built-in's recommended grid), else the scene.
            let grid = vol.as_ref().map(|v| v.spec().clone()).or_else(|| loaded.grid.clone());
            let (lo, hi) = match grid {
                Some(g) if g.placement().is_none() => {
                    let (a, b) = g.bounds();
                    (DVec3::from(a), DVec3::from(b))
                }
                _ => loaded.scene.bounds(),
            };
            (Camera::overview(lo, hi)?, None)
        }
    };
    let (w, h) = args.size(aspect)?;
    // With --reference the volume (if given) only frames the view.
    let shade_vol = if args.reference { None } else { vol.as_ref() };
    let img = with_threads(args.threads, || -> Rgb32 {
        let tracer = Tracer::new(&loaded.scene);
        let transport = Transport::new(&loaded.scene, &tracer, args.path.transport());
        let scene = &loaded.scene;
        let pixels: Vec<[f32; 3]> = (0..w * h)
            .into_par_iter()
            .map(|i| {
                let (x, y) = (i % w, i / w);
                let d = cam.ray(x, y, w, h);
                let Some(hit) = tracer.closest_hit(cam.eye, d, 0.0, f64::INFINITY) else {
                    // The sky behind the scene is seen, not a surface: only `shaded` shows it.
                    return if args.quantity == "shaded" {
                        scene.environment.radiance(d).map(|v| v as f32)
                    } else {
                        [0.0; 3]
                    };
                };
                let p = cam.eye + d * hit.t;
                // Shade the side the camera sees.
                let n = if hit.normal.dot(d) > 0.0 { -hit.normal } else { hit.normal };
                let albedo = scene.albedo(hit.triangle, hit.bary[0], hit.bary[1]);
                let emission = scene.material_of(hit.triangle).emission;
                let e: [f64; 3] = match shade_vol {
                    Some(v) => v
                        .irradiance(p.as_vec3().to_array(), n.as_vec3().to_array())
                        .map(|c| f64::from(c).max(0.0)),
                    None => {
                        reference_irradiance(
                            &transport,
                            p,
                            n,
                            args.reference_samples,
                            args.seed,
                            hash2(0x7e2d, u64::from(i)),
                        )
                        .0
                    }
                };
                core::array::from_fn(|c| {
                    let reflected = albedo[c] * e[c] / std::f64::consts::PI;
                    (match args.quantity.as_str() {
                        "irradiance" => e[c],
                        "radiosity" => reflected,
                        _ => emission[c] + reflected,
                    }) as f32
                })
            })
            .collect();
        Rgb32 { width: w as usize, height: h as usize, pixels }
    })?;
    let exposure = args.exposure.unwrap_or_else(|| {
        let mean: f64 = img.pixels.iter().map(|p| f64::from(p[0] + p[1] + p[2]) / 3.0).sum::<f64>()
            / img.pixels.len() as f64;
        if mean > 0.0 { (0.35 / mean) as f32 } else { 1.0 }
    });
    crate::imaging::write_image(&args.output, &img, exposure)?;
    eprintln!("wrote {}", args.output.display());
    Ok(ExitCode::SUCCESS)
}
