//! The thin ash layer: instance, validation, the context and its submissions; devices, memory and pipelines beside it.
mod buffer;
mod devices;
mod pipeline;

pub use buffer::{Buffer, TexelViews};
pub use devices::{list_devices, ray_query_support, DeviceChoice, DeviceInfo, RAY_QUERY_EXTENSIONS};
pub use pipeline::{add_labelled, Pipelines, Timestamps};

use devices::pick_device;

use crate::error::Error;
use ash::vk;
use gpu_allocator::vulkan::{Allocator, AllocatorCreateDesc};
use std::ffi::{c_void, CStr};
use std::mem::ManuallyDrop;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

const VALIDATION_LAYER: &CStr = c"VK_LAYER_KHRONOS_validation";

/// Set when a submission outlived PATHWAVE_GPU_TIMEOUT_SECS. The device may then run (or hang) for ever, so from then
/// on nothing waits for it and nothing it may still use is destroyed: every Drop of a Vulkan object in this crate
/// leaks instead, and the process's exit reclaims the memory. Process-wide because one hung device is reason enough
/// to stop touching Vulkan at all.
static DEVICE_LOST: AtomicBool = AtomicBool::new(false);

/// Whether a submission timed out (see DEVICE_LOST): if so, Vulkan objects are leaked rather than destroyed.
pub fn device_lost() -> bool {
    DEVICE_LOST.load(Ordering::Relaxed)
}

impl From<vk::Result> for Error {
    fn from(r: vk::Result) -> Self {
        Error::Vulkan(format!("{r:?}"))
    }
}

/// How the validation layer is used, from `PATHWAVE_VALIDATION`: unset/0 off, 1 on, `sync` on with synchronization checks.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Validation {
    Off,
    On,
    Sync,
}

impl Validation {
    /// Unset or empty, 0, off or false: off; 1, on or true: on; sync: on with synchronization validation. Any
    /// other word is refused rather than silently read as off.
    pub fn from_env() -> Result<Self, Error> {
        match std::env::var("PATHWAVE_VALIDATION").as_deref() {
            Err(std::env::VarError::NotPresent) | Ok("") | Ok("0") | Ok("off") | Ok("false") => Ok(Validation::Off),
            Ok("1") | Ok("on") | Ok("true") => Ok(Validation::On),
            Ok("sync") => Ok(Validation::Sync),
            Ok(other) => Err(Error::Settings(format!(
                "PATHWAVE_VALIDATION={other}: expected 0, off, 1, on or sync"
            ))),
            Err(_) => Err(Error::Settings("PATHWAVE_VALIDATION is not valid Unicode".into())),
        }
    }
}

/// The longest wait for one submission: PATHWAVE_GPU_TIMEOUT_SECS, whole seconds from 1 to a week (300 unset).
pub fn gpu_timeout_from_env() -> Result<Duration, Error> {
    const WEEK: u64 = 7 * 24 * 3600;
    match std::env::var("PATHWAVE_GPU_TIMEOUT_SECS") {
        Err(std::env::VarError::NotPresent) => Ok(Duration::from_secs(300)),
        Ok(s) => match s.trim().parse::<u64>() {
            Ok(n) if (1..=WEEK).contains(&n) => Ok(Duration::from_secs(n)),
            _ => Err(Error::Settings(format!(
                "PATHWAVE_GPU_TIMEOUT_SECS={s}: expected whole seconds from 1 to {WEEK}"
            ))),
        },
        Err(_) => Err(Error::Settings("PATHWAVE_GPU_TIMEOUT_SECS is not valid Unicode".into())),
    }
}

/// Messages the validation layer reported, kept so a render can fail on any error.
#[derive(Default)]
struct ValidationLog {
    errors: Mutex<Vec<String>>,
}

