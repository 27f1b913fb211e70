//! The Vulkan context: loader, instance (with optional validation), physical and logical
//! device, one compute queue, and the command buffer, fence and timestamp queries that
//! dispatches share.
//!
//! [`GpuContext`] is a cheap handle (`Arc` inside). Buffers and pipelines keep their own
//! handle to the device, so the device is destroyed only after the last of them is dropped,
//! whatever the drop order in user code.

use std::ffi::{CStr, c_void};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};

use ash::vk;

use crate::error::{GpuError, VkContext};
use crate::info::{DEVICE_ENV, DeviceInfo, describe, enumerate, select_device};

/// Environment variable: `1` enables `VK_LAYER_KHRONOS_validation` and counts the errors it
/// reports (see [`GpuContext::validation_errors`]).
pub const VALIDATION_ENV: &str = "LIGHTVOL_VK_VALIDATION";

const VALIDATION_LAYER: &CStr = c"VK_LAYER_KHRONOS_validation";

/// How to create a [`GpuContext`].
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct ContextOptions {
    /// Device selector: a decimal index or a case-insensitive name substring (see
    /// [`crate::info::select_device`]). `None` picks the most capable device.
    pub device: Option<String>,
    /// Enable the Khronos validation layer and count its messages. Context creation fails
    /// with [`GpuError::ValidationUnavailable`] if the layer is not installed.
    pub validation: bool,
}

impl ContextOptions {
    /// Options from the environment: [`DEVICE_ENV`] (`LIGHTVOL_VK_DEVICE`) and
    /// [`VALIDATION_ENV`] (`LIGHTVOL_VK_VALIDATION=1`).
    #[must_use]
    pub fn from_env() -> Self {
        Self {
            device: std::env::var(DEVICE_ENV).ok(),
            validation: std::env::var(VALIDATION_ENV).is_ok_and(|v| v.trim() == "1"),
        }
    }
}

/// Counts of validation messages by severity, and the first few error texts.
#[derive(Debug, Default)]
struct ValidationLog {
    errors: AtomicU64,
    warnings: AtomicU64,
    first_errors: Mutex<Vec<String>>,
}

/// How many error texts [`ValidationLog`] keeps for reports.
const KEPT_ERRORS: usize = 8;

/// Receives validation-layer messages: counts errors and warnings, prints them to stderr.
///
/// # Safety
/// Called by the Vulkan loader with `user_data` pointing at the `ValidationLog` that
/// [`RawInstance`] keeps alive until the messenger is destroyed, and `data` either null or
/// valid for the duration of the call (VK_EXT_debug_utils).
unsafe extern "system" fn debug_callback(
    severity: vk::DebugUtilsMessageSeverityFlagsEXT,
    _types: vk::DebugUtilsMessageTypeFlagsEXT,
    data: *const vk::DebugUtilsMessengerCallbackDataEXT<'_>,
    user_data: *mut c_void,
) -> vk::Bool32 {
    // SAFETY: the loader passes back the pointer given at messenger creation: a
    // `ValidationLog` owned by an `Arc` that the instance keeps until after the messenger
    // is destroyed.
    let Some(log) = (unsafe { user_data.cast::<ValidationLog>().as_ref() }) else {
        return vk::FALSE;
    };
    // SAFETY: `data` is null or valid for this call (spec of PFN_vkDebugUtilsMessengerCallbackEXT);
    // `p_message` is null or a NUL-terminated string, which `message_as_c_str` handles.
    let msg = unsafe { data.as_ref().and_then(|d| d.message_as_c_str()) }
        .map_or_else(|| "<no message>".to_owned(), |m| m.to_string_lossy().into_owned());
    if severity.contains(vk::DebugUtilsMessageSeverityFlagsEXT::ERROR) {
        log.errors.fetch_add(1, Ordering::Relaxed);
        eprintln!("vulkan validation error: {msg}");
        if let Ok(mut v) = log.first_errors.lock()
            && v.len() < KEPT_ERRORS
        {
            v.push(msg);
        }
    } else if severity.contains(vk::DebugUtilsMessageSeverityFlagsEXT::WARNING) {
        log.warnings.fetch_add(1, Ordering::Relaxed);
        eprintln!("vulkan validation warning: {msg}");
    }
    vk::FALSE
}

