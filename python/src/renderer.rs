//! `pathwave.Renderer`: a Vulkan device and the scene last uploaded to it, rendering as `pathwave render` does, with
//! the GIL released, progress through a callback, and Ctrl-C ending the render after its pass.
use crate::film::Film;
use crate::scene::Scene;
use crate::{argv, errors};
use pathwave::cli::render::RenderArgs;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Mutex;

/// Options that shape what is uploaded (the camera and the environment), beside the load's own: a render that
/// changes one uploads the scene again.
const UPLOADED: [&str; 10] = [
    "camera",
    "eye",
    "target",
    "up",
    "yfov",
    "orbit",
    "env",
    "env_color",
    "env_intensity",
    "env_rotation",
];

/// Keywords `render` refuses, and where they belong instead.
const REFUSED: [(&str, &str); 16] = [
    ("output", "render returns a Film; Film.save(path) writes it"),
    ("frames", "render one Film per time (Scene.load(time=...))"),
    ("fps", "render one Film per time (Scene.load(time=...))"),
    ("resume", "render one Film per time (Scene.load(time=...))"),
    ("part", "give samples=(a, b) instead"),
    ("watch", "not available from Python"),
    ("shader_dir", "not available from Python"),
    (
        "aov_files",
        "Film.save writes AOV files beside PNG outputs; EXRs hold them as layers",
    ),
    ("variant", "it is an option of Scene.load"),
    ("time", "it is an option of Scene.load"),
    ("animation", "it is an option of Scene.load"),
    ("shutter", "it is an option of Scene.load"),
    ("max_memory", "it is an option of Scene.load"),
    ("max_texture_pixels", "it is an option of Scene.load"),
    ("device", "it is an option of Renderer"),
    ("traversal", "it is an option of Renderer"),
];

/// The scene on the device, and what it was uploaded from.
struct Uploaded {
    renderer: pathwave::Renderer,
    key: Key,
}

#[derive(Clone, PartialEq)]
struct Key {
    scene: u64,
    /// The options of `UPLOADED` the render gave.
    shaping: Vec<String>,
    fingerprint: bool,
}

#[pyclass(module = "pathwave._pathwave", frozen)]
pub struct Renderer {
    /// --device and --traversal as given.
    options: Vec<String>,
    state: Mutex<Option<Uploaded>>,
}

#[pymethods]
impl Renderer {
    /// A renderer on `device` (an index or part of a name, as `pathwave info --devices` lists them; default: the
    /// first GPU, else lavapipe), tracing with `traversal` ("compute", "ray-query" or "auto").
    #[new]
    #[pyo3(signature = (device=None, *, traversal=None))]
    fn new(device: Option<Bound<'_, PyAny>>, traversal: Option<Bound<'_, PyAny>>) -> PyResult<Self> {
        let mut options = Vec::new();
        if let Some(d) = device {
            argv::push(&mut options, "device", &d)?;
        }
        if let Some(t) = traversal {
            argv::push(&mut options, "traversal", &t)?;
        }
        // Checked now, with a scene path that is never read.
        RenderArgs::parse_from(options.iter().cloned().chain(["--".into(), "-".into()]))
            .map_err(|e| errors::from_clap("Renderer", e))?;
        Ok(Renderer {
            options,
            state: Mutex::new(None),
        })
    }

