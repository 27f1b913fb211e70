//! Instanced geometry: a mesh stored once in its own frame (a [`Prototype`]) and placed any
//! number of times by affine transforms ([`Instance`]), so that memory grows with unique
//! triangles plus instances, not with the triangles the instances place.
//!
//! Scene triangle indices (the numbers in [`crate::Hit::triangle`], light sampling and
//! lightmap references) run over [`Scene::triangles`](crate::Scene::triangles) first, the triangles placed directly
//! in the world frame, and then over every instance in order, each contributing its
//! prototype's triangles in prototype order. [`Scene::flattened`](crate::Scene::flattened) writes every instance out
//! in that order, so an instanced scene and its flattened copy number their triangles alike.
//!
//! A mirroring transform (negative determinant) reverses the winding of what it places, as
//! glTF 2.0 §3.7.4 asks: [`Instance::place`] swaps vertices 1 and 2 (and their UVs), so
//! the placed triangle's front face is the prototype triangle's front face.

use glam::{DAffine3, DVec3};

use crate::error::SceneError;
use crate::triangle::Triangle;

/// A mesh stored once, in its own frame, for [`Instance`]s to place.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Prototype {
    /// The mesh name (for reports).
    pub name: String,
    /// Its triangles in the prototype's frame (materials and UVs as placed).
    pub triangles: Vec<Triangle>,
}

/// One placement of a [`Prototype`] in the world frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Instance {
    /// Index into [`Scene::prototypes`](crate::Scene::prototypes).
    pub prototype: u32,
    /// Prototype frame → world frame.
    pub to_world: DAffine3,
    /// Scene index of the instance's first triangle (set by
    /// [`SceneBuilder::build`](crate::SceneBuilder::build)).
    pub first: u32,
    /// World-space bounds of the placed triangles (exact: every vertex transformed).
    pub bounds: (DVec3, DVec3),
}

impl Instance {
    /// True when the transform mirrors (negative determinant), which reverses the winding.
    #[must_use]
    #[inline]
    pub fn mirrored(&self) -> bool {
        self.to_world.matrix3.determinant() < 0.0
    }

    /// The prototype triangle `t` placed in the world frame, with the winding restored for
    /// a mirroring transform (see the module docs).
    #[must_use]
    #[inline]
    pub fn place(&self, t: &Triangle) -> Triangle {
        place(&self.to_world, t)
    }
}

/// `t` placed by `to_world` (vertices 1 and 2 swapped under a mirroring transform).
#[must_use]
#[inline]
pub fn place(to_world: &DAffine3, t: &Triangle) -> Triangle {
    let mut v = t.v.map(|p| to_world.transform_point3(p));
    let mut uv = t.uv;
    if to_world.matrix3.determinant() < 0.0 {
        v.swap(1, 2);
        uv.swap(1, 2);
    }
    Triangle { v, uv, material: t.material }
}

/// Where a scene triangle lives: directly in [`Scene::triangles`](crate::Scene::triangles) or in an instance.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Located {
    /// Index into [`Scene::triangles`](crate::Scene::triangles).
    World(u32),
    /// An instance (index into [`Scene::instances`](crate::Scene::instances)) and the triangle's index in its
    /// prototype.
    Instanced {
        /// Index into [`Scene::instances`](crate::Scene::instances).
        instance: u32,
        /// Index into the prototype's triangles.
        local: u32,
    },
}

/// Assigns each instance its first scene index and its world bounds, and drops instances
/// of empty prototypes. Fails when the scene would number more triangles than a `u32`.
pub(crate) fn finish_instances(
    direct: usize,
    prototypes: &[Prototype],
    instances: &mut Vec<Instance>,
    name: &str,
) -> Result<(), SceneError> {
    instances.retain(|i| !prototypes[i.prototype as usize].triangles.is_empty());
    let mut next = direct as u64;
    for inst in instances.iter_mut() {
        let tris = &prototypes[inst.prototype as usize].triangles;
        inst.first = u32::try_from(next).map_err(|_| too_many(name, next))?;
        next += tris.len() as u64;
        let mut lo = DVec3::splat(f64::INFINITY);
        let mut hi = DVec3::splat(f64::NEG_INFINITY);
        for t in tris {
            for p in t.v {
                let w = inst.to_world.transform_point3(p);
                lo = lo.min(w);
                hi = hi.max(w);
            }
        }
        if !(lo.is_finite() && hi.is_finite()) {
            return Err(SceneError::NonFinite {
                what: format!("an instance of '{}' in {name}", prototypes[inst.prototype as usize].name),
            });
        }
        inst.bounds = (lo, hi);
    }
    if next > u64::from(u32::MAX) {
        return Err(too_many(name, next));
    }
    Ok(())
}

fn too_many(name: &str, triangles: u64) -> SceneError {
    SceneError::TooManyTriangles { name: name.to_owned(), triangles, max: u32::MAX }
}
