//! Spherical-harmonic irradiance gradients and the lookups that use them (Oat, *Irradiance
//! Volumes for Games*, GDC 2005 — \[Oat05\], slides "Spherical Harmonic Irradiance
//! Gradients", "Central Differencing", "First-Order Taylor Expansion", "Using Gradients for
//! Interpolation", "Tricubic Interpolation" and the two "Memory Requirements" slides).
//!
//! [`VolumeGradients`] stores, beside an [`IrradianceVolume`], the 3D world-space gradient
//! of every SH coefficient of every node: f32, layout `[node][coeff][rgb][xyz]` (the
//! `9 · coeffs` floats of one node are contiguous; component `xyz` is `∂c/∂x_world`,
//! per world unit). The gradients are computed by lightvol-sampler (`gradients` module).
//!
//! Three lookups, all in f64, all returning the `3 · coeffs` coefficients `[coeff][rgb]`
//! at a world point (clamped into the box first, like [`IrradianceVolume::coeffs_reference`]):
//!
//! - [`GradientLookup::Taylor`]: \[Oat05\]'s first-order Taylor expansion
//!   `I'_i = I_i + ∇I_i · d` from the **nearest** node, `d` the (non-unit) vector from the
//!   node to the point. Exact for fields linear in x, y, z. Continuous across cell faces
//!   (the nearest node on a face is the same from both sides), but it jumps half-way
//!   between nodes wherever the field is not linear (the nearest node changes there).
//! - [`GradientLookup::GradientTrilinear`]: "before using a sample for interpolation,
//!   evaluate the first-order Taylor expansion, then interpolate as usual":
//!   `I(x) = Σ_c b_c(x) (I_c + ∇I_c · (x − x_c))` over the 8 corners with the trilinear
//!   weights `b_c`. Exact for linear fields; continuous everywhere (a face's off-face
//!   corners have weight 0 on it).
//! - [`GradientLookup::Hermite`]: the tensor-product cubic Hermite patch of the cell.
//!   With cell-local `u ∈ [0, 1]³`, cell size `Δ_a` along grid axis `a`, and the 1D
//!   Hermite functions `h00 = 2t³−3t²+1`, `h01 = 3t²−2t³`, `h10 = t³−2t²+t`, `h11 = t³−t²`
//!   (value and tangent at the near `0` / far `1` end), the full tricubic Hermite
//!   interpolant is `Σ_c Σ_{α ∈ {0,1}³} Π_a B_a^{c_a, α_a}(u_a) · ∂^α f_c · Π_{a: α_a=1} Δ_a`
//!   (`B^{0,0} = h00`, `B^{1,0} = h01`, `B^{0,1} = h10`, `B^{1,1} = h11`). It needs 8 values
//!   per corner: `f, f_x, f_y, f_z, f_xy, f_xz, f_yz, f_xyz`. Only the first derivatives are
//!   stored, so **the four cross-derivative terms `f_xy, f_xz, f_yz, f_xyz` are dropped (taken
//!   as zero)**; nothing approximates them. The grid-axis derivatives come from the stored
//!   world gradient by the chain rule, `∂f/∂g_a = ∇f · A e_a` (A the placement's linear part).
//!
//!   *What it reproduces exactly:* every field whose restriction to each cell is a
//!   tensor-product cubic (degree ≤ 3 in each grid coordinate separately) and whose
//!   cross-derivatives `f_ab`, `f_xyz` vanish at the nodes. In particular every additively
//!   separable cubic `f = p(g_x) + q(g_y) + r(g_z)` (p, q, r cubic polynomials) — all linear
//!   fields and all cubics in x alone. It is **not** exact for e.g. `f = g_x g_y` (the
//!   dropped `f_xy = 1`); a test shows both. It is C¹ across cell faces (on a face the
//!   patch and its normal derivative depend only on that face's four corners).
//!
//! All three agree with plain trilinear interpolation at the nodes (they return the node's
//! value there).
//!
//! **Validity and node reach.** On a volume with a validity mask ([`crate::validity`]) or a
//! node reach ([`crate::reach`]) the lookups leave out the corners the trilinear lookups
//! leave out (the reach tested at the point moved along the surface normal for
//! [`irradiance`], at the point itself for [`coeffs_at`]): `GradientTrilinear` takes the
//! reweighted trilinear weights; `Taylor` expands about the nearest corner if it is kept,
//! else about the kept corner of largest weight; `Hermite`, whose tensor-product weights
//! are no partition over a subset of the corners, becomes `GradientTrilinear` with the
//! reweighted weights in a cell where a corner is left out. Where no corner is left out
//! every lookup is bit for bit the one without a mask or reach. [`floats_per_sample`] and [`sample_bytes`] give \[Oat05\]'s memory
//! accounting: `3 n²` floats of SH per sample for order (bands) `n`, and `3 · 3 n²` more
//! for the gradients.

