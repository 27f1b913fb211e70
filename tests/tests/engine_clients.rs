//! Real engines draw lightvol volumes: three.js (`clients/three`, in Debian's Chromium) and
//! Bevy (`clients/bevy`, on lavapipe) render the living room lit only by their export of
//! one bake, and each frame is compared with lightvol's emulation of that engine's lookup
//! (`lightvol render --lookup ENGINE --quantity radiosity`, same camera).
//!
//! - Known points: white spheres placed on pixel-centre rays; the pixel sees the point
//!   facing the camera, whose position and normal are exact, so the engine's value there is
//!   compared with `engine_irradiance / π` of the volume itself ([`F16_REL`]). The spheres
//!   are large ([`SPHERE_RADIUS`]): on a small one the normal turns several degrees per
//!   pixel, and a rasteriser's sub-pixel vertex snapping alone moves the value by 0.3%.
//! - The frame: relative RMSE over the pixels both see lit, away from geometric edges
//!   ([`FRAME_RMSE`], [`edge_mask`]).
//! - Negative controls: texels scaled by π, and the atlas laid out along swapped x and z,
//!   must each fail the frame comparison by far.
//!
//! A missing browser, Node.js package or Bevy build skips a client loudly; with
//! `LIGHTVOL_REQUIRE_CHROMIUM=1` or `LIGHTVOL_REQUIRE_BEVY=1` (set by `.ci/run`) it fails.

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

use common::{ok, s};
use glam::DVec3;
use lightvol_scene::bvh::Tracer;
use lightvol_scene::load::{LoadOptions, load_scene};
use lightvol_view::camera::Camera;
use lightvol_view::render::visible_surface;
use lightvol_volume::up_axis::UpAxis;
use lightvol_volume::{AnyVolume, EngineLookup};

/// f16 texels (2^-11 relative per coefficient, summed over nine with factors up to π)
/// and, for Bevy, its RGBA16F render target (another 2^-11): 2e-3 of the value.
const F16_REL: f64 = 2e-3;
/// Relative RMSE allowed between an engine's frame and lightvol's emulation of it over the
/// lit pixels away from edges: the texel and target rounding (≤ 1e-3) and the engines'
/// f32 rasterisation of positions and normals against lightvol's f64 ray hits.
const FRAME_RMSE: f64 = 1e-2;
/// A negative control must miss by at least this much (π-scaled texels give about 2.1,
/// swapped axes tenths).
const CONTROL_RMSE: f64 = 0.05;

const WIDTH: u32 = 160;
const HEIGHT: u32 = 128;
/// The view across the living room (file frame, +Y up), as in the engines' comparison.
const EYE: [f64; 3] = [3.5, 1.5, 10.5];
const TARGET: [f64; 3] = [-3.0, -0.5, -1.0];
const FOV: f64 = 80.0;
/// Pixels whose rays carry the known-point spheres, and the spheres' distance and radius.
const SPHERE_PIXELS: [(u32, u32); 3] = [(40, 70), (80, 64), (115, 50)];
const SPHERE_DISTANCE: f64 = 2.5;
/// (Large enough that the normal turns about 2° per pixel.)
const SPHERE_RADIUS: f64 = 0.6;

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// The shared inputs: the scene, its volume and both exports, in one folder.
struct Bake {
    dir: tempfile::TempDir,
}

fn bake() -> &'static Bake {
    static BAKE: OnceLock<Bake> = OnceLock::new();
    BAKE.get_or_init(|| {
        let dir = tempfile::tempdir().unwrap();
        let scene = dir.path().join("living_room.glb");
        std::fs::copy(root().join("data/scenes/living_room/living_room.glb"), &scene).unwrap();
        let v = dir.path().join("v.exr");
        ok(&["bake", s(&scene), "--light", "sky+indirect", "--samples", "64", "--quiet", "-o", s(&v)]);
        ok(&["export", s(&v), "--format", "three", "-o", s(&dir.path().join("three.ktx2"))]);
        ok(&["export", s(&v), "--format", "bevy", "-o", s(&dir.path().join("bevy.ktx2"))]);
        Bake { dir }
    })
}

/// A linear float image with its alpha, rows top to bottom.
struct Frame {
    rgb: Vec<[f64; 3]>,
    alpha: Vec<f64>,
}

