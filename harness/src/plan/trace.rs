//! A trace case's plan: the world's buffers with their writes (bytes, and shader group handles named by
//! group), the pipeline, the scene, the harness's own buffers (output, rays, callables) with their
//! bytes and descriptor set, the command buffer's steps and the call's arguments — and what the
//! harness cannot realise, refused before anything is made.

use super::pipeline::PipelinePlan;
use super::scene::ScenePlan;
use super::{step_text, Step};
use crate::error::HarnessError;
use ash::vk;
use model::call::{Address, NvTable, StridedRegion};
use model::world::{CommandBufferLevel, Contents, HandleRef, MemoryBinding, PipelineApi, World};

/// Bytes of one ray record of the rays buffer (std430 `Ray` after a 16-byte header).
pub const RAY_RECORD_SIZE: usize = 64;

/// Why [`TracePlan::of`] (and so the call plan, `rtconf export` and replay's call list) refuses every
/// trace case.
pub const NOT_DESCRIBED: &str = "the call plan does not yet describe rendered-scene trace cases \
     (explicit and camera rays into bottom levels and instances, 28-word ray records); the harness runs \
     them from the case itself, but cannot export or list their calls";

/// A write into one of the world's buffers.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
pub enum BufferWrite {
    Bytes {
        offset: u64,
        bytes: Vec<u8>,
    },
    /// A shader group handle: of the case's pipeline (`Group`), of a second pipeline of the same
    /// description (`Foreign`), or zeros.
    Handle {
        offset: u64,
        handle: HandleRef,
    },
}

/// One of the world's buffers.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
pub struct BufferPlan {
    pub name: String,
    pub size: u64,
    /// `VkBufferUsageFlags` and `VkBufferCreateFlags`, as the case has them.
    pub usage: u32,
    pub flags: u32,
    pub memory: MemoryBinding,
    pub sparse: bool,
    /// In order: later writes win where they overlap.
    pub writes: Vec<BufferWrite>,
}

/// One binding of the harness's descriptor set.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub struct BindingPlan {
    pub binding: u32,
    /// `VkDescriptorType`.
    pub ty: i32,
    /// `VkShaderStageFlags`.
    pub stages: u32,
}

/// The harness's buffers: what the raygen reads and writes.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
pub struct IoPlan {
    /// Output words the buffer holds (at least one).
    pub output_words: usize,
    /// Fill the output with [`model::semantics::NOT_RUN`] first (cases that are read back).
    pub fill_output: bool,
    /// The rays buffer: `[count, capacity, extra recursion, 0]`, then one record per ray.
    pub rays: Vec<u8>,
    /// The callables buffer: `[count, 0, 0, 0]`, then the callable record indices.
    pub callables: Vec<u8>,
}

/// The call's arguments, with symbolic addresses.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub enum TraceCall {
    TraceRays {
        regions: [StridedRegion; 4],
        dims: [u32; 3],
    },
    TraceRaysIndirect {
        regions: [StridedRegion; 4],
        indirect: Address,
    },
    TraceRaysNv {
        tables: [NvTable; 4],
        dims: [u32; 3],
    },
}

/// A trace case's plan.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct TracePlan {
    /// The API of the pipeline (and so of the scene and descriptor types).
    pub api: PipelineApi,
    /// The launch traces rays: the scene is built and bound at binding 0.
    pub traces: bool,
    pub buffers: Vec<BufferPlan>,
    pub pipeline: Option<PipelinePlan>,
    /// A second pipeline of the same description is made for `Foreign` handles.
    pub foreign_pipeline: bool,
    pub scene: Option<ScenePlan>,
    pub bindings: Vec<BindingPlan>,
    pub io: IoPlan,
    /// The secondary level records the call.
    pub level: CommandBufferLevel,
    pub in_render_pass: bool,
    pub steps: Vec<Step>,
    pub call: TraceCall,
    /// The world has a resource state (descriptors, images, samplers, push constants): realised by
    /// `realise::resources`, outside this plan.
    pub resources: bool,
    /// Words the launch writes (its dimensions' product; 0 when unknown).
    pub launch_words: usize,
}

