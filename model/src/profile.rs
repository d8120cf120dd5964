//! Device profiles: what a real device reported (API version, extensions, features, limits), read
//! from and written to the Vulkan Profiles JSON schema that `vulkaninfo --json` and `rtconf probe` write.
//!
//! Rules and generators look limits up by `Struct::member` (`VkPhysicalDeviceRayTracingPipelinePropertiesKHR::
//! shaderGroupBaseAlignment`) or by the member name alone; nothing about a particular driver lives in code.

use serde_json::{Map, Value};
use std::collections::{BTreeMap, BTreeSet};

/// One value a device reported for a property member.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(untagged)]
pub enum PropertyValue {
    Bool(bool),
    Int(u64),
    SignedInt(i64),
    Float(f64),
    Array(Vec<PropertyValue>),
    Text(String),
}

impl PropertyValue {
    pub fn as_u64(&self) -> Option<u64> {
        match self {
            PropertyValue::Int(v) => Some(*v),
            PropertyValue::Bool(b) => Some(*b as u64),
            PropertyValue::SignedInt(v) if *v >= 0 => Some(*v as u64),
            _ => None,
        }
    }

    fn from_json(v: &Value) -> Option<PropertyValue> {
        Some(match v {
            Value::Bool(b) => PropertyValue::Bool(*b),
            Value::Number(n) => {
                if let Some(u) = n.as_u64() {
                    PropertyValue::Int(u)
                } else if let Some(i) = n.as_i64() {
                    PropertyValue::SignedInt(i)
                } else {
                    PropertyValue::Float(n.as_f64()?)
                }
            }
            Value::Array(a) => {
                PropertyValue::Array(a.iter().filter_map(PropertyValue::from_json).collect())
            }
            Value::String(s) => PropertyValue::Text(s.clone()),
            _ => return None,
        })
    }

    fn to_json(&self) -> Value {
        match self {
            PropertyValue::Bool(b) => Value::Bool(*b),
            PropertyValue::Int(v) => Value::from(*v),
            PropertyValue::SignedInt(v) => Value::from(*v),
            PropertyValue::Float(v) => Value::from(*v),
            PropertyValue::Array(a) => Value::Array(a.iter().map(PropertyValue::to_json).collect()),
            PropertyValue::Text(s) => Value::String(s.clone()),
        }
    }
}

/// The most bytes read from one profile file (a probed one is about a hundred kilobytes).
pub const PROFILE_FILE_LIMIT: u64 = 64 * vk_registry::input::MIB;

/// A device as a real driver described it.
#[derive(Debug, Clone, PartialEq, Default, serde::Serialize, serde::Deserialize)]
pub struct DeviceProfile {
    /// Short name used on the command line and in cases (`lavapipe`, `nvidia-h100`).
    pub name: String,
    /// What produced it: device name, driver name and version.
    pub description: String,
    /// `major.minor.patch` of the device's API version.
    pub api_version: String,
    /// Device extensions the driver exposes.
    pub extensions: BTreeSet<String>,
    /// Feature members by `Struct::member`, with the value reported.
    pub features: BTreeMap<String, bool>,
    /// Property members by `Struct::member` (nested structs flattened by their type name).
    pub properties: BTreeMap<String, PropertyValue>,
    /// Format features by format name: (linear, optimal, buffer) feature names.
    pub formats: BTreeMap<String, FormatFeatures>,
    /// Queue families: flags of each.
    pub queue_families: Vec<Vec<String>>,
}

/// Format features of one format as the device reported them (flag names without the prefix).
#[derive(Debug, Clone, PartialEq, Default, serde::Serialize, serde::Deserialize)]
pub struct FormatFeatures {
    pub linear_tiling: BTreeSet<String>,
    pub optimal_tiling: BTreeSet<String>,
    pub buffer: BTreeSet<String>,
}

/// A profile file that could not be read: what and where.
#[derive(Debug, thiserror::Error)]
#[error("{location}: {problem}")]
pub struct ProfileError {
    pub location: String,
    pub problem: String,
}

