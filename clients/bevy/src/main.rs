//! Renders a glTF scene with Bevy, lit only by a lightvol irradiance volume
//! (`lightvol export --format bevy`), headless into a float image, and writes the frame as
//! a PFM (linear RGB, rows bottom to top) and its alpha as `*.alpha.pfm`.
//!
//! lightvol-bevy-client --assets DIR --scene NAME.glb --volume NAME.ktx2 --eye X,Y,Z
//!     --target X,Y,Z --fov DEG --width W --height H --out FRAME.pfm
//!     [--spheres X,Y,Z,R;...] [--control none|pi|swap]
//!
//! Materials become white-furnace comparable: metallic 0, reflectance 0, no emission, so
//! a pixel is `volume × base colour` (Bevy's `pbr_functions.wgsl` line 715); no ambient
//! light, no tone mapping, no dithering, no MSAA, exposure 1.

mod lightvol_volume;

use std::collections::HashMap;
use std::process::ExitCode;
use std::time::{Duration, Instant};

use bevy::app::ScheduleRunnerPlugin;
use bevy::asset::RenderAssetUsages;
use bevy::camera::{Exposure, Hdr, RenderTarget};
use bevy::core_pipeline::tonemapping::{DebandDither, Tonemapping};
use bevy::gltf::GltfAssetLabel;
use bevy::light::GlobalAmbientLight;
use bevy::prelude::*;
use bevy::render::gpu_readback::{Readback, ReadbackComplete};
use bevy::render::render_resource::{TextureFormat, TextureUsages};
use bevy::render::view::Msaa;
use bevy::window::ExitCondition;
use bevy::world_serialization::WorldAssetRoot;

/// Frames to wait after everything loaded before reading back (pipelines compile in the
/// background); then the frame is taken once three readbacks in a row agree.
const WARMUP_FRAMES: u32 = 10;
const STABLE_READBACKS: u32 = 3;
/// Wall-clock limit: a frame that never settles is an error, not a hang.
const TIMEOUT: Duration = Duration::from_secs(300);

#[derive(Resource, Clone)]
struct Args {
    assets: String,
    scene: String,
    volume: String,
    eye: Vec3,
    target: Vec3,
    fov: f32,
    width: u32,
    height: u32,
    out: String,
    spheres: Vec<Vec4>,
    control: String,
}

fn parse_args() -> Result<Args, String> {
    let mut m = HashMap::new();
    let mut it = std::env::args().skip(1);
    while let Some(k) = it.next() {
        let key = k.strip_prefix("--").ok_or(format!("unexpected argument {k:?}"))?.to_owned();
        m.insert(key, it.next().ok_or(format!("{k} needs a value"))?);
    }
    let get = |k: &str| m.get(k).cloned().ok_or(format!("missing --{k}"));
    let floats = |s: &str| -> Result<Vec<f32>, String> {
        s.split(',').map(|v| v.trim().parse::<f32>().map_err(|e| format!("{s:?}: {e}"))).collect()
    };
    let vec3 = |k: &str| -> Result<Vec3, String> {
        let v = floats(&get(k)?)?;
        if v.len() != 3 {
            return Err(format!("--{k} takes X,Y,Z"));
        }
        Ok(Vec3::new(v[0], v[1], v[2]))
    };
    let spheres = match m.get("spheres") {
        None => Vec::new(),
        Some(s) => s
            .split(';')
            .map(|one| {
                let v = floats(one)?;
                if v.len() != 4 {
                    return Err("--spheres takes X,Y,Z,R;...".to_owned());
                }
                Ok(Vec4::new(v[0], v[1], v[2], v[3]))
            })
            .collect::<Result<_, _>>()?,
    };
    let int = |k: &str| -> Result<u32, String> { get(k)?.parse().map_err(|e| format!("--{k}: {e}")) };
    Ok(Args {
        assets: get("assets")?,
        scene: get("scene")?,
        volume: get("volume")?,
        eye: vec3("eye")?,
        target: vec3("target")?,
        fov: get("fov")?.parse().map_err(|e| format!("--fov: {e}"))?,
        width: int("width")?,
        height: int("height")?,
        out: get("out")?,
        spheres,
        control: m.get("control").cloned().unwrap_or_else(|| "none".into()),
    })
}

#[derive(Resource)]
struct State {
    scene: Handle<WorldAsset>,
    volume: Handle<Image>,
    target: Handle<Image>,
    ready_frames: Option<u32>,
    last: Option<Vec<u8>>,
    stable: u32,
    started: Instant,
    done: Option<Result<(), String>>,
}

