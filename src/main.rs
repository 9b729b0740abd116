//! The pathwave command line: render, view, bench, info, export-shaders.
use clap::{Parser, Subcommand};
use std::path::PathBuf;

use cli::args::LoadArgs;
use cli::bench::{bench, BenchArgs};
use cli::film as film_cli;
use cli::info::{export_shaders, info};
use cli::render::{render, RenderArgs};
use cli::view::{view, ViewArgs};
use pathwave::cli;

#[derive(Parser)]
#[command(
    name = "pathwave",
    version,
    about = "A physically based wavefront path tracer on Vulkan compute"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Render a glTF scene to an EXR (linear) or PNG (sRGB) file.
    Render(RenderArgs),
    /// Show a scene in a window, rendering progressively; see docs/guide/viewer.md for the controls.
    View(ViewArgs),
    /// Describe a scene (triangles, materials, lights, BVH), take a census of a folder of scenes, or list the
    /// Vulkan devices.
    Info {
        /// The glTF (.gltf or .glb) scene, or a folder: every .gltf and .glb under it, each loaded as `render` would,
        /// one line each, then the extensions they use and how many files use each.
        scene: Option<PathBuf>,
        /// List the Vulkan devices instead (their index is what --device takes).
        #[arg(long)]
        devices: bool,
        #[command(flatten)]
        limits: LoadArgs,
    },
    /// Merge film files of disjoint sample ranges of one render (`render --samples` or `--part`) into one film
    /// file, bit-identical to rendering their union at once.
    Merge(film_cli::MergeArgs),
    /// Compare a render with a reference: a per-pixel statistical test when either carries film statistics, else
    /// relMSE and FLIP against thresholds. Exit 0: consistent; 1: they differ; 2: an error.
    Diff(film_cli::DiffArgs),
    /// Measure a fixed set of renders (Cornell box, glass, a 1M-triangle terrain): a table, and JSON with --json.
    Bench(BenchArgs),
    /// Write the built-in GLSL stages (and include/) into a folder, to edit and use with --shader-dir.
    ExportShaders {
        /// The folder to write into (created if missing).
        dir: PathBuf,
    },
}

fn main() {
    let cli = Cli::parse();
    // tests/guide.rs checks every command the guide shows against the parser without running it.
    if std::env::var_os("PATHWAVE_PARSE_ONLY").is_some() {
        return;
    }
    // diff's exit codes are cmp's: 1 means the images differ, so its errors exit 2.
    let error_code = if matches!(cli.command, Command::Diff(_)) { 2 } else { 1 };
    let result = match cli.command {
        Command::Render(args) => render(args),
        Command::View(args) => view(args),
        Command::Info { scene, devices, limits } => info(scene, devices, &limits),
        Command::ExportShaders { dir } => export_shaders(dir),
        Command::Bench(args) => bench(args),
        Command::Merge(args) => film_cli::merge(args),
        Command::Diff(args) => film_cli::diff(args),
    };
    if let Err(e) = result {
        eprintln!("error: {e:#}");
        std::process::exit(error_code);
    }
}
