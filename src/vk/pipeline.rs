//! Compute pipelines that share one descriptor set layout and one push-constant range, and per-stage GPU timers.
use super::{Buffer, Context};
use crate::constants::{BINDING_COUNT, BINDING_FIRST_TEXEL, BINDING_TLAS, SPEC_SCENE_FEATURES};
use crate::error::Error;
use ash::vk;

/// Storage buffers, then the texel-buffer bindings (see BINDING_FIRST_TEXEL).
fn descriptor_type(binding: u32) -> vk::DescriptorType {
    if binding >= BINDING_FIRST_TEXEL {
        vk::DescriptorType::UNIFORM_TEXEL_BUFFER
    } else {
        vk::DescriptorType::STORAGE_BUFFER
    }
}

/// The one descriptor set and push-constant range every compute pipeline shares, and the creation and dispatch of
/// pipelines. Which pipelines exist, and what for, is render::kernels' business.
pub struct Pipelines {
    pub set_layout: vk::DescriptorSetLayout,
    pub layout: vk::PipelineLayout,
    pool: vk::DescriptorPool,
    pub set: vk::DescriptorSet,
    push_bytes: u32,
    device: ash::Device,
}

impl Pipelines {
    /// `push_bytes`: the shared push-constant range every stage's block must fit in.
    pub fn new(ctx: &Context, push_bytes: u32) -> Result<Self, Error> {
        let d = &ctx.device;
        let binding = |b: u32, ty: vk::DescriptorType| {
            vk::DescriptorSetLayoutBinding::default()
                .binding(b)
                .descriptor_type(ty)
                .descriptor_count(1)
                .stage_flags(vk::ShaderStageFlags::COMPUTE)
        };
        let mut bindings: Vec<_> = (0..BINDING_COUNT).map(|b| binding(b, descriptor_type(b))).collect();
        // The top-level structure ray queries walk, on devices that have them (the descriptor type needs the
        // extension).
        if ctx.accel.is_some() {
            bindings.push(binding(BINDING_TLAS, vk::DescriptorType::ACCELERATION_STRUCTURE_KHR));
        }
        let set_layout = unsafe {
            d.create_descriptor_set_layout(&vk::DescriptorSetLayoutCreateInfo::default().bindings(&bindings), None)
        }?;
        let ranges = [vk::PushConstantRange::default()
            .stage_flags(vk::ShaderStageFlags::COMPUTE)
            .offset(0)
            .size(push_bytes)];
        let set_layouts = [set_layout];
        let layout = unsafe {
            d.create_pipeline_layout(
                &vk::PipelineLayoutCreateInfo::default()
                    .set_layouts(&set_layouts)
                    .push_constant_ranges(&ranges),
                None,
            )
        }?;
        let mut sizes = vec![
            vk::DescriptorPoolSize::default()
                .ty(vk::DescriptorType::STORAGE_BUFFER)
                .descriptor_count(BINDING_FIRST_TEXEL),
            vk::DescriptorPoolSize::default()
                .ty(vk::DescriptorType::UNIFORM_TEXEL_BUFFER)
                .descriptor_count(BINDING_COUNT - BINDING_FIRST_TEXEL),
        ];
        if ctx.accel.is_some() {
            sizes.push(
                vk::DescriptorPoolSize::default()
                    .ty(vk::DescriptorType::ACCELERATION_STRUCTURE_KHR)
                    .descriptor_count(1),
            );
        }
        let pool = unsafe {
            d.create_descriptor_pool(
                &vk::DescriptorPoolCreateInfo::default().max_sets(1).pool_sizes(&sizes),
                None,
            )
        }?;
        let set = unsafe {
            d.allocate_descriptor_sets(
                &vk::DescriptorSetAllocateInfo::default()
                    .descriptor_pool(pool)
                    .set_layouts(&set_layouts),
            )
        }?[0];
        Ok(Pipelines {
            set_layout,
            layout,
            pool,
            set,
            push_bytes,
            device: d.clone(),
        })
    }

