//! Wavefront OBJ/MTL loading with `tobj`: `Kd`, `Ke`, `map_Kd`; faces triangulated.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use glam::{DVec2, DVec3};

use crate::base_color::Texture;
use crate::builder::SceneBuilder;
use crate::error::SceneError;
use crate::material::Material;
use crate::scene::Scene;

use super::image::decode_texture;
use super::options::{DEFAULT_ALBEDO, LoadOptions};

/// Loads an OBJ file and its MTL library. A missing MTL or texture is a warning in
/// [`Scene::report`]; the material then uses its factor (or [`DEFAULT_ALBEDO`]).
///
/// # Errors
/// [`SceneError::NotFound`], [`SceneError::Obj`], [`SceneError::NonFinite`],
/// [`SceneError::Empty`].
pub fn load_obj(path: &Path, opts: &LoadOptions) -> Result<Scene, SceneError> {
    if !path.is_file() {
        return Err(SceneError::NotFound(path.to_owned()));
    }
    let tobj_opts = tobj::LoadOptions { triangulate: true, single_index: true, ..Default::default() };
    let (models, materials) = tobj::load_obj(path, &tobj_opts)
        .map_err(|e| SceneError::Obj { path: path.to_owned(), message: e.to_string() })?;
    let name = path.file_name().map_or_else(|| "obj".to_owned(), |n| n.to_string_lossy().into_owned());
    let mut b = SceneBuilder::new(&name);
    let base = path.parent().map(Path::to_path_buf).unwrap_or_default();
    let materials = match materials {
        Ok(m) => m,
        Err(e) => {
            if models.iter().any(|m| m.mesh.material_id.is_some()) || !e.to_string().is_empty() {
                b.warn(format!("{name}: material library not loaded ({e}); using default albedo"));
            }
            Vec::new()
        }
    };
    // Every texture file once, decoded in parallel (each on its own, so the textures are
    // the same on any thread count), then given ids in the materials' order.
    let mut files: Vec<PathBuf> =
        materials.iter().filter_map(|m| m.diffuse_texture.as_ref()).map(|t| base.join(t.trim())).collect();
    files.sort();
    files.dedup();
    let mut decoded: HashMap<PathBuf, Result<Texture, String>> = {
        use rayon::prelude::*;
        files
            .into_par_iter()
            .map(|tp| {
                let label = tp.display().to_string();
                let t = std::fs::read(&tp)
                    .map_err(|e| format!("{label}: {e}"))
                    .and_then(|bytes| decode_texture(&bytes, &label));
                (tp, t)
            })
            .collect()
    };
    let mut textures: HashMap<PathBuf, Option<u32>> = HashMap::new();
    let mut mat_ids = Vec::with_capacity(materials.len());
    for m in &materials {
        let mut mat = Material::diffuse(&m.name, m.diffuse.map_or(DEFAULT_ALBEDO, |d| d.map(f64::from)));
        if let Some(e) = m.emissive {
            mat.emission = e.map(f64::from);
        }
        mat.double_sided = opts.force_double_sided;
        if let Some(tex) = &m.diffuse_texture {
            let tp = base.join(tex.trim());
            let id = match textures.get(&tp) {
                Some(id) => *id,
                None => {
                    let decoded =
                        decoded.remove(&tp).unwrap_or_else(|| Err(format!("{} not read", tp.display())));
                    let id = match decoded {
                        Ok(t) => Some(b.add_texture(t)),
                        Err(why) => {
                            b.warn(format!("material '{}': texture not loaded ({why}); using Kd", m.name));
                            None
                        }
                    };
                    textures.insert(tp, id);
                    id
                }
            };
            mat.albedo_texture = id;
        }
        mat_ids.push(b.add_material(mat)?);
    }
    let mut default_mat = None;
    for model in &models {
        let mesh = &model.mesh;
        let mat = match mesh.material_id.and_then(|i| mat_ids.get(i).copied()) {
            Some(m) => m,
            None => match default_mat {
                Some(m) => m,
                None => {
                    let mut m = Material::diffuse("default", DEFAULT_ALBEDO);
                    m.double_sided = opts.force_double_sided;
                    let id = b.add_material(m)?;
                    default_mat = Some(id);
                    id
                }
            },
        };
        let pos = |i: u32| -> DVec3 {
            let i = i as usize * 3;
            let p = DVec3::new(
                f64::from(mesh.positions[i]),
                f64::from(mesh.positions[i + 1]),
                f64::from(mesh.positions[i + 2]),
            );
            DVec3::from_array(opts.up.to_world((p * opts.scale).to_array()))
        };
        let uv = |i: u32| -> DVec2 {
            let i = i as usize * 2;
            if mesh.texcoords.len() > i + 1 {
                // OBJ's v axis points up the image; textures are stored top row first.
                DVec2::new(f64::from(mesh.texcoords[i]), 1.0 - f64::from(mesh.texcoords[i + 1]))
            } else {
                DVec2::ZERO
            }
        };
        for (f, tri) in mesh.indices.chunks_exact(3).enumerate() {
            let v = [pos(tri[0]), pos(tri[1]), pos(tri[2])];
            if !v.iter().all(|p| p.is_finite()) {
                return Err(SceneError::NonFinite {
                    what: format!("vertex of face {f} in object '{}' of {name}", model.name),
                });
            }
            b.add_triangle(v, [uv(tri[0]), uv(tri[1]), uv(tri[2])], mat)?;
        }
    }
    {
        let r = b.report_mut();
        r.up = opts.up;
        r.instances = models.len();
    }
    let mut scene = b.build()?;
    // OBJ has no instancing: every kept triangle is unique.
    scene.report.unique_triangles = scene.triangles.len();
    Ok(scene)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::load::load_scene;
    use crate::scene::UpAxis;

    fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
        let p = dir.join(name);
        std::fs::write(&p, text).unwrap();
        p
    }

    #[test]
    fn missing_file_and_unknown_extension() {
        let e = load_scene(Path::new("/nonexistent/x.obj"), &LoadOptions::default()).unwrap_err();
        assert!(matches!(e, SceneError::NotFound(_)), "{e}");
        let e = load_scene(Path::new("x.stl"), &LoadOptions::default()).unwrap_err();
        assert!(matches!(e, SceneError::UnsupportedFormat(_)));
    }

    #[test]
    fn missing_mtl_and_texture_warn_and_use_factor() {
        let d = tempfile::tempdir().unwrap();
        let p = write(d.path(), "a.obj", "mtllib none.mtl\nusemtl x\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
        let s = load_obj(&p, &LoadOptions::default()).unwrap();
        assert_eq!(s.materials[0].albedo, DEFAULT_ALBEDO);
        assert!(!s.report.warnings.is_empty());

        write(d.path(), "b.mtl", "newmtl t\nKd 0.5 0.25 0.125\nmap_Kd missing.png\n");
        let p = write(d.path(), "b.obj", "mtllib b.mtl\nusemtl t\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
        let s = load_obj(&p, &LoadOptions::default()).unwrap();
        assert_eq!(s.materials[0].albedo, [0.5, 0.25, 0.125]);
        assert_eq!(s.materials[0].albedo_texture, None);
        assert!(s.report.warnings.iter().any(|w| w.contains("missing.png")), "{:?}", s.report.warnings);

        // A file the decoder does not read is refused with its reason, as glTF images are.
        std::fs::write(d.path().join("t.dds"), b"DDS \x7c\0\0\0").unwrap();
        write(d.path(), "c.mtl", "newmtl t\nKd 0.5 0.5 0.5\nmap_Kd t.dds\n");
        let p = write(d.path(), "c.obj", "mtllib c.mtl\nusemtl t\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
        let s = load_obj(&p, &LoadOptions::default()).unwrap();
        assert_eq!(s.materials[0].albedo_texture, None);
        assert!(
            s.report.warnings.iter().any(|w| w.contains("t.dds is DDS, which this build does not decode")),
            "{:?}",
            s.report.warnings
        );
    }

    #[test]
    fn texture_is_sampled_at_hit_uv() {
        let d = tempfile::tempdir().unwrap();
        let img = image::RgbImage::from_fn(2, 2, |x, y| {
            if (x, y) == (0, 1) { image::Rgb([255, 255, 255]) } else { image::Rgb([0, 0, 0]) }
        });
        img.save(d.path().join("t.png")).unwrap();
        write(
            d.path(),
            "c.mtl",
            "newmtl t\nKd 0.5 0.5 0.5\nmap_Kd t.png\nnewmtl u\nKd 1 1 1\nmap_Kd t.png\n",
        );
        let p = write(
            d.path(),
            "c.obj",
            "mtllib c.mtl\nusemtl t\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0.25 0.25\nvt 0.75 0.25\nvt 0.25 0.75\nf 1/1 2/2 3/3\n",
        );
        let s = load_obj(&p, &LoadOptions { up: UpAxis::Z, ..Default::default() }).unwrap();
        assert!(s.report.warnings.is_empty(), "{:?}", s.report.warnings);
        // Two materials with one image share one texture.
        assert_eq!(s.textures.len(), 1);
        assert_eq!((s.materials[0].albedo_texture, s.materials[1].albedo_texture), (Some(0), Some(0)));
        // Vertex 0 sits on the centre of the bottom-left texel (image row 1), which is white.
        let a = s.albedo(0, 0.0, 0.0);
        assert!((a[0] - 0.5).abs() < 1e-9, "{a:?}");
        // Vertex 1: bottom-right texel centre, black; vertex 2: top-left, black.
        assert!(s.albedo(0, 1.0, 0.0)[0] < 1e-9 && s.albedo(0, 0.0, 1.0)[0] < 1e-9);
    }

    #[test]
    fn non_finite_vertex_is_an_error_and_degenerate_is_counted() {
        let d = tempfile::tempdir().unwrap();
        let p = write(d.path(), "n.obj", "v 0 0 0\nv 1 0 0\nv 0 nan 0\nf 1 2 3\n");
        let e = load_obj(&p, &LoadOptions::default());
        // tobj may reject "nan" itself; either way the load fails with a clear error.
        assert!(matches!(e, Err(SceneError::NonFinite { .. } | SceneError::Obj { .. })), "{e:?}");
        let p = write(d.path(), "g.obj", "v 0 0 0\nv 1 0 0\nv 2 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 4\n");
        let s = load_obj(&p, &LoadOptions::default()).unwrap();
        assert_eq!((s.triangles.len(), s.report.degenerate_skipped), (1, 1));
        let p = write(d.path(), "e.obj", "v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n");
        assert!(matches!(load_obj(&p, &LoadOptions::default()), Err(SceneError::Empty(_))));
    }
}
