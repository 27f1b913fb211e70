//! Reusable compute pipelines over storage buffers, and synchronous dispatch.
//!
//! A [`ComputePipeline`] is one SPIR-V entry point whose bindings are `bindings` storage
//! buffers at `@group(0) @binding(0..bindings)`. It owns one descriptor set; a dispatch
//! points the set at the given buffers, records the dispatch `repeats` times (with a
//! compute-to-compute barrier between repeats), submits, and waits. Dispatches are
//! serialised per device, so the single descriptor set is never updated while in use.

use std::sync::Arc;

use ash::vk;

use crate::buffer::GpuBuffer;
use crate::context::{DeviceShared, GpuContext};
use crate::error::{GpuError, VkContext};

/// Workgroup size (x) of every lightvol compute shader (`@workgroup_size(64)`).
pub const WORKGROUP_SIZE: u32 = 64;

/// What one synchronous dispatch measured.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DispatchStats {
    /// GPU time between timestamps written before the first and after the last repeat,
    /// seconds; `None` where the queue cannot write timestamps.
    pub gpu_seconds: Option<f64>,
    /// Host wall time of record + submit + wait, seconds.
    pub wall_seconds: f64,
    /// Number of times the dispatch was recorded.
    pub repeats: u32,
}

/// A compute pipeline whose bindings are storage buffers (see the module docs).
pub struct ComputePipeline {
    shared: Arc<DeviceShared>,
    name: &'static str,
    bindings: u32,
    set_layout: vk::DescriptorSetLayout,
    layout: vk::PipelineLayout,
    pipeline: vk::Pipeline,
    pool: vk::DescriptorPool,
    set: vk::DescriptorSet,
}

impl std::fmt::Debug for ComputePipeline {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ComputePipeline").field("name", &self.name).field("bindings", &self.bindings).finish()
    }
}

impl ComputePipeline {
    /// Builds the pipeline for entry point `main` of the SPIR-V module `spirv` with
    /// `bindings` storage buffers. `name` labels errors.
    pub fn new(ctx: &GpuContext, name: &'static str, spirv: &[u32], bindings: u32) -> Result<Self, GpuError> {
        if spirv.first() != Some(&0x0723_0203) {
            return Err(GpuError::Spirv(name));
        }
        let shared = ctx.shared.clone();
        let d = &shared.device;
        // Created objects are recorded in `this` as they appear so Drop cleans up after an
        // early error (destroying null handles is a no-op in Vulkan).
        let mut this = Self {
            shared: shared.clone(),
            name,
            bindings,
            set_layout: vk::DescriptorSetLayout::null(),
            layout: vk::PipelineLayout::null(),
            pipeline: vk::Pipeline::null(),
            pool: vk::DescriptorPool::null(),
            set: vk::DescriptorSet::null(),
        };
        let binding_info: Vec<_> = (0..bindings)
            .map(|b| {
                vk::DescriptorSetLayoutBinding::default()
                    .binding(b)
                    .descriptor_type(vk::DescriptorType::STORAGE_BUFFER)
                    .descriptor_count(1)
                    .stage_flags(vk::ShaderStageFlags::COMPUTE)
            })
            .collect();
        let dsl = vk::DescriptorSetLayoutCreateInfo::default().bindings(&binding_info);
        // SAFETY: valid create info (distinct binding numbers) for a live device.
        this.set_layout =
            unsafe { d.create_descriptor_set_layout(&dsl, None) }.vk("vkCreateDescriptorSetLayout")?;
        let set_layouts = [this.set_layout];
        let pl = vk::PipelineLayoutCreateInfo::default().set_layouts(&set_layouts);
        // SAFETY: the set layout is live.
        this.layout = unsafe { d.create_pipeline_layout(&pl, None) }.vk("vkCreatePipelineLayout")?;

        let module_info = vk::ShaderModuleCreateInfo::default().code(spirv);
        // SAFETY: `spirv` is a SPIR-V module produced and validated by naga at build time
        // (magic number checked above); the create info borrows it for the call only.
        let module = unsafe { d.create_shader_module(&module_info, None) }.vk("vkCreateShaderModule")?;
        let stage = vk::PipelineShaderStageCreateInfo::default()
            .stage(vk::ShaderStageFlags::COMPUTE)
            .module(module)
            .name(c"main");
        let info = [vk::ComputePipelineCreateInfo::default().stage(stage).layout(this.layout)];
        // SAFETY: the module has a compute entry point `main` whose bindings match the
        // layout (checked by the validation-layer test); all referenced objects are live.
        let created = unsafe { d.create_compute_pipelines(vk::PipelineCache::null(), &info, None) };
        // SAFETY: the module is no longer needed once the pipeline exists (or failed).
        unsafe { d.destroy_shader_module(module, None) };
        this.pipeline =
            created.map_err(|(_, result)| GpuError::Vk { call: "vkCreateComputePipelines", result })?[0];

        let sizes = [vk::DescriptorPoolSize {
            ty: vk::DescriptorType::STORAGE_BUFFER,
            descriptor_count: bindings.max(1),
        }];
        let pool_info = vk::DescriptorPoolCreateInfo::default().max_sets(1).pool_sizes(&sizes);
        // SAFETY: valid create info for a live device.
        this.pool = unsafe { d.create_descriptor_pool(&pool_info, None) }.vk("vkCreateDescriptorPool")?;
        let alloc =
            vk::DescriptorSetAllocateInfo::default().descriptor_pool(this.pool).set_layouts(&set_layouts);
        // SAFETY: the pool has room for exactly this one set.
        this.set = unsafe { d.allocate_descriptor_sets(&alloc) }.vk("vkAllocateDescriptorSets")?[0];
        Ok(this)
    }

