//! Storage buffers: allocation, upload and readback.
//!
//! A [`GpuBuffer`] lives in device-local memory. Where that memory is also host-visible
//! and coherent (integrated GPUs, lavapipe, resizable-BAR discrete GPUs) it stays mapped
//! and uploads/readbacks are plain copies; otherwise they go through a temporary
//! host-visible staging buffer and a `vkCmdCopyBuffer`. Callers see the same API either way.
//!
//! Data crosses the API as `f32`/`u32` slices (the shaders' element types), copied as
//! native-endian bytes; Vulkan devices share the host's endianness.

use std::ptr::NonNull;
use std::sync::Arc;

use ash::vk;

use crate::context::{DeviceShared, GpuContext};
use crate::error::{GpuError, VkContext};

/// A device buffer usable as a storage buffer and as a transfer source and destination.
pub struct GpuBuffer {
    shared: Arc<DeviceShared>,
    pub(crate) buffer: vk::Buffer,
    memory: vk::DeviceMemory,
    size: u64,
    /// The persistent mapping when the memory is host-visible and coherent.
    mapped: Option<NonNull<u8>>,
}

// SAFETY: the raw mapping pointer is only dereferenced through `&mut self` (writes) or
// `&self` reads of memory the device does not write concurrently (every dispatch waits for
// completion before returning); Vulkan handles themselves are plain identifiers usable
// from any thread.
unsafe impl Send for GpuBuffer {}
// SAFETY: see `Send`; shared references only read the mapping, and do so holding the
// device's dispatch lock, so never while a dispatch (which may write the buffer) runs.
unsafe impl Sync for GpuBuffer {}

impl std::fmt::Debug for GpuBuffer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GpuBuffer").field("size", &self.size).field("mapped", &self.mapped.is_some()).finish()
    }
}

/// Memory-type search: the first type allowed by `bits` with all `required` flags,
/// preferring one that also has all `preferred` flags.
pub(crate) fn find_memory_type(
    props: &vk::PhysicalDeviceMemoryProperties,
    bits: u32,
    required: vk::MemoryPropertyFlags,
    preferred: vk::MemoryPropertyFlags,
) -> Option<u32> {
    let types = &props.memory_types[..props.memory_type_count as usize];
    let ok =
        |i: usize, f: vk::MemoryPropertyFlags| bits & (1 << i) != 0 && types[i].property_flags.contains(f);
    (0..types.len())
        .find(|&i| ok(i, required | preferred))
        .or_else(|| (0..types.len()).find(|&i| ok(i, required)))
        .map(|i| i as u32)
}

const HOST: vk::MemoryPropertyFlags = vk::MemoryPropertyFlags::from_raw(
    vk::MemoryPropertyFlags::HOST_VISIBLE.as_raw() | vk::MemoryPropertyFlags::HOST_COHERENT.as_raw(),
);

impl GpuBuffer {
    /// Allocates `size` bytes (at least 4). `host` asks for host-visible coherent memory
    /// (a staging buffer); otherwise device-local memory, mapped if it happens to be
    /// host-visible and coherent too.
    fn allocate(shared: &Arc<DeviceShared>, size: u64, host: bool) -> Result<Self, GpuError> {
        let size = size.max(4).next_multiple_of(4);
        let d = &shared.device;
        let info = vk::BufferCreateInfo::default()
            .size(size)
            .usage(
                vk::BufferUsageFlags::STORAGE_BUFFER
                    | vk::BufferUsageFlags::TRANSFER_SRC
                    | vk::BufferUsageFlags::TRANSFER_DST,
            )
            .sharing_mode(vk::SharingMode::EXCLUSIVE);
        // SAFETY: valid create info (non-zero size, exclusive sharing) for a live device.
        let buffer = unsafe { d.create_buffer(&info, None) }.vk("vkCreateBuffer")?;
        // From here, dropping `this` destroys what exists if we return early.
        let mut this =
            Self { shared: shared.clone(), buffer, memory: vk::DeviceMemory::null(), size, mapped: None };
        // SAFETY: `buffer` was created from `d`.
        let req = unsafe { d.get_buffer_memory_requirements(buffer) };
        let (required, preferred) = if host {
            (HOST, vk::MemoryPropertyFlags::HOST_CACHED)
        } else {
            (vk::MemoryPropertyFlags::DEVICE_LOCAL, HOST)
        };
        let ty = find_memory_type(&shared.memory, req.memory_type_bits, required, preferred)
            .ok_or(GpuError::NoMemoryType(if host { "a staging buffer" } else { "a storage buffer" }))?;
        let alloc = vk::MemoryAllocateInfo::default().allocation_size(req.size).memory_type_index(ty);
        // SAFETY: the type index comes from this device's memory properties and allows the
        // buffer's requirements.
        this.memory = unsafe { d.allocate_memory(&alloc, None) }.vk("vkAllocateMemory")?;
        // SAFETY: fresh memory of a compatible type, offset 0 satisfies any alignment.
        unsafe { d.bind_buffer_memory(buffer, this.memory, 0) }.vk("vkBindBufferMemory")?;
        let flags = shared.memory.memory_types[ty as usize].property_flags;
        if flags.contains(HOST) {
            // SAFETY: host-visible memory, mapped once for its whole size, never unmapped
            // before being freed (freeing unmaps implicitly).
            let p = unsafe { d.map_memory(this.memory, 0, vk::WHOLE_SIZE, vk::MemoryMapFlags::empty()) }
                .vk("vkMapMemory")?;
            this.mapped = NonNull::new(p.cast::<u8>());
        }
        Ok(this)
    }

