//! The receiver scene of the `proxies` command: rectangles (ground and walls) that receive,
//! a sphere-set character that casts, a sky/sun light and a pinhole camera; and the
//! receiver buffer (\[SGNS07\] §4: per pixel the receiver point `p`, normal `N_p` and eye
//! depth `z_p = (p - e)·E`).

use crate::error::ProxyError;
use crate::light::SkySun;
use crate::proxy::SphereProxy;

/// A diffuse rectangle `origin + a u + b v`, `a, b ∈ [0, 1]`, facing `u × v`.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Rect {
    /// A corner.
    pub origin: [f64; 3],
    /// First edge.
    pub u: [f64; 3],
    /// Second edge.
    pub v: [f64; 3],
    /// Diffuse albedo.
    pub albedo: [f64; 3],
}

/// A pinhole camera.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Camera {
    /// Eye point `e`.
    pub eye: [f64; 3],
    /// Point looked at.
    pub target: [f64; 3],
    /// Approximate up vector.
    pub up: [f64; 3],
    /// Vertical field of view in degrees.
    pub fov_y_deg: f64,
}

/// A receiver scene.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Scene {
    /// Receiving rectangles.
    pub rects: Vec<Rect>,
    /// The moving object's sphere proxies.
    pub proxies: Vec<SphereProxy>,
    /// The light.
    pub light: SkySun,
    /// The camera.
    pub camera: Camera,
}

pub(crate) fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
pub(crate) fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
pub(crate) fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}
pub(crate) fn normalize(a: [f64; 3]) -> [f64; 3] {
    let l = dot(a, a).sqrt();
    [a[0] / l, a[1] / l, a[2] / l]
}

impl Rect {
    /// Unit normal `u × v / |u × v|`.
    #[must_use]
    pub fn normal(&self) -> [f64; 3] {
        normalize(cross(self.u, self.v))
    }

    /// Ray parameter of the hit with `o + t d`, if any (`t > 0`).
    #[must_use]
    pub fn intersect(&self, o: [f64; 3], d: [f64; 3]) -> Option<f64> {
        let n = cross(self.u, self.v);
        let den = dot(n, d);
        if den.abs() < 1e-12 {
            return None;
        }
        let t = dot(n, sub(self.origin, o)) / den;
        if !(t > 1e-9) {
            return None;
        }
        let q = sub([o[0] + t * d[0], o[1] + t * d[1], o[2] + t * d[2]], self.origin);
        let (uu, vv) = (dot(self.u, self.u), dot(self.v, self.v));
        let (a, b) = (dot(q, self.u) / uu, dot(q, self.v) / vv);
        ((0.0..=1.0).contains(&a) && (0.0..=1.0).contains(&b)).then_some(t)
    }
}

/// Camera frame: right, up, forward (unit vectors).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CameraFrame {
    /// Eye.
    pub eye: [f64; 3],
    /// Right.
    pub right: [f64; 3],
    /// Up.
    pub up: [f64; 3],
    /// Forward (the image-plane normal `E`).
    pub forward: [f64; 3],
    /// `tan(fov_y / 2)`.
    pub tan_half: f64,
}

impl Camera {
    /// The orthonormal camera frame.
    #[must_use]
    pub fn frame(&self) -> CameraFrame {
        let forward = normalize(sub(self.target, self.eye));
        let right = normalize(cross(forward, self.up));
        let up = cross(right, forward);
        CameraFrame { eye: self.eye, right, up, forward, tan_half: (0.5 * self.fov_y_deg.to_radians()).tan() }
    }
}

impl CameraFrame {
    /// Unit ray direction through pixel centre `(x + 0.5, y + 0.5)` of a `w × h` image (row 0
    /// at the top).
    #[must_use]
    pub fn ray(&self, x: usize, y: usize, w: usize, h: usize) -> [f64; 3] {
        let aspect = w as f64 / h as f64;
        let sx = (2.0 * (x as f64 + 0.5) / w as f64 - 1.0) * self.tan_half * aspect;
        let sy = (1.0 - 2.0 * (y as f64 + 0.5) / h as f64) * self.tan_half;
        normalize(core::array::from_fn(|k| self.forward[k] + sx * self.right[k] + sy * self.up[k]))
    }

