//! Device descriptions and device selection (`LIGHTVOL_VK_DEVICE`). The listing itself,
//! [`crate::context::gpu_info`] (`lightvol gpu-info`), opens an instance and lives with the
//! context.

use std::ffi::CStr;
use std::fmt;

use ash::vk;

use crate::error::{GpuError, VkContext};

/// Environment variable picking the device: a decimal index into the list that
/// [`crate::context::gpu_info`] prints, or a case-insensitive substring of the device name.
pub const DEVICE_ENV: &str = "LIGHTVOL_VK_DEVICE";

/// The kind of a physical device, in the order the default selection prefers them.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum DeviceKind {
    /// A discrete GPU.
    Discrete,
    /// A GPU integrated with the CPU.
    Integrated,
    /// A virtualised GPU.
    Virtual,
    /// A CPU implementation, such as Mesa's lavapipe or SwiftShader.
    Cpu,
    /// Anything else.
    Other,
}

impl DeviceKind {
    /// Maps the Vulkan device type.
    #[must_use]
    pub fn from_vk(t: vk::PhysicalDeviceType) -> Self {
        match t {
            vk::PhysicalDeviceType::DISCRETE_GPU => Self::Discrete,
            vk::PhysicalDeviceType::INTEGRATED_GPU => Self::Integrated,
            vk::PhysicalDeviceType::VIRTUAL_GPU => Self::Virtual,
            vk::PhysicalDeviceType::CPU => Self::Cpu,
            _ => Self::Other,
        }
    }
}

impl fmt::Display for DeviceKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Self::Discrete => "discrete GPU",
            Self::Integrated => "integrated GPU",
            Self::Virtual => "virtual GPU",
            Self::Cpu => "CPU",
            Self::Other => "other",
        })
    }
}

/// What `lightvol gpu-info` prints about one physical device.
#[derive(Debug, Clone, PartialEq)]
pub struct DeviceInfo {
    /// Position in the loader's enumeration (what `LIGHTVOL_VK_DEVICE=<index>` selects).
    pub index: usize,
    /// Device name, e.g. `"llvmpipe (LLVM 15.0.6, 256 bits)"`.
    pub name: String,
    /// Device type.
    pub kind: DeviceKind,
    /// Vulkan API version the device supports, `major.minor.patch`.
    pub api_version: String,
    /// Driver name and info (Vulkan 1.2 driver properties), e.g. `"llvmpipe: Mesa 22.3.6"`;
    /// the raw driver version number where the device predates Vulkan 1.2.
    pub driver: String,
    /// PCI vendor and device id.
    pub vendor_device: (u32, u32),
    /// Total size of the device-local memory heaps, bytes.
    pub device_local_bytes: u64,
    /// Total size of all memory heaps, bytes.
    pub total_heap_bytes: u64,
    /// Whether the device has a queue family with compute support.
    pub has_compute: bool,
    /// `maxStorageBufferRange`: the largest storage buffer binding, bytes.
    pub max_storage_buffer_range: u32,
    /// Nanoseconds per timestamp tick (0 when compute queues cannot write timestamps).
    pub timestamp_period_ns: f32,
}

impl fmt::Display for DeviceInfo {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let gib = |b: u64| b as f64 / f64::from(1u32 << 30);
        write!(
            f,
            "[{}] {} ({}), Vulkan {}, driver {}, {:.2} GiB device-local / {:.2} GiB total{}",
            self.index,
            self.name,
            self.kind,
            self.api_version,
            self.driver,
            gib(self.device_local_bytes),
            gib(self.total_heap_bytes),
            if self.has_compute { "" } else { ", NO compute queue" }
        )
    }
}

/// Formats a packed Vulkan version number.
#[must_use]
pub fn version_string(v: u32) -> String {
    format!("{}.{}.{}", vk::api_version_major(v), vk::api_version_minor(v), vk::api_version_patch(v))
}

fn c_string(s: Result<&CStr, std::ffi::FromBytesUntilNulError>) -> String {
    s.map_or_else(|_| "<unterminated>".to_owned(), |c| c.to_string_lossy().into_owned())
}

/// Describes physical device `pd` (number `index` in the enumeration).
///
/// `instance_version` is the API version the instance was created with: driver properties
/// are queried only where both it and the device support Vulkan 1.2.
pub(crate) fn describe(
    instance: &ash::Instance,
    instance_version: u32,
    pd: vk::PhysicalDevice,
    index: usize,
) -> DeviceInfo {
    // SAFETY: `pd` was enumerated from this live instance; the call only writes the
    // returned struct.
    let props = unsafe { instance.get_physical_device_properties(pd) };
    // SAFETY: as above.
    let mem = unsafe { instance.get_physical_device_memory_properties(pd) };
    // SAFETY: as above.
    let families = unsafe { instance.get_physical_device_queue_family_properties(pd) };
    let vk12 = vk::make_api_version(0, 1, 2, 0);
    let driver = if props.api_version >= vk12 && instance_version >= vk12 {
        let mut drv = vk::PhysicalDeviceDriverProperties::default();
        let mut p2 = vk::PhysicalDeviceProperties2::default().push_next(&mut drv);
        // SAFETY: both the instance and the device support Vulkan 1.2, where
        // VkPhysicalDeviceDriverProperties is core; the chain holds only that struct, which
        // outlives the call.
        unsafe { instance.get_physical_device_properties2(pd, &mut p2) };
        format!("{}: {}", c_string(drv.driver_name_as_c_str()), c_string(drv.driver_info_as_c_str()))
    } else {
        format!("version 0x{:08x}", props.driver_version)
    };
    let heaps = &mem.memory_heaps[..mem.memory_heap_count as usize];
    DeviceInfo {
        index,
        name: c_string(props.device_name_as_c_str()),
        kind: DeviceKind::from_vk(props.device_type),
        api_version: version_string(props.api_version),
        driver,
        vendor_device: (props.vendor_id, props.device_id),
        device_local_bytes: heaps
            .iter()
            .filter(|h| h.flags.contains(vk::MemoryHeapFlags::DEVICE_LOCAL))
            .map(|h| h.size)
            .sum(),
        total_heap_bytes: heaps.iter().map(|h| h.size).sum(),
        has_compute: families.iter().any(|f| f.queue_flags.contains(vk::QueueFlags::COMPUTE)),
        max_storage_buffer_range: props.limits.max_storage_buffer_range,
        timestamp_period_ns: if props.limits.timestamp_compute_and_graphics == vk::TRUE {
            props.limits.timestamp_period
        } else {
            0.0
        },
    }
}

