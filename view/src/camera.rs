//! The pinhole camera of a view: from a look-at specification, from a camera of the scene
//! file, or the default overview of a box; and its primary rays.

use std::str::FromStr;

use glam::DVec3;

use crate::error::ViewError;
use lightvol_scene::scene::{Scene, SceneCamera, UpAxis};
use lightvol_volume::GridSpec;

/// Vertical field of view of a look-at specification without one, in degrees.
pub const DEFAULT_FOV_DEG: f64 = 50.0;

/// A pinhole camera: eye, orthonormal view frame, and the tangent of half the vertical field
/// of view. Pixel `(x, y)` of a `w × h` image looks through the centre of its square, row 0
/// at the top ([`Camera::ray`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    eye: DVec3,
    forward: DVec3,
    right: DVec3,
    up: DVec3,
    tan_half: f64,
}

impl Camera {
    /// A camera of the scene file (a [`SceneCamera`], already in the internal frame): its
    /// position, view and up directions and vertical field of view.
    ///
    /// # Errors
    /// [`ViewError::NoViewDirection`], [`ViewError::UpAlongView`].
    pub fn from_scene(c: &SceneCamera) -> Result<Self, ViewError> {
        let forward = c.forward.try_normalize().ok_or(ViewError::NoViewDirection)?;
        let right = forward.cross(c.up).try_normalize().ok_or(ViewError::UpAlongView)?;
        let up = right.cross(forward);
        Ok(Self { eye: c.position, forward, right, up, tan_half: (c.yfov / 2.0).tan() })
    }

    /// Looks from `eye` at `target` (internal frame) with vertical field of view `fov_deg`,
    /// +Z up (a view straight up or down takes +X as its right).
    ///
    /// # Errors
    /// [`ViewError::EyeAtTarget`], then [`ViewError::FovRange`] outside `[1, 179)` degrees.
    pub fn look_at(eye: DVec3, target: DVec3, fov_deg: f64) -> Result<Self, ViewError> {
        let forward = (target - eye).try_normalize().ok_or(ViewError::EyeAtTarget)?;
        let right = forward.cross(DVec3::Z).try_normalize().unwrap_or(DVec3::X);
        let up = right.cross(forward);
        if !(1.0..179.0).contains(&fov_deg) {
            return Err(ViewError::FovRange(fov_deg));
        }
        Ok(Self { eye, forward, right, up, tan_half: (fov_deg.to_radians() / 2.0).tan() })
    }

    /// The default view of the box `[lo, hi]` (internal frame): from above its min-x, min-y
    /// corner, looking at its centre near the floor, 50° field of view.
    ///
    /// # Errors
    /// As [`Camera::look_at`] (a degenerate box).
    pub fn overview(lo: DVec3, hi: DVec3) -> Result<Self, ViewError> {
        let c = (lo + hi) * 0.5;
        let ext = hi - lo;
        let eye = DVec3::new(c.x - 0.55 * ext.x, c.y - 0.85 * ext.y, hi.z + 0.6 * ext.x.max(ext.y));
        Self::look_at(eye, DVec3::new(c.x, c.y, lo.z + 0.15 * ext.z), DEFAULT_FOV_DEG)
    }

    /// The default view of `scene`: the [`overview`](Self::overview) of `grid` where one
    /// is given and not placed (a volume's grid, or a scene's recommended one), else of the
    /// scene's bounds.
    ///
    /// # Errors
    /// As [`Camera::look_at`] (a degenerate box).
    pub fn framing(scene: &Scene, grid: Option<&GridSpec>) -> Result<Self, ViewError> {
        let (lo, hi) = match grid {
            Some(g) if g.placement().is_none() => {
                let (a, b) = g.bounds();
                (DVec3::from(a), DVec3::from(b))
            }
            _ => scene.bounds(),
        };
        Self::overview(lo, hi)
    }

    /// The camera position.
    #[must_use]
    pub fn eye(&self) -> DVec3 {
        self.eye
    }

    /// The unit view direction.
    #[must_use]
    pub fn forward(&self) -> DVec3 {
        self.forward
    }

    /// The unit ray direction through the centre of pixel `(x, y)` of a `w × h` image (row
    /// 0 at the top; square pixels, the vertical field of view fixed).
    #[must_use]
    pub fn ray(&self, x: u32, y: u32, w: u32, h: u32) -> DVec3 {
        let aspect = f64::from(w) / f64::from(h);
        let sx = (2.0 * (f64::from(x) + 0.5) / f64::from(w) - 1.0) * self.tan_half * aspect;
        let sy = (1.0 - 2.0 * (f64::from(y) + 0.5) / f64::from(h)) * self.tan_half;
        (self.forward + self.right * sx + self.up * sy).normalize()
    }
}

