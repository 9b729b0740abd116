//! Denoising with Intel Open Image Denoise (OIDN), loaded at run time: its `RT` filter on the beauty image, guided by
//! the albedo and normal AOVs, prefiltered first as OIDN recommends for noisy ones. No build-time dependency: the
//! library comes from `PATHWAVE_OIDN` or the `pyoidn` Python package (PyPI's wheel ships it with its CPU device).
use crate::error::Error;
use std::ffi::{c_char, c_void, CStr};
use std::path::{Path, PathBuf};

/// The library's file name (OIDN 2's soname).
pub const LIBRARY: &str = "libOpenImageDenoise.so.2";

/// What to tell a user without the library.
pub const INSTALL_HINT: &str = "pathwave loads Intel Open Image Denoise at run time: `pip install pyoidn` (its wheel \
     ships libOpenImageDenoise.so.2), or set PATHWAVE_OIDN to the library's path";

const DEVICE_TYPE_CPU: i32 = 1;
const FORMAT_FLOAT3: i32 = 3;
const ERROR_NONE: i32 = 0;

type Device = *mut c_void;
type Filter = *mut c_void;

/// The C API's entry points pathwave calls, resolved once when the library loads.
struct Api {
    new_device: unsafe extern "C" fn(i32) -> Device,
    commit_device: unsafe extern "C" fn(Device),
    release_device: unsafe extern "C" fn(Device),
    device_error: unsafe extern "C" fn(Device, *mut *const c_char) -> i32,
    new_filter: unsafe extern "C" fn(Device, *const c_char) -> Filter,
    #[allow(clippy::type_complexity)]
    set_shared_image: unsafe extern "C" fn(Filter, *const c_char, *mut c_void, i32, usize, usize, usize, usize, usize),
    set_bool: unsafe extern "C" fn(Filter, *const c_char, bool),
    commit_filter: unsafe extern "C" fn(Filter),
    execute_filter: unsafe extern "C" fn(Filter),
    release_filter: unsafe extern "C" fn(Filter),
}

/// Open Image Denoise, loaded, with a CPU device.
pub struct Denoiser {
    api: Api,
    device: Device,
    /// Where the library came from.
    pub path: PathBuf,
    // Last: the entry points above must not outlive it.
    _lib: libloading::Library,
}

/// The guides of a denoise: the albedo and normal AOVs (each optional, the normal only with the albedo).
pub struct Guides<'a> {
    pub albedo: Option<&'a [[f32; 3]]>,
    pub normal: Option<&'a [[f32; 3]]>,
    /// The guides are noise-free: skip the prefilter (OIDN's `cleanAux`).
    pub clean: bool,
}

impl Denoiser {
    /// The library `PATHWAVE_OIDN` names (the file, or a folder holding it), else the `pyoidn` package's that
    /// `python3` finds or that `ci/setup.sh` installed (in ~/.cache/pathwave/oidn-venv), else an error saying how to
    /// install it.
    pub fn from_env() -> Result<Denoiser, Error> {
        let path = match std::env::var_os("PATHWAVE_OIDN") {
            Some(p) => {
                let p = PathBuf::from(p);
                let file = if p.is_dir() { p.join(LIBRARY) } else { p };
                if !file.is_file() {
                    return Err(Error::Settings(format!(
                        "PATHWAVE_OIDN={}: no such file ({LIBRARY} expected)",
                        file.display()
                    )));
                }
                file
            }
            None => pip_library().ok_or_else(|| {
                Error::Settings(format!("--denoise: Open Image Denoise was not found; {INSTALL_HINT}"))
            })?,
        };
        Denoiser::load(&path)
    }

