//! Vulkan instance and device: loading a chosen driver, the validation layer with a debug-utils messenger
//! that collects VUIDs, and devices created with exactly the extensions and features a case enables.

use crate::error::HarnessError;
use crate::layout::{self, EXTENSIBLE_HEADER};
use crate::structs::{self, RawChain, FEATURE_STRUCTS};
use crate::vk_tables;
use ash::vk;
use std::collections::{BTreeMap, BTreeSet};
use std::ffi::{c_void, CStr, CString};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};

/// The name of the Khronos validation layer.
pub const VALIDATION_LAYER: &str = "VK_LAYER_KHRONOS_validation";

/// Which Vulkan driver to load.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Driver {
    /// Mesa's CPU driver: `/usr/share/vulkan/icd.d/lvp_icd.json`.
    Lavapipe,
    /// NVIDIA's driver: `/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json`.
    Nvidia,
    /// Any ICD manifest.
    Icd(PathBuf),
}

impl Driver {
    pub fn icd_path(&self) -> PathBuf {
        match self {
            Driver::Lavapipe => PathBuf::from("/usr/share/vulkan/icd.d/lvp_icd.json"),
            Driver::Nvidia => PathBuf::from("/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json"),
            Driver::Icd(p) => p.clone(),
        }
    }

    /// Short name for profiles and reports.
    pub fn name(&self) -> String {
        match self {
            Driver::Lavapipe => "lavapipe".into(),
            Driver::Nvidia => "nvidia".into(),
            Driver::Icd(p) => p
                .file_stem()
                .map_or("icd".into(), |s| s.to_string_lossy().into_owned()),
        }
    }

    /// `lavapipe`, `nvidia`, or a path to an ICD json.
    pub fn parse(s: &str) -> Driver {
        match s {
            "lavapipe" | "lvp" => Driver::Lavapipe,
            "nvidia" => Driver::Nvidia,
            path => Driver::Icd(PathBuf::from(path)),
        }
    }
}

/// One message of the validation layer.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct LayerMessage {
    /// `error`, `warning`, `info` or `verbose`.
    pub severity: String,
    /// `pMessageIdName`: the VUID for valid-usage errors.
    pub id: String,
    pub text: String,
}

/// What the messenger callback writes into; shared with the callback through its user-data pointer.
#[derive(Default)]
pub struct Collector {
    messages: Mutex<Vec<LayerMessage>>,
    /// While set, the callback returns VK_TRUE so the layer drops the call instead of passing it on.
    abort: AtomicBool,
}

impl Collector {
    pub fn clear(&self) {
        self.messages
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .clear();
    }
    pub fn take(&self) -> Vec<LayerMessage> {
        std::mem::take(&mut *self.messages.lock().unwrap_or_else(|e| e.into_inner()))
    }
    pub fn set_abort(&self, abort: bool) {
        self.abort.store(abort, Ordering::SeqCst);
    }
}

unsafe extern "system" fn messenger_callback(
    severity: vk::DebugUtilsMessageSeverityFlagsEXT,
    _types: vk::DebugUtilsMessageTypeFlagsEXT,
    data: *const vk::DebugUtilsMessengerCallbackDataEXT<'_>,
    user: *mut c_void,
) -> vk::Bool32 {
    if user.is_null() {
        return vk::FALSE;
    }
    let collector = &*(user as *const Collector);
    let text = |p: *const std::ffi::c_char| {
        if p.is_null() {
            String::new()
        } else {
            CStr::from_ptr(p).to_string_lossy().into_owned()
        }
    };
    let (id, message) = if data.is_null() {
        (String::new(), String::new())
    } else {
        (text((*data).p_message_id_name), text((*data).p_message))
    };
    let severity = if severity.contains(vk::DebugUtilsMessageSeverityFlagsEXT::ERROR) {
        "error"
    } else if severity.contains(vk::DebugUtilsMessageSeverityFlagsEXT::WARNING) {
        "warning"
    } else if severity.contains(vk::DebugUtilsMessageSeverityFlagsEXT::INFO) {
        "info"
    } else {
        "verbose"
    };
    collector
        .messages
        .lock()
        .unwrap_or_else(|e| e.into_inner())
        .push(LayerMessage {
            severity: severity.into(),
            id,
            text: message,
        });
    if collector.abort.load(Ordering::SeqCst) {
        vk::TRUE
    } else {
        vk::FALSE
    }
}

