//! The render farm: a Slurm job array of parts and a merge job (examples/slurm/submit.sh on the one-node cluster
//! of ci/slurm.sh) must give the very bytes of one `--film-stats` render, and `--part auto/N` must read each
//! scheduler's index variable.
#![cfg(unix)]

mod common;

use std::fs::File;
use std::os::unix::process::CommandExt;
use std::path::{Path, PathBuf};
use std::process::{Command, ExitStatus, Stdio};
use std::time::{Duration, Instant};

const SCHEDULER_INDEX_VARS: [&str; 3] = [
    "SLURM_ARRAY_TASK_ID",
    "JOB_COMPLETION_INDEX",
    "AWS_BATCH_JOB_ARRAY_INDEX",
];

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

struct Ran {
    status: ExitStatus,
    stdout: String,
    stderr: String,
}

/// Runs `cmd` with no input, its output in files (a daemon it leaves behind cannot then hold a pipe open and hang
/// the test), and kills its whole process group if it takes longer than `limit`.
fn run(mut cmd: Command, limit: Duration, what: &str) -> Result<Ran, String> {
    let dir = tempfile::tempdir().map_err(|e| e.to_string())?;
    let (out_path, err_path) = (dir.path().join("stdout"), dir.path().join("stderr"));
    let out = File::create(&out_path).map_err(|e| e.to_string())?;
    let err = File::create(&err_path).map_err(|e| e.to_string())?;
    cmd.stdin(Stdio::null()).stdout(out).stderr(err).process_group(0);
    let mut child = cmd.spawn().map_err(|e| format!("{what}: cannot start: {e}"))?;
    let read = |p: &Path| String::from_utf8_lossy(&std::fs::read(p).unwrap_or_default()).into_owned();
    let deadline = Instant::now() + limit;
    let status = loop {
        if let Some(status) = child.try_wait().map_err(|e| e.to_string())? {
            break status;
        }
        if Instant::now() >= deadline {
            // The group too: scripts wait in sleep, sbatch or scontrol, which killing bash alone would leave running.
            let _ = Command::new("kill")
                .args(["-s", "KILL", "--", &format!("-{}", child.id())])
                .status();
            let _ = child.kill();
            let _ = child.wait();
            return Err(format!(
                "{what}: still running after {limit:?}, killed; stderr:\n{}",
                read(&err_path)
            ));
        }
        std::thread::sleep(Duration::from_millis(100));
    };
    Ok(Ran {
        status,
        stdout: read(&out_path),
        stderr: read(&err_path),
    })
}

/// Like `run`, but the command must succeed.
fn run_ok(cmd: Command, limit: Duration, what: &str) -> Ran {
    let ran = run(cmd, limit, what).unwrap_or_else(|e| panic!("{e}"));
    assert!(
        ran.status.success(),
        "{what} failed ({}):\n{}{}",
        ran.status,
        ran.stdout,
        ran.stderr
    );
    ran
}

fn slurm_sh(state: &Path, action: &str) -> Command {
    let mut c = Command::new("bash");
    c.arg(repo().join("ci/slurm.sh"))
        .arg(action)
        .current_dir(repo())
        .env("PATHWAVE_SLURM_DIR", state);
    c
}

/// Stops the daemons however the test ends: a panic must not leave a cluster running.
struct Slurm {
    state: PathBuf,
}

impl Drop for Slurm {
    fn drop(&mut self) {
        match run(
            slurm_sh(&self.state, "stop"),
            Duration::from_secs(120),
            "ci/slurm.sh stop",
        ) {
            Ok(r) if r.status.success() => {}
            Ok(r) => eprintln!("ci/slurm.sh stop failed ({}):\n{}{}", r.status, r.stdout, r.stderr),
            Err(e) => eprintln!("{e}"),
        }
    }
}

