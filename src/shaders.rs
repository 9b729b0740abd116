//! Run-time shader compilation for user stages and hot reload: glslang on a shader folder, include tracking, watching.
use crate::error::Error;
use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::mpsc;
use std::time::Duration;

mod embedded {
    include!(concat!(env!("OUT_DIR"), "/shaders.rs"));
}

/// The built-in stages' SPIR-V, by stage name.
pub const BUILTIN_SPIRV: &[(&str, &[u8])] = embedded::STAGES;

/// Every constant src/constants.rs shares with GLSL, as (name, u32 bits), in the order probe_constants writes them.
pub const SHARED_CONSTANTS: &[(&str, u32)] = embedded::CONSTANTS;

/// The program that compiles GLSL: $GLSLANG_VALIDATOR, else glslangValidator on the PATH.
pub fn glslang() -> String {
    std::env::var("GLSLANG_VALIDATOR").unwrap_or_else(|_| "glslangValidator".into())
}

/// Writes the built-in GLSL (stages at the top, shared code in include/) into `dir`, the layout `--shader-dir`
/// expects. Existing files are overwritten.
pub fn export_builtin(dir: &Path) -> Result<Vec<PathBuf>, Error> {
    let err = |p: &Path, e: std::io::Error| Error::Output {
        path: p.to_path_buf(),
        message: format!("cannot write: {e}"),
    };
    let mut written = Vec::new();
    for (rel, text) in embedded::SOURCES {
        let path = dir.join(rel);
        if let Some(parent) = path.parent() {
            std::fs::create_dir_all(parent).map_err(|e| err(parent, e))?;
        }
        std::fs::write(&path, text).map_err(|e| err(&path, e))?;
        written.push(path);
    }
    Ok(written)
}

/// A folder of GLSL stages (`*.comp`, with shared code in `include/`) compiled on demand. Includes the folder lacks
/// come from the built-in ones, and the constants generated from src/constants.rs always come from this binary, so
/// user stages cannot drift from the host's layout.
pub struct ShaderDir {
    root: PathBuf,
    generated: tempfile::TempDir,
}

impl ShaderDir {
    pub fn open(root: &Path) -> Result<Self, Error> {
        let bad = |m: String| Error::Shader(format!("{}: {m}", root.display()));
        if !root.is_dir() {
            return Err(bad("not a folder".into()));
        }
        let generated = tempfile::tempdir().map_err(|e| bad(format!("cannot make a temporary folder: {e}")))?;
        std::fs::write(
            generated.path().join("shared_constants.glsl"),
            embedded::SHARED_CONSTANTS,
        )
        .map_err(|e| bad(format!("cannot write the shared constants: {e}")))?;
        // The built-in includes come last on the include path, so a folder may hold only the stages it changes.
        for (rel, text) in embedded::SOURCES {
            if let Some(name) = rel.strip_prefix("include/") {
                std::fs::write(generated.path().join(name), text)
                    .map_err(|e| bad(format!("cannot write the built-in {name}: {e}")))?;
            }
        }
        let root = root.canonicalize().map_err(|e| bad(e.to_string()))?;
        Ok(ShaderDir { root, generated })
    }

    pub fn root(&self) -> &Path {
        &self.root
    }

    /// The built-in stages this folder overrides (its `*.comp` files with a built-in stage's name, and their
    /// variants), sorted. Other `.comp` files are reported by `unknown_stages`.
    pub fn stages(&self) -> Vec<String> {
        let mut names: Vec<String> = BUILTIN_SPIRV
            .iter()
            .map(|(n, _)| n.to_string())
            .filter(|n| self.comp_files().contains(&source_of(n).0))
            .collect();
        names.sort();
        names
    }

    pub fn unknown_stages(&self) -> Vec<String> {
        self.comp_files()
            .into_iter()
            .filter(|s| !BUILTIN_SPIRV.iter().any(|(n, _)| n == s))
            .collect()
    }

    fn comp_files(&self) -> Vec<String> {
        let mut names: Vec<String> = std::fs::read_dir(&self.root)
            .into_iter()
            .flatten()
            .flatten()
            .map(|e| e.path())
            .filter(|p| p.extension().is_some_and(|e| e == "comp"))
            .filter_map(|p| p.file_stem().and_then(|s| s.to_str()).map(str::to_string))
            .collect();
        names.sort();
        names
    }

    fn include_dirs(&self) -> [PathBuf; 3] {
        [
            self.root.join("include"),
            self.root.clone(),
            self.generated.path().to_path_buf(),
        ]
    }

