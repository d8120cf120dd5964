//! Executes a case: picks (or creates) the device for its enabled state, realises the world, records the
//! trace call with the layer's messages collected — dropped by the layer for invalid cases, which are never
//! submitted — and, for valid cases, submits, waits and reads the output words back.

use crate::error::HarnessError;
use crate::observe::{Observation, Status};
use crate::realise::{Allocation, DeviceCache, RealiseError, RAY_RECORD_SIZE};
use crate::vulkan::{DeviceError, Driver, VkDevice, VkInstance};
use ash::vk;
use model::call::{Address, Call, StridedRegion};
use model::case::{Case, Intent};
use model::flags::QueueFlags;
use model::world::{CommandBufferLevel, CommandBufferLifecycle, RayTarget, World};
use std::collections::HashMap;
use std::sync::Arc;
use std::time::Duration;

/// The most output words the harness reads back for one launch.
pub const MAX_OUTPUT_WORDS: usize = 1 << 24;

/// Runs cases on one driver, caching a device per distinct enabled (extensions, features) set.
pub struct Executor {
    inst: Arc<VkInstance>,
    devices: HashMap<String, Result<DeviceCache, String>>,
    /// How long a valid case's submission may run.
    pub gpu_timeout: Duration,
}

impl Executor {
    /// Loads `driver` with the validation layer.
    pub fn new(driver: Driver) -> Result<Executor, HarnessError> {
        Ok(Executor { inst: Arc::new(VkInstance::new(driver, true)?), devices: HashMap::new(), gpu_timeout: Duration::from_secs(20) })
    }

    pub fn driver(&self) -> &Driver {
        &self.inst.driver
    }

    fn device(&mut self, world: &World) -> Result<&mut DeviceCache, Observation> {
        let key = serde_json::to_string(&world.device).unwrap_or_default();
        if !self.devices.contains_key(&key) {
            let made = match VkDevice::new(self.inst.clone(), &world.device.extensions, &world.device.features) {
                Ok(dev) => DeviceCache::new(dev).map_err(|e| match e {
                    RealiseError::Unsupported(s) => format!("unsupported: {s}"),
                    RealiseError::Failed(s) => s,
                }),
                Err(DeviceError::Unsupported(s)) => Err(format!("unsupported: {s}")),
                Err(DeviceError::Failed(e)) => Err(e.to_string()),
            };
            self.inst.collector.clear();
            self.devices.insert(key.clone(), made);
        }
        match self.devices.get_mut(&key).expect("inserted above") {
            Ok(c) => Ok(c),
            Err(s) => Err(match s.strip_prefix("unsupported: ") {
                Some(r) => Observation::unsupported(r),
                None => Observation::crash(s.clone()),
            }),
        }
    }
}

fn realise_failure(e: RealiseError) -> Observation {
    match e {
        RealiseError::Unsupported(s) => Observation::unsupported(s),
        RealiseError::Failed(s) if s.starts_with("TIMEOUT") => Observation::with_status(Status::Timeout { seconds: 0.0 }),
        RealiseError::Failed(s) => Observation::crash(s),
    }
}

/// Runs one case and reports what the layer said and, for valid cases, what the shaders wrote.
pub fn execute(case: &Case, ctx: &mut Executor) -> Observation {
    let timeout = ctx.gpu_timeout;
    let collector = ctx.inst.collector.clone();
    let cache = match ctx.device(&case.world) {
        Ok(c) => c,
        Err(obs) => return obs,
    };
    let mut buffers = Vec::new();
    let result = run(case, cache, &mut buffers, timeout, &collector);
    // Nothing recorded is pending: valid cases waited, invalid ones were never submitted.
    // SAFETY: the command buffers are not in use by the GPU.
    unsafe {
        let _ = cache.dev.device.reset_command_buffer(cache.primary, vk::CommandBufferResetFlags::empty());
        let _ = cache.dev.device.reset_command_buffer(cache.secondary, vk::CommandBufferResetFlags::empty());
    }
    for (_, a) in buffers {
        a.destroy(&cache.dev);
    }
    collector.set_abort(false);
    collector.clear();
    match result {
        Ok(obs) => obs,
        Err(e) => realise_failure(e),
    }
}

fn region(r: &StridedRegion, addr: &dyn Fn(&Address) -> Result<u64, RealiseError>) -> Result<vk::StridedDeviceAddressRegionKHR, RealiseError> {
    Ok(vk::StridedDeviceAddressRegionKHR { device_address: addr(&r.address)?, stride: r.stride, size: r.size })
}

