//! The window's swapchain: tone-mapped pixels are copied into its images and presented, one frame at a time.
use crate::error::Error;
use crate::vk::{Buffer, Context};
use ash::vk;

pub struct Swapchain {
    loader: ash::khr::swapchain::Device,
    raw: vk::SwapchainKHR,
    images: Vec<vk::Image>,
    pub extent: [u32; 2],
    /// The images store blue first (B8G8R8A8), so the tone map packs BGRA.
    pub bgra: bool,
    acquired: vk::Semaphore,
    /// One per image: a present waits on the semaphore of the image it shows, which no later submit reuses early.
    rendered: Vec<vk::Semaphore>,
    fence: vk::Fence,
    cmd: vk::CommandBuffer,
    pool: vk::CommandPool,
    device: ash::Device,
}

impl Swapchain {
    pub fn new(ctx: &Context, size: [u32; 2]) -> Result<Self, Error> {
        let d = &ctx.device;
        let cmd = unsafe {
            d.allocate_command_buffers(
                &vk::CommandBufferAllocateInfo::default()
                    .command_pool(ctx.pool)
                    .level(vk::CommandBufferLevel::PRIMARY)
                    .command_buffer_count(1),
            )
        }?[0];
        let mut me = Swapchain {
            loader: ash::khr::swapchain::Device::new(&ctx.instance, d),
            raw: vk::SwapchainKHR::null(),
            images: Vec::new(),
            extent: size,
            bgra: true,
            acquired: unsafe { d.create_semaphore(&vk::SemaphoreCreateInfo::default(), None) }?,
            rendered: Vec::new(),
            fence: unsafe { d.create_fence(&vk::FenceCreateInfo::default(), None) }?,
            cmd,
            pool: ctx.pool,
            device: d.clone(),
        };
        me.recreate(ctx, size)?;
        Ok(me)
    }

    /// (Re)builds the swapchain for a window of `size`, replacing the old one.
    pub fn recreate(&mut self, ctx: &Context, size: [u32; 2]) -> Result<(), Error> {
        let surface = ctx
            .surface
            .as_ref()
            .ok_or_else(|| Error::Vulkan("the device was not made for a window".into()))?;
        unsafe { ctx.device.device_wait_idle() }?;
        let (pd, sl) = (ctx.physical, &surface.loader);
        let caps = unsafe { sl.get_physical_device_surface_capabilities(pd, surface.raw) }?;
        let formats = unsafe { sl.get_physical_device_surface_formats(pd, surface.raw) }?;
        let modes = unsafe { sl.get_physical_device_surface_present_modes(pd, surface.raw) }?;
        let (format, bgra) = pick_format(&formats)?;
        if !caps.supported_usage_flags.contains(vk::ImageUsageFlags::TRANSFER_DST) {
            return Err(Error::Vulkan("the window's images cannot be copied into".into()));
        }
        let mode = pick_mode(&modes);
        let extent = pick_extent(&caps, size);
        let mut count = caps.min_image_count + 1;
        if caps.max_image_count > 0 {
            count = count.min(caps.max_image_count);
        }
        let alpha = pick_alpha(&caps);
        let info = vk::SwapchainCreateInfoKHR::default()
            .surface(surface.raw)
            .min_image_count(count)
            .image_format(format.format)
            .image_color_space(format.color_space)
            .image_extent(extent)
            .image_array_layers(1)
            .image_usage(vk::ImageUsageFlags::TRANSFER_DST)
            .image_sharing_mode(vk::SharingMode::EXCLUSIVE)
            .pre_transform(caps.current_transform)
            .composite_alpha(alpha)
            .present_mode(mode)
            .clipped(true)
            .old_swapchain(self.raw);
        let raw = unsafe { self.loader.create_swapchain(&info, None) }?;
        unsafe {
            if self.raw != vk::SwapchainKHR::null() {
                self.loader.destroy_swapchain(self.raw, None);
            }
            for s in self.rendered.drain(..) {
                self.device.destroy_semaphore(s, None);
            }
        }
        self.raw = raw;
        self.images = unsafe { self.loader.get_swapchain_images(raw) }?;
        for _ in &self.images {
            self.rendered
                .push(unsafe { self.device.create_semaphore(&vk::SemaphoreCreateInfo::default(), None) }?);
        }
        self.extent = [extent.width, extent.height];
        self.bgra = bgra;
        Ok(())
    }

