//! Ray-query traversal's ground: the second lavapipe (Mesa >= 24.1 from the backports suite, fetched by
//! ci/lavapipe-rt.sh into the user's cache) exposes VK_KHR_ray_query beside the system's driver, and pathwave tells
//! them apart. Tests that need ray queries run pathwave under that driver's ICD file.
mod common;

use std::path::PathBuf;
use std::process::Output;

fn devices(icd: &std::path::Path) -> Output {
    common::pathwave_cli()
        .args(["info", "--devices"])
        .env("VK_DRIVER_FILES", icd)
        .env_remove("VK_ICD_FILENAMES")
        .output()
        .expect("the pathwave binary runs")
}

#[test]
fn the_backports_lavapipe_offers_ray_queries_and_info_says_so() {
    let o = devices(&common::rt::icd());
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let line = text.lines().next().unwrap_or_default();
    assert!(line.contains("llvmpipe") && line.contains("Mesa 2"), "{text}");
    assert!(line.contains("ray queries: yes"), "{text}");
    // The system's lavapipe (Debian 12's Mesa 22.3) has none; a newer system driver may, and says which it is.
    let system = PathBuf::from("/usr/share/vulkan/icd.d/lvp_icd.x86_64.json");
    if system.is_file() {
        let o = devices(&system);
        let text = String::from_utf8_lossy(&o.stdout);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        if text.contains("Mesa 22.") {
            assert!(text.contains("ray queries: no"), "{text}");
        }
    }
}
