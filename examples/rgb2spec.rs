//! Fits the RGB-to-spectrum table (src/spectrum/fit.rs) and writes data/rgb2spec_srgb_32.bin, which the renderer
//! includes. Run after changing the fit or the CIE tables; tests/spectrum.rs checks the kept table against the fit.
use pathwave::constants::RGB2SPEC_RES;
use pathwave::spectrum::fit;

fn main() {
    let start = std::time::Instant::now();
    let cie = fit::Cie::parse(include_str!("../data/cie1931_d65.tsv"));
    let table = fit::build_table(&fit::Fit::new(&cie), RGB2SPEC_RES as usize);
    let bytes: Vec<u8> = table.iter().flat_map(|v| v.to_le_bytes()).collect();
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("data/rgb2spec_srgb_32.bin");
    std::fs::write(&path, bytes).expect("writing the table");
    println!(
        "wrote {} ({} coefficient triples) in {:.1} s",
        path.display(),
        table.len() / 3,
        start.elapsed().as_secs_f64()
    );
}
