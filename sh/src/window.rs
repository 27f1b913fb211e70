//! Windowing (band-wise damping) against ringing, and the minimum of an SH function.
//!
//! Truncated SH expansions of sharp signals ring: the reconstruction overshoots and can turn
//! negative. Multiplying band `l` by a window factor `w_l` trades sharpness for less ringing
//! (Sloan 2008, "Stupid Spherical Harmonics (SH) Tricks", §"Windowing"):
//!
//! - Hanning: `w_l = (1 + cos(π l / W)) / 2` for `l < W`, 0 beyond;
//! - Lanczos: `w_l = sinc(π l / W) = sin(π l / W) / (π l / W)` for `l < W`, 0 beyond;
//! - Sloan's ringing-minimising window, the minimiser of
//!   `∫ (g - f)² + λ ∫ (Δg)²` over band-limited `g`: since `Δ y_lm = -l(l+1) y_lm`, it is
//!   `w_l = 1 / (1 + λ l² (l + 1)²)`.
//!
//! [`min_value`] estimates the minimum of a function over the sphere (dense start set plus
//! local pattern search), and [`deringing_lambda`] finds the smallest `λ` that lifts the
//! minimum of the windowed function to a target (e.g. 0 for non-negative radiance).

use std::f64::consts::PI;

use crate::coeffs::Sh;
use crate::index::sh_lm;
use crate::sampling::{Frame, fibonacci_sphere};

/// Hanning window factor of band `l` for window width `w` (bands `>= w` are zeroed).
#[must_use]
pub fn hanning(l: u32, w: f64) -> f64 {
    let l = f64::from(l);
    if l >= w { 0.0 } else { 0.5 * (1.0 + (PI * l / w).cos()) }
}

/// Lanczos (sinc) window factor of band `l` for window width `w`.
#[must_use]
pub fn lanczos(l: u32, w: f64) -> f64 {
    let l = f64::from(l);
    if l == 0.0 {
        1.0
    } else if l >= w {
        0.0
    } else {
        let x = PI * l / w;
        x.sin() / x
    }
}

/// Sloan's ringing-minimising window factor `1 / (1 + λ l²(l+1)²)`.
#[must_use]
pub fn ringing_minimizing(l: u32, lambda: f64) -> f64 {
    let l = f64::from(l);
    1.0 / (1.0 + lambda * l * l * (l + 1.0) * (l + 1.0))
}

/// Multiplies band `l` of `f` by `window(l)`.
#[must_use]
pub fn apply_window<const N: usize>(f: &Sh<f64, N>, window: impl Fn(u32) -> f64) -> Sh<f64, N> {
    let mut out = *f;
    for (i, c) in out.0.iter_mut().enumerate() {
        *c *= window(sh_lm(i).0);
    }
    out
}

fn normalize(v: [f64; 3]) -> [f64; 3] {
    let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    [v[0] / n, v[1] / n, v[2] / n]
}

/// Estimated minimum of `f` over the sphere and a direction where it occurs.
///
/// Evaluates a Fibonacci lattice of `64 N` points (spacing well below the width of the
/// narrowest lobe of degree `sqrt(N) - 1`), then refines the 8 best by a pattern search in
/// the tangent plane down to steps of 1e-9 radians. Deterministic.
#[must_use]
pub fn min_value<const N: usize>(f: &Sh<f64, N>) -> (f64, [f64; 3]) {
    let mut starts: Vec<(f64, [f64; 3])> = fibonacci_sphere(64 * N.max(4)).map(|d| (f.eval(d), d)).collect();
    starts.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut best = starts[0];
    let spacing = (4.0 * PI / starts.len() as f64).sqrt();
    for &(mut v, mut d) in starts.iter().take(8) {
        let mut step = spacing;
        while step > 1e-9 {
            let frame = Frame::from_normal(d);
            let mut improved = false;
            for (a, b) in [(1.0, 0.0), (-1.0, 0.0), (0.0, 1.0), (0.0, -1.0)] {
                let c = normalize(frame.to_world([a * step, b * step, 1.0]));
                let vc = f.eval(c);
                if vc < v {
                    v = vc;
                    d = c;
                    improved = true;
                    break;
                }
            }
            if !improved {
                step *= 0.5;
            }
        }
        if v < best.0 {
            best = (v, d);
        }
    }
    best
}

