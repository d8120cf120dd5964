//! `probe`: asks a real driver what it offers (API version, extensions, features, limits and properties,
//! format features, queue families) and fills a [`DeviceProfile`] keyed `Struct::member`.

use crate::error::HarnessError;
use crate::vk::layout::{self, EXTENSIBLE_HEADER};
use crate::vk::structs::{self, RawChain, PROPERTY_STRUCTS};
use crate::vk::{Driver, VkInstance};
use ash::vk;
use model::profile::{DeviceProfile, FormatFeatures, PropertyValue};
use std::collections::BTreeSet;

/// Formats whose features the probe records: vertex formats for acceleration structure builds,
/// common storage/colour formats, formats that need a sampler Y′CbCr conversion, and the 64-bit
/// integer formats of 64-bit image accesses (VK_EXT_shader_image_atomic_int64).
const FORMATS: &[(vk::Format, &str)] = &[
    (vk::Format::R32G32B32_SFLOAT, "VK_FORMAT_R32G32B32_SFLOAT"),
    (vk::Format::R32G32_SFLOAT, "VK_FORMAT_R32G32_SFLOAT"),
    (
        vk::Format::R16G16B16A16_SFLOAT,
        "VK_FORMAT_R16G16B16A16_SFLOAT",
    ),
    (vk::Format::R16G16_SFLOAT, "VK_FORMAT_R16G16_SFLOAT"),
    (vk::Format::R16G16_SNORM, "VK_FORMAT_R16G16_SNORM"),
    (
        vk::Format::R16G16B16A16_SNORM,
        "VK_FORMAT_R16G16B16A16_SNORM",
    ),
    (vk::Format::R8G8B8A8_UNORM, "VK_FORMAT_R8G8B8A8_UNORM"),
    (vk::Format::R32_UINT, "VK_FORMAT_R32_UINT"),
    (
        vk::Format::R32G32B32A32_SFLOAT,
        "VK_FORMAT_R32G32B32A32_SFLOAT",
    ),
    (vk::Format::R32G32B32A32_UINT, "VK_FORMAT_R32G32B32A32_UINT"),
    // Formats that need a sampler Y′CbCr conversion: single-plane 4:2:2 and two- and three-plane.
    (
        vk::Format::G8B8G8R8_422_UNORM,
        "VK_FORMAT_G8B8G8R8_422_UNORM",
    ),
    (
        vk::Format::B8G8R8G8_422_UNORM,
        "VK_FORMAT_B8G8R8G8_422_UNORM",
    ),
    (
        vk::Format::G8_B8R8_2PLANE_420_UNORM,
        "VK_FORMAT_G8_B8R8_2PLANE_420_UNORM",
    ),
    (
        vk::Format::G8_B8_R8_3PLANE_420_UNORM,
        "VK_FORMAT_G8_B8_R8_3PLANE_420_UNORM",
    ),
    (
        vk::Format::G8_B8R8_2PLANE_422_UNORM,
        "VK_FORMAT_G8_B8R8_2PLANE_422_UNORM",
    ),
    (
        vk::Format::G8_B8_R8_3PLANE_422_UNORM,
        "VK_FORMAT_G8_B8_R8_3PLANE_422_UNORM",
    ),
    (
        vk::Format::G8_B8_R8_3PLANE_444_UNORM,
        "VK_FORMAT_G8_B8_R8_3PLANE_444_UNORM",
    ),
    (vk::Format::R64_UINT, "VK_FORMAT_R64_UINT"),
    (vk::Format::R64_SINT, "VK_FORMAT_R64_SINT"),
];

