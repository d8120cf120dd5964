//! What the Vulkan specification requires of the device limits rtconf reads: each member's C type
//! (from its structure's definition) and its required bound (the specification's "Limit
//! Requirements" section, `chapters/limits.adoc`), and the members it says must be powers of two.
//!
//! Two uses. A value its C type cannot hold, a handle size or alignment of zero, or an alignment
//! that is not the power of two the specification requires makes a profile unusable: no case laid
//! out with it means anything, so [`unusable`] names it and the profile reader refuses the file.
//! A value outside the required bound (lavapipe's `maxRayDispatchInvocationCount` of 2^26 against
//! the required 2^30) is a conformance finding about the device, not a reason to stop:
//! [`findings`] lists them, the cases keep to the value the device reports, and `rtconf probe`,
//! `gen` and `run` print them.

use crate::profile::{DeviceProfile, PropertyValue};
use serde_json::Value;

/// The C type of a member, as its structure declares it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CType {
    U32,
    U64,
    /// `uint32_t member[3]`.
    U32x3,
}

impl CType {
    fn name(self) -> &'static str {
        match self {
            CType::U32 => "a uint32_t",
            CType::U64 => "a uint64_t",
            CType::U32x3 => "an array of three uint32_t",
        }
    }

    fn max(self) -> u64 {
        match self {
            CType::U32 | CType::U32x3 => u64::from(u32::MAX),
            CType::U64 => u64::MAX,
        }
    }
}

/// The bound the specification's required-limits table states for a member.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Required {
    /// Limit type `min`: at least this.
    AtLeast(u64),
    /// Limit type `max`: at most this.
    AtMost(u64),
    /// Limit type `exact`.
    Exactly(u64),
    /// A `min` row and the text's own upper bound (counts given at creation as 32-bit values).
    Between(u64, u64),
    /// Limit type `min`, per element of a three-element array.
    EachAtLeast([u64; 3]),
}

impl Required {
    /// Whether `v` (element `i` of an array) meets the bound.
    fn holds(self, i: usize, v: u64) -> bool {
        match self {
            Required::AtLeast(m) => v >= m,
            Required::AtMost(m) => v <= m,
            Required::Exactly(m) => v == m,
            Required::Between(lo, hi) => (lo..=hi).contains(&v),
            // An element past the three the type has (a profile made in code) is bounded by nothing.
            Required::EachAtLeast(m) => m.get(i).is_none_or(|m| v >= *m),
        }
    }

    fn describe(self, i: usize) -> String {
        match self {
            Required::AtLeast(m) => format!("at least {m}"),
            Required::AtMost(m) => format!("at most {m}"),
            Required::Exactly(m) => format!("exactly {m}"),
            Required::Between(lo, hi) => format!("from {lo} to {hi}"),
            Required::EachAtLeast(m) => m.get(i).map_or(String::new(), |m| format!("at least {m}")),
        }
    }
}

/// One limit: where it lives, its type, what the specification requires of it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RequiredLimit {
    /// `Struct::member`, as [`DeviceProfile::limit`] finds it.
    pub member: &'static str,
    pub c_type: CType,
    pub required: Required,
    /// An alignment the specification says is a power of two.
    pub power_of_two: bool,
    /// A size or alignment cases are laid out with, which zero would make meaningless (the
    /// specification's bound alone would allow it).
    pub nonzero: bool,
}

const fn limit(member: &'static str, c_type: CType, required: Required) -> RequiredLimit {
    RequiredLimit {
        member,
        c_type,
        required,
        power_of_two: false,
        nonzero: false,
    }
}

const fn alignment(member: &'static str, required: Required, power_of_two: bool) -> RequiredLimit {
    RequiredLimit {
        member,
        c_type: CType::U32,
        required,
        power_of_two,
        nonzero: true,
    }
}

const U24: u64 = (1 << 24) - 1;
const U29: u64 = (1 << 29) - 1;
const U32MAX: u64 = u32::MAX as u64;

