//! Coefficient maps: storage, dilation of texels without valid samples, bilinear lookup and
//! shading at a tangent-space normal (\[Ish11\] §2.5.1, Listing 2.2 without the 8-bit
//! encoding).

use glam::DVec3;
use lightvol_hemibasis::HemiBasis;

use super::{BasisChoice, Quantity, SurfaceError, UvSet};

/// One object's baked map.
#[derive(Clone, Debug, PartialEq)]
pub struct CoefficientMap {
    /// Object name.
    pub object: String,
    /// Width in texels.
    pub width: u32,
    /// Height in texels.
    pub height: u32,
    /// The basis (stored as its tag, `hbasis_mod6`, see [`BasisChoice`]).
    pub basis: BasisChoice,
    /// Coefficients per colour channel.
    pub coeffs: usize,
    /// Texel density the atlas was sized for.
    pub texels_per_unit: f64,
    /// What the coefficients reconstruct.
    pub quantity: Quantity,
    /// The UV set the map is addressed with.
    pub uv_set: UvSet,
    /// Coefficients, RGB, at `(y · width + x) · coeffs + k`.
    pub data: Vec<[f32; 3]>,
    /// Per texel: [`VALID_BAKED`], [`VALID_DILATED`] or [`VALID_EMPTY`].
    pub valid: Vec<f32>,
    /// What lit the bake: [`lighting_fingerprint`](lightvol_scene::fingerprint::lighting_fingerprint) of the scene
    /// and bounce count (EXR attribute `lightvol.lighting`). A renderer compares it with the
    /// fingerprint of the scene it shades to detect maps baked under other lighting.
    pub lighting: String,
    /// This object's invalid-texel counters (the bake's
    /// [`SurfaceReport`](super::SurfaceReport) sums them over objects).
    pub invalid: InvalidCounts,
}

/// Invalid-texel counters of one object (\[KL06\] §5's domain of interest applied to texels):
/// `invalid_texels = moved + dilated + unfilled` with [`InvalidTexels::Fix`](super::InvalidTexels),
/// `moved = dilated = unfilled = 0` with `Keep`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct InvalidCounts {
    /// Covered texels with at least one sample point that saw a back face.
    pub invalid_texels: u64,
    /// Invalid texels whose samples were all re-drawn in the valid part of the footprint.
    pub moved: u64,
    /// Invalid texels with no valid point, filled from valid neighbours.
    pub dilated: u64,
    /// Invalid texels no dilation reached (left 0, `valid` = 0).
    pub unfilled: u64,
}

/// `valid` of a texel baked from its own (in-domain) samples.
pub const VALID_BAKED: f32 = 1.0;
/// `valid` of a texel filled from its neighbours (an invalid texel, or the gutter).
pub const VALID_DILATED: f32 = 0.5;
/// `valid` of a texel that holds nothing (outside every chart, or unreachable).
pub const VALID_EMPTY: f32 = 0.0;

/// Per-texel state during a bake.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum TexelState {
    Empty,
    Baked,
    NeedsFill,
    Dilated,
    Gutter,
}

impl TexelState {
    pub(crate) fn valid_value(self) -> f32 {
        match self {
            Self::Baked => VALID_BAKED,
            Self::Dilated | Self::Gutter => VALID_DILATED,
            Self::Empty | Self::NeedsFill => VALID_EMPTY,
        }
    }
    fn has_value(self) -> bool {
        matches!(self, Self::Baked | Self::Dilated | Self::Gutter)
    }
}

/// What a texel's value belongs to: its primary triangle's UV chart and geometric normal.
/// Dilation only takes values from neighbours with the same chart whose normals are within
/// [`FOOTPRINT_MIN_COS`](super::atlas::FOOTPRINT_MIN_COS) (the footprint's own rule), so an
/// invalid or gutter texel never mixes in a chart packed beside it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct TexelKey {
    pub chart: u32,
    pub normal: DVec3,
}

impl TexelKey {
    fn accepts(&self, other: &Self) -> bool {
        self.chart == other.chart && self.normal.dot(other.normal) >= super::atlas::FOOTPRINT_MIN_COS
    }
}

/// Counters of [`dilate`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct DilateCounts {
    pub dilated: u64,
    pub unfilled: u64,
    pub gutter: u64,
}