/// The harness's descriptor bindings: 1 the output, 2 the rays, 3 the callable indices, and, when the
/// launch traces, 0 the scene (a KHR or NV structure by `api`), also read by the closest-hit shaders,
/// which trace their ray again.
pub fn harness_bindings(traces: bool, api: PipelineApi) -> Vec<BindingPlan> {
    let raygen = vk::ShaderStageFlags::RAYGEN_KHR;
    let traced = if traces {
        raygen | vk::ShaderStageFlags::CLOSEST_HIT_KHR
    } else {
        raygen
    };
    let storage = vk::DescriptorType::STORAGE_BUFFER.as_raw();
    let mut b = vec![
        BindingPlan {
            binding: 1,
            ty: storage,
            stages: raygen.as_raw(),
        },
        BindingPlan {
            binding: 2,
            ty: storage,
            stages: traced.as_raw(),
        },
        BindingPlan {
            binding: 3,
            ty: storage,
            stages: raygen.as_raw(),
        },
    ];
    if traces {
        let ty = match api {
            PipelineApi::Khr => vk::DescriptorType::ACCELERATION_STRUCTURE_KHR,
            PipelineApi::Nv => vk::DescriptorType::ACCELERATION_STRUCTURE_NV,
        };
        b.push(BindingPlan {
            binding: 0,
            ty: ty.as_raw(),
            stages: traced.as_raw(),
        });
    }
    b
}

/// The writes of one buffer's contents.
fn writes(contents: &[Contents]) -> Vec<BufferWrite> {
    let mut out = Vec::new();
    for c in contents {
        match c {
            Contents::ShaderRecords {
                offset,
                stride,
                handles,
            } => {
                for (i, h) in handles.iter().enumerate() {
                    // A record past u64::MAX lies past the end of the buffer: nothing is written.
                    let Some(at) = (i as u64)
                        .checked_mul(*stride)
                        .and_then(|d| d.checked_add(*offset))
                    else {
                        break;
                    };
                    out.push(BufferWrite::Handle {
                        offset: at,
                        handle: *h,
                    });
                }
            }
            Contents::TraceRaysIndirectCommand {
                offset,
                width,
                height,
                depth,
            } => {
                let bytes = [width, height, depth]
                    .iter()
                    .flat_map(|v| v.to_le_bytes())
                    .collect();
                out.push(BufferWrite::Bytes {
                    offset: *offset,
                    bytes,
                });
            }
        }
    }
    out
}

/// The plans of a world's buffers: their sizes, usage and create flags, memory binding and writes.
pub fn buffer_plans(world: &World) -> Vec<BufferPlan> {
    world
        .buffers
        .iter()
        .map(|b| BufferPlan {
            name: b.name.clone(),
            size: b.size,
            usage: b.usage.0 as u32,
            flags: b.flags.0 as u32,
            memory: b.memory,
            sparse: b.is_sparse(),
            writes: writes(&b.contents),
        })
        .collect()
}

impl TracePlan {
    /// The plan of a trace case. Not described yet: a trace case's launch traces a rendered scene
    /// (bottom levels with their geometry, instances with transforms, explicit and camera rays, one
    /// [`model::tracer::record::RayRecord`] per launch ID), which this plan does not carry; the
    /// executor realises trace cases from the case itself ([`crate::execute`]), so every trace case
    /// is refused here with [`NOT_DESCRIBED`].
    pub fn of(_case: &model::TraceBody, _run_valid: bool) -> Result<TracePlan, HarnessError> {
        Err(HarnessError::NotRealised(NOT_DESCRIBED.into()))
    }