/// The members of the three ray tracing property structures with an unconditional required bound
/// (the two update-after-bind descriptor counts, bounded only where a feature is supported, are
/// left out), and the compute limits a launch's dimensions are checked against.
pub static REQUIRED_LIMITS: &[RequiredLimit] = &[
    RequiredLimit {
        nonzero: true,
        ..limit(
            "VkPhysicalDeviceRayTracingPipelinePropertiesKHR::shaderGroupHandleSize",
            CType::U32,
            Required::Exactly(32),
        )
    },
    limit(
        "VkPhysicalDeviceRayTracingPipelinePropertiesKHR::maxRayRecursionDepth",
        CType::U32,
        Required::AtLeast(1),
    ),
    limit(
        "VkPhysicalDeviceRayTracingPipelinePropertiesKHR::maxShaderGroupStride",
        CType::U32,
        Required::AtLeast(4096),
    ),
    alignment(
        "VkPhysicalDeviceRayTracingPipelinePropertiesKHR::shaderGroupBaseAlignment",
        Required::AtMost(64),
        false,
    ),
    limit(
        "VkPhysicalDeviceRayTracingPipelinePropertiesKHR::shaderGroupHandleCaptureReplaySize",
        CType::U32,
        Required::AtMost(64),
    ),
    limit(
        "VkPhysicalDeviceRayTracingPipelinePropertiesKHR::maxRayDispatchInvocationCount",
        CType::U32,
        Required::AtLeast(1 << 30),
    ),
    alignment(
        "VkPhysicalDeviceRayTracingPipelinePropertiesKHR::shaderGroupHandleAlignment",
        Required::AtMost(32),
        true,
    ),
    limit(
        "VkPhysicalDeviceRayTracingPipelinePropertiesKHR::maxRayHitAttributeSize",
        CType::U32,
        Required::AtLeast(32),
    ),
    RequiredLimit {
        nonzero: true,
        ..limit(
            "VkPhysicalDeviceRayTracingPropertiesNV::shaderGroupHandleSize",
            CType::U32,
            Required::AtLeast(16),
        )
    },
    limit(
        "VkPhysicalDeviceRayTracingPropertiesNV::maxRecursionDepth",
        CType::U32,
        Required::AtLeast(31),
    ),
    limit(
        "VkPhysicalDeviceRayTracingPropertiesNV::maxShaderGroupStride",
        CType::U32,
        Required::AtLeast(4096),
    ),
    alignment(
        "VkPhysicalDeviceRayTracingPropertiesNV::shaderGroupBaseAlignment",
        Required::AtMost(64),
        false,
    ),
    limit(
        "VkPhysicalDeviceRayTracingPropertiesNV::maxGeometryCount",
        CType::U64,
        Required::Between(U24, U32MAX),
    ),
    limit(
        "VkPhysicalDeviceRayTracingPropertiesNV::maxInstanceCount",
        CType::U64,
        Required::Between(U24, U32MAX),
    ),
    limit(
        "VkPhysicalDeviceRayTracingPropertiesNV::maxTriangleCount",
        CType::U64,
        Required::Between(U29, U32MAX),
    ),
    limit(
        "VkPhysicalDeviceRayTracingPropertiesNV::maxDescriptorSetAccelerationStructures",
        CType::U32,
        Required::AtLeast(16),
    ),
    limit(
        "VkPhysicalDeviceAccelerationStructurePropertiesKHR::maxGeometryCount",
        CType::U64,
        Required::Between(U24, U32MAX),
    ),
    limit(
        "VkPhysicalDeviceAccelerationStructurePropertiesKHR::maxInstanceCount",
        CType::U64,
        Required::Between(U24, U32MAX),
    ),
    limit(
        "VkPhysicalDeviceAccelerationStructurePropertiesKHR::maxPrimitiveCount",
        CType::U64,
        Required::Between(U29, U32MAX),
    ),
    limit(
        "VkPhysicalDeviceAccelerationStructurePropertiesKHR::maxPerStageDescriptorAccelerationStructures",
        CType::U32,
        Required::AtLeast(16),
    ),
    limit(
        "VkPhysicalDeviceAccelerationStructurePropertiesKHR::maxDescriptorSetAccelerationStructures",
        CType::U32,
        Required::AtLeast(16),
    ),
    alignment(
        "VkPhysicalDeviceAccelerationStructurePropertiesKHR::minAccelerationStructureScratchOffsetAlignment",
        Required::AtMost(256),
        true,
    ),
    limit(
        "VkPhysicalDeviceLimits::maxComputeWorkGroupCount",
        CType::U32x3,
        Required::EachAtLeast([65535, 65535, 65535]),
    ),
    limit(
        "VkPhysicalDeviceLimits::maxComputeWorkGroupSize",
        CType::U32x3,
        Required::EachAtLeast([128, 128, 64]),
    ),
];

