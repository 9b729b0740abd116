//! pathwave's errors as Python exceptions: one class per kind of failure, with the command line's message.
use pyo3::create_exception;
use pyo3::exceptions::{PyException, PyKeyboardInterrupt, PyTypeError};
use pyo3::prelude::*;

create_exception!(
    pathwave,
    Error,
    PyException,
    "Every error pathwave raises, with the command line's message."
);
create_exception!(
    pathwave,
    InputError,
    Error,
    "A file that cannot be read or is not valid (scene, image, film file)."
);
create_exception!(
    pathwave,
    SettingsError,
    Error,
    "An option out of its range, or options that do not go together."
);
create_exception!(
    pathwave,
    LimitError,
    Error,
    "Work or memory past a limit (--max-memory, the device's memory)."
);
create_exception!(
    pathwave,
    DeviceError,
    Error,
    "The Vulkan device failed, or the validation layer reported errors."
);
create_exception!(pathwave, ShaderError, Error, "A user shader that does not compile.");
create_exception!(
    pathwave,
    Interrupted,
    PyKeyboardInterrupt,
    "Ctrl-C during a render: raised after the pass under way, with the samples done in `.film`."
);

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("Error", py.get_type::<Error>())?;
    m.add("InputError", py.get_type::<InputError>())?;
    m.add("SettingsError", py.get_type::<SettingsError>())?;
    m.add("LimitError", py.get_type::<LimitError>())?;
    m.add("DeviceError", py.get_type::<DeviceError>())?;
    m.add("ShaderError", py.get_type::<ShaderError>())?;
    m.add("Interrupted", py.get_type::<Interrupted>())?;
    Ok(())
}

/// The exception for a failure, chosen by the library error at the root of its chain; the message is the one the
/// command line prints after "error: ".
pub fn to_py(e: anyhow::Error) -> PyErr {
    let message = format!("{e:#}");
    let kind = e.chain().find_map(|c| c.downcast_ref::<pathwave::Error>());
    match kind {
        Some(pathwave::Error::Scene { .. } | pathwave::Error::Output { .. }) => InputError::new_err(message),
        Some(pathwave::Error::Settings(_)) => SettingsError::new_err(message),
        Some(pathwave::Error::Limit(_)) => LimitError::new_err(message),
        Some(pathwave::Error::Vulkan(_) | pathwave::Error::Validation { .. }) => DeviceError::new_err(message),
        Some(pathwave::Error::Shader(_)) => ShaderError::new_err(message),
        None => Error::new_err(message),
    }
}

/// A command-line parse error as Python reports bad arguments: an unknown option is a keyword the function does not
/// take (TypeError); anything else is a value out of range (SettingsError) with clap's message (possible values
/// included) without its "error: " prefix and usage hint.
pub fn from_clap(function: &str, e: clap::Error) -> PyErr {
    use clap::error::{ContextKind, ContextValue, ErrorKind};
    if e.kind() == ErrorKind::UnknownArgument {
        let name = match e.get(ContextKind::InvalidArg) {
            Some(ContextValue::String(s)) => crate::argv::keyword(s),
            _ => "?".to_string(),
        };
        return PyTypeError::new_err(format!("{function}() got an unexpected keyword argument '{name}'"));
    }
    let text = e.render().to_string();
    let text = text.split("\n\nFor more information").next().unwrap_or_default();
    SettingsError::new_err(text.trim().trim_start_matches("error: ").to_string())
}
