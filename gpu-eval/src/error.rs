//! Typed errors of the GPU evaluator.

use ash::vk;

/// Everything that can go wrong between opening the Vulkan loader and reading results back.
#[derive(Debug, thiserror::Error)]
pub enum GpuError {
    /// The Vulkan loader (`libvulkan.so.1`, `vulkan-1.dll`, ...) could not be opened, or it
    /// could not create an instance because no driver is installed.
    #[error("no Vulkan loader: {0}")]
    NoLoader(String),
    /// The loader works but offers no usable device (none at all, none with a compute
    /// queue, or none matching `LIGHTVOL_VK_DEVICE`).
    #[error("no Vulkan device: {0}")]
    NoDevice(String),
    /// Validation was requested but `VK_LAYER_KHRONOS_validation` (Debian/Ubuntu package
    /// `vulkan-validationlayers`) or `VK_EXT_debug_utils` is not installed.
    #[error("Vulkan validation requested but unavailable: {0}")]
    ValidationUnavailable(String),
    /// A Vulkan call failed.
    #[error("{call} failed: {result:?} ({result})")]
    Vk {
        /// The Vulkan entry point that failed.
        call: &'static str,
        /// Its result code.
        result: vk::Result,
    },
    /// No memory type satisfies a buffer's requirements.
    #[error("no suitable memory type for {0}")]
    NoMemoryType(&'static str),
    /// A buffer or dispatch exceeds a device limit (storage buffer range, 32-bit indexing, ...).
    #[error("exceeds a device limit: {0}")]
    Limit(String),
    /// Inconsistent inputs (slice lengths, sizes).
    #[error("invalid input: {0}")]
    Invalid(String),
    /// A SPIR-V blob embedded at build time is malformed (a build bug).
    #[error("invalid SPIR-V for {0}")]
    Spirv(&'static str),
}

/// Attaches the name of the failing Vulkan call to a `vk::Result` error.
pub(crate) trait VkContext<T> {
    /// Maps `Err(result)` to [`GpuError::Vk`] naming `call`.
    fn vk(self, call: &'static str) -> Result<T, GpuError>;
}

impl<T> VkContext<T> for Result<T, vk::Result> {
    fn vk(self, call: &'static str) -> Result<T, GpuError> {
        self.map_err(|result| GpuError::Vk { call, result })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn messages_name_the_call_and_code() {
        let e = Err::<(), _>(vk::Result::ERROR_OUT_OF_DEVICE_MEMORY).vk("vkAllocateMemory").unwrap_err();
        let msg = e.to_string();
        assert!(msg.contains("vkAllocateMemory") && msg.contains("OUT_OF_DEVICE_MEMORY"), "{msg}");
        assert_eq!(GpuError::NoDevice("x".into()).to_string(), "no Vulkan device: x");
    }
}
