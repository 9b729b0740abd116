//! Hostile inputs: URIs confined to the scene's folder, only regular files read, sizes checked against what the
//! scene declares, and images refused from their header, each quickly and with bounded memory.
mod common;

use common::gltf_builder::GltfBuilder;
use common::{cornell_arg, render_args};
use pathwave::scene::{self, LoadOptions};
use serde_json::{json, Value};
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

/// A textured quad, its buffer in `scene.bin` beside the JSON (returned parsed, to edit URIs).
fn textured() -> (Value, Vec<u8>) {
    let mut b = GltfBuilder::new();
    let m = b.material("lit", [0.8; 3], [1.0; 3], true);
    let img = b.png_image(2, 1, &[[255, 0, 0, 255], [0, 255, 0, 255]]);
    let t = b.texture(img, json!({}));
    b.material_json(m)["pbrMetallicRoughness"]["baseColorTexture"] = json!({ "index": t });
    let quad = [[-1.0, -1.0, 0.0], [1.0, -1.0, 0.0], [1.0, 1.0, 0.0], [-1.0, 1.0, 0.0]];
    b.textured_quad("quad", quad, [[0.0, 1.0], [1.0, 1.0], [1.0, 0.0], [0.0, 0.0]], m);
    let (text, bin) = b.to_json_and_bin("scene.bin");
    (serde_json::from_str(&text).unwrap(), bin)
}

fn write_json(path: &Path, doc: &Value) {
    std::fs::write(path, serde_json::to_string(doc).unwrap()).unwrap();
}

/// A folder holding `scene/scene.gltf` and its `scene.bin`; the folder around it is "outside".
struct Layout {
    root: tempfile::TempDir,
    doc: Value,
    bin: Vec<u8>,
}

impl Layout {
    fn new() -> Self {
        let root = tempfile::tempdir().unwrap();
        std::fs::create_dir(root.path().join("scene")).unwrap();
        let (doc, bin) = textured();
        std::fs::write(root.path().join("scene/scene.bin"), &bin).unwrap();
        Layout { root, doc, bin }
    }

    fn folder(&self) -> PathBuf {
        self.root.path().join("scene")
    }

    /// Writes the scene with buffer 0's URI (or image 0's, with `image`) replaced; returns its path.
    fn with_uri(&self, uri: &str, image: bool) -> PathBuf {
        let mut doc = self.doc.clone();
        if image {
            doc["images"][0] = json!({ "uri": uri, "name": "tile" });
        } else {
            doc["buffers"][0]["uri"] = json!(uri);
        }
        let path = self.folder().join("scene.gltf");
        write_json(&path, &doc);
        path
    }
}

fn refusal(path: &Path, options: &LoadOptions) -> String {
    match scene::load_with(path, options) {
        Ok(_) => panic!("{} loaded; it should have been refused", path.display()),
        Err(e) => e.to_string(),
    }
}

#[test]
fn uris_outside_the_scene_folder_are_refused() {
    let l = Layout::new();
    std::fs::write(l.root.path().join("outside.bin"), &l.bin).unwrap();
    std::os::unix::fs::symlink(l.root.path().join("outside.bin"), l.folder().join("link.bin")).unwrap();
    let classes = [
        "/etc/passwd",
        "../../../../etc/passwd",
        "file:///etc/passwd",
        "file:/etc/passwd",
        "FILE:///etc/passwd",
        "%2e%2e/%2e%2e/%2e%2e/%2e%2e/etc/passwd",
        "%2Fetc%2Fpasswd",
        "/proc/self/environ",
        "sub/../../outside.bin",
        "link.bin",
    ];
    for uri in classes {
        for image in [false, true] {
            let path = l.with_uri(uri, image);
            let e = refusal(&path, &LoadOptions::default());
            let item = if image { "image 0 'tile'" } else { "buffer 0" };
            assert!(
                e.contains(&path.display().to_string()) && e.contains(&format!("{item} ({uri})")),
                "{uri}: the error should name the scene, {item} and the URI: {e}"
            );
            assert!(
                e.contains("--allow-outside-paths"),
                "{uri}: should be refused as outside the folder: {e}"
            );
        }
    }
    // Paths that stay inside the folder, written in any of these ways, still load.
    std::fs::create_dir(l.folder().join("sub")).unwrap();
    for uri in ["scene.bin", "./scene.bin", "sub/../scene.bin", "%73cene.bin"] {
        scene::load_with(&l.with_uri(uri, false), &LoadOptions::default()).unwrap_or_else(|e| panic!("{uri}: {e}"));
    }
}

