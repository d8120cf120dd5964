//! The world a call is made in: enabled device state, buffers and their memory, the bound ray tracing
//! pipeline, the command buffer's state, the scene the rays see, and what the shaders do.
//!
//! Everything is symbolic so a case means the same on every device: buffers are named, addresses are
//! a buffer plus an offset, shader group handles are group indices. The harness resolves them.

use crate::flags::{BufferCreate, BufferUsage, PipelineCreate, QueueFlags};
use std::collections::BTreeSet;

/// The device as the case enables it (a subset of what its profile reports).
#[derive(Debug, Clone, PartialEq, Default, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DeviceState {
    /// Enabled device extensions.
    #[serde(default)]
    pub extensions: BTreeSet<String>,
    /// Enabled features, by member name (`rayTracingPipelineTraceRaysIndirect`).
    #[serde(default)]
    pub features: BTreeSet<String>,
}

impl DeviceState {
    pub fn feature(&self, name: &str) -> bool {
        self.features.contains(name)
    }
    pub fn extension(&self, name: &str) -> bool {
        self.extensions.contains(name)
    }
}

/// How a buffer's memory is bound.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum MemoryBinding {
    /// Bound completely and contiguously to one `VkDeviceMemory`.
    #[default]
    Whole,
    /// Not bound to any memory.
    Unbound,
    /// Sparse buffer whose pages are bound to several memory objects.
    Scattered,
}

/// A `VkBuffer` and what the rules need to know of it.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Buffer {
    pub name: String,
    pub size: u64,
    pub usage: BufferUsage,
    #[serde(default, skip_serializing_if = "is_default")]
    pub flags: BufferCreate,
    #[serde(default, skip_serializing_if = "is_default")]
    pub memory: MemoryBinding,
    /// What the buffer holds, as writes at offsets (later writes win where they overlap).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub contents: Vec<Contents>,
}

impl Buffer {
    pub fn is_sparse(&self) -> bool {
        self.flags
            .intersects(BufferCreate::SPARSE_BINDING_BIT | BufferCreate::SPARSE_RESIDENCY_BIT)
    }
}

/// A shader group handle as written into a shader binding table.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum HandleRef {
    /// The handle of group `n` of the bound pipeline.
    Group(u32),
    /// All zero bytes: a "zero group".
    Zero,
    /// The handle of group `n` of a different pipeline (never queried from the bound one).
    Foreign(u32),
}

/// A write into a buffer's memory image.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields)]
pub enum Contents {
    /// Shader group handles, record `i` at `offset + i * stride`.
    ShaderRecords {
        offset: u64,
        stride: u64,
        handles: Vec<HandleRef>,
    },
    /// A `VkTraceRaysIndirectCommandKHR` at `offset`.
    TraceRaysIndirectCommand {
        offset: u64,
        width: u32,
        height: u32,
        depth: u32,
    },
}

/// The stage of a general shader group.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum GeneralStage {
    Raygen,
    Miss,
    Callable,
}

/// One shader group of a ray tracing pipeline.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields)]
pub enum ShaderGroup {
    General {
        stage: GeneralStage,
    },
    TrianglesHit {
        #[serde(default)]
        closest_hit: bool,
        #[serde(default)]
        any_hit: bool,
    },
    ProceduralHit {
        #[serde(default)]
        closest_hit: bool,
        #[serde(default)]
        any_hit: bool,
        intersection: bool,
    },
}

/// Which extension created the pipeline.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum PipelineApi {
    #[default]
    Khr,
    Nv,
}

/// The ray tracing pipeline bound at `VK_PIPELINE_BIND_POINT_RAY_TRACING_KHR`.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Pipeline {
    #[serde(default, skip_serializing_if = "is_default")]
    pub api: PipelineApi,
    #[serde(default, skip_serializing_if = "is_default")]
    pub flags: PipelineCreate,
    pub groups: Vec<ShaderGroup>,
    pub max_recursion_depth: u32,
    /// Created with `VK_DYNAMIC_STATE_RAY_TRACING_PIPELINE_STACK_SIZE_KHR`.
    #[serde(default, skip_serializing_if = "is_default")]
    pub dynamic_stack_size: bool,
    /// `VkRayTracingPipelineClusterAccelerationStructureCreateInfoNV::allowClusterAccelerationStructure`.
    #[serde(default, skip_serializing_if = "is_default")]
    pub allow_cluster_acceleration_structures: bool,
}

/// Command buffer lifecycle state.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum CommandBufferLifecycle {
    Initial,
    #[default]
    Recording,
    Executable,
    Invalid,
}

/// Primary or secondary.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum CommandBufferLevel {
    #[default]
    Primary,
    Secondary,
}

/// The command buffer the call is recorded into.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CommandBufferState {
    #[serde(default, skip_serializing_if = "is_default")]
    pub level: CommandBufferLevel,
    #[serde(default, skip_serializing_if = "is_default")]
    pub lifecycle: CommandBufferLifecycle,
    /// Capabilities of the queue family its pool was created for.
    pub pool_queue: QueueFlags,
    #[serde(default, skip_serializing_if = "is_default")]
    pub protected: bool,
    #[serde(default, skip_serializing_if = "is_default")]
    pub in_render_pass: bool,
    #[serde(default, skip_serializing_if = "is_default")]
    pub in_video_coding: bool,
    /// Whether `world.pipeline` is bound (false: nothing bound at the ray tracing bind point).
    #[serde(default = "yes", skip_serializing_if = "is_true")]
    pub pipeline_bound: bool,
    /// Whether `vkCmdSetRayTracingPipelineStackSizeKHR` was recorded after binding.
    #[serde(default, skip_serializing_if = "is_default")]
    pub stack_size_set: bool,
    /// Recorded between suspended render pass instances (dynamic rendering with SUSPENDING/RESUMING).
    #[serde(default, skip_serializing_if = "is_default")]
    pub between_suspended_render_passes: bool,
}

