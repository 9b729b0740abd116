//! The second lavapipe (Mesa >= 24.1 from the backports suite, which ci/lavapipe-rt.sh fetches beside the system's):
//! the driver ray-query tests run on. A test re-runs itself in a child process pointed at that driver's ICD file, so
//! the rest of its binary keeps the system's driver.
use std::path::PathBuf;
use std::process::Command;

const CHILD: &str = "PATHWAVE_TEST_RT_CHILD";

/// The backports lavapipe's ICD file (the script fetches it once; later calls only print the path).
pub fn icd() -> PathBuf {
    let script = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("ci/lavapipe-rt.sh");
    let o = Command::new("bash").arg(&script).output().expect("bash runs");
    assert!(
        o.status.success(),
        "ci/lavapipe-rt.sh failed: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    let path = PathBuf::from(String::from_utf8_lossy(&o.stdout).trim());
    assert!(path.is_file(), "{} is not a file", path.display());
    path
}

/// True in the child process, where the test named `test` runs its body on the ray-query driver; in the parent,
/// runs that child, fails the test if the child failed (or ran no test of that name), and returns false.
pub fn on_ray_query_driver(test: &str) -> bool {
    if std::env::var_os(CHILD).is_some() {
        return true;
    }
    let o = Command::new(std::env::current_exe().expect("the test binary's path"))
        .args([test, "--exact", "--nocapture", "--test-threads", "1"])
        .env("VK_DRIVER_FILES", icd())
        .env_remove("VK_ICD_FILENAMES")
        .env(CHILD, "1")
        .output()
        .expect("the test binary runs");
    let out = String::from_utf8_lossy(&o.stdout);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "on the ray-query lavapipe:\n{out}\n{err}");
    assert!(out.contains("1 passed"), "no test named {test} ran:\n{out}");
    eprint!("{err}");
    false
}
