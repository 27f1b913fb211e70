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

mod clients;
mod common;

use std::sync::OnceLock;

use clients::{Engine, Frame, Shot, csv, edge_mask, frame_rmse, path_traced, render_view, root};
use common::{ok, s};
use glam::DVec3;
use lightvol_view::camera::Camera;
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

/// The shared shot: the living room from [`EYE`] towards [`TARGET`].
fn shot() -> Shot<'static> {
    Shot {
        files: bake().dir.path(),
        scene: "living_room.glb",
        eye: EYE,
        target: TARGET,
        fov: FOV,
        width: WIDTH,
        height: HEIGHT,
    }
}

/// The path-traced view under the bake's light (the ground truth), 256 samples a pixel.
fn reference() -> &'static Frame {
    static REFERENCE: OnceLock<Frame> = OnceLock::new();
    REFERENCE.get_or_init(|| path_traced(&shot(), &["--light", "sky+indirect"]))
}

/// The view through lightvol's own lookup (validity and node reach) of the same volume.
fn own_view() -> &'static Frame {
    static OWN: OnceLock<Frame> = OnceLock::new();
    OWN.get_or_init(|| {
        let v = bake().dir.path().join("v.exr");
        render_view(&shot(), "lightvol.exr", &["--volume", s(&v), "--lookup", "lightvol"])
    })
}

/// One engine client: how to run it and which lookup it uses.
struct Client {
    engine: Engine,
    lookup: EngineLookup,
    texture: &'static str,
    /// The volume the emulation reads: the export itself where lightvol reads it back
    /// (three's atlas: the same f16 coefficients), else the native bake.
    emulated: &'static str,
    /// Known-point and frame bounds for this client (the same for both today).
    point_rel: f64,
    frame_rmse: f64,
}

impl Client {
    /// Renders one frame; `None` (after a loud message) when the client cannot run here
    /// and is not required.
    fn render(&self, control: &str, spheres: Option<&str>) -> Option<Frame> {
        self.engine.render(&shot(), self.texture, control, spheres)
    }

    /// lightvol's emulation of this engine's view: `render --lookup`.
    fn emulation(&self) -> Frame {
        let volume = bake().dir.path().join(self.emulated);
        render_view(
            &shot(),
            &format!("emu-{}.exr", self.engine.name()),
            &["--volume", s(&volume), "--lookup", self.lookup.name()],
        )
    }

    fn check(&self) {
        let Some(frame) = self.render("none", None) else { return };
        let emu = self.emulation();
        let interior = edge_mask(&shot());
        let (rmse, n) = frame_rmse(&frame, &emu, &interior);
        eprintln!("{}: relative RMSE {rmse:.5} over {n} lit interior pixels", self.engine.name());
        assert!(n > (WIDTH * HEIGHT / 2) as usize, "{}: only {n} pixels compared", self.engine.name());
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
            self.engine.name()
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
                self.engine.name()
            );
            for c in 0..3 {
                let rel = (got[c] - want[c]).abs() / scale;
                eprintln!(
                    "{}: sphere pixel ({x}, {y}) channel {c}: {:.6} against {:.6} (relative {rel:.2e})",
                    self.engine.name(),
                    got[c],
                    want[c]
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
            eprintln!("{}: control {control}: relative RMSE {rmse:.4}", self.engine.name());
            if rmse <= CONTROL_RMSE {
                failures.push(format!("the {control} control passes ({rmse})"));
            }
        }
        assert!(failures.is_empty(), "{}: {}", self.engine.name(), failures.join("; "));
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
        engine: Engine::Three,
        lookup: EngineLookup::Three,
        texture: "three.ktx2",
        emulated: "three.ktx2",
        point_rel: F16_REL,
        frame_rmse: FRAME_RMSE,
    }
    .check();
}

#[test]
fn bevy_draws_what_lightvol_emulates() {
    Client {
        engine: Engine::Bevy,
        lookup: EngineLookup::Bevy,
        texture: "bevy.ktx2",
        emulated: "v.exr",
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
