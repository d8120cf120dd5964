//! The concrete, pre-layout description of a case (groups, launch, shader binding tables as records,
//! strides and layout knobs, dimensions) and its realisation into a model `World` and `Call`.
//!
//! Strategies resolve drawn indices into a [`Plan`]; mutations edit a plan (or the realised world);
//! [`realize`] lays the tables out at multiples of the profile's base alignment.

use crate::GenError;
use model::call::{NvTable, TraceRays, TraceRaysIndirect, TraceRaysNv};
use model::flags::{BufferUsage, PipelineCreate, QueueFlags};
use model::world::{
    Buffer, CommandBufferState, Contents, DeviceState, HandleRef, Launch, MemoryBinding, Pipeline,
    PipelineApi, ShaderGroup,
};
use model::CommandId;
use model::{Address, Call, DeviceProfile, StridedRegion, Table, World};

/// The device numbers a case is laid out with, read from the profile for the command's extension.
#[derive(Debug, Clone, PartialEq)]
pub struct Limits {
    pub handle_size: u64,
    /// What strides must be multiples of (KHR: handle alignment; NV: handle size).
    pub stride_align: u64,
    pub base_align: u64,
    pub max_stride: u64,
    pub max_recursion: u64,
    /// Per dimension: the most a dimension may be (KHR: count × size; NV: count).
    pub max_dim: [u64; 3],
    /// `maxRayDispatchInvocationCount` (KHR only).
    pub max_invocations: Option<u64>,
}

fn need(profile: &DeviceProfile, name: &str) -> Result<u64, GenError> {
    profile.limit(name).ok_or_else(|| GenError::MissingLimit {
        profile: profile.name.clone(),
        limit: name.to_string(),
    })
}

impl Limits {
    /// The numbers a trace command's case is laid out with (a build case has no trace plan).
    pub fn for_command(profile: &DeviceProfile, command: CommandId) -> Result<Limits, GenError> {
        let limits = Self::read(profile, command)?;
        if limits.max_stride < limits.min_stride() {
            return Err(GenError::Unsupported(format!(
                "profile `{}` reports a maximum shader group stride of {} bytes, below the {} a record takes (the handle size {} rounded up to the alignment {}): no shader binding table is valid on it",
                profile.name,
                limits.max_stride,
                limits.min_stride(),
                limits.handle_size,
                limits.stride_align
            )));
        }
        Ok(limits)
    }

    /// The profile's numbers as it reports them, each present.
    fn read(profile: &DeviceProfile, command: CommandId) -> Result<Limits, GenError> {
        if !command.is_trace() {
            return Err(GenError::Unsupported(format!(
                "{command} is not a trace command: its cases come from `generator::accel`"
            )));
        }
        if command.is_nv() {
            let s = "VkPhysicalDeviceRayTracingPropertiesNV::";
            let handle_size = need(profile, &format!("{s}shaderGroupHandleSize"))?;
            let mut max_dim = [0; 3];
            for (i, d) in max_dim.iter_mut().enumerate() {
                *d = need(
                    profile,
                    &format!("VkPhysicalDeviceLimits::maxComputeWorkGroupCount[{i}]"),
                )?;
            }
            Ok(Limits {
                handle_size,
                stride_align: handle_size,
                base_align: need(profile, &format!("{s}shaderGroupBaseAlignment"))?,
                max_stride: need(profile, &format!("{s}maxShaderGroupStride"))?,
                max_recursion: need(profile, &format!("{s}maxRecursionDepth"))?,
                max_dim,
                max_invocations: None,
            })
        } else {
            let s = "VkPhysicalDeviceRayTracingPipelinePropertiesKHR::";
            let mut max_dim = [0; 3];
            for (i, d) in max_dim.iter_mut().enumerate() {
                let count = need(
                    profile,
                    &format!("VkPhysicalDeviceLimits::maxComputeWorkGroupCount[{i}]"),
                )?;
                let size = need(
                    profile,
                    &format!("VkPhysicalDeviceLimits::maxComputeWorkGroupSize[{i}]"),
                )?;
                *d = count.saturating_mul(size);
            }
            Ok(Limits {
                handle_size: need(profile, &format!("{s}shaderGroupHandleSize"))?,
                stride_align: need(profile, &format!("{s}shaderGroupHandleAlignment"))?.max(1),
                base_align: need(profile, &format!("{s}shaderGroupBaseAlignment"))?.max(1),
                max_stride: need(profile, &format!("{s}maxShaderGroupStride"))?,
                max_recursion: need(profile, &format!("{s}maxRayRecursionDepth"))?,
                max_dim,
                max_invocations: Some(need(profile, &format!("{s}maxRayDispatchInvocationCount"))?),
            })
        }
    }