use crate::error::VolumeError;
use crate::grid::{GridSpec, corner_weights};
use crate::lookup::expand;
use crate::volume::IrradianceVolume;

pub use crate::volume::{floats_per_sample, sample_bytes};

/// Per-node world-space gradients of every SH coefficient of an [`IrradianceVolume`]
/// (\[Oat05\], "Spherical Harmonic Irradiance Gradients"), f32, `[node][coeff][rgb][xyz]`.
#[derive(Clone, Debug, PartialEq)]
pub struct VolumeGradients {
    nodes: usize,
    coeffs: usize,
    data: Vec<f32>,
}

impl VolumeGradients {
    /// Gradients for `volume` from a flat `[node][coeff][rgb][xyz]` array; errors if the
    /// length does not match `volume` or a value is not finite.
    pub fn new(volume: &IrradianceVolume, data: Vec<f32>) -> Result<Self, VolumeError> {
        let nodes = volume.spec().node_count();
        let coeffs = volume.coeffs();
        if data.len() != nodes * coeffs * 9 {
            return Err(VolumeError::Mismatch(format!(
                "gradient array has {} floats, volume needs {} ({nodes} nodes x {coeffs} coeffs x 3 rgb x 3 xyz)",
                data.len(),
                nodes * coeffs * 9
            )));
        }
        if let Some(i) = data.iter().position(|v| !v.is_finite()) {
            return Err(VolumeError::InvalidData(format!("gradient value {} at index {i}", data[i])));
        }
        Ok(Self { nodes, coeffs, data })
    }

    /// All-zero gradients for `volume` (with them every lookup here is piecewise constant
    /// or plain trilinear, see the tests).
    #[must_use]
    pub fn zeros(volume: &IrradianceVolume) -> Self {
        let (nodes, coeffs) = (volume.spec().node_count(), volume.coeffs());
        Self { nodes, coeffs, data: vec![0.0; nodes * coeffs * 9] }
    }

    /// Gradients whose node `i` holds `f(world position of node i)`, which must return
    /// `coeffs · 3` world gradients `[coeff][rgb] -> [x, y, z]`.
    pub fn from_fn(
        volume: &IrradianceVolume,
        mut f: impl FnMut([f64; 3]) -> Vec<[f64; 3]>,
    ) -> Result<Self, VolumeError> {
        let spec = volume.spec();
        let k = volume.coeffs() * 3;
        let mut data = Vec::with_capacity(spec.node_count() * k * 3);
        for node in 0..spec.node_count() {
            let [i, j, l] = spec.node_coords(node);
            let g = f(spec.node_position_world(i, j, l));
            if g.len() != k {
                return Err(VolumeError::Mismatch(format!(
                    "closure returned {} gradients, want {k}",
                    g.len()
                )));
            }
            data.extend(g.iter().flatten().map(|&v| v as f32));
        }
        Self::new(volume, data)
    }

    /// Node count.
    #[must_use]
    pub fn nodes(&self) -> usize {
        self.nodes
    }

    /// SH coefficients per channel.
    #[must_use]
    pub fn coeffs(&self) -> usize {
        self.coeffs
    }

    /// All gradients, `[node][coeff][rgb][xyz]`.
    #[must_use]
    pub fn data(&self) -> &[f32] {
        &self.data
    }