fn read_pfm(path: &Path) -> Vec<[f64; 3]> {
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
    assert_eq!((w, h), (WIDTH as usize, HEIGHT as usize));
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

fn read_frame(out: &Path) -> Frame {
    let rgb = read_pfm(out);
    let alpha = read_pfm(&out.with_extension("alpha.pfm")).iter().map(|p| p[0]).collect();
    Frame { rgb, alpha }
}

fn read_exr(path: &Path) -> Frame {
    let img = exr::prelude::read_all_flat_layers_from_file(path).expect("an EXR");
    let layer = &img.layer_data[0];
    let ch = |name: &str| -> Vec<f64> {
        let c = layer.channel_data.list.iter().find(|c| c.name.to_string() == name).expect(name);
        c.sample_data.values_as_f32().map(f64::from).collect()
    };
    let (r, g, b) = (ch("R"), ch("G"), ch("B"));
    Frame { rgb: (0..r.len()).map(|i| [r[i], g[i], b[i]]).collect(), alpha: ch("A") }
}

fn csv(v: [f64; 3]) -> String {
    format!("{},{},{}", v[0], v[1], v[2])
}

/// The unit ray through the centre of pixel `(x, y)` in the file frame (+Y up), as
/// lightvol's camera casts it (checked against `Camera::ray`).
fn pixel_ray(x: u32, y: u32) -> DVec3 {
    let to = |p: [f64; 3]| DVec3::from(UpAxis::Y.to_world(p));
    let cam = Camera::look_at(to(EYE), to(TARGET), FOV).unwrap();
    let d = cam.ray(x, y, WIDTH, HEIGHT);
    DVec3::from(UpAxis::Y.to_file(d.to_array()))
}

/// The spheres `X,Y,Z,R;...` on the known pixels' rays.
fn spheres() -> (String, Vec<(DVec3, DVec3)>) {
    let eye = DVec3::from(EYE);
    let mut spec = Vec::new();
    let mut points = Vec::new();
    for &(x, y) in &SPHERE_PIXELS {
        let d = pixel_ray(x, y);
        let c = eye + d * SPHERE_DISTANCE;
        spec.push(format!("{},{}", csv(c.to_array()), SPHERE_RADIUS));
        // The point the pixel sees and its normal (file frame).
        points.push((c - d * SPHERE_RADIUS, -d));
    }
    (spec.join(";"), points)
}

/// Pixels away from geometric and material edges: the 8 neighbours' hits have the pixel's
/// albedo and lie near its tangent plane with normals within ~8°, so that a rasteriser
/// (snapping vertices to a sub-pixel grid, in f32) and lightvol's f64 ray caster see the
/// same surface at the pixel centre. (Without the albedo test one pixel on the edge between
/// the living room's wall and ceiling, albedos 0.42 and 0.51, held most of three.js's
/// frame error.)
fn edge_mask() -> Vec<bool> {
    let scene =
        load_scene(&root().join("data/scenes/living_room/living_room.glb"), &LoadOptions::default()).unwrap();
    let tracer = Tracer::new(&scene);
    let to = |p: [f64; 3]| DVec3::from(UpAxis::Y.to_world(p));
    let cam = Camera::look_at(to(EYE), to(TARGET), FOV).unwrap();
    let hits: Vec<_> = (0..WIDTH * HEIGHT)
        .map(|i| visible_surface(&scene, &tracer, to(EYE), cam.ray(i % WIDTH, i / WIDTH, WIDTH, HEIGHT)))
        .collect();
    (0..WIDTH * HEIGHT)
        .map(|i| {
            let (x, y) = (i % WIDTH, i / WIDTH);
            let Some(h) = &hits[i as usize] else { return false };
            if x == 0 || y == 0 || x + 1 == WIDTH || y + 1 == HEIGHT {
                return false;
            }
            (0..9).all(|k| {
                let (nx, ny) = (x + k % 3 - 1, y + k / 3 - 1);
                hits[(ny * WIDTH + nx) as usize].as_ref().is_some_and(|o| {
                    let d = o.position - h.position;
                    o.albedo == h.albedo
                        && o.normal.dot(h.normal) > 0.99
                        && d.dot(h.normal).abs() <= 0.25 * d.length()
                })
            })
        })
        .collect()
}

/// Relative RMSE of `got` against `want` over the pixels both see lit, away from edges,
/// and how many pixels entered.
fn frame_rmse(got: &Frame, want: &Frame, interior: &[bool]) -> (f64, usize) {
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

/// `render` of the bake's scene and camera with extra arguments, as an EXR frame.
fn render_view(name: &str, extra: &[&str]) -> Frame {
    let b = bake();
    let out = b.dir.path().join(name);
    let cam = format!("{}:{}:{FOV}", csv(EYE), csv(TARGET));
    let (w, h) = (WIDTH.to_string(), HEIGHT.to_string());
    let scene = b.dir.path().join("living_room.glb");
    let mut args = vec!["render", s(&scene), "--quantity", "radiosity"];
    args.extend(["--camera", &cam, "--width", &w, "--height", &h, "--quiet", "-o", s(&out)]);
    args.extend(extra);
    ok(&args);
    read_exr(&out)
}

/// The path-traced view under the bake's light (the ground truth), 256 samples a pixel.
fn reference() -> &'static Frame {
    static REFERENCE: OnceLock<Frame> = OnceLock::new();
    REFERENCE.get_or_init(|| {
        render_view(
            "reference.exr",
            &["--reference", "--light", "sky+indirect", "--reference-samples", "256"],
        )
    })
}

/// The view through lightvol's own lookup (validity and node reach) of the same volume.
fn own_view() -> &'static Frame {
    static OWN: OnceLock<Frame> = OnceLock::new();
    OWN.get_or_init(|| {
        let v = bake().dir.path().join("v.exr");
        render_view("lightvol.exr", &["--volume", s(&v), "--lookup", "lightvol"])
    })
}