    /// Loads the library at `path` and makes a CPU device.
    pub fn load(path: &Path) -> Result<Denoiser, Error> {
        let err = |m: String| Error::Settings(format!("Open Image Denoise at {}: {m}", path.display()));
        // SAFETY: loading runs the library's initialisers; OIDN's are its own static set-up.
        let lib = unsafe { libloading::Library::new(path) }.map_err(|e| err(format!("cannot load it: {e}")))?;
        // SAFETY: each symbol is looked up by the name and C signature of OIDN 2's public API (OpenImageDenoise/oidn.h).
        let api = unsafe {
            Api {
                new_device: sym(&lib, path, b"oidnNewDevice\0")?,
                commit_device: sym(&lib, path, b"oidnCommitDevice\0")?,
                release_device: sym(&lib, path, b"oidnReleaseDevice\0")?,
                device_error: sym(&lib, path, b"oidnGetDeviceError\0")?,
                new_filter: sym(&lib, path, b"oidnNewFilter\0")?,
                set_shared_image: sym(&lib, path, b"oidnSetSharedFilterImage\0")?,
                set_bool: sym(&lib, path, b"oidnSetFilterBool\0")?,
                commit_filter: sym(&lib, path, b"oidnCommitFilter\0")?,
                execute_filter: sym(&lib, path, b"oidnExecuteFilter\0")?,
                release_filter: sym(&lib, path, b"oidnReleaseFilter\0")?,
            }
        };
        // SAFETY: the API is resolved; a null device is checked below.
        let device = unsafe { (api.new_device)(DEVICE_TYPE_CPU) };
        if device.is_null() {
            return Err(err(
                "it made no CPU device (OIDN's CPU device needs SSE4.1 or NEON)".into()
            ));
        }
        let d = Denoiser {
            api,
            device,
            path: path.to_path_buf(),
            _lib: lib,
        };
        // SAFETY: a live device.
        unsafe { (d.api.commit_device)(d.device) };
        d.check("committing the CPU device")?;
        Ok(d)
    }

    /// The beauty image denoised (linear HDR radiance, row 0 at the top) with `guides`.
    pub fn denoise(&self, width: u32, height: u32, color: &[[f32; 3]], guides: Guides) -> Result<Vec<[f32; 3]>, Error> {
        let pixels = width as usize * height as usize;
        assert_eq!(color.len(), pixels);
        if guides.normal.is_some() && guides.albedo.is_none() {
            return Err(Error::Settings(
                "OIDN takes a normal guide only with an albedo guide".into(),
            ));
        }
        // The filter may write its output while it reads the inputs; they are copies, so nothing the caller holds
        // changes.
        let mut color = color.to_vec();
        let mut albedo = guides.albedo.map(<[_]>::to_vec);
        let mut normal = guides.normal.map(<[_]>::to_vec);
        if !guides.clean {
            // OIDN's advice for noisy guides: denoise each with the same filter first, then tell the main filter
            // they are clean.
            if let Some(a) = albedo.as_mut() {
                self.run(width, height, &mut [("albedo", a)], None)?;
            }
            if let Some(n) = normal.as_mut() {
                self.run(width, height, &mut [("normal", n)], None)?;
            }
        }
        let mut inputs: Vec<(&str, &mut Vec<[f32; 3]>)> = Vec::new();
        inputs.extend(albedo.as_mut().map(|a| ("albedo", a)));
        inputs.extend(normal.as_mut().map(|n| ("normal", n)));
        let mut out = vec![[0f32; 3]; pixels];
        inputs.push(("color", &mut color));
        self.run(width, height, &mut inputs, Some(&mut out))?;
        Ok(out)
    }