/// The loader, an instance, and (with validation) the debug messenger.
pub(crate) struct RawInstance {
    // Field order: `instance` and `messenger` are destroyed in Drop before `entry` (the
    // loader library) is unloaded by its own drop, after Drop ran.
    pub(crate) entry: ash::Entry,
    pub(crate) instance: ash::Instance,
    pub(crate) api_version: u32,
    messenger: Option<(ash::ext::debug_utils::Instance, vk::DebugUtilsMessengerEXT)>,
    log: Arc<ValidationLog>,
}

impl RawInstance {
    /// Opens the loader and creates an instance (Vulkan 1.0 to 1.3, whatever the loader
    /// offers), with the validation layer and a counting messenger when `validation`.
    pub(crate) fn new(validation: bool) -> Result<Self, GpuError> {
        // SAFETY: loading the system Vulkan loader runs its initialisation code; we trust
        // the installed loader like any Vulkan application does. No other precondition.
        let entry = unsafe { ash::Entry::load() }.map_err(|e| GpuError::NoLoader(e.to_string()))?;
        // SAFETY: `entry` is a loaded loader; the call takes no pointers from us.
        let loader_version = unsafe { entry.try_enumerate_instance_version() }
            .vk("vkEnumerateInstanceVersion")?
            .unwrap_or(vk::API_VERSION_1_0);
        let api_version = loader_version.min(vk::API_VERSION_1_3);

        let mut layers = Vec::new();
        let mut extensions = Vec::new();
        if validation {
            // SAFETY: `entry` is loaded; the call fills a vector it allocates.
            let available = unsafe { entry.enumerate_instance_layer_properties() }
                .vk("vkEnumerateInstanceLayerProperties")?;
            if !available.iter().any(|l| l.layer_name_as_c_str() == Ok(VALIDATION_LAYER)) {
                return Err(GpuError::ValidationUnavailable(
                    "VK_LAYER_KHRONOS_validation is not installed (apt-get install vulkan-validationlayers)"
                        .into(),
                ));
            }
            // SAFETY: as above; a null layer name asks for the loader's and implicit
            // layers' extensions. The validation layer does not provide debug utils itself
            // in every version, so ask the layer too.
            let mut exts = unsafe { entry.enumerate_instance_extension_properties(None) }
                .vk("vkEnumerateInstanceExtensionProperties")?;
            // SAFETY: as above, for the named (installed) layer.
            exts.extend(
                unsafe { entry.enumerate_instance_extension_properties(Some(VALIDATION_LAYER)) }
                    .vk("vkEnumerateInstanceExtensionProperties")?,
            );
            if !exts.iter().any(|e| e.extension_name_as_c_str() == Ok(ash::ext::debug_utils::NAME)) {
                return Err(GpuError::ValidationUnavailable("VK_EXT_debug_utils is not available".into()));
            }
            layers.push(VALIDATION_LAYER.as_ptr());
            extensions.push(ash::ext::debug_utils::NAME.as_ptr());
        }

        let log = Arc::new(ValidationLog::default());
        let mut messenger_info = vk::DebugUtilsMessengerCreateInfoEXT::default()
            .message_severity(
                vk::DebugUtilsMessageSeverityFlagsEXT::ERROR | vk::DebugUtilsMessageSeverityFlagsEXT::WARNING,
            )
            .message_type(
                vk::DebugUtilsMessageTypeFlagsEXT::GENERAL
                    | vk::DebugUtilsMessageTypeFlagsEXT::VALIDATION
                    | vk::DebugUtilsMessageTypeFlagsEXT::PERFORMANCE,
            )
            .pfn_user_callback(Some(debug_callback))
            .user_data(Arc::as_ptr(&log).cast_mut().cast());
        let app = vk::ApplicationInfo::default()
            .application_name(c"lightvol")
            .engine_name(c"lightvol-gpu")
            .api_version(api_version);
        let mut create = vk::InstanceCreateInfo::default()
            .application_info(&app)
            .enabled_layer_names(&layers)
            .enabled_extension_names(&extensions);
        if validation {
            // Also report problems in vkCreateInstance / vkDestroyInstance themselves.
            create = create.push_next(&mut messenger_info);
        }
        // SAFETY: every pointer in `create` (application info, layer and extension names,
        // the chained messenger info and its user data) outlives the call; the names are
        // 'static C strings that the loader reported as available.
        let instance = unsafe { entry.create_instance(&create, None) }.map_err(|result| match result {
            vk::Result::ERROR_INCOMPATIBLE_DRIVER => GpuError::NoDevice(
                "the Vulkan loader found no driver (vkCreateInstance: ERROR_INCOMPATIBLE_DRIVER); \
                 install one, e.g. mesa-vulkan-drivers for lavapipe"
                    .into(),
            ),
            vk::Result::ERROR_LAYER_NOT_PRESENT | vk::Result::ERROR_EXTENSION_NOT_PRESENT => {
                GpuError::ValidationUnavailable(format!("vkCreateInstance: {result}"))
            }
            _ => GpuError::Vk { call: "vkCreateInstance", result },
        })?;
        let mut raw = Self { entry, instance, api_version, messenger: None, log };
        if validation {
            let du = ash::ext::debug_utils::Instance::new(&raw.entry, &raw.instance);
            // SAFETY: the instance was created with VK_EXT_debug_utils enabled; the create
            // info's user data points into `raw.log`, which lives as long as `raw` (the
            // messenger is destroyed first in Drop).
            let m = unsafe { du.create_debug_utils_messenger(&messenger_info, None) }
                .vk("vkCreateDebugUtilsMessengerEXT")?;
            raw.messenger = Some((du, m));
        }
        Ok(raw)
    }