/// Nested property structs inside `VkPhysicalDeviceProperties`, flattened under their own type name.
const NESTED_PROPERTY_STRUCTS: &[(&str, &str)] = &[
    ("limits", "VkPhysicalDeviceLimits"),
    ("sparseProperties", "VkPhysicalDeviceSparseProperties"),
];

impl DeviceProfile {
    /// Whether the device reports the feature, looked up as `Struct::member` or by member name alone.
    pub fn has_feature(&self, name: &str) -> bool {
        if let Some(v) = self.features.get(name) {
            return *v;
        }
        let member = last_segment(name);
        self.features
            .iter()
            .any(|(k, v)| *v && last_segment_is(k, member))
    }

    /// A property looked up by `Struct::member` or by member name alone (first match in key order).
    pub fn property(&self, name: &str) -> Option<&PropertyValue> {
        if let Some(v) = self.properties.get(name) {
            return Some(v);
        }
        let member = last_segment(name);
        self.properties
            .iter()
            .find(|(k, _)| last_segment_is(k, member))
            .map(|(_, v)| v)
    }

    /// An unsigned limit; `name[i]` picks an array element.
    pub fn limit(&self, name: &str) -> Option<u64> {
        if let Some((base, idx)) = name.strip_suffix(']').and_then(|s| s.split_once('[')) {
            let i: usize = idx.parse().ok()?;
            return match self.property(base)? {
                PropertyValue::Array(a) => a.get(i)?.as_u64(),
                _ => None,
            };
        }
        self.property(name)?.as_u64()
    }

    pub fn has_extension(&self, name: &str) -> bool {
        self.extensions.contains(name)
    }

    /// `(major, minor)` of the API version.
    pub fn api_major_minor(&self) -> (u32, u32) {
        let mut it = self
            .api_version
            .split('.')
            .map(|p| p.parse::<u32>().unwrap_or(0));
        (it.next().unwrap_or(1), it.next().unwrap_or(0))
    }

    /// Reads a Vulkan Profiles JSON document (`capabilities.*.{extensions,features,properties,formats}`
    /// merged over every capability block, `profiles.*.api-version`).
    pub fn from_profiles_json(name: &str, text: &str) -> Result<DeviceProfile, ProfileError> {
        let root: Value = serde_json::from_str(text).map_err(|e| ProfileError {
            location: format!("{name}:{}:{}", e.line(), e.column()),
            problem: format!("not valid JSON: {e}"),
        })?;
        let caps = root
            .get("capabilities")
            .and_then(Value::as_object)
            .ok_or_else(|| ProfileError {
                location: format!("{name}: $.capabilities"),
                problem: "missing the `capabilities` object of the Vulkan Profiles schema".into(),
            })?;
        let mut p = DeviceProfile {
            name: name.to_string(),
            ..Default::default()
        };
        if let Some(profiles) = root.get("profiles").and_then(Value::as_object) {
            if let Some((_, first)) = profiles.iter().next() {
                p.api_version = first
                    .get("api-version")
                    .and_then(Value::as_str)
                    .unwrap_or("")
                    .to_string();
                p.description = first
                    .get("description")
                    .and_then(Value::as_str)
                    .unwrap_or("")
                    .to_string();
            }
        }
        for (cap, block) in caps {
            if let Some(ext) = block.get("extensions").and_then(Value::as_object) {
                p.extensions.extend(ext.keys().cloned());
            }
            if let Some(feats) = block.get("features").and_then(Value::as_object) {
                for (st, members) in feats {
                    for (m, v) in members.as_object().into_iter().flatten() {
                        if let Some(b) = v.as_bool() {
                            p.features.insert(format!("{st}::{m}"), b);
                        }
                    }
                }
            }
            if let Some(props) = block.get("properties").and_then(Value::as_object) {
                for (st, members) in props {
                    let path = format!("$.capabilities.{cap}.properties.{st}");
                    refuse_unusable(name, &path, st, members)?;
                    flatten_properties(st, members, &mut p.properties);
                }
            }
            if let Some(formats) = block.get("formats").and_then(Value::as_object) {
                for (fmt, v) in formats {
                    let mut ff = FormatFeatures::default();
                    for key in [
                        "VkFormatProperties",
                        "VkFormatProperties3",
                        "VkFormatProperties3KHR",
                    ] {
                        if let Some(fp) = v.get(key) {
                            let names = |k: &str| -> Vec<String> {
                                fp.get(k)
                                    .and_then(Value::as_array)
                                    .map(|a| {
                                        a.iter()
                                            .filter_map(|s| s.as_str().map(String::from))
                                            .collect()
                                    })
                                    .unwrap_or_default()
                            };
                            ff.linear_tiling.extend(names("linearTilingFeatures"));
                            ff.optimal_tiling.extend(names("optimalTilingFeatures"));
                            ff.buffer.extend(names("bufferFeatures"));
                        }
                    }
                    p.formats.insert(fmt.clone(), ff);
                }
            }
            if let Some(q) = block
                .get("queueFamiliesProperties")
                .and_then(Value::as_array)
            {
                for fam in q {
                    let flags = fam
                        .pointer("/VkQueueFamilyProperties/queueFlags")
                        .and_then(Value::as_array)
                        .map(|a| {
                            a.iter()
                                .filter_map(|s| s.as_str().map(String::from))
                                .collect()
                        })
                        .unwrap_or_default();
                    p.queue_families.push(flags);
                }
            }
        }
        if p.api_version.is_empty() {
            if let Some(PropertyValue::Text(v)) =
                p.properties.get("VkPhysicalDeviceProperties::apiVersion")
            {
                p.api_version = v.clone();
            }
        }
        Ok(p)
    }

