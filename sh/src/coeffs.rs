//! SH coefficient vectors: fixed-size `Copy` types, RGB triples, and a dynamic-order vector.
//!
//! A function `f(ω) = Σ_i c_i y_i(ω)` is stored as its coefficients `c_i` in the flat order
//! of [`crate::index::sh_index`]. Because the basis is orthonormal, the inner product of two
//! functions over the sphere is the dot product of their coefficient vectors.

use core::ops::{Add, AddAssign, Index, IndexMut, Mul, Neg, Sub, SubAssign};

use crate::eval::{eval_basis, eval_into};
use crate::index::bands_of;
use crate::real::Real;

/// A fixed-size SH coefficient vector with `N = bands²` coefficients.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(transparent)]
pub struct Sh<T, const N: usize>(pub [T; N]);

/// The `N = bands²` basis values at the unit vector `dir` as an [`Sh`] vector: the array of
/// [`eval_basis`] wrapped (the generated straight-line evaluation, Sloan 2013).
#[must_use]
#[inline]
pub fn eval_sh<T: Real, const N: usize>(dir: [T; 3]) -> Sh<T, N> {
    Sh(eval_basis(dir))
}

/// 1 coefficient (l = 0, a constant).
pub type Sh1<T = f32> = Sh<T, 1>;
/// 4 coefficients (l <= 1).
pub type Sh4<T = f32> = Sh<T, 4>;
/// 9 coefficients (l <= 2): the usual irradiance order.
pub type Sh9<T = f32> = Sh<T, 9>;
/// 16 coefficients (l <= 3).
pub type Sh16<T = f32> = Sh<T, 16>;
/// 25 coefficients (l <= 4).
pub type Sh25<T = f32> = Sh<T, 25>;
/// 36 coefficients (l <= 5).
pub type Sh36<T = f32> = Sh<T, 36>;
/// 49 coefficients (l <= 6).
pub type Sh49<T = f32> = Sh<T, 49>;
/// 64 coefficients (l <= 7).
pub type Sh64<T = f32> = Sh<T, 64>;

impl<T: Real, const N: usize> Default for Sh<T, N> {
    fn default() -> Self {
        Self::ZERO
    }
}

impl<T: Real, const N: usize> Sh<T, N> {
    /// The zero function.
    pub const ZERO: Self = Self([T::ZERO; N]);

    /// Number of bands, `sqrt(N)`.
    pub const BANDS: usize = N.isqrt();

    /// Wraps an array of coefficients.
    #[must_use]
    #[inline]
    pub const fn new(c: [T; N]) -> Self {
        Self(c)
    }

    /// The coefficients as a slice.
    #[must_use]
    #[inline]
    pub fn as_slice(&self) -> &[T] {
        &self.0
    }

    /// Inner product over the sphere, `∫ f g dω = Σ f_i g_i`.
    #[must_use]
    #[inline]
    pub fn dot(&self, other: &Self) -> T {
        let mut acc = T::ZERO;
        for i in 0..N {
            acc = self.0[i].mul_add(other.0[i], acc);
        }
        acc
    }

    /// Linear interpolation `self + (other - self) t`.
    #[must_use]
    #[inline]
    pub fn lerp(&self, other: &Self, t: T) -> Self {
        let mut out = *self;
        for i in 0..N {
            out.0[i] = (other.0[i] - self.0[i]).mul_add(t, self.0[i]);
        }
        out
    }

    /// Value of the function at the unit direction `dir`.
    #[must_use]
    #[inline]
    pub fn eval(&self, dir: [T; 3]) -> T {
        Sh(eval_basis::<T, N>(dir)).dot(self)
    }

    /// The L2 norm over the sphere.
    #[must_use]
    pub fn norm(&self) -> T {
        self.dot(self).sqrt()
    }

    /// Converts the scalar type (e.g. f64 accumulators to f32 storage).
    #[must_use]
    pub fn cast<U: Real>(&self) -> Sh<U, N> {
        Sh(self.0.map(|v| U::from_f64(v.to_f64())))
    }

    /// Copies the first `M` coefficients (truncates to fewer bands) or zero-pads (more bands).
    #[must_use]
    pub fn resize<const M: usize>(&self) -> Sh<T, M> {
        let mut out = [T::ZERO; M];
        let k = N.min(M);
        out[..k].copy_from_slice(&self.0[..k]);
        Sh(out)
    }
}

impl<T: Real, const N: usize> Index<usize> for Sh<T, N> {
    type Output = T;
    #[inline]
    fn index(&self, i: usize) -> &T {
        &self.0[i]
    }
}

impl<T: Real, const N: usize> IndexMut<usize> for Sh<T, N> {
    #[inline]
    fn index_mut(&mut self, i: usize) -> &mut T {
        &mut self.0[i]
    }
}

