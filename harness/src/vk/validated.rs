//! The validation layer's record of the shader modules it found valid (VK_EXT_validation_cache), kept
//! on disk per device configuration, so that each worker process and each later run does not have the
//! layer validate again (spirv-val) a module it passed before.
//!
//! The layer keys its record by a hash of the SPIR-V alone (1.3.239: `ValidationCache::MakeShaderHash`,
//! XXH32 of the code), while what it checks a module against depends on the device: its API version,
//! its extensions and its enabled features choose the validator's options. So a record is kept per
//! device configuration (the layer's build, the API version, the extensions and features the case
//! enables) and never shared between two. A record holds only modules the layer passed: a module it
//! would reject is validated, and reported, every time.
//!
//! A record is a file named by the configuration's fingerprint in a folder under the temporary
//! directory; it is read when a device is made (at most [`MAX_RECORD_BYTES`], else ignored) and
//! written whole (a temporary file, then a rename) when the device is destroyed or its process ends,
//! merged with what another process wrote meanwhile. `RTCONF_LAYER_CACHE=off` turns it off.

use ash::vk;
use std::collections::BTreeSet;
use std::io::Read;
use std::path::{Path, PathBuf};

/// The extension the layer offers for its record.
pub(crate) const EXTENSION: &str = "VK_EXT_validation_cache";

/// A record larger than this is not read (the layer's holds 4 bytes per module it passed).
const MAX_RECORD_BYTES: u64 = 8 << 20;

/// One device's record: the layer's cache object and the file it is kept in.
pub(crate) struct ValidatedModules {
    fns: ash::ext::validation_cache::Device,
    cache: vk::ValidationCacheEXT,
    file: PathBuf,
    /// The size of the record's data when it was read (nothing to write while it stays so).
    read_size: usize,
}

/// The file of the record of a device configuration, or None when records are off.
pub(crate) fn record_file(
    layer_build: (u32, u32),
    api_version: u32,
    extensions: &BTreeSet<String>,
    features: &BTreeSet<String>,
) -> Option<PathBuf> {
    if std::env::var_os("RTCONF_LAYER_CACHE").is_some_and(|v| v == "off") {
        return None;
    }
    let key = model::fingerprint::of(&(layer_build, api_version, extensions, features))?;
    Some(
        std::env::temp_dir()
            .join("rtconf-layer-validated")
            .join(format!("{key:032x}.bin")),
    )
}

/// The file's bytes, if it exists and is no larger than [`MAX_RECORD_BYTES`].
fn read_record(file: &Path) -> Option<Vec<u8>> {
    let f = std::fs::File::open(file).ok()?;
    let mut bytes = Vec::new();
    f.take(MAX_RECORD_BYTES + 1).read_to_end(&mut bytes).ok()?;
    (bytes.len() as u64 <= MAX_RECORD_BYTES).then_some(bytes)
}

impl ValidatedModules {
    /// The layer's cache object on `device` (made with [`EXTENSION`] enabled), filled from `file`.
    /// None when the layer does not make one.
    pub(crate) fn open(
        instance: &ash::Instance,
        device: &ash::Device,
        file: PathBuf,
    ) -> Option<ValidatedModules> {
        let fns = ash::ext::validation_cache::Device::new(instance, device);
        let bytes = read_record(&file).unwrap_or_default();
        let cache = create(&fns, &bytes)?;
        let read_size = data_size(&fns, cache).unwrap_or(0);
        Some(ValidatedModules {
            fns,
            cache,
            file,
            read_size,
        })
    }

    /// The cache object, for a module's `VkShaderModuleValidationCacheCreateInfoEXT`.
    pub(crate) fn cache(&self) -> vk::ValidationCacheEXT {
        self.cache
    }

    /// Writes the record when the layer passed modules it did not hold when read, merged with what
    /// the file holds now (another process may have written it since). A record that cannot be
    /// written is only slower.
    pub(crate) fn save(&mut self) {
        let Some(size) = data_size(&self.fns, self.cache) else {
            return;
        };
        if size <= self.read_size {
            return;
        }
        if let Some(theirs) = read_record(&self.file).and_then(|b| create(&self.fns, &b)) {
            // SAFETY: both caches are this device's; the source is destroyed right after.
            let _ = unsafe {
                (self.fns.fp().merge_validation_caches_ext)(
                    self.fns.device(),
                    self.cache,
                    1,
                    &theirs,
                )
            };
            destroy_cache(&self.fns, theirs);
        }
        if let Some(bytes) = data(&self.fns, self.cache) {
            crate::shaders::disk::write(&self.file, &bytes);
            self.read_size = bytes.len();
        }
    }

    /// Destroys the cache object (before its device).
    pub(crate) fn destroy(&mut self) {
        destroy_cache(&self.fns, self.cache);
        self.cache = vk::ValidationCacheEXT::null();
    }
}

/// Destroys a cache object of the device (no module is being made with it).
fn destroy_cache(fns: &ash::ext::validation_cache::Device, cache: vk::ValidationCacheEXT) {
    // SAFETY: the cache is this device's and not in use.
    unsafe { (fns.fp().destroy_validation_cache_ext)(fns.device(), cache, std::ptr::null()) };
}

/// A cache object filled from `bytes` (the layer ignores data of another build).
fn create(
    fns: &ash::ext::validation_cache::Device,
    bytes: &[u8],
) -> Option<vk::ValidationCacheEXT> {
    let info = vk::ValidationCacheCreateInfoEXT::default().initial_data(bytes);
    let mut cache = vk::ValidationCacheEXT::null();
    // SAFETY: `info` and `bytes` outlive the call.
    let r = unsafe {
        (fns.fp().create_validation_cache_ext)(fns.device(), &info, std::ptr::null(), &mut cache)
    };
    (r == vk::Result::SUCCESS).then_some(cache)
}