fn bytes(path: &Path) -> Vec<u8> {
    std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

#[test]
fn slurm_array_and_merge_equal_one_render() {
    // CI, and the README's test command (ci/test.sh), must run it; a bare `cargo test` may skip it.
    let ci = std::env::var("CI").as_deref() == Ok("true") || std::env::var("PATHWAVE_FARM_TEST").as_deref() == Ok("1");
    let tmp = tempfile::tempdir().unwrap();
    // A state directory of its own, so the test neither uses nor stops a cluster someone started by hand.
    let slurm = Slurm {
        state: tmp.path().join("slurm"),
    };

    let start = || {
        let mut start = slurm_sh(&slurm.state, "start");
        if !ci {
            // Installing system packages is CI's business, not a side effect of `cargo test` on someone's machine.
            start.env("PATHWAVE_SLURM_NO_INSTALL", "1");
        }
        run(
            start,
            Duration::from_secs(if ci { 900 } else { 120 }),
            "ci/slurm.sh start",
        )
    };
    // Once, in a fresh clone's CI run, start said slurmctld had exited while its log showed it running; it never
    // happened again in 20 starts, loaded or not. A second try (start stops a partial cluster first) keeps that
    // from failing the suite, and the first failure is printed.
    let started = match start() {
        Ok(r) if r.status.success() => Ok(r),
        first => {
            match &first {
                Ok(r) => eprintln!(
                    "ci/slurm.sh start failed once ({}), trying again:\n{}",
                    r.status, r.stderr
                ),
                Err(e) => eprintln!("ci/slurm.sh start failed once, trying again: {e}"),
            }
            start()
        }
    };
    let started = match started {
        Ok(r) if r.status.success() => r,
        failed => {
            let why = match failed {
                Ok(r) => format!("{}:\n{}", r.status, r.stderr),
                Err(e) => e,
            };
            assert!(!ci, "CI must run the farm test, but Slurm did not start: {why}");
            eprintln!("skipping: Slurm could not be started here (`bash ci/slurm.sh start` installs it): {why}");
            return;
        }
    };
    let conf = started
        .stdout
        .lines()
        .find_map(|l| l.strip_prefix("export SLURM_CONF="))
        .unwrap_or_else(|| panic!("ci/slurm.sh start printed no SLURM_CONF:\n{}", started.stdout))
        .to_string();

    let farm = tmp.path().join("farm.exr");
    let mut submit = Command::new("bash");
    submit
        .arg(repo().join("examples/slurm/submit.sh"))
        .arg("--wait")
        .arg(common::cornell())
        .arg(&farm)
        .args(["4", "32", "--size", "48x36"])
        .current_dir(tmp.path())
        .env("PATHWAVE", env!("CARGO_BIN_EXE_pathwave"))
        .env("SLURM_CONF", &conf)
        .env("PATHWAVE_SUBMIT_TIMEOUT", "600");
    // The jobs inherit the submitter's environment: give them the test binary's settings (validation).
    for (k, v) in common::pathwave_cli().get_envs() {
        match v {
            Some(v) => submit.env(k, v),
            None => submit.env_remove(k),
        };
    }
    run_ok(submit, Duration::from_secs(660), "examples/slurm/submit.sh --wait");
    for i in 0..4 {
        let part = tmp.path().join(format!("farm.exr.parts/part-{i}.exr"));
        assert!(part.is_file(), "{} is missing", part.display());
    }

    let single = tmp.path().join("single.exr");
    let mut render = common::pathwave_cli();
    render
        .arg("render")
        .arg(common::cornell())
        .args(["--spp", "32", "--size", "48x36", "--film-stats", "-o"])
        .arg(&single);
    run_ok(render, Duration::from_secs(600), "pathwave render (the single image)");

    let (farm_bytes, single_bytes) = (bytes(&farm), bytes(&single));
    assert!(
        farm_bytes == single_bytes,
        "the merged farm render ({} bytes) differs from the single render ({} bytes)",
        farm_bytes.len(),
        single_bytes.len()
    );
}

#[test]
fn part_auto_reads_each_schedulers_index() {
    let tmp = tempfile::tempdir().unwrap();
    let render = |out: &Path, extra: &[&str], var: Option<&str>| {
        let mut c = common::pathwave_cli();
        for v in SCHEDULER_INDEX_VARS {
            c.env_remove(v);
        }
        if let Some(v) = var {
            c.env(v, "2");
        }
        c.arg("render")
            .arg(common::cornell())
            .args(["--size", "48x36"])
            .args(extra)
            .arg("-o")
            .arg(out);
        run(
            c,
            Duration::from_secs(600),
            &format!("pathwave render {extra:?} with {var:?}=2"),
        )
        .unwrap_or_else(|e| panic!("{e}"))
    };
    let check = |r: Ran, what: &str| assert!(r.status.success(), "{what} failed ({}):\n{}", r.status, r.stderr);

    // Part 2 of 4 of 32 samples per pixel: samples 16 to 23 (--samples takes no --spp).
    let part = ["--spp", "32", "--part", "auto/4"];
    let reference = tmp.path().join("samples-16-24.exr");
    check(render(&reference, &["--samples", "16..24"], None), "--samples 16..24");
    let film = |path: &Path| {
        let file = pathwave::output::read_film(path).unwrap_or_else(|e| panic!("{e}"));
        let (exact, meta) = file.stats.expect("film statistics");
        (file.mean, exact, meta)
    };
    let (mean, exact, _) = film(&reference);
    for var in SCHEDULER_INDEX_VARS {
        let out = tmp.path().join(format!("{var}.exr"));
        check(render(&out, &part, Some(var)), var);
        // The same samples, so the same sums; the file also records which part it is, which --samples does not.
        let (part_mean, part_exact, meta) = film(&out);
        assert!(
            part_exact == exact && part_mean == mean,
            "--part auto/4 with {var}=2 differs from --samples 16..24"
        );
        assert_eq!(meta.samples, vec![16..24]);
        let part = meta.part.expect("a part");
        assert_eq!((part.index, part.count, part.spp), (2, 4, 32), "{var}=2");
    }

    // With no scheduler's variable there is no part to take: an error, and no file.
    let out = tmp.path().join("none.exr");
    let r = render(&out, &part, None);
    assert!(
        !r.status.success(),
        "--part auto/4 with no scheduler variable set succeeded"
    );
    assert!(
        !out.exists(),
        "--part auto/4 with no scheduler variable set wrote {}",
        out.display()
    );
}
