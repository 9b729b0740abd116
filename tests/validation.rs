//! The validation layer's plumbing: it catches a real error, and a render passes synchronization validation.
mod common;

use ash::vk;
use pathwave::vk::{Context, DeviceChoice, Validation};

#[test]
fn the_layer_reports_a_deliberate_error() {
    if !common::validation_layer_installed() {
        eprintln!("skipped: VK_LAYER_KHRONOS_validation is not installed");
        return;
    }
    // Without this check a broken messenger would make every "no validation errors" test pass vacuously.
    let ctx = Context::new(&DeviceChoice::Best, Validation::On).unwrap();
    assert!(ctx.validation_errors().is_empty());
    let info = vk::BufferCreateInfo::default()
        .size(0)
        .usage(vk::BufferUsageFlags::STORAGE_BUFFER);
    if let Ok(b) = unsafe { ctx.device.create_buffer(&info, None) } {
        unsafe { ctx.device.destroy_buffer(b, None) };
    }
    let errors = ctx.validation_errors();
    assert!(!errors.is_empty(), "a zero-sized buffer must be reported");
    assert!(errors.iter().any(|e| e.contains("size")), "{errors:?}");
}

#[test]
fn a_render_passes_synchronization_validation() {
    if !common::validation_layer_installed() {
        eprintln!("skipped: VK_LAYER_KHRONOS_validation is not installed");
        return;
    }
    let scene = pathwave::scene::load(&common::scenes_dir().join("cornell-box.gltf"), None).unwrap();
    let mut r = pathwave::Renderer::with_validation(&scene, &DeviceChoice::Best, Validation::Sync).unwrap();
    // Two chunks' worth of paths is not possible at this size, but several passes and all bounces are, in both
    // schedules: the wavefront's queues between stages are where a missing barrier would hide.
    for schedule in [pathwave::Schedule::Wavefront, pathwave::Schedule::Fused] {
        r.set_schedule(schedule);
        let (film, _) = r
            .render(&common::settings(16, 16, 3, 0), &mut |_| {})
            .unwrap_or_else(|e| panic!("{schedule:?}: {e}"));
        assert!(film.mean().iter().any(|p| p[0] > 0.0));
        // The AOV and debug-view surveys after each pass, and adaptive sampling's plan between passes (a part past
        // sample 0, so its pilot, the plan and the cleared film too).
        let s = pathwave::RenderSettings {
            aovs: true,
            debug_aovs: true,
            adaptive: Some(pathwave::Adaptive {
                threshold: 0.05,
                pilot: 2,
            }),
            first_sample: 1,
            spp: 6,
            ..common::settings(16, 16, 6, 0)
        };
        let (film, _) = r
            .render(&s, &mut |_| {})
            .unwrap_or_else(|e| panic!("{schedule:?}, AOVs and adaptive: {e}"));
        assert!(film.aovs.is_some_and(|a| a.debug.is_some()));
    }
}