/// One engine client: how to run it and which lookup it uses.
struct Client {
    name: &'static str,
    lookup: EngineLookup,
    texture: &'static str,
    /// The volume the emulation reads: the export itself where lightvol reads it back
    /// (three's atlas: the same f16 coefficients), else the native bake.
    emulated: &'static str,
    require: &'static str,
    /// Known-point and frame bounds for this client (the same for both today).
    point_rel: f64,
    frame_rmse: f64,
}

impl Client {
    /// The command that renders `control` (and spheres) to `out`, or why it cannot run.
    fn command(&self, out: &Path, control: &str, spheres: Option<&str>) -> Result<Command, String> {
        let b = bake();
        let mut c = match self.name {
            "three" => {
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
                c.arg(dir.join("render.mjs")).args([
                    "--files",
                    s(b.dir.path()),
                    "--scene",
                    "living_room.glb",
                    "--grid",
                ]);
                c.arg(self.texture);
                c
            }
            _ => {
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
                c.args(["--assets", s(b.dir.path()), "--scene", "living_room.glb", "--volume", self.texture]);
                c
            }
        };
        c.args(["--eye", &csv(EYE), "--target", &csv(TARGET), "--fov", &FOV.to_string()]);
        c.args(["--width", &WIDTH.to_string(), "--height", &HEIGHT.to_string(), "--control", control]);
        c.arg("--out").arg(out);
        if let Some(sp) = spheres {
            c.args(["--spheres", sp]);
        }
        Ok(c)
    }

    /// Renders one frame; `None` (after a loud message) when the client cannot run here
    /// and is not required.
    fn render(&self, control: &str, spheres: Option<&str>) -> Option<Frame> {
        let out = bake().dir.path().join(format!(
            "{}-{control}{}.pfm",
            self.name,
            if spheres.is_some() { "-spheres" } else { "" }
        ));
        let mut cmd = match self.command(&out, control, spheres) {
            Ok(c) => c,
            Err(why) => {
                assert!(
                    std::env::var(self.require).as_deref() != Ok("1"),
                    "{} client required ({}=1): {why}",
                    self.name,
                    self.require
                );
                eprintln!(
                    "SKIPPED: the {} client cannot run here: {why}; set {}=1 to make this a failure",
                    self.name, self.require
                );
                return None;
            }
        };
        let o = cmd.output().unwrap_or_else(|e| panic!("{} client: {e}", self.name));
        assert!(
            o.status.success(),
            "{} client failed: {}\n{}",
            self.name,
            String::from_utf8_lossy(&o.stdout),
            String::from_utf8_lossy(&o.stderr)
        );
        Some(read_frame(&out))
    }

    /// lightvol's emulation of this engine's view: `render --lookup`.
    fn emulation(&self) -> Frame {
        let volume = bake().dir.path().join(self.emulated);
        render_view(
            &format!("emu-{}.exr", self.name),
            &["--volume", s(&volume), "--lookup", self.lookup.name()],
        )
    }

