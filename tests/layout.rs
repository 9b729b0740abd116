//! Owns the Rust/GLSL layout contract: every struct in src/layout.rs must match its GLSL twin in shaders/include/layout.glsl, as read from the compiled SPIR-V by naga.
use pathwave::layout::{
    AovSums, BsdfRecord, BvhNode, Counters, DebugSums, EnvRecord, Frame, GpuInstance, GpuLight, GpuLightNode,
    GpuMaterial, GpuPunctual, GpuTexture, LightSelectRecord, MotionKey, PhaseRecord, TextureSlot, ToneMap, TraceRecord,
    TriColors, TriShading, TriTangents, TriTexcoords, TriVerts,
};
use pathwave::render::{builtin_spirv, builtin_stage_names};

mod common;

/// The push-constant size every Vulkan implementation guarantees (maxPushConstantsSize >= 128).
const PUSH_CONSTANT_BUDGET: usize = 128;

/// One field of a Rust mirror: name, byte offset, byte size.
struct RustField {
    name: &'static str,
    offset: usize,
    size: usize,
}

/// A Rust mirror and the name of its GLSL struct.
struct Mirror {
    rust: &'static str,
    glsl: &'static str,
    size: usize,
    fields: Vec<RustField>,
}

/// `mirror!(RustType => "GlslName", [field, ...])`, fields in declaration order.
macro_rules! mirror {
    ($ty:ty => $glsl:literal, [$($field:ident),+ $(,)?]) => {{
        let zero = <$ty as bytemuck::Zeroable>::zeroed();
        Mirror {
            rust: stringify!($ty),
            glsl: $glsl,
            size: std::mem::size_of::<$ty>(),
            fields: vec![$(RustField {
                name: stringify!($field),
                offset: std::mem::offset_of!($ty, $field),
                size: std::mem::size_of_val(&zero.$field),
            }),+],
        }
    }};
}

/// Adding a shared struct is one line here.
fn mirrors() -> Vec<Mirror> {
    vec![
        mirror!(BvhNode => "BvhNode", [origin, q0, q1]),
        mirror!(TriVerts => "TriVerts", [v0, e1, e2]),
        mirror!(TriShading => "TriShading", [n0, n1, n2]),
        mirror!(GpuMaterial => "Material", [base_color, emission, params, specular_color, transmission, attenuation, alpha, clearcoat, sheen, anisotropy, iridescence, diffuse_transmission, textures, medium, base_color_spectrum, emission_spectrum]),
        mirror!(TextureSlot => "TextureSlot", [u, v]),
        mirror!(ToneMap => "ToneMap", [film_width, film_height, out_width, out_height, samples, op, exposure, pad]),
        mirror!(GpuTexture => "TextureInfo", [offset, width, height, flags]),
        mirror!(TriTexcoords => "TriTexcoords", [t0, t1, t2]),
        mirror!(TriTangents => "TriTangents", [t0, t1, t2]),
        mirror!(TriColors => "TriColors", [c0, c1, c2]),
        mirror!(MotionKey => "MotionKey", [v0, e1, e2, n0, n1, n2]),
        mirror!(GpuLight => "Light", [id, cdf, prob, area]),
        mirror!(GpuLightNode => "LightNode", [sphere, cone, angles, link]),
        mirror!(LightSelectRecord => "LightSelectRecord", [p, entry, n, u, v, picked, prob, pmf, sub_entry, sub_picked, pad0, pad1]),
        mirror!(GpuPunctual => "PunctualLight", [position, direction, intensity]),
        mirror!(Counters => "Counters", [queue_count, dispatch, extension_rays, shadow_rays, follow_cut, nonfinite, stage_cut, budget_max, pad1, pad2]),
        mirror!(TraceRecord => "TraceRecord", [origin, tmin, dir, tmax, time, inst, key, pad2, t, tri, uv]),
        mirror!(GpuInstance => "Instance", [world0, world1, world2, object0, object1, object2, info, light]),
        mirror!(AovSums => "AovSums", [albedo, normal, position, ids]),
        mirror!(DebugSums => "DebugSums", [geometric, shading, uv]),
        mirror!(BsdfRecord => "BsdfRecord", [wo, material, x, front, wi, pdf, weight, flags, eval, pdf_wi, eval_reverse, pad0]),
        mirror!(EnvRecord => "EnvRecord", [x, pdf, dir, pdf_dir, radiance, pad0]),
        mirror!(PhaseRecord => "PhaseRecord", [d_in, g, x, pdf, wi, pad0]),
        mirror!(Frame => "Frame", [
            cam_origin, cam_right, cam_up, cam_forward, width, height, sample_index, seed, bounce,
            max_depth, pass_pixels, pixel_offset, path_count, path_capacity, light_count, flags, env_prob, env_rotation, env_width, env_height,
        ]),
    ]
}