    /// Writes the profile in the Vulkan Profiles JSON schema (one `device` capability block).
    pub fn to_profiles_json(&self) -> String {
        let mut features: BTreeMap<&str, Map<String, Value>> = BTreeMap::new();
        for (k, v) in &self.features {
            let (st, m) = k
                .split_once("::")
                .unwrap_or(("VkPhysicalDeviceFeatures", k));
            features
                .entry(st)
                .or_default()
                .insert(m.to_string(), Value::Bool(*v));
        }
        let mut props: BTreeMap<String, Map<String, Value>> = BTreeMap::new();
        for (k, v) in &self.properties {
            let (st, m) = k
                .split_once("::")
                .unwrap_or(("VkPhysicalDeviceProperties", k));
            if let Some((field, _)) = NESTED_PROPERTY_STRUCTS.iter().find(|(_, ty)| *ty == st) {
                let outer = props
                    .entry("VkPhysicalDeviceProperties".into())
                    .or_default();
                let inner = outer
                    .entry(field.to_string())
                    .or_insert_with(|| Value::Object(Map::new()));
                inner
                    .as_object_mut()
                    .expect("nested property struct is an object")
                    .insert(m.to_string(), v.to_json());
            } else {
                props
                    .entry(st.to_string())
                    .or_default()
                    .insert(m.to_string(), v.to_json());
            }
        }
        let formats: Map<String, Value> = self
            .formats
            .iter()
            .map(|(f, ff)| {
                let list = |s: &BTreeSet<String>| {
                    Value::Array(s.iter().cloned().map(Value::String).collect())
                };
                (
                    f.clone(),
                    serde_json::json!({"VkFormatProperties": {
                        "linearTilingFeatures": list(&ff.linear_tiling),
                        "optimalTilingFeatures": list(&ff.optimal_tiling),
                        "bufferFeatures": list(&ff.buffer)}}),
                )
            })
            .collect();
        let extensions: Map<String, Value> = self
            .extensions
            .iter()
            .map(|e| (e.clone(), Value::from(1)))
            .collect();
        let queues: Vec<Value> = self
            .queue_families
            .iter()
            .map(|f| serde_json::json!({"VkQueueFamilyProperties": {"queueFlags": f}}))
            .collect();
        let profile_key = format!(
            "VP_RTCONF_{}",
            self.name.to_uppercase().replace(['-', ' ', '.'], "_")
        );
        let doc = serde_json::json!({
            "$schema": "https://schema.khronos.org/vulkan/profiles-0.8-latest.json#",
            "capabilities": {
                "device": {
                    "extensions": extensions,
                    "features": features,
                    "properties": props,
                    "formats": formats,
                    "queueFamiliesProperties": queues,
                }
            },
            "profiles": {
                profile_key: {
                    "version": 1,
                    "api-version": self.api_version,
                    "label": self.name,
                    "description": self.description,
                    "capabilities": ["device"],
                }
            }
        });
        serde_json::to_string_pretty(&doc).expect("a profile always serialises") + "\n"
    }
}