/// The requirement on `Struct::member`, if rtconf reads that member.
pub fn requirement(member: &str) -> Option<&'static RequiredLimit> {
    REQUIRED_LIMITS.iter().find(|l| l.member == member)
}

/// Why a value read from a profile file cannot be used: not an unsigned integer its C type holds
/// (three of them for an array), or zero or not a power of two where the layout needs otherwise.
pub fn unusable(limit: &RequiredLimit, value: &Value) -> Option<String> {
    let what = || vk_registry::error::excerpt(&value.to_string()).into_owned();
    let elements: Vec<&Value> = match (limit.c_type, value) {
        (CType::U32x3, Value::Array(a)) if a.len() == 3 => a.iter().collect(),
        (CType::U32x3, _) => return Some(format!("{} is not {}", what(), limit.c_type.name())),
        (_, v) => vec![v],
    };
    let element_type = match limit.c_type {
        CType::U32x3 => CType::U32,
        t => t,
    };
    for v in elements {
        let Some(n) = v.as_u64().filter(|n| *n <= element_type.max()) else {
            return Some(format!("{} is not {}", what(), limit.c_type.name()));
        };
        if (limit.nonzero || limit.power_of_two) && n == 0 {
            return Some(
                "0: no shader binding table or scratch buffer can be laid out with a size or alignment of 0"
                    .into(),
            );
        }
        if limit.power_of_two && !n.is_power_of_two() {
            return Some(format!(
                "{n} is not a power of two, which the specification requires"
            ));
        }
    }
    None
}

/// A limit a device reports outside what the specification requires of it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct LimitFinding {
    pub member: &'static str,
    /// The value reported (one element's, with its index, for an array).
    pub reported: String,
    pub required: String,
}

impl std::fmt::Display for LimitFinding {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "the device reports {} = {}; the specification requires {} (Limit Requirements)",
            self.member, self.reported, self.required
        )
    }
}

impl LimitFinding {
    /// The finding as a run or generation warns of it: the profile's name, and that its cases keep
    /// to the value reported.
    pub fn warning(&self, profile: &str) -> String {
        format!("profile {profile}: {self}; its cases keep to the reported value")
    }
}

