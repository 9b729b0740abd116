//! Python keywords as the command line's options (`max_depth=3` is `--max-depth=3`), so that both front ends share
//! one parser, its checks and its messages.
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyList, PyString, PyTuple};

/// The option a keyword names.
pub fn flag(keyword: &str) -> String {
    format!("--{}", keyword.replace('_', "-"))
}

/// The keyword an option names (`--max-depth=3` or `--max-depth <N>`: max_depth).
pub fn keyword(flag: &str) -> String {
    let name = flag.trim_start_matches('-');
    let name = name.split(['=', ' ']).next().unwrap_or(name);
    name.replace('-', "_")
}

/// The options that are flags (they take no value), of `render` and of `diff`.
fn is_flag(key: &str) -> bool {
    use clap::Args as _;
    static FLAGS: std::sync::OnceLock<Vec<String>> = std::sync::OnceLock::new();
    let flags = FLAGS.get_or_init(|| {
        let render = pathwave::cli::render::RenderArgs::augment_args(clap::Command::new("render"));
        let diff = pathwave::cli::film::CompareOptions::augment_args(clap::Command::new("diff"));
        (render.get_arguments().chain(diff.get_arguments()))
            .filter(|a| !a.get_action().takes_values())
            .filter_map(|a| a.get_long().map(|l| l.replace('-', "_")))
            .collect()
    });
    flags.iter().any(|f| f == key)
}

/// Appends `key=value` as the command line spells it: for a flag, True is the flag alone and False leaves it out;
/// None leaves any option out; `size` (w, h) is WxH, `samples` (a, b) is A..B, other sequences are comma-separated
/// (a point, a colour, AOV names; an empty one leaves the option out), paths are their text, and everything else
/// is its `str`.
pub fn push(out: &mut Vec<String>, key: &str, value: &Bound<'_, PyAny>) -> PyResult<()> {
    if value.is_none() {
        return Ok(());
    }
    if let Ok(b) = value.cast::<PyBool>() {
        if !is_flag(key) {
            return Err(crate::errors::SettingsError::new_err(format!(
                "{key}={}: {} takes a value, not True or False",
                if b.is_true() { "True" } else { "False" },
                flag(key)
            )));
        }
        if b.is_true() {
            out.push(flag(key));
        }
        return Ok(());
    }
    let sequence = value.is_instance_of::<PyTuple>() || value.is_instance_of::<PyList>();
    if sequence && value.len()? == 0 {
        return Ok(());
    }
    let text = if sequence {
        let items: Vec<String> = value.try_iter()?.map(|item| text(&item?)).collect::<PyResult<_>>()?;
        match (key, &items[..]) {
            ("size", [w, h]) => format!("{w}x{h}"),
            ("samples", [a, b]) => format!("{a}..{b}"),
            _ => items.join(","),
        }
    } else {
        text(value)?
    };
    out.push(format!("{}={text}", flag(key)));
    Ok(())
}

/// A value's text: a str as it is, a path-like through os.fspath, anything else through str().
fn text(value: &Bound<'_, PyAny>) -> PyResult<String> {
    if let Ok(s) = value.cast::<PyString>() {
        return s.extract::<String>();
    }
    if value.hasattr("__fspath__")? {
        let path: std::path::PathBuf = value.extract()?;
        return Ok(path.display().to_string());
    }
    value.str()?.extract::<String>()
}

/// Every keyword of `kwargs` in turn, refusing those in `refused` with why.
pub fn push_all(
    out: &mut Vec<String>,
    function: &str,
    kwargs: Option<&Bound<'_, PyDict>>,
    refused: &[(&str, &str)],
) -> PyResult<()> {
    let Some(kwargs) = kwargs else {
        return Ok(());
    };
    for (k, v) in kwargs.iter() {
        let key: String = k.extract()?;
        if let Some((_, why)) = refused.iter().find(|(name, _)| *name == key) {
            return Err(pyo3::exceptions::PyTypeError::new_err(format!(
                "{function}() does not take '{key}': {why}"
            )));
        }
        push(out, &key, &v)?;
    }
    Ok(())
}
