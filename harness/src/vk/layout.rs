//! Reads and writes Vulkan feature and property structures by their C layout, from the member lists in
//! [`crate::vk::tables`], so the probe and device creation need no hand-written field per member.

use model::profile::PropertyValue;

/// The C type of a structure member, as far as its layout and its printed value go.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum MemberKind {
    U32,
    I32,
    F32,
    Bool,
    U64,
    U8,
    Char,
    /// `VkFlags`: printed as a number.
    Flags,
    /// `VkConformanceVersion`: four bytes, printed `major.minor.subminor.patch`.
    Conformance,
}

/// One member of a structure: name, type, array length (1 for a scalar).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Member {
    pub(crate) name: &'static str,
    pub(crate) kind: MemberKind,
    pub(crate) count: usize,
}

impl MemberKind {
    fn size_align(self) -> (usize, usize) {
        match self {
            MemberKind::U64 => (8, 8),
            MemberKind::U8 | MemberKind::Char => (1, 1),
            MemberKind::Conformance => (4, 1),
            _ => (4, 4),
        }
    }
}

/// Bytes before the first member: `sType` and `pNext` for extensible structures, none otherwise.
pub(crate) const EXTENSIBLE_HEADER: usize = 16;

/// The offset of each member and the structure's total size, C rules, after a header of `header` bytes.
pub(crate) fn offsets(members: &[Member], header: usize) -> (Vec<usize>, usize) {
    let mut at = header;
    let mut max_align = if header > 0 { 8 } else { 1 };
    let mut out = Vec::with_capacity(members.len());
    for m in members {
        let (size, align) = m.kind.size_align();
        max_align = max_align.max(align);
        at = at.div_ceil(align) * align;
        out.push(at);
        at += size * m.count;
    }
    (out, at.div_ceil(max_align) * max_align)
}

fn read_u32(bytes: &[u8], at: usize) -> u32 {
    u32::from_ne_bytes(bytes[at..at + 4].try_into().unwrap_or([0; 4]))
}

fn read_one(kind: MemberKind, bytes: &[u8], at: usize) -> PropertyValue {
    match kind {
        MemberKind::U32 | MemberKind::Flags => PropertyValue::Int(read_u32(bytes, at) as u64),
        MemberKind::I32 => PropertyValue::SignedInt(read_u32(bytes, at) as i32 as i64),
        MemberKind::F32 => PropertyValue::Float(f32::from_bits(read_u32(bytes, at)) as f64),
        MemberKind::Bool => PropertyValue::Bool(read_u32(bytes, at) != 0),
        MemberKind::U64 => PropertyValue::Int(u64::from_ne_bytes(
            bytes[at..at + 8].try_into().unwrap_or([0; 8]),
        )),
        MemberKind::U8 | MemberKind::Char => PropertyValue::Int(bytes[at] as u64),
        MemberKind::Conformance => PropertyValue::Text(format!(
            "{}.{}.{}.{}",
            bytes[at],
            bytes[at + 1],
            bytes[at + 2],
            bytes[at + 3]
        )),
    }
}

/// Every member's value read from a structure's bytes; `char` arrays become text, other arrays arrays.
pub(crate) fn read_members(
    members: &[Member],
    header: usize,
    bytes: &[u8],
) -> Vec<(&'static str, PropertyValue)> {
    let (offs, size) = offsets(members, header);
    if bytes.len() < size {
        return Vec::new();
    }
    members
        .iter()
        .zip(offs)
        .map(|(m, at)| {
            let value = if m.kind == MemberKind::Char {
                let raw = &bytes[at..at + m.count];
                let end = raw.iter().position(|&b| b == 0).unwrap_or(raw.len());
                PropertyValue::Text(String::from_utf8_lossy(&raw[..end]).into_owned())
            } else if m.count == 1 {
                read_one(m.kind, bytes, at)
            } else {
                let step = m.kind.size_align().0;
                PropertyValue::Array(
                    (0..m.count)
                        .map(|i| read_one(m.kind, bytes, at + i * step))
                        .collect(),
                )
            };
            (m.name, value)
        })
        .collect()
}

/// The boolean members (features) of a structure with their values.
pub(crate) fn read_bools(
    members: &[Member],
    header: usize,
    bytes: &[u8],
) -> Vec<(&'static str, bool)> {
    read_members(members, header, bytes)
        .into_iter()
        .filter_map(|(n, v)| match v {
            PropertyValue::Bool(b) => Some((n, b)),
            _ => None,
        })
        .collect()
}

/// Sets the boolean member `name` to true; false when the structure has no such member.
pub(crate) fn set_bool(members: &[Member], header: usize, bytes: &mut [u8], name: &str) -> bool {
    let (offs, size) = offsets(members, header);
    if bytes.len() < size {
        return false;
    }
    match members
        .iter()
        .zip(offs)
        .find(|(m, _)| m.name == name && m.kind == MemberKind::Bool)
    {
        Some((_, at)) => {
            bytes[at..at + 4].copy_from_slice(&1u32.to_ne_bytes());
            true
        }
        None => false,
    }
}