    /// Compiles one stage to SPIR-V. The error is glslang's own report, whose lines read
    /// `ERROR: /path/stage.comp:LINE: message`.
    pub fn compile(&self, stage: &str) -> Result<Vec<u8>, Error> {
        let (base, define) = source_of(stage);
        let src = self.root.join(format!("{base}.comp"));
        let out = self.generated.path().join(format!("{stage}.spv"));
        let mut cmd = Command::new(glslang());
        // Vulkan 1.1 / SPIR-V 1.3 like build.rs: the same compiler flags as the built-in stages.
        cmd.args(["-V", "--target-env", "vulkan1.1"]);
        for d in define.into_iter().flat_map(|d| d.split_whitespace()) {
            cmd.arg(format!("-D{d}"));
        }
        for dir in self.include_dirs() {
            cmd.arg(format!("-I{}", dir.display()));
        }
        let output = cmd
            .arg("-o")
            .arg(&out)
            .arg(&src)
            .output()
            .map_err(|e| Error::Shader(format!("cannot run {}: {e} (install glslang-tools)", glslang())))?;
        if !output.status.success() {
            let text: Vec<String> = String::from_utf8_lossy(&output.stdout)
                .lines()
                .chain(String::from_utf8_lossy(&output.stderr).lines())
                .map(str::trim)
                .filter(|l| !l.is_empty() && *l != src.display().to_string())
                .map(str::to_string)
                .collect();
            return Err(Error::Shader(text.join("\n")));
        }
        std::fs::read(&out).map_err(|e| Error::Shader(format!("{stage}: cannot read glslang's output: {e}")))
    }

    /// The files a stage reads: its `.comp` and everything it includes, transitively, as canonical paths.
    pub fn dependencies(&self, stage: &str) -> BTreeSet<PathBuf> {
        let mut seen = BTreeSet::new();
        let mut todo = vec![self.root.join(format!("{}.comp", source_of(stage).0))];
        while let Some(file) = todo.pop() {
            let file = file.canonicalize().unwrap_or(file);
            if !seen.insert(file.clone()) {
                continue;
            }
            let Ok(text) = std::fs::read_to_string(&file) else {
                continue;
            };
            for line in text.lines() {
                let Some(rest) = line.trim_start().strip_prefix("#include") else {
                    continue;
                };
                let Some(name) = rest.trim().strip_prefix('"').and_then(|r| r.split('"').next()) else {
                    continue;
                };
                // glslang looks beside the including file first, then in the -I folders.
                let here = file.parent().map(|d| d.join(name));
                let found = here
                    .into_iter()
                    .chain(self.include_dirs().iter().map(|d| d.join(name)))
                    .find(|p| p.is_file());
                if let Some(p) = found {
                    todo.push(p);
                }
            }
        }
        seen
    }

    /// The stages (of `stages()`) that read any of `changed`, which may be paths of files since deleted or renamed.
    pub fn affected(&self, changed: &[PathBuf]) -> Vec<String> {
        let changed: Vec<PathBuf> = changed
            .iter()
            .map(|p| p.canonicalize().unwrap_or_else(|_| p.clone()))
            .collect();
        let mut stages = self.stages();
        stages.retain(|s| {
            let deps = self.dependencies(s);
            // A stage file that appeared since the last look is affected too.
            let own = self.root.join(format!("{}.comp", source_of(s).0));
            changed.iter().any(|c| deps.contains(c) || *c == own)
        });
        stages
    }
}

/// The source file (without `.comp`) a stage is compiled from, and the define of its variant, if it is one.
pub fn source_of(stage: &str) -> (String, Option<&'static str>) {
    for (base, suffix, define) in crate::variants::STAGE_VARIANTS {
        if stage.strip_prefix(base).and_then(|r| r.strip_prefix('_')) == Some(suffix) {
            return (base.to_string(), Some(define));
        }
    }
    (stage.to_string(), None)
}

/// Watches a shader folder for changes (notify), so a caller can rebuild only the stale stages.
pub struct ShaderWatcher {
    _watcher: notify::RecommendedWatcher,
    events: mpsc::Receiver<notify::Result<notify::Event>>,
}

impl ShaderWatcher {
    pub fn new(dir: &ShaderDir) -> Result<Self, Error> {
        use notify::Watcher;
        let (tx, events) = mpsc::channel();
        let mut watcher = notify::recommended_watcher(move |e| {
            let _ = tx.send(e);
        })
        .map_err(|e| Error::Shader(format!("cannot watch {}: {e}", dir.root().display())))?;
        watcher
            .watch(dir.root(), notify::RecursiveMode::Recursive)
            .map_err(|e| Error::Shader(format!("cannot watch {}: {e}", dir.root().display())))?;
        Ok(ShaderWatcher {
            _watcher: watcher,
            events,
        })
    }

    /// Files changed since the last call, waiting up to `timeout` for the first one. Editors save in bursts
    /// (write, rename, touch), so a short quiet period is awaited before returning.
    pub fn changed(&self, timeout: Duration) -> Vec<PathBuf> {
        let mut paths = BTreeSet::new();
        let mut add = |e: notify::Result<notify::Event>| {
            if let Ok(e) = e {
                if !matches!(e.kind, notify::EventKind::Access(_)) {
                    paths.extend(e.paths);
                }
            }
        };
        match self.events.recv_timeout(timeout) {
            Ok(e) => add(e),
            Err(_) => return Vec::new(),
        }
        while let Ok(e) = self.events.recv_timeout(Duration::from_millis(150)) {
            add(e);
        }
        paths.into_iter().collect()
    }
}