/// The size of the cache's data.
fn data_size(
    fns: &ash::ext::validation_cache::Device,
    cache: vk::ValidationCacheEXT,
) -> Option<usize> {
    let mut size = 0usize;
    // SAFETY: a size query.
    let r = unsafe {
        (fns.fp().get_validation_cache_data_ext)(
            fns.device(),
            cache,
            &mut size,
            std::ptr::null_mut(),
        )
    };
    (r == vk::Result::SUCCESS).then_some(size)
}

/// The cache's data.
fn data(
    fns: &ash::ext::validation_cache::Device,
    cache: vk::ValidationCacheEXT,
) -> Option<Vec<u8>> {
    let mut size = data_size(fns, cache)?;
    let mut bytes = vec![0u8; size];
    // SAFETY: writes at most `size` bytes into a buffer of that size.
    let r = unsafe {
        (fns.fp().get_validation_cache_data_ext)(
            fns.device(),
            cache,
            &mut size,
            bytes.as_mut_ptr().cast(),
        )
    };
    if r != vk::Result::SUCCESS {
        return None;
    }
    bytes.truncate(size);
    Some(bytes)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::vk::{Driver, VkDevice, VkInstance};
    use std::sync::Arc;

    fn set(names: &[&str]) -> BTreeSet<String> {
        names.iter().map(|s| s.to_string()).collect()
    }

    #[test]
    fn each_device_configuration_has_a_record_of_its_own() {
        let file = |ext: &[&str], feat: &[&str]| {
            record_file((1, 2), vk::API_VERSION_1_3, &set(ext), &set(feat))
        };
        let plain = file(&[], &[]);
        assert!(plain.is_some());
        assert_eq!(plain, file(&[], &[]));
        assert_ne!(plain, file(&["VK_KHR_ray_tracing_pipeline"], &[]));
        assert_ne!(
            plain,
            file(
                &[],
                &["VkPhysicalDeviceVulkan12Features::scalarBlockLayout"]
            )
        );
        assert_ne!(
            plain,
            record_file((1, 3), vk::API_VERSION_1_3, &set(&[]), &set(&[]))
        );
        assert_ne!(
            plain,
            record_file((1, 2), vk::API_VERSION_1_2, &set(&[]), &set(&[]))
        );
    }

    #[test]
    fn a_record_larger_than_the_bound_is_not_read() {
        let dir = tempfile::tempdir().unwrap();
        let big = dir.path().join("big.bin");
        std::fs::File::create(&big)
            .unwrap()
            .set_len(MAX_RECORD_BYTES + 1)
            .unwrap();
        assert_eq!(read_record(&big), None);
        let small = dir.path().join("small.bin");
        std::fs::write(&small, [1u8, 2, 3]).unwrap();
        assert_eq!(read_record(&small), Some(vec![1, 2, 3]));
        assert_eq!(read_record(&dir.path().join("absent.bin")), None);
    }

    /// A module the layer passed is in the record a device of the same configuration reads, once;
    /// a module it rejects is reported with that record in place, and never enters it.
    #[test]
    fn the_record_keeps_passed_modules_only_and_never_hides_a_rejected_one() {
        // Vulkan called directly, as the executor does, in the process's turn.
        let _turn = crate::vk::turn::take();
        let inst =
            Arc::new(VkInstance::new(Driver::Lavapipe, true).expect("lavapipe with the layer"));
        assert!(
            inst.layer_extensions.contains(EXTENSION),
            "the layer offers {EXTENSION}: {:?}",
            inst.layer_extensions
        );
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("record.bin");
        let device = |file: &Path| {
            let mut dev =
                VkDevice::new(inst.clone(), &set(&[]), &set(&[]), None).expect("a device");
            let default = dev.validated.take();
            assert!(default.is_some(), "a device under the layer keeps a record");
            default.unwrap().destroy();
            dev.validated = Some(
                ValidatedModules::open(&inst.instance, &dev.device, file.to_path_buf())
                    .expect("the layer makes a cache"),
            );
            dev
        };
        let size = |dev: &VkDevice| {
            let v = dev.validated.as_ref().unwrap();
            data_size(&v.fns, v.cache).unwrap()
        };
        let code = crate::shaders::compile_glsl(
            "record-test",
            "comp",
            "#version 460\nlayout(local_size_x = 1) in;\nvoid main() {}\n",
            &[],
        )
        .unwrap();
        let make = |dev: &VkDevice, code: &[u32]| {
            let m = crate::shaders::module(dev, code);
            if let Ok(m) = m {
                // SAFETY: nothing uses the module.
                unsafe { dev.device.destroy_shader_module(m, None) };
            }
        };

        let first = device(&file);
        let empty = size(&first);
        make(&first, &code);
        assert_eq!(size(&first), empty + 4, "the passed module is recorded");
        make(&first, &code);
        assert_eq!(size(&first), empty + 4, "once");
        inst.collector.clear();
        drop(first);
        assert!(file.is_file(), "destroying the device writes its record");

        let second = device(&file);
        assert_eq!(
            size(&second),
            empty + 4,
            "a device of the configuration reads it"
        );
        // A module spirv-val rejects: an OpNop after the function.
        let mut bad = code.clone();
        bad.push(1 << 16);
        inst.collector.clear();
        make(&second, &bad);
        let messages = inst.collector.take();
        assert!(
            messages
                .iter()
                .any(|m| m.severity == "error" && m.text.contains("SPIR-V")),
            "the rejected module is reported: {messages:?}"
        );
        assert_eq!(size(&second), empty + 4, "and is not recorded");
    }
}
