//! What a render is asked for: image size, samples, depth, estimator and camera options, and the renderer's
//! overrides read from the environment once, at the edge.
use super::{BvhReads, Schedule};
use crate::constants::*;
use crate::error::Error;

/// Which estimator shade uses; the three must agree in expectation (tests/estimators.rs).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum Estimator {
    /// Next-event estimation and BSDF sampling combined with the power heuristic.
    #[default]
    Mis,
    /// Light sampling only: emission found by BSDF-sampled rays is ignored after the camera ray.
    Light,
    /// BSDF sampling only: no next-event estimation.
    Bsdf,
}

impl Estimator {
    pub(super) fn code(self) -> u32 {
        match self {
            Estimator::Mis => ESTIMATOR_MIS,
            Estimator::Light => ESTIMATOR_LIGHT,
            Estimator::Bsdf => ESTIMATOR_BSDF,
        }
    }
}

/// How rays find what they hit (--traversal): pathwave's own BVH in compute shaders everywhere, or the device's
/// acceleration structures through VK_KHR_ray_query where it has them (src/render/accel.rs).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum Traversal {
    /// Ray queries on a GPU that has them; the compute BVH on CPU devices (on lavapipe the compute BVH is faster,
    /// see docs/guide/traversal.md) and wherever a scene needs what ray queries lack (motion blur).
    #[default]
    Auto,
    /// The compute BVH (traverse.glsl), on every device.
    Compute,
    /// Ray queries; a device without them, or a scene they cannot trace, keeps the compute BVH with a warning
    /// saying why.
    RayQuery,
}

/// How minified textures are read (--texture-filter).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum TextureFilter {
    /// From the two mip levels around the footprint of the pixel at the hit (FEATURE_TEXTURE_LOD): distant textures
    /// are prefiltered instead of aliasing, and read from a working set that fits the caches.
    #[default]
    Trilinear,
    /// Bilinear from the full-resolution image at every distance: the converged image of point-sampled textures.
    Bilinear,
}

impl TextureFilter {
    pub fn name(self) -> &'static str {
        match self {
            TextureFilter::Trilinear => "trilinear",
            TextureFilter::Bilinear => "bilinear",
        }
    }
}

/// How next-event estimation picks a light (--light-sampler); the three converge to the same image
/// (tests/light_tree.rs).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum LightSampler {
    /// By importance at the shading point: a descent of the light BVH (bounds, power and normal cone per node).
    #[default]
    Bvh,
    /// In proportion to each light's estimated power, the same table at every point.
    Power,
    /// Every light (triangle, emissive instance, punctual light, environment) with the same probability.
    Uniform,
}

impl LightSampler {
    /// The Frame.flags bits that ask for it (none: by power).
    pub fn flags(self) -> u32 {
        match self {
            LightSampler::Bvh => FLAG_LIGHT_TREE,
            LightSampler::Power => 0,
            LightSampler::Uniform => FLAG_LIGHT_UNIFORM,
        }
    }
    pub fn name(self) -> &'static str {
        match self {
            LightSampler::Bvh => "bvh",
            LightSampler::Power => "power",
            LightSampler::Uniform => "uniform",
        }
    }
}

/// Bounces recorded when no `max_depth` is given: Russian roulette ends paths long before this.
pub const DEPTH_SAFETY_CAP: u32 = 64;
/// The same cap in a scene with scattering media (FEATURE_MEDIA), where each scattering is a bounce: light diffusing
/// through a dense medium scatters hundreds of times. A path that reaches it ends there (its light beyond is lost, the
/// image darkens where media are denser than this resolves), which bounds the work of a medium whose mean free path
/// is far below the scene's size. An explicit --max-depth is taken as given.
pub const MEDIA_DEPTH_CAP: u32 = 1024;