/// Fills `NeedsFill` texels from neighbours that hold values, pass by pass (each pass reads
/// only the previous pass's values: Jacobi order, deterministic), until none is left or a pass
/// fills nothing; then `gutter` passes fill `Empty` texels the same way. A filled texel is the
/// plain average of its (up to 8) neighbours with values whose [`TexelKey`] its own accepts.
/// `keys` holds the key of every covered texel; an `Empty` texel takes the key of its first
/// valued neighbour (edge neighbours left, right, up, down, then the diagonals) when the
/// gutter fills it.
pub(crate) fn dilate(
    data: &mut [[f32; 3]],
    state: &mut [TexelState],
    keys: &mut [Option<TexelKey>],
    [w, h]: [u32; 2],
    k: usize,
    gutter: u32,
) -> DilateCounts {
    let mut counts = DilateCounts::default();
    let inside = |x: i64, y: i64| x >= 0 && y >= 0 && x < i64::from(w) && y < i64::from(h);
    let idx = |x: i64, y: i64| (y * i64::from(w) + x) as usize;
    let pass = |target: TexelState,
                to: TexelState,
                data: &mut [[f32; 3]],
                state: &mut [TexelState],
                keys: &mut [Option<TexelKey>]| {
        let mut fills: Vec<(usize, Vec<[f32; 3]>, TexelKey)> = Vec::new();
        for y in 0..h as i64 {
            for x in 0..w as i64 {
                let t = idx(x, y);
                if state[t] != target {
                    continue;
                }
                let own = keys[t].or_else(|| {
                    [(-1, 0), (1, 0), (0, -1), (0, 1), (-1, -1), (1, -1), (-1, 1), (1, 1)]
                        .into_iter()
                        .map(|(dx, dy)| (x + dx, y + dy))
                        .filter(|&(nx, ny)| inside(nx, ny) && state[idx(nx, ny)].has_value())
                        .find_map(|(nx, ny)| keys[idx(nx, ny)])
                });
                let Some(own) = own else { continue };
                let mut acc = vec![[0.0f64; 3]; k];
                let mut n = 0;
                for (dx, dy) in [(-1, -1), (0, -1), (1, -1), (-1, 0), (1, 0), (-1, 1), (0, 1), (1, 1)] {
                    let (nx, ny) = (x + dx, y + dy);
                    if !inside(nx, ny) {
                        continue;
                    }
                    let s = idx(nx, ny);
                    if !state[s].has_value() || !keys[s].is_some_and(|key| own.accepts(&key)) {
                        continue;
                    }
                    n += 1;
                    for (a, v) in acc.iter_mut().zip(&data[s * k..(s + 1) * k]) {
                        for c in 0..3 {
                            a[c] += f64::from(v[c]);
                        }
                    }
                }
                if n > 0 {
                    let inv = 1.0 / f64::from(n);
                    fills.push((t, acc.iter().map(|a| a.map(|v| (v * inv) as f32)).collect(), own));
                }
            }
        }
        for (t, v, key) in &fills {
            data[t * k..(t + 1) * k].copy_from_slice(v);
            state[*t] = to;
            keys[*t] = Some(*key);
        }
        fills.len() as u64
    };
    loop {
        let filled = pass(TexelState::NeedsFill, TexelState::Dilated, data, state, keys);
        counts.dilated += filled;
        if filled == 0 {
            break;
        }
    }
    counts.unfilled = state.iter().filter(|&&s| s == TexelState::NeedsFill).count() as u64;
    for _ in 0..gutter {
        let filled = pass(TexelState::Empty, TexelState::Gutter, data, state, keys);
        counts.gutter += filled;
        if filled == 0 {
            break;
        }
    }
    counts
}

impl CoefficientMap {
    /// Coefficients of texel `(x, y)` (RGB per coefficient).
    ///
    /// # Panics
    /// If `(x, y)` is outside the map.
    #[must_use]
    pub fn texel(&self, x: u32, y: u32) -> &[[f32; 3]] {
        assert!(x < self.width && y < self.height, "texel ({x}, {y}) outside {}×{}", self.width, self.height);
        let t = (y * self.width + x) as usize;
        &self.data[t * self.coeffs..(t + 1) * self.coeffs]
    }

    /// `valid` of texel `(x, y)`.
    #[must_use]
    pub fn valid_at(&self, x: u32, y: u32) -> f32 {
        self.valid[(y * self.width + x) as usize]
    }

