//! `pathwave.diff`: a candidate against a reference (films or film files) as `pathwave diff` judges them.
use crate::film::Film;
use crate::{argv, errors};
use pathwave::cli::film::{compare, CompareOptions, Verdict};
use pathwave::output::{self, FilmFile};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use std::path::PathBuf;

#[pyclass(module = "pathwave._pathwave", frozen)]
pub struct DiffResult {
    verdict: Verdict,
    width: u32,
    height: u32,
}

/// A side of the comparison: a Film, or a path to a film file read as `diff` reads it.
fn side(py: Python<'_>, value: &Bound<'_, PyAny>) -> PyResult<(String, FilmFile)> {
    if let Ok(film) = value.cast::<Film>() {
        return Ok((film.repr()?.to_string(), film.get().as_film_file()));
    }
    let path: PathBuf = value.extract()?;
    let file = py
        .detach(|| output::read_film(&path))
        .map_err(|e| errors::to_py(e.into()))?;
    Ok((path.display().to_string(), file))
}

/// Compares `candidate` with `reference` as `pathwave diff` does: the statistical test when either carries film
/// statistics, else relMSE and FLIP against the thresholds.
#[pyfunction]
#[pyo3(signature = (candidate, reference, *, alpha=None, plain=false, max_rel_mse=None, max_flip=None, worst=None))]
#[allow(clippy::too_many_arguments)]
pub fn diff(
    py: Python<'_>,
    candidate: Bound<'_, PyAny>,
    reference: Bound<'_, PyAny>,
    alpha: Option<Bound<'_, PyAny>>,
    plain: bool,
    max_rel_mse: Option<Bound<'_, PyAny>>,
    max_flip: Option<Bound<'_, PyAny>>,
    worst: Option<Bound<'_, PyAny>>,
) -> PyResult<DiffResult> {
    let mut given = Vec::new();
    for (key, value) in [
        ("alpha", &alpha),
        ("max_rel_mse", &max_rel_mse),
        ("max_flip", &max_flip),
        ("worst", &worst),
    ] {
        if let Some(v) = value {
            argv::push(&mut given, key, v)?;
        }
    }
    if plain {
        given.push(argv::flag("plain"));
    }
    let options = CompareOptions::parse_from(given).map_err(|e| errors::from_clap("diff", e))?;
    let (c_name, c) = side(py, &candidate)?;
    let (r_name, r) = side(py, &reference)?;
    let verdict = py
        .detach(|| compare((&c_name, &c), (&r_name, &r), &options))
        .map_err(errors::to_py)?;
    for note in &verdict.notes {
        let text = note.trim_start_matches("warning: ").trim_start_matches("note: ");
        crate::renderer::warn(py, text)?;
    }
    Ok(DiffResult {
        verdict,
        width: c.width,
        height: c.height,
    })
}

#[pymethods]
impl DiffResult {
    /// No test rejected (statistical), or within both thresholds (plain).
    #[getter]
    fn consistent(&self) -> bool {
        self.verdict.consistent
    }

    /// The family-wise p-value of the statistical test (None for a plain comparison).
    #[getter]
    fn p_value(&self) -> Option<f64> {
        self.verdict.report.as_ref().map(|r| r.p_value)
    }

    /// The significance level the test used (None for a plain comparison).
    #[getter]
    fn alpha(&self) -> Option<f64> {
        self.verdict.report.as_ref().map(|r| r.alpha)
    }

    /// The plain comparison's relMSE and mean FLIP (None for a statistical one).
    #[getter]
    fn rel_mse(&self) -> Option<f64> {
        self.verdict.plain.as_ref().map(|p| p.rel_mse)
    }

    #[getter]
    fn flip(&self) -> Option<f64> {
        self.verdict.plain.as_ref().map(|p| p.flip_mean)
    }

    /// The lowest-p tests, most significant first: dicts of x, y, size (1 for a pixel, else a block's edge), channel,
    /// candidate, reference, stat, df and p. Empty for a plain comparison.
    #[getter]
    fn worst<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyList>> {
        let list = PyList::empty(py);
        for w in self.verdict.report.iter().flat_map(|r| &r.worst) {
            let d = PyDict::new(py);
            d.set_item("x", w.x)?;
            d.set_item("y", w.y)?;
            d.set_item("size", w.size)?;
            d.set_item("channel", "RGB".chars().nth(w.channel).map(String::from))?;
            d.set_item("candidate", w.candidate)?;
            d.set_item("reference", w.reference)?;
            d.set_item("stat", w.stat)?;
            d.set_item("df", w.df)?;
            d.set_item("p", w.p)?;
            list.append(d)?;
        }
        Ok(list)
    }

    /// What `pathwave diff` prints: the verdict and what it rests on.
    #[getter]
    fn summary(&self) -> String {
        self.verdict.summary.clone()
    }

    /// Where they differ as an sRGB picture, uint8 of shape (height, width, 3): the tests' p-values (green where
    /// rejected), or FLIP's error map; written as `diff --heatmap` writes it when `path` is given.
    #[pyo3(signature = (path=None))]
    fn heatmap<'py>(&self, py: Python<'py>, path: Option<PathBuf>) -> PyResult<Bound<'py, PyAny>> {
        if let Some(p) = &path {
            py.detach(|| -> anyhow::Result<()> {
                if output::format_of(p)? != output::Format::Png {
                    anyhow::bail!("{}: the heat map is a PNG", p.display());
                }
                output::write_srgb8(p, self.width, self.height, &self.verdict.heat)?;
                Ok(())
            })
            .map_err(errors::to_py)?;
        }
        let flat: Vec<u8> = self.verdict.heat.iter().flatten().copied().collect();
        let array = numpy::PyArray1::from_vec(py, flat);
        use numpy::PyArrayMethods;
        Ok(array
            .reshape([self.height as usize, self.width as usize, 3])?
            .into_any())
    }

    fn __bool__(&self) -> PyResult<bool> {
        Err(pyo3::exceptions::PyTypeError::new_err(
            "a DiffResult has no truth value: test .consistent",
        ))
    }

    fn __repr__(&self) -> String {
        self.verdict.summary.trim_end().to_string()
    }
}
