//! The Vulkan instance: loading a chosen driver, and the validation layer with a debug-utils messenger
//! that collects the layer's messages (and, while asked, makes the layer drop the call).

use crate::error::HarnessError;
use crate::vk::layout::{self, EXTENSIBLE_HEADER};
use crate::vk::structs::{self, RawChain, FEATURE_STRUCTS};
use crate::vk::tables as vk_tables;
use ash::vk;
use std::collections::{BTreeMap, BTreeSet};
use std::ffi::{c_void, CStr, CString};
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, OnceLock};

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

/// The validation layer as the loader lists it (`vkEnumerateInstanceLayerProperties`): the API version
/// it was built for (`specVersion`, `1.3.239`), which names its VUIDs' registry, and its own
/// implementation version.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct LayerInfo {
    /// `major.minor.patch` of `specVersion`.
    pub version: String,
    pub implementation_version: u32,
    pub description: String,
}

/// The validation layer the loader finds (honouring `VK_LAYER_PATH`); reads only the layer's manifest.
pub fn validation_layer() -> Result<LayerInfo, HarnessError> {
    // SAFETY: loading the system loader library; failure is reported, not unwound.
    let entry =
        unsafe { ash::Entry::load() }.map_err(|e| HarnessError::LoaderMissing(e.to_string()))?;
    // SAFETY: plain query.
    let layers = unsafe { entry.enumerate_instance_layer_properties() }
        .map_err(HarnessError::vk("vkEnumerateInstanceLayerProperties"))?;
    let layer = layers
        .iter()
        .find(|l| {
            l.layer_name_as_c_str()
                .is_ok_and(|n| n.to_bytes() == VALIDATION_LAYER.as_bytes())
        })
        .ok_or_else(|| HarnessError::LayerMissing(VALIDATION_LAYER.into()))?;
    let v = layer.spec_version;
    Ok(LayerInfo {
        version: format!(
            "{}.{}.{}",
            vk::api_version_major(v),
            vk::api_version_minor(v),
            vk::api_version_patch(v)
        ),
        implementation_version: layer.implementation_version,
        description: layer
            .description_as_c_str()
            .map(|d| d.to_string_lossy().into_owned())
            .unwrap_or_default(),
    })
}