    /// Descriptions of every physical device.
    pub(crate) fn devices(&self) -> Result<Vec<DeviceInfo>, GpuError> {
        Ok(enumerate(&self.instance)?
            .into_iter()
            .enumerate()
            .map(|(i, pd)| describe(&self.instance, self.api_version, pd, i))
            .collect())
    }
}

impl Drop for RawInstance {
    fn drop(&mut self) {
        if let Some((du, m)) = self.messenger.take() {
            // SAFETY: the messenger was created from this instance and is destroyed once.
            unsafe { du.destroy_debug_utils_messenger(m, None) };
        }
        // SAFETY: every child object (device, messenger) is destroyed before this point:
        // `DeviceShared::drop` destroys the device before dropping its `RawInstance`.
        unsafe { self.instance.destroy_instance(None) };
    }
}

/// Lists every physical device the Vulkan loader offers (for `lightvol gpu-info`).
///
/// Errors with [`GpuError::NoLoader`] when there is no loader or no driver. An empty list
/// means the loader works but reports no device.
pub fn gpu_info() -> Result<Vec<DeviceInfo>, GpuError> {
    let inst = RawInstance::new(false)?;
    inst.devices()
}

/// State shared by the context and every buffer and pipeline made from it.
pub(crate) struct DeviceShared {
    // Drop order: `Drop for DeviceShared` destroys the device objects, then the fields drop
    // (`raw` last of the Vulkan objects, destroying the instance).
    pub(crate) device: ash::Device,
    pub(crate) info: DeviceInfo,
    pub(crate) memory: vk::PhysicalDeviceMemoryProperties,
    pub(crate) limits: vk::PhysicalDeviceLimits,
    pub(crate) submit: Mutex<Submitter>,
    /// Held across a pipeline's descriptor update and its submission.
    pub(crate) dispatch_lock: Mutex<()>,
    raw: RawInstance,
}

/// The objects one submission uses; behind a mutex so submissions are serialised.
pub(crate) struct Submitter {
    pub(crate) queue: vk::Queue,
    pub(crate) pool: vk::CommandPool,
    pub(crate) cmd: vk::CommandBuffer,
    pub(crate) fence: vk::Fence,
    /// Two timestamps around the recorded work, when the queue supports them.
    pub(crate) timestamps: Option<vk::QueryPool>,
}

