//! Storage buffers from gpu-allocator, with uploads and downloads that work whether or not the memory is mappable.
use super::Context;
use crate::error::Error;
use ash::vk;
use gpu_allocator::vulkan::{Allocation, AllocationCreateDesc, AllocationScheme, Allocator};
use gpu_allocator::MemoryLocation;
use std::sync::{Arc, Mutex};

pub struct Buffer {
    pub raw: vk::Buffer,
    pub size: u64,
    /// Also read through texel views (UNIFORM_TEXEL_BUFFER): only such a buffer may outgrow the storage range, and
    /// its storage binding is then clipped to it (`DescriptorSet::bind_buffers`).
    pub viewed: bool,
    allocation: Option<Allocation>,
    device: ash::Device,
    allocator: Arc<Mutex<Allocator>>,
}

fn alloc_err(e: impl std::fmt::Display) -> Error {
    Error::Vulkan(format!("memory allocation failed: {e}"))
}

impl Buffer {
    /// A buffer of at least `size` bytes (Vulkan forbids empty buffers, so 0 becomes 16).
    pub fn new(
        ctx: &Context,
        name: &str,
        size: u64,
        usage: vk::BufferUsageFlags,
        location: MemoryLocation,
    ) -> Result<Self, Error> {
        let size = size.max(16);
        let info = vk::BufferCreateInfo::default()
            .size(size)
            .usage(usage | vk::BufferUsageFlags::TRANSFER_DST | vk::BufferUsageFlags::TRANSFER_SRC)
            .sharing_mode(vk::SharingMode::EXCLUSIVE);
        let raw = unsafe { ctx.device.create_buffer(&info, None) }?;
        let requirements = unsafe { ctx.device.get_buffer_memory_requirements(raw) };
        let allocation = ctx
            .allocator
            .lock()
            .map_err(alloc_err)?
            .allocate(&AllocationCreateDesc {
                name,
                requirements,
                location,
                linear: true,
                allocation_scheme: AllocationScheme::GpuAllocatorManaged,
            })
            .map_err(|e| {
                unsafe { ctx.device.destroy_buffer(raw, None) };
                alloc_err(format!("{name} ({size} bytes): {e}"))
            })?;
        unsafe {
            ctx.device
                .bind_buffer_memory(raw, allocation.memory(), allocation.offset())
        }?;
        ctx.set_name(raw, name);
        Ok(Buffer {
            raw,
            size,
            viewed: usage.contains(vk::BufferUsageFlags::UNIFORM_TEXEL_BUFFER),
            allocation: Some(allocation),
            device: ctx.device.clone(),
            allocator: (*ctx.allocator).clone(),
        })
    }

    /// A device-local storage buffer holding `data`.
    pub fn with_data<T: bytemuck::Pod>(ctx: &Context, name: &str, data: &[T]) -> Result<Self, Error> {
        Self::with_data_usage(ctx, name, data, vk::BufferUsageFlags::STORAGE_BUFFER)
    }

    /// As `with_data`, with other usages (e.g. also a uniform texel buffer).
    pub fn with_data_usage<T: bytemuck::Pod>(
        ctx: &Context,
        name: &str,
        data: &[T],
        usage: vk::BufferUsageFlags,
    ) -> Result<Self, Error> {
        let bytes: &[u8] = bytemuck::cast_slice(data);
        let mut b = Buffer::new(ctx, name, bytes.len() as u64, usage, MemoryLocation::GpuOnly)?;
        b.upload(ctx, bytes)?;
        Ok(b)
    }

    /// Where the buffer starts in the device's address space (made with SHADER_DEVICE_ADDRESS usage, on a context
    /// with ray queries, which enables buffer device addresses).
    pub fn address(&self, ctx: &Context) -> u64 {
        unsafe {
            ctx.device
                .get_buffer_device_address(&vk::BufferDeviceAddressInfo::default().buffer(self.raw))
        }
    }