    /// A compute pipeline from SPIR-V with SCENE_FEATURES specialised to `features`; `label` names it for debuggers
    /// and in errors.
    pub fn create(&self, ctx: &Context, label: &str, spv: &[u8], features: u32) -> Result<vk::Pipeline, Error> {
        let d = &ctx.device;
        let words = ash::util::read_spv(&mut std::io::Cursor::new(spv))
            .map_err(|e| Error::Vulkan(format!("shader {label}: not SPIR-V: {e}")))?;
        let module = unsafe { d.create_shader_module(&vk::ShaderModuleCreateInfo::default().code(&words), None) }?;
        let entries = [vk::SpecializationMapEntry::default()
            .constant_id(SPEC_SCENE_FEATURES)
            .offset(0)
            .size(4)];
        let data = features.to_ne_bytes();
        let specialization = vk::SpecializationInfo::default().map_entries(&entries).data(&data);
        let stage = vk::PipelineShaderStageCreateInfo::default()
            .stage(vk::ShaderStageFlags::COMPUTE)
            .module(module)
            .name(c"main")
            .specialization_info(&specialization);
        let info = [vk::ComputePipelineCreateInfo::default()
            .stage(stage)
            .layout(self.layout)];
        let result = unsafe { d.create_compute_pipelines(vk::PipelineCache::null(), &info, None) };
        unsafe { d.destroy_shader_module(module, None) };
        let pipeline = result.map_err(|(_, e)| Error::Vulkan(format!("pipeline {label}: {e:?}")))?[0];
        ctx.set_name(pipeline, label);
        Ok(pipeline)
    }

    /// Destroys a pipeline no command buffer still uses (callers wait for the device between passes).
    pub fn destroy(&self, pipeline: vk::Pipeline) {
        unsafe { self.device.destroy_pipeline(pipeline, None) };
    }

    /// Points storage bindings at buffers. A buffer larger than the device's storage range that is also read through
    /// texel views (the BVH, per-triangle and texel ones the TEXEL_READS stages read so) is bound up to that range.
    /// Every other buffer is bound whole: its size was checked against the range where it was made, or, for the
    /// fixed energy tables, fits the 2^27 bytes every Vulkan device's range holds (constants::ENERGY_BUFFER_FLOATS).
    pub fn bind_buffers(&self, ctx: &Context, buffers: &[(u32, &Buffer)]) {
        let range = ctx.properties.limits.max_storage_buffer_range as u64;
        let infos: Vec<[vk::DescriptorBufferInfo; 1]> = buffers
            .iter()
            .map(|(_, b)| {
                [vk::DescriptorBufferInfo::default()
                    .buffer(b.raw)
                    .offset(0)
                    .range(if b.viewed && b.size > range {
                        range
                    } else {
                        vk::WHOLE_SIZE
                    })]
            })
            .collect();
        let writes: Vec<_> = buffers
            .iter()
            .zip(&infos)
            .map(|((binding, _), info)| {
                vk::WriteDescriptorSet::default()
                    .dst_set(self.set)
                    .dst_binding(*binding)
                    .descriptor_type(vk::DescriptorType::STORAGE_BUFFER)
                    .buffer_info(info)
            })
            .collect();
        unsafe { ctx.device.update_descriptor_sets(&writes, &[]) };
    }

    /// Points BINDING_TLAS at a top-level acceleration structure.
    pub fn bind_tlas(&self, ctx: &Context, tlas: vk::AccelerationStructureKHR) {
        let structures = [tlas];
        let mut info = vk::WriteDescriptorSetAccelerationStructureKHR::default().acceleration_structures(&structures);
        let write = vk::WriteDescriptorSet::default()
            .dst_set(self.set)
            .dst_binding(BINDING_TLAS)
            .descriptor_type(vk::DescriptorType::ACCELERATION_STRUCTURE_KHR)
            .descriptor_count(1)
            .push_next(&mut info);
        unsafe { ctx.device.update_descriptor_sets(&[write], &[]) };
    }

    /// Points texel-buffer bindings at buffer views.
    pub fn bind_texel_views(&self, ctx: &Context, views: &[(u32, vk::BufferView)]) {
        let raw: Vec<[vk::BufferView; 1]> = views.iter().map(|(_, v)| [*v]).collect();
        let writes: Vec<_> = views
            .iter()
            .zip(&raw)
            .map(|((binding, _), view)| {
                vk::WriteDescriptorSet::default()
                    .dst_set(self.set)
                    .dst_binding(*binding)
                    .descriptor_type(vk::DescriptorType::UNIFORM_TEXEL_BUFFER)
                    .texel_buffer_view(view)
            })
            .collect();
        unsafe { ctx.device.update_descriptor_sets(&writes, &[]) };
    }

    /// `groups` workgroups of `pipeline` with `push` as its push constants (within the shared range).
    pub fn dispatch(&self, cmd: vk::CommandBuffer, pipeline: vk::Pipeline, push: &[u8], groups: [u32; 3]) {
        self.bind(cmd, pipeline, push);
        unsafe { self.device.cmd_dispatch(cmd, groups[0], groups[1], groups[2]) };
    }