impl Drop for DeviceShared {
    fn drop(&mut self) {
        let s = self.submit.get_mut().unwrap_or_else(std::sync::PoisonError::into_inner);
        // SAFETY: this is the last reference to the device (buffers and pipelines hold an
        // `Arc` to `DeviceShared`), so no other object of it exists any more; waiting for
        // idle makes sure no submitted work still uses the objects destroyed below. Each
        // object was created from this device and is destroyed exactly once.
        unsafe {
            let _ = self.device.device_wait_idle();
            if let Some(q) = s.timestamps {
                self.device.destroy_query_pool(q, None);
            }
            self.device.destroy_fence(s.fence, None);
            self.device.destroy_command_pool(s.pool, None);
            self.device.destroy_device(None);
        }
    }
}

/// A Vulkan device ready for compute work: see the module docs.
#[derive(Clone)]
pub struct GpuContext {
    pub(crate) shared: Arc<DeviceShared>,
}

impl std::fmt::Debug for GpuContext {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GpuContext").field("device", &self.shared.info).finish_non_exhaustive()
    }
}

impl GpuContext {
    /// A context configured from the environment ([`ContextOptions::from_env`]).
    pub fn new() -> Result<Self, GpuError> {
        Self::with_options(&ContextOptions::from_env())
    }

    /// A context with explicit options.
    pub fn with_options(opts: &ContextOptions) -> Result<Self, GpuError> {
        let raw = RawInstance::new(opts.validation)?;
        let physicals = enumerate(&raw.instance)?;
        let infos = raw.devices()?;
        let index = select_device(&infos, opts.device.as_deref())?;
        let physical = physicals[index];
        let info = infos[index].clone();
        let instance = &raw.instance;

        // SAFETY: `physical` belongs to this live instance.
        let families = unsafe { instance.get_physical_device_queue_family_properties(physical) };
        // Prefer a compute family that can write timestamps; compute-only families (async
        // compute) first, as they do not compete with graphics work.
        let queue_family = (0..families.len())
            .filter(|&i| families[i].queue_flags.contains(vk::QueueFlags::COMPUTE))
            .min_by_key(|&i| {
                (
                    families[i].timestamp_valid_bits == 0,
                    families[i].queue_flags.contains(vk::QueueFlags::GRAPHICS),
                    i,
                )
            })
            .ok_or_else(|| GpuError::NoDevice(format!("{} has no compute queue", info.name)))?;
        let timestamp_bits = families[queue_family].timestamp_valid_bits;
        let queue_family = queue_family as u32;

        let priorities = [1.0f32];
        let queue_info = [vk::DeviceQueueCreateInfo::default()
            .queue_family_index(queue_family)
            .queue_priorities(&priorities)];
        let device_info = vk::DeviceCreateInfo::default().queue_create_infos(&queue_info);
        // SAFETY: the create info points at locals that outlive the call; `queue_family`
        // is a valid family index of `physical` and one queue is requested.
        let device = unsafe { instance.create_device(physical, &device_info, None) }.vk("vkCreateDevice")?;
        // SAFETY: `physical` belongs to this live instance.
        let memory = unsafe { instance.get_physical_device_memory_properties(physical) };
        // SAFETY: as above.
        let limits = unsafe { instance.get_physical_device_properties(physical) }.limits;

        // From here on, clean up `device` if a later step fails.
        let submit = match Self::make_submitter(&device, queue_family, timestamp_bits, &limits) {
            Ok(s) => s,
            Err(e) => {
                // SAFETY: nothing else was created from `device` (make_submitter cleans up
                // after itself on failure).
                unsafe { device.destroy_device(None) };
                return Err(e);
            }
        };
        Ok(Self {
            shared: Arc::new(DeviceShared {
                device,
                info,
                memory,
                limits,
                submit: Mutex::new(submit),
                dispatch_lock: Mutex::new(()),
                raw,
            }),
        })
    }