    /// Renders `scene` as `pathwave render` does with the same options; see the .pyi for them.
    #[pyo3(signature = (scene, *, spp=None, size=None, seed=None, camera=None, progress=None, **settings))]
    #[allow(clippy::too_many_arguments)]
    fn render(
        &self,
        py: Python<'_>,
        scene: PyRef<'_, Scene>,
        spp: Option<Bound<'_, PyAny>>,
        size: Option<Bound<'_, PyAny>>,
        seed: Option<Bound<'_, PyAny>>,
        camera: Option<Bound<'_, PyAny>>,
        progress: Option<Py<PyAny>>,
        settings: Option<&Bound<'_, PyDict>>,
    ) -> PyResult<Film> {
        let mut given = self.options.clone();
        for (key, value) in [("spp", &spp), ("size", &size), ("seed", &seed)] {
            if let Some(v) = value {
                argv::push(&mut given, key, v)?;
            }
        }
        let camera_index = camera_options(&mut given, camera.as_ref())?;
        argv::push_all(&mut given, "render", settings, &REFUSED)?;
        // A camera index given here replaces the one the scene was loaded with.
        let scene_argv = (scene.argv.iter()).filter(|a| !(camera_index && a.starts_with("--camera=")));
        let all: Vec<String> = scene_argv.chain(&given).cloned().collect();
        let path_text = scene.path.display().to_string();
        let args = RenderArgs::parse_from(all.iter().cloned().chain(["--".into(), path_text.clone()]))
            .map_err(|e| errors::from_clap("render", e))?;
        args.sample_range().map_err(errors::to_py)?;
        let key = Key {
            scene: scene.id,
            shaping: (all.iter())
                .filter(|a| UPLOADED.iter().any(|k| argv::keyword(a) == *k))
                .cloned()
                .collect(),
            fingerprint: args.film_stats(),
        };
        let loaded_camera = scene.loaded.rig.camera_choice;
        let total = args.spp;
        let stop = AtomicBool::new(false);
        // What the progress callback or a signal handler raised at a pass's end (Python runs a signal's handler
        // at the next bytecode, which may be the callback's).
        let stopped: Mutex<Option<PyErr>> = Mutex::new(None);
        let on_pass = &mut |done: u32| {
            let outcome = Python::attach(|py| -> PyResult<()> {
                if let Some(callback) = &progress {
                    callback.call1(py, (done, total))?;
                }
                // Python's handlers run here: the default one raises KeyboardInterrupt.
                py.check_signals()
            });
            if let Err(why) = outcome {
                stop.store(true, Ordering::SeqCst);
                *stopped.lock().unwrap_or_else(|p| p.into_inner()) = Some(why);
            }
        };
        let loaded = &scene.loaded;
        let rendered = py.detach(|| -> anyhow::Result<_> {
            // Found before rendering, so a missing library costs no render.
            let denoiser = args.denoiser()?;
            let mut state = self.state.lock().unwrap_or_else(|p| p.into_inner());
            let renderer = upload(&mut state, &args, loaded, loaded_camera, key)?;
            let settings = args.render_settings(loaded)?;
            pathwave::cli::shot::render_shot(renderer, &settings, &args, denoiser.as_ref(), on_pass, &stop)
        });
        let rendered = rendered.map_err(errors::to_py)?;
        for w in &rendered.warnings {
            warn(py, &format!("{}: {w}", scene.path.display()))?;
        }
        let film = Film::rendered(all, path_text, args.common.time.unwrap_or(0.0), rendered);
        let stopped = stopped.into_inner().unwrap_or_else(|p| p.into_inner());
        finish(py, film, stopped, total)
    }

    fn __repr__(&self) -> String {
        let state = self.state.lock().unwrap_or_else(|p| p.into_inner());
        match &*state {
            Some(u) => format!("Renderer('{}')", u.renderer.context().device_name()),
            None => format!("Renderer({})", self.options.join(" ")),
        }
    }
}

/// The film, or what stopped the render at a pass's end: a KeyboardInterrupt (Ctrl-C) becomes `Interrupted`
/// holding the film (a signal during the last pass leaves a complete one; before the first pass ended, none);
/// anything else the progress callback raised is raised as it is.
fn finish(py: Python<'_>, film: Film, stopped: Option<PyErr>, total: u32) -> PyResult<Film> {
    match stopped {
        None => Ok(film),
        Some(e) if e.is_instance_of::<pyo3::exceptions::PyKeyboardInterrupt>(py) => {
            let message = format!(
                "interrupted: the film holds {} of {} samples per pixel",
                film.spp(),
                total
            );
            let err = errors::Interrupted::new_err(message);
            let film = match film.spp() > 0 {
                true => Some(Py::new(py, film)?),
                false => None,
            };
            err.value(py).setattr("film", film)?;
            err.set_cause(py, Some(e));
            Err(err)
        }
        Some(e) => Err(e),
    }
}

