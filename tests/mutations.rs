//! Deterministic mutation testing of the loaders (glTF/GLB, environment maps, EXR): seeded damage to the validator corpus and the project's scenes must never panic, abort or hang.
//!
//! The mutants are written to a temporary folder and loaded by a child process (this test binary, running the
//! ignored `mutation_worker`), under a memory limit, with a deadline per input: an abort or a runaway allocation
//! kills only the child, and the supervisor names the input that was in flight and goes on with the next one.
mod common;

use common::mutate::mutate;
use common::rng::Rng;
use std::io::{BufRead, BufReader, Write};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

/// Mutants per seed that is refused as it is, and per seed that is read (whose mutants reach deeper): about 30 s
/// in all for the corpus and the scenes in a test build on 2 cores.
const MUTANTS_PER_REFUSED_SEED: usize = 100;
const MUTANTS_PER_READ_SEED: usize = 2500;
/// No single load may take longer (a load of any seed takes well under a second).
const DEADLINE: Duration = Duration::from_secs(10);
/// The child's address-space limit: far above what any seed needs, far below what a runaway count asks for.
const MEMORY_LIMIT: u64 = 4 << 30;
/// Tells the worker where the list of inputs is.
const LIST_VAR: &str = "PATHWAVE_MUTATION_LIST";

/// What reads a mutant.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Reader {
    Scene,
    Environment,
    Exr,
}

impl Reader {
    fn name(self) -> &'static str {
        match self {
            Reader::Scene => "scene",
            Reader::Environment => "env",
            Reader::Exr => "exr",
        }
    }

    fn parse(s: &str) -> Reader {
        match s {
            "scene" => Reader::Scene,
            "env" => Reader::Environment,
            _ => Reader::Exr,
        }
    }
}

/// Runs one reader on one file; `Err` holds the error message, which must name the file.
fn read(reader: Reader, path: &Path) -> Result<(), String> {
    let message = match reader {
        Reader::Scene => pathwave::scene::load(path, None).map(|s| drop(s.flatten())).err(),
        Reader::Environment => pathwave::scene::Environment::load(path, 1.0).map(drop).err(),
        // Both readers of pathwave's EXRs: the plain one and the film files' (merge, diff).
        Reader::Exr => (pathwave::output::read_exr(path).map(drop))
            .and_then(|()| pathwave::output::read_film(path).map(drop))
            .err(),
    };
    match message {
        None => Ok(()),
        Some(e) => Err(e.to_string()),
    }
}

/// Small maps written at test time: a gradient as .hdr (Radiance RGBE) and as .exr.
fn write_maps(dir: &Path) -> Vec<PathBuf> {
    let (w, h) = (16u32, 8u32);
    let px: Vec<[f32; 3]> = (0..w * h)
        .map(|i| [(i % w) as f32 / w as f32, (i / w) as f32 / h as f32, 2.0])
        .collect();
    let exr = dir.join("map.exr");
    pathwave::output::write_image(&exr, w, h, &px, 0.0).unwrap();
    let hdr = dir.join("map.hdr");
    let rgb: Vec<image::Rgb<f32>> = px.iter().map(|p| image::Rgb(*p)).collect();
    let file = std::io::BufWriter::new(std::fs::File::create(&hdr).unwrap());
    image::codecs::hdr::HdrEncoder::new(file)
        .encode(&rgb, w as usize, h as usize)
        .unwrap();
    vec![hdr, exr, write_film(dir, &px, w, h)]
}

/// A film file of `px` (four samples a pixel), so the mutations reach its u32 channels and its JSON metadata.
fn write_film(dir: &Path, px: &[[f32; 3]], w: u32, h: u32) -> PathBuf {
    use pathwave::render::film::{ExactFilm, Wide};
    let film = ExactFilm {
        samples: std::iter::once(0..4).collect(),
        count: vec![4; px.len()],
        sum: px
            .iter()
            .map(|p| p.map(|c| (c as f64 * 4.0 * 2f64.powi(64)) as i128))
            .collect(),
        sum_sq: (px.iter())
            .map(|p| {
                p.map(|c| Wide {
                    lo: (c as f64 * c as f64 * 4.0 * 2f64.powi(48)) as u128,
                    hi: 0,
                })
            })
            .collect(),
    };
    let meta = pathwave::output::FilmMeta {
        scene: "5".repeat(64),
        frame: "6".repeat(64),
        shaders: "7".repeat(64),
        settings: vec![("size".into(), format!("{w}x{h}"))],
        seed: 3,
        samples: film.samples.clone(),
        part: Some(pathwave::output::PartOf {
            index: 1,
            count: 4,
            spp: 16,
        }),
        device: "test".into(),
        version: "0".into(),
    };
    let path = dir.join("film.exr");
    let stats = pathwave::output::Stats {
        film: &film,
        meta: &meta,
    };
    pathwave::output::write_images_with(
        &[&path],
        w,
        h,
        &film.mean(),
        pathwave::output::Display::linear(0.0),
        Some(stats),
    )
    .unwrap();
    assert!(pathwave::output::read_film(&path).unwrap().stats.is_some());
    path
}