    /// The smallest valid stride: the handle size rounded up to the stride alignment.
    pub fn min_stride(&self) -> u64 {
        round_up(self.handle_size, self.stride_align)
    }

    /// The valid strides strategies choose from: the smallest, a few larger multiples, the maximum.
    pub fn stride_choices(&self) -> Vec<u64> {
        let min = self.min_stride();
        let mut v: Vec<u64> = (0..3)
            .map(|k| min + k * self.stride_align)
            .filter(|s| *s <= self.max_stride)
            .collect();
        let top = self.max_stride / self.stride_align * self.stride_align;
        if top >= min && !v.contains(&top) {
            v.push(top);
        }
        if v.is_empty() {
            v.push(min);
        }
        v
    }
}

pub fn round_up(v: u64, a: u64) -> u64 {
    if a <= 1 {
        v
    } else {
        v.div_ceil(a) * a
    }
}

/// One shader binding table before layout.
#[derive(Debug, Clone, PartialEq)]
pub struct TablePlan {
    /// The handle of each record; empty: the table is unused.
    pub records: Vec<HandleRef>,
    pub stride: u64,
    /// Bytes the region's size exceeds `records × stride` by (raygen: ignored, size is the stride).
    pub size_extra: u64,
    /// An explicit region size (mutations).
    pub size_override: Option<u64>,
    /// Bytes of base-aligned padding before the region.
    pub lead: u64,
    /// Bytes added to the aligned offset (mutations: misalignment).
    pub misalign: u64,
    /// Whether the table lives in a buffer of its own (`sbt-<table>`) rather than the shared `sbt`.
    pub separate: bool,
    /// An explicit size of the table's own buffer (mutations).
    pub buffer_size_override: Option<u64>,
}

impl TablePlan {
    pub fn unused() -> TablePlan {
        TablePlan {
            records: vec![],
            stride: 0,
            size_extra: 0,
            size_override: None,
            lead: 0,
            misalign: 0,
            separate: false,
            buffer_size_override: None,
        }
    }

    pub fn used(&self) -> bool {
        !self.records.is_empty()
    }
}

/// The indirect command's placement.
#[derive(Debug, Clone, PartialEq)]
pub struct IndirectPlan {
    /// Offset of the command (a multiple of 4 unless misaligned).
    pub offset: u64,
    pub misalign: u64,
    /// Bytes after the command.
    pub slack: u64,
    pub buffer_size_override: Option<u64>,
}

/// A case before layout.
#[derive(Debug, Clone, PartialEq)]
pub struct Plan {
    pub command: CommandId,
    pub device: DeviceState,
    pub command_buffer: CommandBufferState,
    pub groups: Vec<ShaderGroup>,
    pub flags: PipelineCreate,
    pub max_recursion_depth: u32,
    pub dynamic_stack_size: bool,
    pub launch: Launch,
    /// Raygen, miss, hit, callable.
    pub tables: [TablePlan; 4],
    /// Bytes after the last region of the shared buffer.
    pub sbt_tail: u64,
    pub dims: [u32; 3],
    pub indirect: IndirectPlan,
}

