//! Views against answers known in closed form: a ground plane under a uniform sky, shaded by
//! a volume whose irradiance is an exact function of position and normal, and by path
//! tracing.

use lightvol_core::samples::samples;

use std::f64::consts::PI;

use glam::DVec3;
use lightvol_sh::index::sh_index;
use lightvol_volume::{GridSpec, IrradianceVolume};

use super::*;
use lightvol_scene::builder::SceneBuilder;
use lightvol_scene::bvh::Tracer;
use lightvol_scene::lights::Environment;
use lightvol_scene::material::Material;
use lightvol_scene::scene::{Scene, SceneCamera, UpAxis};
use lightvol_scene::transport::{Transport, TransportSettings};

/// Half the side of the ground quad (m).
const HALF: f64 = 10.0;
/// Albedo of the ground.
const ALBEDO: [f64; 3] = [0.5, 0.25, 0.8];
/// Radiance of the sky.
const SKY: [f64; 3] = [1.0, 2.0, 0.5];

/// Relative error allowed between a view shaded by a volume and the closed form: the
/// coefficients are stored in f32 and the trilinear lookup and shading run in f32 (a few
/// roundings of ~6e-8 each over some 30 operations), the hit point comes from an f32
/// intersection test, and the pixel is stored in f32; 1e-5 leaves a margin of ~10× over
/// the ~1e-6 these add up to.
const F32_LOOKUP_TOLERANCE: f64 = 1e-5;

/// Relative error allowed for the path-traced view under a uniform sky: every cosine-sampled
/// ray from the ground escapes, so each sample is exactly π L; what is left is the f64 sum
/// and the f32 pixel (relative 6e-8).
const F32_PIXEL_TOLERANCE: f64 = 2e-7;

/// A single-sided ground quad at z = 0 facing up under the sky (nothing below the horizon),
/// and a camera of the file frame named `top`.
fn ground() -> Scene {
    let mut b = SceneBuilder::new("ground");
    let m = b.add_material(Material::diffuse("ground", ALBEDO)).unwrap();
    let c = [(-HALF, -HALF), (HALF, -HALF), (HALF, HALF), (-HALF, HALF)];
    b.add_quad(c.map(|(x, y)| DVec3::new(x, y, 0.0)), m).unwrap();
    b.environment = Environment::UniformSky { sky: SKY, ground: None };
    b.cameras.push(SceneCamera {
        name: "top".into(),
        position: DVec3::new(0.0, 0.0, 30.0),
        forward: DVec3::NEG_Z,
        up: DVec3::Y,
        yfov: 0.5,
        aspect: Some(2.0),
    });
    b.build().unwrap()
}

/// Scale of the linear field per channel.
const CHANNEL: [f64; 3] = [1.0, 0.5, 2.0];
/// Radiance of the field: `L(p, ω) = (A0 + A1 x + A2 y + B ω_z) · CHANNEL`.
const A0: f64 = 2.0;
const A1: f64 = 0.05;
const A2: f64 = -0.03;
const B: f64 = 0.6;

/// The field's irradiance at `p` for the normal `±Z` (`up`): ∫ L cos θ dω over the
/// hemisphere = π a(p) ± 2π B / 3.
fn field_irradiance(p: DVec3, up: bool) -> [f64; 3] {
    let a = A0 + A1 * p.x + A2 * p.y;
    let b = if up { B } else { -B };
    CHANNEL.map(|c| c * (PI * a + 2.0 * PI * b / 3.0))
}

/// A volume holding the field's SH projection at every node: `L_00 = 2√π a`,
/// `L_10 = √(4π/3) B`. It is linear in position, which trilinear interpolation reproduces.
fn field_volume() -> IrradianceVolume {
    let grid = GridSpec::new([-HALF, -HALF, -1.0], [HALF, HALF, 3.0], [5, 6, 3]).unwrap();
    IrradianceVolume::from_fn(grid, 9, |p| {
        let a = A0 + A1 * p[0] + A2 * p[1];
        let mut c = vec![[0.0; 3]; 9];
        c[sh_index(0, 0)] = CHANNEL.map(|k| k * 2.0 * PI.sqrt() * a);
        c[sh_index(1, 0)] = CHANNEL.map(|k| k * (4.0 * PI / 3.0).sqrt() * B);
        c
    })
    .unwrap()
}