/// A seed, the folder its mutants are written to (beside copies of the files it refers to), and the run's inputs
/// that are its mutants.
struct Seed {
    reader: Reader,
    path: PathBuf,
    folder: PathBuf,
    inputs: std::ops::Range<usize>,
}

/// The seed input `index` is a mutant of.
fn seed_of(seeds: &[Seed], index: usize) -> &Seed {
    &seeds[seeds.partition_point(|s| s.inputs.end <= index)]
}

/// Copies the files a seed may refer to (buffers, images) into `to`.
fn copy_resources(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for entry in std::fs::read_dir(from).unwrap() {
        let p = entry.unwrap().path();
        let ext = p.extension().and_then(|e| e.to_str()).unwrap_or("");
        if p.is_file() && !matches!(ext, "gltf" | "glb" | "json") {
            std::fs::copy(&p, to.join(p.file_name().unwrap())).unwrap();
        }
    }
}

/// Gives every seed a folder under `root` holding copies of its source folder's resources, one per source folder,
/// and its share of the inputs.
fn place(root: &Path, seeds: Vec<(Reader, PathBuf)>) -> Vec<Seed> {
    let mut next = 0;
    let mut sources: Vec<PathBuf> = Vec::new();
    let mut placed = Vec::new();
    for (reader, path) in seeds {
        let source = path.parent().unwrap().to_path_buf();
        let i = sources.iter().position(|f| *f == source).unwrap_or_else(|| {
            copy_resources(&source, &root.join(sources.len().to_string()));
            sources.push(source);
            sources.len() - 1
        });
        // The seeds themselves never panic (tests/gltf_corpus.rs), so the supervisor may read them in process.
        let count = match read(reader, &path) {
            Ok(()) => MUTANTS_PER_READ_SEED,
            Err(_) => MUTANTS_PER_REFUSED_SEED,
        };
        placed.push(Seed {
            reader,
            path,
            folder: root.join(i.to_string()),
            inputs: next..next + count,
        });
        next += count;
    }
    placed
}

/// Input `index` of the run, a mutant of `seed`, written beside the seed's resources. Each mutant has its own RNG, so any one can be made again on its own.
fn write_mutant(seed: &Seed, bytes: &[u8], index: usize, to: &Path) -> String {
    let mut rng = Rng(0x5eed_0000_0000 ^ index as u64);
    let (mutant, what) = mutate(bytes, &mut rng);
    std::fs::write(to, mutant).unwrap();
    format!("{}: {what}", seed.path.file_name().unwrap().to_string_lossy())
}

fn mutant_path(seed: &Seed, index: usize) -> PathBuf {
    let ext = seed.path.extension().unwrap().to_str().unwrap();
    seed.folder.join(format!("m{index}.{ext}"))
}

fn seeds(maps: Vec<PathBuf>) -> Vec<(Reader, PathBuf)> {
    let mut scenes = Vec::new();
    let corpus = Path::new(common::CORPUS);
    if corpus.is_dir() {
        common::corpus_files(corpus, &mut scenes);
    } else {
        eprintln!(
            "note: the glTF-Validator corpus is not at {}; seeding with scenes/ only",
            corpus.display()
        );
    }
    common::corpus_files(&common::scenes_dir(), &mut scenes);
    let mut seeds: Vec<(Reader, PathBuf)> = scenes.into_iter().map(|p| (Reader::Scene, p)).collect();
    for map in maps {
        if map.file_name().is_some_and(|n| n != "film.exr") {
            seeds.push((Reader::Environment, map.clone()));
        }
        if map.extension().is_some_and(|e| e == "exr") {
            seeds.push((Reader::Exr, map));
        }
    }
    seeds
}

