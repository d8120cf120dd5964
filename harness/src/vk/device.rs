//! Devices created with exactly the extensions and features a case enables (or the reason it cannot
//! be), with a queue of the compute family and, for a case whose command pool's family lacks compute, a
//! queue of such a family; and the ray tracing limits the harness lays tables out with.

use super::instance::VkInstance;
use crate::error::HarnessError;
use crate::vk::layout::{self, EXTENSIBLE_HEADER};
use crate::vk::structs::{self, RawChain, FEATURE_STRUCTS};
use crate::vk::tables as vk_tables;
use crate::vk::validated::{self, ValidatedModules};
use ash::vk;
use model::flags::QueueFlags;
use std::collections::{BTreeMap, BTreeSet};
use std::ffi::CString;
use std::sync::Arc;

/// The features structures to chain for a requested feature set, or why the set cannot be enabled.
fn feature_chain(
    inst: &VkInstance,
    extensions: &BTreeSet<String>,
    features: &BTreeSet<String>,
    supported: &BTreeMap<String, bool>,
) -> Result<(vk::PhysicalDeviceFeatures, RawChain), HarnessError> {
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
            return Err(HarnessError::NotRealised(format!(
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
            return Err(HarnessError::NotRealised(format!(
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
    if let Some(first) = missing.first() {
        let member = first.rsplit("::").next().unwrap_or(first).to_string();
        return Err(HarnessError::lacks(
            crate::observe::DeviceLack::Feature(member),
            format!("the device lacks feature(s): {}", missing.join(", ")),
        ));
    }
    Ok((core, chain))
}

/// Ray tracing limits the harness lays tables out with.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct RtLimits {
    pub(crate) handle_size: u32,
    pub(crate) handle_alignment: u32,
    pub(crate) base_alignment: u32,
    pub(crate) scratch_alignment: u32,
    /// `VkPhysicalDeviceRayTracingPropertiesNV::shaderGroupHandleSize` (0 without VK_NV_ray_tracing).
    pub(crate) nv_handle_size: u32,
}

/// How the family chosen for a command pool without compute matches the capabilities a case states.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum PoolMatch {
    /// Its flags, as far as the model names queue flags, are the case's.
    Exact,
    /// It has every capability the case states and more (the fewest more of any such family).
    Superset,
    /// It lacks some capability the case states besides compute (the most of them of any family).
    Nearest,
}

/// The queue family a command pool of a family with `want` and without compute comes from, among
/// `families` (the device's, in order), and how it matches; None when every family has compute.
///
/// Flags are compared on the bits the model names ([`QueueFlags::NAMES`]): a driver's family may carry
/// bits no profile records (optical flow, for one), which no rule reads. An exact match is taken
/// first, then the family with every stated capability and the fewest others, then the one with the
/// most of them. The last two still give the layer the call the case states: a trace command's (and a
/// build's) only rule on its pool's family is that it has compute
/// (`VUID-vkCmdTraceRaysKHR-commandBuffer-cmdpool` and its siblings), and every candidate lacks it.
pub(crate) fn pool_family(
    families: &[vk::QueueFlags],
    want: QueueFlags,
) -> Option<(usize, PoolMatch)> {
    let known = QueueFlags::NAMES.iter().fold(0u64, |a, (_, v)| a | v);
    let named = |f: &vk::QueueFlags| QueueFlags(f.as_raw() as u64 & known);
    let without: Vec<(usize, QueueFlags)> = families
        .iter()
        .map(named)
        .enumerate()
        .filter(|(_, f)| !f.contains(QueueFlags::COMPUTE_BIT))
        .collect();
    if let Some((i, _)) = without.iter().find(|(_, f)| *f == want) {
        return Some((*i, PoolMatch::Exact));
    }
    let extra = |f: &QueueFlags| f.without(want).0.count_ones();
    if let Some((i, _)) = without
        .iter()
        .filter(|(_, f)| f.contains(want.without(QueueFlags::COMPUTE_BIT)))
        .min_by_key(|(i, f)| (extra(f), *i))
    {
        return Some((*i, PoolMatch::Superset));
    }
    let shared = |f: &QueueFlags| QueueFlags(f.0 & want.0).0.count_ones();
    without
        .iter()
        .max_by_key(|(i, f)| (shared(f), std::cmp::Reverse(*i)))
        .map(|(i, _)| (*i, PoolMatch::Nearest))
}

/// What a device with `count` queue families, every one with compute, lacks for a command pool of a
/// family without compute.
pub(crate) fn lacks_family_without_compute(count: usize) -> HarnessError {
    HarnessError::lacks(
        crate::observe::DeviceLack::QueueFamilyWithout("VK_QUEUE_COMPUTE_BIT".into()),
        format!(
            "a pool of a queue family without VK_QUEUE_COMPUTE_BIT needs such a family; every one of the \
             device's {count} queue famil{} has compute",
            if count == 1 { "y" } else { "ies" }
        ),
    )
}

/// A logical device with exactly a case's extensions and features, and what the harness needs of it.
pub(crate) struct VkDevice {
    pub(crate) inst: Arc<VkInstance>,
    pub(crate) device: ash::Device,
    /// The queue of the compute family, which every submission of the harness goes to.
    pub(crate) queue: vk::Queue,
    pub(crate) queue_family: u32,
    /// The family without compute the device also has a queue of, for a case whose command pool's
    /// family lacks compute ([`pool_family`]); nothing is submitted to it.
    pub(crate) pool_family: Option<u32>,
    pub(crate) features: BTreeSet<String>,
    pub(crate) rt: Option<ash::khr::ray_tracing_pipeline::Device>,
    pub(crate) accel: Option<ash::khr::acceleration_structure::Device>,
    pub(crate) memory: vk::PhysicalDeviceMemoryProperties,
    pub(crate) limits: RtLimits,
    pub(crate) sparse_binding: bool,
    /// VK_NV_ray_tracing, when the case enables it.
    pub(crate) nv: Option<ash::nv::ray_tracing::Device>,
    /// VK_EXT_descriptor_buffer, when the case enables it with the `descriptorBuffer` feature.
    pub(crate) descriptor_buffer: Option<crate::vk::descriptors::DescriptorBufferDevice>,
    /// Set by the owner when the device was lost or a submission never finished: dropping then neither
    /// waits for nor destroys the device, and keeps its instance alive (a leak, never a hang).
    pub(crate) leak: bool,
    /// The layer's record of the modules it passed, where the layer keeps one for this device.
    pub(crate) validated: Option<ValidatedModules>,
}

impl VkDevice {
    /// Creates a device with exactly `extensions` and `features` enabled (and, where the layer offers
    /// it, the layer's own VK_EXT_validation_cache: see [`validated`]), with a queue of the first
    /// family with compute and, when `pool_without_compute` states a pool's family, a queue of the family
    /// [`pool_family`] picks for it (VUID-vkCreateCommandPool-queueFamilyIndex-01937: a pool's family is
    /// one the device was created with); or says what the driver lacks.
    pub(crate) fn new(
        inst: Arc<VkInstance>,
        extensions: &BTreeSet<String>,
        features: &BTreeSet<String>,
        pool_without_compute: Option<QueueFlags>,
    ) -> Result<VkDevice, HarnessError> {
        let _turn = super::turn::take();
        let available = inst.device_extensions();
        let missing: Vec<&String> = extensions
            .iter()
            .filter(|e| !available.contains(*e))
            .collect();
        if let Some(first) = missing.first() {
            let names: Vec<&str> = missing.iter().map(|s| s.as_str()).collect();
            return Err(HarnessError::lacks(
                crate::observe::DeviceLack::Extension(first.to_string()),
                format!("the device lacks extension(s): {}", names.join(", ")),
            ));
        }
        let supported = inst.device_features();
        let (core, mut chain) = feature_chain(&inst, extensions, features, supported)?;
        // SAFETY: plain query.
        let families = unsafe {
            inst.instance
                .get_physical_device_queue_family_properties(inst.physical)
        };
        let Some(family) = families
            .iter()
            .position(|f| f.queue_flags.contains(vk::QueueFlags::COMPUTE))
        else {
            return Err(HarnessError::lacks(
                crate::observe::DeviceLack::QueueFamilyWithAny(vec!["VK_QUEUE_COMPUTE_BIT".into()]),
                "no queue family with VK_QUEUE_COMPUTE_BIT",
            ));
        };
        let pool_family = match pool_without_compute {
            None => None,
            Some(want) => {
                let flags: Vec<vk::QueueFlags> = families.iter().map(|f| f.queue_flags).collect();
                match pool_family(&flags, want) {
                    Some((i, _)) => Some(i as u32),
                    None => return Err(lacks_family_without_compute(families.len())),
                }
            }
        };
        let priorities = [1.0f32];
        let queue_info: Vec<vk::DeviceQueueCreateInfo> = std::iter::once(family as u32)
            .chain(pool_family)
            .map(|f| {
                vk::DeviceQueueCreateInfo::default()
                    .queue_family_index(f)
                    .queue_priorities(&priorities)
            })
            .collect();
        // The layer's record of the modules it passed on devices of this configuration (see
        // `validated`), where the layer offers its extension: enabled beside the case's own.
        let record = inst
            .layer_build
            .filter(|_| inst.layer_extensions.contains(validated::EXTENSION))
            .and_then(|build| {
                validated::record_file(build, inst.api_version, extensions, features)
            });
        let ext_c: Vec<CString> = extensions
            .iter()
            .map(String::as_str)
            .chain(
                record
                    .as_ref()
                    .filter(|_| !extensions.contains(validated::EXTENSION))
                    .map(|_| validated::EXTENSION),
            )
            .filter_map(|e| CString::new(e).ok())
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
                HarnessError::Vulkan {
                    what: "vkCreateDevice".into(),
                    result: r,
                }
            })?;
        let validated =
            record.and_then(|file| ValidatedModules::open(&inst.instance, &device, file));
        // SAFETY: queue 0 of the family we created.
        let queue = unsafe { device.get_device_queue(family as u32, 0) };
        let rt = extensions
            .contains("VK_KHR_ray_tracing_pipeline")
            .then(|| ash::khr::ray_tracing_pipeline::Device::new(&inst.instance, &device));
        let nv = extensions
            .contains("VK_NV_ray_tracing")
            .then(|| ash::nv::ray_tracing::Device::new(&inst.instance, &device));
        let descriptor_buffer = (extensions.contains("VK_EXT_descriptor_buffer")
            && features
                .iter()
                .any(|f| f.rsplit("::").next() == Some("descriptorBuffer")))
        .then(|| {
            crate::vk::descriptors::DescriptorBufferDevice::new(
                &inst.instance,
                inst.physical,
                &device,
            )
        });
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
            pool_family,
            features: features.clone(),
            rt,
            accel,
            memory,
            limits,
            sparse_binding,
            nv,
            descriptor_buffer,
            validated,
            leak: false,
        })
    }

    /// Whether the device was created with feature `name` (member name or `Struct::member`).
    pub(crate) fn has_feature(&self, name: &str) -> bool {
        self.features
            .iter()
            .any(|f| f == name || f.rsplit("::").next() == Some(name))
    }

    /// `SHADER_DEVICE_ADDRESS` when the device has `bufferDeviceAddress` (so a buffer's address may be
    /// asked and written into descriptors), else no usage.
    pub(crate) fn address_usage(&self) -> vk::BufferUsageFlags {
        if self.has_feature("bufferDeviceAddress") {
            vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS
        } else {
            vk::BufferUsageFlags::empty()
        }
    }

    /// A memory type index allowed by `bits` with all of `flags`.
    pub(crate) fn memory_type(&self, bits: u32, flags: vk::MemoryPropertyFlags) -> Option<u32> {
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
        let _turn = super::turn::take();
        if self.leak {
            std::mem::forget(self.inst.clone());
            return;
        }
        if let Some(v) = &mut self.validated {
            v.save();
            v.destroy();
        }
        // SAFETY: every object made from the device is destroyed by its owner before this runs.
        unsafe {
            let _ = self.device.device_wait_idle();
            self.device.destroy_device(None);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const G: vk::QueueFlags = vk::QueueFlags::GRAPHICS;
    const C: vk::QueueFlags = vk::QueueFlags::COMPUTE;
    const T: vk::QueueFlags = vk::QueueFlags::TRANSFER;
    const S: vk::QueueFlags = vk::QueueFlags::SPARSE_BINDING;
    const V: vk::QueueFlags = vk::QueueFlags::VIDEO_DECODE_KHR;

    #[test]
    fn a_pool_family_matches_the_stated_flags_first() {
        // The H200's families as its profile lists them.
        let h200 = [G | C | T | S, T | S, C | T | S, T | S, T | S];
        let ts = QueueFlags::TRANSFER_BIT | QueueFlags::SPARSE_BINDING_BIT;
        assert_eq!(pool_family(&h200, ts), Some((1, PoolMatch::Exact)));
        // Bits no rule reads (optical flow) do not spoil a match.
        let flow = vk::QueueFlags::OPTICAL_FLOW_NV;
        assert_eq!(
            pool_family(&[G | C | T, T | S | flow], ts),
            Some((1, PoolMatch::Exact))
        );
        // Transfer only asked, none that exact: the family with the fewest other capabilities.
        let t = QueueFlags::TRANSFER_BIT;
        assert_eq!(
            pool_family(&[G | C | T, V | T | S, T | S], t),
            Some((2, PoolMatch::Superset))
        );
        // Sparse binding asked and no family without compute has it: the one sharing the most.
        assert_eq!(
            pool_family(&[G | C | T | S, V, T], ts),
            Some((2, PoolMatch::Nearest))
        );
    }

    #[test]
    fn no_pool_family_where_every_family_has_compute() {
        let lavapipe = [G | C | T];
        assert_eq!(pool_family(&lavapipe, QueueFlags::TRANSFER_BIT), None);
        let e = lacks_family_without_compute(lavapipe.len());
        let HarnessError::DeviceLacks { lack, reason } = e else {
            panic!("{e:?}")
        };
        assert_eq!(
            lack,
            crate::observe::DeviceLack::QueueFamilyWithout("VK_QUEUE_COMPUTE_BIT".into())
        );
        assert!(reason.contains("1 queue family has compute"), "{reason}");
    }
}