#[derive(Clone, Debug)]
pub struct RenderSettings {
    pub width: u32,
    pub height: u32,
    pub spp: u32,
    /// Longest path in bounces; None means unbounded (Russian roulette, with DEPTH_SAFETY_CAP).
    pub max_depth: Option<u32>,
    pub seed: u32,
    pub estimator: Estimator,
    /// How next-event estimation picks lights.
    pub light_sampler: LightSampler,
    /// Return the energy rough metals lose to single scattering (Kulla-Conty); on by default.
    pub energy_compensation: bool,
    /// Keep the environment out of camera rays (it still lights the scene).
    pub hide_environment: bool,
    /// Thin-lens aperture radius in scene units; 0 is a pinhole (everything sharp).
    pub aperture: f32,
    /// Distance from the camera to the plane in focus, along the view direction; None: the camera's distance to
    /// the scene's centre.
    pub focus_distance: Option<f32>,
    /// The first sample index: the render takes samples `first_sample .. first_sample + spp` of every pixel, the
    /// same samples a render from 0 takes there (`--samples A..B`).
    pub first_sample: u32,
    /// Keep the exact film (fixed-point sums that merge to the same bits in any split, FEATURE_EXACT_FILM), whose
    /// `Film::exact` carries the statistics a film file holds.
    pub exact_film: bool,
    /// Survey the AOVs (albedo, normal, depth, position, ids) over the same samples as the image: `Film::aovs`.
    pub aovs: bool,
    /// Survey the debug views too (`Aovs::debug`: geometric and shading normals, UV, traversal cost, light-pick
    /// probability); implies `aovs`.
    pub debug_aovs: bool,
    /// Sample adaptively: pixels stop once their mean is estimated to be within the threshold.
    pub adaptive: Option<Adaptive>,
    /// Spectral transport (FEATURE_SPECTRAL): paths carry four wavelengths, colours become spectra at them (see
    /// `spectrum`); off, the render is RGB. `Scene::wants_spectral` says when a scene needs it (dispersion).
    pub spectral: bool,
    /// How minified textures are read: from mip levels at the pixel's footprint, or from level 0.
    pub texture_filter: TextureFilter,
}

/// Adaptive sampling (FEATURE_ADAPTIVE): every pixel takes the first `pilot` samples; then each pixel's budget is the
/// samples its mean needs for a relative standard error of `threshold`, as its 24 nearest neighbours' pilot samples
/// estimate it (plan.comp), at most the render's.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Adaptive {
    pub threshold: f32,
    pub pilot: u32,
}

impl Default for RenderSettings {
    fn default() -> Self {
        RenderSettings {
            width: 256,
            height: 256,
            spp: 16,
            max_depth: None,
            seed: 0,
            estimator: Estimator::Mis,
            light_sampler: LightSampler::Bvh,
            energy_compensation: true,
            hide_environment: false,
            aperture: 0.0,
            focus_distance: None,
            first_sample: 0,
            exact_film: false,
            aovs: false,
            debug_aovs: false,
            adaptive: None,
            spectral: false,
            texture_filter: TextureFilter::Trilinear,
        }
    }
}

/// How the renderer may be steered past its own choices; `from_env` is the one place that reads the environment for
/// it (PATHWAVE_SCHEDULE, PATHWAVE_BVH_READS, PATHWAVE_INSTANCING, PATHWAVE_TRAVERSAL), so the library below takes typed options.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RendererOptions {
    /// Fix the schedule instead of choosing (a trial on CPU devices, the wavefront on GPUs).
    pub schedule: Option<Schedule>,
    /// Force storage-buffer reads of the BVH and per-triangle data even where texel reads are possible.
    pub storage_reads: bool,
    /// Device memory the scene's buffers may take; None: the device's largest device-local heap. A scene past it
    /// is refused before anything is uploaded.
    pub max_device_memory: Option<u64>,
    /// Which meshes are kept in object space under a two-level BVH (PATHWAVE_INSTANCING=auto|always|never).
    pub instancing: crate::scene::Instancing,
    /// Keep the scene's fingerprint (`PackedScene::fingerprint`) for film files: hashing every buffer takes a few
    /// milliseconds per 10 MB, which renders that write none need not spend.
    pub fingerprint: bool,
    /// Compute BVH or ray queries (PATHWAVE_TRAVERSAL=auto|compute|ray-query, or --traversal).
    pub traversal: Traversal,
}