/// The worker's report on one input: its index, and "read", "refused" or "fault: what went wrong".
type Report = (usize, String);

/// Starts a worker on inputs `from..` of the list, under the memory limit; its reports arrive on the channel.
fn start_worker(list: &Path, from: usize) -> (Child, mpsc::Receiver<Report>) {
    let exe = std::env::current_exe().unwrap();
    let args = [
        "--exact",
        "mutation_worker",
        "--ignored",
        "--nocapture",
        "--test-threads=1",
    ];
    let mut command = if Path::new("/usr/bin/prlimit").exists() {
        let mut c = Command::new("/usr/bin/prlimit");
        c.arg(format!("--as={MEMORY_LIMIT}")).arg(&exe);
        c
    } else {
        Command::new(&exe)
    };
    let mut child = command
        .args(args)
        .env(LIST_VAR, list)
        .env("PATHWAVE_MUTATION_FROM", from.to_string())
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let stdout = BufReader::new(child.stdout.take().unwrap());
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        for line in stdout.lines().map_while(Result::ok) {
            // libtest's "test mutation_worker ... " may precede the first report on its line.
            let Some(rest) = line.split_once("MUTANT ").map(|(_, r)| r) else {
                continue;
            };
            let (index, outcome) = rest.split_once(' ').unwrap_or((rest, ""));
            if tx.send((index.parse().unwrap(), outcome.to_string())).is_err() {
                break;
            }
        }
    });
    (child, rx)
}

/// Runs every input through workers, restarting after a crash or a hang; returns each input's fault and how many
/// inputs were read (rather than refused).
fn supervise(list: &Path, count: usize) -> (Vec<(usize, String)>, usize) {
    let mut faults = Vec::new();
    let mut read = 0;
    let mut next = 0;
    while next < count {
        let (mut child, reports) = start_worker(list, next);
        loop {
            match reports.recv_timeout(DEADLINE) {
                Ok((index, outcome)) => {
                    assert_eq!(index, next, "the worker reports inputs in order");
                    match outcome.strip_prefix("fault: ") {
                        Some(f) => faults.push((index, f.to_string())),
                        None if outcome == "read" => read += 1,
                        None if std::env::var_os("PATHWAVE_MUTATION_VERBOSE").is_some() => eprintln!("{outcome}"),
                        None => {}
                    }
                    next += 1;
                    if next == count {
                        break;
                    }
                }
                Err(mpsc::RecvTimeoutError::Timeout) => {
                    let _ = child.kill();
                    faults.push((next, format!("no result within {DEADLINE:?}")));
                    next += 1;
                    break;
                }
                Err(mpsc::RecvTimeoutError::Disconnected) => {
                    let status = child.wait().unwrap();
                    faults.push((
                        next,
                        format!("the process died ({status}): an abort or an allocation failure"),
                    ));
                    next += 1;
                    break;
                }
            }
        }
        let _ = child.kill();
        let _ = child.wait();
    }
    (faults, read)
}

#[test]
fn mutated_inputs_never_panic_abort_or_hang() {
    let dir = tempfile::tempdir().unwrap();
    let maps = write_maps(dir.path());
    let seeds = place(&dir.path().join("mutants"), seeds(maps));
    let list = dir.path().join("seeds.tsv");
    let mut file = std::fs::File::create(&list).unwrap();
    for seed in &seeds {
        let (path, folder) = (seed.path.display(), seed.folder.display());
        let (from, to) = (seed.inputs.start, seed.inputs.end);
        writeln!(file, "{}\t{path}\t{folder}\t{from}\t{to}", seed.reader.name()).unwrap();
    }
    drop(file);
    let start = Instant::now();
    let count = seeds.last().unwrap().inputs.end;
    let (faults, read) = supervise(&list, count);
    eprintln!(
        "{count} mutants of {} seeds in {:.1?}: {read} read, the rest refused; {} fault(s)",
        seeds.len(),
        start.elapsed(),
        faults.len()
    );
    // Each failing mutant is kept for a regression file in tests/regressions/.
    let kept = Path::new(env!("CARGO_TARGET_TMPDIR")).join("mutations");
    let report: Vec<String> = faults
        .iter()
        .map(|(i, f)| {
            let seed = seed_of(&seeds, *i);
            std::fs::create_dir_all(&kept).unwrap();
            let to = kept.join(mutant_path(seed, *i).file_name().unwrap());
            let what = write_mutant(seed, &std::fs::read(&seed.path).unwrap(), *i, &to);
            format!("{} ({}, {what}): {f}", to.display(), seed.reader.name())
        })
        .collect();
    assert!(
        faults.is_empty(),
        "{} mutant(s) failed:\n{}",
        faults.len(),
        report.join("\n")
    );
}