/// Selects the validation layer build in `dir` for this process's loader and the workers it starts: a
/// directory holding the layer's manifest (`VkLayer_khronos_validation.json`), or an unpacked package
/// root (`dir/usr/share/vulkan/explicit_layer.d`), whose library directory
/// (`dir/usr/lib/x86_64-linux-gnu`) goes first on `LD_LIBRARY_PATH` (the manifest names the library
/// without a path, and the layer may need that directory's libstdc++).
pub fn select_layer(dir: &std::path::Path) -> Result<(), HarnessError> {
    let unpacked = dir.join("usr/share/vulkan/explicit_layer.d");
    let manifests = if unpacked.is_dir() {
        unpacked
    } else {
        dir.to_path_buf()
    };
    if !manifests.join("VkLayer_khronos_validation.json").is_file() {
        return Err(HarnessError::LayerMissing(format!(
            "{VALIDATION_LAYER} (no VkLayer_khronos_validation.json in {} or {})",
            dir.display(),
            manifests.display()
        )));
    }
    std::env::set_var("VK_LAYER_PATH", &manifests);
    let lib = dir.join("usr/lib/x86_64-linux-gnu");
    if lib.is_dir() {
        let old = std::env::var("LD_LIBRARY_PATH").unwrap_or_default();
        let joined = if old.is_empty() {
            lib.display().to_string()
        } else {
            format!("{}:{old}", lib.display())
        };
        std::env::set_var("LD_LIBRARY_PATH", joined);
    }
    Ok(())
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
pub(crate) struct Collector {
    messages: Mutex<Vec<LayerMessage>>,
    /// While set, the callback returns VK_TRUE so the layer drops the call instead of passing it on.
    abort: AtomicBool,
    /// Message ids the callback returns VK_FALSE for even while `abort` is set, so the layer's later
    /// checks of the call still run: the layer stops validating a call at the first validation object
    /// (parameter checks, object lifetimes, core checks…) whose check the callback aborted, so a VUID the
    /// device makes unavoidable (reported in the parameter checks) would hide every core check.
    continue_past: Mutex<BTreeSet<String>>,
}

impl Collector {
    pub(crate) fn clear(&self) {
        self.messages
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .clear();
    }
    pub(crate) fn take(&self) -> Vec<LayerMessage> {
        std::mem::take(&mut *self.messages.lock().unwrap_or_else(|e| e.into_inner()))
    }
    pub(crate) fn set_abort(&self, abort: bool) {
        self.abort.store(abort, Ordering::SeqCst);
    }
    /// The message ids the layer's validation continues past (see [`Collector::continue_past`]).
    pub(crate) fn set_continue_past(&self, ids: &[String]) {
        *self.continue_past.lock().unwrap_or_else(|e| e.into_inner()) =
            ids.iter().cloned().collect();
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
    let continues = collector
        .continue_past
        .lock()
        .unwrap_or_else(|e| e.into_inner())
        .contains(&id);
    collector
        .messages
        .lock()
        .unwrap_or_else(|e| e.into_inner())
        .push(LayerMessage {
            severity: severity.into(),
            id,
            text: message,
        });
    if collector.abort.load(Ordering::SeqCst) && !continues {
        vk::TRUE
    } else {
        vk::FALSE
    }
}

/// The names of extensions as a query lists them (a name that is not a C string is left out).
fn extension_names(props: &[vk::ExtensionProperties]) -> BTreeSet<String> {
    props
        .iter()
        .filter_map(|e| e.extension_name_as_c_str().ok())
        .map(|n| n.to_string_lossy().into_owned())
        .collect()
}

/// A loaded driver: entry, instance, and (with validation) the layer's messenger.
pub(crate) struct VkInstance {
    pub(crate) driver: Driver,
    /// The loaded Vulkan loader, kept for as long as the instance lives.
    _entry: ash::Entry,
    pub(crate) instance: ash::Instance,
    debug: Option<(ash::ext::debug_utils::Instance, vk::DebugUtilsMessengerEXT)>,
    pub(crate) collector: Arc<Collector>,
    pub(crate) physical: vk::PhysicalDevice,
    pub(crate) api_version: u32,
    /// The validation layer's spec and implementation versions, when it is loaded.
    pub(crate) layer_build: Option<(u32, u32)>,
    /// The device extensions the validation layer itself offers (VK_EXT_validation_cache, ...).
    pub(crate) layer_extensions: BTreeSet<String>,
    /// What the physical device exposes, asked once ([`VkInstance::device_extensions`],
    /// [`VkInstance::device_features`]): through the loader and the layer, each query costs as much
    /// as recording several cases, and a worker's every device made asked both again.
    exposed_extensions: OnceLock<BTreeSet<String>>,
    exposed_features: OnceLock<BTreeMap<String, bool>>,
}

// SAFETY: Vulkan instance handles may be used from any thread; the harness serialises use per device,
// and calls into Vulkan one thread at a time per process (see `turn`).
unsafe impl Send for VkInstance {}
unsafe impl Sync for VkInstance {}

impl VkInstance {
    /// Loads `driver` (setting `VK_DRIVER_FILES` before the loader reads it) and creates an instance, with
    /// the validation layer and a messenger when `validation` is set, and picks the driver's first device.
    pub(crate) fn new(driver: Driver, validation: bool) -> Result<VkInstance, HarnessError> {
        let _turn = super::turn::take();
        let icd = driver.icd_path();
        if !icd.is_file() {
            return Err(HarnessError::IcdMissing(icd.display().to_string()));
        }
        std::env::set_var("VK_DRIVER_FILES", &icd);
        // SAFETY: loading the system loader library; failure is reported, not unwound.
        let entry = unsafe { ash::Entry::load() }
            .map_err(|e| HarnessError::LoaderMissing(e.to_string()))?;
        let layer = CString::new(VALIDATION_LAYER).expect("no NUL in a constant");
        let mut layer_build = None;
        if validation {
            // SAFETY: plain query.
            let layers = unsafe { entry.enumerate_instance_layer_properties() }
                .map_err(HarnessError::vk("vkEnumerateInstanceLayerProperties"))?;
            let found = layers
                .iter()
                .find(|l| l.layer_name_as_c_str().is_ok_and(|n| n == layer.as_c_str()))
                .ok_or_else(|| HarnessError::LayerMissing(VALIDATION_LAYER.into()))?;
            layer_build = Some((found.spec_version, found.implementation_version));
        }
        // Every message of every case, however often it repeats: newer layers stop reporting a message
        // id after `duplicate_message_limit` (10 by default since the VK_EXT_layer_settings layers) per
        // instance, so a worker's later cases would miss VUIDs its earlier cases drew, and a call whose
        // aborting message went silent would be validated further and passed on. Older layers read the
        // limit from the environment (0 there means unlimited, but a settings file may set one).
        std::env::set_var("VK_LAYER_DUPLICATE_MESSAGE_LIMIT", "1000000000");
        std::env::set_var("VK_LAYER_ENABLE_MESSAGE_LIMIT", "false");
        std::env::set_var("VK_KHRONOS_VALIDATION_ENABLE_MESSAGE_LIMIT", "false");
        let settings_ext = validation
            && unsafe { entry.enumerate_instance_extension_properties(Some(layer.as_c_str())) }
                .unwrap_or_default()
                .iter()
                .any(|e| {
                    e.extension_name_as_c_str()
                        .is_ok_and(|n| n == ash::ext::layer_settings::NAME)
                });
        let limit_off: [vk::Bool32; 1] = [vk::FALSE];
        let limit_key = CString::new("enable_message_limit").expect("no NUL");
        let mut setting = [vk::LayerSettingEXT::default()
            .layer_name(layer.as_c_str())
            .setting_name(limit_key.as_c_str())
            .ty(vk::LayerSettingTypeEXT::BOOL32)
            .values(structs::as_bytes(&limit_off))];
        // `values` counts bytes; the setting holds one VkBool32.
        setting[0].value_count = 1;
        let mut settings = vk::LayerSettingsCreateInfoEXT::default().settings(&setting);
        let app_name = CString::new("rtconf").expect("no NUL");
        let app = vk::ApplicationInfo::default()
            .application_name(&app_name)
            .api_version(vk::API_VERSION_1_3);
        let layer_ptrs = if validation {
            vec![layer.as_ptr()]
        } else {
            vec![]
        };
        let mut ext_ptrs = if validation {
            vec![ash::ext::debug_utils::NAME.as_ptr()]
        } else {
            vec![]
        };
        if settings_ext {
            ext_ptrs.push(ash::ext::layer_settings::NAME.as_ptr());
        }
        let mut info = vk::InstanceCreateInfo::default()
            .application_info(&app)
            .enabled_layer_names(&layer_ptrs)
            .enabled_extension_names(&ext_ptrs);
        if settings_ext {
            info = info.push_next(&mut settings);
        }
        // SAFETY: valid create info whose pointers outlive the call.
        let created = unsafe { entry.create_instance(&info, None) };
        let instance = match created {
            // An older loader under a newer layer (bookworm's 1.3.239 loader with the 1.4.309 layer)
            // passes the layer's VK_EXT_layer_settings down to a driver that lacks it; the layer then
            // takes the limit from the environment set above.
            Err(vk::Result::ERROR_EXTENSION_NOT_PRESENT) if settings_ext => {
                ext_ptrs.retain(|p| *p != ash::ext::layer_settings::NAME.as_ptr());
                let info = vk::InstanceCreateInfo::default()
                    .application_info(&app)
                    .enabled_layer_names(&layer_ptrs)
                    .enabled_extension_names(&ext_ptrs);
                // SAFETY: valid create info whose pointers outlive the call.
                unsafe { entry.create_instance(&info, None) }
            }
            other => other,
        }
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
        // The layer's own device extensions (the loader lists only the driver's without a layer name).
        let layer_extensions = if validation {
            // SAFETY: plain queries; the count bounds the second call's writes.
            unsafe {
                let f = instance.fp_v1_0().enumerate_device_extension_properties;
                let mut count = 0u32;
                let _ = f(physical, layer.as_ptr(), &mut count, std::ptr::null_mut());
                let mut props = vec![vk::ExtensionProperties::default(); count as usize];
                let _ = f(physical, layer.as_ptr(), &mut count, props.as_mut_ptr());
                props.truncate(count as usize);
                extension_names(&props)
            }
        } else {
            BTreeSet::new()
        };
        Ok(VkInstance {
            driver,
            _entry: entry,
            instance,
            debug,
            collector,
            physical,
            api_version,
            layer_build,
            layer_extensions,
            exposed_extensions: OnceLock::new(),
            exposed_features: OnceLock::new(),
        })
    }

    /// What runs cases: the physical device, its driver and the validation layer.
    pub(crate) fn running_on(&self) -> crate::observe::RunningOn {
        let version = |v: u32| {
            format!(
                "{}.{}.{}",
                vk::api_version_major(v),
                vk::api_version_minor(v),
                vk::api_version_patch(v)
            )
        };
        let mut driver = vk::PhysicalDeviceDriverProperties::default();
        let mut p2 = vk::PhysicalDeviceProperties2::default().push_next(&mut driver);
        // SAFETY: plain query; the driver properties are core in Vulkan 1.2.
        unsafe {
            self.instance
                .get_physical_device_properties2(self.physical, &mut p2)
        };
        let p = p2.properties;
        let text = |c: Result<&CStr, _>| {
            c.map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_default()
        };
        let name = text(p.device_name_as_c_str());
        let layer = self.debug.as_ref().and_then(|_| {
            // SAFETY: plain query.
            let layers = unsafe { self._entry.enumerate_instance_layer_properties() }.ok()?;
            let l = layers.iter().find(|l| {
                l.layer_name_as_c_str()
                    .is_ok_and(|n| n.to_bytes() == VALIDATION_LAYER.as_bytes())
            })?;
            Some(format!(
                "{VALIDATION_LAYER} {} (implementation {})",
                version(l.spec_version),
                l.implementation_version
            ))
        });
        crate::observe::RunningOn {
            device: format!(
                "{name} (vendor {:#06x}, device {:#06x})",
                p.vendor_id, p.device_id
            ),
            api_version: version(p.api_version),
            driver: format!(
                "{} {} (driver version {:#010x})",
                text(driver.driver_name_as_c_str()),
                text(driver.driver_info_as_c_str()),
                p.driver_version
            ),
            layer,
        }
    }

    /// The name the physical device reports.
    pub(crate) fn device_name(&self) -> String {
        // SAFETY: plain query.
        let p = unsafe { self.instance.get_physical_device_properties(self.physical) };
        p.device_name_as_c_str()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default()
    }

    /// The device extensions the physical device exposes (asked of the driver once).
    pub(crate) fn device_extensions(&self) -> &BTreeSet<String> {
        self.exposed_extensions.get_or_init(|| {
            // SAFETY: plain query.
            extension_names(
                &unsafe {
                    self.instance
                        .enumerate_device_extension_properties(self.physical)
                }
                .unwrap_or_default(),
            )
        })
    }

    /// Every feature the device reports, keyed `Struct::member`, querying each structure it supports
    /// (asked of the driver once).
    pub(crate) fn device_features(&self) -> &BTreeMap<String, bool> {
        self.exposed_features
            .get_or_init(|| self.query_device_features())
    }

    fn query_device_features(&self) -> BTreeMap<String, bool> {
        let exts = self.device_extensions();
        let mut chain = RawChain::new();
        for s in FEATURE_STRUCTS {
            if s.usable(self.api_version, |e| exts.contains(e)) {
                chain.push(s);
            }
        }
        let head = chain.link();
        let mut f2 = vk::PhysicalDeviceFeatures2 {
            p_next: head,
            ..Default::default()
        };
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
        let _turn = super::turn::take();
        // SAFETY: every device made from this instance is dropped first (DeviceContext holds an Arc).
        unsafe {
            if let Some((du, m)) = self.debug.take() {
                du.destroy_debug_utils_messenger(m, None);
            }
            self.instance.destroy_instance(None);
        }
    }
}