/// Where the ray from `eye` along `d` meets the ground quad, when it does (away from its
/// edges, where the f32 tracer and this f64 answer may disagree).
fn ground_hit(eye: DVec3, d: DVec3) -> Option<Option<DVec3>> {
    if d.z == 0.0 || (eye.z > 0.0) == (d.z > 0.0) {
        return Some(None);
    }
    let p = eye + d * (-eye.z / d.z);
    let edge = HALF - p.x.abs().max(p.y.abs());
    if edge.abs() < 1e-3 {
        return None;
    }
    Some((edge > 0.0).then_some(p))
}

fn close(got: f32, want: f64, rel: f64) -> bool {
    (f64::from(got) - want).abs() <= rel * want.abs().max(1e-3)
}

/// A view from above shaded by the linear field: every ground pixel is albedo · E / π with
/// E the closed form at the pixel's hit point and normal +Z, every sky pixel the sky's
/// radiance (shaded) or zero (radiosity); from below, the pixels see the quad's back face
/// and hold the irradiance for the normal -Z.
#[test]
fn volume_views_of_a_linear_field_are_exact() {
    let scene = ground();
    let tracer = Tracer::new(&scene);
    let vol = field_volume();
    let check = |camera: &Camera, quantity: Quantity, up: bool| {
        let config = ViewConfig { width: 48, height: 32, quantity };
        let img = render_volume(&scene, &tracer, camera, &config, &vol).unwrap();
        let (mut ground_px, mut sky_px) = (0, 0);
        for y in 0..32 {
            for x in 0..48 {
                let i = (y * 48 + x) as usize;
                let d = camera.ray(x, y, 48, 32);
                let Some(hit) = ground_hit(camera.eye(), d) else { continue };
                assert_eq!(img.surface[i], hit.is_some(), "pixel {x},{y}");
                let want: [f64; 3] = match hit {
                    Some(p) => {
                        ground_px += 1;
                        let e = field_irradiance(p, up);
                        std::array::from_fn(|c| quantity.value(0.0, ALBEDO[c], e[c]))
                    }
                    None => {
                        sky_px += 1;
                        let sky = scene.environment.radiance(d);
                        if quantity == Quantity::Shaded { sky } else { [0.0; 3] }
                    }
                };
                for c in 0..3 {
                    let got = img.pixels[i][c];
                    assert!(
                        close(got, want[c], F32_LOOKUP_TOLERANCE),
                        "pixel {x},{y}[{c}]: {got} vs {want:?}"
                    );
                }
            }
        }
        assert!(ground_px > 200 && sky_px > 50, "{ground_px} ground and {sky_px} sky pixels");
        img
    };
    let above = Camera::look_at(DVec3::new(-3.0, -16.0, 6.0), DVec3::new(1.0, 0.0, 0.0), 70.0).unwrap();
    let shaded = check(&above, Quantity::Shaded, true);
    let radiosity = check(&above, Quantity::Radiosity, true);
    // Radiosity is shaded less the sky, pixel for pixel (the ground emits nothing).
    for i in 0..shaded.pixels.len() {
        if shaded.surface[i] {
            assert_eq!(shaded.pixels[i], radiosity.pixels[i]);
        }
    }
    let below = Camera::look_at(DVec3::new(-3.0, -16.0, -6.0), DVec3::new(1.0, 0.0, 0.0), 70.0).unwrap();
    check(&below, Quantity::Irradiance, false);
}

