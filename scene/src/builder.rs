//! Assembling a [`Scene`]: materials, textures, triangles (degenerates skipped and counted,
//! non-finite input refused), meshes with their attributes, prototypes and instances.

use glam::{DVec2, DVec3};

use crate::base_color::Texture;
use crate::error::SceneError;
use crate::instance::{Instance, Prototype, finish_instances};
use crate::lights::{Environment, PunctualLight, Sun};
use crate::material::Material;
use crate::scene::{LoadReport, Scene, SceneCamera};
use crate::triangle::{DEGENERATE_RELATIVE_AREA, MeshAttributes, Triangle, TriangleRef};

/// The faces of the axis-aligned box `lo..hi` as quads, counter-clockwise seen from outside
/// (`outward`) or from inside; `skip_bottom` leaves out the -Z face. Order: +X, -X, +Y, -Y,
/// +Z, -Z.
#[must_use]
pub fn box_faces(lo: DVec3, hi: DVec3, outward: bool, skip_bottom: bool) -> Vec<[DVec3; 4]> {
    let c = |x: usize, y: usize, z: usize| {
        DVec3::new(
            if x == 0 { lo.x } else { hi.x },
            if y == 0 { lo.y } else { hi.y },
            if z == 0 { lo.z } else { hi.z },
        )
    };
    // Each face listed counter-clockwise seen from outside.
    let faces = [
        [c(1, 0, 0), c(1, 1, 0), c(1, 1, 1), c(1, 0, 1)], // +X
        [c(0, 0, 0), c(0, 0, 1), c(0, 1, 1), c(0, 1, 0)], // -X
        [c(0, 1, 0), c(0, 1, 1), c(1, 1, 1), c(1, 1, 0)], // +Y
        [c(0, 0, 0), c(1, 0, 0), c(1, 0, 1), c(0, 0, 1)], // -Y
        [c(0, 0, 1), c(1, 0, 1), c(1, 1, 1), c(0, 1, 1)], // +Z
        [c(0, 0, 0), c(0, 1, 0), c(1, 1, 0), c(1, 0, 0)], // -Z
    ];
    faces
        .into_iter()
        .take(if skip_bottom { 5 } else { 6 })
        .map(|mut q| {
            if !outward {
                q.reverse();
            }
            q
        })
        .collect()
}

/// Assembles a [`Scene`], validating as it goes.
#[derive(Debug, Default)]
pub struct SceneBuilder {
    scene_name: String,
    triangles: Vec<Triangle>,
    materials: Vec<Material>,
    textures: Vec<Texture>,
    report: LoadReport,
    meshes: Vec<MeshAttributes>,
    triangle_refs: Vec<Option<TriangleRef>>,
    prototypes: Vec<Prototype>,
    instances: Vec<Instance>,
    /// Cameras to attach.
    pub cameras: Vec<SceneCamera>,
    /// Lights to attach.
    pub environment: Environment,
    /// Sun to attach.
    pub sun: Option<Sun>,
    /// Punctual lights to attach.
    pub punctual: Vec<PunctualLight>,
    /// Names of the punctual lights, in the same order (may be shorter).
    pub punctual_names: Vec<String>,
}

impl SceneBuilder {
    /// An empty builder for a scene called `name`.
    #[must_use]
    pub fn new(name: &str) -> Self {
        Self { scene_name: name.to_owned(), ..Self::default() }
    }

    /// Adds a material, returning its index.
    ///
    /// # Errors
    /// [`SceneError::NonFinite`] if a factor is NaN or infinite.
    pub fn add_material(&mut self, m: Material) -> Result<u32, SceneError> {
        if !m.albedo.iter().chain(m.emission.iter()).all(|x| x.is_finite()) {
            return Err(SceneError::NonFinite { what: format!("material '{}'", m.name) });
        }
        self.materials.push(m);
        Ok(self.materials.len() as u32 - 1)
    }

    /// Adds a texture, returning its index.
    pub fn add_texture(&mut self, t: Texture) -> u32 {
        self.textures.push(t);
        self.textures.len() as u32 - 1
    }

    /// Records a warning.
    pub fn warn(&mut self, w: String) {
        self.report.warnings.push(w);
    }

    /// The loader notes so far, to fill in counts and extension reports.
    pub fn report_mut(&mut self) -> &mut LoadReport {
        &mut self.report
    }

    /// Number of materials so far.
    #[must_use]
    pub fn material_count(&self) -> usize {
        self.materials.len()
    }

    /// Adds a triangle. Returns `Ok(false)` (and counts it) when it is degenerate.
    ///
    /// # Errors
    /// [`SceneError::NonFinite`] for NaN/infinite coordinates, [`SceneError::BadMaterial`]
    /// for an unknown material.
    pub fn add_triangle(&mut self, v: [DVec3; 3], uv: [DVec2; 3], material: u32) -> Result<bool, SceneError> {
        let Some(tri) = self.checked(v, uv, material, self.triangles.len())? else { return Ok(false) };
        self.triangles.push(tri);
        if !self.triangle_refs.is_empty() {
            self.triangle_refs.push(None);
        }
        Ok(true)
    }

