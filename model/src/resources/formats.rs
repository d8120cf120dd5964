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
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FormatInfo {
    pub numeric: Numeric,
    /// Number of components (`R8G8B8A8` → 4, `A8` → 1, `D24` with `X8` → 1).
    pub components: u32,
    /// Widest component in bits.
    pub width: u32,
    pub depth: bool,
}

/// The most names [`info`] keeps its answer for on a thread (a profile reports a few hundred formats;
/// names from case files past this many are parsed each time).
const INFO_MEMO_SIZE: usize = 4096;

/// Parses `VK_FORMAT_R32G32_SFLOAT`-style names; None for block-compressed and unknown shapes.
/// Called for every format of a profile each time a valid resource state is drawn: a name's answer is
/// kept on the thread after its first parse.
pub fn info(format: &str) -> Option<FormatInfo> {
    thread_local! {
        static MEMO: std::cell::RefCell<std::collections::HashMap<String, Option<FormatInfo>>> =
            Default::default();
    }
    MEMO.with(|memo| {
        if let Some(known) = memo.borrow().get(format) {
            return *known;
        }
        let parsed = parse_info(format);
        let mut memo = memo.borrow_mut();
        if memo.len() < INFO_MEMO_SIZE {
            memo.insert(format.to_string(), parsed);
        }
        parsed
    })
}

