//! The catalogue of feature and property structures the harness chains (`pNext`) into queries and device
//! creation, and an owned chain of raw structures built from it.

use crate::vk::layout::{self, Member, EXTENSIBLE_HEADER};
use crate::vk::tables as t;
use ash::vk;

/// One extensible structure: its type name, members, `sType`, and when a device may use it.
#[derive(Debug, Clone, Copy)]
pub(crate) struct StructInfo {
    pub(crate) name: &'static str,
    pub(crate) members: &'static [Member],
    pub(crate) s_type: vk::StructureType,
    /// Usable when the device's API version is at least this (core), …
    pub(crate) core: Option<u32>,
    /// … or when the device exposes (and, for device creation, the case enables) this extension.
    pub(crate) extension: Option<&'static str>,
}

impl StructInfo {
    /// Whether a device of `api_version` with `has_ext` may use this structure.
    pub(crate) fn usable(&self, api_version: u32, has_ext: impl Fn(&str) -> bool) -> bool {
        self.core.is_some_and(|v| api_version >= v) || self.extension.is_some_and(has_ext)
    }
}

const V1_2: u32 = vk::API_VERSION_1_2;
const V1_3: u32 = vk::API_VERSION_1_3;

/// Feature structures chained behind `VkPhysicalDeviceFeatures2`, in lookup order (core first).
pub(crate) const FEATURE_STRUCTS: &[StructInfo] = &[
    StructInfo {
        name: "VkPhysicalDeviceVulkan11Features",
        members: t::PHYSICAL_DEVICE_VULKAN11_FEATURES,
        s_type: vk::StructureType::PHYSICAL_DEVICE_VULKAN_1_1_FEATURES,
        core: Some(V1_2),
        extension: None,
    },
    StructInfo {
        name: "VkPhysicalDeviceVulkan12Features",
        members: t::PHYSICAL_DEVICE_VULKAN12_FEATURES,
        s_type: vk::StructureType::PHYSICAL_DEVICE_VULKAN_1_2_FEATURES,
        core: Some(V1_2),
        extension: None,
    },
    StructInfo {
        name: "VkPhysicalDeviceVulkan13Features",
        members: t::PHYSICAL_DEVICE_VULKAN13_FEATURES,
        s_type: vk::StructureType::PHYSICAL_DEVICE_VULKAN_1_3_FEATURES,
        core: Some(V1_3),
        extension: None,
    },
    StructInfo {
        name: "VkPhysicalDeviceRayTracingPipelineFeaturesKHR",
        members: t::PHYSICAL_DEVICE_RAY_TRACING_PIPELINE_FEATURES_KHR,
        s_type: vk::StructureType::PHYSICAL_DEVICE_RAY_TRACING_PIPELINE_FEATURES_KHR,
        core: None,
        extension: Some("VK_KHR_ray_tracing_pipeline"),
    },
    StructInfo {
        name: "VkPhysicalDeviceAccelerationStructureFeaturesKHR",
        members: t::PHYSICAL_DEVICE_ACCELERATION_STRUCTURE_FEATURES_KHR,
        s_type: vk::StructureType::PHYSICAL_DEVICE_ACCELERATION_STRUCTURE_FEATURES_KHR,
        core: None,
        extension: Some("VK_KHR_acceleration_structure"),
    },
    StructInfo {
        name: "VkPhysicalDeviceRayQueryFeaturesKHR",
        members: t::PHYSICAL_DEVICE_RAY_QUERY_FEATURES_KHR,
        s_type: vk::StructureType::PHYSICAL_DEVICE_RAY_QUERY_FEATURES_KHR,
        core: None,
        extension: Some("VK_KHR_ray_query"),
    },
    StructInfo {
        name: "VkPhysicalDeviceRayTracingMaintenance1FeaturesKHR",
        members: t::PHYSICAL_DEVICE_RAY_TRACING_MAINTENANCE1_FEATURES_KHR,
        s_type: vk::StructureType::PHYSICAL_DEVICE_RAY_TRACING_MAINTENANCE_1_FEATURES_KHR,
        core: None,
        extension: Some("VK_KHR_ray_tracing_maintenance1"),
    },
    StructInfo {
        name: "VkPhysicalDeviceRayTracingMotionBlurFeaturesNV",
        members: t::PHYSICAL_DEVICE_RAY_TRACING_MOTION_BLUR_FEATURES_NV,
        s_type: vk::StructureType::PHYSICAL_DEVICE_RAY_TRACING_MOTION_BLUR_FEATURES_NV,
        core: None,
        extension: Some("VK_NV_ray_tracing_motion_blur"),
    },
    StructInfo {
        name: "VkPhysicalDeviceDescriptorBufferFeaturesEXT",
        members: t::PHYSICAL_DEVICE_DESCRIPTOR_BUFFER_FEATURES_EXT,
        s_type: vk::StructureType::PHYSICAL_DEVICE_DESCRIPTOR_BUFFER_FEATURES_EXT,
        core: None,
        extension: Some("VK_EXT_descriptor_buffer"),
    },
    StructInfo {
        name: "VkPhysicalDeviceShaderImageAtomicInt64FeaturesEXT",
        members: t::PHYSICAL_DEVICE_SHADER_IMAGE_ATOMIC_INT64_FEATURES_EXT,
        s_type: vk::StructureType::PHYSICAL_DEVICE_SHADER_IMAGE_ATOMIC_INT64_FEATURES_EXT,
        core: None,
        extension: Some("VK_EXT_shader_image_atomic_int64"),
    },
];