    fn check(&self) {
        let Some(frame) = self.render("none", None) else { return };
        let emu = self.emulation();
        let interior = edge_mask();
        let (rmse, n) = frame_rmse(&frame, &emu, &interior);
        eprintln!("{}: relative RMSE {rmse:.5} over {n} lit interior pixels", self.name);
        assert!(n > (WIDTH * HEIGHT / 2) as usize, "{}: only {n} pixels compared", self.name);
        let mut failures = Vec::new();
        if rmse > self.frame_rmse {
            failures.push(format!("frame against lightvol's emulation: relative RMSE {rmse}"));
        }

        // Against the path-traced view: the engine's frame is as far from it as lightvol
        // predicts (the emulation's distance), within the frame's own bound; lightvol's
        // lookup of the same volume is printed beside it.
        let truth = reference();
        let (engine_err, _) = frame_rmse(&frame, truth, &interior);
        let (emu_err, _) = frame_rmse(&emu, truth, &interior);
        let (own_err, _) = frame_rmse(own_view(), truth, &interior);
        eprintln!(
            "{}: against the path-traced view: the engine's frame {engine_err:.4}, its emulation {emu_err:.4}, lightvol's lookup {own_err:.4}",
            self.name
        );
        if (engine_err - emu_err).abs() > self.frame_rmse {
            failures.push(format!("against the path-traced view {engine_err}, emulated {emu_err}"));
        }

        // Known points on the spheres.
        let (spec, points) = spheres();
        let lit = self.render("none", Some(&spec)).expect("the client ran once already");
        let AnyVolume::Uniform(vol) = lightvol_volume::open(&bake().dir.path().join(self.emulated)).unwrap()
        else {
            panic!("a uniform grid")
        };
        for (&(x, y), (p, n)) in SPHERE_PIXELS.iter().zip(&points) {
            let to = |v: DVec3| UpAxis::Y.to_world(v.to_array());
            let e = vol.engine_irradiance(self.lookup, to(*p), to(*n), to(*n));
            let want = e.map(|v| v / std::f64::consts::PI);
            let got = lit.rgb[(y * WIDTH + x) as usize];
            let scale = want.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            assert!(
                scale > 0.0,
                "{}: the sphere point at pixel ({x}, {y}) is unlit in the emulation",
                self.name
            );
            for c in 0..3 {
                let rel = (got[c] - want[c]).abs() / scale;
                eprintln!(
                    "{}: sphere pixel ({x}, {y}) channel {c}: {:.6} against {:.6} (relative {rel:.2e})",
                    self.name, got[c], want[c]
                );
                if rel > self.point_rel {
                    failures.push(format!("sphere pixel ({x}, {y}): {got:?} against {want:?}"));
                }
            }
        }

        // Negative controls.
        for control in ["pi", "swap"] {
            let bad = self.render(control, None).expect("the client ran once already");
            let (rmse, _) = frame_rmse(&bad, &emu, &interior);
            eprintln!("{}: control {control}: relative RMSE {rmse:.4}", self.name);
            if rmse <= CONTROL_RMSE {
                failures.push(format!("the {control} control passes ({rmse})"));
            }
        }
        assert!(failures.is_empty(), "{}: {}", self.name, failures.join("; "));
    }
}

/// The camera ray of the known points is lightvol's own (the spheres sit on the rays the
/// emulation casts): the centre pixel looks along the view direction.
#[test]
fn known_point_rays_are_the_cameras() {
    let d = pixel_ray(WIDTH / 2, HEIGHT / 2);
    let f = (DVec3::from(TARGET) - DVec3::from(EYE)).normalize();
    // Pixel (80, 64) is half a pixel right of and below the image centre.
    assert!(d.dot(f) > 0.9999 && d.dot(f) < 1.0, "{d} against {f}");
}

#[test]
fn three_js_draws_what_lightvol_emulates() {
    Client {
        name: "three",
        lookup: EngineLookup::Three,
        texture: "three.ktx2",
        emulated: "three.ktx2",
        require: "LIGHTVOL_REQUIRE_CHROMIUM",
        point_rel: F16_REL,
        frame_rmse: FRAME_RMSE,
    }
    .check();
}

#[test]
fn bevy_draws_what_lightvol_emulates() {
    Client {
        name: "bevy",
        lookup: EngineLookup::Bevy,
        texture: "bevy.ktx2",
        emulated: "v.exr",
        require: "LIGHTVOL_REQUIRE_BEVY",
        point_rel: F16_REL,
        frame_rmse: FRAME_RMSE,
    }
    .check();
}

/// What docs/ENGINES.md shows users is the clients' code, verbatim.
#[test]
fn the_engine_doc_shows_the_clients_code() {
    let doc = std::fs::read_to_string(root().join("docs/ENGINES.md")).unwrap();
    for file in ["clients/three/lightvol-grid.js", "clients/bevy/src/lightvol_volume.rs"] {
        let code = std::fs::read_to_string(root().join(file)).unwrap();
        assert!(code.lines().count() > 10, "{file} is the client's code");
        assert!(doc.contains(&code), "docs/ENGINES.md does not quote {file} verbatim");
    }
}