    /// Size in bytes (rounded up to a multiple of 4, at least 4).
    #[must_use]
    pub fn size(&self) -> u64 {
        self.size
    }

    /// Whether the buffer is host-visible (uploads and readbacks avoid staging copies).
    #[must_use]
    pub fn is_mapped(&self) -> bool {
        self.mapped.is_some()
    }

    pub(crate) fn shared(&self) -> &Arc<DeviceShared> {
        &self.shared
    }

    /// Writes `data` at byte `offset`. Errors if it does not fit.
    pub fn write<T: Pod>(&mut self, offset: u64, data: &[T]) -> Result<(), GpuError> {
        let bytes = as_bytes(data);
        let end = offset.checked_add(bytes.len() as u64).filter(|&e| e <= self.size);
        if end.is_none() {
            return Err(GpuError::Invalid(format!(
                "write of {} bytes at {offset} into a {}-byte buffer",
                bytes.len(),
                self.size
            )));
        }
        if bytes.is_empty() {
            return Ok(());
        }
        if let Some(p) = self.mapped {
            // SAFETY: the mapping covers `size` bytes and `offset + len <= size` was
            // checked; `&mut self` excludes concurrent host access, and no device work is
            // in flight (submissions are synchronous); source and mapping do not overlap.
            unsafe {
                std::ptr::copy_nonoverlapping(bytes.as_ptr(), p.as_ptr().add(offset as usize), bytes.len())
            };
            return Ok(());
        }
        let mut staging = Self::allocate(&self.shared, bytes.len() as u64, true)?;
        staging.write(0, data)?;
        let region = [vk::BufferCopy { src_offset: 0, dst_offset: offset, size: bytes.len() as u64 }];
        self.shared.submit_and_wait(|d, cmd| {
            // SAFETY: both buffers are live, have TRANSFER usage and the region lies
            // inside both (checked above; staging is at least `len` bytes).
            unsafe { d.cmd_copy_buffer(cmd, staging.buffer, self.buffer, &region) };
        })?;
        Ok(())
    }

    /// Reads `count` elements starting at byte `offset`.
    pub fn read<T: Pod>(&self, offset: u64, count: usize) -> Result<Vec<T>, GpuError> {
        let len = count
            .checked_mul(size_of::<T>())
            .ok_or_else(|| GpuError::Invalid("read size overflows".into()))?;
        if offset.checked_add(len as u64).is_none_or(|e| e > self.size) {
            return Err(GpuError::Invalid(format!(
                "read of {len} bytes at {offset} from a {}-byte buffer",
                self.size
            )));
        }
        let mut out = vec![T::ZERO; count];
        if len == 0 {
            return Ok(out);
        }
        if let Some(p) = self.mapped {
            // Another thread may hold `&self` in a dispatch; the dispatch lock waits for it.
            let _no_dispatch =
                self.shared.dispatch_lock.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
            // SAFETY: the range lies inside the mapping (checked); no device work is in
            // flight (dispatches hold the lock taken above until their fence signals;
            // staging copies into this buffer need `&mut self`), and the memory is
            // coherent, so it holds the device's writes; `out` has exactly `len` bytes and
            // every bit pattern is a valid `T` (`Pod`).
            unsafe {
                std::ptr::copy_nonoverlapping(
                    p.as_ptr().add(offset as usize),
                    out.as_mut_ptr().cast::<u8>(),
                    len,
                );
            }
            return Ok(out);
        }
        let staging = Self::allocate(&self.shared, len as u64, true)?;
        let region = [vk::BufferCopy { src_offset: offset, dst_offset: 0, size: len as u64 }];
        self.shared.submit_and_wait(|d, cmd| {
            // SAFETY: both buffers are live with TRANSFER usage; the region lies inside both.
            unsafe { d.cmd_copy_buffer(cmd, self.buffer, staging.buffer, &region) };
        })?;
        staging.read(0, count)
    }
}

