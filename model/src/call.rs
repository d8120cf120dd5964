//! The calls the model judges: `vkCmdTraceRaysIndirectKHR`, `vkCmdTraceRaysKHR` and `vkCmdTraceRaysNV`,
//! with symbolic addresses, and the parameter paths (`pMissShaderBindingTable->stride`) that VUID
//! texts quote, resolved once to a [`Param`] so evaluating a rule does no string work.

use crate::world::World;

/// A device address: null, a raw value, or a named buffer's address plus an offset.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(untagged)]
pub enum Address {
    /// A literal address; 0 is the null address.
    Raw(u64),
    /// `vkGetBufferDeviceAddress(buffer) + offset`.
    InBuffer { buffer: String, offset: u64 },
}

impl Address {
    pub const NULL: Address = Address::Raw(0);

    pub fn is_null(&self) -> bool {
        matches!(self, Address::Raw(0))
    }

    /// The part of the address the model can reason about for alignment: buffers are placed by the
    /// harness at addresses aligned to [`BUFFER_PLACEMENT_ALIGNMENT`], so only the offset matters.
    pub fn alignment_value(&self) -> u64 {
        match self {
            Address::Raw(v) => *v,
            Address::InBuffer { offset, .. } => *offset,
        }
    }

    pub fn buffer(&self) -> Option<(&str, u64)> {
        match self {
            Address::InBuffer { buffer, offset } => Some((buffer, *offset)),
            Address::Raw(_) => None,
        }
    }
}

/// The harness places every buffer at a device address that is a multiple of this, and reports a case
/// `unsupported` where the driver does not; every alignment a Vulkan limit can ask for divides it.
pub const BUFFER_PLACEMENT_ALIGNMENT: u64 = 4096;

/// A `VkStridedDeviceAddressRegionKHR`.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StridedRegion {
    pub address: Address,
    pub stride: u64,
    pub size: u64,
}

impl StridedRegion {
    pub fn unused() -> StridedRegion {
        StridedRegion {
            address: Address::NULL,
            stride: 0,
            size: 0,
        }
    }
}

/// One of the four shader binding tables.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, serde::Serialize, serde::Deserialize,
)]
#[serde(rename_all = "kebab-case")]
pub enum Table {
    Raygen,
    Miss,
    Hit,
    Callable,
}

impl Table {
    pub const ALL: [Table; 4] = [Table::Raygen, Table::Miss, Table::Hit, Table::Callable];

    /// The KHR parameter name (`pRaygenShaderBindingTable`).
    pub fn khr_param(self) -> &'static str {
        match self {
            Table::Raygen => "pRaygenShaderBindingTable",
            Table::Miss => "pMissShaderBindingTable",
            Table::Hit => "pHitShaderBindingTable",
            Table::Callable => "pCallableShaderBindingTable",
        }
    }

    /// The NV parameter stem (`raygenShaderBinding`).
    pub fn nv_stem(self) -> &'static str {
        match self {
            Table::Raygen => "raygenShaderBinding",
            Table::Miss => "missShaderBinding",
            Table::Hit => "hitShaderBinding",
            Table::Callable => "callableShaderBinding",
        }
    }
}

/// `vkCmdTraceRaysIndirectKHR`: the dimensions come from a `VkTraceRaysIndirectCommandKHR` in memory.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TraceRaysIndirect {
    pub raygen: StridedRegion,
    pub miss: StridedRegion,
    pub hit: StridedRegion,
    pub callable: StridedRegion,
    pub indirect_address: Address,
}

/// `vkCmdTraceRaysKHR`.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TraceRays {
    pub raygen: StridedRegion,
    pub miss: StridedRegion,
    pub hit: StridedRegion,
    pub callable: StridedRegion,
    pub width: u32,
    pub height: u32,
    pub depth: u32,
}

/// One table of `vkCmdTraceRaysNV`: a buffer (or none), an offset and, except for raygen, a stride.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NvTable {
    pub buffer: Option<String>,
    #[serde(default)]
    pub offset: u64,
    #[serde(default)]
    pub stride: u64,
}