fn flatten_properties(st: &str, members: &Value, out: &mut BTreeMap<String, PropertyValue>) {
    let Some(obj) = members.as_object() else {
        return;
    };
    for (m, v) in obj {
        if let Some((_, ty)) = NESTED_PROPERTY_STRUCTS.iter().find(|(f, _)| f == m) {
            flatten_properties(ty, v, out);
        } else if let Some(pv) = PropertyValue::from_json(v) {
            out.insert(format!("{st}::{m}"), pv);
        }
    }
}

/// Refuses the first member of a property struct that [`crate::required_limits::unusable`] rejects,
/// at its place in the file (`path` is the struct's).
fn refuse_unusable(name: &str, path: &str, st: &str, members: &Value) -> Result<(), ProfileError> {
    let Some(obj) = members.as_object() else {
        return Ok(());
    };
    for (m, v) in obj {
        if let Some((_, ty)) = NESTED_PROPERTY_STRUCTS.iter().find(|(f, _)| f == m) {
            refuse_unusable(name, &format!("{path}.{m}"), ty, v)?;
        } else if let Some(limit) = crate::required_limits::requirement(&format!("{st}::{m}")) {
            if let Some(problem) = crate::required_limits::unusable(limit, v) {
                return Err(ProfileError {
                    location: format!("{name}: {path}.{m}"),
                    problem,
                });
            }
        }
    }
    Ok(())
}

/// The member name of `Struct::member` (the text after the last `::`; the whole name without one).
fn last_segment(name: &str) -> &str {
    name.rfind("::").map_or(name, |i| &name[i + 2..])
}