fn parse_all_stages() -> Vec<(&'static str, naga::Module)> {
    // naga 30's spv-in has neither the SampledBuffer nor the RayQueryKHR capability, so the TEXEL_READS and
    // RAY_QUERY variants cannot be read. They are the same sources as their storage-buffer, compute-BVH twins
    // (parsed here) with texel fetches or ray queries added, so their structs are the same.
    let unreadable = |n: &str| n.ends_with("_texel") || n.ends_with("_rq");
    let names: Vec<&str> = builtin_stage_names().filter(|n| !unreadable(n)).collect();
    assert!(builtin_stage_names().filter(|n| unreadable(n)).all(|n| {
        let twin = n
            .trim_end_matches("_texel")
            .trim_end_matches("_rq")
            .trim_end_matches('_');
        builtin_stage_names().any(|m| m == twin)
    }));
    assert!(!names.is_empty(), "no built-in shader stages");
    let mut modules = Vec::new();
    let mut errors = Vec::new();
    for name in names {
        let spv = builtin_spirv(name).unwrap_or_else(|| panic!("builtin_spirv({name:?}) is None"));
        match naga::front::spv::parse_u8_slice(spv, &naga::front::spv::Options::default()) {
            Ok(module) => modules.push((name, module)),
            Err(e) => errors.push(format!("{name}: naga cannot parse the SPIR-V: {e}")),
        }
    }
    assert!(errors.is_empty(), "{}", errors.join("\n"));
    modules
}

/// Compares one GLSL struct (members with name, offset, size; and span) with its Rust mirror.
/// A GLSL run `pad0, pad1, ...` may stand for one Rust array field `pad`: its members must tile
/// the Rust field exactly, in order.
fn compare(m: &Mirror, members: &[(String, u32, u32)], span: u32, errors: &mut Vec<String>) {
    let at = format!("{} (Rust {})", m.glsl, m.rust);
    if span as usize != m.size {
        errors.push(format!("{at}: size is {span} in GLSL, {} in Rust", m.size));
    }
    let mut fields = m.fields.iter().peekable();
    let mut consumed = 0usize; // bytes of the current Rust field already matched by split GLSL members
    for (name, offset, size) in members {
        let (offset, size) = (*offset as usize, *size as usize);
        let Some(field) = fields.peek() else {
            errors.push(format!(
                "{at}: GLSL member `{name}` (offset {offset}) has no Rust field; GLSL has more members"
            ));
            continue;
        };
        let split = consumed > 0
            || (name != field.name
                && name
                    .strip_prefix(field.name)
                    .is_some_and(|d| !d.is_empty() && d.bytes().all(|b| b.is_ascii_digit())));
        if !split && name != field.name {
            errors.push(format!(
                "{at}: member order/name differs: GLSL `{name}` (offset {offset}) vs Rust `{}` (offset {})",
                field.name, field.offset
            ));
            fields.next();
            continue;
        }
        let expected = field.offset + consumed;
        if offset != expected {
            errors.push(format!(
                "{at}.{name}: offset is {offset} in GLSL, {expected} in Rust (`{}`{})",
                field.name,
                if split { format!(" + {consumed}") } else { String::new() }
            ));
        }
        if split {
            consumed += size;
            if consumed >= field.size {
                if consumed > field.size {
                    errors.push(format!(
                        "{at}.{name}: GLSL members `{}*` cover {consumed} bytes, Rust `{}` is {} bytes",
                        field.name, field.name, field.size
                    ));
                }
                consumed = 0;
                fields.next();
            }
        } else {
            if size != field.size {
                errors.push(format!("{at}.{name}: size is {size} in GLSL, {} in Rust", field.size));
            }
            fields.next();
        }
    }
    if consumed > 0 {
        errors.push(format!(
            "{at}: GLSL members cover only {consumed} bytes of a split Rust field"
        ));
    }
    for field in fields {
        errors.push(format!(
            "{at}: Rust field `{}` (offset {}) has no GLSL member; Rust has more fields",
            field.name, field.offset
        ));
    }
}

/// Types reachable from storage, uniform and push-constant globals: the only ones whose offsets come
/// from explicit `Offset` decorations. (A function-local copy of a struct is a separate, undecorated
/// SPIR-V type that naga lays out by its own rules, so it says nothing about the host layout.)
fn buffer_types(module: &naga::Module) -> Vec<naga::Handle<naga::Type>> {
    let mut stack: Vec<_> = module
        .global_variables
        .iter()
        .filter(|(_, g)| {
            matches!(
                g.space,
                naga::AddressSpace::Storage { .. } | naga::AddressSpace::Uniform | naga::AddressSpace::Immediate
            )
        })
        .map(|(_, g)| g.ty)
        .collect();
    let mut seen = Vec::new();
    while let Some(h) = stack.pop() {
        if seen.contains(&h) {
            continue;
        }
        seen.push(h);
        match &module.types[h].inner {
            naga::TypeInner::Struct { members, .. } => stack.extend(members.iter().map(|m| m.ty)),
            naga::TypeInner::Array { base, .. } | naga::TypeInner::BindingArray { base, .. } => stack.push(*base),
            _ => {}
        }
    }
    seen
}

