//! The SPIR-V modules compiled from `shaders/*.wgsl` by `build.rs` (naga), embedded at
//! build time.

use crate::error::GpuError;

/// One embedded SPIR-V module.
#[derive(Debug, Clone, Copy)]
pub struct Shader {
    /// Variant name (`lookup_9`, ...).
    pub name: &'static str,
    bytes: &'static [u8],
}

impl Shader {
    /// The SPIR-V words (little-endian in the file; SPIR-V consumers accept either order
    /// via the magic number, but we decode as the file was written).
    pub fn words(&self) -> Result<Vec<u32>, GpuError> {
        if !self.bytes.len().is_multiple_of(4) || self.bytes.len() < 20 {
            return Err(GpuError::Spirv(self.name));
        }
        Ok(self.bytes.chunks_exact(4).map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect())
    }
}

macro_rules! shader {
    ($name:literal) => {
        Shader { name: $name, bytes: include_bytes!(concat!(env!("OUT_DIR"), "/", $name, ".spv")) }
    };
}

/// The volume-lookup kernel for 4, 9 and 16 coefficients (`shaders/lookup.wgsl`).
pub const LOOKUP: [Shader; 3] = [shader!("lookup_4"), shader!("lookup_9"), shader!("lookup_16")];

/// The proxy-accumulation kernel for 9 and 16 shadow coefficients (`shaders/accumulate.wgsl`).
pub const ACCUMULATE: [Shader; 2] = [shader!("accumulate_9"), shader!("accumulate_16")];

/// The proxy exponentiation kernel for 9 and 16 coefficients (`shaders/exponentiate.wgsl`).
pub const EXPONENTIATE: [Shader; 2] = [shader!("exponentiate_9"), shader!("exponentiate_16")];

/// The bilateral upsampling kernel (`shaders/upsample.wgsl`).
pub const UPSAMPLE: Shader = shader!("upsample");

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn embedded_modules_are_spirv() {
        for s in LOOKUP.into_iter().chain(ACCUMULATE).chain(EXPONENTIATE).chain([UPSAMPLE]) {
            let w = s.words().unwrap();
            assert_eq!(w[0], 0x0723_0203, "{}: SPIR-V magic", s.name);
            // Version word: SPIR-V 1.0 as requested in build.rs.
            assert_eq!(w[1], 0x0001_0000, "{}", s.name);
        }
    }
}