    /// Validates a triangle: `None` (counted) when it is degenerate.
    fn checked(
        &mut self,
        v: [DVec3; 3],
        uv: [DVec2; 3],
        material: u32,
        index: usize,
    ) -> Result<Option<Triangle>, SceneError> {
        if !v.iter().all(|p| p.is_finite()) {
            return Err(SceneError::NonFinite {
                what: format!("vertex of triangle {index} in scene '{}'", self.scene_name),
            });
        }
        if material as usize >= self.materials.len() {
            return Err(SceneError::BadMaterial { index: material, count: self.materials.len() });
        }
        let uv = if uv.iter().all(|t| t.is_finite()) { uv } else { [DVec2::ZERO; 3] };
        let tri = Triangle { v, uv, material };
        let longest = (v[1] - v[0])
            .length_squared()
            .max((v[2] - v[1]).length_squared())
            .max((v[0] - v[2]).length_squared());
        if !(tri.cross().length() > DEGENERATE_RELATIVE_AREA * longest) {
            self.report.degenerate_skipped += 1;
            return Ok(None);
        }
        Ok(Some(tri))
    }

    /// Starts a prototype (a mesh to instance), returning its index for
    /// [`add_prototype_triangle`](Self::add_prototype_triangle) and
    /// [`add_instance`](Self::add_instance).
    pub fn add_prototype(&mut self, name: &str) -> u32 {
        self.prototypes.push(Prototype { name: name.to_owned(), triangles: Vec::new() });
        self.prototypes.len() as u32 - 1
    }

    /// Adds a triangle, in the prototype's frame, to prototype `p`. Returns `Ok(false)` (and
    /// counts it) when it is degenerate there.
    ///
    /// # Errors
    /// As [`add_triangle`](Self::add_triangle), and [`SceneError::BadMesh`] for an unknown
    /// prototype.
    pub fn add_prototype_triangle(
        &mut self,
        p: u32,
        v: [DVec3; 3],
        uv: [DVec2; 3],
        material: u32,
    ) -> Result<bool, SceneError> {
        let Some(n) = self.prototypes.get(p as usize).map(|q| q.triangles.len()) else {
            return Err(SceneError::BadMesh(format!("prototype {p} of {}", self.prototypes.len())));
        };
        let Some(tri) = self.checked(v, uv, material, n)? else { return Ok(false) };
        self.prototypes[p as usize].triangles.push(tri);
        Ok(true)
    }

    /// Places prototype `p` with `to_world` (prototype frame → world frame).
    ///
    /// # Errors
    /// [`SceneError::BadMesh`] for an unknown prototype, [`SceneError::NonFinite`] for a
    /// transform with NaN or infinite entries.
    pub fn add_instance(&mut self, p: u32, to_world: glam::DAffine3) -> Result<(), SceneError> {
        if p as usize >= self.prototypes.len() {
            return Err(SceneError::BadMesh(format!("prototype {p} of {}", self.prototypes.len())));
        }
        if !to_world.is_finite() {
            return Err(SceneError::NonFinite {
                what: format!("instance transform in scene '{}'", self.scene_name),
            });
        }
        self.instances.push(Instance {
            prototype: p,
            to_world,
            first: 0,
            bounds: (DVec3::ZERO, DVec3::ZERO),
        });
        Ok(())
    }

    /// Adds a lightmap object's attributes, returning its index for [`TriangleRef::mesh`].
    pub fn add_mesh(&mut self, m: MeshAttributes) -> u32 {
        self.meshes.push(m);
        self.meshes.len() as u32 - 1
    }

    /// Adds a triangle that belongs to a lightmap object. Returns `Ok(false)` (and counts
    /// it) when it is degenerate.
    ///
    /// # Errors
    /// As [`add_triangle`](Self::add_triangle), and [`SceneError::BadMesh`] when `r` names
    /// an object or a vertex that does not exist.
    pub fn add_mesh_triangle(
        &mut self,
        v: [DVec3; 3],
        uv: [DVec2; 3],
        material: u32,
        r: TriangleRef,
    ) -> Result<bool, SceneError> {
        let Some(m) = self.meshes.get(r.mesh as usize) else {
            return Err(SceneError::BadMesh(format!("mesh {} of {}", r.mesh, self.meshes.len())));
        };
        if r.vertices.iter().any(|&i| i as usize >= m.positions.len()) {
            return Err(SceneError::BadMesh(format!(
                "face {} of mesh '{}' refers to vertex {:?} of {}",
                r.face,
                m.name,
                r.vertices,
                m.positions.len()
            )));
        }
        let kept = self.add_triangle(v, uv, material)?;
        if kept {
            // Earlier plain triangles get `None` (add_triangle only pads once refs exist).
            self.triangle_refs.resize(self.triangles.len(), None);
            self.triangle_refs[self.triangles.len() - 1] = Some(r);
        }
        Ok(kept)
    }