    /// The `9 · coeffs` floats of one node, `[coeff][rgb][xyz]`.
    #[must_use]
    #[inline]
    pub fn node(&self, node: usize) -> &[f32] {
        let k = self.coeffs * 9;
        &self.data[node * k..(node + 1) * k]
    }

    /// The world gradient of coefficient `j`, channel `ch` at `node`.
    #[must_use]
    #[inline]
    pub fn gradient(&self, node: usize, j: usize, ch: usize) -> [f64; 3] {
        let o = node * self.coeffs * 9 + (3 * j + ch) * 3;
        [0, 1, 2].map(|a| f64::from(self.data[o + a]))
    }

    /// Bytes of gradient data (f32): what the gradients add to [`sample_bytes`], three
    /// floats per coefficient and channel.
    #[must_use]
    pub fn memory_bytes(&self) -> usize {
        let bands = self.coeffs.isqrt();
        sample_bytes(self.nodes, bands, true) - sample_bytes(self.nodes, bands, false)
    }

    fn check(&self, volume: &IrradianceVolume) -> Result<(), VolumeError> {
        if self.nodes != volume.spec().node_count() || self.coeffs != volume.coeffs() {
            return Err(VolumeError::Mismatch(format!(
                "gradients for {} nodes x {} coeffs, volume has {} x {}",
                self.nodes,
                self.coeffs,
                volume.spec().node_count(),
                volume.coeffs()
            )));
        }
        Ok(())
    }
}

/// Which gradient-using lookup (\[Oat05\]'s three).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GradientLookup {
    /// First-order Taylor expansion from the nearest node.
    Taylor,
    /// Each corner extrapolated to the point, then trilinear interpolation.
    GradientTrilinear,
    /// Tensor-product cubic Hermite with the cross-derivative terms dropped.
    Hermite,
}

/// The located cell of a world point: its corner nodes, the fractional position, the world
/// position of the clamped point and the grid-axis world vectors `A e_a Δ_a` of one cell.
struct Located {
    nodes: [usize; 8],
    frac: [f64; 3],
    point: [f64; 3],
    axes: [[f64; 3]; 3],
}

fn locate(spec: &GridSpec, p: [f64; 3]) -> Located {
    let (cell, frac) = spec.locate(spec.to_grid(p));
    let nodes = spec.cell_corners(spec.cell_index(cell[0], cell[1], cell[2]));
    let size = spec.cell_size();
    let lo = spec.node_position(cell[0], cell[1], cell[2]);
    let g: [f64; 3] = std::array::from_fn(|a| lo[a] + frac[a] * size[a]);
    let o = spec.to_world([0.0; 3]);
    let axes = std::array::from_fn(|a| {
        let mut e = [0.0; 3];
        e[a] = size[a];
        let w = spec.to_world(e);
        [w[0] - o[0], w[1] - o[1], w[2] - o[2]]
    });
    Located { nodes, frac, point: spec.to_world(g), axes }
}

fn node_world(spec: &GridSpec, node: usize) -> [f64; 3] {
    let [i, j, k] = spec.node_coords(node);
    spec.node_position_world(i, j, k)
}