fn main() -> ExitCode {
    let args = match parse_args() {
        Ok(a) => a,
        Err(e) => {
            eprintln!("lightvol-bevy-client: {e}");
            return ExitCode::from(2);
        }
    };
    if args.width % 32 != 0 {
        eprintln!("lightvol-bevy-client: --width must be a multiple of 32 (unpadded readback rows)");
        return ExitCode::from(2);
    }
    let mut app = App::new();
    app.add_plugins((
        DefaultPlugins
            .set(WindowPlugin { primary_window: None, exit_condition: ExitCondition::DontExit, ..default() })
            .set(AssetPlugin { file_path: args.assets.clone(), ..default() }),
        ScheduleRunnerPlugin::run_loop(Duration::from_millis(1)),
    ))
    .insert_resource(GlobalAmbientLight { brightness: 0.0, ..default() })
    .insert_resource(args)
    .add_systems(Startup, setup)
    .add_systems(Update, (prepare, finish).chain());
    match app.run() {
        AppExit::Success => ExitCode::SUCCESS,
        AppExit::Error(_) => ExitCode::FAILURE,
    }
}

fn setup(
    mut commands: Commands,
    args: Res<Args>,
    assets: Res<AssetServer>,
    mut images: ResMut<Assets<Image>>,
    mut meshes: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
) {
    let mut image = Image::new_target_texture(args.width, args.height, TextureFormat::Rgba16Float, None);
    image.texture_descriptor.usage |= TextureUsages::COPY_SRC;
    image.asset_usage = RenderAssetUsages::RENDER_WORLD;
    let target = images.add(image);
    commands.spawn((
        Camera3d::default(),
        Camera { clear_color: ClearColorConfig::Custom(Color::NONE), ..default() },
        RenderTarget::Image(target.clone().into()),
        Projection::Perspective(PerspectiveProjection {
            fov: args.fov.to_radians(),
            aspect_ratio: args.width as f32 / args.height as f32,
            near: 0.01,
            far: 1000.0,
            ..default()
        }),
        Transform::from_translation(args.eye).looking_at(args.target, Vec3::Y),
        Hdr,
        Msaa::Off,
        Tonemapping::None,
        DebandDither::Disabled,
        // exposure() = 2^-ev100 / 1.2: ev100 = -log2(1.2) makes it one.
        Exposure { ev100: -(1.2f32).log2() },
    ));
    let scene = assets.load(GltfAssetLabel::Scene(0).from_asset(args.scene.clone()));
    commands.spawn(WorldAssetRoot(scene.clone()));
    lightvol_volume::spawn_lightvol_volume(&mut commands, &assets, &args.assets, &args.volume);
    // The same handle the probe holds (the asset server loads a path once), to wait for it.
    let volume = assets.load(args.volume.clone());
    for s in &args.spheres {
        commands.spawn((
            Mesh3d(meshes.add(Sphere::new(s.w).mesh().uv(256, 128))),
            MeshMaterial3d(materials.add(StandardMaterial {
                base_color: Color::WHITE,
                metallic: 0.0,
                reflectance: 0.0,
                perceptual_roughness: 1.0,
                ..default()
            })),
            Transform::from_translation(s.truncate()),
        ));
    }
    commands.insert_resource(State {
        scene,
        volume,
        target,
        ready_frames: None,
        last: None,
        stable: 0,
        started: Instant::now(),
        done: None,
    });
}

/// Once the scene and the volume have loaded: materials to white-furnace terms, the
/// negative control applied, then a readback of every frame after the warm-up.
fn prepare(
    mut commands: Commands,
    args: Res<Args>,
    assets: Res<AssetServer>,
    mut state: ResMut<State>,
    mut materials: ResMut<Assets<StandardMaterial>>,
    mut images: ResMut<Assets<Image>>,
) {
    if state.started.elapsed() > TIMEOUT {
        state.done = Some(Err("timed out waiting for a settled frame".into()));
        return;
    }
    match state.ready_frames {
        None => {
            if !assets.is_loaded_with_dependencies(&state.scene)
                || !assets.is_loaded_with_dependencies(&state.volume)
            {
                if let Some(bevy::asset::LoadState::Failed(e)) = assets.get_load_state(&state.volume) {
                    state.done = Some(Err(format!("loading {}: {e}", args.volume)));
                }
                return;
            }
            for (_, m) in materials.iter_mut() {
                m.metallic = 0.0;
                m.reflectance = 0.0;
                m.perceptual_roughness = 1.0;
                m.emissive = LinearRgba::BLACK;
            }
            if let Some(mut img) = images.get_mut(&state.volume)
                && let Err(e) = corrupt(&mut img, &args.control)
            {
                state.done = Some(Err(e));
                return;
            }
            state.ready_frames = Some(0);
        }
        Some(n) if n == WARMUP_FRAMES => {
            let target = state.target.clone();
            commands.spawn(Readback::texture(target)).observe(on_readback);
            state.ready_frames = Some(n + 1);
        }
        Some(n) => state.ready_frames = Some(n + 1),
    }
}

fn on_readback(ev: On<ReadbackComplete>, mut state: ResMut<State>) {
    if state.done.is_some() {
        return;
    }
    let data = ev.data.clone();
    let covered = data.chunks_exact(8).any(|t| half_to_f32(u16::from_le_bytes([t[6], t[7]])) > 0.0);
    if covered && state.last.as_ref() == Some(&data) {
        state.stable += 1;
    } else {
        state.stable = 0;
    }
    state.last = Some(data);
}

