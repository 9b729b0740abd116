//! `pathwave.Film`: a render's result (or a film file read back) as numpy arrays, saved exactly as `pathwave render`
//! writes it.
use crate::errors;
use numpy::{PyArray1, PyArrayMethods};
use pathwave::cli::render::{RenderArgs, Shot};
use pathwave::cli::shot::Rendered;
use pathwave::output::{self, Aov, Channel, FilmFile, Samples};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::path::PathBuf;

enum Source {
    /// A render: its options as the command line spells them, its scene's path, the time it was posed at, and
    /// what it gave.
    Rendered {
        argv: Vec<String>,
        scene: String,
        aovs: Vec<Aov>,
        time: f32,
        rendered: Box<Rendered>,
    },
    /// A film file (EXR) read back.
    File(Box<FilmFile>),
}

#[pyclass(module = "pathwave._pathwave", frozen)]
pub struct Film {
    source: Source,
}

impl Film {
    pub fn rendered(argv: Vec<String>, scene: String, time: f32, rendered: Rendered) -> Film {
        let aovs = parse(&argv, &scene).map(|a| a.aovs().to_vec()).unwrap_or_default();
        Film {
            source: Source::Rendered {
                argv,
                scene,
                aovs,
                time,
                rendered: Box::new(rendered),
            },
        }
    }

    pub fn size(&self) -> (u32, u32) {
        match &self.source {
            Source::Rendered { rendered, .. } => (rendered.film.width, rendered.film.height),
            Source::File(f) => (f.width, f.height),
        }
    }

    pub fn spp(&self) -> u64 {
        match &self.source {
            Source::Rendered { rendered, .. } => rendered.film.spp as u64,
            Source::File(f) => f.stats.as_ref().map_or(0, |(film, _)| film.spp()),
        }
    }

    /// The film as `diff` reads it from a file: the image, and the exact film with its metadata when kept.
    pub fn as_film_file(&self) -> FilmFile {
        match &self.source {
            Source::Rendered { rendered, .. } => FilmFile {
                width: rendered.film.width,
                height: rendered.film.height,
                mean: rendered.pixels.clone(),
                stats: rendered.film.exact.clone().zip(rendered.meta.clone()),
            },
            Source::File(f) => FilmFile {
                width: f.width,
                height: f.height,
                mean: f.mean.clone(),
                stats: f.stats.clone(),
            },
        }
    }

    fn exact(&self) -> Option<&pathwave::render::film::ExactFilm> {
        match &self.source {
            Source::Rendered { rendered, .. } => rendered.film.exact.as_ref(),
            Source::File(f) => f.stats.as_ref().map(|(film, _)| film),
        }
    }
}

/// A film's options (and its scene's path) parsed again.
fn parse(argv: &[String], scene: &str) -> PyResult<RenderArgs> {
    let all = argv.iter().cloned().chain(["--".to_string(), scene.to_string()]);
    RenderArgs::parse_from(all).map_err(|e| errors::from_clap("Film.save", e))
}

/// Row-major pixels as an array of shape (height, width, channels), or (height, width) for one channel.
fn image<'py, T: numpy::Element>(
    py: Python<'py>,
    (w, h): (u32, u32),
    channels: usize,
    data: Vec<T>,
) -> PyResult<Bound<'py, PyAny>> {
    let flat = PyArray1::from_vec(py, data);
    let shaped = match channels {
        1 => flat.reshape([h as usize, w as usize])?.into_any(),
        c => flat.reshape([h as usize, w as usize, c])?.into_any(),
    };
    Ok(shaped)
}

fn rgb<'py, T: numpy::Element + Copy>(
    py: Python<'py>,
    size: (u32, u32),
    pixels: &[[T; 3]],
) -> PyResult<Bound<'py, PyAny>> {
    image(py, size, 3, pixels.iter().flatten().copied().collect())
}

/// An AOV's channels as one array: float32, or uint32 for ids and sample counts.
fn channels<'py>(py: Python<'py>, size: (u32, u32), channels: &[Channel]) -> PyResult<Bound<'py, PyAny>> {
    let n = channels.len();
    let pixels = (size.0 * size.1) as usize;
    match channels.first().map(|c| &c.samples) {
        Some(Samples::U32(_)) => {
            let mut data = vec![0u32; pixels * n];
            for (c, ch) in channels.iter().enumerate() {
                if let Samples::U32(v) = &ch.samples {
                    (0..pixels).for_each(|i| data[i * n + c] = v[i]);
                }
            }
            image(py, size, n, data)
        }
        _ => {
            let mut data = vec![0f32; pixels * n];
            for (c, ch) in channels.iter().enumerate() {
                if let Samples::F32(v) = &ch.samples {
                    (0..pixels).for_each(|i| data[i * n + c] = v[i]);
                }
            }
            image(py, size, n, data)
        }
    }
}

#[pymethods]
impl Film {
    /// Reads a film file (an EXR `pathwave render` or `merge` wrote, or any RGB EXR) as `pathwave diff` does.
    #[staticmethod]
    fn load(py: Python<'_>, path: PathBuf) -> PyResult<Film> {
        let file = py
            .detach(|| output::read_film(&path))
            .map_err(|e| errors::to_py(e.into()))?;
        Ok(Film {
            source: Source::File(Box::new(file)),
        })
    }

    #[getter]
    fn width(&self) -> u32 {
        self.size().0
    }

    #[getter]
    fn height(&self) -> u32 {
        self.size().1
    }

    /// Samples per pixel the film holds (fewer than asked after an interrupt; 0 for an image without statistics).
    #[getter(spp)]
    fn spp_py(&self) -> u64 {
        self.spp()
    }