/// Property structures chained behind `VkPhysicalDeviceProperties2`.
pub(crate) const PROPERTY_STRUCTS: &[StructInfo] = &[
    StructInfo {
        name: "VkPhysicalDeviceVulkan11Properties",
        members: t::PHYSICAL_DEVICE_VULKAN11_PROPERTIES,
        s_type: vk::StructureType::PHYSICAL_DEVICE_VULKAN_1_1_PROPERTIES,
        core: Some(V1_2),
        extension: None,
    },
    StructInfo {
        name: "VkPhysicalDeviceVulkan12Properties",
        members: t::PHYSICAL_DEVICE_VULKAN12_PROPERTIES,
        s_type: vk::StructureType::PHYSICAL_DEVICE_VULKAN_1_2_PROPERTIES,
        core: Some(V1_2),
        extension: None,
    },
    StructInfo {
        name: "VkPhysicalDeviceVulkan13Properties",
        members: t::PHYSICAL_DEVICE_VULKAN13_PROPERTIES,
        s_type: vk::StructureType::PHYSICAL_DEVICE_VULKAN_1_3_PROPERTIES,
        core: Some(V1_3),
        extension: None,
    },
    StructInfo {
        name: "VkPhysicalDeviceRayTracingPipelinePropertiesKHR",
        members: t::PHYSICAL_DEVICE_RAY_TRACING_PIPELINE_PROPERTIES_KHR,
        s_type: vk::StructureType::PHYSICAL_DEVICE_RAY_TRACING_PIPELINE_PROPERTIES_KHR,
        core: None,
        extension: Some("VK_KHR_ray_tracing_pipeline"),
    },
    StructInfo {
        name: "VkPhysicalDeviceAccelerationStructurePropertiesKHR",
        members: t::PHYSICAL_DEVICE_ACCELERATION_STRUCTURE_PROPERTIES_KHR,
        s_type: vk::StructureType::PHYSICAL_DEVICE_ACCELERATION_STRUCTURE_PROPERTIES_KHR,
        core: None,
        extension: Some("VK_KHR_acceleration_structure"),
    },
    StructInfo {
        name: "VkPhysicalDeviceRayTracingPropertiesNV",
        members: t::PHYSICAL_DEVICE_RAY_TRACING_PROPERTIES_NV,
        s_type: vk::StructureType::PHYSICAL_DEVICE_RAY_TRACING_PROPERTIES_NV,
        core: None,
        extension: Some("VK_NV_ray_tracing"),
    },
];

/// An owned `pNext` chain of raw extensible structures (8-byte aligned storage).
pub(crate) struct RawChain {
    parts: Vec<(&'static StructInfo, Vec<u64>)>,
}

impl RawChain {
    pub(crate) fn new() -> RawChain {
        RawChain { parts: Vec::new() }
    }

    /// Appends a zeroed structure (with its `sType`) and returns its index.
    pub(crate) fn push(&mut self, info: &'static StructInfo) -> usize {
        let (_, size) = layout::offsets(info.members, EXTENSIBLE_HEADER);
        let mut words = vec![0u64; size.div_ceil(8)];
        words[0] = info.s_type.as_raw() as u32 as u64;
        self.parts.push((info, words));
        self.parts.len() - 1
    }

    pub(crate) fn position(&self, name: &str) -> Option<usize> {
        self.parts.iter().position(|(i, _)| i.name == name)
    }

    pub(crate) fn bytes(&self, i: usize) -> &[u8] {
        let w = &self.parts[i].1;
        // SAFETY: a u64 slice viewed as bytes of the same length.
        unsafe { std::slice::from_raw_parts(w.as_ptr() as *const u8, w.len() * 8) }
    }

