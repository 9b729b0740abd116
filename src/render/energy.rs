//! The microfacet and sheen energy tables energy compensation and layering read: the grid from the device (the BSDF's
//! own sampling), the hemispherical averages from the host; and after them the spectral tables (SPECTRUM_*) and the
//! dielectric layer's multiple scattering (DIELECTRIC_MS, walked once by examples/dielectric_ms.rs), from the host;
//! the CIE rows among them also as texels (BINDING_CIE_TEXELS).
use super::kernels::{Kernel, Stage};
use super::Renderer;
use crate::constants::*;
use crate::error::Error;
use crate::layout::Frame;
use crate::vk::{Buffer, Context, TexelViews};
use ash::vk;
use gpu_allocator::MemoryLocation;

/// The tables are one storage buffer bound whole on every device: Vulkan requires every device's storage range to
/// hold 2^27 bytes, so a device (or a test) with a smaller range for scene data still reads all of them.
const _: () = assert!(ENERGY_BUFFER_FLOATS as u64 * 4 <= 1 << 27);
/// The CIE rows' view starts at a multiple of the largest minTexelBufferOffsetAlignment Vulkan allows.
const _: () = assert!((4 * SPECTRUM_CIE).is_multiple_of(256));

/// The energy buffer and which of its grids are built. The GGX grids are built at start-up; the sheen and anisotropic
/// grids wait for a scene that needs them (zeros until then).
pub(super) struct EnergyTables {
    /// The CIE rows' view of `buffer`; dropped before it.
    cie_view: TexelViews,
    buffer: Buffer,
    sheen: bool,
    aniso: bool,
}

impl EnergyTables {
    /// The buffer as the host fills it: zeros for the grids the device builds, then the spectral tables and the
    /// dielectric layer's multiple scattering.
    pub(super) fn upload(ctx: &Context) -> Result<Self, Error> {
        let floats = ENERGY_BUFFER_FLOATS as usize;
        let mut buffer = Buffer::new(
            ctx,
            "energy tables",
            floats as u64 * 4,
            vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::UNIFORM_TEXEL_BUFFER,
            MemoryLocation::GpuOnly,
        )?;
        // Bound whole even where storage bindings of viewed scene buffers are cut to a small storage range (its view
        // serves only the CIE rows), as the assertion above allows.
        buffer.viewed = false;
        let mut floats_in = vec![0f32; SPECTRUM_MATRIX as usize];
        floats_in.extend(crate::spectrum::tables().device_floats());
        floats_in.extend(crate::microsurface::shipped_table());
        debug_assert_eq!(floats_in.len(), floats);
        buffer.upload(ctx, bytemuck::cast_slice(&floats_in))?;
        let cie_view = TexelViews::range(
            ctx,
            (BINDING_CIE_TEXELS, &buffer, vk::Format::R32G32B32A32_SFLOAT),
            4 * SPECTRUM_CIE as u64,
            16 * CIE_ROWS as u64,
        )?;
        Ok(EnergyTables {
            buffer,
            cie_view,
            sheen: false,
            aniso: false,
        })
    }

    pub(super) fn binding(&self) -> (u32, &Buffer) {
        (BINDING_ENERGY, &self.buffer)
    }

    pub(super) fn texel_views(&self) -> &[(u32, vk::BufferView)] {
        &self.cie_view.views
    }

    /// A sheen in any of the scene's materials (not only the ones its triangles use: the probes read any material)
    /// and no sheen grid yet.
    fn wants_sheen(&self, scene: &crate::scene::Scene) -> bool {
        !self.sheen && scene.materials.iter().any(|m| m.sheen.color != glam::Vec3::ZERO)
    }

    fn wants_aniso(&self, scene: &crate::scene::Scene) -> bool {
        !self.aniso && scene.materials.iter().any(|m| m.anisotropy.strength > 0.0)
    }
}

/// Every GGX and sheen grid's hemispherical average over its rows: 2 * int_0^1 E(mu) mu dmu by the trapezoid rule on
/// the grid the table was made on.
pub(super) fn grid_averages(table: &mut [f32]) {
    let n = ENERGY_RES as usize;
    let h = 1.0 / (n - 1) as f64;
    let grids = ENERGY_GRIDS as usize;
    for t in 0..grids {
        for j in 0..n {
            let row = &table[t * n * n + j * n..t * n * n + (j + 1) * n];
            let integral: f64 = (0..n - 1)
                .map(|i| 0.5 * h * (row[i] as f64 * i as f64 * h + row[i + 1] as f64 * (i + 1) as f64 * h))
                .sum();
            table[grids * n * n + t * n + j] = (2.0 * integral) as f32;
        }
    }
}