impl Drop for GpuBuffer {
    fn drop(&mut self) {
        // SAFETY: no submission that uses the buffer is in flight (all are synchronous);
        // the handles came from this device and are destroyed once; freeing mapped
        // memory unmaps it. Null handles (a failed allocation) are ignored by Vulkan.
        unsafe {
            self.shared.device.destroy_buffer(self.buffer, None);
            self.shared.device.free_memory(self.memory, None);
        }
    }
}

/// Plain element types that may be copied to and from device memory as raw bytes.
///
/// Sealed: implemented for `f32`, `u32` and `i32` only (no padding, every bit pattern
/// valid).
pub trait Pod: Copy + sealed::Sealed + 'static {
    /// The zero value.
    const ZERO: Self;
}
impl Pod for f32 {
    const ZERO: Self = 0.0;
}
impl Pod for u32 {
    const ZERO: Self = 0;
}
impl Pod for i32 {
    const ZERO: Self = 0;
}
mod sealed {
    pub trait Sealed {}
    impl Sealed for f32 {}
    impl Sealed for u32 {}
    impl Sealed for i32 {}
}

/// The bytes of a slice of plain values.
fn as_bytes<T: Pod>(data: &[T]) -> &[u8] {
    // SAFETY: `T` is one of f32/u32/i32 (sealed `Pod`): no padding, so every byte of the
    // slice is initialised; u8 has alignment 1 and the length is the slice's byte size.
    unsafe { std::slice::from_raw_parts(data.as_ptr().cast::<u8>(), size_of_val(data)) }
}

impl GpuContext {
    /// Allocates a zero-initialised device buffer of `size` bytes (rounded up to 4).
    pub fn zeroed_buffer(&self, size: u64) -> Result<GpuBuffer, GpuError> {
        self.check_storage_size(size)?;
        let b = GpuBuffer::allocate(&self.shared, size, false)?;
        if let Some(p) = b.mapped {
            // SAFETY: the mapping covers `b.size` bytes; nothing else accesses the fresh
            // buffer.
            unsafe { std::ptr::write_bytes(p.as_ptr(), 0, b.size as usize) };
        } else {
            let (buf, sz) = (b.buffer, b.size);
            b.shared.submit_and_wait(|d, cmd| {
                // SAFETY: live buffer with TRANSFER_DST usage; whole-size fill of a size
                // that is a multiple of 4.
                unsafe { d.cmd_fill_buffer(cmd, buf, 0, sz, 0) };
            })?;
        }
        Ok(b)
    }

    /// Uploads `data` into a new device buffer.
    pub fn upload<T: Pod>(&self, data: &[T]) -> Result<GpuBuffer, GpuError> {
        let bytes = size_of_val(data) as u64;
        self.check_storage_size(bytes)?;
        let mut b = GpuBuffer::allocate(&self.shared, bytes, false)?;
        b.write(0, data)?;
        Ok(b)
    }

    /// Checks a storage-buffer size against the device's `maxStorageBufferRange`.
    pub(crate) fn check_storage_size(&self, bytes: u64) -> Result<(), GpuError> {
        let max = u64::from(self.shared.limits.max_storage_buffer_range);
        if bytes > max {
            return Err(GpuError::Limit(format!(
                "{bytes}-byte storage buffer exceeds maxStorageBufferRange ({max} bytes) of {}",
                self.shared.info.name
            )));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn memory_type_search_prefers_then_falls_back() {
        let mut props = vk::PhysicalDeviceMemoryProperties { memory_type_count: 3, ..Default::default() };
        props.memory_types[0].property_flags = vk::MemoryPropertyFlags::DEVICE_LOCAL;
        props.memory_types[1].property_flags = HOST;
        props.memory_types[2].property_flags = HOST | vk::MemoryPropertyFlags::DEVICE_LOCAL;
        let dl = vk::MemoryPropertyFlags::DEVICE_LOCAL;
        assert_eq!(find_memory_type(&props, 0b111, dl, HOST), Some(2));
        assert_eq!(find_memory_type(&props, 0b011, dl, HOST), Some(0));
        assert_eq!(find_memory_type(&props, 0b010, dl, HOST), None);
        assert_eq!(find_memory_type(&props, 0b111, HOST, vk::MemoryPropertyFlags::HOST_CACHED), Some(1));
    }

    #[test]
    fn bytes_view_is_native_endian() {
        let v = [1.0f32, -2.5];
        let b = as_bytes(&v);
        assert_eq!(b.len(), 8);
        assert_eq!(f32::from_ne_bytes(b[4..8].try_into().unwrap()), -2.5);
    }
}