unsafe extern "system" fn debug_callback(
    severity: vk::DebugUtilsMessageSeverityFlagsEXT,
    _types: vk::DebugUtilsMessageTypeFlagsEXT,
    data: *const vk::DebugUtilsMessengerCallbackDataEXT<'_>,
    user: *mut c_void,
) -> vk::Bool32 {
    let log = &*(user as *const ValidationLog);
    let msg = if data.is_null() || (*data).p_message.is_null() {
        "(no message)".to_string()
    } else {
        CStr::from_ptr((*data).p_message).to_string_lossy().into_owned()
    };
    if severity.contains(vk::DebugUtilsMessageSeverityFlagsEXT::ERROR) {
        eprintln!("validation error: {msg}");
        if let Ok(mut e) = log.errors.lock() {
            e.push(msg);
        }
    } else if severity.contains(vk::DebugUtilsMessageSeverityFlagsEXT::WARNING) {
        eprintln!("validation warning: {msg}");
    }
    vk::FALSE
}

/// A device, its one compute queue, the memory allocator and a command pool.
pub struct Context {
    pub instance: ash::Instance,
    pub physical: vk::PhysicalDevice,
    pub properties: vk::PhysicalDeviceProperties,
    pub device: ash::Device,
    pub queue: vk::Queue,
    pub queue_family: u32,
    pub allocator: ManuallyDrop<Arc<Mutex<Allocator>>>,
    pub pool: vk::CommandPool,
    pub timestamps_valid: bool,
    pub fence_timeout: Duration,
    debug: Option<(ash::ext::debug_utils::Instance, vk::DebugUtilsMessengerEXT)>,
    debug_device: Option<ash::ext::debug_utils::Device>,
    log: Box<ValidationLog>,
    /// The window surface this device presents to (the viewer), if any; its queue can present to it.
    pub surface: Option<Surface>,
    /// The acceleration-structure functions, when the device has ray queries (`ray_query_support`): their
    /// extensions and buffer device addresses are then enabled, whichever traversal a renderer chooses.
    pub accel: Option<ash::khr::acceleration_structure::Device>,
    pub entry: ash::Entry,
}

/// A window's Vulkan surface and the instance functions that query it.
pub struct Surface {
    pub loader: ash::khr::surface::Instance,
    pub raw: vk::SurfaceKHR,
}

/// The native handles of a window to present to.
#[derive(Clone, Copy)]
pub struct WindowHandles {
    pub display: raw_window_handle::RawDisplayHandle,
    pub window: raw_window_handle::RawWindowHandle,
}

fn load_entry() -> Result<ash::Entry, Error> {
    // SAFETY: loading the system Vulkan loader; nothing else runs its initialisers concurrently.
    unsafe { ash::Entry::load() }.map_err(|e| {
        Error::Vulkan(format!(
            "cannot load the Vulkan loader ({e}); install libvulkan1 and a driver (bash ci/setup.sh installs lavapipe)"
        ))
    })
}

fn create_instance(
    entry: &ash::Entry,
    validation: Validation,
    window: Option<WindowHandles>,
) -> Result<ash::Instance, Error> {
    let app = vk::ApplicationInfo::default()
        .application_name(c"pathwave")
        .engine_name(c"pathwave")
        .api_version(vk::API_VERSION_1_2);
    let mut layers = Vec::new();
    let mut extensions = Vec::new();
    if let Some(w) = window {
        extensions.extend_from_slice(ash_window::enumerate_required_extensions(w.display)?);
    }
    if validation != Validation::Off {
        let available = unsafe { entry.enumerate_instance_layer_properties() }?;
        let has = available
            .iter()
            .any(|l| l.layer_name_as_c_str().is_ok_and(|n| n == VALIDATION_LAYER));
        if !has {
            return Err(Error::Vulkan(
                "PATHWAVE_VALIDATION is set but VK_LAYER_KHRONOS_validation is not installed (apt-get install vulkan-validationlayers)".into(),
            ));
        }
        layers.push(VALIDATION_LAYER.as_ptr());
        extensions.push(ash::ext::debug_utils::NAME.as_ptr());
    }
    let enables = [
        vk::ValidationFeatureEnableEXT::SYNCHRONIZATION_VALIDATION,
        vk::ValidationFeatureEnableEXT::BEST_PRACTICES,
    ];
    let mut features = vk::ValidationFeaturesEXT::default().enabled_validation_features(&enables[..1]);
    let mut info = vk::InstanceCreateInfo::default()
        .application_info(&app)
        .enabled_layer_names(&layers)
        .enabled_extension_names(&extensions);
    if validation == Validation::Sync {
        info = info.push_next(&mut features);
    }
    Ok(unsafe { entry.create_instance(&info, None) }?)
}

