//! What a bench run found, as the table it prints and as JSON.
use super::adaptive;
use super::compare::{self, EmbreeComparison, MitsubaComparison};
use super::measure::CaseResult;
use std::time::Duration;

pub struct BenchReport {
    pub device: String,
    pub cases: Vec<CaseResult>,
    /// A 64x64, 1-spp Cornell box render as a whole process, after one run warmed the shader cache.
    pub startup_s: Option<f64>,
    pub embree: Option<EmbreeComparison>,
    pub mitsuba: Option<MitsubaComparison>,
    /// The same with spectral transport, against Mitsuba's llvm_ad_spectral.
    pub mitsuba_spectral: Option<MitsubaComparison>,
    /// The lamp grid, the city block and the emissive panel, once per light sampler.
    pub mitsuba_lights: Vec<MitsubaComparison>,
    /// scenes/subsurface.gltf (scattering media behind glass) against Mitsuba's volpath.
    pub mitsuba_media: Option<MitsubaComparison>,
    /// The light BVH's build over the terrain with every triangle emitting: (emitters, depth, seconds).
    pub light_tree: Option<(usize, u32, f64)>,
    /// With the Mitsuba comparison: --adaptive against uniform sampling at equal time, per scene.
    pub adaptive: Vec<adaptive::AdaptiveComparison>,
    pub total: Duration,
}

impl BenchReport {
    pub fn table(&self) -> String {
        let mut s = format!(
            "pathwave bench on {} ({:.0} s in all)\n",
            self.device,
            self.total.as_secs_f64()
        );
        if let Some(t) = self.startup_s {
            s += &format!("start-up, 64x64 Cornell box at 1 spp, whole process: {t:.2} s\n");
        }
        if !self.cases.is_empty() {
            s += &self.cases_table();
        }
        if let Some((emitters, depth, build)) = self.light_tree {
            s += &format!("light tree over the terrain, every triangle emitting: {emitters} emitters, depth {depth}, built in {build:.3} s\n");
        }
        if let Some(e) = &self.embree {
            s += &format!(
                "traversal vs Embree ({} tris, {} random rays, closest hit, {} threads; BVH build {:.2} s vs {:.2} s):\n",
                e.triangles, e.rays, e.threads, e.pathwave_build_s, e.embree_build_s
            );
            for (k, (ours, theirs)) in e.rounds.iter().enumerate() {
                s += &format!(
                    "  round {}: pathwave {:.2} Mrays/s, Embree {:.2} Mrays/s, ratio {:.3}\n",
                    k + 1,
                    ours * 1e-6,
                    theirs * 1e-6,
                    ours / theirs
                );
            }
            s += &format!(
                "  median ratio {:.3} (target >= 0.5); hits agree on {:.3} % of rays{}\n",
                e.ratio,
                100.0 * e.agreement,
                if e.traversal == "compute" {
                    ""
                } else {
                    " (pathwave with ray queries)"
                }
            );
            if let Some(q) = &e.ray_query {
                let rates: Vec<String> = q.rays_per_s.iter().map(|r| format!("{:.2}", r * 1e-6)).collect();
                let over: Vec<f64> = q.rays_per_s.iter().zip(&e.rounds).map(|(q, (c, _))| q / c).collect();
                s += &format!(
                    "  the same rays with ray queries: {} Mrays/s by round, {:.3} x the compute BVH (median); \
                     structures built in {:.2} s; hits agree with Embree's on {:.3} %\n",
                    rates.join(", "),
                    compare::median(over),
                    q.build_s,
                    100.0 * q.agreement
                );
            }
        }
        for m in self
            .mitsuba
            .iter()
            .chain(&self.mitsuba_spectral)
            .chain(&self.mitsuba_media)
            .chain(&self.mitsuba_lights)
        {
            s += &m.summary();
        }
        if let (Some(rgb), Some(spectral)) = (&self.mitsuba, &self.mitsuba_spectral) {
            s += &format!(
                "spectral transport's cost (pathwave, Cornell box {}x{}): {} against {} spp in the same budget; \
                 relMSE x time, spectral over RGB (each against its own Mitsuba reference): {:.3}\n",
                rgb.width,
                rgb.height,
                spectral.rounds.first().map_or(0, |r| r[0].0),
                rgb.rounds.first().map_or(0, |r| r[0].0),
                spectral.pathwave_score() / rgb.pathwave_score()
            );
        }
        for a in &self.adaptive {
            s += &a.summary();
        }
        s
    }

    /// Ray queries against the compute BVH, case by case where both ran: samples/s and extension rays/s of the
    /// extend stage, ray queries over compute (above 1: ray queries are faster).
    fn traversal_ratios(&self) -> Option<String> {
        let mut s = String::new();
        for rq in self.cases.iter().filter(|c| c.traversal == "ray queries") {
            let Some(base) = rq.name.strip_suffix("+rq") else {
                continue;
            };
            let Some(compute) = self.cases.iter().find(|c| c.name == base) else {
                continue;
            };
            let extend = if rq.extend_stage_rays_per_s > 0.0 && compute.extend_stage_rays_per_s > 0.0 {
                format!("{:.2}", rq.extend_stage_rays_per_s / compute.extend_stage_rays_per_s)
            } else {
                "-".into()
            };
            s += &format!(
                "  {:<22} samples/s {:.2}, extend-stage rays/s {}\n",
                base,
                rq.samples_per_s / compute.samples_per_s.max(1e-9),
                extend
            );
        }
        (!s.is_empty()).then(|| format!("ray queries over the compute BVH (above 1: ray queries faster):\n{s}"))
    }