#[test]
fn rust_mirrors_match_spirv_layouts() {
    let modules = parse_all_stages();
    let mirrors = mirrors();
    // Each distinct mismatch once, with the stages it shows up in.
    let mut errors: Vec<(String, Vec<&str>)> = Vec::new();
    for m in &mirrors {
        let mut found_in = Vec::new();
        for (stage, module) in &modules {
            for handle in buffer_types(module) {
                let ty = &module.types[handle];
                let naga::TypeInner::Struct { members, span } = &ty.inner else {
                    continue;
                };
                if ty.name.as_deref() != Some(m.glsl) {
                    continue;
                }
                let members: Vec<(String, u32, u32)> = members
                    .iter()
                    .map(|mem| {
                        let size = module.types[mem.ty].inner.size(module.to_ctx());
                        (mem.name.clone().unwrap_or_default(), mem.offset, size)
                    })
                    .collect();
                let mut found = Vec::new();
                compare(m, &members, *span, &mut found);
                for e in found {
                    match errors.iter_mut().find(|(msg, _)| *msg == e) {
                        Some((_, stages)) => stages.push(stage),
                        None => errors.push((e, vec![stage])),
                    }
                }
                found_in.push(*stage);
            }
        }
        if found_in.is_empty() {
            let e = format!(
                "struct {} (Rust {}) is in no stage's SPIR-V buffer or push constants: renamed or unused?",
                m.glsl, m.rust
            );
            errors.push((e, Vec::new()));
        }
        eprintln!(
            "{:<10} {:>3} bytes, {:>2} fields: checked in {:?}",
            m.glsl,
            m.size,
            m.fields.len(),
            found_in
        );
    }
    let report: Vec<String> = errors
        .iter()
        .map(|(e, stages)| format!("{e}  [stages: {}]", stages.join(", ")))
        .collect();
    assert!(errors.is_empty(), "layout mismatches:\n{}", report.join("\n"));
}

#[test]
fn push_constants_fit_the_guaranteed_budget() {
    assert_eq!(
        std::mem::size_of::<Frame>(),
        PUSH_CONSTANT_BUDGET,
        "Rust Frame must be exactly 128 bytes"
    );
    let mut errors = Vec::new();
    for (stage, module) in parse_all_stages() {
        let blocks: Vec<_> = module
            .global_variables
            .iter()
            .filter(|(_, g)| g.space == naga::AddressSpace::Immediate)
            .collect();
        let [(_, block)] = blocks.as_slice() else {
            errors.push(format!(
                "{stage}: expected one push-constant block, found {}",
                blocks.len()
            ));
            continue;
        };
        let ty = &module.types[block.ty];
        let size = ty.inner.size(module.to_ctx()) as usize;
        if size > PUSH_CONSTANT_BUDGET {
            errors.push(format!(
                "{stage}: push-constant block is {size} bytes, over the {PUSH_CONSTANT_BUDGET}-byte budget"
            ));
        }
        // The block wraps a single `Frame frame;` member at offset 0; the tone map has its own `ToneMap tone;`.
        let wraps = |name: &str| match &ty.inner {
            naga::TypeInner::Struct { members, .. } => {
                members.len() == 1
                    && members[0].offset == 0
                    && module.types[members[0].ty].name.as_deref() == Some(name)
            }
            _ => false,
        };
        if stage == "tonemap" && wraps("ToneMap") {
            continue;
        }
        match &ty.inner {
            naga::TypeInner::Struct { members, .. }
                if members.len() == 1
                    && members[0].offset == 0
                    && module.types[members[0].ty].name.as_deref() == Some("Frame") =>
            {
                let frame = module.types[members[0].ty].inner.size(module.to_ctx()) as usize;
                if frame != PUSH_CONSTANT_BUDGET {
                    errors.push(format!(
                        "{stage}: GLSL Frame is {frame} bytes, must be exactly {PUSH_CONSTANT_BUDGET}"
                    ));
                }
            }
            other => errors.push(format!(
                "{stage}: push-constant block is not `{{ Frame frame; }}`: {other:?}"
            )),
        }
    }
    assert!(errors.is_empty(), "{}", errors.join("\n"));
}

/// Every constant build.rs exports to GLSL has, as the device computes it, the value Rust gives it. A constant
/// exported without parentheses or with a stray suffix (the generated ENERGY_TABLE_FLOATS once ended in
/// `ENERGY_RESu`) either fails to compile in probe_constants or gives another number here.
#[test]
fn shared_constants_have_the_same_values_in_glsl() {
    let mut r = common::renderer(&common::scenes_dir().join("cornell-box.gltf"));
    let device = r.probe_constants().unwrap();
    let mut wrong = Vec::new();
    for ((name, rust), glsl) in pathwave::shaders::SHARED_CONSTANTS.iter().zip(&device) {
        if rust != glsl {
            wrong.push(format!("{name}: Rust {rust:#x}, GLSL {glsl:#x}"));
        }
    }
    assert_eq!(device.len(), pathwave::shaders::SHARED_CONSTANTS.len());
    assert!(wrong.is_empty(), "{}", wrong.join("\n"));
    for expression in ["ENERGY_TABLE_FLOATS", "MAX_SCENE_ITEMS"] {
        assert!(pathwave::shaders::SHARED_CONSTANTS
            .iter()
            .any(|(n, _)| *n == expression));
    }
}
