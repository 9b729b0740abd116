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
        let film = [session.settings.width, session.settings.height];
        self.record_tone(cmd, film, session.done, out_size, op, exposure);
    }

    /// `record_tonemap` of an image the host made (`image`: a vec4 per pixel, rgb and 1, `size` pixels), e.g. the
    /// denoised image or an AOV, in place of a session's film.
    #[allow(clippy::too_many_arguments)]
    pub fn record_tonemap_image(
        &self,
        cmd: vk::CommandBuffer,
        image: &Buffer,
        size: [u32; 2],
        out: &Buffer,
        out_size: [u32; 2],
        op: u32,
        exposure: f32,
    ) {
        self.bind(&[(BINDING_FILM, image), (BINDING_TONEMAP_OUT, out)], &[]);
        self.record_tone(cmd, size, 1, out_size, op, exposure);
    }

    fn record_tone(
        &self,
        cmd: vk::CommandBuffer,
        film: [u32; 2],
        samples: u32,
        out_size: [u32; 2],
        op: u32,
        exposure: f32,
    ) {
        let tone = crate::layout::ToneMap {
            film_width: film[0],
            film_height: film[1],
            out_width: out_size[0],
            out_height: out_size[1],
            samples,
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