/// A loaded driver: entry, instance, and (with validation) the layer's messenger.
pub struct VkInstance {
    pub driver: Driver,
    pub entry: ash::Entry,
    pub instance: ash::Instance,
    debug: Option<(ash::ext::debug_utils::Instance, vk::DebugUtilsMessengerEXT)>,
    pub collector: Arc<Collector>,
    pub physical: vk::PhysicalDevice,
    pub api_version: u32,
}

// SAFETY: Vulkan instance handles may be used from any thread; the harness serialises use per device.
unsafe impl Send for VkInstance {}
unsafe impl Sync for VkInstance {}

impl VkInstance {
    /// Loads `driver` (setting `VK_DRIVER_FILES` before the loader reads it) and creates an instance, with
    /// the validation layer and a messenger when `validation` is set, and picks the driver's first device.
    pub fn new(driver: Driver, validation: bool) -> Result<VkInstance, HarnessError> {
        let icd = driver.icd_path();
        if !icd.is_file() {
            return Err(HarnessError::IcdMissing(icd.display().to_string()));
        }
        std::env::set_var("VK_DRIVER_FILES", &icd);
        // SAFETY: loading the system loader library; failure is reported, not unwound.
        let entry = unsafe { ash::Entry::load() }
            .map_err(|e| HarnessError::LoaderMissing(e.to_string()))?;
        let layer = CString::new(VALIDATION_LAYER).expect("no NUL in a constant");
        if validation {
            // SAFETY: plain query.
            let layers = unsafe { entry.enumerate_instance_layer_properties() }
                .map_err(HarnessError::vk("vkEnumerateInstanceLayerProperties"))?;
            let found = layers
                .iter()
                .any(|l| l.layer_name_as_c_str().is_ok_and(|n| n == layer.as_c_str()));
            if !found {
                return Err(HarnessError::LayerMissing(VALIDATION_LAYER.into()));
            }
        }
        let app_name = CString::new("rtconf").expect("no NUL");
        let app = vk::ApplicationInfo::default()
            .application_name(&app_name)
            .api_version(vk::API_VERSION_1_3);
        let layer_ptrs = if validation {
            vec![layer.as_ptr()]
        } else {
            vec![]
        };
        let ext_ptrs = if validation {
            vec![ash::ext::debug_utils::NAME.as_ptr()]
        } else {
            vec![]
        };
        let info = vk::InstanceCreateInfo::default()
            .application_info(&app)
            .enabled_layer_names(&layer_ptrs)
            .enabled_extension_names(&ext_ptrs);
        // SAFETY: valid create info whose pointers outlive the call.
        let instance = unsafe { entry.create_instance(&info, None) }
            .map_err(HarnessError::vk("vkCreateInstance"))?;
        let collector = Arc::new(Collector::default());
        let debug = if validation {
            let du = ash::ext::debug_utils::Instance::new(&entry, &instance);
            let info = vk::DebugUtilsMessengerCreateInfoEXT::default()
                .message_severity(
                    vk::DebugUtilsMessageSeverityFlagsEXT::ERROR
                        | vk::DebugUtilsMessageSeverityFlagsEXT::WARNING,
                )
                .message_type(
                    vk::DebugUtilsMessageTypeFlagsEXT::VALIDATION
                        | vk::DebugUtilsMessageTypeFlagsEXT::GENERAL
                        | vk::DebugUtilsMessageTypeFlagsEXT::PERFORMANCE,
                )
                .pfn_user_callback(Some(messenger_callback))
                .user_data(Arc::as_ptr(&collector) as *mut c_void);
            // SAFETY: the collector outlives the messenger (destroyed in Drop before the Arc goes).
            let m = unsafe { du.create_debug_utils_messenger(&info, None) }
                .map_err(HarnessError::vk("vkCreateDebugUtilsMessengerEXT"))?;
            Some((du, m))
        } else {
            None
        };
        // SAFETY: plain query.
        let physicals = unsafe { instance.enumerate_physical_devices() }.unwrap_or_default();
        let Some(&physical) = physicals.first() else {
            // SAFETY: destroying what was created above.
            unsafe {
                if let Some((du, m)) = &debug {
                    du.destroy_debug_utils_messenger(*m, None);
                }
                instance.destroy_instance(None);
            }
            return Err(HarnessError::NoDevice(icd.display().to_string()));
        };
        // SAFETY: plain query.
        let api_version = unsafe { instance.get_physical_device_properties(physical) }.api_version;
        Ok(VkInstance {
            driver,
            entry,
            instance,
            debug,
            collector,
            physical,
            api_version,
        })
    }

