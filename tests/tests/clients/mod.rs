//! Running the engine clients (`clients/three` in Debian's Chromium, `clients/bevy` on
//! lavapipe) on a scene and a volume export, and reading their frames: shared by the tests
//! that compare an engine's frame with lightvol's emulation of it and with path tracing.
//!
//! A missing browser, Node.js package or Bevy build skips a client loudly; with
//! `LIGHTVOL_REQUIRE_CHROMIUM=1` or `LIGHTVOL_REQUIRE_BEVY=1` (set by `.ci/run`) it fails.

use std::path::{Path, PathBuf};
use std::process::Command;

use glam::DVec3;
use lightvol_scene::bvh::Tracer;
use lightvol_scene::load::{LoadOptions, load_scene};
use lightvol_view::camera::Camera;
use lightvol_view::render::visible_surface;
use lightvol_volume::up_axis::UpAxis;

use crate::common::s;

/// The workspace root.
pub fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// A linear float image with its alpha, rows top to bottom.
pub struct Frame {
    pub rgb: Vec<[f64; 3]>,
    pub alpha: Vec<f64>,
}

/// One camera on one scene: what every client and `lightvol render` are given.
pub struct Shot<'a> {
    /// The folder holding the scene, its resources and the exports.
    pub files: &'a Path,
    /// The scene's file name in `files`.
    pub scene: &'a str,
    /// Eye and target in the file's frame (+Y up), vertical field of view in degrees.
    pub eye: [f64; 3],
    pub target: [f64; 3],
    pub fov: f64,
    pub width: u32,
    pub height: u32,
}

impl Shot<'_> {
    /// `render`'s `--camera` specification of the shot.
    pub fn camera_spec(&self) -> String {
        format!("{}:{}:{}", csv(self.eye), csv(self.target), self.fov)
    }
}

/// `X,Y,Z`.
pub fn csv(v: [f64; 3]) -> String {
    format!("{},{},{}", v[0], v[1], v[2])
}

/// The engine clients.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Engine {
    Three,
    Bevy,
}