    /// Number of storage-buffer bindings.
    #[must_use]
    pub fn bindings(&self) -> u32 {
        self.bindings
    }

    /// Binds `buffers` (binding `i` = `buffers[i]`), records the dispatch of `groups`
    /// workgroups `repeats` times (at least once) with compute barriers between, submits
    /// and waits.
    pub fn dispatch(
        &self,
        buffers: &[&GpuBuffer],
        groups: [u32; 3],
        repeats: u32,
    ) -> Result<DispatchStats, GpuError> {
        if buffers.len() != self.bindings as usize {
            return Err(GpuError::Invalid(format!(
                "{}: {} buffers for {} bindings",
                self.name,
                buffers.len(),
                self.bindings
            )));
        }
        if buffers.iter().any(|b| !Arc::ptr_eq(b.shared(), &self.shared)) {
            return Err(GpuError::Invalid(format!("{}: a buffer belongs to another device", self.name)));
        }
        let max = self.shared.limits.max_compute_work_group_count;
        if groups.iter().zip(max).any(|(&g, m)| g == 0 || g > m) {
            return Err(GpuError::Limit(format!(
                "{}: workgroup count {groups:?} outside 1..={max:?}",
                self.name
            )));
        }
        let repeats = repeats.max(1);
        let infos: Vec<[vk::DescriptorBufferInfo; 1]> = buffers
            .iter()
            .map(|b| [vk::DescriptorBufferInfo { buffer: b.buffer, offset: 0, range: vk::WHOLE_SIZE }])
            .collect();
        let writes: Vec<_> = infos
            .iter()
            .enumerate()
            .map(|(i, info)| {
                vk::WriteDescriptorSet::default()
                    .dst_set(self.set)
                    .dst_binding(i as u32)
                    .descriptor_type(vk::DescriptorType::STORAGE_BUFFER)
                    .buffer_info(info)
            })
            .collect();
        let start = std::time::Instant::now();
        let (pipeline, layout, set) = (self.pipeline, self.layout, self.set);
        // Take the submit lock for the descriptor update too, so no other dispatch of this
        // pipeline can update or use the set concurrently.
        let gpu = {
            let _serialise =
                self.shared.dispatch_lock.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
            // SAFETY: the set is not in use by any pending submission (dispatches wait for
            // completion and are serialised by the guard); the writes reference live
            // buffers with STORAGE_BUFFER usage.
            unsafe { self.shared.device.update_descriptor_sets(&writes, &[]) };
            self.shared.submit_and_wait(|d, cmd| {
                // SAFETY: `cmd` is recording; pipeline, layout and set are live and
                // compatible; the barrier orders each repeat's shader writes before the
                // next repeat's reads and writes.
                unsafe {
                    d.cmd_bind_pipeline(cmd, vk::PipelineBindPoint::COMPUTE, pipeline);
                    d.cmd_bind_descriptor_sets(cmd, vk::PipelineBindPoint::COMPUTE, layout, 0, &[set], &[]);
                    for r in 0..repeats {
                        if r > 0 {
                            let barrier = [vk::MemoryBarrier::default()
                                .src_access_mask(vk::AccessFlags::SHADER_WRITE)
                                .dst_access_mask(
                                    vk::AccessFlags::SHADER_READ | vk::AccessFlags::SHADER_WRITE,
                                )];
                            d.cmd_pipeline_barrier(
                                cmd,
                                vk::PipelineStageFlags::COMPUTE_SHADER,
                                vk::PipelineStageFlags::COMPUTE_SHADER,
                                vk::DependencyFlags::empty(),
                                &barrier,
                                &[],
                                &[],
                            );
                        }
                        d.cmd_dispatch(cmd, groups[0], groups[1], groups[2]);
                    }
                    // Make the shader writes visible to later transfers and host reads.
                    let barrier = [vk::MemoryBarrier::default()
                        .src_access_mask(vk::AccessFlags::SHADER_WRITE)
                        .dst_access_mask(vk::AccessFlags::TRANSFER_READ | vk::AccessFlags::HOST_READ)];
                    d.cmd_pipeline_barrier(
                        cmd,
                        vk::PipelineStageFlags::COMPUTE_SHADER,
                        vk::PipelineStageFlags::TRANSFER | vk::PipelineStageFlags::HOST,
                        vk::DependencyFlags::empty(),
                        &barrier,
                        &[],
                        &[],
                    );
                }
            })?
        };
        Ok(DispatchStats { gpu_seconds: gpu, wall_seconds: start.elapsed().as_secs_f64(), repeats })
    }
}