fn finish(args: Res<Args>, mut state: ResMut<State>, mut exit: MessageWriter<AppExit>) {
    if state.done.is_none() && state.stable + 1 >= STABLE_READBACKS {
        let data = state.last.clone().expect("a readback");
        state.done = Some(write_frame(&args, &data));
    }
    match state.done.take() {
        Some(Ok(())) => {
            println!("wrote {} ({}x{})", args.out, args.width, args.height);
            exit.write(AppExit::Success);
        }
        Some(Err(e)) => {
            eprintln!("lightvol-bevy-client: {e}");
            exit.write(AppExit::error());
        }
        None => {}
    }
}

/// Writes the RGBA16F rows (top to bottom) as two PFMs (rows bottom to top).
fn write_frame(args: &Args, data: &[u8]) -> Result<(), String> {
    let (w, h) = (args.width as usize, args.height as usize);
    if data.len() != w * h * 8 {
        return Err(format!("readback of {} bytes for {w}x{h} RGBA16F", data.len()));
    }
    let texel = |x: usize, y: usize, c: usize| {
        let at = ((h - 1 - y) * w + x) * 8 + 2 * c;
        half_to_f32(u16::from_le_bytes([data[at], data[at + 1]]))
    };
    let pfm = |channel: &dyn Fn(usize, usize, usize) -> f32| {
        let mut bytes = format!("PF\n{w} {h}\n-1.0\n").into_bytes();
        for y in 0..h {
            for x in 0..w {
                for c in 0..3 {
                    bytes.extend_from_slice(&channel(x, y, c).to_le_bytes());
                }
            }
        }
        bytes
    };
    let write = |path: &str, bytes: Vec<u8>| -> Result<(), String> {
        let part = format!("{path}.part");
        std::fs::write(&part, bytes).map_err(|e| format!("{part}: {e}"))?;
        std::fs::rename(&part, path).map_err(|e| format!("{path}: {e}"))
    };
    write(&args.out, pfm(&|x, y, c| texel(x, y, c)))?;
    let alpha = format!("{}.alpha.pfm", args.out.trim_end_matches(".pfm"));
    write(&alpha, pfm(&|x, y, _| texel(x, y, 3)))
}

/// Negative controls: texels π times too bright, or the atlas `(nx, 2 ny, 3 nz)` laid out
/// along swapped x and z.
fn corrupt(img: &mut Image, control: &str) -> Result<(), String> {
    let size = img.texture_descriptor.size;
    let (nx, h2, nz3) = (size.width as usize, size.height as usize, size.depth_or_array_layers as usize);
    let nz = nz3 / 3;
    let data = img.data.as_mut().ok_or("the volume has no CPU data")?;
    match control {
        "none" => {}
        "pi" => {
            for t in data.chunks_exact_mut(2) {
                let v = half_to_f32(u16::from_le_bytes([t[0], t[1]])) * std::f32::consts::PI;
                t.copy_from_slice(&f32_to_half(v).to_le_bytes());
            }
        }
        "swap" => {
            let mut out = vec![0u8; data.len()];
            for b in 0..3 {
                for z in 0..nz {
                    for y in 0..h2 {
                        for x in 0..nx {
                            let src = (((b * nz + z) * h2 + y) * nx + x) * 8;
                            let dst = (((b * nx + x) * h2 + y) * nz + z) * 8;
                            out[dst..dst + 8].copy_from_slice(&data[src..src + 8]);
                        }
                    }
                }
            }
            *data = out;
            img.texture_descriptor.size.width = nz as u32;
            img.texture_descriptor.size.depth_or_array_layers = 3 * nx as u32;
        }
        other => return Err(format!("unknown --control {other:?}")),
    }
    Ok(())
}

/// IEEE 754 binary16 to f32 (exact).
fn half_to_f32(h: u16) -> f32 {
    let sign = if h & 0x8000 != 0 { -1.0 } else { 1.0 };
    let exp = i32::from((h >> 10) & 0x1f);
    let frac = f32::from(h & 0x3ff);
    match exp {
        0 => sign * frac * 2f32.powi(-24),
        31 => {
            if frac == 0.0 {
                sign * f32::INFINITY
            } else {
                f32::NAN
            }
        }
        e => sign * (1.0 + frac / 1024.0) * 2f32.powi(e - 15),
    }
}

/// f32 to binary16, rounding to nearest (finite, normal range: the controls only).
fn f32_to_half(v: f32) -> u16 {
    let sign = if v < 0.0 { 0x8000 } else { 0 };
    let a = v.abs();
    if a < 2f32.powi(-14) {
        return sign | (a / 2f32.powi(-24)).round() as u16;
    }
    let e = a.log2().floor() as i32;
    let m = ((a / 2f32.powi(e) - 1.0) * 1024.0).round() as u32;
    let (e, m) = if m == 1024 { (e + 1, 0) } else { (e, m) };
    sign | (((e + 15) as u16) << 10) | m as u16
}