    /// The basis named by [`basis`](Self::basis).
    ///
    /// # Errors
    /// [`SurfaceError::UnknownBasis`] when the basis is not compiled in.
    pub fn basis(&self) -> Result<Box<dyn HemiBasis>, SurfaceError> {
        let b = self.basis;
        if b.coeffs() != self.coeffs {
            return Err(SurfaceError::UnknownBasis(format!(
                "{} with {} coefficients",
                self.basis, self.coeffs
            )));
        }
        Ok(b.basis())
    }

    /// Bilinear interpolation of the coefficients at lightmap UV `uv` (texel centres at
    /// `((x + ½)/W, (y + ½)/H)`, clamped at the borders). Texels with `valid = 0` are left out
    /// and the remaining weights renormalised; all zero when none of the four has a value.
    #[must_use]
    pub fn lookup(&self, uv: [f64; 2]) -> Vec<[f64; 3]> {
        let (w, h) = (self.width as i64, self.height as i64);
        let px = uv[0] * w as f64 - 0.5;
        let py = uv[1] * h as f64 - 0.5;
        let mut out = vec![[0.0; 3]; self.coeffs];
        if !(px.is_finite() && py.is_finite()) {
            return out;
        }
        let (x0, y0) = (px.floor(), py.floor());
        let (fx, fy) = (px - x0, py - y0);
        let mut total = 0.0;
        for (dx, dy, wgt) in [
            (0, 0, (1.0 - fx) * (1.0 - fy)),
            (1, 0, fx * (1.0 - fy)),
            (0, 1, (1.0 - fx) * fy),
            (1, 1, fx * fy),
        ] {
            let x = (x0 as i64 + dx).clamp(0, w - 1);
            let y = (y0 as i64 + dy).clamp(0, h - 1);
            let t = (y * w + x) as usize;
            if self.valid[t] == VALID_EMPTY || wgt <= 0.0 {
                continue;
            }
            total += wgt;
            for (o, v) in out.iter_mut().zip(&self.data[t * self.coeffs..(t + 1) * self.coeffs]) {
                for c in 0..3 {
                    o[c] += wgt * f64::from(v[c]);
                }
            }
        }
        if total > 0.0 {
            for o in &mut out {
                *o = o.map(|v| v / total);
            }
        }
        out
    }