impl RendererOptions {
    /// PATHWAVE_SCHEDULE=wavefront|fused fixes the schedule; PATHWAVE_BVH_READS=storage forces storage reads
    /// (texel: the default choice). Any other word is refused, naming the variable.
    pub fn from_env() -> Result<Self, Error> {
        let schedule = match std::env::var("PATHWAVE_SCHEDULE").as_deref() {
            Ok("wavefront") => Some(Schedule::Wavefront),
            Ok("fused") => Some(Schedule::Fused),
            Ok(other) => {
                return Err(Error::Settings(format!(
                    "PATHWAVE_SCHEDULE={other}: expected wavefront or fused"
                )))
            }
            Err(std::env::VarError::NotPresent) => None,
            Err(_) => return Err(Error::Settings("PATHWAVE_SCHEDULE is not valid Unicode".into())),
        };
        let storage_reads = match std::env::var("PATHWAVE_BVH_READS").as_deref() {
            Ok("storage") => true,
            Ok("texel") | Err(std::env::VarError::NotPresent) => false,
            Ok(other) => {
                return Err(Error::Settings(format!(
                    "PATHWAVE_BVH_READS={other}: expected storage or texel"
                )))
            }
            Err(_) => return Err(Error::Settings("PATHWAVE_BVH_READS is not valid Unicode".into())),
        };
        let instancing = match std::env::var("PATHWAVE_INSTANCING").as_deref() {
            Ok("auto") | Err(std::env::VarError::NotPresent) => crate::scene::Instancing::Auto,
            Ok("always") => crate::scene::Instancing::Always,
            Ok("never") => crate::scene::Instancing::Never,
            Ok(other) => {
                return Err(Error::Settings(format!(
                    "PATHWAVE_INSTANCING={other}: expected auto, always or never"
                )))
            }
            Err(_) => return Err(Error::Settings("PATHWAVE_INSTANCING is not valid Unicode".into())),
        };
        let traversal = match std::env::var("PATHWAVE_TRAVERSAL").as_deref() {
            Ok("auto") | Err(std::env::VarError::NotPresent) => Traversal::Auto,
            Ok("compute") => Traversal::Compute,
            Ok("ray-query") => Traversal::RayQuery,
            Ok(other) => {
                return Err(Error::Settings(format!(
                    "PATHWAVE_TRAVERSAL={other}: expected auto, compute or ray-query"
                )))
            }
            Err(_) => return Err(Error::Settings("PATHWAVE_TRAVERSAL is not valid Unicode".into())),
        };
        Ok(RendererOptions {
            schedule,
            storage_reads,
            max_device_memory: None,
            instancing,
            fingerprint: false,
            traversal,
        })
    }

    /// How traversal reads the scene given what the device can hold (`texel`: texel views exist; `storage`: every
    /// buffer fits the storage range).
    pub(super) fn bvh_reads(&self, texel: bool, storage: bool) -> Result<BvhReads, Error> {
        match (texel, self.storage_reads) {
            (true, true) if !storage => Err(Error::Settings(
                "PATHWAVE_BVH_READS=storage: the scene's BVH or per-triangle data outgrow this device's \
                 storage-buffer range"
                    .into(),
            )),
            (_, true) | (false, _) => Ok(BvhReads::Storage),
            (true, false) => Ok(BvhReads::Texel),
        }
    }
}

/// Whether a render is spectral, and why: asked for (`--spectral`), or a scene with dispersion
/// (KHR_materials_dispersion needs spectral transport) unless RGB is asked for. The command line and the viewer
/// both decide with it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SpectralChoice {
    Asked,
    /// The scene has dispersion and RGB was not asked for.
    Dispersion,
    Rgb,
    /// RGB asked for over a scene with dispersion, which then renders without it.
    RgbOverDispersion,
}

impl SpectralChoice {
    pub fn new(spectral: bool, rgb: bool, dispersive: bool) -> Self {
        match (spectral, rgb, dispersive) {
            (true, _, _) => SpectralChoice::Asked,
            (false, false, true) => SpectralChoice::Dispersion,
            (false, true, true) => SpectralChoice::RgbOverDispersion,
            (false, _, false) => SpectralChoice::Rgb,
        }
    }

    pub fn spectral(self) -> bool {
        matches!(self, SpectralChoice::Asked | SpectralChoice::Dispersion)
    }
}

impl RenderSettings {
    /// The FEATURE_* bits these settings specialise the render stages for: a lens, the exact film, adaptive sampling,
    /// spectral transport and mip-mapped textures (the scene and the light selection add theirs; the renderer clears
    /// FEATURE_TEXTURE_LOD for a scene without textures).
    pub fn features(&self) -> u32 {
        let bit = |on: bool, feature: u32| if on { feature } else { 0 };
        bit(self.aperture > 0.0, FEATURE_LENS)
            | bit(self.exact_film, FEATURE_EXACT_FILM)
            | bit(self.adaptive.is_some(), FEATURE_ADAPTIVE)
            | bit(self.spectral, FEATURE_SPECTRAL)
            | bit(self.texture_filter == TextureFilter::Trilinear, FEATURE_TEXTURE_LOD)
    }