    /// The device extensions the physical device exposes.
    pub fn device_extensions(&self) -> BTreeSet<String> {
        // SAFETY: plain query.
        unsafe {
            self.instance
                .enumerate_device_extension_properties(self.physical)
        }
        .unwrap_or_default()
        .iter()
        .filter_map(|e| {
            e.extension_name_as_c_str()
                .ok()
                .map(|n| n.to_string_lossy().into_owned())
        })
        .collect()
    }

    /// Every feature the device reports, keyed `Struct::member`, querying each structure it supports.
    pub fn device_features(&self) -> BTreeMap<String, bool> {
        let exts = self.device_extensions();
        let mut chain = RawChain::new();
        for s in FEATURE_STRUCTS {
            if s.usable(self.api_version, |e| exts.contains(e)) {
                chain.push(s);
            }
        }
        let head = chain.link();
        let mut f2 = vk::PhysicalDeviceFeatures2::default();
        f2.p_next = head;
        // SAFETY: the chain holds structures with correct sTypes and sizes; it lives across the call.
        unsafe {
            self.instance
                .get_physical_device_features2(self.physical, &mut f2)
        };
        let mut out = BTreeMap::new();
        for (n, v) in layout::read_bools(
            vk_tables::PHYSICAL_DEVICE_FEATURES,
            0,
            structs::as_bytes(&f2.features),
        ) {
            out.insert(format!("VkPhysicalDeviceFeatures::{n}"), v);
        }
        for (info, bytes) in chain.parts() {
            for (n, v) in layout::read_bools(info.members, EXTENSIBLE_HEADER, bytes) {
                out.insert(format!("{}::{n}", info.name), v);
            }
        }
        out
    }
}

impl Drop for VkInstance {
    fn drop(&mut self) {
        // SAFETY: every device made from this instance is dropped first (DeviceContext holds an Arc).
        unsafe {
            if let Some((du, m)) = self.debug.take() {
                du.destroy_debug_utils_messenger(m, None);
            }
            self.instance.destroy_instance(None);
        }
    }
}

/// Why a device cannot be made for a case: a missing capability (unsupported) or a failure.
#[derive(Debug)]
pub enum DeviceError {
    Unsupported(String),
    Failed(HarnessError),
}

/// The features structures to chain for a requested feature set, or why the set cannot be enabled.
fn feature_chain(
    inst: &VkInstance,
    extensions: &BTreeSet<String>,
    features: &BTreeSet<String>,
    supported: &BTreeMap<String, bool>,
) -> Result<(vk::PhysicalDeviceFeatures, RawChain), DeviceError> {
    let mut core = vk::PhysicalDeviceFeatures::default();
    let mut chain = RawChain::new();
    let mut missing = Vec::new();
    for name in features {
        let (want_struct, member) = match name.split_once("::") {
            Some((s, m)) => (Some(s), m),
            None => (None, name.as_str()),
        };
        let in_core = vk_tables::PHYSICAL_DEVICE_FEATURES
            .iter()
            .any(|m| m.name == member);
        if in_core && want_struct.is_none_or(|s| s == "VkPhysicalDeviceFeatures") {
            if !supported
                .get(&format!("VkPhysicalDeviceFeatures::{member}"))
                .copied()
                .unwrap_or(false)
            {
                missing.push(name.clone());
                continue;
            }
            // SAFETY: VkPhysicalDeviceFeatures is a plain array of VkBool32.
            let bytes = unsafe {
                std::slice::from_raw_parts_mut(
                    &mut core as *mut _ as *mut u8,
                    std::mem::size_of::<vk::PhysicalDeviceFeatures>(),
                )
            };
            layout::set_bool(vk_tables::PHYSICAL_DEVICE_FEATURES, 0, bytes, member);
            continue;
        }
        let candidates: Vec<&'static structs::StructInfo> = FEATURE_STRUCTS
            .iter()
            .filter(|s| {
                want_struct.is_none_or(|w| w == s.name)
                    && s.members.iter().any(|m| m.name == member)
            })
            .collect();
        if candidates.is_empty() {
            return Err(DeviceError::Unsupported(format!(
                "unknown device feature `{name}`"
            )));
        }
        let usable = candidates.iter().find(|s| {
            s.usable(inst.api_version, |e| extensions.contains(e))
                && supported.contains_key(&format!("{}::{member}", s.name))
        });
        let Some(s) = usable else {
            let needs: Vec<String> = candidates
                .iter()
                .map(|s| s.extension.map_or_else(|| s.name.to_string(), String::from))
                .collect();
            return Err(DeviceError::Unsupported(format!(
                "feature `{name}` needs one of [{}] enabled on a device that has it",
                needs.join(", ")
            )));
        };
        if !supported
            .get(&format!("{}::{member}", s.name))
            .copied()
            .unwrap_or(false)
        {
            missing.push(name.clone());
            continue;
        }
        let i = chain.position(s.name).unwrap_or_else(|| chain.push(s));
        layout::set_bool(s.members, EXTENSIBLE_HEADER, chain.bytes_mut(i), member);
    }
    if !missing.is_empty() {
        return Err(DeviceError::Unsupported(format!(
            "the device lacks feature(s): {}",
            missing.join(", ")
        )));
    }
    Ok((core, chain))
}