/// A camera as a person writes it: `EYE_X,EYE_Y,EYE_Z:TARGET_X,TARGET_Y,TARGET_Z[:FOV_DEG]`
/// (points in the scene file's frame, [`DEFAULT_FOV_DEG`] when the field of view is left
/// out), or `gltf:NAME` / `gltf:INDEX` for a camera of the scene file.
#[derive(Clone, Debug, PartialEq)]
pub enum CameraSpec {
    /// Look from `eye` at `target` (the file's frame) with a vertical field of view.
    LookAt {
        /// The eye, file frame.
        eye: [f64; 3],
        /// The point looked at, file frame.
        target: [f64; 3],
        /// Vertical field of view in degrees (checked when resolved).
        fov_deg: f64,
    },
    /// A camera of the scene file, by name or, when the key is a number, by index.
    File(String),
}

impl FromStr for CameraSpec {
    type Err = ViewError;

    /// Parses a specification (type docs); the field of view is read first, then the eye,
    /// then the target.
    fn from_str(s: &str) -> Result<Self, ViewError> {
        if let Some(key) = s.strip_prefix("gltf:") {
            return Ok(Self::File(key.to_owned()));
        }
        let parts: Vec<&str> = s.split(':').collect();
        if !(2..=3).contains(&parts.len()) {
            return Err(ViewError::CameraSyntax);
        }
        let point = |t: &str| -> Result<[f64; 3], ViewError> {
            let x: Vec<f64> = t
                .split(',')
                .map(|c| {
                    c.trim()
                        .parse::<f64>()
                        .map_err(|source| ViewError::CameraNumber { text: c.to_owned(), source })
                })
                .collect::<Result<_, _>>()?;
            if x.len() != 3 || x.iter().any(|v| !v.is_finite()) {
                return Err(ViewError::CameraPoint(t.to_owned()));
            }
            Ok([x[0], x[1], x[2]])
        };
        let fov_deg = match parts.get(2) {
            Some(f) => f.trim().parse::<f64>().map_err(ViewError::FovNumber)?,
            None => DEFAULT_FOV_DEG,
        };
        Ok(Self::LookAt { eye: point(parts[0])?, target: point(parts[1])?, fov_deg })
    }
}

impl CameraSpec {
    /// The camera of this specification in `scene`, whose file frame is `frame`, and the
    /// file camera's aspect ratio (width / height) when it has one.
    ///
    /// # Errors
    /// [`ViewError::NoFileCameras`] and [`ViewError::NoSuchCamera`] for a file camera that
    /// is not there; the errors of [`Camera::from_scene`] and [`Camera::look_at`].
    pub fn resolve(&self, scene: &Scene, frame: UpAxis) -> Result<(Camera, Option<f64>), ViewError> {
        match self {
            Self::LookAt { eye, target, fov_deg } => {
                let world = |p: &[f64; 3]| DVec3::from_array(frame.to_world(*p));
                Ok((Camera::look_at(world(eye), world(target), *fov_deg)?, None))
            }
            Self::File(key) => {
                let c = file_camera(scene, key)?;
                Ok((Camera::from_scene(c)?, c.aspect))
            }
        }
    }

    /// The name of the file camera this specification picks, when it picks one.
    ///
    /// # Errors
    /// As [`resolve`](Self::resolve) for a missing file camera.
    pub fn file_camera_name<'s>(&self, scene: &'s Scene) -> Result<Option<&'s str>, ViewError> {
        match self {
            Self::LookAt { .. } => Ok(None),
            Self::File(key) => Ok(Some(file_camera(scene, key)?.name.as_str())),
        }
    }
}

/// The scene camera with index `key`, else the first named `key`.
fn file_camera<'s>(scene: &'s Scene, key: &str) -> Result<&'s SceneCamera, ViewError> {
    let found = match key.parse::<usize>() {
        Ok(i) => scene.cameras.get(i),
        Err(_) => scene.cameras.iter().find(|c| c.name == key),
    };
    found.ok_or_else(|| {
        if scene.cameras.is_empty() {
            return ViewError::NoFileCameras;
        }
        let names: Vec<String> =
            scene.cameras.iter().enumerate().map(|(i, c)| format!("{i} '{}'", c.name)).collect();
        ViewError::NoSuchCamera { available: names.join(", ") }
    })
}