/// Whether `key`'s member name ([`last_segment`]) is `member` (itself a member name): compared
/// from the end, with no searcher built per key (the profile's lookups by member name scan every key).
fn last_segment_is(key: &str, member: &str) -> bool {
    match key.strip_suffix(member) {
        Some("") => true,
        Some(rest) => rest.ends_with("::") && !member.starts_with(':'),
        None => false,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The member-name comparison is the one `rsplit("::")` defines, on names with and without a
    /// struct, with colons in odd places, and on near misses.
    #[test]
    fn member_names_compare_as_the_text_after_the_last_double_colon() {
        let names = [
            "rayQuery",
            "VkPhysicalDeviceRayQueryFeaturesKHR::rayQuery",
            "a::b::rayQuery",
            "xrayQuery",
            "a::xrayQuery",
            "a:::rayQuery",
            ":rayQuery",
            "a:b",
            "a::",
            "::",
            "",
            "rayQuery::",
            "b",
            "a::b",
            "a:::b",
            ":b",
        ];
        for key in names {
            for name in names {
                let member = last_segment(name);
                assert_eq!(member, name.rsplit("::").next().unwrap_or(name), "{name}");
                assert_eq!(
                    last_segment_is(key, member),
                    key.rsplit("::").next() == Some(member),
                    "key {key:?}, member {member:?}"
                );
            }
        }
    }

    const SMALL: &str = r#"{
      "capabilities": {"device": {
        "extensions": {"VK_KHR_ray_tracing_pipeline": 1},
        "features": {"VkPhysicalDeviceRayTracingPipelineFeaturesKHR": {"rayTracingPipeline": true, "rayTracingPipelineTraceRaysIndirect": false}},
        "properties": {
          "VkPhysicalDeviceProperties": {"limits": {"maxComputeWorkGroupCount": [65535, 65535, 65535]}},
          "VkPhysicalDeviceRayTracingPipelinePropertiesKHR": {"shaderGroupBaseAlignment": 64}
        }
      }},
      "profiles": {"VP_X": {"version": 1, "api-version": "1.3.289", "label": "x", "description": "d", "capabilities": ["device"]}}
    }"#;

    #[test]
    fn limits_resolve_by_struct_member_by_member_and_by_index() {
        let p = DeviceProfile::from_profiles_json("x", SMALL).unwrap();
        assert_eq!(
            p.limit("VkPhysicalDeviceRayTracingPipelinePropertiesKHR::shaderGroupBaseAlignment"),
            Some(64)
        );
        assert_eq!(p.limit("shaderGroupBaseAlignment"), Some(64));
        assert_eq!(
            p.limit("VkPhysicalDeviceLimits::maxComputeWorkGroupCount[2]"),
            Some(65535)
        );
        assert!(p.has_feature("rayTracingPipeline"));
        assert!(!p.has_feature("rayTracingPipelineTraceRaysIndirect"));
        assert_eq!(p.api_major_minor(), (1, 3));
    }

    #[test]
    fn writing_then_reading_keeps_every_value() {
        let p = DeviceProfile::from_profiles_json("x", SMALL).unwrap();
        let again = DeviceProfile::from_profiles_json("x", &p.to_profiles_json()).unwrap();
        assert_eq!(again, p);
    }

    /// A limit its C type cannot hold, or an alignment that is zero or not the power of two the
    /// specification requires, is refused at its place in the file: cases laid out with it would
    /// carry wrapped offsets and strides.
    #[test]
    fn unusable_limits_are_refused_at_their_place() {
        let cases = [
            ("\"shaderGroupBaseAlignment\": 64", "\"shaderGroupBaseAlignment\": 18446744073709551615",
             "x: $.capabilities.device.properties.VkPhysicalDeviceRayTracingPipelinePropertiesKHR.shaderGroupBaseAlignment",
             "not a uint32_t"),
            ("\"shaderGroupBaseAlignment\": 64", "\"shaderGroupBaseAlignment\": 0",
             "x: $.capabilities.device.properties.VkPhysicalDeviceRayTracingPipelinePropertiesKHR.shaderGroupBaseAlignment",
             "0: no shader binding table"),
            ("\"shaderGroupBaseAlignment\": 64", "\"shaderGroupHandleAlignment\": 12",
             "x: $.capabilities.device.properties.VkPhysicalDeviceRayTracingPipelinePropertiesKHR.shaderGroupHandleAlignment",
             "power of two"),
            ("[65535, 65535, 65535]", "[65535, -1, 65535]",
             "x: $.capabilities.device.properties.VkPhysicalDeviceProperties.limits.maxComputeWorkGroupCount",
             "not an array of three uint32_t"),
        ];
        for (from, to, location, problem) in cases {
            let text = SMALL.replace(from, to);
            assert_ne!(text, SMALL);
            let err = DeviceProfile::from_profiles_json("x", &text).unwrap_err();
            assert_eq!(err.location, location);
            assert!(err.problem.contains(problem), "{err}");
        }
        // Outside the required bound but usable: read, and a finding.
        let text = SMALL.replace(
            "\"shaderGroupBaseAlignment\": 64",
            "\"shaderGroupBaseAlignment\": 256",
        );
        let p = DeviceProfile::from_profiles_json("x", &text).unwrap();
        assert_eq!(crate::required_limits::findings(&p).len(), 1);
    }

    #[test]
    fn bad_json_reports_line_and_column() {
        let err =
            DeviceProfile::from_profiles_json("p.json", "{\n  \"capabilities\": [").unwrap_err();
        assert!(err.location.starts_with("p.json:2:"), "{err}");
    }
}