    fn make_submitter(
        device: &ash::Device,
        queue_family: u32,
        timestamp_bits: u32,
        limits: &vk::PhysicalDeviceLimits,
    ) -> Result<Submitter, GpuError> {
        // SAFETY: one queue was requested from `queue_family` at device creation.
        let queue = unsafe { device.get_device_queue(queue_family, 0) };
        let pool_info = vk::CommandPoolCreateInfo::default()
            .queue_family_index(queue_family)
            .flags(vk::CommandPoolCreateFlags::RESET_COMMAND_BUFFER);
        // SAFETY: valid create info for a live device.
        let pool = unsafe { device.create_command_pool(&pool_info, None) }.vk("vkCreateCommandPool")?;
        let alloc = vk::CommandBufferAllocateInfo::default()
            .command_pool(pool)
            .level(vk::CommandBufferLevel::PRIMARY)
            .command_buffer_count(1);
        // SAFETY: `pool` was just created from `device`.
        let cmd = match unsafe { device.allocate_command_buffers(&alloc) } {
            Ok(v) => v[0],
            Err(result) => {
                // SAFETY: `pool` is unused and destroyed once.
                unsafe { device.destroy_command_pool(pool, None) };
                return Err(GpuError::Vk { call: "vkAllocateCommandBuffers", result });
            }
        };
        // SAFETY: valid create info for a live device.
        let fence = match unsafe { device.create_fence(&vk::FenceCreateInfo::default(), None) } {
            Ok(f) => f,
            Err(result) => {
                // SAFETY: `pool` (and its command buffer) are unused and destroyed once.
                unsafe { device.destroy_command_pool(pool, None) };
                return Err(GpuError::Vk { call: "vkCreateFence", result });
            }
        };
        let timestamps = if timestamp_bits > 0 && limits.timestamp_compute_and_graphics == vk::TRUE {
            let qi = vk::QueryPoolCreateInfo::default().query_type(vk::QueryType::TIMESTAMP).query_count(2);
            // SAFETY: valid create info for a live device. A failure only disables timing.
            unsafe { device.create_query_pool(&qi, None) }.ok()
        } else {
            None
        };
        Ok(Submitter { queue, pool, cmd, fence, timestamps })
    }

    /// The selected device.
    #[must_use]
    pub fn device_info(&self) -> &DeviceInfo {
        &self.shared.info
    }

    /// Validation-layer errors reported so far (always 0 without validation).
    #[must_use]
    pub fn validation_errors(&self) -> u64 {
        self.shared.raw.log.errors.load(Ordering::Relaxed)
    }

    /// Validation-layer warnings reported so far.
    #[must_use]
    pub fn validation_warnings(&self) -> u64 {
        self.shared.raw.log.warnings.load(Ordering::Relaxed)
    }

    /// The first few validation error messages (for test failure reports).
    #[must_use]
    pub fn validation_messages(&self) -> Vec<String> {
        self.shared.raw.log.first_errors.lock().map(|v| v.clone()).unwrap_or_default()
    }

    /// Whether the validation layer is active on this context.
    #[must_use]
    pub fn validation_enabled(&self) -> bool {
        self.shared.raw.messenger.is_some()
    }

    /// Waits for all submitted work (there is none outstanding between calls of this
    /// crate's synchronous API; useful before timing host-side work).
    pub fn wait_idle(&self) -> Result<(), GpuError> {
        let _guard = self.shared.lock_submit();
        // SAFETY: the device is live; holding the submit lock means no queue submission
        // races with the wait (vkDeviceWaitIdle requires external sync of all queues).
        unsafe { self.shared.device.device_wait_idle() }.vk("vkDeviceWaitIdle")
    }
}

