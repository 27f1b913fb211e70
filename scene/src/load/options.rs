//! What every loader takes: the file's up axis, a scale, sidedness and instancing choices,
//! and the albedo of a material that gives none.

use crate::scene::UpAxis;

/// Options shared by the loaders.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LoadOptions {
    /// The file's up axis (glTF is +Y by specification; OBJ has no convention, +Y is common).
    pub up: UpAxis,
    /// Uniform scale applied to positions (e.g. 0.001 for millimetre files).
    pub scale: f64,
    /// Make every material double-sided (for files whose winding cannot be trusted; this
    /// disables domain-of-interest classification on them, see Kontkanen & Laine 2006 §7).
    pub force_double_sided: bool,
    /// Write every placement of an instanced glTF mesh out as its own world-space
    /// triangles and lightmap object, instead of storing the mesh once and placing it
    /// ([`crate::instance`]). The surface bake needs this: each placement gets its own
    /// lightmap. An OBJ has no instancing either way.
    pub flatten_instances: bool,
}

impl Default for LoadOptions {
    fn default() -> Self {
        Self { up: UpAxis::Y, scale: 1.0, force_double_sided: false, flatten_instances: false }
    }
}

/// Albedo used when a material gives no `Kd` (or a mesh has no material).
pub const DEFAULT_ALBEDO: [f64; 3] = [0.8, 0.8, 0.8];