/// `camera=`: a file camera's index, or a mapping of eye, target, up, yfov and orbit (the command line's camera
/// options). Returns whether it named an index.
fn camera_options(given: &mut Vec<String>, camera: Option<&Bound<'_, PyAny>>) -> PyResult<bool> {
    let Some(camera) = camera.filter(|c| !c.is_none()) else {
        return Ok(false);
    };
    if let Ok(d) = camera.cast::<PyDict>() {
        for (k, v) in d.iter() {
            let key: String = k.extract()?;
            if !["eye", "target", "up", "yfov", "orbit"].contains(&key.as_str()) {
                return Err(pyo3::exceptions::PyTypeError::new_err(format!(
                    "camera: '{key}' is not one of eye, target, up, yfov, orbit"
                )));
            }
            argv::push(given, &key, &v)?;
        }
        return Ok(false);
    }
    argv::push(given, "camera", camera)?;
    Ok(true)
}

/// The renderer for this render: the one already holding the scene as asked, the same device with the scene
/// uploaded again, or a new one.
fn upload<'a>(
    state: &'a mut Option<Uploaded>,
    args: &RenderArgs,
    loaded: &pathwave::Scene,
    loaded_camera: Option<usize>,
    key: Key,
) -> anyhow::Result<&'a mut pathwave::Renderer> {
    if state.as_ref().is_some_and(|u| u.key == key) {
        return Ok(&mut state.as_mut().expect("checked").renderer);
    }
    let common = &args.common;
    // The file's camera is chosen while loading: another index reads it again.
    let mut scene = match common.camera == loaded_camera {
        true => loaded.clone(),
        false => common.limits.load(&common.scene, common.camera)?,
    };
    common.aim(&mut scene)?;
    common.pose(&mut scene, common.time.unwrap_or(0.0))?;
    scene.environment = common.env.environment(common.limits.max_texture_pixels)?;
    match state {
        Some(u) => {
            u.renderer.set_fingerprint(key.fingerprint);
            u.renderer.set_scene(&scene)?;
            u.key = key;
        }
        None => {
            let renderer = pathwave::cli::render::renderer_for(args, &scene)?;
            *state = Some(Uploaded { renderer, key });
        }
    }
    Ok(&mut state.as_mut().expect("just set").renderer)
}

/// A warning through Python's warnings module, so that notebooks and pytest show it.
pub fn warn(py: Python<'_>, message: &str) -> PyResult<()> {
    let warnings = py.import("warnings")?;
    // Level 1 is the innermost Python frame: the line that called into pathwave.
    warnings.call_method1("warn", (message, py.get_type::<pyo3::exceptions::PyUserWarning>(), 1))?;
    Ok(())
}

/// The Vulkan devices, as `pathwave info --devices` lists them: their index is what Renderer(device=) takes.
#[pyfunction]
pub fn devices(py: Python<'_>) -> PyResult<Bound<'_, PyList>> {
    let list = py
        .detach(pathwave::vk::list_devices)
        .map_err(|e| errors::to_py(e.into()))?;
    let out = PyList::empty(py);
    for d in list {
        let item = PyDict::new(py);
        item.set_item("index", d.index)?;
        item.set_item("name", &d.name)?;
        item.set_item("kind", &d.kind)?;
        item.set_item("driver", &d.driver)?;
        item.set_item("ray_queries", d.ray_query)?;
        out.append(item)?;
    }
    Ok(out)
}
