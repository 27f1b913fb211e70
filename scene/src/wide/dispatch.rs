//! Run-time choice of the traversal kernel: the instruction sets a tracer can use
//! ([`Isa`]), detected once when a tracer is built, and [`run`], which instantiates a
//! query for the chosen kernel.

use super::kernel::{Query, Scalar};

/// The kernels the tracer can traverse with. All return the same hits bit for bit; they
/// differ only in speed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Isa {
    /// One child box and one triangle at a time, in portable Rust (every target).
    Scalar,
    /// 4-wide SSE2: eight child boxes as two halves, four triangles at once (every x86-64).
    Sse2,
    /// 8-wide AVX2: eight child boxes at once (x86-64 with AVX2 and FMA, detected at run
    /// time; the default build still runs on baseline x86-64).
    Avx2,
}

/// The environment variable that picks a kernel for every tracer a process builds
/// (`scalar`, `sse2` or `avx2`), to compare kernels or to reproduce one machine's run on
/// another; results are the same whichever runs.
pub const ISA_ENV: &str = "LIGHTVOL_TRACE_ISA";

impl Isa {
    /// Every kernel, slowest first.
    pub const ALL: [Isa; 3] = [Isa::Scalar, Isa::Sse2, Isa::Avx2];

    /// The kernel's name, as [`Isa::parse`] reads it.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Isa::Scalar => "scalar",
            Isa::Sse2 => "sse2",
            Isa::Avx2 => "avx2",
        }
    }

    /// The kernel named `name` (case-insensitive).
    #[must_use]
    pub fn parse(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|i| i.name().eq_ignore_ascii_case(name.trim()))
    }

    /// True when this machine can run the kernel.
    #[must_use]
    pub fn is_available(self) -> bool {
        match self {
            Isa::Scalar => true,
            #[cfg(target_arch = "x86_64")]
            Isa::Sse2 => true,
            #[cfg(target_arch = "x86_64")]
            Isa::Avx2 => super::simd::avx2_detected(),
            #[cfg(not(target_arch = "x86_64"))]
            _ => false,
        }
    }

    /// The kernels this machine can run, slowest first.
    #[must_use]
    pub fn available() -> Vec<Self> {
        Self::ALL.into_iter().filter(|i| i.is_available()).collect()
    }

    /// The names of the kernels this machine runs, for messages (`scalar, sse2, avx2`).
    #[must_use]
    pub fn available_names() -> String {
        Self::available().iter().map(|i| i.name()).collect::<Vec<_>>().join(", ")
    }

    /// The fastest kernel this machine runs.
    #[must_use]
    pub fn best() -> Self {
        Self::ALL.into_iter().rev().find(|i| i.is_available()).unwrap_or(Isa::Scalar)
    }

    /// The kernel [`ISA_ENV`] asks for, or [`Isa::best`] when it is unset. An unknown
    /// name or one this machine cannot run is an error that says which it can.
    pub fn from_env() -> Result<Self, String> {
        let Ok(name) = std::env::var(ISA_ENV) else { return Ok(Self::best()) };
        match Self::parse(&name) {
            Some(isa) if isa.is_available() => Ok(isa),
            Some(isa) => Err(format!(
                "{ISA_ENV}={}: this machine cannot run it (it runs {})",
                isa.name(),
                Self::available_names()
            )),
            None => Err(format!(
                "{ISA_ENV}={name}: no such kernel (this machine runs {})",
                Self::available_names()
            )),
        }
    }
}

impl std::fmt::Display for Isa {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// Runs `q` with the kernel of `isa`, or with the scalar kernel where `isa` is not
/// available on this machine.
#[inline]
pub(crate) fn run<Q: Query>(isa: Isa, q: &Q) -> Q::Out {
    match isa {
        #[cfg(target_arch = "x86_64")]
        Isa::Sse2 => q.run::<super::simd::Sse2>(),
        #[cfg(target_arch = "x86_64")]
        Isa::Avx2 => super::simd::run_avx2(q).unwrap_or_else(|| q.run::<Scalar>()),
        _ => q.run::<Scalar>(),
    }
}