impl Default for CommandBufferState {
    fn default() -> Self {
        CommandBufferState {
            level: CommandBufferLevel::Primary,
            lifecycle: CommandBufferLifecycle::Recording,
            pool_queue: QueueFlags::GRAPHICS_BIT
                | QueueFlags::COMPUTE_BIT
                | QueueFlags::TRANSFER_BIT,
            protected: false,
            in_render_pass: false,
            in_video_coding: false,
            pipeline_bound: true,
            stack_size_set: false,
            between_suspended_render_passes: false,
        }
    }
}

/// Geometry kind of one geometry of a bottom-level structure.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum GeometryKind {
    Triangles,
    Aabbs,
}

/// One instance of the scene's top-level structure; geometry `g` of instance `i` sits at (2g, 4i, 0)
/// in the harness's layout, so rays can aim at exactly one.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Instance {
    pub geometries: Vec<GeometryKind>,
    /// `instanceShaderBindingTableRecordOffset` (24 bits).
    #[serde(default)]
    pub sbt_record_offset: u32,
    #[serde(default = "full_mask")]
    pub mask: u8,
    /// The instance references a cluster acceleration structure (VK_NV_cluster_acceleration_structure).
    #[serde(default, skip_serializing_if = "is_default")]
    pub cluster: bool,
}

/// What a ray traced by the raygen shader aims at.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum RayTarget {
    /// Nothing: the ray misses.
    Nothing,
    /// Geometry `geometry` of instance `instance`.
    Geometry { instance: u32, geometry: u32 },
}

/// The parameters of one `traceRayEXT` call in the raygen shader.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TraceRay {
    pub target: RayTarget,
    #[serde(default)]
    pub sbt_offset: u32,
    #[serde(default)]
    pub sbt_stride: u32,
    #[serde(default)]
    pub miss_index: u32,
    #[serde(default = "full_mask_u32")]
    pub cull_mask: u32,
    #[serde(default)]
    pub ray_flags: u32,
}

/// What the shaders of a launch do: each launch ID traces ray `id % rays.len()`.
#[derive(Debug, Clone, PartialEq, Default, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Launch {
    #[serde(default)]
    pub instances: Vec<Instance>,
    #[serde(default)]
    pub rays: Vec<TraceRay>,
    /// Callable shader records executed by each launch (`executeCallableEXT` indices).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub callables: Vec<u32>,
    /// Deepest recursion a shader call is made from (1: raygen traces; 2: closest-hit traces again).
    #[serde(default, skip_serializing_if = "is_default")]
    pub extra_recursion: u32,
}

impl Launch {
    /// The recursion depth of the deepest shader call: raygen's `traceRayEXT` is depth 1.
    pub fn recursion_depth(&self) -> u32 {
        if self.rays.is_empty() && self.callables.is_empty() {
            0
        } else {
            self.extra_recursion.saturating_add(1)
        }
    }
}

/// Everything a call is made in.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct World {
    pub device: DeviceState,
    #[serde(default)]
    pub buffers: Vec<Buffer>,
    pub pipeline: Option<Pipeline>,
    #[serde(default)]
    pub command_buffer: CommandBufferState,
    #[serde(default)]
    pub launch: Launch,
    /// Descriptors, views, samplers, push constants and the shaders' resource use.
    #[serde(
        default,
        skip_serializing_if = "crate::resources::ResourceState::is_empty"
    )]
    pub resources: crate::resources::ResourceState,
}

impl World {
    pub fn buffer(&self, name: &str) -> Option<&Buffer> {
        self.buffers.iter().find(|b| b.name == name)
    }

    /// The pipeline bound at the ray tracing bind point, if any. A command buffer in the initial state
    /// has recorded nothing since it was allocated or reset, so nothing is bound in it.
    pub fn bound_pipeline(&self) -> Option<&Pipeline> {
        if self.command_buffer.pipeline_bound
            && self.command_buffer.lifecycle != CommandBufferLifecycle::Initial
        {
            self.pipeline.as_ref()
        } else {
            None
        }
    }

    /// The handle stored at `offset` of `buffer` (the last write covering it), if any write put one there.
    pub fn handle_at(&self, buffer: &str, offset: u64) -> Option<HandleRef> {
        let b = self.buffer(buffer)?;
        let mut found = None;
        for c in &b.contents {
            if let Contents::ShaderRecords {
                offset: base,
                stride,
                handles,
            } = c
            {
                if offset >= *base && *stride > 0 && (offset - base) % stride == 0 {
                    if let Some(h) = handles.get(((offset - base) / stride) as usize) {
                        found = Some(*h);
                    }
                } else if *stride == 0 && offset == *base {
                    found = handles.first().copied();
                }
            }
        }
        found
    }

    /// The `VkTraceRaysIndirectCommandKHR` stored at `offset` of `buffer`, if a write put one there.
    pub fn indirect_command_at(&self, buffer: &str, offset: u64) -> Option<[u32; 3]> {
        self.buffer(buffer)?
            .contents
            .iter()
            .rev()
            .find_map(|c| match c {
                Contents::TraceRaysIndirectCommand {
                    offset: o,
                    width,
                    height,
                    depth,
                } if *o == offset => Some([*width, *height, *depth]),
                _ => None,
            })
    }
}

fn is_default<T: Default + PartialEq>(v: &T) -> bool {
    *v == T::default()
}
fn is_true(v: &bool) -> bool {
    *v
}
fn yes() -> bool {
    true
}
fn full_mask() -> u8 {
    0xff
}
fn full_mask_u32() -> u32 {
    0xff
}
