//! A trace case's plan: the world's buffers with their writes (bytes, and shader group handles named by
//! group), the pipeline, the rendered scene ([`ScenePlan`]), the harness's own buffers (ray records
//! pre-filled, rays, callables, spheres) with their bytes and descriptor set, the command buffer's
//! steps and the call's arguments — and what the harness cannot realise, refused before anything is
//! made. The trace executor realises this plan's scene, buffers and bytes.

use super::pipeline::PipelinePlan;
use super::scene::ScenePlan;
use super::Barrier;
use super::ShaderBody;
use super::{step_text, Step};
use crate::error::HarnessError;
use ash::vk;
use model::call::{Address, Call, NvTable, StridedRegion};
use model::flags::QueueFlags;
use model::tracer::record::RayRecord;
use model::world::{
    CommandBufferLevel, CommandBufferLifecycle, Contents, HandleRef, MemoryBinding, PipelineApi,
    World,
};

/// Bytes of one ray record of the rays buffer (std430 `Ray` after a 16-byte header).
pub const RAY_RECORD_SIZE: usize = 64;

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
    /// Launch IDs with a record in the output buffer (each [`RayRecord::WORDS`] words).
    pub records: usize,
    /// Output words the records binding covers: `records` records, at least one.
    pub output_words: usize,
    /// Fill every record with [`RayRecord::PREFILL`] first (cases that are read back).
    pub fill_output: bool,
    /// The rays buffer: `[count, capacity in launch IDs, extra recursion, 0]`, then per ray origin and
    /// tmin, direction and tmax (f32), SBT offset and stride, miss index, cull mask, flags (u32) and
    /// three zero words.
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
    /// The capabilities of the queue family of the command buffer's pool when it lacks compute: the
    /// device gets a queue of a family without compute, the command buffer comes from that family's
    /// pool and holds the call alone (None: the compute family's pool).
    pub pool_family: Option<QueueFlags>,
    /// The secondary level records the call.
    pub level: CommandBufferLevel,
    pub in_render_pass: bool,
    pub steps: Vec<Step>,
    pub call: TraceCall,
    /// The world has a resource state (descriptors, images, samplers, push constants): realised by
    /// `realise::resources`, outside this plan.
    pub resources: bool,
    /// Launch IDs of the call (its dimensions' product; 0 when unknown).
    pub launch_ids: usize,
    /// Buffers an NV call's tables name that the world lacks (an invalid case's handle that is no
    /// valid VkBuffer): each is created and destroyed before the call, which gets its handle.
    pub destroyed_buffers: Vec<String>,
}

/// Launch IDs are read back only up to this many output words.
pub const MAX_OUTPUT_WORDS: usize = crate::execute::MAX_OUTPUT_WORDS;

