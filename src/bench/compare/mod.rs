//! `pathwave bench --compare`: the same work done by Mitsuba 3 and Embree in this run, interleaved with ours.
mod embree;
mod helper;
mod mitsuba;
mod mitsuba_scene;
mod reference;

pub use embree::{compare_embree, random_rays, EmbreeComparison, RayQueryRounds};
pub use mitsuba::{compare_mitsuba, MitsubaCase, MitsubaComparison};

use crate::error::Error;
use crate::render::{Renderer, Traversal};
use crate::vk::{Context, DeviceChoice, Validation};

fn err(msg: impl std::fmt::Display) -> Error {
    Error::Settings(format!("bench --compare: {msg}"))
}

pub(crate) fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    if v.is_empty() {
        return f64::NAN;
    }
    let m = v.len() / 2;
    if v.len() % 2 == 1 {
        v[m]
    } else {
        0.5 * (v[m - 1] + v[m])
    }
}

/// A renderer over `scene` tracing with `traversal`, refused when ray queries were asked for and cannot run: every
/// bench case and comparison builds its renderer here.
pub(super) fn tracer(
    scene: &crate::scene::Scene,
    device: &DeviceChoice,
    traversal: Traversal,
) -> Result<Renderer, Error> {
    let ctx = Context::new(device, Validation::Off)?;
    let options = crate::render::RendererOptions {
        traversal,
        ..crate::render::RendererOptions::from_env()?
    };
    let r = Renderer::with_options(scene, ctx, options)?;
    if traversal == Traversal::RayQuery && r.traversal() != Traversal::RayQuery {
        return Err(Error::Settings(format!(
            "cannot trace with ray queries: {}",
            r.warnings.join("; ")
        )));
    }
    Ok(r)
}