    /// Refuses settings no render can honour, before anything is allocated.
    pub(super) fn check(&self) -> Result<(), Error> {
        if self.width == 0 || self.height == 0 {
            return Err(Error::Settings(format!(
                "image size {}x{} has no pixels",
                self.width, self.height
            )));
        }
        if self.spp == 0 {
            return Err(Error::Settings("samples per pixel must be at least 1".into()));
        }
        if self.first_sample.checked_add(self.spp).is_none() {
            return Err(Error::Settings(format!(
                "samples {}..{} run past the last sample index, {}",
                self.first_sample,
                self.first_sample as u64 + self.spp as u64,
                u32::MAX
            )));
        }
        if let Some(a) = self.adaptive {
            if a.pilot < 2 || !(a.threshold.is_finite() && a.threshold > 0.0) {
                return Err(Error::Settings(format!(
                    "adaptive sampling needs a pilot of at least 2 samples (a variance) and a noise threshold above \
                     0; got {} and {}",
                    a.pilot, a.threshold
                )));
            }
        }
        if !(self.aperture.is_finite() && self.aperture >= 0.0)
            || self.focus_distance.is_some_and(|f| !(f.is_finite() && f > 0.0))
        {
            return Err(Error::Settings(
                "the aperture must be >= 0 and the focus distance > 0".into(),
            ));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::{Adaptive, RenderSettings, SpectralChoice, TextureFilter};
    use crate::constants::*;

    /// Each setting adds its own bit and nothing else; the defaults specialise for none of them. A closed aperture is
    /// a pinhole (no lens stage work), any opening a lens.
    #[test]
    fn settings_features_are_one_bit_each() {
        let bilinear = RenderSettings {
            texture_filter: TextureFilter::Bilinear,
            ..RenderSettings::default()
        };
        assert_eq!(bilinear.features(), 0);
        assert_eq!(RenderSettings::default().features(), FEATURE_TEXTURE_LOD);
        let with = |edit: fn(&mut RenderSettings)| {
            let mut s = RenderSettings {
                texture_filter: TextureFilter::Bilinear,
                ..RenderSettings::default()
            };
            edit(&mut s);
            s.features()
        };
        assert_eq!(with(|s| s.aperture = 0.05), FEATURE_LENS);
        assert_eq!(with(|s| s.aperture = 0.0), 0);
        assert_eq!(with(|s| s.exact_film = true), FEATURE_EXACT_FILM);
        let adaptive = Some(Adaptive {
            threshold: 0.01,
            pilot: 16,
        });
        let s = RenderSettings {
            adaptive,
            ..bilinear.clone()
        };
        assert_eq!(s.features(), FEATURE_ADAPTIVE);
        assert_eq!(with(|s| s.spectral = true), FEATURE_SPECTRAL);
        // Settings that change no stage's specialisation.
        assert_eq!(with(|s| s.aovs = true), 0);
        assert_eq!(with(|s| s.seed = 9), 0);
        let all = RenderSettings {
            aperture: 1.0,
            exact_film: true,
            adaptive,
            spectral: true,
            ..RenderSettings::default()
        };
        assert_eq!(
            all.features(),
            FEATURE_LENS | FEATURE_EXACT_FILM | FEATURE_ADAPTIVE | FEATURE_SPECTRAL | FEATURE_TEXTURE_LOD
        );
    }

    /// --spectral always renders spectrally (the command line refuses it with --rgb, but the rule stays); a scene with
    /// dispersion does unless --rgb; nothing else does.
    #[test]
    fn spectral_choice_truth_table() {
        use SpectralChoice::*;
        for (spectral, rgb, dispersive, want) in [
            (false, false, false, Rgb),
            (false, false, true, Dispersion),
            (false, true, false, Rgb),
            (false, true, true, RgbOverDispersion),
            (true, false, false, Asked),
            (true, false, true, Asked),
            (true, true, false, Asked),
            (true, true, true, Asked),
        ] {
            let c = SpectralChoice::new(spectral, rgb, dispersive);
            assert_eq!(c, want, "{spectral} {rgb} {dispersive}");
            assert_eq!(c.spectral(), spectral || (dispersive && !rgb));
        }
    }
}