/// The child side of `mutated_inputs_never_panic_abort_or_hang`; does nothing when run on its own.
#[test]
#[ignore = "run by mutated_inputs_never_panic_abort_or_hang in a child process"]
fn mutation_worker() {
    let Ok(list) = std::env::var(LIST_VAR) else { return };
    let from: usize = std::env::var("PATHWAVE_MUTATION_FROM").unwrap().parse().unwrap();
    std::panic::set_hook(Box::new(|_| {}));
    let seeds: Vec<Seed> = std::fs::read_to_string(list)
        .unwrap()
        .lines()
        .map(|line| {
            let f: Vec<&str> = line.split('\t').collect();
            Seed {
                reader: Reader::parse(f[0]),
                path: f[1].into(),
                folder: f[2].into(),
                inputs: f[3].parse().unwrap()..f[4].parse().unwrap(),
            }
        })
        .collect();
    let mut bytes = (PathBuf::new(), Vec::new());
    for i in from..seeds.last().unwrap().inputs.end {
        let seed = seed_of(&seeds, i);
        if bytes.0 != seed.path {
            bytes = (seed.path.clone(), std::fs::read(&seed.path).unwrap());
        }
        let path = mutant_path(seed, i);
        write_mutant(seed, &bytes.1, i, &path);
        let fault = match std::panic::catch_unwind(|| read(seed.reader, &path)) {
            Ok(Ok(())) => "read".to_string(),
            Ok(Err(m)) if m.contains(&path.display().to_string()) => format!("refused {m}"),
            Ok(Err(m)) => format!("fault: the error does not name the file: {m}"),
            Err(payload) => format!("fault: panicked: {}", panic_message(&payload)),
        };
        let _ = std::fs::remove_file(&path);
        println!("MUTANT {i} {}", fault.replace('\n', " "));
    }
}

fn panic_message(payload: &Box<dyn std::any::Any + Send>) -> String {
    payload
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| payload.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "(non-string panic payload)".into())
}

/// Each crash the mutations found, as a small file in tests/regressions/ beside a `.expect` holding words its
/// error must contain: it must be refused, naming the file, within the deadline and without a panic. A
/// `film-*.exr` goes to `read_exr`, any other image to `Environment::load`. An abort would end this test's process
/// (a failure too); the memory limit of `prlimit` keeps a runaway allocation from taking the machine first.
#[test]
fn regression_files_are_refused_clearly() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/regressions");
    let mut checked = 0;
    for entry in std::fs::read_dir(&dir).unwrap() {
        let expect = entry.unwrap().path();
        if expect.extension().is_none_or(|e| e != "expect") {
            continue;
        }
        let needle = std::fs::read_to_string(&expect).unwrap().trim().to_string();
        let input = ["gltf", "glb", "hdr", "exr"]
            .iter()
            .map(|e| expect.with_extension(e))
            .find(|p| p.exists())
            .unwrap_or_else(|| panic!("{}: no input file beside it", expect.display()));
        let film = input.file_name().unwrap().to_string_lossy().starts_with("film-");
        let reader = match input.extension().unwrap().to_str().unwrap() {
            "gltf" | "glb" => Reader::Scene,
            "exr" if film => Reader::Exr,
            _ => Reader::Environment,
        };
        let (tx, rx) = mpsc::channel();
        let path = input.clone();
        std::thread::spawn(move || {
            let _ = tx.send(std::panic::catch_unwind(|| read(reader, &path)).map_err(|p| panic_message(&p)));
        });
        let name = input.display();
        match rx.recv_timeout(DEADLINE) {
            Err(_) => panic!("{name}: no result within {DEADLINE:?}"),
            Ok(Err(panic)) => panic!("{name}: panicked: {panic}"),
            Ok(Ok(Ok(()))) => panic!("{name}: was read; expected a refusal with '{needle}'"),
            Ok(Ok(Err(m))) => assert!(
                m.contains(&needle) && m.contains(&name.to_string()),
                "{name}: expected an error naming the file with '{needle}', got: {m}"
            ),
        }
        checked += 1;
    }
    assert!(checked > 0, "no regression files in {}", dir.display());
}
