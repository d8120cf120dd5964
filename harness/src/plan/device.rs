//! The device of a plan: the extensions a case enables and its features resolved to the structures
//! that hold them (`VkPhysicalDeviceFeatures` or a structure chained behind it), as the harness's
//! device creation chains them on a Vulkan 1.3 device, and the queue families it gets a queue of.

use crate::vk::structs::FEATURE_STRUCTS;
use crate::vk::tables as vk_tables;
use ash::vk;
use std::collections::BTreeSet;

/// A feature structure chained into `VkDeviceCreateInfo`, with the members the case enables.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
pub struct FeatureStruct {
    /// `VkPhysicalDeviceVulkan12Features`.
    pub name: String,
    /// `VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_2_FEATURES`.
    pub s_type_name: String,
    pub s_type: i32,
    /// The Vulkan version that makes it core, as `VK_API_VERSION_1_2` would (None: an extension's).
    pub core_version: Option<u32>,
    pub members: Vec<String>,
}

/// The device a case's plan creates.
#[derive(Debug, Clone, PartialEq, Eq, Default, serde::Serialize)]
pub struct DevicePlan {
    pub extensions: Vec<String>,
    /// The features as the case names them.
    pub features: Vec<String>,
    /// Members of `VkPhysicalDeviceFeatures` to enable.
    pub core: Vec<String>,
    /// The structures to chain, in order.
    pub chain: Vec<FeatureStruct>,
    /// Features no known structure holds (the device creation reports them unsupported).
    pub unknown: Vec<String>,
    /// Besides the first family with compute, a queue of a family without compute whose capabilities
    /// are these (or the nearest, as the harness's device creation picks it), for a command pool of
    /// such a family.
    pub pool_family: Option<model::flags::QueueFlags>,
}

/// The version every plan's device is assumed to have: the harness asks for Vulkan 1.3.
const API_VERSION: u32 = vk::API_VERSION_1_3;

/// The C name of a structure type (`VK_STRUCTURE_TYPE_…`), from ash's name of the value.
fn s_type_name(s: vk::StructureType) -> String {
    let debug = format!("{s:?}");
    if debug
        .chars()
        .all(|c| c.is_ascii_uppercase() || c.is_ascii_digit() || c == '_')
    {
        format!("VK_STRUCTURE_TYPE_{debug}")
    } else {
        format!("(VkStructureType){}", s.as_raw())
    }
}

impl DevicePlan {
    /// Resolves each feature (a member name, or `Struct::member`) as the harness's device creation does:
    /// `VkPhysicalDeviceFeatures` first, then the first structure holding the member that a Vulkan 1.3
    /// device with the case's extensions may use.
    pub fn of(extensions: &BTreeSet<String>, features: &BTreeSet<String>) -> DevicePlan {
        let mut plan = DevicePlan {
            extensions: extensions.iter().cloned().collect(),
            features: features.iter().cloned().collect(),
            ..Default::default()
        };
        for name in features {
            let (want, member) = match name.split_once("::") {
                Some((s, m)) => (Some(s), m),
                None => (None, name.as_str()),
            };
            let in_core = vk_tables::PHYSICAL_DEVICE_FEATURES
                .iter()
                .any(|m| m.name == member);
            if in_core && want.is_none_or(|s| s == "VkPhysicalDeviceFeatures") {
                plan.core.push(member.to_string());
                continue;
            }
            let found = FEATURE_STRUCTS.iter().find(|s| {
                want.is_none_or(|w| w == s.name)
                    && s.members.iter().any(|m| m.name == member)
                    && s.usable(API_VERSION, |e| extensions.contains(e))
            });
            let Some(s) = found else {
                plan.unknown.push(name.clone());
                continue;
            };
            match plan.chain.iter_mut().find(|c| c.name == s.name) {
                Some(c) => c.members.push(member.to_string()),
                None => plan.chain.push(FeatureStruct {
                    name: s.name.to_string(),
                    s_type_name: s_type_name(s.s_type),
                    s_type: s.s_type.as_raw(),
                    core_version: s.core,
                    members: vec![member.to_string()],
                }),
            }
        }
        plan
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn features_resolve_to_the_structures_device_creation_chains() {
        let ext: BTreeSet<String> = [
            "VK_KHR_acceleration_structure",
            "VK_KHR_ray_tracing_pipeline",
            "VK_KHR_deferred_host_operations",
        ]
        .map(String::from)
        .into();
        let feat: BTreeSet<String> = [
            "accelerationStructure",
            "bufferDeviceAddress",
            "rayTracingPipeline",
            "shaderInt64",
            "noSuchFeature",
        ]
        .map(String::from)
        .into();
        let p = DevicePlan::of(&ext, &feat);
        assert_eq!(p.core, vec!["shaderInt64"]);
        assert_eq!(p.unknown, vec!["noSuchFeature"]);
        let names: Vec<(&str, &str, Vec<String>)> = p
            .chain
            .iter()
            .map(|c| (c.name.as_str(), c.s_type_name.as_str(), c.members.clone()))
            .collect();
        assert_eq!(
            names,
            vec![
                (
                    "VkPhysicalDeviceAccelerationStructureFeaturesKHR",
                    "VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_ACCELERATION_STRUCTURE_FEATURES_KHR",
                    vec!["accelerationStructure".to_string()]
                ),
                (
                    "VkPhysicalDeviceVulkan12Features",
                    "VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_2_FEATURES",
                    vec!["bufferDeviceAddress".to_string()]
                ),
                (
                    "VkPhysicalDeviceRayTracingPipelineFeaturesKHR",
                    "VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_RAY_TRACING_PIPELINE_FEATURES_KHR",
                    vec!["rayTracingPipeline".to_string()]
                ),
            ]
        );
    }
}
