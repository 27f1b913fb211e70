#![doc = include_str!("../README.md")]
#![allow(
    unsafe_code,
    reason = "Vulkan through ash is FFI: every unsafe block carries a SAFETY comment and every unsafe fn a Safety section"
)]

pub mod brick_shader;
pub mod buffer;
pub mod context;
pub mod engine_shader;
pub mod error;
pub mod info;
pub mod lookup;
pub mod pipeline;
pub mod proxy;
pub mod shaders;
pub mod synthetic;
pub mod testing;

pub use buffer::GpuBuffer;
pub use context::{ContextOptions, GpuContext, VALIDATION_ENV, gpu_info};
pub use error::GpuError;
pub use info::{DEVICE_ENV, DeviceInfo, DeviceKind, select_device};
pub use lookup::{LookupBatch, Quantity, VolumeLookup};
pub use pipeline::{ComputePipeline, DispatchStats};
pub use proxy::{ProxyFrame, ProxyShading, UpsampleTarget};
pub use testing::{REQUIRE_GPU_ENV, gpu_or_skip};

#[cfg(test)]
mod tests {
    /// The handles users keep in their own structs may cross threads.
    #[test]
    fn handles_are_send_and_sync() {
        fn check<T: Send + Sync>() {}
        check::<crate::GpuContext>();
        check::<crate::GpuBuffer>();
        check::<crate::ComputePipeline>();
        check::<crate::VolumeLookup>();
        check::<crate::LookupBatch>();
        check::<crate::ProxyShading<16>>();
    }
}