    /// Adds a planar quad `a b c d` (counter-clockwise seen from the front) as two triangles.
    ///
    /// # Errors
    /// As [`add_triangle`](Self::add_triangle).
    pub fn add_quad(&mut self, q: [DVec3; 4], material: u32) -> Result<(), SceneError> {
        let uv = [DVec2::new(0.0, 0.0), DVec2::new(1.0, 0.0), DVec2::new(1.0, 1.0), DVec2::new(0.0, 1.0)];
        self.add_triangle([q[0], q[1], q[2]], [uv[0], uv[1], uv[2]], material)?;
        self.add_triangle([q[0], q[2], q[3]], [uv[0], uv[2], uv[3]], material)?;
        Ok(())
    }

    /// Adds an axis-aligned box as 12 triangles with outward (`outward = true`) or inward
    /// normals. `skip_bottom` omits the -Z face (buildings standing on the ground).
    ///
    /// # Errors
    /// As [`add_triangle`](Self::add_triangle).
    pub fn add_box(
        &mut self,
        lo: DVec3,
        hi: DVec3,
        material: u32,
        outward: bool,
        skip_bottom: bool,
    ) -> Result<(), SceneError> {
        for q in box_faces(lo, hi, outward, skip_bottom) {
            self.add_quad(q, material)?;
        }
        Ok(())
    }

    /// Finishes the scene.
    ///
    /// # Errors
    /// [`SceneError::Empty`] when no triangle was kept.
    pub fn build(mut self) -> Result<Scene, SceneError> {
        finish_instances(self.triangles.len(), &self.prototypes, &mut self.instances, &self.scene_name)?;
        if self.triangles.is_empty() && self.instances.is_empty() {
            return Err(SceneError::Empty(self.scene_name));
        }
        Ok(Scene {
            name: self.scene_name,
            triangles: self.triangles,
            prototypes: self.prototypes,
            instances: self.instances,
            materials: self.materials,
            textures: self.textures,
            environment: self.environment,
            sun: self.sun,
            punctual: self.punctual,
            punctual_names: self.punctual_names,
            report: self.report,
            meshes: self.meshes,
            triangle_refs: self.triangle_refs,
            cameras: self.cameras,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn builder_skips_degenerate_and_rejects_nan() {
        let mut b = SceneBuilder::new("t");
        let m = b.add_material(Material::diffuse("m", [0.5; 3])).unwrap();
        let ok = b.add_triangle([DVec3::ZERO, DVec3::X, DVec3::Y], [DVec2::ZERO; 3], m).unwrap();
        let collinear = b.add_triangle([DVec3::ZERO, DVec3::X, 2.0 * DVec3::X], [DVec2::ZERO; 3], m).unwrap();
        assert!(ok && !collinear);
        assert!(matches!(
            b.add_triangle([DVec3::ZERO, DVec3::X, DVec3::new(f64::NAN, 0.0, 0.0)], [DVec2::ZERO; 3], m),
            Err(SceneError::NonFinite { .. })
        ));
        assert!(matches!(
            b.add_triangle([DVec3::ZERO, DVec3::X, DVec3::Y], [DVec2::ZERO; 3], 9),
            Err(SceneError::BadMaterial { .. })
        ));
        let s = b.build().unwrap();
        assert_eq!(s.triangles.len(), 1);
        assert_eq!(s.report.degenerate_skipped, 1);
        assert!(matches!(SceneBuilder::new("e").build(), Err(SceneError::Empty(_))));
    }

    /// Every face of an outward box has its normal pointing away from the centre.
    #[test]
    fn box_normals_point_outward() {
        let mut b = SceneBuilder::new("box");
        let m = b.add_material(Material::diffuse("m", [0.5; 3])).unwrap();
        let (lo, hi) = (DVec3::new(-1.0, -2.0, 0.0), DVec3::new(1.0, 1.0, 3.0));
        b.add_box(lo, hi, m, true, false).unwrap();
        let s = b.build().unwrap();
        assert_eq!(s.triangles.len(), 12);
        let centre = (lo + hi) / 2.0;
        let total: f64 = s.triangles.iter().map(Triangle::area).sum();
        assert!((total - 2.0 * (2.0 * 3.0 + 2.0 * 3.0 + 3.0 * 3.0)).abs() < 1e-12);
        for t in &s.triangles {
            assert!(t.normal().dot(t.centroid() - centre) > 0.0);
        }
    }
}