#[test]
fn allow_outside_paths_reads_a_file_outside_the_folder() {
    let l = Layout::new();
    let outside = l.root.path().join("elsewhere");
    std::fs::create_dir(&outside).unwrap();
    std::fs::write(outside.join("data.bin"), &l.bin).unwrap();
    let allow = LoadOptions {
        allow_outside_paths: true,
        ..Default::default()
    };
    let absolute = outside.join("data.bin").display().to_string();
    for uri in [
        "../elsewhere/data.bin",
        absolute.as_str(),
        &format!("file://{absolute}"),
    ] {
        let path = l.with_uri(uri, false);
        refusal(&path, &LoadOptions::default());
        let s = scene::load_with(&path, &allow).unwrap_or_else(|e| panic!("{uri}: {e}"));
        assert_eq!(s.meshes.len(), 1, "{uri}");
    }
    // The CLI passes the flag through (info reads the scene without a device).
    let path = l.with_uri("../elsewhere/data.bin", false);
    let p = path.to_str().unwrap();
    let o = pathwave(&["info", p], 10);
    assert!(!o.status.success() && stderr(&o).contains("error: "), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("buffer 0 (../elsewhere/data.bin)"),
        "{}",
        stderr(&o)
    );
    let o = pathwave(&["info", p, "--allow-outside-paths"], 10);
    assert!(o.status.success(), "{}", stderr(&o));
}