    /// One RT filter over `images` (by OIDN's names), writing `output`, or the first image in place when None.
    fn run(
        &self,
        width: u32,
        height: u32,
        images: &mut [(&str, &mut Vec<[f32; 3]>)],
        output: Option<&mut Vec<[f32; 3]>>,
    ) -> Result<(), Error> {
        let a = &self.api;
        let c = |s: &str| std::ffi::CString::new(s).expect("no NUL in OIDN's parameter names");
        let (w, h) = (width as usize, height as usize);
        // SAFETY: a live device; every image is w x h packed FLOAT3 and outlives the filter, which is released
        // before returning.
        unsafe {
            let filter = (a.new_filter)(self.device, c"RT".as_ptr());
            if filter.is_null() {
                self.check("making the RT filter")?;
                return Err(Error::Settings("Open Image Denoise made no RT filter".into()));
            }
            let result = (|| {
                for (name, img) in images.iter_mut() {
                    let ptr = img.as_mut_ptr() as *mut c_void;
                    (a.set_shared_image)(filter, c(name).as_ptr(), ptr, FORMAT_FLOAT3, w, h, 0, 0, 0);
                }
                let out_ptr = match output {
                    Some(o) => o.as_mut_ptr() as *mut c_void,
                    None => images[0].1.as_mut_ptr() as *mut c_void,
                };
                (a.set_shared_image)(filter, c"output".as_ptr(), out_ptr, FORMAT_FLOAT3, w, h, 0, 0, 0);
                let main = images.iter().any(|(n, _)| *n == "color");
                if main {
                    (a.set_bool)(filter, c"hdr".as_ptr(), true);
                    (a.set_bool)(filter, c"cleanAux".as_ptr(), images.len() > 1);
                }
                (a.commit_filter)(filter);
                self.check("setting up the filter")?;
                (a.execute_filter)(filter);
                self.check("filtering")
            })();
            (a.release_filter)(filter);
            result
        }
    }

    /// The device's pending error, if any.
    fn check(&self, doing: &str) -> Result<(), Error> {
        let mut message: *const c_char = std::ptr::null();
        // SAFETY: a live device; OIDN owns the message, valid until the next call on the device.
        let code = unsafe { (self.api.device_error)(self.device, &mut message) };
        if code == ERROR_NONE {
            return Ok(());
        }
        let text = match message.is_null() {
            true => String::new(),
            // SAFETY: a NUL-terminated string OIDN owns.
            false => unsafe { CStr::from_ptr(message) }.to_string_lossy().into_owned(),
        };
        Err(Error::Settings(format!(
            "Open Image Denoise, {doing}: error {code}: {text}"
        )))
    }
}

impl Drop for Denoiser {
    fn drop(&mut self) {
        // SAFETY: the device is live and nothing else holds it.
        unsafe { (self.api.release_device)(self.device) };
    }
}

/// The entry point `name` (NUL-terminated) of the library at `path`.
///
/// # Safety
/// T must be the symbol's true (function pointer) type.
unsafe fn sym<T: Copy>(lib: &libloading::Library, path: &Path, name: &[u8]) -> Result<T, Error> {
    // SAFETY: the caller names T as the symbol's true type.
    unsafe { lib.get::<T>(name) }.map(|s| *s).map_err(|e| {
        let name = String::from_utf8_lossy(&name[..name.len() - 1]);
        Error::Settings(format!(
            "Open Image Denoise at {}: not OIDN 2 ({name}: {e})",
            path.display()
        ))
    })
}

/// The library inside the `pyoidn` package the user's `python3` finds, else the one ci/setup.sh installed, without
/// importing it (which would load the library through Python).
fn pip_library() -> Option<PathBuf> {
    let setup = std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".cache/pathwave/oidn-venv/bin/python3"));
    let pythons = std::iter::once(PathBuf::from("python3")).chain(setup.filter(|p| p.is_file()));
    pythons.into_iter().find_map(|p| package_library(&p))
}

/// The library in the `pyoidn` package `python` finds.
fn package_library(python: &Path) -> Option<PathBuf> {
    let out = std::process::Command::new(python)
        .args([
            "-c",
            "import importlib.util as u; s = u.find_spec('pyoidn'); \
             print(s.submodule_search_locations[0] if s and s.submodule_search_locations else '')",
        ])
        .stderr(std::process::Stdio::null())
        .output()
        .ok()?;
    let dir = String::from_utf8(out.stdout).ok()?;
    let file = Path::new(dir.trim()).join("oidn").join("lib").join(LIBRARY);
    (!dir.trim().is_empty() && file.is_file()).then_some(file)
}
