//! Named bit sets (buffer usage, pipeline create flags, queue flags) that read and write as lists of Vulkan names.
//!
//! A case file says `usage: [SHADER_BINDING_TABLE_BIT_KHR, SHADER_DEVICE_ADDRESS_BIT]`; in memory it is
//! a plain bit mask, so rules test bits without string work.

use std::fmt;

/// Declares a bit-set type whose bits are the given Vulkan flag names (without the `VK_<TYPE>_` prefix).
macro_rules! named_flags {
    ($(#[$m:meta])* $name:ident : $vk_prefix:literal { $($bit:ident = $value:expr),* $(,)? }) => {
        $(#[$m])*
        #[derive(Clone, Copy, Default, PartialEq, Eq, Hash, PartialOrd, Ord)]
        pub struct $name(pub u64);

        #[allow(non_upper_case_globals)]
        impl $name {
            $(pub const $bit: $name = $name($value);)*
            /// Every named bit with its name, in declaration order.
            pub const NAMES: &'static [(&'static str, u64)] = &[$((stringify!($bit), $value)),*];
            /// The prefix that turns a short name into the registry's enumerant name.
            pub const VK_PREFIX: &'static str = $vk_prefix;

            pub const fn empty() -> Self { $name(0) }
            pub const fn contains(self, other: Self) -> bool { self.0 & other.0 == other.0 }
            pub const fn intersects(self, other: Self) -> bool { self.0 & other.0 != 0 }
            pub const fn union(self, other: Self) -> Self { $name(self.0 | other.0) }
            pub const fn without(self, other: Self) -> Self { $name(self.0 & !other.0) }
            pub fn insert(&mut self, other: Self) { self.0 |= other.0; }
            pub fn remove(&mut self, other: Self) { self.0 &= !other.0; }
            /// Looks a flag up by its short name (`SHADER_BINDING_TABLE_BIT_KHR`) or its full registry name.
            pub fn from_name(name: &str) -> Option<Self> {
                let short = name.strip_prefix(Self::VK_PREFIX).unwrap_or(name);
                Self::NAMES.iter().find(|(n, _)| *n == short).map(|(_, v)| $name(*v))
            }
            pub fn names(self) -> Vec<String> {
                // The first name of a value wins: aliases (RAY_TRACING_BIT_NV) are not repeated.
                let mut seen = 0u64;
                let mut out = Vec::new();
                for (n, v) in Self::NAMES {
                    if *v != 0 && self.0 & v == *v && seen & v != *v {
                        seen |= v;
                        out.push(n.to_string());
                    }
                }
                let known: u64 = Self::NAMES.iter().fold(0, |a, (_, v)| a | v);
                if self.0 & !known != 0 {
                    out.push(format!("0x{:x}", self.0 & !known));
                }
                out
            }
        }

        impl std::ops::BitOr for $name {
            type Output = $name;
            fn bitor(self, o: $name) -> $name { $name(self.0 | o.0) }
        }

        impl fmt::Debug for $name {
            fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                write!(f, "{}({})", stringify!($name), self.names().join(" | "))
            }
        }

        impl serde::Serialize for $name {
            fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
                s.collect_seq(self.names())
            }
        }

        impl<'de> serde::Deserialize<'de> for $name {
            fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
                let names: Vec<String> = serde::Deserialize::deserialize(d)?;
                let mut bits = 0u64;
                for n in &names {
                    if let Some(hex) = n.strip_prefix("0x") {
                        bits |= u64::from_str_radix(hex, 16)
                            .map_err(|_| serde::de::Error::custom(format!("bad hex flag value `{n}`")))?;
                    } else {
                        let v = $name::from_name(n).ok_or_else(|| {
                            let known: Vec<&str> = $name::NAMES.iter().map(|(n, _)| *n).collect();
                            serde::de::Error::custom(format!(
                                "unknown {} flag `{n}` (known: {})", stringify!($name), known.join(", ")))
                        })?;
                        bits |= v.0;
                    }
                }
                Ok($name(bits))
            }
        }
    };
}

