//! The display pipeline: the image the window shows (tone-mapped, an AOV view or denoised), and screenshots of it.
use super::State;
use crate::error::Error;
use crate::output::ToneCurve;
use crate::vk::{Buffer, Context};
use std::time::Duration;

impl State {
    /// The host's image for the display mode or denoising, made again once the samples have doubled (denoising
    /// only while the camera is still: while it moves, the live image shows).
    fn update_shown(&mut self) -> Result<(), Error> {
        let still = self.last_move.is_none_or(|t| t.elapsed() > Duration::from_millis(300));
        let wanted = self.display.is_some() || (self.denoising && still);
        let done = self.session.done;
        if !wanted || done == 0 || self.shown.as_ref().is_some_and(|(n, _, _)| done < 2 * n) {
            return Ok(());
        }
        let film = self.renderer.film(&self.session)?;
        let (w, h) = (film.width, film.height);
        let linear: Vec<[f32; 3]> = match (self.display, &self.denoiser) {
            (Some(aov), _) => {
                let source = crate::output::AovSource {
                    film: &film,
                    noisy: None,
                };
                // The picture's sRGB bytes, back to linear: the clamp curve at exposure 0 shows them as they are.
                let decode = |b: u8| crate::output::srgb_decode(b as f32 / 255.0);
                match source.picture(aov, 0.0) {
                    Some(p) => p.iter().map(|px| px.map(decode)).collect(),
                    None => return Ok(()),
                }
            }
            (None, Some(d)) => {
                let aovs = film
                    .aovs
                    .as_ref()
                    .ok_or_else(|| Error::Settings("no AOVs to denoise with".into()))?;
                let (albedo, normal) = (aovs.albedo(), aovs.normal());
                let guides = crate::denoise::Guides {
                    albedo: Some(&albedo),
                    normal: Some(&normal),
                    clean: false,
                };
                d.denoise(w, h, &film.mean(), guides)?
            }
            (None, None) => return Ok(()),
        };
        let words: Vec<[f32; 4]> = linear.iter().map(|p| [p[0], p[1], p[2], 1.0]).collect();
        let mut image = Buffer::new(
            self.renderer.context(),
            "shown image",
            (words.len() * 16) as u64,
            ash::vk::BufferUsageFlags::STORAGE_BUFFER | ash::vk::BufferUsageFlags::TRANSFER_DST,
            gpu_allocator::MemoryLocation::GpuOnly,
        )?;
        image.upload(self.renderer.context(), bytemuck::cast_slice(&words))?;
        self.shown = Some((done, image, linear));
        Ok(())
    }

    pub(super) fn present(&mut self) -> Result<(), Error> {
        self.update_shown()?;
        let bgra = self.swapchain.bgra;
        let bgra_bit = if bgra { crate::constants::TONEMAP_BGRA } else { 0 };
        let (curve, exposure) = match self.display {
            Some(_) => (ToneCurve::None, 1.0),
            None => (self.curve, 2f32.powf(self.exposure)),
        };
        let op = curve.code() | bgra_bit;
        let size = [self.session.settings.width, self.session.settings.height];
        let (renderer, session, pixels, shown) = (&self.renderer, &self.session, &self.pixels, &self.shown);
        let ok = self
            .swapchain
            .present(renderer.context(), pixels, |cmd, extent| match shown {
                Some((_, image, _)) => renderer.record_tonemap_image(cmd, image, size, pixels, extent, op, exposure),
                None => renderer.record_tonemap(cmd, session, pixels, extent, op, exposure),
            })?;
        if !ok {
            let size = self.window.inner_size();
            self.resize(size)?;
        }
        Ok(())
    }

    /// Writes the running mean to `path`, and with `both` as EXR (linear) and PNG (this view's exposure and tone curve) side by side.
    pub(super) fn save(&mut self, path: &std::path::Path, both: bool) -> Result<(), Error> {
        let film = self.renderer.film(&self.session)?;
        // What the window shows: the denoised image or a view, once made; else the running mean. The PNG shows it
        // as the window does (a view linear at exposure 0).
        let look = crate::output::Display {
            exposure: self.exposure,
            curve: self.curve,
        };
        let (pixels, display) = match (&self.shown, self.display) {
            (Some((_, _, linear)), Some(_)) => (linear.clone(), crate::output::Display::linear(0.0)),
            (Some((_, _, linear)), None) => (linear.clone(), look),
            (None, _) => (film.mean(), look),
        };
        let paths = if both {
            vec![path.with_extension("exr"), path.with_extension("png")]
        } else {
            vec![path.to_path_buf()]
        };
        for p in paths {
            crate::output::write_images_with(&[&p], film.width, film.height, &pixels, display, None)?;
            eprintln!("saved {} ({} spp)", p.display(), film.spp);
        }
        Ok(())
    }
}

pub(super) fn pixel_buffer(ctx: &Context, extent: [u32; 2]) -> Result<Buffer, Error> {
    Buffer::new(
        ctx,
        "display pixels",
        extent[0] as u64 * extent[1] as u64 * 4,
        ash::vk::BufferUsageFlags::STORAGE_BUFFER | ash::vk::BufferUsageFlags::TRANSFER_SRC,
        gpu_allocator::MemoryLocation::GpuOnly,
    )
}