    /// Continuous pixel coordinates and eye depth of a point, if it is in front of the eye.
    #[must_use]
    pub fn project(&self, p: [f64; 3], w: usize, h: usize) -> Option<(f64, f64, f64)> {
        let v = sub(p, self.eye);
        let z = dot(v, self.forward);
        if !(z > 1e-9) {
            return None;
        }
        let aspect = w as f64 / h as f64;
        let sx = dot(v, self.right) / z / (self.tan_half * aspect);
        let sy = dot(v, self.up) / z / self.tan_half;
        Some((0.5 * (sx + 1.0) * w as f64, 0.5 * (1.0 - sy) * h as f64, z))
    }
}

/// Per-pixel receiver data (\[SGNS07\] §4). Pixels that see no receiver have `depth = ∞`.
#[derive(Clone, Debug, PartialEq)]
pub struct ReceiverBuffer {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// Receiver points `p`.
    pub position: Vec<[f32; 3]>,
    /// Unit normals `N_p`.
    pub normal: Vec<[f32; 3]>,
    /// Eye depth `z_p = (p - e)·E` (`f32::INFINITY` where no receiver is seen).
    pub depth: Vec<f32>,
    /// Receiver albedo.
    pub albedo: Vec<[f32; 3]>,
}

impl ReceiverBuffer {
    /// Ray-casts the scene's rectangles through each pixel centre (the "receiver setup
    /// pass"; the proxies themselves are not drawn).
    #[must_use]
    pub fn render(scene: &Scene, width: usize, height: usize) -> Self {
        let cam = scene.camera.frame();
        let n = width * height;
        let mut b = Self {
            width,
            height,
            position: vec![[0.0; 3]; n],
            normal: vec![[0.0, 0.0, 1.0]; n],
            depth: vec![f32::INFINITY; n],
            albedo: vec![[0.0; 3]; n],
        };
        for y in 0..height {
            for x in 0..width {
                let d = cam.ray(x, y, width, height);
                let hit = scene
                    .rects
                    .iter()
                    .filter_map(|r| r.intersect(cam.eye, d).map(|t| (t, r)))
                    .min_by(|a, b| a.0.total_cmp(&b.0));
                if let Some((t, r)) = hit {
                    let i = y * width + x;
                    let p: [f64; 3] = core::array::from_fn(|k| cam.eye[k] + t * d[k]);
                    let mut nn = r.normal();
                    if dot(nn, d) > 0.0 {
                        nn = nn.map(|v| -v);
                    }
                    b.position[i] = p.map(|v| v as f32);
                    b.normal[i] = nn.map(|v| v as f32);
                    b.depth[i] = dot(sub(p, cam.eye), cam.forward) as f32;
                    b.albedo[i] = r.albedo.map(|v| v as f32);
                }
            }
        }
        b
    }

    /// Whether pixel `i` holds a receiver.
    #[must_use]
    #[inline]
    pub fn valid(&self, i: usize) -> bool {
        self.depth[i].is_finite()
    }
}

/// The built-in character: 18 spheres (feet crossing the ground, legs, hips, torso, arms,
/// head), standing at `base` on the `z = 0` ground.
#[must_use]
pub fn character(base: [f64; 3]) -> Vec<SphereProxy> {
    let shirt = [0.75, 0.18, 0.12];
    let pants = [0.15, 0.25, 0.6];
    let skin = [0.8, 0.6, 0.48];
    let mut s = Vec::new();
    let mut add = |c: [f64; 3], r: f64, a: [f64; 3]| {
        s.push(SphereProxy::new([base[0] + c[0], base[1] + c[1], base[2] + c[2]], r, a));
    };
    for side in [-1.0, 1.0] {
        add([0.15 * side, 0.05, 0.08], 0.1, pants);
        add([0.15 * side, 0.0, 0.32], 0.12, pants);
        add([0.15 * side, 0.0, 0.6], 0.15, pants);
        add([0.4 * side, 0.0, 1.32], 0.1, shirt);
        add([0.46 * side, 0.0, 1.05], 0.09, shirt);
        add([0.48 * side, 0.0, 0.82], 0.07, skin);
    }
    add([0.0, 0.0, 0.86], 0.2, pants);
    add([0.0, 0.0, 1.1], 0.25, shirt);
    add([0.0, 0.0, 1.36], 0.26, shirt);
    add([0.0, 0.0, 1.56], 0.1, skin);
    add([0.0, 0.0, 1.76], 0.17, skin);
    add([0.0, 0.12, 1.74], 0.08, skin);
    s
}