/// The harness's descriptor bindings: 1 the records (written by the raygen, counted into by the
/// any-hit and intersection shaders), 2 the rays, 3 the callable indices, 4 the spheres the
/// intersection shader reports, and, when the launch traces, 0 the scene (a KHR or NV structure by
/// `api`); the closest-hit reads the scene and the rays to trace its ray again.
pub fn harness_bindings(traces: bool, api: PipelineApi) -> Vec<BindingPlan> {
    let raygen = vk::ShaderStageFlags::RAYGEN_KHR;
    let traced = if traces {
        raygen | vk::ShaderStageFlags::CLOSEST_HIT_KHR
    } else {
        raygen
    };
    let any = vk::ShaderStageFlags::ANY_HIT_KHR;
    let isect = vk::ShaderStageFlags::INTERSECTION_KHR;
    let storage = vk::DescriptorType::STORAGE_BUFFER.as_raw();
    let binding = |binding: u32, stages: vk::ShaderStageFlags| BindingPlan {
        binding,
        ty: storage,
        stages: stages.as_raw(),
    };
    let mut b = vec![
        binding(1, raygen | any | isect),
        binding(2, traced),
        binding(3, raygen),
        binding(4, isect),
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

/// The scene's builds as a person reads them: one line per bottom-level build (its geometries) and
/// the top-level build (its instances).
fn describe_scene(s: &ScenePlan, out: &mut Vec<String>) {
    use super::scene::GeometryDataPlan;
    let (khr, nv) = (s.api == PipelineApi::Khr, s.api == PipelineApi::Nv);
    let build = if nv {
        "vkCmdBuildAccelerationStructureNV"
    } else {
        "vkCmdBuildAccelerationStructuresKHR"
    };
    out.push(format!(
        "vkCreateBuffer scene input ({} bytes), instances ({} records of 64 bytes){}",
        s.input.len(),
        s.instances.len(),
        if khr {
            "; vkCreateAccelerationStructureKHR per structure"
        } else {
            "; vkCreateAccelerationStructureNV per structure"
        }
    ));
    for (b, bl) in s.bottoms.iter().enumerate() {
        if !bl.built() {
            out.push(format!(
                "  bottom level {b}: no geometries, not built (referenced as 0)"
            ));
            continue;
        }
        let geoms: Vec<String> = bl
            .geometries
            .iter()
            .map(|g| {
                let mut names = Vec::new();
                if g.flags & vk::GeometryFlagsKHR::OPAQUE.as_raw() != 0 {
                    names.push("OPAQUE");
                }
                if g.flags & vk::GeometryFlagsKHR::NO_DUPLICATE_ANY_HIT_INVOCATION.as_raw() != 0 {
                    names.push("NO_DUPLICATE_ANY_HIT_INVOCATION");
                }
                let flags = if names.is_empty() {
                    String::new()
                } else {
                    format!(" ({})", names.join(" | "))
                };
                match g.data {
                    GeometryDataPlan::Triangles {
                        indices, transform, ..
                    } => format!(
                        "{} triangles{}{}{flags}",
                        g.primitive_count,
                        match indices {
                            Some((_, _, bits)) => format!(", u{bits} indices"),
                            None => String::new(),
                        },
                        if transform.is_some() {
                            ", 3x4 transform"
                        } else {
                            ""
                        },
                    ),
                    GeometryDataPlan::Aabbs { .. } => format!("{} AABBs{flags}", g.primitive_count),
                }
            })
            .collect();
        out.push(format!("{build}: bottom level {b}: {}", geoms.join("; ")));
    }
    let active = s.instances.iter().filter(|i| i.bottom.is_some()).count();
    out.push(format!(
        "{build}: top level of {} instance(s) ({active} active), after a barrier; one submission, waited for",
        s.instances.len()
    ));
}

/// The rays buffer's bytes: the header, then every ray of the launch as it is.
fn ray_bytes(world: &World, capacity: usize) -> Vec<u8> {
    let launch = &world.launch;
    let rays = if launch.traces() {
        launch.ray_list()
    } else {
        vec![]
    };
    let mut bytes: Vec<u8> = Vec::with_capacity(16 + rays.len() * RAY_RECORD_SIZE);
    for v in [
        rays.len() as u32,
        capacity as u32,
        launch.extra_recursion,
        0,
    ] {
        bytes.extend_from_slice(&v.to_le_bytes());
    }
    for r in &rays {
        let [ox, oy, oz] = r.origin;
        let [dx, dy, dz] = r.direction;
        let words = [
            ox.to_bits(),
            oy.to_bits(),
            oz.to_bits(),
            r.tmin.to_bits(),
            dx.to_bits(),
            dy.to_bits(),
            dz.to_bits(),
            r.tmax.to_bits(),
            r.sbt_offset,
            r.sbt_stride,
            r.miss_index,
            r.cull_mask,
            r.flags.0,
            0,
            0,
            0,
        ];
        // One record of RAY_RECORD_SIZE bytes, appended at once.
        let mut record = [0u8; RAY_RECORD_SIZE];
        for (at, w) in record.chunks_exact_mut(4).zip(words) {
            at.copy_from_slice(&w.to_le_bytes());
        }
        bytes.extend_from_slice(&record);
    }
    bytes
}

impl TracePlan {
    /// The plan of a trace case run as valid (`run_valid`: submitted and its records read back) or
    /// only recorded under the layer, or why the harness cannot realise it.
    pub fn of(case: &model::TraceBody, run_valid: bool) -> Result<TracePlan, HarnessError> {
        let world = &case.world;
        let cbs = &world.command_buffer;
        if cbs.in_video_coding || cbs.protected {
            return Err(HarnessError::NotRealised(
                "video coding scopes and protected command buffers are not realised by the harness yet"
                    .into(),
            ));
        }
        let pool_family =
            (!cbs.pool_queue.contains(QueueFlags::COMPUTE_BIT)).then_some(cbs.pool_queue);
        if pool_family.is_some() {
            if cbs.lifecycle == CommandBufferLifecycle::Invalid {
                return Err(HarnessError::NotRealised(
                    "an invalid command buffer of a pool without compute is not realised: a buffer becomes invalid \
                     through a submission, and the harness submits only on its compute queue"
                        .into(),
                ));
            }
            // The command buffer comes from a pool of a family without compute, where nothing but the
            // call is recorded: the world is realised on the compute queue first, and every command the
            // harness records around a call needs compute or graphics in the pool's family.
            if run_valid {
                return Err(HarnessError::NotRealised(
                    "a command buffer of a pool without compute is never submitted: no trace command is valid in it (VUID-vkCmdTraceRaysKHR-commandBuffer-cmdpool)".into(),
                ));
            }
            if world.pipeline.is_some()
                && cbs.pipeline_bound
                && cbs.lifecycle != CommandBufferLifecycle::Initial
            {
                return Err(HarnessError::NotRealised(
                    "a pipeline bound in a pool without compute: binding a ray tracing pipeline needs compute in the pool's family (VUID-vkCmdBindPipeline-pipelineBindPoint-02391), so such a pool's case states nothing bound".into(),
                ));
            }
            if !world.resources.is_empty() {
                return Err(HarnessError::NotRealised(
                    "a resource state in a pool without compute: its descriptor binds need graphics or compute in the pool's family (VUID-vkCmdBindDescriptorSets-commandBuffer-cmdpool)".into(),
                ));
            }
            if cbs.in_render_pass {
                return Err(HarnessError::NotRealised(
                    "a render pass in a pool without compute is not realised: the harness begins its empty render pass only in its compute family's pool (a family without compute would need graphics, VUID-vkCmdBeginRenderPass-commandBuffer-cmdpool)".into(),
                ));
            }
        }
        if cbs.level == CommandBufferLevel::Secondary && cbs.in_render_pass {
            return Err(HarnessError::NotRealised(
                "secondary command buffers inside a render pass are not realised yet".into(),
            ));
        }
        super::refuse_ended_inside_render_pass(cbs)?;
        let nv_call = matches!(case.call, Call::TraceRaysNv(_));
        let traces = world.launch.traces();
        // What the case's device (exactly its extensions and features) cannot do, as the realisation
        // says it.
        let has_extension = |x: &str| world.device.extensions.contains(x);
        let has_feature = |n: &str| {
            world
                .device
                .features
                .iter()
                .any(|f| f == n || f.rsplit("::").next() == Some(n))
        };
        let not_realised = |why: &str| Err(HarnessError::NotRealised(why.into()));
        if nv_call && !has_extension("VK_NV_ray_tracing") {
            return not_realised(
                "the case does not enable VK_NV_ray_tracing, so vkCmdTraceRaysNV cannot be called",
            );
        }
        if !nv_call && !has_extension("VK_KHR_ray_tracing_pipeline") {
            return not_realised("the case does not enable VK_KHR_ray_tracing_pipeline, so vkCmdTraceRays*KHR cannot be called");
        }
        let launch_ids = case
            .call
            .dimensions(world)
            .map(|d| {
                d.iter()
                    .map(|&x| x as usize)
                    .fold(1usize, usize::saturating_mul)
            })
            .unwrap_or(0);
        if run_valid && launch_ids.saturating_mul(RayRecord::WORDS) > MAX_OUTPUT_WORDS {
            return Err(HarnessError::NotRealised(format!(
                "a launch of {launch_ids} IDs is larger than the harness reads back"
            )));
        }
        // Records for every launch ID the harness reads back (an invalid case is never submitted).
        let records = launch_ids.min(MAX_OUTPUT_WORDS / RayRecord::WORDS);
        // The scene and descriptor layout follow the pipeline's API (an NV pipeline reads an NV structure).
        let api = world.pipeline.as_ref().map_or(
            if nv_call {
                PipelineApi::Nv
            } else {
                PipelineApi::Khr
            },
            |p| p.api,
        );
        match world.pipeline.as_ref().map(|p| p.api) {
            Some(PipelineApi::Khr) if !has_extension("VK_KHR_ray_tracing_pipeline") => {
                return not_realised("the case does not enable VK_KHR_ray_tracing_pipeline, so no ray tracing pipeline can be made");
            }
            Some(PipelineApi::Nv) if !has_extension("VK_NV_ray_tracing") => {
                return not_realised("the case does not enable VK_NV_ray_tracing, so no NV ray tracing pipeline can be made");
            }
            _ => {}
        }
        let pipeline = world
            .pipeline
            .as_ref()
            .map(|p| PipelinePlan::of(p, traces, ShaderBody::for_run(run_valid)))
            .transpose()?;
        if traces {
            match api {
                PipelineApi::Nv if !has_extension("VK_NV_ray_tracing") => {
                    return not_realised(
                        "the case traces rays but does not enable VK_NV_ray_tracing",
                    );
                }
                PipelineApi::Khr if !has_extension("VK_KHR_acceleration_structure") => {
                    return not_realised(
                        "the case traces rays but does not enable VK_KHR_acceleration_structure",
                    );
                }
                PipelineApi::Khr
                    if !has_feature("accelerationStructure")
                        || !has_feature("bufferDeviceAddress") =>
                {
                    return not_realised("the case traces rays but does not enable accelerationStructure and bufferDeviceAddress");
                }
                _ => {}
            }
        }
        let buffers = buffer_plans(world);
        let foreign_pipeline = buffers.iter().any(|b| {
            b.writes.iter().any(|w| {
                matches!(
                    w,
                    BufferWrite::Handle {
                        handle: HandleRef::Foreign(_),
                        ..
                    }
                )
            })
        });
        let scene = traces.then(|| ScenePlan::of(&world.launch.scene, api));
        let read_back = run_valid
            && cbs.lifecycle == CommandBufferLifecycle::Recording
            && cbs.level == CommandBufferLevel::Primary
            && !cbs.in_render_pass;
        let callables: Vec<u8> = [world.launch.callables.len() as u32, 0, 0, 0]
            .iter()
            .chain(&world.launch.callables)
            .flat_map(|v| v.to_le_bytes())
            .collect();
        let io = IoPlan {
            records,
            output_words: (records * RayRecord::WORDS).max(RayRecord::WORDS),
            fill_output: read_back,
            rays: ray_bytes(world, records),
            callables,
        };
        let mut steps = Vec::new();
        if cbs.lifecycle != CommandBufferLifecycle::Initial {
            steps.push(Step::Begin {
                level: cbs.level,
                continue_render_pass: false,
            });
            // In a pool without compute nothing is recorded before the call: the barrier's stages, the
            // binds and the harness's descriptor set need compute there (the case is never submitted).
            let compute_pool = pool_family.is_none();
            if traces && compute_pool {
                // The scene was built by an earlier submission: a memory dependency from its build to
                // the shaders' reads (submission order alone gives only an execution dependency).
                // Recorded before any render pass begins, where a barrier would need a subpass
                // self-dependency.
                steps.push(Step::Barrier(Barrier::SceneBuildToShaders));
            }
            if !world.resources.is_empty() {
                steps.push(Step::ResourceTransitions);
            }
            if world.pipeline.is_some() && cbs.pipeline_bound {
                steps.push(Step::BindPipeline);
                if cbs.stack_size_set {
                    steps.push(Step::SetStackSize);
                }
            }
            if compute_pool {
                steps.push(Step::BindHarnessSet);
            }
            if !world.resources.is_empty() {
                steps.push(Step::ResourceBinds);
            }
            if cbs.in_render_pass {
                steps.push(Step::BeginRenderPass);
            }
            if matches!(
                cbs.lifecycle,
                CommandBufferLifecycle::Executable | CommandBufferLifecycle::Invalid
            ) {
                steps.push(Step::End);
            }
            if cbs.lifecycle == CommandBufferLifecycle::Invalid {
                steps.push(Step::SubmitToInvalidate);
            }
        }
        steps.push(Step::Call {
            dropped: !run_valid,
        });
        if read_back {
            steps.push(Step::Barrier(Barrier::ShaderWritesToHost));
            steps.push(Step::Submit);
            steps.push(Step::ReadBack {
                words: records * RayRecord::WORDS,
            });
        }
        // An NV table naming a buffer the world lacks: a handle that is not a valid VkBuffer, made by
        // destroying a buffer (the layer knows every handle it gave out; an invalid case's call is
        // dropped before the driver sees it). A valid case names none.
        let mut destroyed_buffers: Vec<String> = Vec::new();
        if let Call::TraceRaysNv(c) = &case.call {
            for name in [&c.raygen, &c.miss, &c.hit, &c.callable]
                .into_iter()
                .filter_map(|t| t.buffer.as_ref())
            {
                if !world.buffers.iter().any(|b| &b.name == name)
                    && !destroyed_buffers.contains(name)
                {
                    if run_valid {
                        return Err(HarnessError::NotRealised(format!(
                            "a valid call names buffer `{name}`, which the world lacks"
                        )));
                    }
                    destroyed_buffers.push(name.clone());
                }
            }
        }
        let call = match &case.call {
            Call::TraceRays(c) => TraceCall::TraceRays {
                regions: [
                    c.raygen.clone(),
                    c.miss.clone(),
                    c.hit.clone(),
                    c.callable.clone(),
                ],
                dims: [c.width, c.height, c.depth],
            },
            Call::TraceRaysIndirect(c) => TraceCall::TraceRaysIndirect {
                regions: [
                    c.raygen.clone(),
                    c.miss.clone(),
                    c.hit.clone(),
                    c.callable.clone(),
                ],
                indirect: c.indirect_address.clone(),
            },
            Call::TraceRaysNv(c) => TraceCall::TraceRaysNv {
                tables: [
                    c.raygen.clone(),
                    c.miss.clone(),
                    c.hit.clone(),
                    c.callable.clone(),
                ],
                dims: [c.width, c.height, c.depth],
            },
        };
        Ok(TracePlan {
            api,
            traces,
            buffers,
            pipeline,
            foreign_pipeline,
            scene,
            bindings: harness_bindings(traces, api),
            io,
            pool_family,
            level: cbs.level,
            in_render_pass: cbs.in_render_pass,
            steps,
            call,
            resources: !world.resources.is_empty(),
            launch_ids,
            destroyed_buffers,
        })
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
        for name in &self.destroyed_buffers {
            out.push(format!(
                "vkCreateBuffer `{name}`, then vkDestroyBuffer: the call gets a handle that is no longer valid"
            ));
        }
        if let Some(p) = &self.pipeline {
            out.push(format!(
                "vkCreateRayTracingPipelines{}: {} stages, {} groups, maxRecursionDepth {}, flags {}{}{}",
                if p.api == PipelineApi::Nv { "NV" } else { "KHR" },
                p.stages.len(),
                p.groups.len(),
                p.max_recursion_depth,
                names(model::flags::PipelineCreate(p.flags as u64).names()),
                if p.dynamic_stack_size {
                    ", dynamic stack size"
                } else {
                    ""
                },
                match p.body {
                    ShaderBody::Full => "",
                    ShaderBody::InterfaceOnly => ", interface-only shader bodies (never submitted)",
                }
            ));
            if self.foreign_pipeline {
                out.push("vkCreateRayTracingPipelines: a second pipeline of the same description (for foreign handles)".into());
            }
        }
        if let Some(s) = &self.scene {
            describe_scene(s, out);
        }
        out.push(format!(
            "vkCreateBuffer records ({} launch IDs of {} words{}), rays ({} bytes), callables ({} bytes), spheres ({} words); one descriptor set",
            self.io.records,
            RayRecord::WORDS,
            if self.io.fill_output { ", pre-filled" } else { "" },
            self.io.rays.len(),
            self.io.callables.len(),
            self.scene.as_ref().map_or(4, |s| s.spheres.len()),
        ));
        if self.resources {
            out.push(
                "the resource state: descriptor sets, images, samplers, push constants".into(),
            );
        }
        if let Some(q) = self.pool_family {
            out.push(format!(
                "vkCreateCommandPool of the device's queue family without compute for {} (the world above made on the compute queue); the command buffer from it",
                names(q.names())
            ));
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
