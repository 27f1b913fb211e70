use bevy::light::{IrradianceVolume, LightProbe};
use bevy::prelude::*;

/// Spawns the irradiance volume that `lightvol export VOLUME.exr --format bevy -o
/// ASSETS/volume.ktx2` wrote (the texture and the `volume.ktx2.json` beside it): a light
/// probe whose `Transform` puts Bevy's voxel centres on lightvol's nodes.
pub fn spawn_lightvol_volume(
    commands: &mut Commands,
    assets: &AssetServer,
    assets_dir: &str,
    name: &str,
) -> Entity {
    let json = std::fs::read_to_string(format!("{assets_dir}/{name}.json")).expect("the export's JSON");
    let info: serde_json::Value = serde_json::from_str(&json).expect("valid JSON");
    let v = |key: &str, i: usize| info["transform"][key][i].as_f64().expect("a number") as f32;
    commands
        .spawn((
            LightProbe::default(),
            IrradianceVolume {
                voxels: assets.load(name.to_owned()),
                intensity: info["intensity"].as_f64().expect("a number") as f32,
                ..default()
            },
            Transform {
                translation: Vec3::new(v("translation", 0), v("translation", 1), v("translation", 2)),
                rotation: Quat::from_xyzw(
                    v("rotation", 0),
                    v("rotation", 1),
                    v("rotation", 2),
                    v("rotation", 3),
                ),
                scale: Vec3::new(v("scale", 0), v("scale", 1), v("scale", 2)),
            },
        ))
        .id()
}
