//! Display pixels from a session's film for the viewer: exposure, a tone curve and sRGB, on the device.
use super::kernels::{Kernel, Stage};
use super::{Renderer, Session};
use crate::constants::*;
use crate::vk::Buffer;
use ash::vk;

impl Renderer {
    /// Writes the session's running mean into `out` as packed 8-bit sRGB pixels of `out_size` (nearest-scaled from
    /// the film), through `op`'s tone curve after scaling by `exposure` (linear). Recorded into `cmd`, which the
    /// caller submits; a barrier after it makes the pixels ready for transfers.
    pub fn record_tonemap(
        &self,
        cmd: vk::CommandBuffer,
        session: &Session,
        out: &Buffer,
        out_size: [u32; 2],
        op: u32,
        exposure: f32,
    ) {
        let mut bound = session.bindings().to_vec();
        bound.push((BINDING_TONEMAP_OUT, out));
        self.bind(&bound, session.texel_views());
        let tone = crate::layout::ToneMap {
            film_width: session.settings.width,
            film_height: session.settings.height,
            out_width: out_size[0],
            out_height: out_size[1],
            samples: session.done,
            op,
            exposure,
            pad: 0,
        };
        let groups = [out_size[0].div_ceil(TONEMAP_TILE), out_size[1].div_ceil(TONEMAP_TILE)];
        // Stages that do not render are built with the renderer, so the viewer's frames never compile.
        let k = self
            .kernels
            .built(Kernel::of(Stage::Tonemap))
            .expect("built in Kernels::new");
        self.kernels.dispatch_2d(cmd, k, bytemuck::bytes_of(&tone), groups);
        let barrier = vk::MemoryBarrier::default()
            .src_access_mask(vk::AccessFlags::SHADER_WRITE)
            .dst_access_mask(vk::AccessFlags::TRANSFER_READ);
        unsafe {
            self.ctx.device.cmd_pipeline_barrier(
                cmd,
                vk::PipelineStageFlags::COMPUTE_SHADER,
                vk::PipelineStageFlags::TRANSFER,
                vk::DependencyFlags::empty(),
                &[barrier],
                &[],
                &[],
            )
        };
    }
}
