//! The world a call is made in: enabled device state, buffers and their memory, the bound ray tracing
//! pipeline, the command buffer's state, the scene the rays see, and what the shaders do.
//!
//! Everything is symbolic so a case means the same on every device: buffers are named, addresses are
//! a buffer plus an offset, shader group handles are group indices. The harness resolves them.

use crate::flags::{BufferCreate, BufferUsage, PipelineCreate, QueueFlags};
use crate::scene::{Ray, RayFlags, Scene};
use crate::tracer::AnyHitRule;
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
        /// What the any-hit shader does with a candidate (when the group has one).
        #[serde(default, skip_serializing_if = "is_default")]
        any_hit_rule: AnyHitRule,
    },
    ProceduralHit {
        #[serde(default)]
        closest_hit: bool,
        #[serde(default)]
        any_hit: bool,
        #[serde(default, skip_serializing_if = "is_default")]
        any_hit_rule: AnyHitRule,
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
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, serde::Serialize, serde::Deserialize,
)]
#[serde(rename_all = "kebab-case")]
pub enum GeometryKind {
    Triangles,
    Aabbs,
}

impl GeometryKind {
    /// The kind of a scene geometry.
    pub fn of(data: &crate::scene::GeometryData) -> GeometryKind {
        match data {
            crate::scene::GeometryData::Triangles(_) => GeometryKind::Triangles,
            crate::scene::GeometryData::Aabbs(_) => GeometryKind::Aabbs,
        }
    }
}

/// A pinhole camera: launch-ray `(i, j)` of a `width`×`height` grid (x fastest) starts at `eye` with
/// direction `forward + x·right + y·up`, `x = 2(i + ½)/width − 1`, `y = 1 − 2(j + ½)/height`, evaluated
/// in f64 and rounded once to f32 (only additions and multiplications: the same bits on every
/// machine). The other fields are every camera ray's `traceRayEXT` parameters.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Camera {
    pub eye: [f32; 3],
    pub forward: [f32; 3],
    pub right: [f32; 3],
    pub up: [f32; 3],
    pub width: u32,
    pub height: u32,
    #[serde(default)]
    pub tmin: f32,
    /// `+inf` is allowed (`.inf` in YAML).
    pub tmax: f32,
    #[serde(default, skip_serializing_if = "is_default")]
    pub flags: RayFlags,
    #[serde(default = "full_mask_u32")]
    pub cull_mask: u32,
    #[serde(default, skip_serializing_if = "is_default")]
    pub sbt_offset: u32,
    #[serde(default, skip_serializing_if = "is_default")]
    pub sbt_stride: u32,
    #[serde(default, skip_serializing_if = "is_default")]
    pub miss_index: u32,
}

impl Camera {
    /// The camera's rays, x fastest.
    pub fn rays(&self) -> Vec<Ray> {
        let f = self.forward.map(|x| x as f64);
        let r = self.right.map(|x| x as f64);
        let u = self.up.map(|x| x as f64);
        let (w, h) = (self.width.max(1) as f64, self.height.max(1) as f64);
        let mut out = Vec::with_capacity(self.width as usize * self.height as usize);
        for j in 0..self.height {
            for i in 0..self.width {
                let x = 2.0 * (i as f64 + 0.5) / w - 1.0;
                let y = 1.0 - 2.0 * (j as f64 + 0.5) / h;
                let direction = [0, 1, 2].map(|k| (f[k] + x * r[k] + y * u[k]) as f32);
                out.push(Ray {
                    origin: self.eye,
                    direction,
                    tmin: self.tmin,
                    tmax: self.tmax,
                    flags: self.flags,
                    cull_mask: self.cull_mask,
                    sbt_offset: self.sbt_offset,
                    sbt_stride: self.sbt_stride,
                    miss_index: self.miss_index,
                });
            }
        }
        out
    }
}

/// What the shaders of a launch do: launch ID `i` (x fastest) traces ray `i % n` of
/// [`Launch::ray_list`] (the explicit rays, then the camera's) into the scene and writes its
/// `RayRecord` (`crate::tracer::record`).
#[derive(Debug, Clone, PartialEq, Default, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Launch {
    /// The bottom levels and the top level's instances.
    #[serde(default, skip_serializing_if = "scene_is_empty")]
    pub scene: Scene,
    /// Explicit rays, uploaded as they are.
    #[serde(default, skip_serializing_if = "Vec::is_empty", with = "crate::bulk")]
    pub rays: Vec<Ray>,
    /// Camera rays, after the explicit ones.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub camera: Option<Camera>,
    /// Callable shader records executed by each launch (`executeCallableEXT` indices).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub callables: Vec<u32>,
    /// How many more times each closest-hit shader traces again (the harness's closest-hit traces the
    /// same ray while its depth is at most this): 0, raygen's traces only.
    #[serde(default, skip_serializing_if = "is_default")]
    pub extra_recursion: u32,
    /// The scene references a cluster acceleration structure (VK_NV_cluster_acceleration_structure).
    #[serde(default, skip_serializing_if = "is_default")]
    pub cluster_structures: bool,
}

fn scene_is_empty(s: &Scene) -> bool {
    s.bottom_levels.is_empty() && s.instances.is_empty()
}

impl Launch {
    /// The deepest recursion depth the launch's shaders can reach (the specification's "Ray Tracing"
    /// chapter: shaders invoked from the API have depth 0, each shader a pipeline trace ray instruction
    /// executes one more than its invoker; callable shaders add none): 1 when raygen traces, 1 +
    /// `extra_recursion` when closest-hit shaders trace again. What a launch reaches is
    /// [`crate::semantics::recursion_depth`], which also asks whether a closest-hit runs.
    pub fn recursion_depth(&self) -> u32 {
        if !self.traces() {
            0
        } else {
            1u32.saturating_add(self.extra_recursion)
        }
    }

    /// Whether any ray is traced (the raygen then has the scene bound).
    pub fn traces(&self) -> bool {
        !self.rays.is_empty()
            || self
                .camera
                .as_ref()
                .is_some_and(|c| c.width > 0 && c.height > 0)
    }

    /// Every ray of the launch: the explicit ones, then the camera's.
    pub fn ray_list(&self) -> Vec<Ray> {
        let mut v = self.rays.clone();
        if let Some(c) = &self.camera {
            v.extend(c.rays());
        }
        v
    }

    /// The number of rays in [`Launch::ray_list`].
    pub fn ray_count(&self) -> usize {
        self.rays.len()
            + self
                .camera
                .as_ref()
                .map_or(0, |c| c.width as usize * c.height as usize)
    }

    /// The rays a launch of `ids` launch IDs traces (the first `min(ids, n)` of the list; all of them
    /// when the launch size is not known).
    pub fn traced_rays(&self, ids: Option<usize>) -> Vec<Ray> {
        let mut v = self.ray_list();
        if let Some(n) = ids {
            v.truncate(n);
        }
        v
    }

    /// The path of ray `i` of [`Launch::ray_list`] in a case file.
    pub fn ray_path(&self, i: usize) -> String {
        if i < self.rays.len() {
            format!("world.launch.rays[{i}]")
        } else {
            format!("world.launch.camera (ray {})", i - self.rays.len())
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
fn full_mask_u32() -> u32 {
    0xff
}