impl Scene {
    /// The default scene: a 6 × 6 ground, a back and a left wall 3 high, the built-in
    /// character near the corner, a warm sun lobe and a blue sky, seen from the front right.
    #[must_use]
    pub fn default_scene() -> Self {
        let sun = normalize([0.45, -0.5, 0.74]);
        Self {
            rects: vec![
                Rect {
                    origin: [-3.0, -3.0, 0.0],
                    u: [6.0, 0.0, 0.0],
                    v: [0.0, 6.0, 0.0],
                    albedo: [0.7, 0.7, 0.68],
                },
                Rect {
                    origin: [-3.0, 3.0, 0.0],
                    u: [6.0, 0.0, 0.0],
                    v: [0.0, 0.0, 3.0],
                    albedo: [0.65, 0.65, 0.7],
                },
                Rect {
                    origin: [-3.0, -3.0, 0.0],
                    u: [0.0, 0.0, 3.0],
                    v: [0.0, 6.0, 0.0],
                    albedo: [0.7, 0.66, 0.6],
                },
            ],
            proxies: character([-0.6, 1.6, 0.0]),
            light: SkySun {
                sun_dir: sun,
                sun: [3.6, 3.1, 2.4],
                sky: [0.16, 0.24, 0.4],
                ground: [0.06, 0.055, 0.05],
            },
            camera: Camera {
                eye: [2.4, -2.4, 2.3],
                target: [-0.8, 1.5, 0.6],
                up: [0.0, 0.0, 1.0],
                fov_y_deg: 50.0,
            },
        }
    }

    /// Reads a scene from JSON (the serde form of [`Scene`]) and validates it.
    ///
    /// # Errors
    /// [`ProxyError::Scene`] when the JSON does not parse or the scene is degenerate.
    pub fn from_json(text: &str) -> Result<Self, ProxyError> {
        let s: Self = serde_json::from_str(text).map_err(|e| ProxyError::Scene(e.to_string()))?;
        s.validate()?;
        Ok(s)
    }

    /// Checks radii, albedos, rectangles and the camera.
    ///
    /// # Errors
    /// [`ProxyError::Scene`] naming the first problem.
    pub fn validate(&self) -> Result<(), ProxyError> {
        let bad = |m: String| Err(ProxyError::Scene(m));
        for (i, p) in self.proxies.iter().enumerate() {
            let ok = p.radius > 0.0 && p.radius.is_finite() && p.center.iter().all(|v| v.is_finite());
            if !ok {
                return bad(format!("proxy {i}: radius must be positive and the centre finite"));
            }
            if !p.albedo.iter().all(|a| (0.0..=1.0).contains(a)) {
                return bad(format!("proxy {i}: albedo outside [0, 1]"));
            }
        }
        for (i, r) in self.rects.iter().enumerate() {
            if !(dot(cross(r.u, r.v), cross(r.u, r.v)) > 0.0) {
                return bad(format!("rect {i}: edges are parallel or zero"));
            }
        }
        let c = &self.camera;
        if !(c.fov_y_deg > 0.0 && c.fov_y_deg < 180.0)
            || dot(sub(c.target, c.eye), sub(c.target, c.eye)) == 0.0
        {
            return bad("camera: field of view must be in (0, 180) and target != eye".into());
        }
        let l = dot(self.light.sun_dir, self.light.sun_dir);
        if !((l - 1.0).abs() < 1e-6) {
            return bad("light: sun_dir must be a unit vector".into());
        }
        Ok(())
    }
}