/// The anisotropic grids' averages: over the quarter turn of azimuths and over the projected hemisphere, by the
/// trapezoid rule on the grid's points.
fn aniso_averages(table: &mut [f32]) {
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
            let hemisphere = |phi: usize| 2.0 * trapezoid(m, &|i| grid[phi * m + i] as f64 * i as f64 / (m - 1) as f64);
            table[base + 2 * cells + t * r * r + pair] = trapezoid(p, &hemisphere) as f32;
        }
    }
}

impl Renderer {
    /// Builds the sheen grid the first time a scene has a sheen in any of its materials, and the anisotropic grids
    /// the first time one is anisotropic.
    pub(super) fn ensure_layer_tables(&mut self, scene: &crate::scene::Scene) -> Result<(), Error> {
        if self.energy.wants_sheen(scene) {
            self.build_grids(Stage::SheenTable, ENERGY_RES * ENERGY_RES, grid_averages)?;
            self.energy.sheen = true;
        }
        if self.energy.wants_aniso(scene) {
            self.build_grids(Stage::AnisoTable, ANISO_CELLS, aniso_averages)?;
            self.energy.aniso = true;
        }
        Ok(())
    }

    /// One table stage over `cells` cells, then the grids' averages from the host.
    pub(super) fn build_grids(&mut self, stage: Stage, cells: u32, averages: fn(&mut [f32])) -> Result<(), Error> {
        let frame = Frame {
            path_count: cells,
            ..Default::default()
        };
        self.run_kernel(Kernel::of(stage), &[], frame, 1)?;
        let mut table: Vec<f32> = self.energy.buffer.download(&self.ctx)?;
        table.truncate(ENERGY_BUFFER_FLOATS as usize);
        averages(&mut table);
        self.energy.buffer.upload(&self.ctx, bytemuck::cast_slice(&table))
    }

    /// The energy tables as the device uses them: E1, E2 and Esheen grids, then their averages (ENERGY_*).
    pub fn energy_tables(&self) -> Result<Vec<f32>, Error> {
        let mut t: Vec<f32> = self.energy.buffer.download(&self.ctx)?;
        t.truncate(ENERGY_TABLE_FLOATS as usize);
        Ok(t)
    }

    /// The anisotropic grids and their averages (ANISO_*), zeros until a scene with anisotropy has built them.
    pub fn aniso_energy_tables(&self) -> Result<Vec<f32>, Error> {
        let t: Vec<f32> = self.energy.buffer.download(&self.ctx)?;
        Ok(t[ENERGY_TABLE_FLOATS as usize..SPECTRUM_MATRIX as usize].to_vec())
    }
}

/// The averages are computed from the grids alone and written only to their slots.
#[cfg(test)]
mod tests {
    use super::*;

    /// A grid of ones averages to 1 (2 * int mu dmu), zeros to 0; nothing but the average slots changes.
    #[test]
    fn grid_averages_of_constant_grids() {
        let n = ENERGY_RES as usize;
        let grids = ENERGY_GRIDS as usize;
        let mut table = vec![1f32; ENERGY_TABLE_FLOATS as usize];
        let averages = grids * n * n..grids * n * n + grids * n;
        table[averages.clone()].fill(-7.0);
        table[(grids - 1) * n * n..grids * n * n].fill(0.0);
        let before = table.clone();
        grid_averages(&mut table);
        for (i, (&a, &b)) in table.iter().zip(&before).enumerate() {
            if !averages.contains(&i) {
                assert_eq!(a, b, "float {i} is not an average");
            }
        }
        let (full, empty) = (
            &table[averages.start..averages.start + n],
            &table[averages.end - n..averages.end],
        );
        assert!(full.iter().all(|a| (a - 1.0).abs() < 1e-6), "{full:?}");
        assert!(empty.iter().all(|&a| a == 0.0));
    }

    /// An anisotropic grid of ones averages to 1 over azimuths and the projected hemisphere.
    #[test]
    fn aniso_averages_of_constant_grids() {
        let mut table = vec![1f32; ENERGY_BUFFER_FLOATS as usize];
        let r2 = (ANISO_RES_ROUGH * ANISO_RES_ROUGH) as usize;
        let at = ENERGY_TABLE_FLOATS as usize + 2 * ANISO_CELLS as usize;
        table[at..at + 2 * r2].fill(-7.0);
        let before = table.clone();
        aniso_averages(&mut table);
        assert!(table[at..at + 2 * r2].iter().all(|a| (a - 1.0).abs() < 1e-6));
        assert_eq!(table[..at], before[..at]);
        assert_eq!(table[at + 2 * r2..], before[at + 2 * r2..]);
    }
}
