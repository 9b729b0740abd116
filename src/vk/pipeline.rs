//! Compute pipelines that share one descriptor set layout and one push-constant block, and per-stage GPU timers.
use super::{Buffer, Context};
use crate::constants::{BINDING_COUNT, BINDING_FIRST_TEXEL, FEATURES_ALL, FEATURE_DEEP_STACK, SPEC_SCENE_FEATURES};
use crate::layout::Frame;
use crate::Error;
use ash::vk;
use std::collections::HashMap;

/// Storage buffers, then the texel-buffer bindings (see BINDING_FIRST_TEXEL).
fn descriptor_type(binding: u32) -> vk::DescriptorType {
    if binding >= BINDING_FIRST_TEXEL {
        vk::DescriptorType::UNIFORM_TEXEL_BUFFER
    } else {
        vk::DescriptorType::STORAGE_BUFFER
    }
}

pub struct Pipelines {
    pub set_layout: vk::DescriptorSetLayout,
    pub layout: vk::PipelineLayout,
    pool: vk::DescriptorPool,
    pub set: vk::DescriptorSet,
    pipelines: HashMap<String, vk::Pipeline>,
    /// Every render stage's SPIR-V: `ensure` builds the ones a pass needs that are not in `pipelines` yet (building
    /// all eighteen render variants up front cost start-up about a second on lavapipe), `set_features` drops them.
    render_spirv: HashMap<String, Vec<u8>>,
    /// FEATURE_* bits the render stages are specialised for (SCENE_FEATURES in layout.glsl).
    features: u32,
    device: ash::Device,
}

/// Stages that must keep every feature whatever the scene (but the BVH's FEATURE_DEEP_STACK, see `replace`): the
/// probes test device functions with parameters of their own, and the energy tables integrate the full BSDF.
fn scene_independent(stage: &str) -> bool {
    stage.starts_with("probe_") || stage == "energy_tables"
}

/// The stages a pass dispatches: specialised for the scene's features, built when a pass first needs them.
fn render_stage(stage: &str) -> bool {
    !scene_independent(stage) && stage != "tonemap"
}

impl Pipelines {
    /// `features`: the scene's FEATURE_* bits; the render stages are built with code for the others folded away.
    pub fn new(ctx: &Context, stages: &[(&str, &[u8])], features: u32) -> Result<Self, Error> {
        let d = &ctx.device;
        let bindings: Vec<_> = (0..BINDING_COUNT)
            .map(|b| {
                vk::DescriptorSetLayoutBinding::default()
                    .binding(b)
                    .descriptor_type(descriptor_type(b))
                    .descriptor_count(1)
                    .stage_flags(vk::ShaderStageFlags::COMPUTE)
            })
            .collect();
        let set_layout = unsafe {
            d.create_descriptor_set_layout(&vk::DescriptorSetLayoutCreateInfo::default().bindings(&bindings), None)
        }?;
        let ranges = [vk::PushConstantRange::default()
            .stage_flags(vk::ShaderStageFlags::COMPUTE)
            .offset(0)
            .size(std::mem::size_of::<Frame>() as u32)];
        let set_layouts = [set_layout];
        let layout = unsafe {
            d.create_pipeline_layout(
                &vk::PipelineLayoutCreateInfo::default()
                    .set_layouts(&set_layouts)
                    .push_constant_ranges(&ranges),
                None,
            )
        }?;
        let sizes = [
            vk::DescriptorPoolSize::default()
                .ty(vk::DescriptorType::STORAGE_BUFFER)
                .descriptor_count(BINDING_FIRST_TEXEL),
            vk::DescriptorPoolSize::default()
                .ty(vk::DescriptorType::UNIFORM_TEXEL_BUFFER)
                .descriptor_count(BINDING_COUNT - BINDING_FIRST_TEXEL),
        ];
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
        let mut me = Pipelines {
            set_layout,
            layout,
            pool,
            set,
            pipelines: HashMap::new(),
            render_spirv: HashMap::new(),
            features,
            device: d.clone(),
        };
        for (name, spv) in stages {
            if render_stage(name) {
                me.render_spirv.insert(name.to_string(), spv.to_vec());
            } else {
                me.replace(ctx, name, spv)?;
            }
        }
        Ok(me)
    }

    /// Specialises the render stages for `features` from now on: built ones are dropped and built again by `ensure`.
    pub fn set_features(&mut self, features: u32) {
        if features == self.features {
            return;
        }
        self.features = features;
        for name in self.render_spirv.keys() {
            if let Some(old) = self.pipelines.remove(name) {
                // The caller waits for the device before a pass, so no command buffer still uses it.
                unsafe { self.device.destroy_pipeline(old, None) };
            }
        }
    }

