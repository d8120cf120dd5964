//! The world of an acceleration structure build: buffers with typed contents (geometry, range records,
//! instance records, pointer arrays), the acceleration structures that live in them and what their
//! last build left, the command buffer, and the sizes the device reports for each build.
//!
//! Addresses are symbolic (`buffer + offset`, [`Address`]); the memory image of a buffer is computed
//! from its contents through an [`AddressResolver`], so the model and the harness lay out the same
//! bytes, the model with synthetic addresses and the harness with the device's.

use crate::call::Address;
use crate::flags::{BufferCreate, BufferUsage};
use crate::world::{CommandBufferState, DeviceState, MemoryBinding};

use super::call::{BuildFlags, GeometryFlags, IndexType};

/// `VkAccelerationStructureTypeKHR`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum AsType {
    TopLevel,
    BottomLevel,
    Generic,
}

/// One `VkAccelerationStructureBuildRangeInfoKHR`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RangeInfo {
    pub primitive_count: u32,
    #[serde(default)]
    pub primitive_offset: u32,
    #[serde(default)]
    pub first_vertex: u32,
    #[serde(default)]
    pub transform_offset: u32,
}

impl RangeInfo {
    pub const SIZE: u64 = 16;
    pub fn to_bytes(self) -> [u8; 16] {
        let mut b = [0u8; 16];
        for (i, v) in [
            self.primitive_count,
            self.primitive_offset,
            self.first_vertex,
            self.transform_offset,
        ]
        .iter()
        .enumerate()
        {
            b[i * 4..i * 4 + 4].copy_from_slice(&v.to_le_bytes());
        }
        b
    }
    pub fn from_bytes(b: &[u8]) -> RangeInfo {
        let w = |i: usize| u32::from_le_bytes([b[i * 4], b[i * 4 + 1], b[i * 4 + 2], b[i * 4 + 3]]);
        RangeInfo {
            primitive_count: w(0),
            primitive_offset: w(1),
            first_vertex: w(2),
            transform_offset: w(3),
        }
    }
}

/// What an instance record's `accelerationStructureReference` holds.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum InstanceReference {
    /// 0: the instance is inactive.
    Null,
    /// The device address of the named acceleration structure.
    Structure(String),
    /// A value not obtained from `vkGetAccelerationStructureDeviceAddressKHR`.
    Raw(u64),
}

/// One `VkAccelerationStructureInstanceKHR` (64 bytes).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InstanceRecord {
    /// Row-major 3x4; identity when omitted.
    #[serde(default = "identity")]
    pub transform: [f32; 12],
    #[serde(default)]
    pub custom_index: u32,
    #[serde(default = "full_mask")]
    pub mask: u8,
    #[serde(default)]
    pub sbt_offset: u32,
    /// `VkGeometryInstanceFlagsKHR` bits.
    #[serde(default)]
    pub flags: u8,
    pub reference: InstanceReference,
}

pub fn identity() -> [f32; 12] {
    [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0]
}
fn full_mask() -> u8 {
    0xff
}

/// `VK_GEOMETRY_INSTANCE_DISABLE_OPACITY_MICROMAPS_BIT_EXT`.
pub const INSTANCE_DISABLE_OPACITY_MICROMAPS: u8 = 0x20;

/// A write into a build buffer's memory (later writes win where they overlap).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields)]
pub enum BuildContents {
    /// Range records, record `j` at `offset + j * stride`.
    Ranges {
        offset: u64,
        stride: u64,
        ranges: Vec<RangeInfo>,
    },
    /// 32-bit floats, tightly packed (vertices, AABBs, transforms); NaN is written as a quiet NaN.
    Floats { offset: u64, values: Vec<f32> },
    /// 16-bit floats (as IEEE half bit patterns computed from the values).
    Halves { offset: u64, values: Vec<f32> },
    /// 32-bit unsigned integers (indices).
    U32s { offset: u64, values: Vec<u32> },
    /// 16-bit unsigned integers (indices).
    U16s { offset: u64, values: Vec<u16> },
    /// 8-bit unsigned integers (indices).
    U8s { offset: u64, values: Vec<u8> },
    /// Instance records, tightly packed (64 bytes each).
    Instances {
        offset: u64,
        instances: Vec<InstanceRecord>,
    },
    /// Device addresses (8 bytes each), tightly packed: the array of an arrayOfPointers instance geometry.
    Pointers { offset: u64, targets: Vec<Address> },
}