/// The smallest `λ >= 0` such that the ringing-minimised `f` has minimum `>= target`, found by
/// bisection to a relative precision of 1e-6; `None` if even heavy windowing (`λ = 1e6`,
/// which leaves essentially the DC term) cannot reach it.
#[must_use]
pub fn deringing_lambda<const N: usize>(f: &Sh<f64, N>, target: f64) -> Option<f64> {
    let min_at = |lambda: f64| min_value(&apply_window(f, |l| ringing_minimizing(l, lambda))).0;
    if min_at(0.0) >= target {
        return Some(0.0);
    }
    let mut hi = 1e-6;
    while min_at(hi) < target {
        hi *= 4.0;
        if hi > 1e6 {
            return None;
        }
    }
    let mut lo = hi / 4.0;
    while (hi - lo) > 1e-6 * hi {
        let mid = 0.5 * (lo + hi);
        if min_at(mid) >= target { hi = mid } else { lo = mid }
    }
    Some(hi)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::zonal::Zh;

    #[test]
    fn window_shapes() {
        assert_eq!(hanning(0, 3.0), 1.0);
        assert!((hanning(1, 2.0) - 0.5).abs() < 1e-15);
        assert_eq!(hanning(3, 3.0), 0.0);
        assert_eq!(lanczos(0, 3.0), 1.0);
        assert!((lanczos(1, 2.0) - 2.0 / PI).abs() < 1e-15);
        assert_eq!(ringing_minimizing(0, 5.0), 1.0);
        assert!((ringing_minimizing(1, 0.25) - 0.5).abs() < 1e-15);
    }

    /// The ringing-minimising window is the minimiser it claims to be: for each band, the
    /// objective (g - f)² + λ (l(l+1))² g² is smallest at g = w_l f.
    #[test]
    fn ringing_window_minimises_its_objective() {
        let lambda = 0.01;
        for l in 0..6u32 {
            let ll = f64::from(l * (l + 1));
            let obj = |g: f64| (g - 1.0).powi(2) + lambda * ll * ll * g * g;
            let w = ringing_minimizing(l, lambda);
            assert!(obj(w) <= obj(w + 1e-6) && obj(w) <= obj(w - 1e-6));
        }
    }

    #[test]
    fn min_of_linear_function_is_analytic() {
        // f = a y00 + b y10 has minimum a/sqrt(4π) - |b| sqrt(3/4π) at -z (for b > 0).
        let mut f = Sh::<f64, 4>::ZERO;
        f.0[0] = 1.0;
        f.0[2] = 0.8;
        let (v, d) = min_value(&f);
        let want = 1.0 / (4.0 * PI).sqrt() - 0.8 * (3.0 / (4.0 * PI)).sqrt();
        assert!((v - want).abs() < 1e-12);
        assert!((d[2] + 1.0).abs() < 1e-9);
    }

    #[test]
    fn min_matches_dense_search_and_deringing_lifts_it() {
        // A small cap (a sharp light) truncated to 6 bands rings below zero.
        let cap = Zh::<f64, 6>::cap(0.3);
        let f: Sh<f64, 36> = cap.rotate_to(normalize([0.3, -0.2, 0.9]));
        let (v, _) = min_value(&f);
        let dense = fibonacci_sphere(200_000).map(|d| f.eval(d)).fold(f64::INFINITY, f64::min);
        // The refined minimum is at or below the dense lattice's best, and not far below it
        // (lattice spacing 0.008 rad: the function changes by < 1e-4 within it).
        assert!(v <= dense + 1e-12 && v > dense - 1e-4, "{v} vs dense {dense}");
        assert!(v < 0.0, "truncated cap must ring negative");
        let lambda = deringing_lambda(&f, 0.0).expect("windowing can remove ringing");
        let g = apply_window(&f, |l| ringing_minimizing(l, lambda));
        assert!(min_value(&g).0 >= 0.0);
        // And it is the smallest such λ (to the bisection's precision).
        let h = apply_window(&f, |l| ringing_minimizing(l, lambda * 0.99));
        assert!(min_value(&h).0 < 0.0);
        // Windowing keeps the mean (DC term).
        assert_eq!(g.0[0], f.0[0]);
    }
}