fn dot3(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Value plus `∇ · d` of every coefficient of `node`, added with weight `w` into `out`.
fn add_extrapolated(
    vol: &IrradianceVolume,
    grad: &VolumeGradients,
    node: usize,
    d: [f64; 3],
    w: f64,
    out: &mut [f64],
) {
    for (m, (o, v)) in out.iter_mut().zip(vol.node(node)).enumerate() {
        let g = grad.gradient(node, m / 3, m % 3);
        *o += w * (f64::from(*v) + dot3(g, d));
    }
}

/// The `3 · coeffs` coefficients `[coeff][rgb]` at world point `p` by `method` (module
/// docs); errors if `grad` does not belong to `vol`'s grid and coefficient count.
pub fn coeffs_at(
    vol: &IrradianceVolume,
    grad: &VolumeGradients,
    method: GradientLookup,
    p: [f64; 3],
) -> Result<Vec<f64>, VolumeError> {
    coeffs_facing(vol, grad, method, p, None)
}

/// [`coeffs_at`] for a query with surface normal `n` (the node reach's test point moves
/// along it, module docs).
fn coeffs_facing(
    vol: &IrradianceVolume,
    grad: &VolumeGradients,
    method: GradientLookup,
    p: [f64; 3],
    n: Option<[f64; 3]>,
) -> Result<Vec<f64>, VolumeError> {
    grad.check(vol)?;
    let spec = vol.spec();
    let loc = locate(spec, p);
    let plain = corner_weights(loc.frac);
    // The trilinear lookups' weights: the plain ones without a mask or reach.
    let b = if vol.validity().is_some() || vol.reach().is_some() {
        let (nodes, b) = vol.reference_weights(p, n);
        debug_assert_eq!(nodes, loc.nodes);
        b
    } else {
        plain
    };
    let method = if method == GradientLookup::Hermite && b != plain {
        GradientLookup::GradientTrilinear
    } else {
        method
    };
    let mut out = vec![0.0; vol.coeffs() * 3];
    match method {
        GradientLookup::Taylor => {
            // Nearest corner: per axis the far node when frac ≥ 1/2; if it is left out, the
            // kept corner of largest weight (the first of equals).
            let nearest = (0..3).map(|a| usize::from(loc.frac[a] >= 0.5) << a).sum::<usize>();
            let c = if b[nearest] > 0.0 {
                nearest
            } else {
                (0..8).fold(0, |best, c| if b[c] > b[best] { c } else { best })
            };
            let x = node_world(spec, loc.nodes[c]);
            let d = [0, 1, 2].map(|a| loc.point[a] - x[a]);
            add_extrapolated(vol, grad, loc.nodes[c], d, 1.0, &mut out);
        }
        GradientLookup::GradientTrilinear => {
            for c in 0..8 {
                if b[c] == 0.0 {
                    continue;
                }
                let x = node_world(spec, loc.nodes[c]);
                let d = [0, 1, 2].map(|a| loc.point[a] - x[a]);
                add_extrapolated(vol, grad, loc.nodes[c], d, b[c], &mut out);
            }
        }
        GradientLookup::Hermite => {
            let t = loc.frac;
            // Per axis: value weights (near, far) and tangent weights (near, far).
            let h = |t: f64| {
                let (t2, t3) = (t * t, t * t * t);
                ([2.0 * t3 - 3.0 * t2 + 1.0, 3.0 * t2 - 2.0 * t3], [t3 - 2.0 * t2 + t, t3 - t2])
            };
            let hx = [h(t[0]), h(t[1]), h(t[2])];
            for c in 0..8 {
                let bit = [c & 1, (c >> 1) & 1, (c >> 2) & 1];
                let val = [0, 1, 2].map(|a| hx[a].0[bit[a]]);
                let tan = [0, 1, 2].map(|a| hx[a].1[bit[a]]);
                let wv = val[0] * val[1] * val[2];
                // Tangent weight of grid axis a: h1 on axis a, h0 on the other two.
                let wt = [tan[0] * val[1] * val[2], val[0] * tan[1] * val[2], val[0] * val[1] * tan[2]];
                let node = loc.nodes[c];
                for (m, (o, v)) in out.iter_mut().zip(vol.node(node)).enumerate() {
                    let g = grad.gradient(node, m / 3, m % 3);
                    let mut s = wv * f64::from(*v);
                    for a in 0..3 {
                        // ∂f/∂u_a = ∇f · (A e_a Δ_a).
                        s += wt[a] * dot3(g, loc.axes[a]);
                    }
                    *o += s;
                }
            }
        }
    }
    Ok(out)
}

/// Irradiance `E(p, n) = Σ_j A_j c_j(p) Y_j(n)` (Kontkanen & Laine 2006, Eq. 3) with the
/// coefficients `c_j(p)` from [`coeffs_at`].
pub fn irradiance(
    vol: &IrradianceVolume,
    grad: &VolumeGradients,
    method: GradientLookup,
    p: [f64; 3],
    n: [f64; 3],
) -> Result<[f64; 3], VolumeError> {
    let c = coeffs_facing(vol, grad, method, p, Some(n))?;
    Ok(expand(vol.coeffs(), &c, n, true))
}

#[cfg(test)]
#[path = "gradient_tests.rs"]
mod tests;