/// A `VkBuffer` of a build case.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BuildBuffer {
    pub name: String,
    pub size: u64,
    pub usage: BufferUsage,
    #[serde(default, skip_serializing_if = "is_default")]
    pub flags: BufferCreate,
    #[serde(default, skip_serializing_if = "is_default")]
    pub memory: MemoryBinding,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub contents: Vec<BuildContents>,
}

impl BuildBuffer {
    pub fn is_sparse(&self) -> bool {
        self.flags
            .intersects(BufferCreate::SPARSE_BINDING_BIT | BufferCreate::SPARSE_RESIDENCY_BIT)
    }
}

/// The shape of one geometry in a previous build, as the update rules compare it.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LastGeometry {
    pub geometry_type: super::call::GeometryType,
    #[serde(default)]
    pub flags: GeometryFlags,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub vertex_format: Option<super::call::VertexFormat>,
    #[serde(default)]
    pub max_vertex: u32,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub index_type: Option<IndexType>,
    #[serde(default)]
    pub has_transform: bool,
    /// Dense-geometry fields (VK_AMDX_dense_geometry_format), when that was the type.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dense: Option<super::call::DenseTriangles>,
    pub range: RangeInfo,
    /// The index values read, in order (indexed triangles only).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub indices: Vec<u32>,
    /// Whether each primitive was active.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub active: Vec<bool>,
}

/// What the last build of a structure left (the update rules compare against it).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LastBuild {
    #[serde(rename = "type")]
    pub ty: AsType,
    #[serde(default)]
    pub flags: BuildFlags,
    pub geometries: Vec<LastGeometry>,
}

/// A `VkAccelerationStructureKHR`: its type and the range of a buffer that backs it.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AccelerationStructure {
    pub name: String,
    #[serde(rename = "type")]
    pub ty: AsType,
    pub buffer: String,
    #[serde(default)]
    pub offset: u64,
    pub size: u64,
    /// The last build, when it has been built (by an earlier command of the case's set-up).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub last_build: Option<LastBuild>,
}

/// What `vkGetAccelerationStructureBuildSizesKHR` reports for one build info with its maxima.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BuildSizes {
    pub structure: u64,
    pub build_scratch: u64,
    pub update_scratch: u64,
}

/// Everything a build call is made in.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BuildWorld {
    pub device: DeviceState,
    #[serde(default)]
    pub buffers: Vec<BuildBuffer>,
    #[serde(default)]
    pub structures: Vec<AccelerationStructure>,
    #[serde(default)]
    pub command_buffer: CommandBufferState,
    /// The sizes the device reports per build info (index `i` of the call); rules about sizes read these.
    #[serde(default)]
    pub sizes: Vec<BuildSizes>,
}

/// Turns symbolic addresses into numbers when a memory image is laid out.
pub trait AddressResolver {
    fn buffer(&self, name: &str) -> Option<u64>;
    fn structure(&self, name: &str) -> Option<u64>;
    fn address(&self, a: &Address) -> u64 {
        match a {
            Address::Raw(v) => *v,
            // An offset past the address space wraps as the device's address arithmetic would.
            Address::InBuffer { buffer, offset } => {
                self.buffer(buffer).map_or(0, |b| b.wrapping_add(*offset))
            }
        }
    }
}

/// The model's synthetic address space: buffer `k` at `(k + 1) << 36`, structure `s` at
/// `STRUCTURE_BASE + (s << 36)`; a raw value that is neither decodes as itself.
pub struct SyntheticAddresses<'w>(pub &'w BuildWorld);

const BUFFER_SPACING: u64 = 1 << 36;
const STRUCTURE_BASE: u64 = 1 << 60;

impl AddressResolver for SyntheticAddresses<'_> {
    fn buffer(&self, name: &str) -> Option<u64> {
        self.0
            .buffers
            .iter()
            .position(|b| b.name == name)
            .map(|k| (k as u64 + 1) * BUFFER_SPACING)
    }
    fn structure(&self, name: &str) -> Option<u64> {
        self.0
            .structures
            .iter()
            .position(|s| s.name == name)
            .map(|s| STRUCTURE_BASE + (s as u64) * BUFFER_SPACING)
    }
}