impl Context {
    pub fn new(choice: &DeviceChoice, validation: Validation) -> Result<Self, Error> {
        Self::create(choice, validation, None)
    }

    /// A context whose queue can also present to `window` (VK_KHR_swapchain enabled).
    pub fn for_window(choice: &DeviceChoice, validation: Validation, window: WindowHandles) -> Result<Self, Error> {
        Self::create(choice, validation, Some(window))
    }

    fn create(choice: &DeviceChoice, validation: Validation, window: Option<WindowHandles>) -> Result<Self, Error> {
        let entry = load_entry()?;
        let instance = create_instance(&entry, validation, window)?;
        let log = Box::<ValidationLog>::default();
        let debug = create_messenger(&entry, &instance, validation, &log)?;
        let surface = create_surface(&entry, &instance, window)?;
        let (physical, queue_family) = match pick_device(&instance, surface.as_ref(), choice) {
            Ok(picked) => picked,
            Err(e) => {
                unsafe {
                    if let Some(s) = &surface {
                        s.loader.destroy_surface(s.raw, None);
                    }
                    instance.destroy_instance(None)
                };
                return Err(e);
            }
        };
        let properties = unsafe { instance.get_physical_device_properties(physical) };
        let families = unsafe { instance.get_physical_device_queue_family_properties(physical) };
        let timestamps_valid =
            families[queue_family as usize].timestamp_valid_bits > 0 && properties.limits.timestamp_period > 0.0;
        let ray_query = properties.api_version >= vk::API_VERSION_1_2 && ray_query_support(&instance, physical);
        let device = create_device(&instance, physical, queue_family, surface.is_some(), ray_query)?;
        let accel = ray_query.then(|| ash::khr::acceleration_structure::Device::new(&instance, &device));
        let queue = unsafe { device.get_device_queue(queue_family, 0) };
        let allocator = Allocator::new(&AllocatorCreateDesc {
            instance: instance.clone(),
            device: device.clone(),
            physical_device: physical,
            debug_settings: Default::default(),
            buffer_device_address: ray_query,
            allocation_sizes: Default::default(),
        })
        .map_err(|e| Error::Vulkan(format!("allocator: {e}")))?;
        let pool = unsafe {
            device.create_command_pool(
                &vk::CommandPoolCreateInfo::default()
                    .queue_family_index(queue_family)
                    .flags(vk::CommandPoolCreateFlags::RESET_COMMAND_BUFFER),
                None,
            )
        }?;
        let debug_device = debug
            .as_ref()
            .map(|_| ash::ext::debug_utils::Device::new(&instance, &device));
        let fence_timeout = gpu_timeout_from_env()?;
        Ok(Context {
            instance,
            physical,
            properties,
            device,
            queue,
            queue_family,
            allocator: ManuallyDrop::new(Arc::new(Mutex::new(allocator))),
            pool,
            timestamps_valid,
            fence_timeout,
            debug,
            debug_device,
            log,
            surface,
            accel,
            entry,
        })
    }

    /// Bytes of the largest device-local memory heap (256 MiB if the device names none).
    pub fn device_local_heap(&self) -> u64 {
        let memory = unsafe { self.instance.get_physical_device_memory_properties(self.physical) };
        memory.memory_heaps[..memory.memory_heap_count as usize]
            .iter()
            .filter(|h| h.flags.contains(vk::MemoryHeapFlags::DEVICE_LOCAL))
            .map(|h| h.size)
            .max()
            .unwrap_or(256 << 20)
    }

    pub fn device_name(&self) -> String {
        self.properties
            .device_name_as_c_str()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default()
    }

    /// Validation errors reported since the context was made.
    pub fn validation_errors(&self) -> Vec<String> {
        self.log.errors.lock().map(|e| e.clone()).unwrap_or_default()
    }

