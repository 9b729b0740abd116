//! `pathwave bench --compare`: the same work done by Mitsuba 3 and Embree in this run, interleaved with ours.
use super::terrain;
use crate::bvh::Ray;
use crate::error::Error;
use crate::render::{LightSampler, RenderSettings, Renderer, Traversal};
use crate::scene::{self, Projection, Scene};
use crate::vk::{Context, DeviceChoice, Validation};
use glam::Vec3;
use serde_json::{json, Value};
use std::io::{BufRead, BufReader, Write};
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdin, ChildStdout, Command, Stdio};

const HELPER: &str = include_str!("compare.py");

fn err(msg: impl std::fmt::Display) -> Error {
    Error::Settings(format!("bench --compare: {msg}"))
}

/// The Python process that runs Mitsuba and Embree: one JSON request per line each way.
struct Helper {
    child: Child,
    stdin: ChildStdin,
    stdout: BufReader<ChildStdout>,
    dir: tempfile::TempDir,
}

impl Helper {
    fn start(python: &Path) -> Result<Helper, Error> {
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

    fn path(&self, name: &str) -> PathBuf {
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

    fn call(&mut self, request: Value) -> Result<Value, Error> {
        writeln!(self.stdin, "{request}").map_err(err)?;
        self.stdin.flush().map_err(err)?;
        let r = self.read()?;
        if r["ok"] != json!(true) {
            return Err(err(r["error"].as_str().unwrap_or("the helper failed")));
        }
        Ok(r)
    }

    fn f64(r: &Value, key: &str) -> Result<f64, Error> {
        r[key].as_f64().ok_or_else(|| err(format!("helper reply lacks {key}")))
    }
}

impl Drop for Helper {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn write_f32(path: &Path, data: &[f32]) -> Result<(), Error> {
    std::fs::write(path, bytemuck::cast_slice(data)).map_err(err)
}

fn read_f32(path: &Path) -> Result<Vec<f32>, Error> {
    let bytes = std::fs::read(path).map_err(err)?;
    Ok(bytes
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect())
}

/// Deterministic uniforms for the ray set (SplitMix64), so both tracers see the same rays every run.
struct SplitMix(u64);

impl SplitMix {
    fn next(&mut self) -> f32 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        ((z ^ (z >> 31)) >> 40) as f32 / (1u64 << 24) as f32
    }
}

/// Rays with origins uniform in the scene's bounding box and directions uniform on the sphere: the incoherent
/// case DESIGN.md's prototype figures use.
pub fn random_rays(scene: &Scene, n: usize, seed: u64) -> Vec<Ray> {
    let (lo, hi) = scene.bounds();
    let mut rng = SplitMix(seed);
    (0..n)
        .map(|_| {
            let o = lo + (hi - lo) * Vec3::new(rng.next(), rng.next(), rng.next());
            let z = 1.0 - 2.0 * rng.next();
            let phi = std::f32::consts::TAU * rng.next();
            let r = (1.0 - z * z).max(0.0).sqrt();
            Ray {
                origin: o,
                dir: Vec3::new(r * phi.cos(), r * phi.sin(), z),
                tmin: 0.0,
                tmax: f32::MAX,
            }
        })
        .collect()
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

/// Traversal against Embree: the same mesh and random rays, closest hit, all cores each.
#[derive(Clone, Debug, Default)]
pub struct EmbreeComparison {
    pub device: String,
    pub triangles: usize,
    pub rays: usize,
    pub threads: u32,
    pub embree_build_s: f64,
    pub pathwave_build_s: f64,
    /// Per round, interleaved: (pathwave, Embree) rays per second.
    pub rounds: Vec<(f64, f64)>,
    /// Median over rounds of pathwave / Embree.
    pub ratio: f64,
    /// Rays where both miss or both hit at the same distance (within 1e-3 relative).
    pub agreement: f64,
    /// How pathwave traced in `rounds`: "compute" (its BVH) or "ray queries".
    pub traversal: String,
    /// Where the device has ray queries and both traversals were asked for: the same rays traced with them in each
    /// round, right after the compute BVH.
    pub ray_query: Option<RayQueryRounds>,
}

#[derive(Clone, Debug, Default)]
pub struct RayQueryRounds {
    /// Per round, rays per second.
    pub rays_per_s: Vec<f64>,
    /// The acceleration structures' build, compaction included.
    pub build_s: f64,
    /// Rays whose hits agree with Embree's, as `agreement`.
    pub agreement: f64,
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

/// `traversals`: what bench measures (the compute BVH first); the first is timed against Embree, a second (ray
/// queries) beside it.
pub fn compare_embree(
    python: &Path,
    device: &DeviceChoice,
    quick: bool,
    traversals: &[Traversal],
) -> Result<EmbreeComparison, Error> {
    let mut h = Helper::start(python)?;
    let side = if quick { 128 } else { 708 };
    let rays_n = if quick { 1 << 16 } else { 1 << 20 };
    let rounds = if quick { 2 } else { 3 };
    let scene = terrain(side);
    let rays = random_rays(&scene, rays_n, 7);
    let soup = scene.flatten();
    let tris: Vec<f32> = soup.positions().iter().flatten().flat_map(|p| p.to_array()).collect();
    let ray_data: Vec<f32> = rays
        .iter()
        .flat_map(|r| r.origin.to_array().into_iter().chain(r.dir.to_array()))
        .collect();
    let (tri_path, ray_path, hit_path) = (h.path("tris.f32"), h.path("rays.f32"), h.path("hits.f32"));
    write_f32(&tri_path, &tris)?;
    write_f32(&ray_path, &ray_data)?;
    let loaded = h
        .call(json!({"cmd": "embree_load", "triangles": tri_path}))
        .map_err(|e| err(format!("{e}; install it with `pip install embreex`")))?;
    let embree_build_s = Helper::f64(&loaded, "build_s")?;
    let first = traversals.first().copied().unwrap_or(Traversal::Compute);
    let device_choice = device;
    let mut r = tracer(&scene, device_choice, first)?;
    let device = r.context().device_name();
    let pathwave_build_s = match r.acceleration_structures() {
        Some((_, _, t)) => t.as_secs_f64(),
        None => r.bvh_build_time().as_secs_f64(),
    };
    // The first dispatch compiles the pipeline: traced once untimed.
    let (ours, _) = r.trace_timed(&rays, false, 1)?;
    let mut second = match traversals.get(1) {
        Some(&t) => {
            let mut q = tracer(&scene, device_choice, t)?;
            let (hits, _) = q.trace_timed(&rays, false, 1)?;
            let build_s = q.acceleration_structures().map_or(0.0, |(_, _, t)| t.as_secs_f64());
            Some((q, hits, build_s))
        }
        None => None,
    };
    let mut result = EmbreeComparison {
        device,
        triangles: soup.len(),
        rays: rays.len(),
        embree_build_s,
        pathwave_build_s,
        traversal: match r.traversal() {
            Traversal::RayQuery => "ray queries".into(),
            _ => "compute".into(),
        },
        ..Default::default()
    };
    let mut second_rates = Vec::new();
    let mut embree_t = Vec::new();
    for _ in 0..rounds {
        let (_, times) = r.trace_timed(&rays, false, 2)?;
        let t_ours = median(times.iter().map(|t| t.as_secs_f64()).collect());
        if let Some((q, _, _)) = &mut second {
            let (_, times) = q.trace_timed(&rays, false, 2)?;
            second_rates.push(rays_n as f64 / median(times.iter().map(|t| t.as_secs_f64()).collect()));
        }
        let last = embree_t.len() + 1 == rounds;
        let hits = if last { json!(hit_path) } else { Value::Null };
        let traced = h.call(json!({"cmd": "embree_trace", "rays": ray_path, "hits": hits}))?;
        let t_embree = Helper::f64(&traced, "seconds")?;
        result.threads = traced["threads"].as_u64().unwrap_or(0) as u32;
        result.rounds.push((rays_n as f64 / t_ours, rays_n as f64 / t_embree));
        embree_t.push(t_embree);
    }
    result.ratio = median(result.rounds.iter().map(|(a, b)| a / b).collect());
    let theirs = read_f32(&hit_path)?;
    let agreement = |ours: &[crate::bvh::TraceHit]| {
        let agree = ours
            .iter()
            .zip(&theirs)
            .filter(|(a, &b)| {
                let miss_a = a.tri == crate::constants::NO_HIT;
                let miss_b = !b.is_finite();
                (miss_a && miss_b) || (!miss_a && !miss_b && (a.t - b).abs() <= 1e-3 * b.abs().max(1e-3))
            })
            .count();
        agree as f64 / rays.len().max(1) as f64
    };
    result.agreement = agreement(&ours);
    result.ray_query = second.map(|(_, hits, build_s)| RayQueryRounds {
        rays_per_s: second_rates,
        build_s,
        agreement: agreement(&hits),
    });
    Ok(result)
}

/// relMSE x time against Mitsuba 3 on the same scene and image, both unbiased and measured against Mitsuba's own
/// converged render (so any bias of ours counts against us).
#[derive(Clone, Debug, Default)]
pub struct MitsubaComparison {
    pub device: String,
    /// The scene's file stem (cornell-box, lamp-grid).
    pub scene: String,
    /// pathwave's light selection (--light-sampler).
    pub light_sampler: String,
    pub version: String,
    /// Mitsuba's variant, llvm_ad_rgb or (with pathwave spectral) llvm_ad_spectral.
    pub variant: String,
    pub width: u32,
    pub height: u32,
    pub reference_spp: u32,
    pub reference_cached: bool,
    /// Per round, (spp, seconds, relMSE) of: pathwave, Mitsuba with its default `independent` sampler, and Mitsuba
    /// with `ldsampler` ((0,2)-sequences, like pathwave's sampler; its spp a power of four).
    pub rounds: Vec<[(u32, f64, f64); 3]>,
    /// Median over rounds of (relMSE x time of pathwave) / (relMSE x time of Mitsuba): below 1, pathwave wins.
    pub ratio: f64,
    /// The same against Mitsuba with `ldsampler`.
    pub ratio_ld: f64,
    /// Per channel: pathwave's image mean over all rounds relative to the reference's, minus one.
    pub mean_deviation: [f64; 3],
    /// One standard error of that deviation, from pathwave's per-pixel sample variance.
    pub mean_sigma: [f64; 3],
    /// The same deviation for Mitsuba's rounds: checks the reference and the scene translation.
    pub mitsuba_mean_deviation: [f64; 3],
}

impl MitsubaComparison {
    /// Median over rounds of pathwave's relMSE x time.
    pub fn pathwave_score(&self) -> f64 {
        median(self.rounds.iter().map(|r| r[0].1 * r[0].2).collect())
    }

    pub fn summary(&self) -> String {
        let mut s = String::new();
        s += &format!(
            "equal time vs Mitsuba {} {} ({} {}x{}; pathwave {}, lights by {}; reference: Mitsuba at {} spp{}):\n",
            self.version,
            self.variant,
            self.scene,
            self.width,
            self.height,
            if self.variant.ends_with("spectral") {
                "--spectral"
            } else {
                "RGB"
            },
            self.light_sampler,
            self.reference_spp,
            if self.reference_cached { ", cached" } else { "" }
        );
        for (k, [(sp, tp, ep), (sm, tm, em), (sl, tl, el)]) in self.rounds.iter().enumerate() {
            s += &format!(
                "  round {}: pathwave {sp} spp {tp:.2} s relMSE {ep:.5} (x time {:.5}); Mitsuba {sm} spp {tm:.2} s \
                 relMSE {em:.5} (x time {:.5}), ratio {:.3}; Mitsuba ldsampler {sl} spp {tl:.2} s relMSE {el:.5} \
                 (x time {:.5}), ratio {:.3}\n",
                k + 1,
                ep * tp,
                em * tm,
                (ep * tp) / (em * tm),
                el * tl,
                (ep * tp) / (el * tl)
            );
        }
        let pct = |v: [f64; 3]| v.map(|x| format!("{:+.3}", 100.0 * x)).join(" ");
        s += &format!(
            "  median ratio of relMSE x time {:.3} (target <= 1.0); against Mitsuba with ldsampler {:.3}\n  channel \
             means vs reference, %: pathwave {} (one sigma {}, as if samples were independent); \
             Mitsuba {}\n",
            self.ratio,
            self.ratio_ld,
            pct(self.mean_deviation),
            self.mean_sigma.map(|x| format!("{:.3}", 100.0 * x)).join(" "),
            pct(self.mitsuba_mean_deviation)
        );
        s
    }

    pub fn json(&self) -> serde_json::Value {
        serde_json::json!({
            "scene": self.scene,
            "light_sampler": self.light_sampler,
            "variant": self.variant,
            "version": self.version,
            "width": self.width,
            "height": self.height,
            "reference_spp": self.reference_spp,
            "reference_cached": self.reference_cached,
            "rounds": self.rounds.iter().map(|[(sp, tp, ep), (sm, tm, em), (sl, tl, el)]| serde_json::json!({
                "pathwave": {"spp": sp, "seconds": tp, "rel_mse": ep},
                "mitsuba": {"spp": sm, "seconds": tm, "rel_mse": em},
                "mitsuba_ldsampler": {"spp": sl, "seconds": tl, "rel_mse": el},
            })).collect::<Vec<_>>(),
            "ratio": self.ratio,
            "ratio_ldsampler": self.ratio_ld,
            "mean_deviation": self.mean_deviation,
            "mean_sigma": self.mean_sigma,
            "mitsuba_mean_deviation": self.mitsuba_mean_deviation,
        })
    }
}

/// Writes `scene` for the helper: one PLY per material and a JSON description. Only what both renderers agree on
/// translates: Lambertian materials (KHR_materials_specular 0), emissive triangles (an emissive texture too: its
/// texels times the emissive factor, linear, in an EXR the emitter's bitmap reads bilinearly with the sampler's wrap
/// mode) and a pinhole camera. Returns the description's path and a text that names the scene's content (not where
/// its files are) for the reference cache.
fn write_mitsuba_scene(scene: &Scene, size: (u32, u32), dir: &Path) -> Result<(PathBuf, String), Error> {
    if scene.environment.is_some() || !scene.punctual.is_empty() {
        return Err(err("only scenes lit by emissive triangles translate to Mitsuba"));
    }
    let camera = scene.camera.ok_or_else(|| err("the scene has no camera"))?;
    let soup = scene.flatten();
    let mut meshes = Vec::new();
    let mut content = Vec::new();
    for (k, m) in scene.materials.iter().enumerate() {
        let lambertian = m.specular == 0.0 && m.metallic == 0.0 && m.transmission == 0.0;
        let emissive_map = m.emissive_texture.filter(|r| {
            let t = &scene.textures[r.texture];
            r.tex_coord == 0 && r.transform == scene::texture::IDENTITY_TRANSFORM && !t.nearest && t.wrap_s == t.wrap_t
        });
        let others = m.texture_refs().iter().filter(|r| r.is_some()).count();
        let textured = others > usize::from(emissive_map.is_some());
        let tris: Vec<usize> = (0..soup.len()).filter(|&t| soup.material()[t] as usize == k).collect();
        if tris.is_empty() {
            continue;
        }
        if !lambertian || textured || m.double_sided || m.alpha_tested() {
            return Err(err(format!(
                "material '{}' does not translate to Mitsuba (only single-sided Lambertian ones, untextured but for \
                 their emission, do)",
                m.name
            )));
        }
        let uv = if emissive_map.is_some() {
            "property float u\nproperty float v\n"
        } else {
            ""
        };
        let ply = dir.join(format!("mesh{k}.ply"));
        let mut bytes = format!(
            "ply\nformat binary_little_endian 1.0\nelement vertex {}\nproperty float x\nproperty float y\n\
             property float z\n{uv}element face {}\nproperty list uchar int vertex_indices\nend_header\n",
            3 * tris.len(),
            tris.len()
        )
        .into_bytes();
        for &t in &tris {
            for c in 0..3 {
                bytes.extend(soup.positions()[t][c].to_array().iter().flat_map(|x| x.to_le_bytes()));
                if emissive_map.is_some() {
                    let w = soup.texcoords()[t][c];
                    bytes.extend([w.x, w.y].iter().flat_map(|x| x.to_le_bytes()));
                }
            }
        }
        for f in 0..tris.len() as i32 {
            bytes.push(3);
            bytes.extend([3 * f, 3 * f + 1, 3 * f + 2].iter().flat_map(|i| i.to_le_bytes()));
        }
        let e = m.emission;
        let mut mesh = json!({
            "ply": format!("{:016x}", fnv_bytes(&bytes)),
            "reflectance": m.base_color.to_array(),
            "radiance": if e.max_element() > 0.0 { json!(e.to_array()) } else { Value::Null },
        });
        if let Some(r) = emissive_map.filter(|_| e.max_element() > 0.0) {
            let t = &scene.textures[r.texture];
            let image = &scene.images[t.image];
            let linear: Vec<[f32; 3]> = (image.texels.iter())
                .map(|p| std::array::from_fn(|c| crate::output::srgb_decode(p[c] as f32 / 255.0) * e[c]))
                .collect();
            let exr = dir.join(format!("emission{k}.exr"));
            crate::output::write_image(&exr, image.width, image.height, &linear, 0.0)?;
            let wrap = match t.wrap_s {
                scene::Wrap::Repeat => "repeat",
                scene::Wrap::ClampToEdge => "clamp",
                scene::Wrap::MirroredRepeat => "mirror",
            };
            let texels: Vec<u8> = linear.iter().flatten().flat_map(|x| x.to_le_bytes()).collect();
            mesh["radiance_texture"] = json!({"exr": format!("{:016x}", fnv_bytes(&texels)), "wrap": wrap});
            content.push(mesh.clone());
            mesh["radiance_texture"]["exr"] = json!(exr);
        } else {
            content.push(mesh.clone());
        }
        mesh["ply"] = json!(ply);
        std::fs::write(&ply, bytes).map_err(err)?;
        meshes.push(mesh);
    }
    let Projection::Perspective { yfov } = camera.projection else {
        return Err(err("the comparison renderers are given perspective cameras only"));
    };
    let (_, up, forward) = camera.basis();
    let o = camera.origin();
    let camera = json!({
        "origin": o.to_array(),
        "target": (o + forward).to_array(),
        "up": up.to_array(),
        "yfov_deg": yfov.to_degrees(),
        "width": size.0,
        "height": size.1,
    });
    let path = dir.join("scene.json");
    std::fs::write(&path, json!({"camera": camera, "meshes": meshes}).to_string()).map_err(err)?;
    Ok((path, json!({"camera": camera, "meshes": content}).to_string()))
}

/// relMSE of `img` against the reference mean `r`, less what the reference's own noise adds: `a` and `b` are the
/// reference's two halves, so (a - b)^2 / 4 estimates the variance of their mean per pixel.
fn rel_mse(img: &[f32], a: &[f32], b: &[f32]) -> f64 {
    let mut sum = 0.0;
    for ((x, a), b) in img.iter().zip(a).zip(b) {
        let r = 0.5 * (*a as f64 + *b as f64);
        let d = *x as f64 - r;
        let ref_var = 0.25 * (*a as f64 - *b as f64).powi(2);
        sum += (d * d - ref_var) / (r * r + 1e-2);
    }
    sum / img.len().max(1) as f64
}

fn channel_means(img: &[f32]) -> [f64; 3] {
    let mut m = [0.0; 3];
    for px in img.chunks_exact(3) {
        for c in 0..3 {
            m[c] += px[c] as f64;
        }
    }
    m.map(|s| s / (img.len() / 3).max(1) as f64)
}

fn cache_dir() -> PathBuf {
    if let Some(d) = std::env::var_os("XDG_CACHE_HOME").filter(|d| !d.is_empty()) {
        return PathBuf::from(d).join("pathwave/bench");
    }
    match std::env::var_os("HOME") {
        Some(h) => PathBuf::from(h).join(".cache/pathwave/bench"),
        None => std::env::temp_dir().join("pathwave-bench"),
    }
}

/// FNV-1a, for naming the cached reference after everything that decides it.
fn fnv_bytes(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325, |h, b| {
        (h ^ *b as u64).wrapping_mul(0x100_0000_01b3)
    })
}

/// One Mitsuba render of the loaded scene: its time and its pixels (RGB floats).
fn mitsuba_render(h: &mut Helper, pixels: usize, sampler: &str, spp: u32, seed: u32) -> Result<(f64, Vec<f32>), Error> {
    let out = h.path("mitsuba.f32");
    let r = h.call(json!({"cmd": "mitsuba_render", "sampler": sampler, "spp": spp, "seed": seed, "out": out}))?;
    let img = read_f32(&out)?;
    if img.len() != 3 * pixels {
        return Err(err(format!(
            "Mitsuba returned {} floats for {pixels} pixels",
            img.len()
        )));
    }
    Ok((Helper::f64(&r, "seconds")?, img))
}

/// The reference: Mitsuba's, in two independent halves, cached under a name that changes with `key_text` (the
/// scene, the image, the sample count and Mitsuba's version). Returns the halves and whether they came from the cache.
fn mitsuba_reference(
    h: &mut Helper,
    pixels: usize,
    key_text: &str,
    reference_spp: u32,
    progress: &mut dyn FnMut(&str),
) -> Result<(Vec<f32>, Vec<f32>, bool), Error> {
    let key = format!("{:016x}", fnv_bytes(key_text.as_bytes()));
    let cache = cache_dir().join(format!("cornell-reference-{key}"));
    if let (Ok(a), Ok(b)) = (read_f32(&cache.join("a.f32")), read_f32(&cache.join("b.f32"))) {
        if a.len() == 3 * pixels && b.len() == 3 * pixels {
            return Ok((a, b, true));
        }
    }
    let chunk = 256.min(reference_spp / 2);
    let chunks = reference_spp / 2 / chunk;
    let mut halves = [vec![0f32; 3 * pixels], vec![0f32; 3 * pixels]];
    for (half, acc) in halves.iter_mut().enumerate() {
        for c in 0..chunks {
            progress(&format!(
                "Mitsuba reference, {} of {} spp (cached afterwards in {})",
                (half as u32 * chunks + c) * chunk,
                reference_spp,
                cache.display()
            ));
            let seed = 1_000_000 + half as u32 * chunks + c;
            let (_, img) = mitsuba_render(h, pixels, "independent", chunk, seed)?;
            for (s, v) in acc.iter_mut().zip(img) {
                *s += v / chunks as f32;
            }
        }
    }
    std::fs::create_dir_all(&cache).map_err(err)?;
    write_f32(&cache.join("a.f32"), &halves[0])?;
    write_f32(&cache.join("b.f32"), &halves[1])?;
    let [a, b] = halves;
    Ok((a, b, false))
}

/// Mitsuba 3 against pathwave at equal time on the Cornell box. One function past 80 lines: warm-up, calibration
/// and the interleaved rounds share both renderers and the reference, and read best as the one procedure they are.
/// What a Mitsuba comparison renders: a scene file (lit by emissive Lambertian triangles only), spectral or RGB,
/// and pathwave's light selection.
pub struct MitsubaCase<'a> {
    pub scene: &'a Path,
    pub spectral: bool,
    pub light_sampler: LightSampler,
    /// Image size and the reference's samples per pixel (both smaller with --quick).
    pub size: (u32, u32),
    pub reference_spp: u32,
}

pub fn compare_mitsuba(
    python: &Path,
    device: &DeviceChoice,
    case: MitsubaCase,
    quick: bool,
    progress: &mut dyn FnMut(&str),
) -> Result<MitsubaComparison, Error> {
    let MitsubaCase {
        scene: path,
        spectral,
        light_sampler,
        size,
        reference_spp,
    } = case;
    let variant = if spectral { "llvm_ad_spectral" } else { "llvm_ad_rgb" };
    let size = if quick { (64, 64) } else { size };
    let (reference_spp, budget_s, rounds) = if quick { (256, 0.5, 2) } else { (reference_spp, 8.0, 3) };
    let mut h = Helper::start(python)?;
    let scene = scene::load(path, None)?;
    let dir = h.dir.path().to_path_buf();
    let (desc_path, desc) = write_mitsuba_scene(&scene, size, &dir)?;
    let loaded = h
        .call(json!({"cmd": "mitsuba_load", "scene": desc_path, "variant": variant}))
        .map_err(|e| {
            err(format!(
                "{e}; Mitsuba 3 needs `pip install mitsuba` and, for {variant}, `apt-get install libllvm19`"
            ))
        })?;
    let version = loaded["version"].as_str().unwrap_or("?").to_string();
    let pixels = (size.0 * size.1) as usize;
    let mitsuba_with =
        |h: &mut Helper, sampler: &str, spp: u32, seed: u32| mitsuba_render(h, pixels, sampler, spp, seed);
    let mitsuba = |h: &mut Helper, spp: u32, seed: u32| mitsuba_with(h, "independent", spp, seed);
    // The RGB reference keeps its old name; the spectral one is another image.
    let key_text = format!("{desc}{version}{reference_spp}{}", if spectral { variant } else { "" });
    let (ref_a, ref_b, reference_cached) = mitsuba_reference(&mut h, pixels, &key_text, reference_spp, progress)?;

    let ctx = Context::new(device, Validation::Off)?;
    let device = ctx.device_name();
    let mut r = Renderer::with_context(&scene, ctx)?;
    let sampler_name = (r.light_sampler_run(&RenderSettings {
        light_sampler,
        ..Default::default()
    }))
    .unwrap_or("none");
    let mut pathwave = |spp: u32, seed: u32| -> Result<(f64, Vec<f32>, Vec<f32>), Error> {
        let settings = RenderSettings {
            width: size.0,
            height: size.1,
            spp,
            seed,
            spectral,
            light_sampler,
            ..Default::default()
        };
        let (film, stats) = r.render(&settings, &mut |_| {})?;
        let img: Vec<f32> = film.mean().into_iter().flatten().collect();
        let var: Vec<f32> = film.sample_variance().into_iter().flatten().collect();
        Ok((stats.wall.as_secs_f64(), img, var))
    };
    // Warm-up, which also calibrates: both renderers compile on their first render, so the second one's time per
    // sample sets each one's spp for the budget. pathwave's first four passes also choose its schedule on a CPU
    // device (render::Schedule), so it warms up for four renders of one pass each.
    progress("Mitsuba comparison: warming up");
    let probe_spp = if quick { 4 } else { 16 };
    for seed in 0..4 {
        pathwave(probe_spp, 99 - seed)?;
    }
    let (t_ours, _, _) = pathwave(probe_spp, 95)?;
    mitsuba(&mut h, probe_spp, 99)?;
    let (t_theirs, _) = mitsuba(&mut h, probe_spp, 98)?;
    mitsuba_with(&mut h, "ldsampler", probe_spp, 99)?;
    let spp_for = |t: f64| ((budget_s / (t / probe_spp as f64)).round() as u32).clamp(1, 4096);
    let (spp_ours, spp_theirs) = (spp_for(t_ours), spp_for(t_theirs));
    // ldsampler takes a power of four; the nearest one to the budget (time is part of the figure either way).
    let spp_ld = 1u32 << (2 * (spp_theirs as f64).log(4.0).round() as u32);

    let mut result = MitsubaComparison {
        device,
        scene: path
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default(),
        light_sampler: sampler_name.into(),
        version,
        variant: variant.into(),
        width: size.0,
        height: size.1,
        reference_spp,
        reference_cached,
        ..Default::default()
    };
    let reference_means = channel_means(&ref_a.iter().zip(&ref_b).map(|(a, b)| 0.5 * (a + b)).collect::<Vec<_>>());
    let (mut ours_means, mut ours_var, mut theirs_means) = ([0.0; 3], [0.0; 3], [0.0; 3]);
    for round in 0..rounds {
        progress(&format!("Mitsuba comparison: round {} of {rounds}", round + 1));
        let (t_p, img_p, var_p) = pathwave(spp_ours, round)?;
        let (t_m, img_m) = mitsuba(&mut h, spp_theirs, round)?;
        let (t_l, img_l) = mitsuba_with(&mut h, "ldsampler", spp_ld, round)?;
        let e_p = rel_mse(&img_p, &ref_a, &ref_b);
        let e_m = rel_mse(&img_m, &ref_a, &ref_b);
        let e_l = rel_mse(&img_l, &ref_a, &ref_b);
        result
            .rounds
            .push([(spp_ours, t_p, e_p), (spp_theirs, t_m, e_m), (spp_ld, t_l, e_l)]);
        let (mp, mm) = (channel_means(&img_p), channel_means(&img_m));
        // Variance of the image mean: per-pixel sample variance / spp, summed, over pixels squared.
        let vp = channel_means(&var_p).map(|v| v / spp_ours as f64 / pixels as f64);
        for c in 0..3 {
            ours_means[c] += mp[c] / rounds as f64;
            theirs_means[c] += mm[c] / rounds as f64;
            ours_var[c] += vp[c] / (rounds * rounds) as f64;
        }
    }
    let ratio_to = |k: usize| {
        median(
            result
                .rounds
                .iter()
                .map(|r| (r[0].1 * r[0].2) / (r[k].1 * r[k].2))
                .collect(),
        )
    };
    (result.ratio, result.ratio_ld) = (ratio_to(1), ratio_to(2));
    for c in 0..3 {
        result.mean_deviation[c] = ours_means[c] / reference_means[c] - 1.0;
        result.mean_sigma[c] = ours_var[c].sqrt() / reference_means[c];
        result.mitsuba_mean_deviation[c] = theirs_means[c] / reference_means[c] - 1.0;
    }
    Ok(result)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rel_mse_subtracts_the_reference_noise() {
        // Halves 1 and 3 average to 2 and say the reference's own variance is (3 - 1)^2 / 4 = 1.
        let (a, b) = (vec![1.0f32; 4], vec![3.0f32; 4]);
        let exact = rel_mse(&[2.0; 4], &a, &b);
        assert!((exact + 1.0 / 4.01).abs() < 1e-9, "{exact}");
        let off = rel_mse(&[4.0; 4], &a, &b);
        assert!((off - 3.0 / 4.01).abs() < 1e-9, "{off}");
        assert_eq!(rel_mse(&[2.0; 4], &[2.0; 4], &[2.0; 4]), 0.0);
    }

    #[test]
    fn random_rays_are_repeatable_unit_and_inside_the_bounds() {
        let scene = terrain(8);
        let a = random_rays(&scene, 1000, 7);
        assert_eq!(a, random_rays(&scene, 1000, 7));
        assert_ne!(a, random_rays(&scene, 1000, 8));
        for r in &a {
            assert!((r.dir.length() - 1.0).abs() < 1e-5);
            assert!(r.origin.x.abs() <= 1.0 && r.origin.z.abs() <= 1.0 && r.origin.y.abs() < 0.2);
        }
        // Directions cover the sphere: each octant gets about an eighth.
        for octant in 0..8 {
            let k = a
                .iter()
                .filter(|r| {
                    (r.dir.x > 0.0) as usize + 2 * (r.dir.y > 0.0) as usize + 4 * (r.dir.z > 0.0) as usize == octant
                })
                .count();
            assert!((80..170).contains(&k), "octant {octant}: {k} of 1000");
        }
    }
}