/// The path-traced view of the ground under the sky is the closed form (every sample is
/// π L, so a ground pixel is albedo · L); it is the same image on 1 and 2 threads, and its
/// progress reports count the pixels up to the total.
#[test]
fn reference_view_under_a_uniform_sky_is_exact_and_thread_independent() {
    let scene = ground();
    let tracer = Tracer::new(&scene);
    let transport = Transport::new(&scene, &tracer, TransportSettings::default());
    let camera = Camera::look_at(DVec3::new(-3.0, -16.0, 6.0), DVec3::new(1.0, 0.0, 0.0), 70.0).unwrap();
    let config = ViewConfig { width: 80, height: 60, quantity: Quantity::Shaded };
    let reference = ReferenceConfig { samples: samples(8), seed: 3 };
    let reports = std::sync::Mutex::new(Vec::new());
    let log = |p: lightvol_core::progress::Progress| reports.lock().unwrap().push(p.done);
    let on = |threads: usize, progress: Option<&(dyn Fn(lightvol_core::progress::Progress) + Sync)>| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| render_reference(&transport, &camera, &config, &reference, progress).unwrap())
    };
    let img = on(2, Some(&log));
    let mut ground_px = 0;
    for i in 0..img.pixels.len() {
        if img.surface[i] {
            ground_px += 1;
            for c in 0..3 {
                assert!(
                    close(img.pixels[i][c], ALBEDO[c] * SKY[c], F32_PIXEL_TOLERANCE),
                    "{:?}",
                    img.pixels[i]
                );
            }
        }
    }
    assert!(ground_px > 1000, "{ground_px}");
    assert_eq!(on(1, None), img);
    assert_eq!(*reports.lock().unwrap(), [0, 4096, 4800]);
}

/// A path-traced view with occluders (the maze, several bounces) does not depend on the
/// thread count either.
#[test]
fn reference_view_of_the_maze_is_thread_independent() {
    let maze = lightvol_scene::builtin::maze();
    let tracer = Tracer::new(&maze.scene);
    let transport = Transport::new(&maze.scene, &tracer, TransportSettings::default());
    let (lo, hi) = maze.grid.bounds();
    let camera = Camera::overview(DVec3::from(lo), DVec3::from(hi)).unwrap();
    let config = ViewConfig { width: 24, height: 16, quantity: Quantity::Shaded };
    let reference = ReferenceConfig { samples: samples(4), seed: 1 };
    let on = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| render_reference(&transport, &camera, &config, &reference, None).unwrap())
    };
    let one = on(1);
    assert!(one.surface_pixels() > 0);
    assert_eq!(on(2), one);
}

