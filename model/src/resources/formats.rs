//! What a `VkFormat` is (numeric class, components, component width), read from its name, and which
//! format features a device has for it, read from the device profile.
//!
//! Profiles captured with `VkFormatProperties` carry only the first set of feature bits. Bits that
//! exist only in `VkFormatFeatureFlags2` are taken from the profile when it lists them
//! (`VK_FORMAT_FEATURE_2_…`), and otherwise derived where the specification ties them to what the
//! profile does carry: the `*_WITHOUT_FORMAT` bits from the storage bit and the
//! `shaderStorageImage{Read,Write}WithoutFormat` features, the depth comparison bit from a depth
//! format that can be sampled. A format the profile does not report has unknown features, and the
//! rules about format features do not judge it.

use super::Numeric;
use crate::profile::DeviceProfile;
use std::collections::BTreeSet;

/// What a format's name says of it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FormatInfo {
    pub numeric: Numeric,
    /// Number of components (`R8G8B8A8` → 4, `A8` → 1, `D24` with `X8` → 1).
    pub components: u32,
    /// Widest component in bits.
    pub width: u32,
    pub depth: bool,
}

/// Parses `VK_FORMAT_R32G32_SFLOAT`-style names; None for block-compressed and unknown shapes.
pub fn info(format: &str) -> Option<FormatInfo> {
    let name = format.strip_prefix("VK_FORMAT_").unwrap_or(format);
    let parts: Vec<&str> = name.split('_').collect();
    let numeric_at = parts.iter().position(|p| {
        matches!(
            *p,
            "UNORM"
                | "SNORM"
                | "USCALED"
                | "SSCALED"
                | "UINT"
                | "SINT"
                | "UFLOAT"
                | "SFLOAT"
                | "SRGB"
        )
    })?;
    let numeric = match parts[numeric_at] {
        "UINT" => Numeric::Uint,
        "SINT" => Numeric::Int,
        _ => Numeric::Float,
    };
    let (mut components, mut width, mut depth) = (0u32, 0u32, false);
    for part in &parts[..numeric_at] {
        let mut chars = part.chars().peekable();
        while let Some(c) = chars.next() {
            if !c.is_ascii_uppercase() {
                return None;
            }
            let mut digits = String::new();
            while let Some(d) = chars.peek().filter(|d| d.is_ascii_digit()) {
                digits.push(*d);
                chars.next();
            }
            let bits: u32 = digits.parse().ok()?;
            match c {
                'R' | 'G' | 'B' | 'A' | 'D' | 'S' => {
                    components += 1;
                    width = width.max(bits);
                    depth |= c == 'D';
                }
                'X' | 'E' => {}
                _ => return None,
            }
        }
    }
    (components > 0).then_some(FormatInfo {
        numeric,
        components,
        width,
        depth,
    })
}

/// Whether sampling the format needs a sampler Y′CbCr conversion: the 4:2:2 and 4:2:0 formats and
/// the multi-planar ones (their names carry `_422`, `_420` or `PLANE`).
pub fn needs_ycbcr_conversion(format: &str) -> bool {
    let n = format.strip_prefix("VK_FORMAT_").unwrap_or(format);
    n.contains("PLANE") || n.contains("_422") || n.contains("_420")
}

/// The number of planes of a format (1 for every format that is not multi-planar).
pub fn planes(format: &str) -> u32 {
    if format.contains("_3PLANE_") {
        3
    } else if format.contains("_2PLANE_") {
        2
    } else {
        1
    }
}

/// Where the features of a format are looked up.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Usage {
    Optimal,
    Linear,
    Buffer,
}

/// The feature names (without `VK_FORMAT_FEATURE_` / `VK_FORMAT_FEATURE_2_`) the device has for the
/// format, derived bits included; None when the profile does not report the format.
pub fn features(profile: &DeviceProfile, format: &str, usage: Usage) -> Option<BTreeSet<String>> {
    let ff = profile.formats.get(format)?;
    let raw = match usage {
        Usage::Optimal => &ff.optimal_tiling,
        Usage::Linear => &ff.linear_tiling,
        Usage::Buffer => &ff.buffer,
    };
    let mut set: BTreeSet<String> = raw
        .iter()
        .map(|n| {
            let n = n
                .strip_prefix("VK_FORMAT_FEATURE_2_")
                .or_else(|| n.strip_prefix("VK_FORMAT_FEATURE_"))
                .unwrap_or(n);
            n.to_string()
        })
        .collect();
    let explicit2 = raw.iter().any(|n| n.starts_with("VK_FORMAT_FEATURE_2_"));
    if !explicit2 {
        let storage = set.contains("STORAGE_IMAGE_BIT") || set.contains("STORAGE_TEXEL_BUFFER_BIT");
        if storage && profile.has_feature("shaderStorageImageReadWithoutFormat") {
            set.insert("STORAGE_READ_WITHOUT_FORMAT_BIT".into());
        }
        if storage && profile.has_feature("shaderStorageImageWriteWithoutFormat") {
            set.insert("STORAGE_WRITE_WITHOUT_FORMAT_BIT".into());
        }
        if info(format).is_some_and(|i| i.depth) && set.contains("SAMPLED_IMAGE_BIT") {
            set.insert("SAMPLED_IMAGE_DEPTH_COMPARISON_BIT".into());
        }
    }
    Some(set)
}

/// The formats the profile reports, in name order.
pub fn reported(profile: &DeviceProfile) -> Vec<&str> {
    profile.formats.keys().map(String::as_str).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ycbcr_formats_are_told_from_their_names() {
        for f in [
            "VK_FORMAT_G8_B8R8_2PLANE_420_UNORM",
            "VK_FORMAT_G8_B8_R8_3PLANE_444_UNORM",
            "VK_FORMAT_G8B8G8R8_422_UNORM",
        ] {
            assert!(needs_ycbcr_conversion(f), "{f}");
            assert!(info(f).is_none(), "{f} has no per-texel component layout");
        }
        for f in ["VK_FORMAT_R8G8B8A8_UNORM", "VK_FORMAT_R10X6_UNORM_PACK16"] {
            assert!(!needs_ycbcr_conversion(f), "{f}");
        }
        assert_eq!(planes("VK_FORMAT_G8_B8R8_2PLANE_420_UNORM"), 2);
        assert_eq!(planes("VK_FORMAT_G8_B8_R8_3PLANE_420_UNORM"), 3);
        assert_eq!(planes("VK_FORMAT_G8B8G8R8_422_UNORM"), 1);
    }
}
