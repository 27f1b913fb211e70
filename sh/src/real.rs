//! The floating-point scalar trait shared by every generic routine in the crate.
//!
//! Only `f32` and `f64` implement it. It carries just the operations the SH code
//! needs, so that one generic body serves both precisions and the f32 path is
//! tested against the same reference as the f64 path.

use core::fmt::Debug;
use core::ops::{Add, AddAssign, Div, Mul, MulAssign, Neg, Sub, SubAssign};

/// A real floating-point scalar: `f32` or `f64`.
pub trait Real:
    Copy
    + Debug
    + Default
    + PartialOrd
    + Send
    + Sync
    + 'static
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
    + AddAssign
    + SubAssign
    + MulAssign
{
    /// Additive identity.
    const ZERO: Self;
    /// Multiplicative identity.
    const ONE: Self;
    /// Converts from `f64`, rounding to nearest.
    #[must_use]
    fn from_f64(v: f64) -> Self;
    /// Widens (or returns) the value as `f64`.
    #[must_use]
    fn to_f64(self) -> f64;
    /// Square root.
    #[must_use]
    fn sqrt(self) -> Self;
    /// `self * a + b`, fused when the target supports it.
    #[must_use]
    fn mul_add(self, a: Self, b: Self) -> Self;
    /// Absolute value.
    #[must_use]
    fn abs(self) -> Self;
    /// `e^self`, in the type's own precision (the DC factor of the SH exponential,
    /// [`crate::shexp`]).
    #[must_use]
    fn exp(self) -> Self;

    /// Evaluates the first `bands` bands (`bands * bands` values) of the real SH basis at the
    /// unit vector `(x, y, z)` into `out[..bands * bands]`, with the generated straight-line
    /// code. `bands` must be in `1..=`[`crate::eval::MAX_FAST_BANDS`].
    ///
    /// This is the per-precision hook for [`crate::eval`]; call the functions there instead.
    fn eval_sh_fast(bands: usize, x: Self, y: Self, z: Self, out: &mut [Self]);
}

macro_rules! impl_real {
    ($t:ty, $gen:path) => {
        impl Real for $t {
            const ZERO: Self = 0.0;
            const ONE: Self = 1.0;
            #[inline(always)]
            fn from_f64(v: f64) -> Self {
                v as $t
            }
            #[inline(always)]
            fn to_f64(self) -> f64 {
                f64::from(self)
            }
            #[inline(always)]
            fn sqrt(self) -> Self {
                <$t>::sqrt(self)
            }
            #[inline(always)]
            fn mul_add(self, a: Self, b: Self) -> Self {
                // A plain multiply-add: without a guaranteed FMA unit `<$t>::mul_add` calls
                // into libm and is far slower. Both forms are accurate to well within the
                // tolerances this crate states.
                self * a + b
            }
            #[inline(always)]
            fn abs(self) -> Self {
                <$t>::abs(self)
            }
            #[inline(always)]
            fn exp(self) -> Self {
                <$t>::exp(self)
            }
            #[inline(always)]
            fn eval_sh_fast(bands: usize, x: Self, y: Self, z: Self, out: &mut [Self]) {
                $gen(bands, x, y, z, out)
            }
        }
    };
}

impl_real!(f32, crate::generated::eval_sh_f32);
impl_real!(f64, crate::generated::eval_sh_f64);