pub const SHARED_SBT: &str = "sbt";
pub const INDIRECT: &str = "indirect";

/// The name of a table's own buffer.
pub fn table_buffer(t: Table) -> String {
    format!("sbt-{}", table_word(t))
}

pub fn table_word(t: Table) -> &'static str {
    match t {
        Table::Raygen => "raygen",
        Table::Miss => "miss",
        Table::Hit => "hit",
        Table::Callable => "callable",
    }
}

fn sbt_usage() -> BufferUsage {
    BufferUsage::SHADER_BINDING_TABLE_BIT_KHR | BufferUsage::SHADER_DEVICE_ADDRESS_BIT
}

/// Where one table landed.
struct Placed {
    buffer: String,
    offset: u64,
    stride: u64,
    size: u64,
}

/// Lays a plan out and builds the world and the call.
pub fn realize(plan: &Plan, lim: &Limits) -> (World, Call) {
    let nv = plan.command.is_nv();
    let mut buffers: Vec<Buffer> = Vec::new();
    let mut shared = Buffer {
        name: SHARED_SBT.into(),
        size: 0,
        usage: sbt_usage(),
        flags: Default::default(),
        memory: MemoryBinding::Whole,
        contents: vec![],
    };
    let mut cursor = 0u64;
    let mut placed: [Option<Placed>; 4] = [None, None, None, None];
    for t in Table::ALL {
        let tp = &plan.tables[t as usize];
        if !tp.used() {
            continue;
        }
        let n = tp.records.len() as u64;
        let size = match (t, tp.size_override) {
            (_, Some(s)) => s,
            (Table::Raygen, None) => tp.stride,
            (_, None) => n * tp.stride + tp.size_extra,
        };
        // Bytes the region's records and size occupy from its offset; at least one stride, so the
        // buffer is never smaller than the stride (VkStridedDeviceAddressRegionKHR-size-04632).
        let extent = size
            .max((n - 1) * tp.stride + lim.handle_size)
            .max(tp.stride);
        let contents = |offset| Contents::ShaderRecords {
            offset,
            stride: tp.stride,
            handles: tp.records.clone(),
        };
        if tp.separate {
            let offset = tp.lead + tp.misalign;
            let bsize = tp.buffer_size_override.unwrap_or(offset + extent);
            buffers.push(Buffer {
                name: table_buffer(t),
                size: bsize,
                usage: sbt_usage(),
                flags: Default::default(),
                memory: MemoryBinding::Whole,
                contents: vec![contents(offset)],
            });
            placed[t as usize] = Some(Placed {
                buffer: table_buffer(t),
                offset,
                stride: tp.stride,
                size,
            });
        } else {
            let offset = round_up(cursor, lim.base_align) + tp.lead + tp.misalign;
            // The next region starts past this one's records, so no write covers another table's record.
            cursor = offset + extent;
            shared.contents.push(contents(offset));
            placed[t as usize] = Some(Placed {
                buffer: SHARED_SBT.into(),
                offset,
                stride: tp.stride,
                size,
            });
        }
    }
    if !shared.contents.is_empty() {
        shared.size = cursor + plan.sbt_tail;
        buffers.insert(0, shared);
    }
    let dims = plan.dims;
    if plan.command == CommandId::TraceRaysIndirect {
        let ip = &plan.indirect;
        let offset = ip.offset + ip.misalign;
        buffers.push(Buffer {
            name: INDIRECT.into(),
            size: ip.buffer_size_override.unwrap_or(offset + 12 + ip.slack),
            usage: BufferUsage::INDIRECT_BUFFER_BIT | BufferUsage::SHADER_DEVICE_ADDRESS_BIT,
            flags: Default::default(),
            memory: MemoryBinding::Whole,
            contents: vec![Contents::TraceRaysIndirectCommand {
                offset,
                width: dims[0],
                height: dims[1],
                depth: dims[2],
            }],
        });
    }
    let region = |t: Table| match &placed[t as usize] {
        Some(p) => StridedRegion {
            address: Address::InBuffer {
                buffer: p.buffer.clone(),
                offset: p.offset,
            },
            stride: p.stride,
            size: p.size,
        },
        None => StridedRegion::unused(),
    };
    let nv_table = |t: Table| match &placed[t as usize] {
        Some(p) => NvTable {
            buffer: Some(p.buffer.clone()),
            offset: p.offset,
            stride: if t == Table::Raygen { 0 } else { p.stride },
        },
        None => NvTable {
            buffer: None,
            offset: 0,
            stride: 0,
        },
    };
    let call = match plan.command {
        CommandId::TraceRaysIndirect => Call::TraceRaysIndirect(TraceRaysIndirect {
            raygen: region(Table::Raygen),
            miss: region(Table::Miss),
            hit: region(Table::Hit),
            callable: region(Table::Callable),
            indirect_address: Address::InBuffer {
                buffer: INDIRECT.into(),
                offset: plan.indirect.offset + plan.indirect.misalign,
            },
        }),
        CommandId::TraceRays => Call::TraceRays(TraceRays {
            raygen: region(Table::Raygen),
            miss: region(Table::Miss),
            hit: region(Table::Hit),
            callable: region(Table::Callable),
            width: dims[0],
            height: dims[1],
            depth: dims[2],
        }),
        CommandId::TraceRaysNv => Call::TraceRaysNv(TraceRaysNv {
            raygen: nv_table(Table::Raygen),
            miss: nv_table(Table::Miss),
            hit: nv_table(Table::Hit),
            callable: nv_table(Table::Callable),
            width: dims[0],
            height: dims[1],
            depth: dims[2],
        }),
        CommandId::BuildAccelerationStructuresIndirect => {
            unreachable!("trace plans are made for trace commands only (Limits::for_command)")
        }
    };
    let world = World {
        device: plan.device.clone(),
        buffers,
        pipeline: Some(Pipeline {
            api: if nv {
                PipelineApi::Nv
            } else {
                PipelineApi::Khr
            },
            flags: plan.flags,
            groups: plan.groups.clone(),
            max_recursion_depth: plan.max_recursion_depth,
            dynamic_stack_size: plan.dynamic_stack_size,
            allow_cluster_acceleration_structures: false,
        }),
        command_buffer: plan.command_buffer.clone(),
        launch: plan.launch.clone(),
        resources: Default::default(), // resource mutations add a state after layout
    };
    (world, call)
}