    /// Builds the render stages among `names` that are not built yet.
    pub fn ensure(&mut self, ctx: &Context, names: &[&str]) -> Result<(), Error> {
        for name in names {
            if !self.pipelines.contains_key(*name) {
                if let Some(spv) = self.render_spirv.get(*name).cloned() {
                    self.replace(ctx, name, &spv)?;
                }
            }
        }
        Ok(())
    }

    /// Builds (or rebuilds) one stage's pipeline from SPIR-V.
    pub fn replace(&mut self, ctx: &Context, name: &str, spv: &[u8]) -> Result<(), Error> {
        if render_stage(name) {
            self.render_spirv.insert(name.to_string(), spv.to_vec());
        }
        let d = &ctx.device;
        let words = ash::util::read_spv(&mut std::io::Cursor::new(spv))
            .map_err(|e| Error::Vulkan(format!("shader {name}: not SPIR-V: {e}")))?;
        let module = unsafe { d.create_shader_module(&vk::ShaderModuleCreateInfo::default().code(&words), None) }?;
        let features = if scene_independent(name) {
            // Probes keep every bit but the BVH's own (FEATURE_DEEP_STACK), so probe_trace traverses as render stages do.
            (FEATURES_ALL & !FEATURE_DEEP_STACK) | (self.features & FEATURE_DEEP_STACK)
        } else {
            self.features
        };
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
        let pipeline = result.map_err(|(_, e)| Error::Vulkan(format!("pipeline {name}: {e:?}")))?[0];
        ctx.set_name(pipeline, name);
        if let Some(old) = self.pipelines.insert(name.to_string(), pipeline) {
            unsafe { d.destroy_pipeline(old, None) };
        }
        Ok(())
    }

    /// Points storage bindings at buffers. A buffer larger than the device's storage range (only the BVH and
    /// per-triangle ones, which the TEXEL_READS stages read through views) is bound up to that range.
    pub fn bind_buffers(&self, ctx: &Context, buffers: &[(u32, &Buffer)]) {
        let range = ctx.properties.limits.max_storage_buffer_range as u64;
        let infos: Vec<[vk::DescriptorBufferInfo; 1]> = buffers
            .iter()
            .map(|(_, b)| {
                [vk::DescriptorBufferInfo::default()
                    .buffer(b.raw)
                    .offset(0)
                    .range(if b.size > range { range } else { vk::WHOLE_SIZE })]
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

    /// A 2D dispatch with a stage's own push constants (within the shared range), e.g. the tone map.
    pub fn dispatch_2d(&self, cmd: vk::CommandBuffer, name: &str, push: &[u8], groups: [u32; 2]) {
        self.bind(cmd, name, push);
        unsafe { self.device.cmd_dispatch(cmd, groups[0], groups[1], 1) };
    }

    fn bind(&self, cmd: vk::CommandBuffer, name: &str, push: &[u8]) {
        assert!(
            push.len() <= std::mem::size_of::<Frame>(),
            "push constants past the shared range"
        );
        let pipeline = *self
            .pipelines
            .get(name)
            .unwrap_or_else(|| panic!("no pipeline named {name}"));
        unsafe {
            self.device
                .cmd_bind_pipeline(cmd, vk::PipelineBindPoint::COMPUTE, pipeline);
            self.device
                .cmd_bind_descriptor_sets(cmd, vk::PipelineBindPoint::COMPUTE, self.layout, 0, &[self.set], &[]);
            self.device
                .cmd_push_constants(cmd, self.layout, vk::ShaderStageFlags::COMPUTE, 0, push);
        }
    }

    pub fn dispatch(&self, cmd: vk::CommandBuffer, name: &str, frame: &Frame, groups: u32) {
        self.bind(cmd, name, bytemuck::bytes_of(frame));
        unsafe { self.device.cmd_dispatch(cmd, groups, 1, 1) };
    }

    pub fn dispatch_indirect(&self, cmd: vk::CommandBuffer, name: &str, frame: &Frame, args: &Buffer, offset: u64) {
        self.bind(cmd, name, bytemuck::bytes_of(frame));
        unsafe { self.device.cmd_dispatch_indirect(cmd, args.raw, offset) };
    }
}

impl Drop for Pipelines {
    fn drop(&mut self) {
        unsafe {
            for (_, p) in self.pipelines.drain() {
                self.device.destroy_pipeline(p, None);
            }
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
        unsafe { self.device.destroy_query_pool(self.pool, None) };
    }
}
