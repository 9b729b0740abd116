//! Run-time shader compilation for user stages and hot reload: glslang on a shader folder, include tracking, watching.
use crate::error::Error;
use std::collections::BTreeSet;
use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

/// glslang compiles any stage in well under a second; one still running after this is stuck, and is killed.
const COMPILE_TIME_LIMIT: Duration = Duration::from_secs(60);
/// The address space glslang may use: a stage needs tens of MiB, and a runaway preprocessor is stopped here rather
/// than by the machine running out of memory.
const COMPILE_MEMORY_LIMIT: u64 = 4 << 30;

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
    /// `ERROR: /path/stage.comp:LINE: message`. A stage whose includes form a cycle is refused before glslang runs
    /// (glslang would expand it until memory runs out), and glslang itself runs under a time and memory limit.
    pub fn compile(&self, stage: &str) -> Result<Vec<u8>, Error> {
        let (base, define) = source_of(stage);
        let src = self.root.join(format!("{base}.comp"));
        if let Some(cycle) = self.include_cycle(stage) {
            let names: Vec<String> = cycle.iter().map(|p| p.display().to_string()).collect();
            return Err(Error::Shader(format!(
                "{}: #include cycle: {}",
                src.display(),
                names.join(" -> ")
            )));
        }
        let out = self.generated.path().join(format!("{stage}.spv"));
        let mut cmd = Command::new(glslang());
        // The same compiler flags as build.rs gives the built-in stages.
        cmd.args(["-V", "--target-env", crate::variants::target_env(define)]);
        for d in define.into_iter().flat_map(|d| d.split_whitespace()) {
            cmd.arg(format!("-D{d}"));
        }
        for dir in self.include_dirs() {
            cmd.arg(format!("-I{}", dir.display()));
        }
        cmd.arg("-o").arg(&out).arg(&src);
        let output = run_limited(cmd)?;
        if !output.status.success() {
            let mut text: Vec<String> = String::from_utf8_lossy(&output.stdout)
                .lines()
                .chain(String::from_utf8_lossy(&output.stderr).lines())
                .map(str::trim)
                .filter(|l| !l.is_empty() && *l != src.display().to_string())
                .map(str::to_string)
                .collect();
            if let Some(signal) = std::os::unix::process::ExitStatusExt::signal(&output.status) {
                text.push(format!(
                    "{}: {} was killed by signal {signal} (it may use at most {} GiB of address space)",
                    src.display(),
                    glslang(),
                    COMPILE_MEMORY_LIMIT >> 30
                ));
            }
            return Err(Error::Shader(text.join("\n")));
        }
        std::fs::read(&out).map_err(|e| Error::Shader(format!("{stage}: cannot read glslang's output: {e}")))
    }

    /// The files `file` includes that exist, as canonical paths. glslang looks beside the including file first,
    /// then in the -I folders.
    fn includes(&self, file: &Path) -> Vec<PathBuf> {
        let Ok(text) = std::fs::read_to_string(file) else {
            return Vec::new();
        };
        let dirs = self.include_dirs();
        text.lines()
            .filter_map(|line| line.trim_start().strip_prefix("#include"))
            .filter_map(|rest| rest.trim().strip_prefix('"').and_then(|r| r.split('"').next()))
            .filter_map(|name| {
                let here = file.parent().map(|d| d.join(name));
                let found = here
                    .into_iter()
                    .chain(dirs.iter().map(|d| d.join(name)))
                    .find(|p| p.is_file());
                found.map(|p| p.canonicalize().unwrap_or(p))
            })
            .collect()
    }

    /// The files a stage reads: its `.comp` and everything it includes, transitively, as canonical paths.
    pub fn dependencies(&self, stage: &str) -> BTreeSet<PathBuf> {
        let mut seen = BTreeSet::new();
        let mut todo = vec![self.stage_file(stage)];
        while let Some(file) = todo.pop() {
            if seen.insert(file.clone()) {
                todo.extend(self.includes(&file));
            }
        }
        seen
    }

    fn stage_file(&self, stage: &str) -> PathBuf {
        let file = self.root.join(format!("{}.comp", source_of(stage).0));
        file.canonicalize().unwrap_or(file)
    }

    /// A chain of includes from a stage that comes back to a file already on it (first and last the same file), if
    /// any. Every cycle is refused, even one include guards would stop: they cannot be checked without
    /// preprocessing, and the built-in includes have none.
    pub fn include_cycle(&self, stage: &str) -> Option<Vec<PathBuf>> {
        // Depth-first, with the chain from the stage to the current file; `done` holds files fully explored.
        let mut done = BTreeSet::new();
        let mut chain: Vec<(PathBuf, Vec<PathBuf>)> = Vec::new();
        let root = self.stage_file(stage);
        chain.push((root.clone(), self.includes(&root)));
        while let Some((_, pending)) = chain.last_mut() {
            let Some(next) = pending.pop() else {
                done.insert(chain.pop().map(|(f, _)| f)?);
                continue;
            };
            if let Some(at) = chain.iter().position(|(f, _)| *f == next) {
                let mut cycle: Vec<PathBuf> = chain[at..].iter().map(|(f, _)| f.clone()).collect();
                cycle.push(next);
                return Some(cycle);
            }
            if !done.contains(&next) {
                let inc = self.includes(&next);
                chain.push((next, inc));
            }
        }
        None
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

/// Runs `cmd` to completion with its output captured, its address space limited to COMPILE_MEMORY_LIMIT and its
/// run killed after COMPILE_TIME_LIMIT.
fn run_limited(mut cmd: Command) -> Result<Output, Error> {
    use std::os::unix::process::CommandExt;
    let cannot = |e: std::io::Error| Error::Shader(format!("cannot run {}: {e} (install glslang-tools)", glslang()));
    // SAFETY: between fork and exec the hook calls only setrlimit, which is async-signal-safe.
    unsafe {
        cmd.pre_exec(|| {
            let limit = libc::rlimit {
                rlim_cur: COMPILE_MEMORY_LIMIT as libc::rlim_t,
                rlim_max: COMPILE_MEMORY_LIMIT as libc::rlim_t,
            };
            if libc::setrlimit(libc::RLIMIT_AS, &limit) != 0 {
                return Err(std::io::Error::last_os_error());
            }
            Ok(())
        });
    }
    let mut child = cmd
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .map_err(cannot)?;
    // Read both pipes while waiting, so a chatty compiler never blocks on a full pipe.
    fn drain(pipe: Option<impl Read + Send + 'static>) -> std::thread::JoinHandle<Vec<u8>> {
        std::thread::spawn(move || {
            let mut bytes = Vec::new();
            if let Some(mut p) = pipe {
                let _ = p.read_to_end(&mut bytes);
            }
            bytes
        })
    }
    let (stdout, stderr) = (drain(child.stdout.take()), drain(child.stderr.take()));
    let start = Instant::now();
    let status = loop {
        if let Some(status) = child.try_wait().map_err(cannot)? {
            break status;
        }
        if start.elapsed() > COMPILE_TIME_LIMIT {
            let _ = child.kill();
            let _ = child.wait();
            return Err(Error::Shader(format!(
                "{} did not finish within {} s and was stopped",
                glslang(),
                COMPILE_TIME_LIMIT.as_secs()
            )));
        }
        std::thread::sleep(Duration::from_millis(5));
    };
    Ok(Output {
        status,
        stdout: stdout.join().unwrap_or_default(),
        stderr: stderr.join().unwrap_or_default(),
    })
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
