#![doc = include_str!("../README.md")]

pub mod alpha;
pub mod band_limit;
pub mod base_color;
pub mod builder;
pub mod builtin;
pub mod bvh;
pub mod diagnostics;
pub mod envmap;
pub mod error;
pub mod estimate;
pub mod fingerprint;
pub mod instance;
pub mod layout;
pub mod light_groups;
pub mod light_sampler;
pub mod lights;
pub mod load;
pub mod material;
pub mod qmc;
pub mod reference;
pub mod scene;
pub mod scene_summary;
pub mod stats;
pub mod transport;
pub mod triangle;
pub mod watertight;
pub mod wide;

pub use builder::SceneBuilder;
pub use builtin::{BuiltinScene, builtin};
pub use bvh::{BuildQuality, Hit, Levels, Tracer};
pub use error::SceneError;
pub use glam::{DVec2, DVec3};
pub use lights::{Environment, PunctualLight, Sun};
pub use load::{LoadOptions, load_gltf, load_obj, load_scene};
pub use material::{AlphaMode, Material};
pub use reference::{
    PrefixedEstimate, reference_irradiance, reference_irradiance_many, reference_irradiance_many_prefixed,
    reference_irradiance_prefixed,
};
pub use scene::{ExtensionReport, LoadReport, Scene, SceneCamera, UpAxis};
pub use stats::RayCounts;
pub use transport::{PathRng, Transport, TransportSettings};
pub use triangle::{MeshAttributes, Triangle, TriangleRef};
pub use wide::{ISA_ENV, Isa};

#[cfg(test)]
mod cornell_tests {
    use super::*;
    use std::path::Path;

    /// The vendored Cornell box (`data/scenes/cornell_box`) loads: 8 objects, 18 quads = 36 triangles; the light
    /// emits (17, 12, 4); +Y-up millimetres become +Z up.
    #[test]
    fn cornell_box_loads() {
        let p = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../data/scenes/cornell_box/cornell_box.obj"));
        let s = load_scene(p, &LoadOptions::default()).unwrap();
        assert_eq!(s.triangles.len(), 36);
        assert!(s.report.warnings.is_empty(), "{:?}", s.report.warnings);
        let light = s.materials.iter().find(|m| m.name == "light").unwrap();
        assert_eq!(light.emission, [17.0, 12.0, 4.0]);
        let (lo, hi) = s.bounds();
        assert!((hi.z - 548.8).abs() < 1e-3 && lo.z.abs() < 1e-9, "{lo} {hi}");
        // The light faces down (-Z in the world frame).
        let lt = s.triangles.iter().find(|t| s.materials[t.material as usize].name == "light").unwrap();
        assert!(lt.normal().z < -0.99);
    }
}

#[cfg(test)]
mod vendored_scene_tests {
    use super::*;
    use std::path::Path;

    fn data(rel: &str) -> std::path::PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../data/scenes").join(rel)
    }

    /// Every vendored real scene loads with the triangle counts its SOURCE.txt states
    /// (instanced and unique), the cameras and materials the file has, and the warnings a
    /// user should see (the Breakfast Room's absent DDS copies are never read: its textures
    /// have PNG/JPEG sources).
    #[test]
    fn vendored_real_scenes_load() {
        let cases: [(&str, usize, usize, usize); 5] = [
            ("breakfast_room/BreakfastRoom.gltf", 262_687, 82_291, 3),
            ("occlusion_room/room.glb", 63_720, 63_720, 0),
            ("living_room/living_room.glb", 5_088, 5_088, 0),
            ("zdm2/zdm2.glb", 58_772, 58_772, 0),
            ("cornell_original/CornellBox-Original.obj", 36, 36, 0),
        ];
        for (file, instanced, unique, cameras) in cases {
            let s = load_scene(&data(file), &LoadOptions::default()).unwrap();
            let kept = s.triangle_count() + s.report.degenerate_skipped;
            assert_eq!(kept, instanced, "{file}");
            assert_eq!(s.report.unique_triangles, unique, "{file}");
            assert_eq!(s.cameras.len(), cameras, "{file}");
            assert!(
                s.report.warnings.iter().all(|w| !w.contains("texture")),
                "{file}: {:?}",
                s.report.warnings
            );
        }
        let b = load_scene(&data("breakfast_room/BreakfastRoom.gltf"), &LoadOptions::default()).unwrap();
        assert_eq!(b.textures.len(), 3);
        assert_eq!(b.materials.len(), 14);
        let ext: Vec<_> =
            b.report.extensions.iter().map(|e| (e.name.as_str(), e.treatment.as_str())).collect();
        assert_eq!(
            ext,
            [
                ("MSFT_texture_dds", "texture extension not supported, core image used"),
                ("KHR_materials_specular", "material extension not supported, core material used")
            ]
        );
        let z = load_scene(&data("zdm2/zdm2.glb"), &LoadOptions::default()).unwrap();
        assert_eq!(z.materials.len(), 1);
        assert_eq!(z.materials[0].albedo, load::DEFAULT_ALBEDO);
        let l = load_scene(&data("living_room/living_room.glb"), &LoadOptions::default()).unwrap();
        assert!(l.materials.iter().all(|m| m.double_sided));
    }

    /// Images decode in parallel, and the loaded textures are the same on 1 and 2 threads:
    /// the same order, sizes and texels (on a lattice over each image), and materials
    /// that name the same texture.
    #[test]
    fn textures_load_the_same_on_any_thread_count() {
        let load = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            pool.install(|| load_scene(&data("breakfast_room/BreakfastRoom.gltf"), &LoadOptions::default()))
                .unwrap()
        };
        let (one, two) = (load(1), load(2));
        assert_eq!(one.textures.len(), 3);
        assert_eq!(two.textures.len(), one.textures.len());
        for (a, b) in one.textures.iter().zip(&two.textures) {
            assert_eq!((a.width(), a.height(), a.has_alpha()), (b.width(), b.height(), b.has_alpha()));
            for y in (0..i64::from(a.height())).step_by(7) {
                for x in (0..i64::from(a.width())).step_by(5) {
                    assert_eq!(a.texel(x, y), b.texel(x, y));
                }
            }
        }
        let tex = |s: &Scene| s.materials.iter().map(|m| m.albedo_texture).collect::<Vec<_>>();
        assert_eq!(tex(&one), tex(&two));
        assert!(tex(&one).iter().flatten().count() >= 3);
    }
}
