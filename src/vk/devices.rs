//! The physical devices: choosing one, describing and listing them, and whether they have ray queries.
use super::{create_instance, load_entry, Surface, Validation};
use crate::error::Error;
use ash::vk;
use std::ffi::CStr;

/// Which device to use: the best available, or one by index or (part of its) name.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub enum DeviceChoice {
    #[default]
    Best,
    Index(usize),
    Name(String),
}

impl std::str::FromStr for DeviceChoice {
    type Err = std::convert::Infallible;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Ok(match s.parse::<usize>() {
            Ok(i) => DeviceChoice::Index(i),
            Err(_) => DeviceChoice::Name(s.to_string()),
        })
    }
}

#[derive(Clone, Debug)]
pub struct DeviceInfo {
    pub index: usize,
    pub name: String,
    pub kind: String,
    pub api_version: String,
    /// The driver's own name and version (VkPhysicalDeviceDriverProperties), e.g. "llvmpipe: Mesa 25.0.7".
    pub driver: String,
    pub max_storage_buffer_range: u32,
    /// The device can trace rays through acceleration structures from compute shaders (`ray_query_support`).
    pub ray_query: bool,
}

/// Device extensions ray-query traversal enables: the query itself, the structures it walks, and what building
/// them needs (deferred host operations is required by the acceleration-structure extension).
pub const RAY_QUERY_EXTENSIONS: [&CStr; 3] = [
    ash::khr::ray_query::NAME,
    ash::khr::acceleration_structure::NAME,
    ash::khr::deferred_host_operations::NAME,
];

/// Whether `pd` has every ray-query extension and the features they rest on: rayQuery, accelerationStructure and
/// (core in Vulkan 1.2) bufferDeviceAddress, which is how a build is given its geometry.
pub fn ray_query_support(instance: &ash::Instance, pd: vk::PhysicalDevice) -> bool {
    let Ok(available) = (unsafe { instance.enumerate_device_extension_properties(pd) }) else {
        return false;
    };
    let has = |name: &CStr| {
        available
            .iter()
            .any(|e| e.extension_name_as_c_str().is_ok_and(|n| n == name))
    };
    if !RAY_QUERY_EXTENSIONS.iter().all(|n| has(n)) {
        return false;
    }
    let mut rq = vk::PhysicalDeviceRayQueryFeaturesKHR::default();
    let mut accel = vk::PhysicalDeviceAccelerationStructureFeaturesKHR::default();
    let mut v12 = vk::PhysicalDeviceVulkan12Features::default();
    let mut features = vk::PhysicalDeviceFeatures2::default()
        .push_next(&mut rq)
        .push_next(&mut accel)
        .push_next(&mut v12);
    unsafe { instance.get_physical_device_features2(pd, &mut features) };
    rq.ray_query == vk::TRUE && accel.acceleration_structure == vk::TRUE && v12.buffer_device_address == vk::TRUE
}

fn kind_rank(t: vk::PhysicalDeviceType) -> u32 {
    match t {
        vk::PhysicalDeviceType::DISCRETE_GPU => 0,
        vk::PhysicalDeviceType::INTEGRATED_GPU => 1,
        vk::PhysicalDeviceType::VIRTUAL_GPU => 2,
        vk::PhysicalDeviceType::CPU => 3,
        _ => 4,
    }
}

fn kind_name(t: vk::PhysicalDeviceType) -> &'static str {
    match t {
        vk::PhysicalDeviceType::DISCRETE_GPU => "discrete GPU",
        vk::PhysicalDeviceType::INTEGRATED_GPU => "integrated GPU",
        vk::PhysicalDeviceType::VIRTUAL_GPU => "virtual GPU",
        vk::PhysicalDeviceType::CPU => "CPU",
        _ => "other",
    }
}

