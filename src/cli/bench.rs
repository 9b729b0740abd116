//! `pathwave bench`: which peers to compare with, and the report it prints and writes.
use crate::vk::DeviceChoice;
use crate::LightSampler;
use anyhow::{Context as _, Result};
use std::path::PathBuf;

#[derive(Clone, Copy, Debug, clap::ValueEnum)]
pub enum CompareWith {
    Mitsuba,
    Embree,
    /// The lamp grid, the city block and the emissive panel against Mitsuba 3, once per light sampler (bvh, power,
    /// uniform).
    Lights,
}

#[derive(clap::Args)]
pub struct BenchArgs {
    /// Also write the figures as JSON to this file.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Fewer samples and a smaller terrain, for a quick look.
    #[arg(long)]
    pub quick: bool,
    /// Folder holding cornell-box.gltf and glass.gltf (default: ./scenes, else the source tree's).
    #[arg(long)]
    pub scenes: Option<PathBuf>,
    #[arg(long)]
    pub device: Option<DeviceChoice>,
    /// Also measure against another renderer in the same run: `mitsuba` (Mitsuba 3 llvm_ad_rgb, equal-time
    /// relMSE on the Cornell box), `embree` (embreex, random-ray traversal on the terrain) or `lights` (Mitsuba 3 on
    /// the lamp grid, the city block and the emissive panel, once per light sampler). Repeatable.
    #[arg(long, value_enum)]
    pub compare: Vec<CompareWith>,
    /// The Python interpreter that has `mitsuba` and `embreex` installed.
    #[arg(long, default_value = "python3")]
    pub python: PathBuf,
    /// Run only the comparisons, not the fixed cases.
    #[arg(long, requires = "compare")]
    pub only_compare: bool,
    /// Light selection for the fixed cases and the Cornell box comparisons (`--compare lights` runs all three):
    /// bvh (default), power or uniform.
    #[arg(long, value_enum, default_value = "bvh")]
    pub light_sampler: LightSampler,
    /// Which traversals the cases and the Embree comparison measure: `auto` (default) both side by side where the
    /// device has ray queries, else the compute BVH; `compute` or `ray-query` that one alone.
    #[arg(long, value_enum, default_value = "auto", hide_possible_values = true)]
    pub traversal: crate::render::Traversal,
    /// Measure one group of the fixed cases alone (without start-up and the light tree): cornell-box, glass,
    /// textured-props, terrain or instances. With `--compare mitsuba`, `cornell-box` keeps the Cornell box's RGB and
    /// spectral comparisons alone (no subsurface or adaptive ones), any other group none of them.
    #[arg(long, value_parser = clap::builder::PossibleValuesParser::new(crate::bench::CASE_GROUPS))]
    pub only: Option<String>,
}

pub fn bench(a: BenchArgs) -> Result<()> {
    let scenes = a.scenes.unwrap_or_else(|| {
        let here = PathBuf::from("scenes");
        if here.join("cornell-box.gltf").exists() {
            here
        } else {
            PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenes")
        }
    });
    let options = crate::bench::BenchOptions {
        device: a.device.unwrap_or_default(),
        scenes,
        exe: std::env::current_exe()?,
        quick: a.quick,
        compare: (a.compare.iter())
            .map(|c| match c {
                CompareWith::Mitsuba => crate::bench::Compare::Mitsuba,
                CompareWith::Embree => crate::bench::Compare::Embree,
                CompareWith::Lights => crate::bench::Compare::Lights,
            })
            .collect(),
        python: a.python,
        only_compare: a.only_compare,
        light_sampler: a.light_sampler,
        traversal: a.traversal,
        only: a.only,
    };
    let report = crate::bench::run(&options, &mut |case| eprintln!("bench: {case}"))?;
    print!("{}", report.table());
    if let Some(path) = a.json {
        std::fs::write(&path, report.json() + "\n").with_context(|| format!("cannot write {}", path.display()))?;
    }
    Ok(())
}
