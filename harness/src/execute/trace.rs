//! The trace path: the world realised on the device for its enabled state (on its compute queue), the
//! command buffer — of the compute family's pool, or of a family without compute's where the case says
//! so — put in the case's state as the plan's steps say, the call recorded with the layer's messages
//! collected (dropped unless the case is run as valid), and a valid launch submitted and its ray
//! records read back.

use super::{failure, Executor};
use crate::error::HarnessError;
use crate::observe::{Observation, Output, Status};
use crate::plan::{Barrier, Step};
use crate::realise::{DeviceCache, Tlas, RAY_RECORD_SIZE};
use crate::shaders::ShaderBody;
use crate::timing::{span, Phase};
use crate::vk::commands::{begin_render_pass, memory_barrier, Commands};
use crate::vk::descriptors::{storage_write, structure_write, whole};
use crate::vk::memory::Allocation;
use ash::vk;
use model::call::{Address, Call, StridedRegion};
use model::tracer::record::RayRecord;
use model::world::{CommandBufferLevel, CommandBufferLifecycle};
use std::time::Duration;

pub(super) fn trace(ctx: &mut Executor, case: &model::TraceBody, run_valid: bool) -> Observation {
    // Resource states are realised by `crate::realise::resources`; what it cannot realise is unsupported
    // (running without it would show the layer a call that violates nothing).
    let layer_spec = ctx.inst.layer_build.map(|(spec, _)| spec);
    if let Some(why) = crate::realise::resources::unsupported(&case.world)
        .or_else(|| crate::realise::resources::unbound_set(&case.world, layer_spec))
    {
        return Observation::not_realised(why);
    }
    let timeout = ctx.gpu_timeout;
    let collector = ctx.inst.collector.clone();
    let cache = match ctx.device(&case.world, run_valid) {
        Ok(c) => c,
        Err(e) => return failure(e),
    };
    let mut buffers = Vec::new();
    let mut res: Option<crate::realise::resources::Realised> = None;
    let mut pool: Option<Commands> = None;
    let result = run(
        case,
        run_valid,
        cache,
        Made {
            buffers: &mut buffers,
            res: &mut res,
            pool: &mut pool,
        },
        timeout,
        &collector,
    );
    let lost = cache.lost;
    // A pool of a family without compute goes with its case (its command buffers were never submitted).
    if let Some(p) = pool.filter(|_| !lost) {
        p.destroy(&cache.dev);
    }
    // The case's resource objects (and its pipeline) go with the case; a lost device leaks them.
    match res {
        Some(r) if !lost => r.destroy(cache),
        _ => cache.resource_pipeline = None,
    }
    if !lost {
        // Nothing recorded is pending: valid cases waited, invalid ones were never submitted.
        // SAFETY: the command buffers are not in use by the GPU.
        unsafe {
            let _ = cache
                .dev
                .device
                .reset_command_buffer(cache.cmds.cb, vk::CommandBufferResetFlags::empty());
            let _ = cache
                .dev
                .device
                .reset_command_buffer(cache.cmds.secondary, vk::CommandBufferResetFlags::empty());
        }
        cache.give_back_case_buffers(buffers);
    }
    collector.set_abort(false);
    collector.clear();
    if lost {
        // Dropping a lost cache leaks its objects instead of waiting on the device.
        ctx.forget_device(&case.world, run_valid);
        collector.clear();
    }
    match result {
        Ok(obs) => obs,
        Err(e) => failure(e),
    }
}

/// A driver may refuse to create an object whose use the case states invalidly (a shader that fetches
/// through a Y′CbCr sampler fails vkCreateRayTracingPipelinesKHR on NVIDIA): the use is undefined
/// behaviour, so any result is the driver's to give. For a case run as invalid that means the call
/// cannot be recorded — not realised, with the driver's answer — not a crash; a valid case keeps the
/// failure.
fn refused_for_invalid_use(e: HarnessError, valid: bool) -> HarnessError {
    match e {
        HarnessError::Failed(m) if !valid && m.starts_with("vkCreate") => {
            HarnessError::NotRealised(format!(
                "the driver refused an object of this invalid case ({m}): the use the case states is \
                 undefined behaviour, so the call cannot be recorded"
            ))
        }
        e => e,
    }
}