impl SyntheticAddresses<'_> {
    /// The symbolic form of a synthetic address.
    pub fn decode(&self, v: u64) -> Address {
        if v != 0 && v < STRUCTURE_BASE {
            let k = (v / BUFFER_SPACING) as usize;
            if k >= 1 && k <= self.0.buffers.len() {
                return Address::InBuffer {
                    buffer: self.0.buffers[k - 1].name.clone(),
                    offset: v % BUFFER_SPACING,
                };
            }
        }
        Address::Raw(v)
    }
    /// The structure a synthetic reference names.
    pub fn decode_structure(&self, v: u64) -> InstanceReference {
        if v == 0 {
            return InstanceReference::Null;
        }
        if v >= STRUCTURE_BASE && (v - STRUCTURE_BASE) % BUFFER_SPACING == 0 {
            if let Some(s) = self
                .0
                .structures
                .get(((v - STRUCTURE_BASE) / BUFFER_SPACING) as usize)
            {
                return InstanceReference::Structure(s.name.clone());
            }
        }
        InstanceReference::Raw(v)
    }
}

/// IEEE 754 half bits of an f32 (round to nearest even; NaN stays NaN).
pub fn f32_to_half(v: f32) -> u16 {
    let b = v.to_bits();
    let sign = ((b >> 16) & 0x8000) as u16;
    let exp = ((b >> 23) & 0xff) as i32;
    let man = b & 0x7f_ffff;
    if exp == 0xff {
        return sign | 0x7c00 | if man != 0 { 0x200 } else { 0 };
    }
    let e = exp - 127 + 15;
    if e >= 0x1f {
        return sign | 0x7c00;
    }
    if e <= 0 {
        if e < -10 {
            return sign;
        }
        let m = (man | 0x80_0000) >> (1 - e);
        let half = m >> 13;
        let rest = m & 0x1fff;
        let round = (rest > 0x1000 || (rest == 0x1000 && half & 1 == 1)) as u32;
        return sign | (half + round) as u16;
    }
    let half = ((e as u32) << 10) | (man >> 13);
    let rest = man & 0x1fff;
    let round = (rest > 0x1000 || (rest == 0x1000 && half & 1 == 1)) as u32;
    sign | (half + round) as u16
}

/// The f32 value of IEEE half bits.
pub fn half_to_f32(h: u16) -> f32 {
    let sign = if h & 0x8000 != 0 { -1.0 } else { 1.0 };
    let exp = ((h >> 10) & 0x1f) as i32;
    let man = (h & 0x3ff) as f32;
    match exp {
        0 => sign * man * 2f32.powi(-24),
        0x1f => {
            if man == 0.0 {
                sign * f32::INFINITY
            } else {
                f32::NAN
            }
        }
        _ => sign * (1.0 + man / 1024.0) * 2f32.powi(exp - 15),
    }
}

impl BuildWorld {
    pub fn buffer(&self, name: &str) -> Option<&BuildBuffer> {
        self.buffers.iter().find(|b| b.name == name)
    }

    pub fn structure(&self, name: &str) -> Option<&AccelerationStructure> {
        self.structures.iter().find(|s| s.name == name)
    }