const FORMAT_FEATURE_NAMES: &[(vk::FormatFeatureFlags, &str)] = &[
    (
        vk::FormatFeatureFlags::SAMPLED_IMAGE,
        "VK_FORMAT_FEATURE_SAMPLED_IMAGE_BIT",
    ),
    (
        vk::FormatFeatureFlags::STORAGE_IMAGE,
        "VK_FORMAT_FEATURE_STORAGE_IMAGE_BIT",
    ),
    (
        vk::FormatFeatureFlags::STORAGE_IMAGE_ATOMIC,
        "VK_FORMAT_FEATURE_STORAGE_IMAGE_ATOMIC_BIT",
    ),
    (
        vk::FormatFeatureFlags::UNIFORM_TEXEL_BUFFER,
        "VK_FORMAT_FEATURE_UNIFORM_TEXEL_BUFFER_BIT",
    ),
    (
        vk::FormatFeatureFlags::STORAGE_TEXEL_BUFFER,
        "VK_FORMAT_FEATURE_STORAGE_TEXEL_BUFFER_BIT",
    ),
    (
        vk::FormatFeatureFlags::STORAGE_TEXEL_BUFFER_ATOMIC,
        "VK_FORMAT_FEATURE_STORAGE_TEXEL_BUFFER_ATOMIC_BIT",
    ),
    (
        vk::FormatFeatureFlags::VERTEX_BUFFER,
        "VK_FORMAT_FEATURE_VERTEX_BUFFER_BIT",
    ),
    (
        vk::FormatFeatureFlags::COLOR_ATTACHMENT,
        "VK_FORMAT_FEATURE_COLOR_ATTACHMENT_BIT",
    ),
    (
        vk::FormatFeatureFlags::COLOR_ATTACHMENT_BLEND,
        "VK_FORMAT_FEATURE_COLOR_ATTACHMENT_BLEND_BIT",
    ),
    (
        vk::FormatFeatureFlags::DEPTH_STENCIL_ATTACHMENT,
        "VK_FORMAT_FEATURE_DEPTH_STENCIL_ATTACHMENT_BIT",
    ),
    (
        vk::FormatFeatureFlags::BLIT_SRC,
        "VK_FORMAT_FEATURE_BLIT_SRC_BIT",
    ),
    (
        vk::FormatFeatureFlags::BLIT_DST,
        "VK_FORMAT_FEATURE_BLIT_DST_BIT",
    ),
    (
        vk::FormatFeatureFlags::SAMPLED_IMAGE_FILTER_LINEAR,
        "VK_FORMAT_FEATURE_SAMPLED_IMAGE_FILTER_LINEAR_BIT",
    ),
    (
        vk::FormatFeatureFlags::SAMPLED_IMAGE_FILTER_MINMAX,
        "VK_FORMAT_FEATURE_SAMPLED_IMAGE_FILTER_MINMAX_BIT",
    ),
    (
        vk::FormatFeatureFlags::SAMPLED_IMAGE_FILTER_CUBIC_EXT,
        "VK_FORMAT_FEATURE_SAMPLED_IMAGE_FILTER_CUBIC_BIT_EXT",
    ),
    (
        vk::FormatFeatureFlags::TRANSFER_SRC,
        "VK_FORMAT_FEATURE_TRANSFER_SRC_BIT",
    ),
    (
        vk::FormatFeatureFlags::TRANSFER_DST,
        "VK_FORMAT_FEATURE_TRANSFER_DST_BIT",
    ),
    (
        vk::FormatFeatureFlags::ACCELERATION_STRUCTURE_VERTEX_BUFFER_KHR,
        "VK_FORMAT_FEATURE_ACCELERATION_STRUCTURE_VERTEX_BUFFER_BIT_KHR",
    ),
    // What a sampler Y′CbCr conversion of the format may be created with.
    (
        vk::FormatFeatureFlags::MIDPOINT_CHROMA_SAMPLES,
        "VK_FORMAT_FEATURE_MIDPOINT_CHROMA_SAMPLES_BIT",
    ),
    (
        vk::FormatFeatureFlags::COSITED_CHROMA_SAMPLES,
        "VK_FORMAT_FEATURE_COSITED_CHROMA_SAMPLES_BIT",
    ),
    (
        vk::FormatFeatureFlags::SAMPLED_IMAGE_YCBCR_CONVERSION_LINEAR_FILTER,
        "VK_FORMAT_FEATURE_SAMPLED_IMAGE_YCBCR_CONVERSION_LINEAR_FILTER_BIT",
    ),
    (
        vk::FormatFeatureFlags::SAMPLED_IMAGE_YCBCR_CONVERSION_SEPARATE_RECONSTRUCTION_FILTER,
        "VK_FORMAT_FEATURE_SAMPLED_IMAGE_YCBCR_CONVERSION_SEPARATE_RECONSTRUCTION_FILTER_BIT",
    ),
    (
        vk::FormatFeatureFlags::SAMPLED_IMAGE_YCBCR_CONVERSION_CHROMA_RECONSTRUCTION_EXPLICIT,
        "VK_FORMAT_FEATURE_SAMPLED_IMAGE_YCBCR_CONVERSION_CHROMA_RECONSTRUCTION_EXPLICIT_BIT",
    ),
    (
        vk::FormatFeatureFlags::SAMPLED_IMAGE_YCBCR_CONVERSION_CHROMA_RECONSTRUCTION_EXPLICIT_FORCEABLE,
        "VK_FORMAT_FEATURE_SAMPLED_IMAGE_YCBCR_CONVERSION_CHROMA_RECONSTRUCTION_EXPLICIT_FORCEABLE_BIT",
    ),
    (vk::FormatFeatureFlags::DISJOINT, "VK_FORMAT_FEATURE_DISJOINT_BIT"),
];

const QUEUE_FLAG_NAMES: &[(vk::QueueFlags, &str)] = &[
    (vk::QueueFlags::GRAPHICS, "VK_QUEUE_GRAPHICS_BIT"),
    (vk::QueueFlags::COMPUTE, "VK_QUEUE_COMPUTE_BIT"),
    (vk::QueueFlags::TRANSFER, "VK_QUEUE_TRANSFER_BIT"),
    (
        vk::QueueFlags::SPARSE_BINDING,
        "VK_QUEUE_SPARSE_BINDING_BIT",
    ),
    (vk::QueueFlags::PROTECTED, "VK_QUEUE_PROTECTED_BIT"),
];