/// Runs the CLI with at most `secs` seconds and 1.5 GiB of address space (prlimit), so a hang or an unbounded
/// read fails the test rather than the machine.
fn pathwave(args: &[&str], secs: u64) -> Output {
    let mut c = Command::new("prlimit");
    c.arg("--as=1610612736").arg(env!("CARGO_BIN_EXE_pathwave")).args(args);
    let mut child = c
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("prlimit runs");
    let start = Instant::now();
    while child.try_wait().unwrap().is_none() {
        if start.elapsed() > Duration::from_secs(secs) {
            child.kill().unwrap();
            panic!("pathwave {args:?} did not finish within {secs} s");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    child.wait_with_output().unwrap()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// The command fails cleanly, quickly, with a message holding every needle.
fn assert_refused(args: &[&str], needles: &[&str]) {
    let o = pathwave(args, 10);
    let err = stderr(&o);
    assert!(!o.status.success(), "{args:?} succeeded: {err}");
    assert!(
        err.starts_with("error: ") && !err.contains("panicked"),
        "{args:?}: {err}"
    );
    for n in needles {
        assert!(err.contains(n), "{args:?}: the message should mention {n:?}: {err}");
    }
}

#[test]
fn fifos_devices_and_folders_are_refused_before_they_are_opened() {
    let l = Layout::new();
    let d = l.folder();
    let fifo = d.join("pipe.gltf");
    let fifo_hdr = d.join("pipe.hdr");
    for f in [&fifo, &fifo_hdr, &d.join("pipe.bin")] {
        assert!(Command::new("mkfifo").arg(f).status().unwrap().success());
    }
    std::os::unix::fs::symlink("/dev/zero", d.join("zero.hdr")).unwrap();
    std::os::unix::fs::symlink("/dev/zero", d.join("zero.bin")).unwrap();
    let not_regular = "not a regular file";
    for scene in [fifo.to_str().unwrap(), "/dev/zero"] {
        assert_refused(&["info", scene], &[&format!("{scene}: "), not_regular]);
    }
    let png = d.join("folder.png");
    assert_refused(
        &["render", d.to_str().unwrap(), "-o", png.to_str().unwrap()],
        &["is a folder"],
    );
    // A folder given to info is a census; the FIFO in it is listed as refused without being opened (opening
    // it would block for ever: pathwave() kills the run after 10 s).
    let census = pathwave(&["info", d.to_str().unwrap()], 10);
    let out = String::from_utf8_lossy(&census.stdout);
    assert!(census.status.success(), "{}", stderr(&census));
    assert!(
        out.lines()
            .any(|l| l.starts_with("refused  pipe.gltf: ") && l.contains(not_regular)),
        "{out}"
    );
    let out = d.join("out.png");
    for env in [fifo_hdr, d.join("zero.hdr")] {
        let args = render_args(cornell_arg(), out.to_str().unwrap(), &["--env", env.to_str().unwrap()]);
        assert_refused(&args, &[&env.display().to_string(), not_regular]);
    }
    let path = l.with_uri("pipe.bin", false);
    assert_refused(&["info", path.to_str().unwrap()], &["buffer 0 (pipe.bin)", not_regular]);
    // A symlink to a device leads out of the folder; allowed out, it is still not a regular file.
    let path = l.with_uri("zero.bin", false);
    assert_refused(
        &["info", path.to_str().unwrap()],
        &["buffer 0 (zero.bin)", "--allow-outside-paths"],
    );
    let args = ["info", path.to_str().unwrap(), "--allow-outside-paths"];
    assert_refused(&args, &["buffer 0 (zero.bin)", not_regular]);
    assert!(!out.exists());
}

#[test]
fn buffer_files_are_read_as_far_as_declared() {
    let l = Layout::new();
    let bin = l.folder().join("scene.bin");
    let path = l.with_uri("scene.bin", false);
    std::fs::write(&bin, &l.bin[..l.bin.len() - 10]).unwrap();
    let e = refusal(&path, &LoadOptions::default());
    let declared = format!("fewer than the buffer's byteLength {}", l.bin.len());
    assert!(e.contains("buffer 0 (scene.bin)") && e.contains(&declared), "{e}");
    // 3 GiB past byteLength (sparse): only the declared bytes are read, within the 1.5 GiB address-space limit.
    std::fs::write(&bin, &l.bin).unwrap();
    std::fs::File::options()
        .write(true)
        .open(&bin)
        .unwrap()
        .set_len(3 << 30)
        .unwrap();
    let o = pathwave(&["info", path.to_str().unwrap()], 10);
    assert!(o.status.success(), "{}", stderr(&o));
}

#[test]
fn a_scene_file_past_the_limit_is_refused_before_it_is_read() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("huge.gltf");
    std::fs::File::create(&path)
        .unwrap()
        .set_len(scene::MAX_FILE_BYTES + 1)
        .unwrap();
    let limit = format!("more than the {} bytes a scene file may hold", scene::MAX_FILE_BYTES);
    assert_refused(&["info", path.to_str().unwrap()], &["huge.gltf: ", &limit]);
}

/// Writes a valid grayscale PNG of `side`² black pixels (16384² compresses to about 1 MiB).
fn write_black_png(path: &Path, side: u32) {
    let file = std::io::BufWriter::new(std::fs::File::create(path).unwrap());
    let mut enc = png::Encoder::new(file, side, side);
    enc.set_color(png::ColorType::Grayscale);
    enc.set_compression(png::Compression::Fast);
    let mut w = enc.write_header().unwrap().into_stream_writer().unwrap();
    let row = vec![0u8; side as usize];
    for _ in 0..side {
        std::io::Write::write_all(&mut w, &row).unwrap();
    }
    w.finish().unwrap();
}

#[test]
fn images_past_the_pixel_limit_are_refused_from_their_header() {
    let l = Layout::new();
    let start = Instant::now();
    write_black_png(&l.folder().join("big.png"), 16384);
    eprintln!("a 16384² PNG written in {:.1?}", start.elapsed());
    let path = l.with_uri("big.png", true);
    let p = path.to_str().unwrap();
    let figure = "16384x16384 = 268435456 pixels, more than the 67108864 --max-texture-pixels allows";
    // Decoding would take 1 GiB of texels and more to convert them: the 1.5 GiB address-space limit holds it.
    let start = Instant::now();
    assert_refused(&["info", p], &[p, "image 0 'tile' (big.png)", figure]);
    assert!(start.elapsed() < Duration::from_secs(5), "took {:.1?}", start.elapsed());
    // The limit is an option, and a small image within it loads.
    write_black_png(&l.folder().join("small.png"), 64);
    let small = l.with_uri("small.png", true);
    let small = small.to_str().unwrap();
    assert_refused(
        &["info", small, "--max-texture-pixels", "4095"],
        &["64x64 = 4096 pixels"],
    );
    assert!(pathwave(&["info", small, "--max-texture-pixels", "4096"], 10)
        .status
        .success());
    assert_refused(&["info", small, "--max-texture-pixels", "0"], &["--max-texture-pixels"]);

    // An environment map's header: refused before its (absent) pixels are read.
    let hdr = l.folder().join("big.hdr");
    std::fs::write(&hdr, "#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 16384 +X 16384\n").unwrap();
    let out = l.folder().join("out.png");
    let args = render_args(cornell_arg(), out.to_str().unwrap(), &["--env", hdr.to_str().unwrap()]);
    assert_refused(&args, &["big.hdr: ", figure]);
    // An .exr map too, and the option reaches it.
    let exr = l.folder().join("sky.exr");
    pathwave::output::write_image(&exr, 80, 60, &vec![[1.0; 3]; 80 * 60], 0.0).unwrap();
    let more = ["--env", exr.to_str().unwrap(), "--max-texture-pixels", "4799"];
    let args = render_args(cornell_arg(), out.to_str().unwrap(), &more);
    assert_refused(
        &args,
        &[
            "sky.exr: ",
            "80x60 = 4800 pixels, more than the 4799 --max-texture-pixels allows",
        ],
    );
    assert!(!out.exists());
}

/// Catches images that together take more host memory than --max-memory allows: each is checked from its header
/// against what the budget leaves after the buffers and the images before it, so the process never holds more.
/// Two images within --max-texture-pixels: one 2048² fits 90 MB, and the second then no longer does.
#[test]
fn images_together_are_bounded_by_the_host_memory_budget() {
    let l = Layout::new();
    write_black_png(&l.folder().join("a.png"), 2048);
    let mut doc = l.doc.clone();
    doc["images"] = json!([{ "uri": "a.png", "name": "first" }, { "uri": "a.png", "name": "second" }]);
    doc["textures"] = json!([{ "source": 0 }, { "source": 1 }]);
    doc["materials"][0]["emissiveTexture"] = json!({ "index": 1 });
    doc["materials"][0]["emissiveFactor"] = json!([1.0, 1.0, 1.0]);
    let path = l.folder().join("two.gltf");
    write_json(&path, &doc);
    let p = path.to_str().unwrap();
    // 2048² pixels take 64 MiB while decoding and 32 MiB once decoded.
    assert!(
        pathwave(&["info", p, "--max-memory", "150M"], 20).status.success(),
        "both fit 150 MB"
    );
    assert_refused(
        &["info", p, "--max-memory", "90M"],
        &[p, "image 1 'second' (a.png)", "--max-memory", "64.0 MiB"],
    );
    assert_refused(
        &["info", p, "--max-memory", "40M"],
        &["image 0 'first' (a.png)", "--max-memory"],
    );
}

/// What real files get wrong and Blender and three.js read anyway, tolerated with a warning or refused with the
/// reason: POSITION accessors without the min and max glTF requires load (one warning, the same triangles); a file
/// whose only primitives are lines says so; a scene object without `nodes` (valid glTF 2.0) is an empty scene, not
/// a parse error ("missing field nodes", as gltf 1.4 said).
#[test]
fn what_real_files_get_wrong_is_tolerated_or_explained() {
    let original: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(common::cornell()).unwrap()).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let write = |name: &str, edit: &dyn Fn(&mut serde_json::Value)| {
        let mut doc = original.clone();
        edit(&mut doc);
        let path = dir.path().join(name);
        std::fs::write(&path, doc.to_string()).unwrap();
        path
    };
    let unbounded = write("unbounded.gltf", &|d| {
        for a in d["accessors"].as_array_mut().unwrap() {
            let a = a.as_object_mut().unwrap();
            a.remove("min");
            a.remove("max");
        }
    });
    let scene = pathwave::scene::load(&unbounded, None).unwrap_or_else(|e| panic!("{e}"));
    let reference = pathwave::scene::load(&common::cornell(), None).unwrap();
    assert_eq!(scene.flatten().len(), reference.flatten().len());
    assert_eq!(scene.warnings.len(), 1, "{:?}", scene.warnings);
    assert!(
        scene.warnings[0].contains("and 15 more: POSITION without min and max"),
        "{:?}",
        scene.warnings
    );

    let lines = write("lines.gltf", &|d| {
        for m in d["meshes"].as_array_mut().unwrap() {
            m["primitives"][0]["mode"] = 1.into();
        }
    });
    let e = pathwave::scene::load(&lines, None).err().unwrap().to_string();
    assert!(
        e.contains("no triangles to render: its 16 primitives are points or lines"),
        "{e}"
    );

    let empty = write("empty.gltf", &|d| {
        d["scenes"][0].as_object_mut().unwrap().remove("nodes");
    });
    let e = pathwave::scene::load(&empty, None).err().unwrap().to_string();
    assert!(e.contains("no triangles to render: scene 0 has no nodes"), "{e}");
}