    /// Records `fill` (which writes `pixels`, one packed word per pixel of `extent`), copies them into the next image
    /// and presents it. False when the swapchain no longer matches the window and must be recreated.
    pub fn present(
        &mut self,
        ctx: &Context,
        pixels: &Buffer,
        fill: impl FnOnce(vk::CommandBuffer, [u32; 2]),
    ) -> Result<bool, Error> {
        let index = match unsafe {
            self.loader
                .acquire_next_image(self.raw, 1_000_000_000, self.acquired, vk::Fence::null())
        } {
            Ok((i, _)) => i,
            Err(vk::Result::ERROR_OUT_OF_DATE_KHR) => return Ok(false),
            Err(e) => return Err(e.into()),
        };
        let image = self.images[index as usize];
        self.record(image, pixels, fill)?;
        let signals = [self.rendered[index as usize]];
        self.submit(ctx, &signals)?;
        let swapchains = [self.raw];
        let indices = [index];
        let present = vk::PresentInfoKHR::default()
            .wait_semaphores(&signals)
            .swapchains(&swapchains)
            .image_indices(&indices);
        match unsafe { self.loader.queue_present(ctx.queue, &present) } {
            Ok(false) => Ok(true),
            Ok(true) | Err(vk::Result::ERROR_OUT_OF_DATE_KHR) => Ok(false),
            Err(e) => Err(e.into()),
        }
    }

    /// Records `fill`, then the copy of `pixels` into `image` between the layouts the copy and the present need.
    fn record(
        &self,
        image: vk::Image,
        pixels: &Buffer,
        fill: impl FnOnce(vk::CommandBuffer, [u32; 2]),
    ) -> Result<(), Error> {
        let d = &self.device;
        unsafe {
            d.reset_command_buffer(self.cmd, vk::CommandBufferResetFlags::empty())?;
            d.begin_command_buffer(
                self.cmd,
                &vk::CommandBufferBeginInfo::default().flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT),
            )?;
            fill(self.cmd, self.extent);
            transition(
                d,
                self.cmd,
                image,
                (vk::ImageLayout::UNDEFINED, vk::AccessFlags::empty()),
                (vk::ImageLayout::TRANSFER_DST_OPTIMAL, vk::AccessFlags::TRANSFER_WRITE),
                vk::PipelineStageFlags::TRANSFER,
            );
            let region = vk::BufferImageCopy::default()
                .image_subresource(
                    vk::ImageSubresourceLayers::default()
                        .aspect_mask(vk::ImageAspectFlags::COLOR)
                        .layer_count(1),
                )
                .image_extent(vk::Extent3D {
                    width: self.extent[0],
                    height: self.extent[1],
                    depth: 1,
                });
            d.cmd_copy_buffer_to_image(
                self.cmd,
                pixels.raw,
                image,
                vk::ImageLayout::TRANSFER_DST_OPTIMAL,
                &[region],
            );
            transition(
                d,
                self.cmd,
                image,
                (vk::ImageLayout::TRANSFER_DST_OPTIMAL, vk::AccessFlags::TRANSFER_WRITE),
                (vk::ImageLayout::PRESENT_SRC_KHR, vk::AccessFlags::empty()),
                vk::PipelineStageFlags::BOTTOM_OF_PIPE,
            );
            d.end_command_buffer(self.cmd)?;
        }
        Ok(())
    }

    /// Runs the recorded commands once `acquired` is signalled, signals `signals` for the present, and waits for them.
    fn submit(&self, ctx: &Context, signals: &[vk::Semaphore]) -> Result<(), Error> {
        let d = &self.device;
        unsafe {
            let waits = [self.acquired];
            let stages = [vk::PipelineStageFlags::TRANSFER];
            let cmds = [self.cmd];
            let submit = vk::SubmitInfo::default()
                .wait_semaphores(&waits)
                .wait_dst_stage_mask(&stages)
                .command_buffers(&cmds)
                .signal_semaphores(signals);
            d.reset_fences(&[self.fence])?;
            d.queue_submit(ctx.queue, &[submit], self.fence)?;
            d.wait_for_fences(&[self.fence], true, ctx.fence_timeout.as_nanos() as u64)?;
        }
        Ok(())
    }
}