    fn cases_table(&self) -> String {
        let mut s = format!(
            "{:<22} {:>9} {:>9} {:>9} {:>9} {:>10} {:>9} {:>9} {:>10} {:>8} {:>7}\n",
            "case",
            "tris",
            "process",
            "render",
            "1st pass",
            "samples/s",
            "ext Mr/s",
            "shd Mr/s",
            "extend Mr/s",
            "bvh s",
            "B/tri"
        );
        for c in &self.cases {
            s += &format!(
                "{:<22} {:>9} {:>9} {:>9.2} {:>9.2} {:>10.0} {:>9.2} {:>9.2} {:>10} {:>8.3} {:>7.1}\n",
                c.name,
                c.triangles,
                c.process_s.map_or("-".into(), |t| format!("{t:.2}")),
                c.render_s,
                c.first_pass_s,
                c.samples_per_s,
                c.extension_rays_per_s * 1e-6,
                c.shadow_rays_per_s * 1e-6,
                // The fused schedule has no extend stage to time.
                if c.extend_stage_rays_per_s > 0.0 {
                    format!("{:.2}", c.extend_stage_rays_per_s * 1e-6)
                } else {
                    "-".into()
                },
                c.bvh_build_s,
                c.bytes_per_triangle
            );
        }
        s += "GPU ms per stage (the passes after the first, or the only one):\n";
        for c in &self.cases {
            let stages: Vec<String> = c.stage_ms.iter().map(|(l, ms)| format!("{l} {ms:.1}")).collect();
            let schedule = format!("({})", c.schedule);
            s += &format!("  {:<22} {:<11} {}\n", c.name, schedule, stages.join(", "));
        }
        // Ray queries' cases: their structures beside the compute BVH (bvh s and B/tri above are the compute BVH's,
        // which such a scene uploads too).
        for c in &self.cases {
            if let Some((bytes, uncompacted, build_s)) = c.ray_query_structures {
                s += &format!(
                    "  {:<22} ray-query structures {:.1} MiB compacted from {:.1} MiB ({:.1} B/tri), built in {:.3} s\n",
                    c.name,
                    bytes as f64 / (1 << 20) as f64,
                    uncompacted as f64 / (1 << 20) as f64,
                    bytes as f64 / c.triangles.max(1) as f64,
                    build_s
                );
            }
        }
        if let Some(ratios) = self.traversal_ratios() {
            s += &ratios;
        }
        s
    }

    pub fn json(&self) -> String {
        let cases: Vec<serde_json::Value> = self
            .cases
            .iter()
            .map(|c| {
                serde_json::json!({
                    "name": c.name,
                    "triangles": c.triangles,
                    "width": c.size.0,
                    "height": c.size.1,
                    "spp": c.spp,
                    "process_s": c.process_s,
                    "render_s": c.render_s,
                    "first_pass_s": c.first_pass_s,
                    "samples_per_s": c.samples_per_s,
                    "extension_rays_per_s": c.extension_rays_per_s,
                    "shadow_rays_per_s": c.shadow_rays_per_s,
                    "extend_stage_rays_per_s": c.extend_stage_rays_per_s,
                    "stage_ms": c.stage_ms.iter().map(|(l, ms)| (l.clone(), serde_json::json!(ms))).collect::<serde_json::Map<_, _>>(),
                    "schedule": c.schedule,
                    "bvh_build_s": c.bvh_build_s,
                    "bytes_per_triangle": c.bytes_per_triangle,
                    "image_mean": c.image_mean,
                    "traversal": c.traversal,
                    "ray_query_structures": c.ray_query_structures.map(|(bytes, uncompacted, build_s)| serde_json::json!({"bytes": bytes, "uncompacted_bytes": uncompacted, "build_s": build_s})),
                })
            })
            .collect();
        serde_json::to_string_pretty(&serde_json::json!({
            "device": self.device,
            "startup_s": self.startup_s,
            "embree": self.embree.as_ref().map(|e| serde_json::json!({
                "triangles": e.triangles,
                "rays": e.rays,
                "threads": e.threads,
                "embree_build_s": e.embree_build_s,
                "pathwave_build_s": e.pathwave_build_s,
                "rounds": e.rounds.iter().map(|(a, b)| serde_json::json!({"pathwave_rays_per_s": a, "embree_rays_per_s": b})).collect::<Vec<_>>(),
                "ratio": e.ratio,
                "agreement": e.agreement,
                "traversal": e.traversal,
                "ray_query": e.ray_query.as_ref().map(|q| serde_json::json!({"rays_per_s": q.rays_per_s, "build_s": q.build_s, "agreement": q.agreement})),
            })),
            "mitsuba": self.mitsuba.as_ref().map(|m| m.json()),
            "mitsuba_spectral": self.mitsuba_spectral.as_ref().map(|m| m.json()),
            "mitsuba_lights": self.mitsuba_lights.iter().map(|m| m.json()).collect::<Vec<_>>(),
            "mitsuba_media": self.mitsuba_media.as_ref().map(|m| m.json()),
            "light_tree": self.light_tree.map(|(emitters, depth, build_s)| serde_json::json!({"emitters": emitters, "depth": depth, "build_s": build_s})),
            "adaptive": self.adaptive.iter().map(|a| a.json()).collect::<Vec<_>>(),
            "total_s": self.total.as_secs_f64(),
            "cases": cases,
        }))
        .unwrap_or_default()
    }
}