fn region(
    r: &StridedRegion,
    addr: &dyn Fn(&Address) -> Result<u64, HarnessError>,
) -> Result<vk::StridedDeviceAddressRegionKHR, HarnessError> {
    Ok(vk::StridedDeviceAddressRegionKHR {
        device_address: addr(&r.address)?,
        stride: r.stride,
        size: r.size,
    })
}

/// What a case's run makes that its caller destroys afterwards, whether the run succeeded or not.
struct Made<'m> {
    buffers: &'m mut Vec<(String, Allocation)>,
    res: &'m mut Option<crate::realise::resources::Realised>,
    /// The pool of the device's family without compute, for a case whose pool's family lacks compute.
    pool: &'m mut Option<Commands>,
}

fn run(
    case: &model::TraceBody,
    valid: bool,
    cache: &mut DeviceCache,
    made: Made<'_>,
    timeout: Duration,
    collector: &crate::vk::Collector,
) -> Result<Observation, HarnessError> {
    let Made { buffers, res, pool } = made;
    let world = &case.world;
    let cbs = &world.command_buffer;
    let nv_call = matches!(case.call, Call::TraceRaysNv(_));
    if nv_call && cache.dev.nv.is_none() {
        return Err(HarnessError::NotRealised(
            "the case does not enable VK_NV_ray_tracing, so vkCmdTraceRaysNV cannot be called"
                .into(),
        ));
    }
    if !nv_call && cache.dev.rt.is_none() {
        return Err(HarnessError::NotRealised(
            "the case does not enable VK_KHR_ray_tracing_pipeline, so vkCmdTraceRays*KHR cannot be called".into(),
        ));
    }
    // What the device lacks (checked against its profile) before what the harness does not realise.
    if let Some(e) = super::unrealisable_command_buffer(&cache.dev.inst, cbs) {
        return Err(e);
    }
    // What the harness makes and records: the case's plan (its refusals come after the device's).
    let plan = crate::plan::TracePlan::of(case, valid)?;
    let _phase = span(Phase::Resources);
    let trace = plan.traces;
    let body = ShaderBody::for_run(valid);
    let api = plan.api;
    let words = plan.io.records * RayRecord::WORDS;
    let pipeline = world.pipeline.as_ref();
    // The resource state, and the case's pipeline with its templated raygen, before the shader binding
    // tables are filled with that pipeline's handles.
    if !world.resources.is_empty() {
        let harness_set = cache.layouts(trace, api)?.set;
        *res = Some(
            crate::realise::resources::Realised::new(cache, world, trace, body, harness_set)
                .map_err(|e| refused_for_invalid_use(e, valid))?,
        );
    }
    *buffers = cache.case_buffers(&plan.buffers, pipeline.map(|p| (p, trace, body)))?;
    let (tlas, spheres) = match &plan.scene {
        Some(scene) => {
            let _phase = span(Phase::Structures);
            // A case that is only recorded gets its top level made, not built (see `DeviceCache::scene`).
            let (t, s) = cache.scene(&world.launch.scene, scene, valid)?;
            (Some(t), Some(s))
        }
        None => (None, None),
    };
    let layouts = cache.layouts(trace, api)?;
    let (vk_pipeline, stack_size) = match pipeline {
        Some(p) => {
            let real = cache.pipeline(p, trace, body, false)?;
            (Some(real.pipeline), real.default_stack_size)
        }
        None => (None, 0),
    };
    let render_pass = if cbs.in_render_pass {
        Some(cache.empty_render_pass()?)
    } else {
        None
    };
    let ray_count = plan.io.rays.len().saturating_sub(16) / RAY_RECORD_SIZE;
    let callable_count = plan.io.callables.len().saturating_sub(16) / 4;
    cache.io_buffers(words, ray_count, callable_count)?;
    let set = cache.harness_set(layouts.set)?;
    let (out, rays, calls) = (
        cache.output.as_ref().expect("made above"),
        cache.rays.as_ref().expect("made above"),
        cache.callables.as_ref().expect("made above"),
    );
    // The plan's bytes: records pre-filled (outcome NOT_RUN) where they are read back, the rays
    // buffer, the callables.
    if plan.io.fill_output {
        let record: Vec<u8> = RayRecord::PREFILL
            .iter()
            .flat_map(|w| w.to_le_bytes())
            .collect();
        out.write_repeated(0, &record, plan.io.records);
    }
    rays.write(0, &plan.io.rays);
    calls.write(0, &plan.io.callables);

    let d = &cache.dev.device;
    let spheres = spheres.unwrap_or(cache.no_spheres.as_ref().expect("made above").buffer);
    // The records binding covers exactly the launch's records: the any-hit and intersection shaders
    // bound their writes by its length.
    let out_info = [vk::DescriptorBufferInfo {
        buffer: out.buffer,
        offset: 0,
        range: (words.max(RayRecord::WORDS) * 4) as u64,
    }];
    let (rays_info, calls_info, spheres_info) =
        (whole(rays.buffer), whole(calls.buffer), whole(spheres));
    let mut writes = vec![
        storage_write(set, 1, &out_info),
        storage_write(set, 2, &rays_info),
        storage_write(set, 3, &calls_info),
        storage_write(set, 4, &spheres_info),
    ];
    let tl_khr = [match tlas {
        Some(Tlas::Khr(t)) => t,
        _ => vk::AccelerationStructureKHR::null(),
    }];
    let tl_nv = [match tlas {
        Some(Tlas::Nv(t)) => t,
        _ => vk::AccelerationStructureNV::null(),
    }];
    let mut as_khr =
        vk::WriteDescriptorSetAccelerationStructureKHR::default().acceleration_structures(&tl_khr);
    let mut as_nv =
        vk::WriteDescriptorSetAccelerationStructureNV::default().acceleration_structures(&tl_nv);
    match tlas {
        Some(Tlas::Khr(_)) => writes.push(structure_write(
            set,
            0,
            vk::DescriptorType::ACCELERATION_STRUCTURE_KHR,
            &mut as_khr,
        )),
        Some(Tlas::Nv(_)) => writes.push(structure_write(
            set,
            0,
            vk::DescriptorType::ACCELERATION_STRUCTURE_NV,
            &mut as_nv,
        )),
        None => {}
    }
    // SAFETY: writes reference live objects; every binding of the layout is written.
    unsafe { d.update_descriptor_sets(&writes, &[]) };
    // A state whose descriptors come from descriptor buffers holds the harness's set in its descriptor
    // memory. Such a case is never submitted (every descriptor buffer world violates a rule), and the
    // scene's spheres buffer has no device address, so the spheres binding is the empty buffer's.
    if let Some(r) = res.as_ref().filter(|r| r.harness_set_in_buffer()) {
        if valid {
            return Err(HarnessError::NotRealised(
                "a valid launch through descriptor buffers is not realised: the scene's spheres buffer has no device address to write a descriptor of".into(),
            ));
        }
        let none = cache.no_spheres.as_ref().expect("made above");
        r.write_harness_set(
            &cache.dev,
            [
                (out.address, out_info[0].range),
                (rays.address, rays.size),
                (calls.address, calls.size),
                (none.address, none.size),
            ],
            tlas,
        )?;
    }

    // Addresses and buffers by name.
    let addr = |a: &Address| -> Result<u64, HarnessError> {
        match a {
            Address::Raw(v) => Ok(*v),
            Address::InBuffer { buffer, offset } => buffers
                .iter()
                .find(|(n, _)| n == buffer)
                .map(|(_, a)| a.address + offset)
                .ok_or_else(|| {
                    HarnessError::NotRealised(format!(
                        "the call names buffer `{buffer}`, which the world lacks"
                    ))
                }),
        }
    };
    // The handles of the plan's destroyed buffers: each made and destroyed at once (an invalid case's
    // call, which the layer drops, is all that names them).
    let mut destroyed: Vec<(&str, vk::Buffer)> = Vec::new();
    for name in &plan.destroyed_buffers {
        let handle = crate::vk::memory::create_buffer(
            &cache.dev,
            64,
            vk::BufferUsageFlags::SHADER_BINDING_TABLE_KHR,
            vk::BufferCreateFlags::empty(),
        )?;
        // SAFETY: the buffer was just made and nothing uses it.
        unsafe { cache.dev.device.destroy_buffer(handle, None) };
        destroyed.push((name, handle));
    }
    let buffer_named = |name: &Option<String>| -> Result<vk::Buffer, HarnessError> {
        match name {
            None => Ok(vk::Buffer::null()),
            Some(n) => buffers
                .iter()
                .find(|(b, _)| b == n)
                .map(|(_, a)| a.buffer)
                .or_else(|| destroyed.iter().find(|(b, _)| b == n).map(|&(_, h)| h))
                .ok_or_else(|| {
                    HarnessError::NotRealised(format!(
                        "the call names buffer `{n}`, which the world lacks"
                    ))
                }),
        }
    };
    let secondary = cbs.level == CommandBufferLevel::Secondary;
    // The command buffer comes from the compute family's pool, or from a pool of the device's family
    // without compute (made for this case) where the case's pool lacks compute.
    if plan.pool_family.is_some() {
        let family = cache.dev.pool_family.ok_or_else(|| {
            HarnessError::Failed(
                "the device was created without a queue of a family without compute".into(),
            )
        })?;
        *pool = Some(Commands::of_family(&cache.dev, family)?);
    }
    let cmds = pool.as_ref().unwrap_or(&cache.cmds);
    let cb = if secondary { cmds.secondary } else { cmds.cb };
    let step = |s: Step| plan.steps.contains(&s);
    let d = &cache.dev.device;
    let recording = span(Phase::Record);
    // SAFETY: recording into an idle command buffer with live objects.
    unsafe {
        if cbs.lifecycle != CommandBufferLifecycle::Initial {
            let inherit = vk::CommandBufferInheritanceInfo::default();
            let mut begin = vk::CommandBufferBeginInfo::default()
                .flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT);
            if secondary {
                begin = begin.inheritance_info(&inherit);
            }
            d.begin_command_buffer(cb, &begin)
                .map_err(|r| HarnessError::Failed(format!("vkBeginCommandBuffer: {r:?}")))?;
            if step(Step::Barrier(Barrier::SceneBuildToShaders)) {
                // The scene was built by an earlier submission: a memory dependency from its build to the
                // shaders' reads (submission order alone gives only an execution dependency). Recorded
                // before any render pass begins, where a barrier would need a subpass self-dependency.
                memory_barrier(
                    d,
                    cb,
                    (
                        vk::PipelineStageFlags::ACCELERATION_STRUCTURE_BUILD_KHR,
                        vk::AccessFlags::ACCELERATION_STRUCTURE_WRITE_KHR,
                    ),
                    (
                        vk::PipelineStageFlags::RAY_TRACING_SHADER_KHR,
                        vk::AccessFlags::ACCELERATION_STRUCTURE_READ_KHR,
                    ),
                );
            }
            if let Some(r) = res.as_ref().filter(|_| step(Step::ResourceTransitions)) {
                r.record_transitions(d, cb);
            }
            if let Some(p) = vk_pipeline.filter(|_| step(Step::BindPipeline)) {
                d.cmd_bind_pipeline(cb, vk::PipelineBindPoint::RAY_TRACING_KHR, p);
                if step(Step::SetStackSize) {
                    if let Some(rt) = &cache.dev.rt {
                        // The spec's default stack size for the pipeline (a fixed guess can be too small on
                        // a real GPU once closest-hit shaders recurse: undefined behaviour, not a test).
                        let size = if stack_size == 0 { 4096 } else { stack_size };
                        rt.cmd_set_ray_tracing_pipeline_stack_size(cb, size);
                    }
                }
            }
            // With a resource state the harness set is bound with the case pipeline's realised layout,
            // then the case's own binds and pushes follow.
            let harness_layout = res.as_ref().map_or(layouts.pipeline, |r| r.harness_layout);
            if step(Step::BindHarnessSet)
                && !res.as_ref().is_some_and(|r| r.harness_set_in_buffer())
            {
                d.cmd_bind_descriptor_sets(
                    cb,
                    vk::PipelineBindPoint::RAY_TRACING_KHR,
                    harness_layout,
                    0,
                    &[set],
                    &[],
                );
            }
            if let Some(r) = res.as_ref().filter(|_| step(Step::ResourceBinds)) {
                r.record_binds(&cache.dev, cb);
            }
            if let Some(pass) = render_pass {
                begin_render_pass(d, cb, pass, vk::SubpassContents::INLINE);
            }
            if step(Step::End) {
                if render_pass.is_some() {
                    d.cmd_end_render_pass(cb);
                }
                d.end_command_buffer(cb)
                    .map_err(|r| HarnessError::Failed(format!("vkEndCommandBuffer: {r:?}")))?;
            }
        }
    }
    if step(Step::SubmitToInvalidate) {
        // The binds and transitions recorded above run once; the buffer is then invalid. (The plan
        // realises no secondary inside a render pass.)
        cmds.submit_to_invalidate(&cache.dev, cb, secondary, None)?;
    }
    // The call's arguments, resolved before collecting so only the call's own messages are kept.
    enum Resolved {
        Khr([vk::StridedDeviceAddressRegionKHR; 4], Option<u64>),
        Nv([(vk::Buffer, u64, u64); 4]),
    }
    let resolved = match &case.call {
        Call::TraceRaysNv(c) => {
            let t = |t: &model::call::NvTable| -> Result<(vk::Buffer, u64, u64), HarnessError> {
                Ok((buffer_named(&t.buffer)?, t.offset, t.stride))
            };
            Resolved::Nv([t(&c.raygen)?, t(&c.miss)?, t(&c.hit)?, t(&c.callable)?])
        }
        _ => {
            let regions = case.call.regions().expect("KHR call");
            let r = [
                region(regions[0], &addr)?,
                region(regions[1], &addr)?,
                region(regions[2], &addr)?,
                region(regions[3], &addr)?,
            ];
            let indirect = match &case.call {
                Call::TraceRaysIndirect(c) => Some(addr(&c.indirect_address)?),
                _ => None,
            };
            Resolved::Khr(r, indirect)
        }
    };
    collector.clear();
    collector.set_abort(!valid);
    // SAFETY: for valid cases every parameter is valid; for invalid ones the layer drops the call.
    unsafe {
        match (&case.call, &resolved) {
            (Call::TraceRays(c), Resolved::Khr([rg, ms, ht, cl], _)) => cache
                .dev
                .rt
                .as_ref()
                .expect("checked above")
                .cmd_trace_rays(cb, rg, ms, ht, cl, c.width, c.height, c.depth),
            (Call::TraceRaysIndirect(_), Resolved::Khr([rg, ms, ht, cl], Some(a))) => cache
                .dev
                .rt
                .as_ref()
                .expect("checked above")
                .cmd_trace_rays_indirect(cb, rg, ms, ht, cl, *a),
            (Call::TraceRaysNv(c), Resolved::Nv([rg, ms, ht, cl])) => cache
                .dev
                .nv
                .as_ref()
                .expect("checked above")
                .cmd_trace_rays(
                    cb, rg.0, rg.1, ms.0, ms.1, ms.2, ht.0, ht.1, ht.2, cl.0, cl.1, cl.2, c.width,
                    c.height, c.depth,
                ),
            _ => {}
        }
    }
    collector.set_abort(false);
    drop(recording);
    let mut obs = Observation::with_status(Status::Ran);
    obs.set_messages(collector.take());
    if !valid
        || cbs.lifecycle != CommandBufferLifecycle::Recording
        || secondary
        || render_pass.is_some()
    {
        return Ok(obs);
    }
    // SAFETY: ending and submitting a valid recording.
    unsafe {
        memory_barrier(
            d,
            cb,
            (
                vk::PipelineStageFlags::RAY_TRACING_SHADER_KHR,
                vk::AccessFlags::SHADER_WRITE,
            ),
            (vk::PipelineStageFlags::HOST, vk::AccessFlags::HOST_READ),
        );
        d.end_command_buffer(cb)
            .map_err(|r| HarnessError::Failed(format!("vkEndCommandBuffer: {r:?}")))?;
    }
    collector.clear();
    {
        let _phase = span(Phase::Gpu);
        cache.submit_and_wait(timeout)?;
    }
    let _phase = span(Phase::Readback);
    let out = cache.output.as_ref().expect("made above");
    obs.output = Some(Output::Words(out.read_u32s(words)));
    Ok(obs)
}