    /// Irradiance (or radiosity, per [`quantity`](Self::quantity)) at lightmap UV `uv` for a
    /// tangent-space normal `n_tangent` (unit, `z` = surface normal): [`lookup`](Self::lookup)
    /// then `Σ c_i B_i(n)` (\[Ish11\] Listing 2.2). `basis` must be [`basis`](Self::basis)'s.
    #[must_use]
    pub fn shade(&self, basis: &dyn HemiBasis, uv: [f64; 2], n_tangent: [f64; 3]) -> [f64; 3] {
        basis.reconstruct_rgb_f64(&self.lookup(uv), n_tangent)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn map(w: u32, h: u32, valid: Vec<f32>, data: Vec<[f32; 3]>) -> CoefficientMap {
        CoefficientMap {
            object: "o".into(),
            width: w,
            height: h,
            basis: BasisChoice::parse("sh4").unwrap(),
            coeffs: 1,
            texels_per_unit: 1.0,
            quantity: Quantity::Irradiance,
            uv_set: UvSet::Lightmap,
            data,
            valid,
            lighting: String::new(),
            invalid: InvalidCounts::default(),
        }
    }

    /// Bilinear lookup reproduces a linear ramp exactly between texel centres, is constant
    /// across the border half-texel, and skips empty texels.
    #[test]
    fn bilinear_lookup() {
        const TOL: f64 = 1e-6; // f32 storage
        let (w, h) = (4u32, 3u32);
        let f = |x: f64, y: f64| 1.0 + 2.0 * x + 3.0 * y;
        let data =
            (0..h).flat_map(|y| (0..w).map(move |x| [f(f64::from(x), f64::from(y)) as f32; 3])).collect();
        let m = map(w, h, vec![1.0; 12], data);
        for (u, v) in [(0.5, 0.5), (0.3, 0.7), (0.126, 0.17)] {
            let got = m.lookup([u, v])[0][0];
            let want = f(u * 4.0 - 0.5, v * 3.0 - 0.5);
            assert!((got - want).abs() < TOL, "{u},{v}: {got} vs {want}");
        }
        // Border: clamped to the first column's value.
        assert!((m.lookup([0.01, 0.5])[0][1] - f(0.0, 1.0)).abs() < TOL);
        // An empty neighbour is skipped: between texel 0 (value 1) and empty texel 1.
        let mut m2 = map(2, 1, vec![1.0, 0.0], vec![[1.0; 3], [100.0; 3]]);
        assert!((m2.lookup([0.5, 0.5])[0][0] - 1.0).abs() < TOL);
        m2.valid = vec![0.0, 0.0];
        assert_eq!(m2.lookup([0.5, 0.5])[0], [0.0; 3]);
    }

    /// Dilation fills an invalid texel with the average of its valued neighbours, reaches
    /// texels two steps away in a second pass, counts what it could not reach, and grows the
    /// gutter by the requested number of passes.
    #[test]
    fn dilation_passes() {
        use TexelState::*;
        // Row: Baked(2) NeedsFill NeedsFill Empty Empty Empty | isolated NeedsFill at the end
        // of a second row with no valued neighbour.
        let (w, h) = (6u32, 3u32);
        let mut state = vec![Empty; 18];
        let mut data = vec![[0.0f32; 3]; 18];
        state[0] = Baked;
        data[0] = [2.0; 3];
        state[1] = NeedsFill;
        state[2] = NeedsFill;
        state[17] = NeedsFill;
        let key = Some(TexelKey { chart: 0, normal: DVec3::Z });
        let mut keys = vec![None; 18];
        for t in [0, 1, 2, 17] {
            keys[t] = key;
        }
        let c = dilate(&mut data, &mut state, &mut keys, [w, h], 1, 1);
        assert_eq!((c.dilated, c.unfilled), (2, 1));
        assert_eq!(data[1], [2.0; 3]);
        assert_eq!(data[2], [2.0; 3]);
        assert_eq!(state[17], NeedsFill);
        // One gutter pass: every Empty texel touching 0, 1 or 2 (columns 0-3 of rows 0-1).
        assert_eq!(c.gutter, 5);
        assert_eq!(state[3], Gutter);
        assert_eq!(state[4], Empty);
        assert_eq!(state[6].valid_value(), VALID_DILATED);
        assert_eq!(keys[3], key);
    }

    /// An invalid texel between its own chart (value 1) and another chart (value 10), or a
    /// texel of its chart facing 90° away, takes its own chart's value only; a gutter texel
    /// between two charts takes its first edge neighbour's chart (the left one).
    #[test]
    fn dilation_stays_in_its_chart() {
        use TexelState::*;
        let k0 = TexelKey { chart: 0, normal: DVec3::Z };
        let k1 = TexelKey { chart: 1, normal: DVec3::Z };
        let side = TexelKey { chart: 0, normal: DVec3::X }; // cos = 0 < FOOTPRINT_MIN_COS
        // Row 0: Baked k0 (1) | NeedsFill k0 | Baked k1 (10) | Empty | Baked k1 (10)
        // Row 1: Baked side (100) | Empty ...
        let (w, h) = (5u32, 2u32);
        let mut state = vec![Empty; 10];
        let mut data = vec![[0.0f32; 3]; 10];
        let mut keys = vec![None; 10];
        for (t, st, v, key) in [
            (0, Baked, 1.0, k0),
            (1, NeedsFill, 0.0, k0),
            (2, Baked, 10.0, k1),
            (4, Baked, 10.0, k1),
            (5, Baked, 100.0, side),
        ] {
            state[t] = st;
            data[t] = [v; 3];
            keys[t] = Some(key);
        }
        let c = dilate(&mut data, &mut state, &mut keys, [w, h], 1, 1);
        assert_eq!((c.dilated, c.unfilled), (1, 0));
        assert_eq!(data[1], [1.0; 3]);
        // Texel 3 (Empty between charts k1 at 2 and 4): first edge neighbour is 2 (k1).
        assert_eq!(data[3], [10.0; 3]);
        assert_eq!(keys[3], Some(k1));
        // Texel 6 (row 1, below texel 1): first edge neighbour is 5 (side), so it takes the
        // side texel's key and averages only it.
        assert_eq!(data[6], [100.0; 3]);
    }
}