/// `vkCmdTraceRaysNV`.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TraceRaysNv {
    pub raygen: NvTable,
    pub miss: NvTable,
    pub hit: NvTable,
    pub callable: NvTable,
    pub width: u32,
    pub height: u32,
    pub depth: u32,
}

/// A trace call the model judges (a case writes its parameters under `call:`, its command beside it).
#[derive(Debug, Clone, PartialEq)]
pub enum Call {
    TraceRaysIndirect(TraceRaysIndirect),
    TraceRays(TraceRays),
    TraceRaysNv(TraceRaysNv),
}

/// A call parameter a rule reads, resolved from a VUID's quoted path.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Param {
    /// `p<Table>ShaderBindingTable->deviceAddress` (KHR) or `<table>ShaderBindingOffset` (NV).
    TableAddress(Table),
    TableStride(Table),
    TableSize(Table),
    IndirectAddress,
    /// width, height, depth.
    Dimension(u8),
}

impl Call {
    /// The command this call is.
    pub fn command(&self) -> crate::CommandId {
        match self {
            Call::TraceRaysIndirect(_) => crate::CommandId::TraceRaysIndirect,
            Call::TraceRays(_) => crate::CommandId::TraceRays,
            Call::TraceRaysNv(_) => crate::CommandId::TraceRaysNv,
        }
    }

    /// The four KHR regions, if this is a KHR trace call.
    pub fn regions(&self) -> Option<[&StridedRegion; 4]> {
        match self {
            Call::TraceRaysIndirect(c) => Some([&c.raygen, &c.miss, &c.hit, &c.callable]),
            Call::TraceRays(c) => Some([&c.raygen, &c.miss, &c.hit, &c.callable]),
            Call::TraceRaysNv(_) => None,
        }
    }

    pub fn region(&self, t: Table) -> Option<&StridedRegion> {
        self.regions().map(|r| r[t as usize])
    }

    pub fn nv_table(&self, t: Table) -> Option<&NvTable> {
        match self {
            Call::TraceRaysNv(c) => Some(match t {
                Table::Raygen => &c.raygen,
                Table::Miss => &c.miss,
                Table::Hit => &c.hit,
                Table::Callable => &c.callable,
            }),
            _ => None,
        }
    }

    /// Resolves a parameter path as VUID texts quote it (`pMissShaderBindingTable->stride`,
    /// `missShaderBindingStride`, `indirectDeviceAddress`, `width`); case-insensitive on the stem
    /// since the texts spell `pRayGenShaderBindingTable` where the prototype has `pRaygen…`.
    pub fn resolve_path(command: &str, path: &str) -> Option<Param> {
        if !crate::CommandId::from_vk_name(command).is_none_or(|c| c.is_trace()) {
            return None;
        }
        let p = path.trim().trim_matches('`').to_ascii_lowercase();
        let khr = command != "vkCmdTraceRaysNV";
        for t in Table::ALL {
            if khr {
                let stem = t.khr_param().to_ascii_lowercase();
                if let Some(member) = p.strip_prefix(&stem) {
                    let member = member
                        .trim_start_matches("->")
                        .trim_start_matches("::")
                        .trim_start_matches('.');
                    return match member {
                        "deviceaddress" => Some(Param::TableAddress(t)),
                        "stride" => Some(Param::TableStride(t)),
                        "size" => Some(Param::TableSize(t)),
                        _ => None,
                    };
                }
            } else {
                let stem = t.nv_stem().to_ascii_lowercase();
                if let Some(member) = p.strip_prefix(&stem) {
                    return match member {
                        "offset" => Some(Param::TableAddress(t)),
                        "stride" => Some(Param::TableStride(t)),
                        _ => None,
                    };
                }
            }
        }
        match p.as_str() {
            "indirectdeviceaddress" if command == "vkCmdTraceRaysIndirectKHR" => {
                Some(Param::IndirectAddress)
            }
            "width" if command != "vkCmdTraceRaysIndirectKHR" => Some(Param::Dimension(0)),
            "height" if command != "vkCmdTraceRaysIndirectKHR" => Some(Param::Dimension(1)),
            "depth" if command != "vkCmdTraceRaysIndirectKHR" => Some(Param::Dimension(2)),
            _ => None,
        }
    }