/// The queue families of a profile as flag sets (names the flags type does not know are dropped).
pub fn queue_families(profile: &DeviceProfile) -> Vec<QueueFlags> {
    profile
        .queue_families
        .iter()
        .map(|names| {
            let mut q = QueueFlags::empty();
            for n in names {
                if let Some(f) = QueueFlags::from_name(n) {
                    q.insert(f);
                }
            }
            q
        })
        .collect()
}

/// The device state a valid case enables: the features and extensions the command needs that the
/// profile has.
pub fn device_state(profile: &DeviceProfile, command: CommandId) -> DeviceState {
    let (features, extensions): (&[&str], &[&str]) = if command.is_nv() {
        (&[], &["VK_NV_ray_tracing"])
    } else {
        (
            &[
                "rayTracingPipeline",
                "rayTracingPipelineTraceRaysIndirect",
                "bufferDeviceAddress",
                "accelerationStructure",
            ],
            &[
                "VK_KHR_ray_tracing_pipeline",
                "VK_KHR_acceleration_structure",
                "VK_KHR_deferred_host_operations",
                "VK_KHR_buffer_device_address",
            ],
        )
    };
    DeviceState {
        features: features
            .iter()
            .filter(|f| profile.has_feature(f))
            .map(|f| f.to_string())
            .collect(),
        extensions: extensions
            .iter()
            .filter(|e| profile.has_extension(e))
            .map(|e| e.to_string())
            .collect(),
    }
}