    /// Writes bytes at offset 0, through a staging buffer when this memory is not mappable.
    pub fn upload(&mut self, ctx: &Context, bytes: &[u8]) -> Result<(), Error> {
        if bytes.is_empty() {
            return Ok(());
        }
        assert!(bytes.len() as u64 <= self.size, "upload larger than buffer");
        if let Some(slice) = self.allocation.as_mut().and_then(|a| a.mapped_slice_mut()) {
            slice[..bytes.len()].copy_from_slice(bytes);
            return Ok(());
        }
        let mut staging = Buffer::new(
            ctx,
            "staging upload",
            bytes.len() as u64,
            vk::BufferUsageFlags::TRANSFER_SRC,
            MemoryLocation::CpuToGpu,
        )?;
        staging.upload(ctx, bytes)?;
        let region = [vk::BufferCopy::default().size(bytes.len() as u64)];
        ctx.submit_and_wait(|cmd| unsafe { ctx.device.cmd_copy_buffer(cmd, staging.raw, self.raw, &region) })
    }

    /// Reads the whole buffer back as `T`s (the device must be idle with respect to it).
    pub fn download<T: bytemuck::Pod>(&self, ctx: &Context) -> Result<Vec<T>, Error> {
        let n = self.size as usize / std::mem::size_of::<T>();
        let bytes_len = n * std::mem::size_of::<T>();
        let mut out = vec![T::zeroed(); n];
        if let Some(slice) = self.allocation.as_ref().and_then(|a| a.mapped_slice()) {
            bytemuck::cast_slice_mut::<T, u8>(&mut out).copy_from_slice(&slice[..bytes_len]);
            return Ok(out);
        }
        let staging = Buffer::new(
            ctx,
            "staging download",
            self.size,
            vk::BufferUsageFlags::TRANSFER_DST,
            MemoryLocation::GpuToCpu,
        )?;
        let region = [vk::BufferCopy::default().size(self.size)];
        ctx.submit_and_wait(|cmd| unsafe { ctx.device.cmd_copy_buffer(cmd, self.raw, staging.raw, &region) })?;
        staging.download(ctx)
    }
}

impl Drop for Buffer {
    fn drop(&mut self) {
        if super::device_lost() {
            return;
        }
        if let Some(a) = self.allocation.take() {
            if let Ok(mut alloc) = self.allocator.lock() {
                let _ = alloc.free(a);
            }
        }
        unsafe { self.device.destroy_buffer(self.raw, None) };
    }
}

/// Texel views of buffers, each for the binding it is bound at; destroyed on drop (before the buffers they view).
pub struct TexelViews {
    pub views: Vec<(u32, vk::BufferView)>,
    device: ash::Device,
}

impl TexelViews {
    /// One view of the whole of each buffer, in the format given with it.
    pub fn new(ctx: &Context, buffers: &[(u32, &Buffer, vk::Format)]) -> Result<Self, Error> {
        let mut v = TexelViews {
            views: Vec::new(),
            device: ctx.device.clone(),
        };
        for (binding, b, format) in buffers {
            let info = vk::BufferViewCreateInfo::default()
                .buffer(b.raw)
                .format(*format)
                .offset(0)
                .range(vk::WHOLE_SIZE);
            // On failure, Drop releases the views made so far.
            v.views
                .push((*binding, unsafe { ctx.device.create_buffer_view(&info, None) }?));
        }
        Ok(v)
    }
}

impl TexelViews {
    /// One view of `range` bytes of a buffer from `offset` (a multiple of the device's minTexelBufferOffsetAlignment).
    pub fn range(
        ctx: &Context,
        (binding, b, format): (u32, &Buffer, vk::Format),
        offset: u64,
        range: u64,
    ) -> Result<Self, Error> {
        let info = vk::BufferViewCreateInfo::default()
            .buffer(b.raw)
            .format(format)
            .offset(offset)
            .range(range);
        let view = unsafe { ctx.device.create_buffer_view(&info, None) }?;
        Ok(TexelViews {
            views: vec![(binding, view)],
            device: ctx.device.clone(),
        })
    }
}

impl Drop for TexelViews {
    fn drop(&mut self) {
        if super::device_lost() {
            return;
        }
        for (_, view) in &self.views {
            unsafe { self.device.destroy_buffer_view(*view, None) };
        }
    }
}