    /// The numeric value of a parameter (addresses as their alignment-relevant part).
    pub fn value(&self, p: Param) -> u64 {
        match (self, p) {
            (Call::TraceRaysNv(_), Param::TableAddress(t)) => {
                self.nv_table(t).map_or(0, |n| n.offset)
            }
            (Call::TraceRaysNv(_), Param::TableStride(t)) => {
                self.nv_table(t).map_or(0, |n| n.stride)
            }
            (Call::TraceRaysNv(_), Param::TableSize(_)) => 0,
            (_, Param::TableAddress(t)) => {
                self.region(t).map_or(0, |r| r.address.alignment_value())
            }
            (_, Param::TableStride(t)) => self.region(t).map_or(0, |r| r.stride),
            (_, Param::TableSize(t)) => self.region(t).map_or(0, |r| r.size),
            (Call::TraceRaysIndirect(c), Param::IndirectAddress) => {
                c.indirect_address.alignment_value()
            }
            (_, Param::IndirectAddress) => 0,
            (Call::TraceRays(c), Param::Dimension(i)) => {
                [c.width, c.height, c.depth][i as usize] as u64
            }
            (Call::TraceRaysNv(c), Param::Dimension(i)) => {
                [c.width, c.height, c.depth][i as usize] as u64
            }
            (Call::TraceRaysIndirect(_), Param::Dimension(_)) => 0,
        }
    }

    /// The address a parameter holds, when it is one (KHR regions, the indirect address).
    pub fn address(&self, p: Param) -> Option<&Address> {
        match (self, p) {
            (Call::TraceRaysIndirect(c), Param::IndirectAddress) => Some(&c.indirect_address),
            (_, Param::TableAddress(t)) => self.region(t).map(|r| &r.address),
            _ => None,
        }
    }

    /// The buffer a parameter's address points into, when it names one that exists in the world.
    pub fn buffer_of<'w>(&self, world: &'w World, p: Param) -> Option<&'w crate::world::Buffer> {
        match self {
            Call::TraceRaysNv(_) => match p {
                Param::TableAddress(t) => world.buffer(self.nv_table(t)?.buffer.as_deref()?),
                _ => None,
            },
            _ => world.buffer(self.address(p)?.buffer()?.0),
        }
    }

    /// The three launch dimensions as the device will see them; for the indirect call, read from the
    /// memory image (None when the indirect address holds no command the world describes).
    pub fn dimensions(&self, world: &World) -> Option<[u32; 3]> {
        match self {
            Call::TraceRays(c) => Some([c.width, c.height, c.depth]),
            Call::TraceRaysNv(c) => Some([c.width, c.height, c.depth]),
            Call::TraceRaysIndirect(c) => {
                let (b, off) = c.indirect_address.buffer()?;
                world.indirect_command_at(b, off)
            }
        }
    }

    /// The display path of a parameter, as a context for violations.
    pub fn param_path(&self, p: Param) -> String {
        let nv = matches!(self, Call::TraceRaysNv(_));
        match p {
            Param::TableAddress(t) if nv => format!("{}Offset", t.nv_stem()),
            Param::TableStride(t) if nv => format!("{}Stride", t.nv_stem()),
            Param::TableSize(t) if nv => format!("{}Size", t.nv_stem()),
            Param::TableAddress(t) => format!("{}->deviceAddress", t.khr_param()),
            Param::TableStride(t) => format!("{}->stride", t.khr_param()),
            Param::TableSize(t) => format!("{}->size", t.khr_param()),
            Param::IndirectAddress => "indirectDeviceAddress".into(),
            Param::Dimension(i) => ["width", "height", "depth"][i as usize].into(),
        }
    }
}