fn version_text(v: u32) -> String {
    format!(
        "{}.{}.{}",
        vk::api_version_major(v),
        vk::api_version_minor(v),
        vk::api_version_patch(v)
    )
}

fn format_names(f: vk::FormatFeatureFlags) -> BTreeSet<String> {
    FORMAT_FEATURE_NAMES
        .iter()
        .filter(|(b, _)| f.contains(*b))
        .map(|(_, n)| n.to_string())
        .collect()
}

/// Queries `driver`'s first device and describes it as a profile named after the driver.
pub fn probe(driver: Driver) -> Result<DeviceProfile, HarnessError> {
    let _turn = crate::vk::turn::take();
    let name = driver.name();
    let inst = VkInstance::new(driver, false)?;
    let mut p = DeviceProfile {
        name,
        ..Default::default()
    };
    p.extensions = inst.device_extensions().clone();
    p.features = inst.device_features().clone();

    // SAFETY: plain query.
    let base = unsafe { inst.instance.get_physical_device_properties(inst.physical) };
    p.api_version = version_text(base.api_version);
    let device_name = base
        .device_name_as_c_str()
        .map(|c| c.to_string_lossy().into_owned())
        .unwrap_or_default();
    let props = &mut p.properties;
    let put = |props: &mut std::collections::BTreeMap<String, PropertyValue>,
               k: &str,
               v: PropertyValue| {
        props.insert(format!("VkPhysicalDeviceProperties::{k}"), v);
    };
    put(
        props,
        "apiVersion",
        PropertyValue::Text(version_text(base.api_version)),
    );
    put(
        props,
        "driverVersion",
        PropertyValue::Int(base.driver_version as u64),
    );
    put(props, "vendorID", PropertyValue::Int(base.vendor_id as u64));
    put(props, "deviceID", PropertyValue::Int(base.device_id as u64));
    put(
        props,
        "deviceType",
        PropertyValue::Text(format!("{:?}", base.device_type)),
    );
    put(
        props,
        "deviceName",
        PropertyValue::Text(device_name.clone()),
    );
    put(
        props,
        "pipelineCacheUUID",
        PropertyValue::Array(
            base.pipeline_cache_uuid
                .iter()
                .map(|b| PropertyValue::Int(*b as u64))
                .collect(),
        ),
    );
    for (n, v) in layout::read_members(
        crate::vk::tables::PHYSICAL_DEVICE_LIMITS,
        0,
        structs::as_bytes(&base.limits),
    ) {
        props.insert(format!("VkPhysicalDeviceLimits::{n}"), v);
    }
    for (n, v) in layout::read_members(
        crate::vk::tables::PHYSICAL_DEVICE_SPARSE_PROPERTIES,
        0,
        structs::as_bytes(&base.sparse_properties),
    ) {
        props.insert(format!("VkPhysicalDeviceSparseProperties::{n}"), v);
    }

    let mut chain = RawChain::new();
    for s in PROPERTY_STRUCTS {
        if s.usable(inst.api_version, |e| p.extensions.contains(e)) {
            chain.push(s);
        }
    }
    let head = chain.link();
    let mut p2 = vk::PhysicalDeviceProperties2 {
        p_next: head,
        ..Default::default()
    };
    // SAFETY: the chain has correct sTypes and sizes and outlives the call.
    unsafe {
        inst.instance
            .get_physical_device_properties2(inst.physical, &mut p2)
    };
    let mut driver_info = String::new();
    for (info, bytes) in chain.parts() {
        for (n, v) in layout::read_members(info.members, EXTENSIBLE_HEADER, bytes) {
            if info.name == "VkPhysicalDeviceVulkan12Properties"
                && (n == "driverName" || n == "driverInfo")
            {
                if let PropertyValue::Text(t) = &v {
                    driver_info = format!("{driver_info} {t}").trim().to_string();
                }
            }
            props.insert(format!("{}::{n}", info.name), v);
        }
    }
    p.description = format!("{device_name} ({driver_info}), captured by rtconf probe");

    for (f, fname) in FORMATS {
        // SAFETY: plain query.
        let fp = unsafe {
            inst.instance
                .get_physical_device_format_properties(inst.physical, *f)
        };
        p.formats.insert(
            fname.to_string(),
            FormatFeatures {
                linear_tiling: format_names(fp.linear_tiling_features),
                optimal_tiling: format_names(fp.optimal_tiling_features),
                buffer: format_names(fp.buffer_features),
            },
        );
    }
    // SAFETY: plain query.
    let families = unsafe {
        inst.instance
            .get_physical_device_queue_family_properties(inst.physical)
    };
    p.queue_families = families
        .iter()
        .map(|f| {
            QUEUE_FLAG_NAMES
                .iter()
                .filter(|(b, _)| f.queue_flags.contains(*b))
                .map(|(_, n)| n.to_string())
                .collect()
        })
        .collect();
    Ok(p)
}
