//! Walks the GGX microsurface (src/microsurface.rs) over the dielectric layer's grid and writes data/dielectric_ms.bin,
//! the multiple scattering the shaders return. Run after changing the walk or the grid (MS_* in src/constants.rs);
//! tests/bsdf/energy.rs checks cells of the kept table against fresh walks.
use indicatif::{ProgressBar, ProgressStyle};
use pathwave::constants::{MS_RES_F0, MS_RES_ROUGH, MS_WALKS};
use pathwave::microsurface;

fn main() {
    let start = std::time::Instant::now();
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    let bar = ProgressBar::new((MS_RES_F0 * MS_RES_ROUGH) as u64).with_style(
        ProgressStyle::with_template("{bar:40} {pos}/{len} rows of cells, {eta} left").expect("a valid template"),
    );
    let table = microsurface::build_table(MS_WALKS as usize, threads, &|| bar.inc(1));
    bar.finish_and_clear();
    let bytes: Vec<u8> = table.iter().flat_map(|v| v.to_le_bytes()).collect();
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("data/dielectric_ms.bin");
    std::fs::write(&path, bytes).expect("writing the table");
    println!(
        "wrote {} ({} floats, {MS_WALKS} walks a cell, {threads} threads) in {:.1} s",
        path.display(),
        table.len(),
        start.elapsed().as_secs_f64()
    );
}
