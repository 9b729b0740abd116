//! The Python helper that runs Mitsuba and Embree (compare.py, carried in the binary) and the float files they share.
use super::err;
use crate::error::Error;
use serde_json::{json, Value};
use std::io::{BufRead, BufReader, Write};
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdin, ChildStdout, Command, Stdio};

const HELPER: &str = include_str!("../compare.py");

/// The Python process that runs Mitsuba and Embree: one JSON request per line each way.
pub(super) struct Helper {
    child: Child,
    stdin: ChildStdin,
    stdout: BufReader<ChildStdout>,
    pub(super) dir: tempfile::TempDir,
}

impl Helper {
    pub(super) fn start(python: &Path) -> Result<Helper, Error> {
        let dir = tempfile::tempdir().map_err(err)?;
        let script = dir.path().join("compare.py");
        std::fs::write(&script, HELPER).map_err(err)?;
        let mut child = Command::new(python)
            .arg("-u")
            .arg(&script)
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .spawn()
            .map_err(|e| err(format!("cannot run {}: {e}", python.display())))?;
        let stdin = child.stdin.take().ok_or_else(|| err("no stdin"))?;
        let stdout = BufReader::new(child.stdout.take().ok_or_else(|| err("no stdout"))?);
        let mut h = Helper {
            child,
            stdin,
            stdout,
            dir,
        };
        h.read().map_err(|e| {
            err(format!(
                "{} could not start the helper (it needs numpy): {e}",
                python.display()
            ))
        })?;
        Ok(h)
    }

    pub(super) fn path(&self, name: &str) -> PathBuf {
        self.dir.path().join(name)
    }

    fn read(&mut self) -> Result<Value, Error> {
        let mut line = String::new();
        self.stdout.read_line(&mut line).map_err(err)?;
        if line.is_empty() {
            return Err(err("the Python helper exited (its message is above)"));
        }
        serde_json::from_str(&line).map_err(|e| err(format!("helper said {line:?}: {e}")))
    }

    pub(super) fn call(&mut self, request: Value) -> Result<Value, Error> {
        writeln!(self.stdin, "{request}").map_err(err)?;
        self.stdin.flush().map_err(err)?;
        let r = self.read()?;
        if r["ok"] != json!(true) {
            return Err(err(r["error"].as_str().unwrap_or("the helper failed")));
        }
        Ok(r)
    }

    pub(super) fn f64(r: &Value, key: &str) -> Result<f64, Error> {
        r[key].as_f64().ok_or_else(|| err(format!("helper reply lacks {key}")))
    }
}

impl Drop for Helper {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

pub(super) fn write_f32(path: &Path, data: &[f32]) -> Result<(), Error> {
    std::fs::write(path, bytemuck::cast_slice(data)).map_err(err)
}

pub(super) fn read_f32(path: &Path) -> Result<Vec<f32>, Error> {
    let bytes = std::fs::read(path).map_err(err)?;
    Ok(bytes
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect())
}