/// Camera specifications: the look-at form in the file frame, the default field of view,
/// file cameras by index and name with their aspect ratio, and every refusal.
#[test]
fn camera_specs_parse_and_resolve() {
    let scene = ground();
    let spec: CameraSpec = "1,2,3:4,5,6".parse().unwrap();
    assert_eq!(
        spec,
        CameraSpec::LookAt { eye: [1.0, 2.0, 3.0], target: [4.0, 5.0, 6.0], fov_deg: DEFAULT_FOV_DEG }
    );
    // Y up: file (x, y, z) is internal (x, -z, y).
    let (cam, aspect) = spec.resolve(&scene, UpAxis::Y).unwrap();
    assert_eq!((cam.eye(), aspect), (DVec3::new(1.0, -3.0, 2.0), None));
    assert_eq!(cam, Camera::look_at(DVec3::new(1.0, -3.0, 2.0), DVec3::new(4.0, -6.0, 5.0), 50.0).unwrap());
    // The centre of an odd image looks along the view direction.
    assert!((cam.ray(2, 1, 5, 3) - cam.forward()).length() < 1e-15);
    let by_index = "gltf:0".parse::<CameraSpec>().unwrap().resolve(&scene, UpAxis::Z).unwrap();
    let by_name = "gltf:top".parse::<CameraSpec>().unwrap().resolve(&scene, UpAxis::Z).unwrap();
    assert_eq!(by_index, by_name);
    assert_eq!(by_name.1, Some(2.0));
    assert_eq!(by_name.0.forward(), DVec3::NEG_Z);
    assert_eq!("gltf:0".parse::<CameraSpec>().unwrap().file_camera_name(&scene).unwrap(), Some("top"));
    let err = |s: &str| s.parse::<CameraSpec>().and_then(|c| c.resolve(&scene, UpAxis::Z)).unwrap_err();
    assert!(matches!(err("1,2,3"), ViewError::CameraSyntax));
    assert!(matches!(err("1,2,3:4,5,6:7:8"), ViewError::CameraSyntax));
    assert!(matches!(err("1,x,3:4,5,6"), ViewError::CameraNumber { ref text, .. } if text == "x"));
    assert!(matches!(err("1,2:4,5,6"), ViewError::CameraPoint(ref t) if t == "1,2"));
    assert!(matches!(err("1,2,inf:4,5,6"), ViewError::CameraPoint(_)));
    assert!(matches!(err("1,2,3:4,5,6:wide"), ViewError::FovNumber(_)));
    assert!(matches!(err("1,2,3:4,5,6:180"), ViewError::FovRange(180.0)));
    assert!(matches!(err("1,2,3:1,2,3"), ViewError::EyeAtTarget));
    let e = err("gltf:side");
    assert!(matches!(e, ViewError::NoSuchCamera { .. }));
    assert_eq!(e.to_string(), "no such camera (the file has 0 'top')");
    assert!(matches!(err("gltf:1"), ViewError::NoSuchCamera { .. }));
    let maze = lightvol_scene::builtin::maze();
    let none = "gltf:0".parse::<CameraSpec>().unwrap().resolve(&maze.scene, UpAxis::Z).unwrap_err();
    assert!(matches!(none, ViewError::NoFileCameras));
    let bad = SceneCamera {
        name: "up".into(),
        position: DVec3::ZERO,
        forward: DVec3::Z,
        up: DVec3::Z,
        yfov: 1.0,
        aspect: None,
    };
    assert!(matches!(Camera::from_scene(&bad), Err(ViewError::UpAlongView)));
    let config = |width, height| ViewConfig { width, height, quantity: Quantity::Shaded };
    assert!(matches!(config(0, 5).validate(), Err(ViewError::ImageSize { width: 0, height: 5 })));
    assert!(matches!(config(8193, 8193).validate(), Err(ViewError::ImageSize { .. })));
    assert!(config(8192, 8192).validate().is_ok());
    assert_eq!("radiosity".parse::<Quantity>().unwrap(), Quantity::Radiosity);
    assert!(matches!("bright".parse::<Quantity>(), Err(ViewError::UnknownQuantity(_))));
}

/// The default view frames an unplaced grid, else the scene's bounds.
#[test]
fn the_default_view_frames_the_grid_or_the_scene() {
    let maze = lightvol_scene::builtin("maze").unwrap();
    let (lo, hi) = maze.scene.bounds();
    let of_scene = Camera::framing(&maze.scene, None).unwrap();
    assert_eq!(of_scene.eye(), Camera::overview(lo, hi).unwrap().eye());
    let grid = GridSpec::new([0.0, 0.0, 0.0], [4.0, 2.0, 1.0], [3, 3, 3]).unwrap();
    let of_grid = Camera::framing(&maze.scene, Some(&grid)).unwrap();
    // Above the (0, 0) corner side: centre (2, 1), extent (4, 2), eye at
    // (2 - 0.55 · 4, 1 - 0.85 · 2, 1 + 0.6 · 4).
    let eye = of_grid.eye();
    assert!((eye - DVec3::new(-0.2, -0.7, 3.4)).length() < 1e-12, "{eye}");
    assert_ne!(eye, of_scene.eye());
    // A placed grid's box is not in the scene's frame: the scene is framed.
    let placement =
        lightvol_volume::Placement::new([[1.0, 0.0, 0.0, 5.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0]])
            .unwrap();
    let placed = grid.with_placement(placement);
    assert_eq!(Camera::framing(&maze.scene, Some(&placed)).unwrap().eye(), of_scene.eye());
}