impl DeviceShared {
    /// Locks the submitter, recovering from a poisoned lock (the Vulkan objects stay
    /// valid; a panic mid-record leaves the command buffer to be reset by the next use).
    pub(crate) fn lock_submit(&self) -> MutexGuard<'_, Submitter> {
        self.submit.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
    }

    /// Nanoseconds per timestamp tick.
    pub(crate) fn timestamp_period(&self) -> f64 {
        f64::from(self.limits.timestamp_period)
    }

    /// Records commands with `record`, submits them, waits for completion and returns the
    /// GPU time between the two timestamps written around them (when supported).
    pub(crate) fn submit_and_wait(
        &self,
        record: impl FnOnce(&ash::Device, vk::CommandBuffer),
    ) -> Result<Option<f64>, GpuError> {
        let s = self.lock_submit();
        let d = &self.device;
        // SAFETY: the submit lock gives exclusive use of `cmd`, `fence` and the query pool;
        // the previous submission (if any) completed (we always wait before unlocking), so
        // resetting them is allowed. All handles were created from `d`.
        unsafe {
            d.reset_command_buffer(s.cmd, vk::CommandBufferResetFlags::empty()).vk("vkResetCommandBuffer")?;
            d.begin_command_buffer(
                s.cmd,
                &vk::CommandBufferBeginInfo::default().flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT),
            )
            .vk("vkBeginCommandBuffer")?;
            if let Some(q) = s.timestamps {
                d.cmd_reset_query_pool(s.cmd, q, 0, 2);
                d.cmd_write_timestamp(s.cmd, vk::PipelineStageFlags::TOP_OF_PIPE, q, 0);
            }
        }
        record(d, s.cmd);
        // SAFETY: as above; the command buffer is in the recording state.
        unsafe {
            if let Some(q) = s.timestamps {
                d.cmd_write_timestamp(s.cmd, vk::PipelineStageFlags::BOTTOM_OF_PIPE, q, 1);
            }
            d.end_command_buffer(s.cmd).vk("vkEndCommandBuffer")?;
            let cmds = [s.cmd];
            let submit = [vk::SubmitInfo::default().command_buffers(&cmds)];
            d.reset_fences(&[s.fence]).vk("vkResetFences")?;
            d.queue_submit(s.queue, &submit, s.fence).vk("vkQueueSubmit")?;
            d.wait_for_fences(&[s.fence], true, u64::MAX).vk("vkWaitForFences")?;
        }
        let Some(q) = s.timestamps else { return Ok(None) };
        let mut ticks = [0u64; 2];
        // SAFETY: both queries were written by the completed submission; WAIT is implied
        // by the fence but requested anyway; `ticks` holds 2 u64 results.
        unsafe {
            d.get_query_pool_results(
                q,
                0,
                &mut ticks,
                vk::QueryResultFlags::TYPE_64 | vk::QueryResultFlags::WAIT,
            )
        }
        .vk("vkGetQueryPoolResults")?;
        Ok(Some(ticks[1].wrapping_sub(ticks[0]) as f64 * self.timestamp_period() * 1e-9))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testing::{gpu_or_skip, gpu_required};

    /// The messenger counts what the layer reports: inject one error and one warning
    /// through `vkSubmitDebugUtilsMessageEXT` (valid API use) and read the counters back.
    /// This is what makes `validation_errors() == 0` in the validation tests meaningful.
    #[test]
    fn messenger_counts_injected_messages() {
        let Some(_plain) = gpu_or_skip() else { return };
        let opts = ContextOptions { validation: true, ..ContextOptions::from_env() };
        let ctx = match GpuContext::with_options(&opts) {
            Ok(c) => c,
            Err(GpuError::ValidationUnavailable(why)) => {
                assert!(!gpu_required(), "LIGHTVOL_REQUIRE_GPU=1 but validation is unavailable: {why}");
                println!("!!! VALIDATION NOT CHECKED: {why} !!!");
                return;
            }
            Err(e) => panic!("{e}"),
        };
        let (du, _) = ctx.shared.raw.messenger.as_ref().expect("validation context has a messenger");
        let before = (ctx.validation_errors(), ctx.validation_warnings());
        for (sev, text) in [
            (vk::DebugUtilsMessageSeverityFlagsEXT::ERROR, c"lightvol injected error"),
            (vk::DebugUtilsMessageSeverityFlagsEXT::WARNING, c"lightvol injected warning"),
            (vk::DebugUtilsMessageSeverityFlagsEXT::INFO, c"lightvol injected info"),
        ] {
            let data = vk::DebugUtilsMessengerCallbackDataEXT::default().message(text);
            // SAFETY: the instance has VK_EXT_debug_utils enabled; `data` and its message
            // outlive the call; exactly one severity bit is set.
            unsafe { du.submit_debug_utils_message(sev, vk::DebugUtilsMessageTypeFlagsEXT::GENERAL, &data) };
        }
        assert_eq!(ctx.validation_errors(), before.0 + 1);
        assert_eq!(ctx.validation_warnings(), before.1 + 1);
        assert!(ctx.validation_messages().iter().any(|m| m == "lightvol injected error"));
    }
}