/// Ray tracing limits the harness lays tables out with.
#[derive(Debug, Clone, Copy, Default)]
pub struct RtLimits {
    pub handle_size: u32,
    pub handle_alignment: u32,
    pub base_alignment: u32,
    pub scratch_alignment: u32,
    /// `VkPhysicalDeviceRayTracingPropertiesNV::shaderGroupHandleSize` (0 without VK_NV_ray_tracing).
    pub nv_handle_size: u32,
}

/// A logical device with exactly a case's extensions and features, and what the harness needs of it.
pub struct VkDevice {
    pub inst: Arc<VkInstance>,
    pub device: ash::Device,
    pub queue: vk::Queue,
    pub queue_family: u32,
    pub extensions: BTreeSet<String>,
    pub features: BTreeSet<String>,
    pub rt: Option<ash::khr::ray_tracing_pipeline::Device>,
    pub accel: Option<ash::khr::acceleration_structure::Device>,
    pub memory: vk::PhysicalDeviceMemoryProperties,
    pub limits: RtLimits,
    pub sparse_binding: bool,
    /// VK_NV_ray_tracing, when the case enables it.
    pub nv: Option<ash::nv::ray_tracing::Device>,
    /// Set by the owner when the device was lost or a submission never finished: dropping then neither
    /// waits for nor destroys the device, and keeps its instance alive (a leak, never a hang).
    pub leak: bool,
}