    pub(crate) fn bytes_mut(&mut self, i: usize) -> &mut [u8] {
        let w = &mut self.parts[i].1;
        // SAFETY: as above, exclusive borrow.
        unsafe { std::slice::from_raw_parts_mut(w.as_mut_ptr() as *mut u8, w.len() * 8) }
    }

    pub(crate) fn parts(&self) -> impl Iterator<Item = (&'static StructInfo, &[u8])> {
        (0..self.parts.len()).map(|i| (self.parts[i].0, self.bytes(i)))
    }

    /// Links every structure's `pNext` to the next one and returns the head (null when empty). The
    /// pointers stay valid while `self` is neither moved-from nor modified.
    pub(crate) fn link(&mut self) -> *mut std::ffi::c_void {
        let n = self.parts.len();
        for i in 0..n {
            let next = if i + 1 < n {
                self.parts[i + 1].1.as_mut_ptr() as u64
            } else {
                0
            };
            self.parts[i].1[1] = next;
        }
        self.parts.first_mut().map_or(std::ptr::null_mut(), |p| {
            p.1.as_mut_ptr() as *mut std::ffi::c_void
        })
    }
}

impl Default for RawChain {
    fn default() -> Self {
        RawChain::new()
    }
}

/// Views a plain Vulkan structure as its bytes.
pub(crate) fn as_bytes<T>(v: &T) -> &[u8] {
    // SAFETY: any initialised value may be viewed as bytes; Vulkan structures have no padding reads that matter.
    unsafe { std::slice::from_raw_parts(v as *const T as *const u8, std::mem::size_of::<T>()) }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::vk::layout::offsets;
    use std::mem::size_of;

    #[test]
    fn computed_layouts_match_ash() {
        let checks: &[(&[Member], usize, usize)] = &[
            (
                t::PHYSICAL_DEVICE_FEATURES,
                0,
                size_of::<vk::PhysicalDeviceFeatures>(),
            ),
            (
                t::PHYSICAL_DEVICE_LIMITS,
                0,
                size_of::<vk::PhysicalDeviceLimits>(),
            ),
            (
                t::PHYSICAL_DEVICE_SPARSE_PROPERTIES,
                0,
                size_of::<vk::PhysicalDeviceSparseProperties>(),
            ),
            (
                t::PHYSICAL_DEVICE_VULKAN11_FEATURES,
                16,
                size_of::<vk::PhysicalDeviceVulkan11Features>(),
            ),
            (
                t::PHYSICAL_DEVICE_VULKAN12_FEATURES,
                16,
                size_of::<vk::PhysicalDeviceVulkan12Features>(),
            ),
            (
                t::PHYSICAL_DEVICE_VULKAN13_FEATURES,
                16,
                size_of::<vk::PhysicalDeviceVulkan13Features>(),
            ),
            (
                t::PHYSICAL_DEVICE_VULKAN11_PROPERTIES,
                16,
                size_of::<vk::PhysicalDeviceVulkan11Properties>(),
            ),
            (
                t::PHYSICAL_DEVICE_VULKAN12_PROPERTIES,
                16,
                size_of::<vk::PhysicalDeviceVulkan12Properties>(),
            ),
            (
                t::PHYSICAL_DEVICE_VULKAN13_PROPERTIES,
                16,
                size_of::<vk::PhysicalDeviceVulkan13Properties>(),
            ),
            (
                t::PHYSICAL_DEVICE_RAY_TRACING_PIPELINE_PROPERTIES_KHR,
                16,
                size_of::<vk::PhysicalDeviceRayTracingPipelinePropertiesKHR>(),
            ),
            (
                t::PHYSICAL_DEVICE_ACCELERATION_STRUCTURE_PROPERTIES_KHR,
                16,
                size_of::<vk::PhysicalDeviceAccelerationStructurePropertiesKHR>(),
            ),
            (
                t::PHYSICAL_DEVICE_RAY_TRACING_PROPERTIES_NV,
                16,
                size_of::<vk::PhysicalDeviceRayTracingPropertiesNV>(),
            ),
        ];
        for (i, (members, header, ash_size)) in checks.iter().enumerate() {
            assert_eq!(offsets(members, *header).1, *ash_size, "structure #{i}");
        }
        let rt = offsets(t::PHYSICAL_DEVICE_RAY_TRACING_PIPELINE_FEATURES_KHR, 16).1;
        assert_eq!(
            rt,
            size_of::<vk::PhysicalDeviceRayTracingPipelineFeaturesKHR>()
        );
    }
}