    /// Names an object for validation messages and capture tools; a no-op without debug utils.
    pub fn set_name<H: vk::Handle>(&self, handle: H, name: &str) {
        if let Some(du) = &self.debug_device {
            if let Ok(c) = std::ffi::CString::new(name) {
                let info = vk::DebugUtilsObjectNameInfoEXT::default()
                    .object_handle(handle)
                    .object_name(&c);
                let _ = unsafe { du.set_debug_utils_object_name(&info) };
            }
        }
    }

    /// Records commands into a fresh command buffer, submits it and waits, with a timeout so a hung device is an error.
    pub fn submit_and_wait(&self, record: impl FnOnce(vk::CommandBuffer)) -> Result<(), Error> {
        let d = &self.device;
        let cmd = unsafe {
            d.allocate_command_buffers(
                &vk::CommandBufferAllocateInfo::default()
                    .command_pool(self.pool)
                    .level(vk::CommandBufferLevel::PRIMARY)
                    .command_buffer_count(1),
            )
        }?[0];
        let fence = unsafe { d.create_fence(&vk::FenceCreateInfo::default(), None) }?;
        let result = (|| -> Result<(), Error> {
            unsafe {
                d.begin_command_buffer(
                    cmd,
                    &vk::CommandBufferBeginInfo::default().flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT),
                )?;
            }
            record(cmd);
            unsafe {
                // Makes device writes visible to host reads of mapped memory once the fence signals.
                let to_host = vk::MemoryBarrier::default()
                    .src_access_mask(vk::AccessFlags::SHADER_WRITE | vk::AccessFlags::TRANSFER_WRITE)
                    .dst_access_mask(vk::AccessFlags::HOST_READ);
                d.cmd_pipeline_barrier(
                    cmd,
                    vk::PipelineStageFlags::COMPUTE_SHADER | vk::PipelineStageFlags::TRANSFER,
                    vk::PipelineStageFlags::HOST,
                    vk::DependencyFlags::empty(),
                    &[to_host],
                    &[],
                    &[],
                );
                d.end_command_buffer(cmd)?;
                let cmds = [cmd];
                d.queue_submit(self.queue, &[vk::SubmitInfo::default().command_buffers(&cmds)], fence)?;
                match d.wait_for_fences(&[fence], true, self.fence_timeout.as_nanos() as u64) {
                    Ok(()) => Ok(()),
                    Err(vk::Result::TIMEOUT) => {
                        DEVICE_LOST.store(true, Ordering::Relaxed);
                        Err(Error::Vulkan(format!(
                            "the device did not finish within {} s (PATHWAVE_GPU_TIMEOUT_SECS); it may be hung",
                            self.fence_timeout.as_secs()
                        )))
                    }
                    Err(e) => Err(e.into()),
                }
            }
        })();
        // A timed-out submission may still be running: its command buffer and fence are leaked, not freed.
        if !device_lost() {
            unsafe {
                if result.is_err() {
                    // A submission that failed some other way may have reached the queue: let it finish first.
                    let _ = d.device_wait_idle();
                }
                d.free_command_buffers(self.pool, &[cmd]);
                d.destroy_fence(fence, None);
            }
        }
        result
    }

    /// A full compute-to-compute (and to indirect-argument and transfer) barrier; the wavefront's stages are serial.
    pub fn barrier(&self, cmd: vk::CommandBuffer) {
        let barrier = vk::MemoryBarrier::default()
            .src_access_mask(vk::AccessFlags::SHADER_WRITE | vk::AccessFlags::TRANSFER_WRITE)
            .dst_access_mask(
                vk::AccessFlags::SHADER_READ
                    | vk::AccessFlags::SHADER_WRITE
                    | vk::AccessFlags::INDIRECT_COMMAND_READ
                    | vk::AccessFlags::TRANSFER_READ
                    | vk::AccessFlags::TRANSFER_WRITE,
            );
        unsafe {
            self.device.cmd_pipeline_barrier(
                cmd,
                vk::PipelineStageFlags::COMPUTE_SHADER | vk::PipelineStageFlags::TRANSFER,
                vk::PipelineStageFlags::COMPUTE_SHADER
                    | vk::PipelineStageFlags::DRAW_INDIRECT
                    | vk::PipelineStageFlags::TRANSFER,
                vk::DependencyFlags::empty(),
                &[barrier],
                &[],
                &[],
            );
        }
    }
}