impl VkDevice {
    /// Creates a device with exactly `extensions` and `features` enabled, or says what the driver lacks.
    pub fn new(
        inst: Arc<VkInstance>,
        extensions: &BTreeSet<String>,
        features: &BTreeSet<String>,
    ) -> Result<VkDevice, DeviceError> {
        let available = inst.device_extensions();
        let missing: Vec<&String> = extensions
            .iter()
            .filter(|e| !available.contains(*e))
            .collect();
        if !missing.is_empty() {
            let names: Vec<&str> = missing.iter().map(|s| s.as_str()).collect();
            return Err(DeviceError::Unsupported(format!(
                "the device lacks extension(s): {}",
                names.join(", ")
            )));
        }
        let supported = inst.device_features();
        let (core, mut chain) = feature_chain(&inst, extensions, features, &supported)?;
        // SAFETY: plain query.
        let families = unsafe {
            inst.instance
                .get_physical_device_queue_family_properties(inst.physical)
        };
        let Some(family) = families
            .iter()
            .position(|f| f.queue_flags.contains(vk::QueueFlags::COMPUTE))
        else {
            return Err(DeviceError::Unsupported(
                "no queue family with VK_QUEUE_COMPUTE_BIT".into(),
            ));
        };
        let priorities = [1.0f32];
        let queue_info = [vk::DeviceQueueCreateInfo::default()
            .queue_family_index(family as u32)
            .queue_priorities(&priorities)];
        let ext_c: Vec<CString> = extensions
            .iter()
            .filter_map(|e| CString::new(e.as_str()).ok())
            .collect();
        let ext_ptrs: Vec<*const std::ffi::c_char> = ext_c.iter().map(|c| c.as_ptr()).collect();
        let head = chain.link();
        let mut info = vk::DeviceCreateInfo::default()
            .queue_create_infos(&queue_info)
            .enabled_extension_names(&ext_ptrs)
            .enabled_features(&core);
        info.p_next = head;
        // SAFETY: every pointer in `info` outlives the call.
        let device =
            unsafe { inst.instance.create_device(inst.physical, &info, None) }.map_err(|r| {
                DeviceError::Failed(HarnessError::Vulkan {
                    what: "vkCreateDevice".into(),
                    result: r,
                })
            })?;
        // SAFETY: queue 0 of the family we created.
        let queue = unsafe { device.get_device_queue(family as u32, 0) };
        let rt = extensions
            .contains("VK_KHR_ray_tracing_pipeline")
            .then(|| ash::khr::ray_tracing_pipeline::Device::new(&inst.instance, &device));
        let nv = extensions
            .contains("VK_NV_ray_tracing")
            .then(|| ash::nv::ray_tracing::Device::new(&inst.instance, &device));
        let accel = extensions
            .contains("VK_KHR_acceleration_structure")
            .then(|| ash::khr::acceleration_structure::Device::new(&inst.instance, &device));
        // SAFETY: plain queries.
        let memory = unsafe {
            inst.instance
                .get_physical_device_memory_properties(inst.physical)
        };
        let mut rtp = vk::PhysicalDeviceRayTracingPipelinePropertiesKHR::default();
        let mut asp = vk::PhysicalDeviceAccelerationStructurePropertiesKHR::default();
        let mut nvp = vk::PhysicalDeviceRayTracingPropertiesNV::default();
        let mut p2 = vk::PhysicalDeviceProperties2::default();
        if available.contains("VK_NV_ray_tracing") {
            p2 = p2.push_next(&mut nvp);
        }
        if available.contains("VK_KHR_ray_tracing_pipeline") {
            p2 = p2.push_next(&mut rtp);
        }
        if available.contains("VK_KHR_acceleration_structure") {
            p2 = p2.push_next(&mut asp);
        }
        // SAFETY: chain of structures the device supports.
        unsafe {
            inst.instance
                .get_physical_device_properties2(inst.physical, &mut p2)
        };
        // A case with only VK_NV_ray_tracing lays its tables out with the NV properties.
        let nv_only = rtp.shader_group_handle_size == 0;
        let limits = RtLimits {
            handle_size: if nv_only {
                nvp.shader_group_handle_size
            } else {
                rtp.shader_group_handle_size
            },
            handle_alignment: if nv_only {
                nvp.shader_group_handle_size
            } else {
                rtp.shader_group_handle_alignment
            },
            base_alignment: if nv_only {
                nvp.shader_group_base_alignment
            } else {
                rtp.shader_group_base_alignment
            },
            scratch_alignment: asp.min_acceleration_structure_scratch_offset_alignment,
            nv_handle_size: nvp.shader_group_handle_size,
        };
        let sparse_binding = supported
            .get("VkPhysicalDeviceFeatures::sparseBinding")
            .copied()
            .unwrap_or(false)
            && families[family]
                .queue_flags
                .contains(vk::QueueFlags::SPARSE_BINDING);
        Ok(VkDevice {
            inst,
            device,
            queue,
            queue_family: family as u32,
            extensions: extensions.clone(),
            features: features.clone(),
            rt,
            accel,
            memory,
            limits,
            sparse_binding,
            nv,
            leak: false,
        })
    }

    /// Whether the device was created with feature `name` (member name or `Struct::member`).
    pub fn has_feature(&self, name: &str) -> bool {
        self.features
            .iter()
            .any(|f| f == name || f.rsplit("::").next() == Some(name))
    }

    /// A memory type index allowed by `bits` with all of `flags`.
    pub fn memory_type(&self, bits: u32, flags: vk::MemoryPropertyFlags) -> Option<u32> {
        (0..self.memory.memory_type_count).find(|&i| {
            bits & (1 << i) != 0
                && self.memory.memory_types[i as usize]
                    .property_flags
                    .contains(flags)
        })
    }
}

impl Drop for VkDevice {
    fn drop(&mut self) {
        if self.leak {
            std::mem::forget(self.inst.clone());
            return;
        }
        // SAFETY: every object made from the device is destroyed by its owner before this runs.
        unsafe {
            let _ = self.device.device_wait_idle();
            self.device.destroy_device(None);
        }
    }
}