    /// The image: linear RGB radiance, float32, shape (height, width, 3), top row first; denoised with denoise=True.
    #[getter(rgb)]
    fn rgb_py<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        match &self.source {
            Source::Rendered { rendered, .. } => rgb(py, self.size(), &rendered.pixels),
            Source::File(f) => rgb(py, self.size(), &f.mean),
        }
    }

    /// The AOVs the render asked for (aov=[...]), by name: float32 arrays of shape (height, width, channels) or
    /// (height, width), uint32 for ids and sample counts; empty for a film file.
    #[getter]
    fn aovs<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        if let Source::Rendered { aovs, rendered, .. } = &self.source {
            let source = output::AovSource {
                film: &rendered.film,
                noisy: Some(&rendered.noisy),
            };
            for &a in aovs {
                let c = source
                    .channels(a, false)
                    .ok_or_else(|| errors::Error::new_err(format!("the render has no {} AOV", a.name())))?;
                d.set_item(a.name(), channels(py, self.size(), &c)?)?;
            }
        }
        Ok(d)
    }

    /// Per pixel and channel, the mean of the samples (float64, from the exact sums), with film_stats=True.
    #[getter]
    fn mean<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyAny>>> {
        let Some(exact) = self.exact() else { return Ok(None) };
        let s = pathwave::diff::Sampled::from_exact(exact);
        Ok(Some(rgb(py, self.size(), &s.mean)?))
    }

    /// Per pixel and channel, the unbiased variance of one sample (not of the mean; divide by `count` for that),
    /// float64, with film_stats=True.
    #[getter]
    fn variance<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyAny>>> {
        let Some(exact) = self.exact() else { return Ok(None) };
        Ok(Some(rgb(py, self.size(), &exact.sample_variance())?))
    }

    /// Per pixel, the samples taken (uint32, shape (height, width)), with film_stats=True.
    #[getter]
    fn count<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyAny>>> {
        let Some(exact) = self.exact() else { return Ok(None) };
        Ok(Some(image(py, self.size(), 1, exact.count.clone())?))
    }

    /// How the render went (None for a film file): wall seconds, passes, samples, rays, and the command line's
    /// one-line summary.
    #[getter]
    fn stats<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyDict>>> {
        let Source::Rendered { rendered, .. } = &self.source else {
            return Ok(None);
        };
        let s = &rendered.stats;
        let d = PyDict::new(py);
        d.set_item("wall", s.wall.as_secs_f64())?;
        d.set_item("passes", s.passes)?;
        d.set_item("samples", s.samples)?;
        d.set_item("extension_rays", s.extension_rays)?;
        d.set_item("shadow_rays", s.shadow_rays)?;
        d.set_item("samples_per_sec", s.samples_per_sec())?;
        d.set_item("interrupted", s.interrupted)?;
        d.set_item("device", &rendered.device)?;
        d.set_item("summary", s.summary())?;
        let stages = PyDict::new(py);
        for (name, ms) in &s.stage_ms {
            stages.set_item(*name, ms)?;
        }
        d.set_item("stage_ms", stages)?;
        Ok(Some(d))
    }

    /// Writes the film as `pathwave render -o PATH` with the render's options does (EXR or PNG by the extension,
    /// AOVs as EXR layers or PNG files beside it, film statistics with film_stats=True), all or nothing; exposure
    /// and tonemap replace the render's. Returns every path written.
    #[pyo3(signature = (path, *, exposure=None, tonemap=None))]
    fn save(
        &self,
        py: Python<'_>,
        path: PathBuf,
        exposure: Option<Bound<'_, PyAny>>,
        tonemap: Option<Bound<'_, PyAny>>,
    ) -> PyResult<Vec<String>> {
        let mut display = Vec::new();
        if let Some(e) = &exposure {
            crate::argv::push(&mut display, "exposure", e)?;
        }
        if let Some(t) = &tonemap {
            crate::argv::push(&mut display, "tonemap", t)?;
        }
        match &self.source {
            Source::Rendered {
                argv,
                scene,
                time,
                rendered,
                ..
            } => {
                let replaced = |a: &String| {
                    display
                        .iter()
                        .any(|d| crate::argv::keyword(d) == crate::argv::keyword(a))
                };
                let given: Vec<String> = (argv.iter().filter(|a| !replaced(a)).cloned())
                    .chain(display.iter().cloned())
                    .collect();
                let mut args = parse(&given, scene)?;
                args.output = vec![path.clone()];
                let shot = Shot {
                    frame: None,
                    time: *time,
                    outputs: vec![path],
                };
                let written = py
                    .detach(|| -> anyhow::Result<Vec<PathBuf>> {
                        pathwave::cli::render::check_outputs(&args, std::slice::from_ref(&shot))?;
                        rendered.write(&args, &shot)
                    })
                    .map_err(errors::to_py)?;
                Ok(written.iter().map(|p| p.display().to_string()).collect())
            }
            Source::File(f) => {
                // A film file's own options are not known: the command line's defaults, and what is given here.
                let mut args = parse(&display, "-")?;
                args.output = vec![path.clone()];
                let display = output::Display {
                    exposure: args.exposure,
                    curve: args.tonemap,
                };
                let stats = f.stats.as_ref().map(|(film, meta)| output::Stats { film, meta });
                py.detach(|| -> anyhow::Result<()> {
                    output::check_writable(&path)?;
                    output::write_images_with(std::slice::from_ref(&path), f.width, f.height, &f.mean, display, stats)?;
                    Ok(())
                })
                .map_err(errors::to_py)?;
                Ok(vec![path.display().to_string()])
            }
        }
    }

    fn __repr__(&self) -> String {
        let (w, h) = self.size();
        format!("Film({w}x{h}, {} spp)", self.spp())
    }
}