/// [`info`] without the memo.
fn parse_info(format: &str) -> Option<FormatInfo> {
    let name = format.strip_prefix("VK_FORMAT_").unwrap_or(format);
    let numeric_of = |p: &str| match p {
        "UINT" => Some(Numeric::Uint),
        "SINT" => Some(Numeric::Int),
        "UNORM" | "SNORM" | "USCALED" | "SSCALED" | "UFLOAT" | "SFLOAT" | "SRGB" => {
            Some(Numeric::Float)
        }
        _ => None,
    };
    let (numeric_at, numeric) = name
        .split('_')
        .enumerate()
        .find_map(|(i, p)| numeric_of(p).map(|n| (i, n)))?;
    let (mut components, mut width, mut depth) = (0u32, 0u32, false);
    for part in name.split('_').take(numeric_at) {
        let bytes = part.as_bytes();
        let mut at = 0;
        while at < bytes.len() {
            let c = bytes[at];
            if !c.is_ascii_uppercase() {
                return None;
            }
            at += 1;
            let digits = bytes[at..]
                .iter()
                .take_while(|d| d.is_ascii_digit())
                .count();
            let bits: u32 = part[at..at + digits].parse().ok()?;
            at += digits;
            match c {
                b'R' | b'G' | b'B' | b'A' | b'D' | b'S' => {
                    components += 1;
                    width = width.max(bits);
                    depth |= c == b'D';
                }
                b'X' | b'E' => {}
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
    let raw = reported_bits(profile, format, usage)?;
    let mut set: BTreeSet<String> = raw.iter().map(|n| unprefixed(n).to_string()).collect();
    if !lists_flags2(raw) {
        let named = |b: &str| set.contains(b);
        let derived: Vec<&str> = DERIVED_BITS
            .into_iter()
            .filter(|bit| derived_bit(profile, format, bit, named))
            .collect();
        set.extend(derived.into_iter().map(String::from));
    }
    Some(set)
}

/// Whether `bit` (a name as [`features`] gives them) is among the format's features: the same
/// answer as `features(..)` containing it, without building the set (the generator asks this of
/// every format of the profile for every case). None when the profile does not report the format.
pub fn has_bit(profile: &DeviceProfile, format: &str, usage: Usage, bit: &str) -> Option<bool> {
    let raw = reported_bits(profile, format, usage)?;
    let named = |b: &str| raw.iter().any(|n| unprefixed(n) == b);
    Some(named(bit) || (!lists_flags2(raw) && derived_bit(profile, format, bit, named)))
}

/// The bits [`derived_bit`] derives where the profile lists no `VK_FORMAT_FEATURE_2_` name.
const DERIVED_BITS: [&str; 3] = [
    "STORAGE_READ_WITHOUT_FORMAT_BIT",
    "STORAGE_WRITE_WITHOUT_FORMAT_BIT",
    "SAMPLED_IMAGE_DEPTH_COMPARISON_BIT",
];

/// Whether a bit of [`DERIVED_BITS`] follows from what the profile carries (the module's text);
/// `named` says whether the profile names a bit for the format. False for any other bit.
fn derived_bit(
    profile: &DeviceProfile,
    format: &str,
    bit: &str,
    named: impl Fn(&str) -> bool,
) -> bool {
    let storage = || named("STORAGE_IMAGE_BIT") || named("STORAGE_TEXEL_BUFFER_BIT");
    match bit {
        "STORAGE_READ_WITHOUT_FORMAT_BIT" => {
            storage() && profile.has_feature("shaderStorageImageReadWithoutFormat")
        }
        "STORAGE_WRITE_WITHOUT_FORMAT_BIT" => {
            storage() && profile.has_feature("shaderStorageImageWriteWithoutFormat")
        }
        "SAMPLED_IMAGE_DEPTH_COMPARISON_BIT" => {
            named("SAMPLED_IMAGE_BIT") && info(format).is_some_and(|i| i.depth)
        }
        _ => false,
    }
}

/// The feature names the profile lists for the format and usage, as listed.
fn reported_bits<'a>(
    profile: &'a DeviceProfile,
    format: &str,
    usage: Usage,
) -> Option<&'a BTreeSet<String>> {
    let ff = profile.formats.get(format)?;
    Some(match usage {
        Usage::Optimal => &ff.optimal_tiling,
        Usage::Linear => &ff.linear_tiling,
        Usage::Buffer => &ff.buffer,
    })
}

/// Whether the profile lists `VkFormatFeatureFlags2` names (then nothing is derived).
fn lists_flags2(raw: &BTreeSet<String>) -> bool {
    raw.iter().any(|n| n.starts_with("VK_FORMAT_FEATURE_2_"))
}

/// A feature name without its `VK_FORMAT_FEATURE_2_` or `VK_FORMAT_FEATURE_` prefix.
fn unprefixed(n: &str) -> &str {
    n.strip_prefix("VK_FORMAT_FEATURE_2_")
        .or_else(|| n.strip_prefix("VK_FORMAT_FEATURE_"))
        .unwrap_or(n)
}

/// The formats the profile reports, in name order.
pub fn reported(profile: &DeviceProfile) -> Vec<&str> {
    profile.formats.keys().map(String::as_str).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `has_bit` answers as the set `features` builds, for every format, usage and bit of the
    /// lavapipe profile (and the derived bits, and one bit no format has), with each derivation's
    /// feature on and off, and with every name a `VK_FORMAT_FEATURE_2_` one.
    #[test]
    fn a_bit_test_agrees_with_the_feature_set() {
        let text = std::fs::read_to_string(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../profiles/lavapipe.json"
        ))
        .expect("the lavapipe profile");
        let base = crate::profile::DeviceProfile::from_profiles_json("lavapipe", &text)
            .expect("the lavapipe profile parses");
        let mut variants = vec![base.clone()];
        for flip in [true, false] {
            let mut p = base.clone();
            for (k, v) in p.features.iter_mut() {
                if k.ends_with("WithoutFormat") {
                    *v = flip;
                }
            }
            variants.push(p);
        }
        // Every name as a `VK_FORMAT_FEATURE_2_` one: nothing is derived.
        let mut flags2 = base.clone();
        for ff in flags2.formats.values_mut() {
            for set in [
                &mut ff.linear_tiling,
                &mut ff.optimal_tiling,
                &mut ff.buffer,
            ] {
                *set = set
                    .iter()
                    .map(|n| format!("VK_FORMAT_FEATURE_2_{}", unprefixed(n)))
                    .collect();
            }
        }
        variants.push(flags2);
        let (mut asked, mut present) = (0, 0);
        for p in &variants {
            let mut bits: BTreeSet<String> = DERIVED_BITS.iter().map(|b| b.to_string()).collect();
            bits.insert("NO_SUCH_BIT".into());
            for ff in p.formats.values() {
                for set in [&ff.linear_tiling, &ff.optimal_tiling, &ff.buffer] {
                    bits.extend(set.iter().map(|n| unprefixed(n).to_string()));
                }
            }
            for f in p.formats.keys() {
                for u in [Usage::Optimal, Usage::Linear, Usage::Buffer] {
                    let set = features(p, f, u).expect("a reported format");
                    for b in &bits {
                        asked += 1;
                        let has = has_bit(p, f, u, b).expect("a reported format");
                        present += has as usize;
                        assert_eq!(has, set.contains(b), "{f} {u:?} {b}");
                    }
                }
            }
        }
        assert!(present > 0 && present < asked, "{present} of {asked}");
        assert_eq!(
            has_bit(
                &base,
                "VK_FORMAT_NO_SUCH",
                Usage::Optimal,
                "SAMPLED_IMAGE_BIT"
            ),
            None
        );
    }

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