    /// The bytes of a buffer: zero (the harness zeroes every buffer) overwritten by its contents in order,
    /// kept as the ranges written ([`SparseImage`]): the model never allocates from a stated size.
    pub fn image(&self, name: &str, resolve: &dyn AddressResolver) -> Option<SparseImage> {
        let b = self.buffer(name)?;
        let mut image = SparseImage::new(b.size);
        for c in &b.contents {
            match c {
                BuildContents::Ranges {
                    offset,
                    stride,
                    ranges,
                } => {
                    for (j, r) in ranges.iter().enumerate() {
                        // A record whose offset passes u64::MAX lies past the end of every buffer.
                        let Some(at) = (j as u64)
                            .checked_mul(*stride)
                            .and_then(|d| offset.checked_add(d))
                        else {
                            break;
                        };
                        image.write(at, &r.to_bytes());
                    }
                }
                BuildContents::Floats { offset, values } => {
                    let d: Vec<u8> = values.iter().flat_map(|v| v.to_le_bytes()).collect();
                    image.write(*offset, &d);
                }
                BuildContents::Halves { offset, values } => {
                    let d: Vec<u8> = values
                        .iter()
                        .flat_map(|v| f32_to_half(*v).to_le_bytes())
                        .collect();
                    image.write(*offset, &d);
                }
                BuildContents::U32s { offset, values } => image.write(
                    *offset,
                    &values
                        .iter()
                        .flat_map(|v| v.to_le_bytes())
                        .collect::<Vec<u8>>(),
                ),
                BuildContents::U16s { offset, values } => image.write(
                    *offset,
                    &values
                        .iter()
                        .flat_map(|v| v.to_le_bytes())
                        .collect::<Vec<u8>>(),
                ),
                BuildContents::U8s { offset, values } => image.write(*offset, values),
                BuildContents::Instances { offset, instances } => {
                    for (k, inst) in instances.iter().enumerate() {
                        let Some(at) = offset.checked_add(64 * k as u64) else {
                            break;
                        };
                        image.write(at, &instance_bytes(inst, resolve));
                    }
                }
                BuildContents::Pointers { offset, targets } => {
                    let d: Vec<u8> = targets
                        .iter()
                        .flat_map(|a| resolve.address(a).to_le_bytes())
                        .collect();
                    image.write(*offset, &d);
                }
            }
        }
        Some(image)
    }

    /// The model's memory image of every buffer, with synthetic addresses.
    pub fn memory(&self) -> Memory<'_> {
        let r = SyntheticAddresses(self);
        let images = self
            .buffers
            .iter()
            .map(|b| self.image(&b.name, &r).unwrap_or_default())
            .collect();
        Memory {
            world: self,
            images,
        }
    }

    /// The buffer range `[offset, offset + size)` that backs a structure.
    pub fn backing(&self, name: &str) -> Option<(&str, u64, u64)> {
        let s = self.structure(name)?;
        Some((s.buffer.as_str(), s.offset, s.size))
    }
}

/// The 64 bytes of an instance record.
pub fn instance_bytes(inst: &InstanceRecord, resolve: &dyn AddressResolver) -> [u8; 64] {
    let mut b = [0u8; 64];
    for (i, v) in inst.transform.iter().enumerate() {
        b[i * 4..i * 4 + 4].copy_from_slice(&v.to_le_bytes());
    }
    let w0 = (inst.custom_index & 0xff_ffff) | ((inst.mask as u32) << 24);
    let w1 = (inst.sbt_offset & 0xff_ffff) | ((inst.flags as u32) << 24);
    b[48..52].copy_from_slice(&w0.to_le_bytes());
    b[52..56].copy_from_slice(&w1.to_le_bytes());
    let r = match &inst.reference {
        InstanceReference::Null => 0,
        InstanceReference::Structure(n) => resolve.structure(n).unwrap_or(0),
        InstanceReference::Raw(v) => *v,
    };
    b[56..64].copy_from_slice(&r.to_le_bytes());
    b
}

/// The bytes of one buffer as its contents wrote them: the written runs only, so a buffer may state any
/// size (u64::MAX, 100 GB) and the model holds no more than what its contents write. Bytes that no
/// write covers read as zero.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct SparseImage {
    size: u64,
    /// Written runs by start offset; they never overlap, never touch (touching runs are one) and
    /// never pass `size`.
    runs: std::collections::BTreeMap<u64, Vec<u8>>,
}

impl SparseImage {
    /// The image of a buffer of `size` bytes, all zero.
    pub fn new(size: u64) -> SparseImage {
        SparseImage {
            size,
            runs: Default::default(),
        }
    }

    pub fn size(&self) -> u64 {
        self.size
    }