/// Picks a device from `devices` by `selector` (the value of [`DEVICE_ENV`], if set): a
/// decimal index, or a case-insensitive substring of the name. Without a selector the
/// first device with a compute queue of the most preferred [`DeviceKind`] wins (discrete,
/// integrated, virtual, CPU, other; ties go to the lower index).
pub fn select_device(devices: &[DeviceInfo], selector: Option<&str>) -> Result<usize, GpuError> {
    let listing = || {
        if devices.is_empty() {
            "the loader reports no devices".to_owned()
        } else {
            devices.iter().map(|d| format!("[{}] {}", d.index, d.name)).collect::<Vec<_>>().join(", ")
        }
    };
    let usable = |d: &DeviceInfo| {
        if d.has_compute {
            Ok(d.index)
        } else {
            Err(GpuError::NoDevice(format!("device [{}] {} has no compute queue", d.index, d.name)))
        }
    };
    match selector.map(str::trim).filter(|s| !s.is_empty()) {
        Some(sel) => {
            if let Ok(i) = sel.parse::<usize>() {
                return devices.iter().find(|d| d.index == i).map_or_else(
                    || {
                        Err(GpuError::NoDevice(format!(
                            "{DEVICE_ENV}={sel}: no device {i} (have: {})",
                            listing()
                        )))
                    },
                    usable,
                );
            }
            let needle = sel.to_lowercase();
            devices.iter().find(|d| d.name.to_lowercase().contains(&needle)).map_or_else(
                || {
                    Err(GpuError::NoDevice(format!(
                        "{DEVICE_ENV}={sel}: no device name matches (have: {})",
                        listing()
                    )))
                },
                usable,
            )
        }
        None => devices
            .iter()
            .filter(|d| d.has_compute)
            .min_by_key(|d| (d.kind, d.index))
            .map(|d| d.index)
            .ok_or_else(|| GpuError::NoDevice(format!("no device with a compute queue ({})", listing()))),
    }
}

/// Enumerates physical devices of a live instance.
pub(crate) fn enumerate(instance: &ash::Instance) -> Result<Vec<vk::PhysicalDevice>, GpuError> {
    // SAFETY: the instance is live; the call only fills the returned vector.
    unsafe { instance.enumerate_physical_devices() }.vk("vkEnumeratePhysicalDevices")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dev(index: usize, name: &str, kind: DeviceKind, has_compute: bool) -> DeviceInfo {
        DeviceInfo {
            index,
            name: name.into(),
            kind,
            api_version: "1.3.0".into(),
            driver: "test".into(),
            vendor_device: (0, 0),
            device_local_bytes: 0,
            total_heap_bytes: 0,
            has_compute,
            max_storage_buffer_range: u32::MAX,
            timestamp_period_ns: 1.0,
        }
    }

    #[test]
    fn default_prefers_discrete_then_lower_index() {
        let d = [
            dev(0, "llvmpipe (LLVM 15)", DeviceKind::Cpu, true),
            dev(1, "Intel UHD", DeviceKind::Integrated, true),
            dev(2, "NVIDIA H100", DeviceKind::Discrete, false),
            dev(3, "AMD Radeon", DeviceKind::Discrete, true),
            dev(4, "NVIDIA RTX", DeviceKind::Discrete, true),
        ];
        assert_eq!(select_device(&d, None).unwrap(), 3);
        assert_eq!(select_device(&d, Some("  ")).unwrap(), 3);
        assert_eq!(select_device(&d[..2], None).unwrap(), 1);
        assert_eq!(select_device(&d[..1], None).unwrap(), 0);
    }

    #[test]
    fn selector_by_index_or_name() {
        let d = [
            dev(0, "llvmpipe (LLVM 15)", DeviceKind::Cpu, true),
            dev(1, "NVIDIA H100", DeviceKind::Discrete, false),
        ];
        assert_eq!(select_device(&d, Some("0")).unwrap(), 0);
        assert_eq!(select_device(&d, Some("LLVMpipe")).unwrap(), 0);
        assert!(
            matches!(select_device(&d, Some("7")), Err(GpuError::NoDevice(m)) if m.contains("no device 7"))
        );
        assert!(
            matches!(select_device(&d, Some("h100")), Err(GpuError::NoDevice(m)) if m.contains("no compute"))
        );
        assert!(
            matches!(select_device(&d, Some("radeon")), Err(GpuError::NoDevice(m)) if m.contains("llvmpipe"))
        );
        assert!(matches!(select_device(&[], None), Err(GpuError::NoDevice(m)) if m.contains("no devices")));
    }

    #[test]
    fn versions_format() {
        assert_eq!(version_string(vk::make_api_version(0, 1, 3, 239)), "1.3.239");
    }
}