/// The first of the 8-bit formats the tone map can fill that the window offers, and whether it stores blue first.
fn pick_format(formats: &[vk::SurfaceFormatKHR]) -> Result<(vk::SurfaceFormatKHR, bool), Error> {
    // The tone map writes sRGB-encoded bytes and a copy does not convert, so UNORM and SRGB images both work.
    let wanted = [
        (vk::Format::B8G8R8A8_UNORM, true),
        (vk::Format::B8G8R8A8_SRGB, true),
        (vk::Format::R8G8B8A8_UNORM, false),
        (vk::Format::R8G8B8A8_SRGB, false),
    ];
    wanted
        .iter()
        .find_map(|&(f, bgra)| formats.iter().find(|s| s.format == f).map(|s| (*s, bgra)))
        .ok_or_else(|| Error::Vulkan(format!("the window offers no 8-bit RGBA format: {formats:?}")))
}

fn pick_mode(modes: &[vk::PresentModeKHR]) -> vk::PresentModeKHR {
    // Never wait for a vertical blank when one exists: the frame budget, not the display, paces the viewer.
    [vk::PresentModeKHR::MAILBOX, vk::PresentModeKHR::IMMEDIATE]
        .into_iter()
        .find(|m| modes.contains(m))
        .unwrap_or(vk::PresentModeKHR::FIFO)
}

/// The window's size, or `size` within the surface's limits when the surface leaves its size to the swapchain.
fn pick_extent(caps: &vk::SurfaceCapabilitiesKHR, size: [u32; 2]) -> vk::Extent2D {
    if caps.current_extent.width != u32::MAX {
        caps.current_extent
    } else {
        vk::Extent2D {
            width: size[0].clamp(caps.min_image_extent.width, caps.max_image_extent.width),
            height: size[1].clamp(caps.min_image_extent.height, caps.max_image_extent.height),
        }
    }
}

fn pick_alpha(caps: &vk::SurfaceCapabilitiesKHR) -> vk::CompositeAlphaFlagsKHR {
    [
        vk::CompositeAlphaFlagsKHR::OPAQUE,
        vk::CompositeAlphaFlagsKHR::INHERIT,
        vk::CompositeAlphaFlagsKHR::PRE_MULTIPLIED,
        vk::CompositeAlphaFlagsKHR::POST_MULTIPLIED,
    ]
    .into_iter()
    .find(|a| caps.supported_composite_alpha.contains(*a))
    .unwrap_or(vk::CompositeAlphaFlagsKHR::OPAQUE)
}

/// Moves a swapchain image from one (layout, access) to another, after the transfer stage and before `dst_stage`.
unsafe fn transition(
    d: &ash::Device,
    cmd: vk::CommandBuffer,
    image: vk::Image,
    from: (vk::ImageLayout, vk::AccessFlags),
    to: (vk::ImageLayout, vk::AccessFlags),
    dst_stage: vk::PipelineStageFlags,
) {
    let range = vk::ImageSubresourceRange::default()
        .aspect_mask(vk::ImageAspectFlags::COLOR)
        .level_count(1)
        .layer_count(1);
    let barrier = vk::ImageMemoryBarrier::default()
        .src_access_mask(from.1)
        .dst_access_mask(to.1)
        .old_layout(from.0)
        .new_layout(to.0)
        .src_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
        .dst_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
        .image(image)
        .subresource_range(range);
    d.cmd_pipeline_barrier(
        cmd,
        vk::PipelineStageFlags::TRANSFER,
        dst_stage,
        vk::DependencyFlags::empty(),
        &[],
        &[],
        &[barrier],
    );
}

impl Drop for Swapchain {
    fn drop(&mut self) {
        if crate::vk::device_lost() {
            return;
        }
        unsafe {
            let _ = self.device.device_wait_idle();
            self.device.free_command_buffers(self.pool, &[self.cmd]);
            self.device.destroy_fence(self.fence, None);
            self.device.destroy_semaphore(self.acquired, None);
            for s in self.rendered.drain(..) {
                self.device.destroy_semaphore(s, None);
            }
            self.loader.destroy_swapchain(self.raw, None);
        }
    }
}
