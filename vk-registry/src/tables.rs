//! Generated structure tables: the member lists (name, C type, array length) of the feature and property
//! structures the rtconf harness reads by C layout, written as the Rust source of
//! `harness/src/vk/tables.rs`. Regenerate with
//! `cargo run -p vk-registry --bin vk-tables -- /usr/share/vulkan/registry/vk.xml harness/src/vk/tables.rs`;
//! the harness's drift test fails with that command when the committed file differs.

use crate::xml::{Registry, TypeCategory};

/// The command that regenerates the harness's tables from the installed registry (run from the
/// workspace root).
pub const REGENERATE: &str =
    "cargo run -p vk-registry --bin vk-tables -- /usr/share/vulkan/registry/vk.xml harness/src/vk/tables.rs";

/// The structures the harness chains when it probes a device or creates one, in output order.
pub const HARNESS_STRUCTURES: &[&str] = &[
    "VkPhysicalDeviceFeatures",
    "VkPhysicalDeviceVulkan11Features",
    "VkPhysicalDeviceVulkan12Features",
    "VkPhysicalDeviceVulkan13Features",
    "VkPhysicalDeviceRayTracingPipelineFeaturesKHR",
    "VkPhysicalDeviceAccelerationStructureFeaturesKHR",
    "VkPhysicalDeviceRayQueryFeaturesKHR",
    "VkPhysicalDeviceRayTracingMaintenance1FeaturesKHR",
    "VkPhysicalDeviceRayTracingMotionBlurFeaturesNV",
    "VkPhysicalDeviceBufferDeviceAddressFeatures",
    "VkPhysicalDeviceDescriptorBufferFeaturesEXT",
    "VkPhysicalDeviceShaderImageAtomicInt64FeaturesEXT",
    "VkPhysicalDeviceLimits",
    "VkPhysicalDeviceSparseProperties",
    "VkPhysicalDeviceVulkan11Properties",
    "VkPhysicalDeviceVulkan12Properties",
    "VkPhysicalDeviceVulkan13Properties",
    "VkPhysicalDeviceRayTracingPipelinePropertiesKHR",
    "VkPhysicalDeviceAccelerationStructurePropertiesKHR",
    "VkPhysicalDeviceRayTracingPropertiesNV",
];

/// What the generator cannot turn into a table: it fails loudly rather than guess a layout.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum TableError {
    #[error("the registry has no structure `{0}`")]
    NoStructure(String),
    #[error("{structure}.{member}: the harness has no layout for type `{ty}`")]
    UnknownType {
        structure: String,
        member: String,
        ty: String,
    },
    #[error("{structure}.{member}: array length `{len}` is neither a number nor an API constant")]
    UnknownLength {
        structure: String,
        member: String,
        len: String,
    },
}

/// The harness's `MemberKind` of a C type: the layout it is read with.
fn kind(registry: &Registry, ty: &str) -> Option<&'static str> {
    Some(match ty {
        "uint32_t" => "U32",
        "int32_t" => "I32",
        "float" => "F32",
        "VkBool32" => "Bool",
        "uint64_t" | "VkDeviceSize" | "size_t" => "U64",
        "uint8_t" => "U8",
        "char" => "Char",
        "VkConformanceVersion" => "Conformance",
        other => match registry.type_def(other)?.category {
            TypeCategory::Enum => "I32",
            TypeCategory::Bitmask => "Flags",
            _ => return None,
        },
    })
}

/// `VkPhysicalDeviceLimits` → `PHYSICAL_DEVICE_LIMITS`.
fn const_name(structure: &str) -> String {
    let s = structure.strip_prefix("Vk").unwrap_or(structure);
    let mut out = String::new();
    let mut prev: Option<char> = None;
    for c in s.chars() {
        if c.is_ascii_uppercase()
            && prev.is_some_and(|p| p.is_ascii_lowercase() || p.is_ascii_digit())
        {
            out.push('_');
        }
        out.push(c.to_ascii_uppercase());
        prev = Some(c);
    }
    out
}

/// The Rust source of the tables of `structures`.
pub fn generate(registry: &Registry, structures: &[&str]) -> Result<String, TableError> {
    let mut out = vec![
        "//! Member lists of the feature and property structures the probe and device creation read, by C layout.".to_string(),
        format!("//! GENERATED from vk.xml by `{REGENERATE}`; do not edit."),
        String::new(),
        "use crate::vk::layout::{Member, MemberKind::*};".to_string(),
        String::new(),
    ];
    for &s in structures {
        let t = registry
            .structure(s)
            .ok_or_else(|| TableError::NoStructure(s.into()))?;
        out.push(format!("/// `{s}`."));
        out.push(format!("pub const {}: &[Member] = &[", const_name(s)));
        for m in &t.members {
            if m.name == "sType" || m.name == "pNext" {
                continue;
            }
            let count = match m.array.first() {
                None => 1,
                Some(len) => len
                    .parse::<i64>()
                    .ok()
                    .or_else(|| registry.enum_value(len))
                    .ok_or_else(|| TableError::UnknownLength {
                        structure: s.into(),
                        member: m.name.clone(),
                        len: len.clone(),
                    })?,
            };
            let k = kind(registry, &m.type_name).ok_or_else(|| TableError::UnknownType {
                structure: s.into(),
                member: m.name.clone(),
                ty: m.type_name.clone(),
            })?;
            out.push(format!(
                "    Member {{ name: \"{}\", kind: {k}, count: {count} }},",
                m.name
            ));
        }
        out.push("];".into());
        out.push(String::new());
    }
    Ok(out.join("\n"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn constant_names_follow_the_structure_names() {
        assert_eq!(
            const_name("VkPhysicalDeviceLimits"),
            "PHYSICAL_DEVICE_LIMITS"
        );
        assert_eq!(
            const_name("VkPhysicalDeviceVulkan11Features"),
            "PHYSICAL_DEVICE_VULKAN11_FEATURES"
        );
        assert_eq!(
            const_name("VkPhysicalDeviceRayTracingPropertiesNV"),
            "PHYSICAL_DEVICE_RAY_TRACING_PROPERTIES_NV"
        );
    }

    #[test]
    fn a_registry_without_the_structures_is_an_error_not_a_table() {
        let r = Registry::parse("<registry><types></types></registry>").unwrap();
        assert_eq!(
            generate(&r, &["VkPhysicalDeviceLimits"]),
            Err(TableError::NoStructure("VkPhysicalDeviceLimits".into()))
        );
    }
}
