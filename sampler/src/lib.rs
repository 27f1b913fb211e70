#![doc = include_str!("../README.md")]

pub mod adaptive;
pub mod bake;
pub mod builtin;
pub mod bvh;
pub mod diagnostics;
pub mod domain;
pub mod envmap;
pub mod error;
pub mod fit;
pub mod gradients;
pub mod light_sampler;
pub mod lights;
pub mod load_gltf;
pub mod load_obj;
pub mod qmc;
pub mod reference;
pub mod scene;
pub mod stats;
pub mod surface;
pub mod texture;
pub mod transport;

pub use bake::{BakeControl, BakeOutput, BakeSettings, Method, Progress, bake};
pub use builtin::{BuiltinScene, builtin};
pub use bvh::{BuildQuality, Hit, Tracer};
pub use error::{BakeError, SceneError};
pub use glam::{DVec2, DVec3};
pub use lights::{Environment, PunctualLight, Sun};
pub use lightvol_volume::{Accumulator, GridSpec, IrradianceVolume};
pub use load_obj::{LoadOptions, load_obj, load_scene};
pub use reference::{reference_irradiance, reference_irradiance_many};
pub use scene::{LoadReport, Material, MeshAttributes, Scene, SceneBuilder, Triangle, TriangleRef, UpAxis};
pub use stats::{BakeStats, RayCounts};
pub use transport::{PathRng, Transport, TransportSettings};

#[cfg(test)]
mod cornell_tests {
    use super::*;
    use std::path::Path;

    /// The vendored Cornell box (`data/scenes/cornell_box`) loads: 8 objects, 18 quads = 36 triangles; the light
    /// emits (17, 12, 4); +Y-up millimetres become +Z up.
    #[test]
    fn cornell_box_loads() {
        let p =
            Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../data/scenes/cornell_box/cornell_box.obj"));
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
