//! `pathwave.Scene`: a glTF file read once with the loader's limits; each render aims, poses and lights a copy of it
//! as its options ask.
use crate::{argv, errors};
use pathwave::cli::render::RenderArgs;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::path::PathBuf;
use std::sync::atomic::{AtomicU64, Ordering};

/// Tells loads apart, so a renderer knows when a scene is new to it.
static LOADS: AtomicU64 = AtomicU64::new(0);

#[pyclass(module = "pathwave._pathwave", frozen)]
pub struct Scene {
    pub path: PathBuf,
    /// The options it was loaded with, as the command line spells them.
    pub argv: Vec<String>,
    /// As read, before a render's camera, pose and environment.
    pub loaded: pathwave::Scene,
    pub id: u64,
}

impl Scene {
    /// `render`'s options for this scene with `more` (a render's own), checked by the command line's parser.
    pub fn args(&self, function: &str, more: &[String]) -> PyResult<RenderArgs> {
        let path = self.path.display().to_string();
        let all = (self.argv.iter().chain(more)).cloned().chain(["--".to_string(), path]);
        RenderArgs::parse_from(all).map_err(|e| errors::from_clap(function, e))
    }
}

#[pymethods]
impl Scene {
    /// Reads a glTF (.gltf or .glb) file as `pathwave render` does, with its limits; see the .pyi for the options.
    #[staticmethod]
    #[pyo3(signature = (path, *, variant=None, time=None, animation=None, shutter=None, camera=None, max_memory=None,
        max_texture_pixels=None, allow_outside_paths=false, strict=false))]
    #[allow(clippy::too_many_arguments)]
    fn load(
        py: Python<'_>,
        path: PathBuf,
        variant: Option<Bound<'_, PyAny>>,
        time: Option<Bound<'_, PyAny>>,
        animation: Option<Bound<'_, PyAny>>,
        shutter: Option<Bound<'_, PyAny>>,
        camera: Option<Bound<'_, PyAny>>,
        max_memory: Option<Bound<'_, PyAny>>,
        max_texture_pixels: Option<Bound<'_, PyAny>>,
        allow_outside_paths: bool,
        strict: bool,
    ) -> PyResult<Scene> {
        let mut options = Vec::new();
        let given = [
            ("variant", variant),
            ("time", time),
            ("animation", animation),
            ("shutter", shutter),
            ("camera", camera),
            ("max_memory", max_memory),
            ("max_texture_pixels", max_texture_pixels),
        ];
        for (key, value) in &given {
            if let Some(v) = value {
                argv::push(&mut options, key, v)?;
            }
        }
        for (key, on) in [("allow_outside_paths", allow_outside_paths), ("strict", strict)] {
            if on {
                options.push(argv::flag(key));
            }
        }
        let mut scene = Scene {
            path,
            argv: options,
            loaded: pathwave::Scene::default(),
            id: LOADS.fetch_add(1, Ordering::Relaxed),
        };
        let args = scene.args("Scene.load", &[])?;
        let common = &args.common;
        scene.loaded = py
            .detach(|| -> anyhow::Result<pathwave::Scene> {
                let loaded = common.limits.load(&common.scene, common.camera)?;
                // An animation that is not there is refused now rather than at the first render.
                common.pose_time(&loaded, common.time.unwrap_or(0.0))?;
                Ok(loaded)
            })
            .map_err(errors::to_py)?;
        Ok(scene)
    }

    /// The file it was read from.
    #[getter]
    fn path(&self) -> PathBuf {
        self.path.clone()
    }

    /// What `pathwave info` reports (packing the scene as a renderer would), with its counts as numbers.
    fn info<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let s = &self.loaded;
        let rule = pathwave::cli::info::instancing_rule();
        let report = py
            .detach(|| pathwave::render::gpu_scene::describe(s, rule))
            .map_err(|e| errors::to_py(e.into()))?;
        let d = PyDict::new(py);
        d.set_item("path", &s.path)?;
        d.set_item("triangles", s.triangle_count())?;
        // Materials as the file holds them: the loader's default material is not one.
        d.set_item("materials", s.materials.len().saturating_sub(1))?;
        d.set_item("cameras", s.camera_count)?;
        d.set_item("punctual_lights", s.punctual.len())?;
        d.set_item("textures", s.textures.len())?;
        d.set_item("images", s.images.len())?;
        d.set_item("variants", s.variants.clone())?;
        let animations: Vec<String> = s.rig.animations.iter().map(|a| a.name.clone()).collect();
        d.set_item("animations", animations)?;
        d.set_item("extensions_used", s.extensions_used.clone())?;
        d.set_item("warnings", s.warnings.clone())?;
        let lines = PyDict::new(py);
        for (label, text) in &report.lines {
            lines.set_item(*label, text)?;
        }
        d.set_item("report", lines)?;
        Ok(d)
    }

    fn __repr__(&self) -> String {
        format!(
            "Scene('{}', {} triangles, {} materials)",
            self.path.display(),
            self.loaded.triangle_count(),
            self.loaded.materials.len().saturating_sub(1)
        )
    }
}