/// Every requirement of [`REQUIRED_LIMITS`] the profile's reported values break, in table order.
/// A member the profile does not report is not a finding here (the reader of that member says so).
pub fn findings(profile: &DeviceProfile) -> Vec<LimitFinding> {
    let mut out = Vec::new();
    for limit in REQUIRED_LIMITS {
        let Some(value) = profile.properties.get(limit.member) else {
            continue;
        };
        let values: Vec<Option<u64>> = match value {
            PropertyValue::Array(a) => a.iter().map(PropertyValue::as_u64).collect(),
            v => vec![v.as_u64()],
        };
        for (i, v) in values.into_iter().enumerate() {
            let Some(v) = v else { continue };
            let reported = if limit.c_type == CType::U32x3 {
                format!("{v} at index {i}")
            } else {
                v.to_string()
            };
            if !limit.required.holds(i, v) {
                out.push(LimitFinding {
                    member: limit.member,
                    reported: reported.clone(),
                    required: limit.required.describe(i),
                });
            }
            if limit.power_of_two && !v.is_power_of_two() {
                out.push(LimitFinding {
                    member: limit.member,
                    reported,
                    required: "a power of two".into(),
                });
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    fn named(member: &str) -> &'static RequiredLimit {
        requirement(member).unwrap_or_else(|| panic!("{member} is in the table"))
    }

    #[test]
    fn every_member_is_named_by_struct_and_listed_once() {
        for (i, l) in REQUIRED_LIMITS.iter().enumerate() {
            assert!(l.member.starts_with("VkPhysicalDevice"), "{}", l.member);
            assert!(l.member.contains("::"), "{}", l.member);
            assert_eq!(
                requirement(l.member).map(|r| r as *const _),
                Some(&REQUIRED_LIMITS[i] as *const _)
            );
        }
    }

    #[test]
    fn values_a_c_type_cannot_hold_are_unusable() {
        let stride = named("VkPhysicalDeviceRayTracingPipelinePropertiesKHR::maxShaderGroupStride");
        assert_eq!(unusable(stride, &json!(4096)), None);
        assert_eq!(unusable(stride, &json!(4294967295u64)), None);
        for bad in [
            json!(4294967296u64),
            json!(-1),
            json!(1.5),
            json!("4096"),
            json!(null),
        ] {
            let why = unusable(stride, &bad).expect("refused");
            assert!(why.contains("not a uint32_t"), "{why}");
        }
        let instances =
            named("VkPhysicalDeviceAccelerationStructurePropertiesKHR::maxInstanceCount");
        assert_eq!(unusable(instances, &json!(u64::MAX)), None);
        let counts = named("VkPhysicalDeviceLimits::maxComputeWorkGroupCount");
        assert_eq!(unusable(counts, &json!([65535, 65535, 65535])), None);
        for bad in [
            json!([65535, 65535]),
            json!([1, "x", 3]),
            json!(7),
            json!([1, 2, 4294967296u64]),
        ] {
            assert!(unusable(counts, &bad).is_some(), "{bad}");
        }
    }

    #[test]
    fn alignments_must_be_nonzero_and_powers_of_two_where_the_spec_says_so() {
        let handle =
            named("VkPhysicalDeviceRayTracingPipelinePropertiesKHR::shaderGroupHandleAlignment");
        assert_eq!(unusable(handle, &json!(16)), None);
        assert!(unusable(handle, &json!(0)).unwrap().starts_with("0: "));
        assert!(unusable(handle, &json!(24))
            .unwrap()
            .contains("power of two"));
        // The base alignment's text asks for no power of two: 48 is usable (and within 64).
        let base =
            named("VkPhysicalDeviceRayTracingPipelinePropertiesKHR::shaderGroupBaseAlignment");
        assert_eq!(unusable(base, &json!(48)), None);
        assert!(unusable(base, &json!(0)).is_some());
        let size = named("VkPhysicalDeviceRayTracingPipelinePropertiesKHR::shaderGroupHandleSize");
        assert!(unusable(size, &json!(0)).is_some());
    }

    #[test]
    fn findings_name_each_bound_a_reported_value_breaks() {
        let mut p = DeviceProfile::default();
        let mut set = |m: &str, v: PropertyValue| {
            p.properties.insert(m.into(), v);
        };
        set(
            "VkPhysicalDeviceRayTracingPipelinePropertiesKHR::maxRayDispatchInvocationCount",
            PropertyValue::Int(1 << 26),
        );
        set(
            "VkPhysicalDeviceRayTracingPipelinePropertiesKHR::shaderGroupHandleSize",
            PropertyValue::Int(32),
        );
        set(
            "VkPhysicalDeviceRayTracingPipelinePropertiesKHR::shaderGroupBaseAlignment",
            PropertyValue::Int(128),
        );
        set(
            "VkPhysicalDeviceLimits::maxComputeWorkGroupSize",
            PropertyValue::Array(vec![
                PropertyValue::Int(1024),
                PropertyValue::Int(1024),
                PropertyValue::Int(32),
            ]),
        );
        set(
            "VkPhysicalDeviceAccelerationStructurePropertiesKHR::maxPrimitiveCount",
            PropertyValue::Int(1 << 33),
        );
        // Four elements where the type has three (a profile made in code): the fourth, 0, is bounded
        // by nothing, and nothing panics.
        let int = PropertyValue::Int;
        set(
            "VkPhysicalDeviceLimits::maxComputeWorkGroupCount",
            PropertyValue::Array(vec![int(65535), int(65535), int(65535), int(0)]),
        );
        let found: Vec<String> = findings(&p).iter().map(|f| f.to_string()).collect();
        assert_eq!(
            found,
            [
                "the device reports VkPhysicalDeviceRayTracingPipelinePropertiesKHR::shaderGroupBaseAlignment = 128; the specification requires at most 64 (Limit Requirements)",
                "the device reports VkPhysicalDeviceRayTracingPipelinePropertiesKHR::maxRayDispatchInvocationCount = 67108864; the specification requires at least 1073741824 (Limit Requirements)",
                "the device reports VkPhysicalDeviceAccelerationStructurePropertiesKHR::maxPrimitiveCount = 8589934592; the specification requires from 536870911 to 4294967295 (Limit Requirements)",
                "the device reports VkPhysicalDeviceLimits::maxComputeWorkGroupSize = 32 at index 2; the specification requires at least 64 (Limit Requirements)",
            ]
        );
    }
}