/// Workgroup counts covering `n` invocations of [`WORKGROUP_SIZE`], folded into a 2D grid
/// when `n` needs more than `max_x` groups along x; the shaders recover the linear index
/// as `gid.x + gid.y * groups.x * 64`.
#[must_use]
pub fn groups_for(n: u64, max_x: u32) -> [u32; 3] {
    let groups = n.div_ceil(u64::from(WORKGROUP_SIZE)).max(1);
    if groups <= u64::from(max_x) {
        [groups as u32, 1, 1]
    } else {
        let y = groups.div_ceil(u64::from(max_x));
        let x = groups.div_ceil(y);
        [x as u32, y.min(u64::from(u32::MAX)) as u32, 1]
    }
}

impl Drop for ComputePipeline {
    fn drop(&mut self) {
        // SAFETY: no submission using these objects is in flight (dispatches are
        // synchronous); each handle was created from this device and is destroyed once;
        // destroying the pool frees its set; null handles are ignored.
        unsafe {
            let d = &self.shared.device;
            d.destroy_descriptor_pool(self.pool, None);
            d.destroy_pipeline(self.pipeline, None);
            d.destroy_pipeline_layout(self.layout, None);
            d.destroy_descriptor_set_layout(self.set_layout, None);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn groups_cover_every_invocation() {
        assert_eq!(groups_for(0, 65535), [1, 1, 1]);
        assert_eq!(groups_for(64, 65535), [1, 1, 1]);
        assert_eq!(groups_for(65, 65535), [2, 1, 1]);
        for (n, max) in [(10_000_000u64, 65535u32), (1_000_000, 100), (12_345, 7)] {
            let [x, y, z] = groups_for(n, max);
            assert!(x <= max && z == 1);
            let cover = u64::from(x) * u64::from(y) * u64::from(WORKGROUP_SIZE);
            assert!(cover >= n && cover - n < u64::from(x) * u64::from(WORKGROUP_SIZE), "{n} {max}: {x}x{y}");
        }
    }
}
