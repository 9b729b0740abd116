//! The microfacet and sheen energy tables energy compensation and layering read: the grid from the device (the BSDF's
//! own sampling), the hemispherical averages from the host; and after them the spectral tables (SPECTRUM_*) and the
//! dielectric layer's multiple scattering (DIELECTRIC_MS, walked once by examples/dielectric_ms.rs), from the host.
use super::kernels::{Kernel, Stage};
use super::Renderer;
use crate::constants::*;
use crate::error::Error;
use crate::layout::Frame;
use crate::vk::Buffer;
use ash::vk;
use gpu_allocator::MemoryLocation;

/// The tables are one storage buffer bound whole on every device: Vulkan requires every device's storage range to
/// hold 2^27 bytes, so a device (or a test) with a smaller range for scene data still reads all of them.
const _: () = assert!(ENERGY_BUFFER_FLOATS as u64 * 4 <= 1 << 27);

impl Renderer {
    /// Builds the GGX tables once per renderer, at start-up; the sheen and anisotropic grids wait for a scene that
    /// needs them (`ensure_layer_tables`).
    pub(super) fn build_energy_tables(&mut self) -> Result<Buffer, Error> {
        let floats = ENERGY_BUFFER_FLOATS as usize;
        let mut energy = Buffer::new(
            &self.ctx,
            "energy tables",
            floats as u64 * 4,
            vk::BufferUsageFlags::STORAGE_BUFFER,
            MemoryLocation::GpuOnly,
        )?;
        // Zeros first: the sheen and anisotropic grids are read only by scenes that have them built. The spectral
        // tables come from the host.
        let mut floats_in = vec![0f32; SPECTRUM_MATRIX as usize];
        floats_in.extend(crate::spectrum::tables().device_floats());
        floats_in.extend(crate::microsurface::shipped_table());
        debug_assert_eq!(floats_in.len(), floats);
        energy.upload(&self.ctx, bytemuck::cast_slice(&floats_in))?;
        self.run_energy_pass(&mut energy, Stage::EnergyTables)?;
        Ok(energy)
    }

    /// Builds the sheen grid the first time a scene has a sheen in any of its materials (not only the ones its
    /// triangles use: the probes read any material), and the anisotropic grids the first time one is anisotropic.
    pub(super) fn ensure_layer_tables(&mut self, scene: &crate::scene::Scene) -> Result<(), Error> {
        if !self.sheen_table && scene.materials.iter().any(|m| m.sheen.color != glam::Vec3::ZERO) {
            let mut energy = self.energy.take().expect("built in Renderer::new");
            let done = self.run_energy_pass(&mut energy, Stage::SheenTable);
            self.energy = Some(energy);
            done?;
            self.sheen_table = true;
        }
        if !self.aniso_table && scene.materials.iter().any(|m| m.anisotropy.strength > 0.0) {
            let mut energy = self.energy.take().expect("built in Renderer::new");
            let done = self.run_aniso_pass(&mut energy);
            self.energy = Some(energy);
            done?;
            self.aniso_table = true;
        }
        Ok(())
    }

    /// The anisotropic grids, then their averages from the host: over the quarter turn of azimuths and over the
    /// projected hemisphere, by the trapezoid rule on the grid's points.
    fn run_aniso_pass(&mut self, energy: &mut Buffer) -> Result<(), Error> {
        self.run_kernel(
            Kernel::of(Stage::AnisoTable),
            &[(BINDING_ENERGY, energy)],
            Frame {
                path_count: ANISO_CELLS,
                ..Default::default()
            },
            1,
        )?;
        let mut table: Vec<f32> = energy.download(&self.ctx)?;
        table.truncate(ENERGY_BUFFER_FLOATS as usize);
        let (m, p, r) = (ANISO_RES_MU as usize, ANISO_RES_PHI as usize, ANISO_RES_ROUGH as usize);
        let cells = ANISO_CELLS as usize;
        let base = ENERGY_TABLE_FLOATS as usize;
        let trapezoid = |n: usize, f: &dyn Fn(usize) -> f64| {
            let h = 1.0 / (n - 1) as f64;
            (0..n - 1).map(|i| 0.5 * h * (f(i) + f(i + 1))).sum::<f64>()
        };
        for t in 0..2 {
            for pair in 0..r * r {
                let grid = &table[base + t * cells + pair * m * p..base + t * cells + (pair + 1) * m * p];
                let hemisphere =
                    |phi: usize| 2.0 * trapezoid(m, &|i| grid[phi * m + i] as f64 * i as f64 / (m - 1) as f64);
                table[base + 2 * cells + t * r * r + pair] = trapezoid(p, &hemisphere) as f32;
            }
        }
        energy.upload(&self.ctx, bytemuck::cast_slice(&table))?;
        Ok(())
    }

    /// One table stage over every cell, then every grid's averages from the host.
    fn run_energy_pass(&mut self, energy: &mut Buffer, stage: Stage) -> Result<(), Error> {
        let n = ENERGY_RES as usize;
        let cells = ENERGY_RES * ENERGY_RES;
        self.run_kernel(
            Kernel::of(stage),
            &[(BINDING_ENERGY, energy)],
            Frame {
                path_count: cells,
                ..Default::default()
            },
            1,
        )?;
        let mut table: Vec<f32> = energy.download(&self.ctx)?;
        table.truncate(ENERGY_BUFFER_FLOATS as usize);
        let h = 1.0 / (n - 1) as f64;
        let grids = ENERGY_GRIDS as usize;
        for t in 0..grids {
            for j in 0..n {
                // 2 * int_0^1 E(mu) mu dmu by the trapezoid rule on the grid the table was made on.
                let row = &table[t * n * n + j * n..t * n * n + (j + 1) * n];
                let integral: f64 = (0..n - 1)
                    .map(|i| 0.5 * h * (row[i] as f64 * i as f64 * h + row[i + 1] as f64 * (i + 1) as f64 * h))
                    .sum();
                table[grids * n * n + t * n + j] = (2.0 * integral) as f32;
            }
        }
        energy.upload(&self.ctx, bytemuck::cast_slice(&table))?;
        Ok(())
    }

    /// The energy tables as the device uses them: E1, E2 and Esheen grids, then their averages (ENERGY_*).
    pub fn energy_tables(&self) -> Result<Vec<f32>, Error> {
        let energy = self.energy.as_ref().expect("built in Renderer::new");
        let mut t: Vec<f32> = energy.download(&self.ctx)?;
        t.truncate(ENERGY_TABLE_FLOATS as usize);
        Ok(t)
    }

    /// The anisotropic grids and their averages (ANISO_*), zeros until a scene with anisotropy has built them.
    pub fn aniso_energy_tables(&self) -> Result<Vec<f32>, Error> {
        let energy = self.energy.as_ref().expect("built in Renderer::new");
        let t: Vec<f32> = energy.download(&self.ctx)?;
        Ok(t[ENERGY_TABLE_FLOATS as usize..SPECTRUM_MATRIX as usize].to_vec())
    }
}