macro_rules! elementwise_ops {
    ($ty:ident) => {
        impl<T: Real, const N: usize> Add for $ty<T, N> {
            type Output = Self;
            #[inline]
            fn add(mut self, rhs: Self) -> Self {
                self += rhs;
                self
            }
        }
        impl<T: Real, const N: usize> Sub for $ty<T, N> {
            type Output = Self;
            #[inline]
            fn sub(mut self, rhs: Self) -> Self {
                self -= rhs;
                self
            }
        }
        impl<T: Real, const N: usize> Neg for $ty<T, N> {
            type Output = Self;
            #[inline]
            fn neg(self) -> Self {
                self * -T::ONE
            }
        }
    };
}

elementwise_ops!(Sh);
elementwise_ops!(ShRgb);

impl<T: Real, const N: usize> AddAssign for Sh<T, N> {
    #[inline]
    fn add_assign(&mut self, rhs: Self) {
        for i in 0..N {
            self.0[i] += rhs.0[i];
        }
    }
}

impl<T: Real, const N: usize> SubAssign for Sh<T, N> {
    #[inline]
    fn sub_assign(&mut self, rhs: Self) {
        for i in 0..N {
            self.0[i] -= rhs.0[i];
        }
    }
}

impl<T: Real, const N: usize> Mul<T> for Sh<T, N> {
    type Output = Self;
    #[inline]
    fn mul(self, s: T) -> Self {
        Sh(self.0.map(|v| v * s))
    }
}

/// Three SH vectors, one per colour channel (R, G, B).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShRgb<T, const N: usize>(pub [Sh<T, N>; 3]);

/// RGB with 4 coefficients per channel.
pub type ShRgb4<T = f32> = ShRgb<T, 4>;
/// RGB with 9 coefficients per channel.
pub type ShRgb9<T = f32> = ShRgb<T, 9>;
/// RGB with 16 coefficients per channel.
pub type ShRgb16<T = f32> = ShRgb<T, 16>;
/// RGB with 25 coefficients per channel.
pub type ShRgb25<T = f32> = ShRgb<T, 25>;
/// RGB with 36 coefficients per channel.
pub type ShRgb36<T = f32> = ShRgb<T, 36>;

impl<T: Real, const N: usize> Default for ShRgb<T, N> {
    fn default() -> Self {
        Self::ZERO
    }
}

impl<T: Real, const N: usize> ShRgb<T, N> {
    /// Zero in every channel.
    pub const ZERO: Self = Self([Sh::ZERO; 3]);

    /// Builds from three channels.
    #[must_use]
    #[inline]
    pub const fn new(r: Sh<T, N>, g: Sh<T, N>, b: Sh<T, N>) -> Self {
        Self([r, g, b])
    }

    /// The same function in every channel, scaled by `rgb`.
    #[must_use]
    pub fn from_scalar(f: Sh<T, N>, rgb: [T; 3]) -> Self {
        Self([f * rgb[0], f * rgb[1], f * rgb[2]])
    }

    /// Per-channel dot product.
    #[must_use]
    #[inline]
    pub fn dot(&self, other: &Self) -> [T; 3] {
        [0, 1, 2].map(|c| self.0[c].dot(&other.0[c]))
    }

    /// Dot product of every channel with one scalar vector (e.g. basis values).
    #[must_use]
    #[inline]
    pub fn dot_scalar(&self, other: &Sh<T, N>) -> [T; 3] {
        [0, 1, 2].map(|c| self.0[c].dot(other))
    }

    /// Linear interpolation per channel.
    #[must_use]
    pub fn lerp(&self, other: &Self, t: T) -> Self {
        Self([0, 1, 2].map(|c| self.0[c].lerp(&other.0[c], t)))
    }

    /// Value of each channel at the unit direction `dir`.
    #[must_use]
    #[inline]
    pub fn eval(&self, dir: [T; 3]) -> [T; 3] {
        self.dot_scalar(&Sh(eval_basis::<T, N>(dir)))
    }

    /// Converts the scalar type.
    #[must_use]
    pub fn cast<U: Real>(&self) -> ShRgb<U, N> {
        ShRgb(self.0.map(|c| c.cast()))
    }

    /// Applies `f` to each channel.
    #[must_use]
    pub fn map(&self, mut f: impl FnMut(&Sh<T, N>) -> Sh<T, N>) -> Self {
        Self([f(&self.0[0]), f(&self.0[1]), f(&self.0[2])])
    }
}

impl<T: Real, const N: usize> AddAssign for ShRgb<T, N> {
    #[inline]
    fn add_assign(&mut self, rhs: Self) {
        for c in 0..3 {
            self.0[c] += rhs.0[c];
        }
    }
}

impl<T: Real, const N: usize> SubAssign for ShRgb<T, N> {
    #[inline]
    fn sub_assign(&mut self, rhs: Self) {
        for c in 0..3 {
            self.0[c] -= rhs.0[c];
        }
    }
}

impl<T: Real, const N: usize> Mul<T> for ShRgb<T, N> {
    type Output = Self;
    #[inline]
    fn mul(self, s: T) -> Self {
        Self(self.0.map(|c| c * s))
    }
}