    /// Appends the plan's call sequence, as a person reads it.
    pub(crate) fn describe(&self, out: &mut Vec<String>) {
        let names = |v: Vec<String>| {
            if v.is_empty() {
                "0".to_string()
            } else {
                v.join(" | ")
            }
        };
        for b in &self.buffers {
            out.push(format!(
                "vkCreateBuffer `{}`: {} bytes, usage {}{}{}",
                b.name,
                b.size,
                names(model::flags::BufferUsage(b.usage as u64).names()),
                if b.flags != 0 {
                    format!(
                        ", flags {}",
                        names(model::flags::BufferCreate(b.flags as u64).names())
                    )
                } else {
                    String::new()
                },
                match b.memory {
                    MemoryBinding::Whole => "",
                    MemoryBinding::Unbound => ", no memory bound",
                    MemoryBinding::Scattered => ", bound to two memory objects",
                }
            ));
            for w in &b.writes {
                out.push(match w {
                    BufferWrite::Bytes { offset, bytes } => {
                        format!("  write {} bytes at offset {offset}", bytes.len())
                    }
                    BufferWrite::Handle { offset, handle } => format!(
                        "  write at offset {offset}: {}",
                        match handle {
                            HandleRef::Group(g) => format!("the handle of group {g}"),
                            HandleRef::Foreign(g) =>
                                format!("the handle of group {g} of a second, distinct pipeline"),
                            HandleRef::Zero => "a zero handle".into(),
                        }
                    ),
                });
            }
        }
        if let Some(p) = &self.pipeline {
            out.push(format!(
                "vkCreateRayTracingPipelines{}: {} stages, {} groups, maxRecursionDepth {}, flags {}{}",
                if p.api == PipelineApi::Nv { "NV" } else { "KHR" },
                p.stages.len(),
                p.groups.len(),
                p.max_recursion_depth,
                names(model::flags::PipelineCreate(p.flags as u64).names()),
                if p.dynamic_stack_size {
                    ", dynamic stack size"
                } else {
                    ""
                }
            ));
            if self.foreign_pipeline {
                out.push("vkCreateRayTracingPipelines: a second pipeline of the same description (for foreign handles)".into());
            }
        }
        if let Some(s) = &self.scene {
            out.push(format!(
                "build the scene: {} bottom-level structure(s), a top-level one of {} instance(s) (one submission)",
                s.bottoms.len(),
                s.instances.len()
            ));
        }
        out.push(format!(
            "vkCreateBuffer output ({} words), rays ({} bytes), callables ({} bytes); one descriptor set",
            self.io.output_words,
            self.io.rays.len(),
            self.io.callables.len()
        ));
        if self.resources {
            out.push(
                "the resource state: descriptor sets, images, samplers, push constants".into(),
            );
        }
        for s in &self.steps {
            if let Step::Call { .. } = s {
                out.push(format!("{}: {}", step_text(s), self.describe_call()));
            } else {
                out.push(step_text(s));
            }
        }
    }

    /// The call with its arguments.
    fn describe_call(&self) -> String {
        let addr = |a: &Address| match a {
            Address::Raw(0) => "0".to_string(),
            Address::Raw(v) => format!("{v:#x}"),
            Address::InBuffer { buffer, offset } => format!("`{buffer}`+{offset}"),
        };
        let region = |r: &StridedRegion| {
            format!(
                "{{{}, stride {}, size {}}}",
                addr(&r.address),
                r.stride,
                r.size
            )
        };
        match &self.call {
            TraceCall::TraceRays { regions, dims } => format!(
                "vkCmdTraceRaysKHR(raygen {}, miss {}, hit {}, callable {}, {}x{}x{})",
                region(&regions[0]),
                region(&regions[1]),
                region(&regions[2]),
                region(&regions[3]),
                dims[0],
                dims[1],
                dims[2]
            ),
            TraceCall::TraceRaysIndirect { regions, indirect } => format!(
                "vkCmdTraceRaysIndirectKHR(raygen {}, miss {}, hit {}, callable {}, indirect {})",
                region(&regions[0]),
                region(&regions[1]),
                region(&regions[2]),
                region(&regions[3]),
                addr(indirect)
            ),
            TraceCall::TraceRaysNv { tables, dims } => {
                let t = |t: &NvTable| {
                    format!(
                        "{{{}, offset {}, stride {}}}",
                        t.buffer
                            .as_deref()
                            .map_or("null".into(), |b| format!("`{b}`")),
                        t.offset,
                        t.stride
                    )
                };
                format!(
                    "vkCmdTraceRaysNV(raygen {}, miss {}, hit {}, callable {}, {}x{}x{})",
                    t(&tables[0]),
                    t(&tables[1]),
                    t(&tables[2]),
                    t(&tables[3]),
                    dims[0],
                    dims[1],
                    dims[2]
                )
            }
        }
    }
}