named_flags! {
    /// `VkBufferUsageFlags` bits that the ray tracing rules speak of.
    BufferUsage: "VK_BUFFER_USAGE_" {
        TRANSFER_SRC_BIT = 0x1,
        TRANSFER_DST_BIT = 0x2,
        UNIFORM_BUFFER_BIT = 0x10,
        STORAGE_BUFFER_BIT = 0x20,
        INDEX_BUFFER_BIT = 0x40,
        VERTEX_BUFFER_BIT = 0x80,
        INDIRECT_BUFFER_BIT = 0x100,
        SHADER_BINDING_TABLE_BIT_KHR = 0x400,
        RAY_TRACING_BIT_NV = 0x400,
        SHADER_DEVICE_ADDRESS_BIT = 0x20000,
        ACCELERATION_STRUCTURE_BUILD_INPUT_READ_ONLY_BIT_KHR = 0x80000,
        ACCELERATION_STRUCTURE_STORAGE_BIT_KHR = 0x100000,
    }
}

named_flags! {
    /// `VkBufferCreateFlags` bits.
    BufferCreate: "VK_BUFFER_CREATE_" {
        SPARSE_BINDING_BIT = 0x1,
        SPARSE_RESIDENCY_BIT = 0x2,
        SPARSE_ALIASED_BIT = 0x4,
        PROTECTED_BIT = 0x8,
    }
}

named_flags! {
    /// `VkPipelineCreateFlags` bits of ray tracing pipelines.
    PipelineCreate: "VK_PIPELINE_CREATE_" {
        LIBRARY_BIT_KHR = 0x800,
        RAY_TRACING_NO_NULL_ANY_HIT_SHADERS_BIT_KHR = 0x4000,
        RAY_TRACING_NO_NULL_CLOSEST_HIT_SHADERS_BIT_KHR = 0x8000,
        RAY_TRACING_NO_NULL_MISS_SHADERS_BIT_KHR = 0x10000,
        RAY_TRACING_NO_NULL_INTERSECTION_SHADERS_BIT_KHR = 0x20000,
        RAY_TRACING_SKIP_TRIANGLES_BIT_KHR = 0x1000,
        RAY_TRACING_SKIP_AABBS_BIT_KHR = 0x2000,
        RAY_TRACING_SHADER_GROUP_HANDLE_CAPTURE_REPLAY_BIT_KHR = 0x80000,
        RAY_TRACING_ALLOW_MOTION_BIT_NV = 0x100000,
    }
}

named_flags! {
    /// `VkQueueFlags` of the pool a command buffer was allocated from.
    QueueFlags: "VK_QUEUE_" {
        GRAPHICS_BIT = 0x1,
        COMPUTE_BIT = 0x2,
        TRANSFER_BIT = 0x4,
        SPARSE_BINDING_BIT = 0x8,
        PROTECTED_BIT = 0x10,
        VIDEO_DECODE_BIT_KHR = 0x20,
        VIDEO_ENCODE_BIT_KHR = 0x40,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flags_round_trip_through_names() {
        let u = BufferUsage::SHADER_BINDING_TABLE_BIT_KHR | BufferUsage::SHADER_DEVICE_ADDRESS_BIT;
        let yaml = serde_yaml::to_string(&u).unwrap();
        let back: BufferUsage = serde_yaml::from_str(&yaml).unwrap();
        assert_eq!(back, u);
        assert_eq!(
            BufferUsage::from_name("VK_BUFFER_USAGE_INDIRECT_BUFFER_BIT"),
            Some(BufferUsage::INDIRECT_BUFFER_BIT)
        );
    }

    #[test]
    fn unknown_flag_names_are_rejected_with_the_known_list() {
        let err = serde_yaml::from_str::<BufferUsage>("[NOT_A_FLAG]")
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("unknown BufferUsage flag `NOT_A_FLAG`"),
            "{err}"
        );
        assert!(err.contains("INDIRECT_BUFFER_BIT"), "{err}");
    }
}