fn run(
    case: &Case,
    cache: &mut DeviceCache,
    buffers: &mut Vec<(String, Allocation)>,
    timeout: Duration,
    collector: &crate::vulkan::Collector,
) -> Result<Observation, RealiseError> {
    let world = &case.world;
    let valid = matches!(case.intent, Intent::Valid);
    let cbs = &world.command_buffer;
    if matches!(case.call, Call::TraceRaysNv(_)) {
        return Err(RealiseError::Unsupported("vkCmdTraceRaysNV is not realised by the harness yet".into()));
    }
    if cache.dev.rt.is_none() {
        return Err(RealiseError::Unsupported(
            "the case does not enable VK_KHR_ray_tracing_pipeline, so vkCmdTraceRays*KHR cannot be called".into(),
        ));
    }
    if cbs.in_video_coding || cbs.protected || cbs.lifecycle == CommandBufferLifecycle::Invalid {
        return Err(RealiseError::Unsupported(
            "video coding scopes, protected and invalid command buffers are not realised by the harness yet".into(),
        ));
    }
    if !cbs.pool_queue.contains(QueueFlags::COMPUTE_BIT) {
        return Err(RealiseError::Unsupported("a command pool for a queue family without compute is not realised yet".into()));
    }
    if cbs.level == CommandBufferLevel::Secondary && cbs.in_render_pass {
        return Err(RealiseError::Unsupported("secondary command buffers inside a render pass are not realised yet".into()));
    }
    let trace = !world.launch.rays.is_empty();
    let dims = case.call.dimensions(world);
    let words = dims.map(|d| d.iter().map(|&x| x as usize).product::<usize>()).unwrap_or(0);
    if valid && words > MAX_OUTPUT_WORDS {
        return Err(RealiseError::Unsupported(format!("a launch of {words} IDs is larger than the harness reads back")));
    }
    let pipeline = world.pipeline.as_ref();
    *buffers = cache.case_buffers(world, pipeline.map(|p| (p, trace)))?;
    let tlas = if trace { Some(cache.scene(&world.launch.instances)?) } else { None };
    let layouts = cache.layouts(trace)?;
    let vk_pipeline = match pipeline {
        Some(p) => Some(cache.pipeline(p, trace, false)?.pipeline),
        None => None,
    };
    let render_pass = if cbs.in_render_pass { Some(cache.empty_render_pass()?) } else { None };
    cache.io_buffers(words.min(MAX_OUTPUT_WORDS), world.launch.rays.len())?;
    let (out, rays) = (cache.output.as_ref().expect("made above"), cache.rays.as_ref().expect("made above"));
    // Output pre-filled with NOT_RUN; rays header and records.
    let fill: Vec<u8> = std::iter::repeat_n(model::semantics::NOT_RUN.to_ne_bytes(), words).flatten().collect();
    out.write(0, &fill);
    let mut ray_bytes: Vec<u8> = Vec::with_capacity(16 + world.launch.rays.len() * RAY_RECORD_SIZE);
    for v in [world.launch.rays.len() as u32, words.min(MAX_OUTPUT_WORDS) as u32, 0, 0] {
        ray_bytes.extend_from_slice(&v.to_ne_bytes());
    }
    for r in &world.launch.rays {
        let (x, y) = match r.target {
            RayTarget::Nothing => (-1000.0f32, -1000.0f32),
            RayTarget::Geometry { instance, geometry } => (2.0 * geometry as f32, 4.0 * instance as f32),
        };
        for f in [x, y, -1.0, 1.0, 0.0, 0.0, 1.0, 0.0] {
            ray_bytes.extend_from_slice(&f32::to_ne_bytes(f));
        }
        for v in [r.sbt_offset, r.sbt_stride, r.miss_index, r.cull_mask, r.ray_flags, 0, 0, 0] {
            ray_bytes.extend_from_slice(&v.to_ne_bytes());
        }
    }
    rays.write(0, &ray_bytes);

    let d = &cache.dev.device;
    // Descriptor set.
    // SAFETY: the pool's sets are not in use (previous cases finished).
    let set = unsafe {
        d.reset_descriptor_pool(cache.descriptor_pool, vk::DescriptorPoolResetFlags::empty())
            .map_err(|r| RealiseError::Failed(format!("vkResetDescriptorPool: {r:?}")))?;
        let sl = [layouts.set];
        d.allocate_descriptor_sets(&vk::DescriptorSetAllocateInfo::default().descriptor_pool(cache.descriptor_pool).set_layouts(&sl))
            .map_err(|r| RealiseError::Failed(format!("vkAllocateDescriptorSets: {r:?}")))?[0]
    };
    let out_info = [vk::DescriptorBufferInfo { buffer: out.buffer, offset: 0, range: vk::WHOLE_SIZE }];
    let rays_info = [vk::DescriptorBufferInfo { buffer: rays.buffer, offset: 0, range: vk::WHOLE_SIZE }];
    let tl = [tlas.unwrap_or(vk::AccelerationStructureKHR::null())];
    let mut as_write = vk::WriteDescriptorSetAccelerationStructureKHR::default().acceleration_structures(&tl);
    let mut writes = vec![
        vk::WriteDescriptorSet::default()
            .dst_set(set)
            .dst_binding(1)
            .descriptor_type(vk::DescriptorType::STORAGE_BUFFER)
            .buffer_info(&out_info),
        vk::WriteDescriptorSet::default()
            .dst_set(set)
            .dst_binding(2)
            .descriptor_type(vk::DescriptorType::STORAGE_BUFFER)
            .buffer_info(&rays_info),
    ];
    if trace {
        let mut w = vk::WriteDescriptorSet::default()
            .dst_set(set)
            .dst_binding(0)
            .descriptor_type(vk::DescriptorType::ACCELERATION_STRUCTURE_KHR)
            .push_next(&mut as_write);
        w.descriptor_count = 1;
        writes.push(w);
    }
    // SAFETY: writes reference live objects.
    unsafe { d.update_descriptor_sets(&writes, &[]) };

    // Addresses.
    let addr = |a: &Address| -> Result<u64, RealiseError> {
        match a {
            Address::Raw(v) => Ok(*v),
            Address::InBuffer { buffer, offset } => buffers
                .iter()
                .find(|(n, _)| n == buffer)
                .map(|(_, a)| a.address + offset)
                .ok_or_else(|| RealiseError::Unsupported(format!("the call names buffer `{buffer}`, which the world lacks"))),
        }
    };
    let rt = cache.dev.rt.as_ref().expect("checked above");
    let secondary = cbs.level == CommandBufferLevel::Secondary;
    let cb = if secondary { cache.secondary } else { cache.primary };
    let d = &cache.dev.device;
    // SAFETY: recording into an idle command buffer with live objects.
    unsafe {
        if cbs.lifecycle != CommandBufferLifecycle::Initial {
            let inherit = vk::CommandBufferInheritanceInfo::default();
            let mut begin = vk::CommandBufferBeginInfo::default().flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT);
            if secondary {
                begin = begin.inheritance_info(&inherit);
            }
            d.begin_command_buffer(cb, &begin).map_err(|r| RealiseError::Failed(format!("vkBeginCommandBuffer: {r:?}")))?;
            if let Some(p) = vk_pipeline.filter(|_| cbs.pipeline_bound) {
                d.cmd_bind_pipeline(cb, vk::PipelineBindPoint::RAY_TRACING_KHR, p);
                if cbs.stack_size_set {
                    rt.cmd_set_ray_tracing_pipeline_stack_size(cb, 4096);
                }
            }
            d.cmd_bind_descriptor_sets(cb, vk::PipelineBindPoint::RAY_TRACING_KHR, layouts.pipeline, 0, &[set], &[]);
            if let Some((rp, fb)) = render_pass {
                let begin = vk::RenderPassBeginInfo::default()
                    .render_pass(rp)
                    .framebuffer(fb)
                    .render_area(vk::Rect2D { offset: vk::Offset2D::default(), extent: vk::Extent2D { width: 1, height: 1 } });
                d.cmd_begin_render_pass(cb, &begin, vk::SubpassContents::INLINE);
            }
            if cbs.lifecycle == CommandBufferLifecycle::Executable {
                if render_pass.is_some() {
                    d.cmd_end_render_pass(cb);
                }
                d.end_command_buffer(cb).map_err(|r| RealiseError::Failed(format!("vkEndCommandBuffer: {r:?}")))?;
            }
        }
    }
    // The call itself, with only its messages collected.
    let regions = case.call.regions().expect("KHR call");
    let [rg, ms, ht, cl] = [region(regions[0], &addr)?, region(regions[1], &addr)?, region(regions[2], &addr)?, region(regions[3], &addr)?];
    let indirect = match &case.call {
        Call::TraceRaysIndirect(c) => Some(addr(&c.indirect_address)?),
        _ => None,
    };
    collector.clear();
    collector.set_abort(!valid);
    // SAFETY: for valid cases every parameter is valid; for invalid ones the layer drops the call.
    unsafe {
        match (&case.call, indirect) {
            (Call::TraceRays(c), _) => rt.cmd_trace_rays(cb, &rg, &ms, &ht, &cl, c.width, c.height, c.depth),
            (_, Some(a)) => rt.cmd_trace_rays_indirect(cb, &rg, &ms, &ht, &cl, a),
            _ => {}
        }
    }
    collector.set_abort(false);
    let mut obs = Observation::with_status(Status::Ran);
    obs.set_messages(collector.take());
    if !valid || cbs.lifecycle != CommandBufferLifecycle::Recording || secondary || render_pass.is_some() {
        return Ok(obs);
    }
    // SAFETY: ending and submitting a valid recording.
    unsafe {
        let barrier = vk::MemoryBarrier::default()
            .src_access_mask(vk::AccessFlags::SHADER_WRITE)
            .dst_access_mask(vk::AccessFlags::HOST_READ);
        d.cmd_pipeline_barrier(
            cb,
            vk::PipelineStageFlags::RAY_TRACING_SHADER_KHR,
            vk::PipelineStageFlags::HOST,
            vk::DependencyFlags::empty(),
            &[barrier],
            &[],
            &[],
        );
        d.end_command_buffer(cb).map_err(|r| RealiseError::Failed(format!("vkEndCommandBuffer: {r:?}")))?;
    }
    collector.clear();
    cache.submit_and_wait(timeout)?;
    let out = cache.output.as_ref().expect("made above");
    obs.output = Some(out.read_u32s(words));
    Ok(obs)
}