impl Engine {
    /// The client's name, in file names and messages.
    pub fn name(self) -> &'static str {
        match self {
            Self::Three => "three",
            Self::Bevy => "bevy",
        }
    }

    /// The variable that makes a client that cannot run a failure.
    pub fn require(self) -> &'static str {
        match self {
            Self::Three => "LIGHTVOL_REQUIRE_CHROMIUM",
            Self::Bevy => "LIGHTVOL_REQUIRE_BEVY",
        }
    }

    /// The command that renders `shot` lit by the export `texture` (in `shot.files`) with
    /// the negative control `control` (and spheres) to `out`, or why it cannot run.
    fn command(
        self,
        shot: &Shot<'_>,
        texture: &str,
        out: &Path,
        control: &str,
        spheres: Option<&str>,
    ) -> Result<Command, String> {
        let mut c = match self {
            Self::Three => {
                let dir = root().join("clients/three");
                for need in ["node_modules/three/package.json", "node_modules/playwright-core/package.json"] {
                    if !dir.join(need).exists() {
                        return Err(format!("clients/three/{need} is missing (run npm ci in clients/three)"));
                    }
                }
                let chromium =
                    std::env::var("LIGHTVOL_CHROMIUM").unwrap_or_else(|_| "/usr/bin/chromium".into());
                if !Path::new(&chromium).exists() {
                    return Err(format!("no Chromium at {chromium}"));
                }
                let mut c = Command::new("node");
                c.arg(dir.join("render.mjs"));
                c.args(["--files", s(shot.files), "--scene", shot.scene, "--grid", texture]);
                c
            }
            Self::Bevy => {
                let target =
                    std::env::var("CARGO_TARGET_DIR").map_or_else(|_| root().join("target"), PathBuf::from);
                let exe = std::env::var("LIGHTVOL_BEVY_CLIENT")
                    .map_or_else(|_| target.join("bevy-client/release/lightvol-bevy-client"), PathBuf::from);
                if !exe.exists() {
                    return Err(format!(
                        "no Bevy client at {} (cargo build --release --manifest-path clients/bevy/Cargo.toml --target-dir {})",
                        exe.display(),
                        target.join("bevy-client").display()
                    ));
                }
                let mut c = Command::new(exe);
                c.env("WGPU_BACKEND", "vulkan");
                c.args(["--assets", s(shot.files), "--scene", shot.scene, "--volume", texture]);
                c
            }
        };
        c.args(["--eye", &csv(shot.eye), "--target", &csv(shot.target), "--fov", &shot.fov.to_string()]);
        c.args(["--width", &shot.width.to_string(), "--height", &shot.height.to_string()]);
        c.args(["--control", control]);
        c.arg("--out").arg(out);
        if let Some(sp) = spheres {
            c.args(["--spheres", sp]);
        }
        Ok(c)
    }

    /// Renders one frame of `shot` lit by `texture`; `None` (after a loud message) when
    /// the client cannot run here and is not required.
    pub fn render(
        self,
        shot: &Shot<'_>,
        texture: &str,
        control: &str,
        spheres: Option<&str>,
    ) -> Option<Frame> {
        let stem = texture.trim_end_matches(".ktx2");
        let out = shot.files.join(format!(
            "{}-{stem}-{control}{}.pfm",
            self.name(),
            if spheres.is_some() { "-spheres" } else { "" }
        ));
        let mut cmd = match self.command(shot, texture, &out, control, spheres) {
            Ok(c) => c,
            Err(why) => {
                assert!(
                    std::env::var(self.require()).as_deref() != Ok("1"),
                    "{} client required ({}=1): {why}",
                    self.name(),
                    self.require()
                );
                eprintln!(
                    "SKIPPED: the {} client cannot run here: {why}; set {}=1 to make this a failure",
                    self.name(),
                    self.require()
                );
                return None;
            }
        };
        let o = cmd.output().unwrap_or_else(|e| panic!("{} client: {e}", self.name()));
        assert!(
            o.status.success(),
            "{} client failed: {}\n{}",
            self.name(),
            String::from_utf8_lossy(&o.stdout),
            String::from_utf8_lossy(&o.stderr)
        );
        Some(read_frame(&out, shot.width, shot.height))
    }
}

/// A PFM frame of `width` × `height`, rows top to bottom.
fn read_pfm(path: &Path, width: u32, height: u32) -> Vec<[f64; 3]> {
    let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut lines = 0;
    let mut at = 0;
    while lines < 3 {
        if bytes[at] == b'\n' {
            lines += 1;
        }
        at += 1;
    }
    let header = std::str::from_utf8(&bytes[..at]).unwrap();
    let dims: Vec<usize> =
        header.lines().nth(1).unwrap().split_whitespace().map(|v| v.parse().unwrap()).collect();
    assert!(header.starts_with("PF\n") && header.lines().nth(2) == Some("-1.0"), "{header:?}");
    let (w, h) = (dims[0], dims[1]);
    assert_eq!((w, h), (width as usize, height as usize));
    let f = |i: usize| f64::from(f32::from_le_bytes(bytes[at + 4 * i..at + 4 * i + 4].try_into().unwrap()));
    // PFM rows run bottom to top.
    (0..w * h)
        .map(|i| {
            let (x, y) = (i % w, i / w);
            let k = (h - 1 - y) * w + x;
            [f(3 * k), f(3 * k + 1), f(3 * k + 2)]
        })
        .collect()
}

/// A client's frame and its alpha (`FRAME.pfm`, `FRAME.alpha.pfm`).
fn read_frame(out: &Path, width: u32, height: u32) -> Frame {
    let rgb = read_pfm(out, width, height);
    let alpha = read_pfm(&out.with_extension("alpha.pfm"), width, height).iter().map(|p| p[0]).collect();
    Frame { rgb, alpha }
}