    /// A dispatch sized by the VkDispatchIndirectCommand at `offset` in `args`.
    pub fn dispatch_indirect(
        &self,
        cmd: vk::CommandBuffer,
        pipeline: vk::Pipeline,
        push: &[u8],
        args: &Buffer,
        offset: u64,
    ) {
        self.bind(cmd, pipeline, push);
        unsafe { self.device.cmd_dispatch_indirect(cmd, args.raw, offset) };
    }

    fn bind(&self, cmd: vk::CommandBuffer, pipeline: vk::Pipeline, push: &[u8]) {
        assert!(
            push.len() <= self.push_bytes as usize,
            "push constants past the shared range"
        );
        unsafe {
            self.device
                .cmd_bind_pipeline(cmd, vk::PipelineBindPoint::COMPUTE, pipeline);
            self.device
                .cmd_bind_descriptor_sets(cmd, vk::PipelineBindPoint::COMPUTE, self.layout, 0, &[self.set], &[]);
            self.device
                .cmd_push_constants(cmd, self.layout, vk::ShaderStageFlags::COMPUTE, 0, push);
        }
    }
}

impl Drop for Pipelines {
    fn drop(&mut self) {
        if super::device_lost() {
            return;
        }
        unsafe {
            self.device.destroy_descriptor_pool(self.pool, None);
            self.device.destroy_pipeline_layout(self.layout, None);
            self.device.destroy_descriptor_set_layout(self.set_layout, None);
        }
    }
}

/// Timestamp pairs around dispatches, summed per stage name after the command buffer completes.
pub struct Timestamps {
    pool: vk::QueryPool,
    capacity: u32,
    labels: Vec<&'static str>,
    period_ns: f64,
    enabled: bool,
    device: ash::Device,
}

impl Timestamps {
    pub fn new(ctx: &Context, capacity: u32) -> Result<Self, Error> {
        let pool = unsafe {
            ctx.device.create_query_pool(
                &vk::QueryPoolCreateInfo::default()
                    .query_type(vk::QueryType::TIMESTAMP)
                    .query_count(capacity),
                None,
            )
        }?;
        Ok(Timestamps {
            pool,
            capacity,
            labels: Vec::new(),
            period_ns: ctx.properties.limits.timestamp_period as f64,
            enabled: ctx.timestamps_valid,
            device: ctx.device.clone(),
        })
    }

    pub fn reset(&mut self, cmd: vk::CommandBuffer) {
        self.labels.clear();
        if self.enabled {
            unsafe { self.device.cmd_reset_query_pool(cmd, self.pool, 0, self.capacity) };
        }
    }

    /// Records `f` between two timestamps labelled `label`; beyond capacity it records untimed.
    pub fn time(&mut self, cmd: vk::CommandBuffer, label: &'static str, f: impl FnOnce()) {
        let q = 2 * self.labels.len() as u32;
        if !self.enabled || q + 2 > self.capacity {
            f();
            return;
        }
        unsafe {
            self.device
                .cmd_write_timestamp(cmd, vk::PipelineStageFlags::TOP_OF_PIPE, self.pool, q)
        };
        f();
        unsafe {
            self.device
                .cmd_write_timestamp(cmd, vk::PipelineStageFlags::BOTTOM_OF_PIPE, self.pool, q + 1)
        };
        self.labels.push(label);
    }

    /// Nanoseconds per label for the last completed command buffer.
    pub fn read(&self) -> Result<Vec<(&'static str, f64)>, Error> {
        if self.labels.is_empty() {
            return Ok(Vec::new());
        }
        let mut raw = vec![0u64; 2 * self.labels.len()];
        unsafe {
            self.device.get_query_pool_results(
                self.pool,
                0,
                &mut raw,
                vk::QueryResultFlags::TYPE_64 | vk::QueryResultFlags::WAIT,
            )
        }?;
        let mut sums: Vec<(&'static str, f64)> = Vec::new();
        for (i, label) in self.labels.iter().enumerate() {
            let ns = raw[2 * i + 1].saturating_sub(raw[2 * i]) as f64 * self.period_ns;
            add_labelled(&mut sums, label, ns);
        }
        Ok(sums)
    }
}

/// Adds `value` to `label`'s entry of per-stage sums, appending the label the first time it is seen.
pub fn add_labelled(sums: &mut Vec<(&'static str, f64)>, label: &'static str, value: f64) {
    match sums.iter_mut().find(|(l, _)| *l == label) {
        Some(e) => e.1 += value,
        None => sums.push((label, value)),
    }
}

impl Drop for Timestamps {
    fn drop(&mut self) {
        if super::device_lost() {
            return;
        }
        unsafe { self.device.destroy_query_pool(self.pool, None) };
    }
}