/// An SH vector whose number of bands is chosen at run time (any order, e.g. 16 bands).
#[derive(Clone, Debug, PartialEq)]
pub struct ShDyn<T> {
    bands: usize,
    coeffs: Vec<T>,
}

impl<T: Real> ShDyn<T> {
    /// The zero function with `bands` bands.
    #[must_use]
    pub fn zeros(bands: usize) -> Self {
        Self { bands, coeffs: vec![T::ZERO; bands * bands] }
    }

    /// Wraps coefficients; `None` unless their count is a perfect square.
    #[must_use]
    pub fn from_vec(coeffs: Vec<T>) -> Option<Self> {
        bands_of(coeffs.len()).map(|bands| Self { bands, coeffs })
    }

    /// From a fixed-size vector.
    #[must_use]
    pub fn from_fixed<const N: usize>(sh: &Sh<T, N>) -> Self {
        Self { bands: N.isqrt(), coeffs: sh.0.to_vec() }
    }

    /// Number of bands.
    #[must_use]
    pub fn bands(&self) -> usize {
        self.bands
    }

    /// The coefficients.
    #[must_use]
    pub fn as_slice(&self) -> &[T] {
        &self.coeffs
    }

    /// The coefficients, mutably.
    pub fn as_mut_slice(&mut self) -> &mut [T] {
        &mut self.coeffs
    }

    /// Consumes into the coefficient vector.
    #[must_use]
    pub fn into_vec(self) -> Vec<T> {
        self.coeffs
    }

    /// Inner product over the sphere; both must have the same number of bands.
    ///
    /// # Panics
    /// If the band counts differ.
    #[must_use]
    pub fn dot(&self, other: &Self) -> T {
        assert_eq!(self.bands, other.bands, "ShDyn::dot needs equal band counts");
        self.coeffs.iter().zip(&other.coeffs).fold(T::ZERO, |acc, (&a, &b)| a.mul_add(b, acc))
    }

    /// `self += other · s` (same band count).
    ///
    /// # Panics
    /// If the band counts differ.
    pub fn add_scaled(&mut self, other: &Self, s: T) {
        assert_eq!(self.bands, other.bands, "ShDyn::add_scaled needs equal band counts");
        for (a, &b) in self.coeffs.iter_mut().zip(&other.coeffs) {
            *a = b.mul_add(s, *a);
        }
    }

    /// Multiplies every coefficient by `s`.
    pub fn scale(&mut self, s: T) {
        for a in &mut self.coeffs {
            *a *= s;
        }
    }

    /// Linear interpolation `self + (other - self) t`.
    ///
    /// # Panics
    /// If the band counts differ.
    #[must_use]
    pub fn lerp(&self, other: &Self, t: T) -> Self {
        assert_eq!(self.bands, other.bands, "ShDyn::lerp needs equal band counts");
        let coeffs = self.coeffs.iter().zip(&other.coeffs).map(|(&a, &b)| (b - a).mul_add(t, a)).collect();
        Self { bands: self.bands, coeffs }
    }

    /// Value at the unit direction `dir`.
    #[must_use]
    pub fn eval(&self, dir: [T; 3]) -> T {
        let mut y = vec![T::ZERO; self.coeffs.len()];
        eval_into(self.bands, dir, &mut y);
        self.coeffs.iter().zip(&y).fold(T::ZERO, |acc, (&a, &b)| a.mul_add(b, acc))
    }
}

impl<T: Real> Index<usize> for ShDyn<T> {
    type Output = T;
    fn index(&self, i: usize) -> &T {
        &self.coeffs[i]
    }
}

impl<T: Real> IndexMut<usize> for ShDyn<T> {
    fn index_mut(&mut self, i: usize) -> &mut T {
        &mut self.coeffs[i]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn arithmetic() {
        let a = Sh4::<f64>::new([1.0, 2.0, 3.0, 4.0]);
        let b = Sh4::<f64>::new([0.5, -1.0, 0.0, 2.0]);
        assert_eq!((a + b).0, [1.5, 1.0, 3.0, 6.0]);
        assert_eq!((a - b).0, [0.5, 3.0, 3.0, 2.0]);
        assert_eq!((a * 2.0).0, [2.0, 4.0, 6.0, 8.0]);
        assert_eq!((-a).0, [-1.0, -2.0, -3.0, -4.0]);
        assert_eq!(a.dot(&b), 0.5 - 2.0 + 8.0);
        assert_eq!(a.lerp(&b, 0.5).0, [0.75, 0.5, 1.5, 3.0]);
        assert_eq!(Sh9::<f32>::BANDS, 3);
        let d = ShDyn::from_fixed(&a);
        assert_eq!(d.dot(&ShDyn::from_fixed(&b)), a.dot(&b));
        assert!(ShDyn::<f64>::from_vec(vec![0.0; 5]).is_none());
        let rgb = ShRgb::from_scalar(a, [1.0, 0.0, 2.0]);
        assert_eq!(rgb.dot_scalar(&b), [a.dot(&b), 0.0, 2.0 * a.dot(&b)]);
    }
}