impl Drop for Context {
    fn drop(&mut self) {
        if device_lost() {
            return;
        }
        unsafe {
            let _ = self.device.device_wait_idle();
            self.device.destroy_command_pool(self.pool, None);
            ManuallyDrop::drop(&mut self.allocator);
            self.device.destroy_device(None);
            if let Some(s) = self.surface.take() {
                s.loader.destroy_surface(s.raw, None);
            }
            if let Some((du, m)) = self.debug.take() {
                du.destroy_debug_utils_messenger(m, None);
            }
            self.instance.destroy_instance(None);
        }
    }
}

/// The window's surface, with the instance functions that query it; None without a window.
fn create_surface(
    entry: &ash::Entry,
    instance: &ash::Instance,
    window: Option<WindowHandles>,
) -> Result<Option<Surface>, Error> {
    let surface = match window {
        Some(w) => {
            let raw = unsafe { ash_window::create_surface(entry, instance, w.display, w.window, None) }?;
            Some(Surface {
                loader: ash::khr::surface::Instance::new(entry, instance),
                raw,
            })
        }
        None => None,
    };
    Ok(surface)
}

/// The logical device with one queue of `queue_family`, the swapchain extension when it is to `present`, and the
/// ray-query extensions and features when the device has `ray_query`.
fn create_device(
    instance: &ash::Instance,
    physical: vk::PhysicalDevice,
    queue_family: u32,
    present: bool,
    ray_query: bool,
) -> Result<ash::Device, Error> {
    let priorities = [1.0];
    let queue_info = [vk::DeviceQueueCreateInfo::default()
        .queue_family_index(queue_family)
        .queue_priorities(&priorities)];
    let mut device_extensions = Vec::new();
    if present {
        device_extensions.push(ash::khr::swapchain::NAME.as_ptr());
    }
    if ray_query {
        device_extensions.extend(RAY_QUERY_EXTENSIONS.iter().map(|n| n.as_ptr()));
    }
    let mut rq_features = vk::PhysicalDeviceRayQueryFeaturesKHR::default().ray_query(true);
    let mut accel_features = vk::PhysicalDeviceAccelerationStructureFeaturesKHR::default().acceleration_structure(true);
    let mut address_features = vk::PhysicalDeviceVulkan12Features::default().buffer_device_address(true);
    let mut device_info = vk::DeviceCreateInfo::default()
        .queue_create_infos(&queue_info)
        .enabled_extension_names(&device_extensions);
    if ray_query {
        device_info = device_info
            .push_next(&mut rq_features)
            .push_next(&mut accel_features)
            .push_next(&mut address_features);
    }
    Ok(unsafe { instance.create_device(physical, &device_info, None) }?)
}

/// The messenger that collects the validation layer's errors and warnings into `log`, when validation is on.
fn create_messenger(
    entry: &ash::Entry,
    instance: &ash::Instance,
    validation: Validation,
    log: &ValidationLog,
) -> Result<Option<(ash::ext::debug_utils::Instance, vk::DebugUtilsMessengerEXT)>, Error> {
    if validation == Validation::Off {
        return Ok(None);
    }
    let du = ash::ext::debug_utils::Instance::new(entry, instance);
    let info = vk::DebugUtilsMessengerCreateInfoEXT::default()
        .message_severity(vk::DebugUtilsMessageSeverityFlagsEXT::ERROR | vk::DebugUtilsMessageSeverityFlagsEXT::WARNING)
        .message_type(
            vk::DebugUtilsMessageTypeFlagsEXT::GENERAL
                | vk::DebugUtilsMessageTypeFlagsEXT::VALIDATION
                | vk::DebugUtilsMessageTypeFlagsEXT::PERFORMANCE,
        )
        .pfn_user_callback(Some(debug_callback))
        .user_data(log as *const ValidationLog as *mut c_void);
    let m = unsafe { du.create_debug_utils_messenger(&info, None) }?;
    Ok(Some((du, m)))
}