    /// Writes `data` at `offset`, cutting what falls past the end; later writes win where they overlap.
    pub fn write(&mut self, offset: u64, data: &[u8]) {
        if offset >= self.size || data.is_empty() {
            return;
        }
        let n = (data.len() as u64).min(self.size - offset);
        let end = offset + n;
        // Cut every run that overlaps [offset, end) down to the parts outside it.
        let overlapping: Vec<u64> = self
            .runs
            .range(..end)
            .filter(|(at, run)| **at + run.len() as u64 > offset)
            .map(|(at, _)| *at)
            .collect();
        for at in overlapping {
            let run = self.runs.remove(&at).unwrap_or_default();
            let run_end = at + run.len() as u64;
            if at < offset {
                self.runs.insert(at, run[..(offset - at) as usize].to_vec());
            }
            if run_end > end {
                self.runs.insert(end, run[(end - at) as usize..].to_vec());
            }
        }
        // Runs that touch the new one join it, so equal contents have one representation.
        let mut start = offset;
        let mut run = data[..n as usize].to_vec();
        if let Some((&at, before)) = self.runs.range(..offset).next_back() {
            if at + before.len() as u64 == offset {
                let mut joined = self.runs.remove(&at).unwrap_or_default();
                joined.extend_from_slice(&run);
                (start, run) = (at, joined);
            }
        }
        if let Some(after) = self.runs.remove(&end) {
            run.extend_from_slice(&after);
        }
        self.runs.insert(start, run);
    }

    /// `len` bytes at `offset` (zero where nothing was written), or None when they pass the end.
    pub fn read(&self, offset: u64, len: u64) -> Option<Vec<u8>> {
        let end = offset.checked_add(len)?;
        if end > self.size {
            return None;
        }
        // Reads are of one record or value (at most a few dozen bytes), never of a stated size.
        let mut out = vec![0u8; usize::try_from(len).ok()?];
        let first = self
            .runs
            .range(..offset)
            .next_back()
            .map_or(offset, |(at, _)| *at);
        for (at, run) in self.runs.range(first..end) {
            let (lo, hi) = ((*at).max(offset), (at + run.len() as u64).min(end));
            if lo < hi {
                out[(lo - offset) as usize..(hi - offset) as usize]
                    .copy_from_slice(&run[(lo - at) as usize..(hi - at) as usize]);
            }
        }
        Some(out)
    }

    /// The written runs, by offset: what a harness copies into a zeroed buffer.
    pub fn runs(&self) -> impl Iterator<Item = (u64, &[u8])> {
        self.runs.iter().map(|(at, run)| (*at, run.as_slice()))
    }
}

/// The model's memory: the image of every buffer, read at symbolic addresses.
pub struct Memory<'w> {
    pub world: &'w BuildWorld,
    images: Vec<SparseImage>,
}

/// The longest read the model makes at once (an instance record); longer reads are refused.
const LONGEST_READ: u64 = 64;

impl Memory<'_> {
    /// `len` bytes at `address`, or None when they do not lie inside one buffer of the world.
    pub fn read(&self, address: &Address, len: u64) -> Option<Vec<u8>> {
        let (name, off) = address.buffer()?;
        let k = self.world.buffers.iter().position(|b| b.name == name)?;
        if len > LONGEST_READ {
            return None;
        }
        self.images[k].read(off, len)
    }

    pub fn u32_at(&self, a: &Address) -> Option<u32> {
        self.read(a, 4)
            .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    }
    pub fn u64_at(&self, a: &Address) -> Option<u64> {
        self.read(a, 8)
            .map(|b| u64::from_le_bytes([b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7]]))
    }
    pub fn f32_at(&self, a: &Address) -> Option<f32> {
        self.u32_at(a).map(f32::from_bits)
    }

    /// The symbolic form of an 8-byte pointer read from memory.
    pub fn pointer_at(&self, a: &Address) -> Option<Address> {
        self.u64_at(a)
            .map(|v| SyntheticAddresses(self.world).decode(v))
    }

    pub fn decode_structure(&self, v: u64) -> InstanceReference {
        SyntheticAddresses(self.world).decode_structure(v)
    }
}

/// `address + delta`, keeping the symbolic form.
pub fn offset(a: &Address, delta: u64) -> Address {
    match a {
        Address::Raw(v) => Address::Raw(v.wrapping_add(delta)),
        // Past u64::MAX the address stays past the end of its buffer.
        Address::InBuffer { buffer, offset } => Address::InBuffer {
            buffer: buffer.clone(),
            offset: offset.saturating_add(delta),
        },
    }
}

fn is_default<T: Default + PartialEq>(v: &T) -> bool {
    *v == T::default()
}