fn describe(instance: &ash::Instance, index: usize, pd: vk::PhysicalDevice) -> DeviceInfo {
    let p = unsafe { instance.get_physical_device_properties(pd) };
    let mut driver = vk::PhysicalDeviceDriverProperties::default();
    if p.api_version >= vk::API_VERSION_1_2 {
        let mut p2 = vk::PhysicalDeviceProperties2::default().push_next(&mut driver);
        unsafe { instance.get_physical_device_properties2(pd, &mut p2) };
    }
    let text = |s: Result<&CStr, _>| s.map(|c: &CStr| c.to_string_lossy().into_owned()).unwrap_or_default();
    let (driver_name, driver_info) = (text(driver.driver_name_as_c_str()), text(driver.driver_info_as_c_str()));
    DeviceInfo {
        index,
        name: p
            .device_name_as_c_str()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default(),
        kind: kind_name(p.device_type).to_string(),
        api_version: format!(
            "{}.{}.{}",
            vk::api_version_major(p.api_version),
            vk::api_version_minor(p.api_version),
            vk::api_version_patch(p.api_version)
        ),
        driver: match (driver_name.is_empty(), driver_info.is_empty()) {
            (true, _) => "unknown driver".into(),
            (false, true) => driver_name,
            (false, false) => format!("{driver_name}: {driver_info}"),
        },
        max_storage_buffer_range: p.limits.max_storage_buffer_range,
        ray_query: p.api_version >= vk::API_VERSION_1_2 && ray_query_support(instance, pd),
    }
}

/// Every Vulkan device on this machine, in the loader's order (the index `--device` takes).
pub fn list_devices() -> Result<Vec<DeviceInfo>, Error> {
    let entry = load_entry()?;
    let instance = create_instance(&entry, Validation::Off, None)?;
    let devices = unsafe { instance.enumerate_physical_devices() }?;
    let infos = devices
        .iter()
        .enumerate()
        .map(|(i, &pd)| describe(&instance, i, pd))
        .collect();
    unsafe { instance.destroy_instance(None) };
    Ok(infos)
}

/// The device `choice` names among those with a compute queue (that can also present to `surface`, if any), and
/// that queue's family.
pub(super) fn pick_device(
    instance: &ash::Instance,
    surface: Option<&Surface>,
    choice: &DeviceChoice,
) -> Result<(vk::PhysicalDevice, u32), Error> {
    // With a window, the one queue must compute and present.
    let queue_family_of = |pd: vk::PhysicalDevice| -> Option<u32> {
        let families = unsafe { instance.get_physical_device_queue_family_properties(pd) };
        (0..families.len() as u32).find(|&i| {
            families[i as usize].queue_flags.contains(vk::QueueFlags::COMPUTE)
                && surface.is_none_or(|s| unsafe {
                    s.loader
                        .get_physical_device_surface_support(pd, i, s.raw)
                        .unwrap_or(false)
                })
        })
    };
    let devices = unsafe { instance.enumerate_physical_devices() }?;
    let usable: Vec<(usize, vk::PhysicalDevice)> = devices
        .iter()
        .copied()
        .enumerate()
        .filter(|(_, pd)| queue_family_of(*pd).is_some())
        .collect();
    let picked = match choice {
        DeviceChoice::Best => usable
            .iter()
            .min_by_key(|(i, pd)| {
                (
                    kind_rank(unsafe { instance.get_physical_device_properties(*pd) }.device_type),
                    *i,
                )
            })
            .copied(),
        DeviceChoice::Index(n) => usable.iter().find(|(i, _)| i == n).copied(),
        DeviceChoice::Name(name) => usable
            .iter()
            .find(|(i, pd)| {
                describe(instance, *i, *pd)
                    .name
                    .to_lowercase()
                    .contains(&name.to_lowercase())
            })
            .copied(),
    };
    let Some((_, physical)) = picked else {
        let names: Vec<String> = devices
            .iter()
            .enumerate()
            .map(|(i, &pd)| format!("{i}: {}", describe(instance, i, pd).name))
            .collect();
        return Err(Error::Vulkan(match choice {
            DeviceChoice::Best if surface.is_some() => {
                "no Vulkan device can both compute and present to this window".into()
            }
            DeviceChoice::Best => {
                "no Vulkan device with a compute queue (install mesa-vulkan-drivers for lavapipe)".into()
            }
            other => format!("no device matches {other:?}; devices: [{}]", names.join(", ")),
        }));
    };
    let queue_family = queue_family_of(physical).expect("filtered above");
    Ok((physical, queue_family))
}