/// An EXR frame written by `lightvol render`.
pub fn read_exr(path: &Path) -> Frame {
    let img = exr::prelude::read_all_flat_layers_from_file(path).expect("an EXR");
    let layer = &img.layer_data[0];
    let ch = |name: &str| -> Vec<f64> {
        let c = layer.channel_data.list.iter().find(|c| c.name.to_string() == name).expect(name);
        c.sample_data.values_as_f32().map(f64::from).collect()
    };
    let (r, g, b) = (ch("R"), ch("G"), ch("B"));
    Frame { rgb: (0..r.len()).map(|i| [r[i], g[i], b[i]]).collect(), alpha: ch("A") }
}

/// `lightvol render` of `shot` (radiosity, so that it compares with the clients' frames)
/// with extra arguments, written to `name` in `shot.files`.
pub fn render_view(shot: &Shot<'_>, name: &str, extra: &[&str]) -> Frame {
    let out = shot.files.join(name);
    let cam = shot.camera_spec();
    let (w, h) = (shot.width.to_string(), shot.height.to_string());
    let scene = shot.files.join(shot.scene);
    let mut args = vec!["render", s(&scene), "--quantity", "radiosity"];
    args.extend(["--camera", &cam, "--width", &w, "--height", &h, "--quiet", "-o", s(&out)]);
    args.extend(extra);
    crate::common::ok(&args);
    read_exr(&out)
}

/// The path-traced view of `shot` under `light` (`render`'s light options), 256 samples a
/// pixel: the ground truth the clients' frames are measured against.
pub fn path_traced(shot: &Shot<'_>, light: &[&str]) -> Frame {
    let mut extra = vec!["--reference", "--reference-samples", "256"];
    extra.extend(light);
    render_view(shot, "reference.exr", &extra)
}

/// Relative RMSE of `got` against `want` over the pixels both see lit and `interior`
/// admits, and how many pixels entered.
pub fn frame_rmse(got: &Frame, want: &Frame, interior: &[bool]) -> (f64, usize) {
    let (mut num, mut den, mut n) = (0.0, 0.0, 0);
    for i in 0..want.rgb.len() {
        let lit = want.alpha[i] == 1.0 && want.rgb[i].iter().any(|&v| v > 0.0);
        if !lit || got.alpha[i] < 0.5 || !interior[i] {
            continue;
        }
        n += 1;
        for c in 0..3 {
            num += (got.rgb[i][c] - want.rgb[i][c]).powi(2);
            den += want.rgb[i][c].powi(2);
        }
    }
    ((num / den).sqrt(), n)
}

/// The pixels of `shot` away from geometric and material edges: the 8 neighbours' hits
/// have the pixel's albedo and lie near its tangent plane with normals within ~8°, so that a
/// rasteriser (snapping vertices to a sub-pixel grid, in f32) and lightvol's f64 ray caster
/// see the same surface at the pixel centre. (Without the albedo test one pixel on the edge
/// between the living room's wall and ceiling, albedos 0.42 and 0.51, held most of
/// three.js's frame error.)
pub fn edge_mask(shot: &Shot<'_>) -> Vec<bool> {
    let scene = load_scene(&shot.files.join(shot.scene), &LoadOptions::default()).unwrap();
    let tracer = Tracer::new(&scene);
    let (w, h) = (shot.width, shot.height);
    let to = |p: [f64; 3]| DVec3::from(UpAxis::Y.to_world(p));
    let cam = Camera::look_at(to(shot.eye), to(shot.target), shot.fov).unwrap();
    let hits: Vec<_> = (0..w * h)
        .map(|i| visible_surface(&scene, &tracer, to(shot.eye), cam.ray(i % w, i / w, w, h)))
        .collect();
    (0..w * h)
        .map(|i| {
            let (x, y) = (i % w, i / w);
            let Some(hit) = &hits[i as usize] else { return false };
            if x == 0 || y == 0 || x + 1 == w || y + 1 == h {
                return false;
            }
            (0..9).all(|k| {
                let (nx, ny) = (x + k % 3 - 1, y + k / 3 - 1);
                hits[(ny * w + nx) as usize].as_ref().is_some_and(|o| {
                    let d = o.position - hit.position;
                    o.albedo == hit.albedo
                        && o.normal.dot(hit.normal) > 0.99
                        && d.dot(hit.normal).abs() <= 0.25 * d.length()
                })
            })
        })
        .collect()
}
