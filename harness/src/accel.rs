//! Realises build cases on a device: buffers at 4096-aligned addresses with the model's memory image
//! (written through the device's addresses), acceleration structures at their buffer ranges, and
//! `vkCmdBuildAccelerationStructuresIndirectKHR` recorded under the validation layer with the messenger
//! returning VK_TRUE (never submitted). A case run as valid is also built directly
//! (`vkCmdBuildAccelerationStructuresKHR` with the ranges the model reads from memory) and the result is
//! traced with one ray per built primitive (the model's [`model::accel::check::expected_rays`]): with ray
//! query in a compute shader, or — where the device lacks rayQuery, or when asked
//! ([`TraceCheck::Pipeline`]) — with a ray tracing pipeline (raygen, closest-hit, intersection for
//! AABBs). Where the device has `accelerationStructureIndirectBuild`, the case's indirect build is
//! submitted for real too and traced the same way. What came back is observed, never judged.

use crate::observe::{
    error_ids, Hits, IndirectBuild, Observation, Output, TraceCheck, TracedBuild,
};
use crate::realise::{Allocation, RealiseError};
use crate::vulkan::{LayerMessage, VkDevice, VkInstance};
use ash::vk;
use model::accel::call::{BuildGeometryInfo, BuildMode, GeometryData, IndexType, VertexFormat};
use model::accel::check::{expected_rays, ExpectedRay};
use model::accel::semantics::Shape;
use model::accel::world::AddressResolver;
use model::accel::{AsType, BuildSizes, BuiltPrimitive};
use model::call::BUFFER_PLACEMENT_ALIGNMENT;
use model::{AccelBody, Case};
use std::collections::BTreeMap;
use std::sync::Arc;

fn fail(what: &'static str) -> impl Fn(vk::Result) -> String {
    move |r| format!("{what} failed: {r:?}")
}

fn realise_err(e: RealiseError) -> String {
    match e {
        RealiseError::Unsupported(s) => format!("unsupported: {s}"),
        RealiseError::Failed(s) => s,
    }
}

/// Device objects of one case.
struct Realised {
    buffers: BTreeMap<String, Allocation>,
    /// Non-sparse buffers with no memory bound (a case's `unbound` buffer that no address names).
    bare: BTreeMap<String, vk::Buffer>,
    structures: BTreeMap<String, (vk::AccelerationStructureKHR, u64)>,
}

impl AddressResolver for Realised {
    fn buffer(&self, name: &str) -> Option<u64> {
        self.buffers.get(name).map(|a| a.address)
    }
    fn structure(&self, name: &str) -> Option<u64> {
        self.structures.get(name).map(|s| s.1)
    }
}

impl Realised {
    fn destroy(self, dev: &VkDevice) {
        if let Some(accel) = &dev.accel {
            for (_, (s, _)) in self.structures {
                // SAFETY: nothing pending uses it (callers wait).
                unsafe { accel.destroy_acceleration_structure(s, None) };
            }
        }
        for (_, a) in self.buffers {
            a.destroy(dev);
        }
        for (_, b) in self.bare {
            // SAFETY: nothing uses it (callers wait).
            unsafe { dev.device.destroy_buffer(b, None) };
        }
    }
}

fn vk_index(t: IndexType) -> vk::IndexType {
    match t {
        IndexType::None => vk::IndexType::NONE_KHR,
        IndexType::Uint8 => vk::IndexType::UINT8_EXT,
        IndexType::Uint16 => vk::IndexType::UINT16,
        IndexType::Uint32 => vk::IndexType::UINT32,
    }
}

fn vk_format(f: VertexFormat) -> vk::Format {
    match f {
        VertexFormat::R32g32b32Sfloat => vk::Format::R32G32B32_SFLOAT,
        VertexFormat::R32g32Sfloat => vk::Format::R32G32_SFLOAT,
        VertexFormat::R16g16b16a16Sfloat => vk::Format::R16G16B16A16_SFLOAT,
        VertexFormat::R16g16Sfloat => vk::Format::R16G16_SFLOAT,
    }
}

fn vk_type(t: AsType) -> vk::AccelerationStructureTypeKHR {
    match t {
        AsType::TopLevel => vk::AccelerationStructureTypeKHR::TOP_LEVEL,
        AsType::BottomLevel => vk::AccelerationStructureTypeKHR::BOTTOM_LEVEL,
        AsType::Generic => vk::AccelerationStructureTypeKHR::GENERIC,
    }
}

/// The Vulkan geometries of an info (None for geometry types the harness does not realise).
fn vk_geometries(
    info: &BuildGeometryInfo,
    r: &Realised,
) -> Option<Vec<vk::AccelerationStructureGeometryKHR<'static>>> {
    info.geometries
        .iter()
        .map(|g| {
            let a = |x: &model::call::Address| vk::DeviceOrHostAddressConstKHR {
                device_address: r.address(x),
            };
            let (ty, data) = match &g.data {
                GeometryData::Triangles {
                    vertex_format,
                    vertex_data,
                    vertex_stride,
                    max_vertex,
                    index_type,
                    index_data,
                    transform_data,
                    motion_vertex_data: None,
                    opacity_micromap: None,
                } => (
                    vk::GeometryTypeKHR::TRIANGLES,
                    vk::AccelerationStructureGeometryDataKHR {
                        triangles: vk::AccelerationStructureGeometryTrianglesDataKHR::default()
                            .vertex_format(vk_format(*vertex_format))
                            .vertex_data(a(vertex_data))
                            .vertex_stride(*vertex_stride)
                            .max_vertex(*max_vertex)
                            .index_type(vk_index(*index_type))
                            .index_data(a(index_data))
                            .transform_data(a(transform_data)),
                    },
                ),
                GeometryData::Aabbs { data, stride } => (
                    vk::GeometryTypeKHR::AABBS,
                    vk::AccelerationStructureGeometryDataKHR {
                        aabbs: vk::AccelerationStructureGeometryAabbsDataKHR::default()
                            .data(a(data))
                            .stride(*stride),
                    },
                ),
                GeometryData::Instances {
                    array_of_pointers,
                    data,
                } => (
                    vk::GeometryTypeKHR::INSTANCES,
                    vk::AccelerationStructureGeometryDataKHR {
                        instances: vk::AccelerationStructureGeometryInstancesDataKHR::default()
                            .array_of_pointers(*array_of_pointers)
                            .data(a(data)),
                    },
                ),
                _ => return None,
            };
            Some(
                vk::AccelerationStructureGeometryKHR::default()
                    .geometry_type(ty)
                    .geometry(data)
                    .flags(vk::GeometryFlagsKHR::from_raw(g.flags.0)),
            )
        })
        .collect()
}

fn vk_info<'a>(
    info: &BuildGeometryInfo,
    geoms: &'a [vk::AccelerationStructureGeometryKHR<'static>],
    r: &Realised,
) -> vk::AccelerationStructureBuildGeometryInfoKHR<'a> {
    let mode = match info.mode {
        BuildMode::Build => vk::BuildAccelerationStructureModeKHR::BUILD,
        BuildMode::Update => vk::BuildAccelerationStructureModeKHR::UPDATE,
        BuildMode::Other(v) => vk::BuildAccelerationStructureModeKHR::from_raw(v as i32),
    };
    let handle = |n: &Option<String>| {
        n.as_ref()
            .and_then(|n| r.structures.get(n))
            .map_or(vk::AccelerationStructureKHR::null(), |s| s.0)
    };
    vk::AccelerationStructureBuildGeometryInfoKHR::default()
        .ty(vk_type(info.ty))
        .flags(vk::BuildAccelerationStructureFlagsKHR::from_raw(
            info.flags.0,
        ))
        .mode(mode)
        .src_acceleration_structure(handle(&info.src))
        .dst_acceleration_structure(handle(&info.dst))
        .geometries(geoms)
        .scratch_data(vk::DeviceOrHostAddressKHR {
            device_address: r.address(&info.scratch),
        })
}

/// A device for build cases: the case's extensions and features plus what the traced check needs
/// (ray query, or a ray tracing pipeline where ray query is absent or the pipeline check is asked for).
pub fn device_for(
    inst: &Arc<VkInstance>,
    case: &AccelBody,
    check: TraceCheck,
) -> Result<VkDevice, String> {
    let mut ext = case.world.device.extensions.clone();
    let mut feat = case.world.device.features.clone();
    let available = inst.device_extensions();
    let query = available.contains("VK_KHR_ray_query");
    if check != TraceCheck::Pipeline && query {
        ext.insert("VK_KHR_ray_query".into());
        feat.insert("rayQuery".into());
    }
    let pipeline = check == TraceCheck::Pipeline || (check == TraceCheck::Auto && !query);
    if pipeline && available.contains("VK_KHR_ray_tracing_pipeline") {
        ext.insert("VK_KHR_ray_tracing_pipeline".into());
        feat.insert("rayTracingPipeline".into());
    }
    VkDevice::new(inst.clone(), &ext, &feat).map_err(|e| match e {
        crate::vulkan::DeviceError::Unsupported(s) => format!("unsupported: {s}"),
        crate::vulkan::DeviceError::Failed(e) => e.to_string(),
    })
}

/// Whether any address of the call (indirect records, scratch, geometry data) lies in buffer `name`.
fn addressed(case: &AccelBody, name: &str) -> bool {
    let is = |a: &model::call::Address| a.buffer().is_some_and(|(b, _)| b == name);
    case.call.indirect_addresses.iter().any(is)
        || case.call.infos.iter().any(|i| {
            is(&i.scratch)
                || i.geometries.iter().any(|g| match &g.data {
                    GeometryData::Triangles {
                        vertex_data,
                        index_data,
                        transform_data,
                        ..
                    } => is(vertex_data) || is(index_data) || is(transform_data),
                    GeometryData::Aabbs { data, .. } => is(data),
                    GeometryData::Instances { data, .. } => is(data),
                    _ => false,
                })
        })
}

/// Creates the case's buffers and structures and writes the memory image. Memory follows each buffer's
/// binding: wholly bound buffers get one allocation; sparse buffers are bound with `vkQueueBindSparse`
/// (whole: one memory object, scattered: two, unbound: none) waiting on `fence`; a non-sparse unbound
/// buffer is created with no memory where no address of the call lies in it (a structure may be placed
/// on it: VkAccelerationStructureCreateInfoKHR asks nothing of its binding). What Vulkan forbids is
/// `unsupported` with the rule: a non-sparse buffer bound to several memory objects, and the device
/// address of a non-sparse unbound buffer (VUID-VkBufferDeviceAddressInfo-buffer-02600).
fn realise(dev: &VkDevice, case: &AccelBody, fence: vk::Fence) -> Result<Realised, String> {
    use model::world::MemoryBinding;
    let accel = dev
        .accel
        .as_ref()
        .ok_or("unsupported: the case does not enable VK_KHR_acceleration_structure")?;
    let mut r = Realised {
        buffers: BTreeMap::new(),
        bare: BTreeMap::new(),
        structures: BTreeMap::new(),
    };
    let made = (|| -> Result<(), String> {
        for b in &case.world.buffers {
            let usage = vk::BufferUsageFlags::from_raw(b.usage.0 as u32)
                | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS;
            let flags = vk::BufferCreateFlags::from_raw(b.flags.0 as u32);
            if b.is_sparse() {
                if !dev.has_feature("sparseBinding") || !dev.sparse_binding {
                    return Err(format!(
                        "unsupported: buffer `{}` is sparse: creating it needs the sparseBinding feature and \
                         binding it a queue with VK_QUEUE_SPARSE_BINDING_BIT (the case's device has {})",
                        b.name,
                        if dev.has_feature("sparseBinding") {
                            "no such queue"
                        } else {
                            "no sparseBinding"
                        }
                    ));
                }
                let plan = match b.memory {
                    MemoryBinding::Whole => crate::realise::SparsePlan::One,
                    MemoryBinding::Scattered => crate::realise::SparsePlan::Two,
                    MemoryBinding::Unbound => crate::realise::SparsePlan::Unbound,
                };
                let a = Allocation::sparse(dev, fence, b.size, usage, flags, plan)
                    .map_err(realise_err)?;
                r.buffers.insert(b.name.clone(), a);
                continue;
            }
            match b.memory {
                MemoryBinding::Whole => {
                    let a = Allocation::new(dev, b.size, usage, flags, BUFFER_PLACEMENT_ALIGNMENT)
                        .map_err(realise_err)?;
                    r.buffers.insert(b.name.clone(), a);
                }
                MemoryBinding::Scattered => {
                    return Err(format!(
                        "unsupported: buffer `{}` is not sparse, so it cannot be bound to several memory objects \
                         (vkBindBufferMemory binds a non-sparse buffer to one, completely and contiguously); the \
                         one realisable non-contiguous non-sparse buffer is an unbound one, whose device address \
                         is itself invalid to ask for (VUID-VkBufferDeviceAddressInfo-buffer-02600)",
                        b.name
                    ))
                }
                MemoryBinding::Unbound if addressed(case, &b.name) || !b.contents.is_empty() => {
                    return Err(format!(
                        "unsupported: buffer `{}` is not sparse and has no memory bound, yet the call reads \
                         it by device address: vkGetBufferDeviceAddress on it is itself invalid \
                         (VUID-VkBufferDeviceAddressInfo-buffer-02600: a non-sparse buffer must be bound \
                         completely and contiguously to a single VkDeviceMemory object)",
                        b.name
                    ))
                }
                MemoryBinding::Unbound => {
                    let info = vk::BufferCreateInfo::default()
                        .size(b.size.max(1))
                        .usage(usage)
                        .flags(flags);
                    // SAFETY: valid create info; destroyed with the case.
                    let buf = unsafe { dev.device.create_buffer(&info, None) }
                        .map_err(fail("vkCreateBuffer"))?;
                    r.bare.insert(b.name.clone(), buf);
                }
            }
        }
        for s in &case.world.structures {
            let (buffer, bound) = match (r.buffers.get(&s.buffer), r.bare.get(&s.buffer)) {
                (Some(a), _) => (a.buffer, a.memory_count() > 0),
                (None, Some(b)) => (*b, false),
                _ => return Err(format!("structure `{}`: no buffer `{}`", s.name, s.buffer)),
            };
            let info = vk::AccelerationStructureCreateInfoKHR::default()
                .buffer(buffer)
                .offset(s.offset)
                .size(s.size)
                .ty(vk_type(s.ty));
            // SAFETY: the buffer lives as long as the structure.
            let h = unsafe { accel.create_acceleration_structure(&info, None) }
                .map_err(fail("vkCreateAccelerationStructureKHR"))?;
            // The address of a structure on unbound memory is never read by the call (newer registries
            // forbid asking: VUID-vkGetAccelerationStructureDeviceAddressKHR-pInfo-09541).
            let addr = if bound {
                // SAFETY: valid structure on bound memory.
                unsafe {
                    accel.get_acceleration_structure_device_address(
                        &vk::AccelerationStructureDeviceAddressInfoKHR::default()
                            .acceleration_structure(h),
                    )
                }
            } else {
                0
            };
            r.structures.insert(s.name.clone(), (h, addr));
        }
        for b in &case.world.buffers {
            let Some(a) = r.buffers.get(&b.name) else {
                continue;
            };
            if a.memory_count() == 0 {
                if !b.contents.is_empty() {
                    return Err(format!(
                        "unsupported: buffer `{}` has no memory bound, so its contents cannot be written",
                        b.name
                    ));
                }
                continue;
            }
            let bytes = case.world.image(&b.name, &r).expect("buffer of the world");
            a.write(0, &bytes);
        }
        Ok(())
    })();
    match made {
        Ok(()) => Ok(r),
        Err(e) => {
            r.destroy(dev);
            Err(e)
        }
    }
}

/// The sizes the device reports for each info of the call with its maxima.
fn device_sizes(dev: &VkDevice, case: &AccelBody, r: &Realised) -> Option<Vec<BuildSizes>> {
    let accel = dev.accel.as_ref()?;
    case.call
        .infos
        .iter()
        .zip(&case.call.max_primitive_counts)
        .map(|(info, max)| {
            let geoms = vk_geometries(info, r)?;
            let vi = vk_info(info, &geoms, r);
            let mut s = vk::AccelerationStructureBuildSizesInfoKHR::default();
            if max.len() != geoms.len() {
                return None;
            }
            // SAFETY: counts match the geometries.
            unsafe {
                accel.get_acceleration_structure_build_sizes(
                    vk::AccelerationStructureBuildTypeKHR::DEVICE,
                    &vi,
                    max,
                    &mut s,
                )
            };
            Some(BuildSizes {
                structure: s.acceleration_structure_size,
                build_scratch: s.build_scratch_size,
                update_scratch: s.update_scratch_size,
            })
        })
        .collect()
}

struct Commands {
    pool: vk::CommandPool,
    cb: vk::CommandBuffer,
    /// A secondary command buffer of the same pool, for cases recorded at the secondary level.
    secondary: vk::CommandBuffer,
    fence: vk::Fence,
    /// An empty render pass and its 1x1 framebuffer, made for cases recorded inside a render pass.
    render_pass: Option<(vk::RenderPass, vk::Framebuffer)>,
}

impl Commands {
    fn new(dev: &VkDevice) -> Result<Commands, String> {
        let d = &dev.device;
        // SAFETY: valid create infos.
        unsafe {
            let pool = d
                .create_command_pool(
                    &vk::CommandPoolCreateInfo::default()
                        .queue_family_index(dev.queue_family)
                        .flags(vk::CommandPoolCreateFlags::RESET_COMMAND_BUFFER),
                    None,
                )
                .map_err(fail("vkCreateCommandPool"))?;
            let cb = d
                .allocate_command_buffers(
                    &vk::CommandBufferAllocateInfo::default()
                        .command_pool(pool)
                        .level(vk::CommandBufferLevel::PRIMARY)
                        .command_buffer_count(1),
                )
                .map_err(fail("vkAllocateCommandBuffers"))?[0];
            let secondary = d
                .allocate_command_buffers(
                    &vk::CommandBufferAllocateInfo::default()
                        .command_pool(pool)
                        .level(vk::CommandBufferLevel::SECONDARY)
                        .command_buffer_count(1),
                )
                .map_err(fail("vkAllocateCommandBuffers"))?[0];
            let fence = d
                .create_fence(&vk::FenceCreateInfo::default(), None)
                .map_err(fail("vkCreateFence"))?;
            Ok(Commands {
                pool,
                cb,
                secondary,
                fence,
                render_pass: None,
            })
        }
    }
    fn begin(&self, dev: &VkDevice) -> Result<(), String> {
        // SAFETY: the command buffer is idle.
        unsafe {
            dev.device
                .reset_command_buffer(self.cb, vk::CommandBufferResetFlags::empty())
                .map_err(fail("vkResetCommandBuffer"))?;
            dev.device
                .begin_command_buffer(self.cb, &vk::CommandBufferBeginInfo::default())
                .map_err(fail("vkBeginCommandBuffer"))
        }
    }
    fn submit(&self, dev: &VkDevice) -> Result<(), String> {
        let d = &dev.device;
        // SAFETY: recorded command buffer, unsignalled fence.
        unsafe {
            d.end_command_buffer(self.cb)
                .map_err(fail("vkEndCommandBuffer"))?;
            let cbs = [self.cb];
            d.queue_submit(
                dev.queue,
                &[vk::SubmitInfo::default().command_buffers(&cbs)],
                self.fence,
            )
            .map_err(fail("vkQueueSubmit"))?;
            d.wait_for_fences(&[self.fence], true, 60_000_000_000)
                .map_err(fail("vkWaitForFences"))?;
            d.reset_fences(&[self.fence]).map_err(fail("vkResetFences"))
        }
    }
    fn barrier(&self, dev: &VkDevice) {
        let b = vk::MemoryBarrier::default()
            .src_access_mask(vk::AccessFlags::ACCELERATION_STRUCTURE_WRITE_KHR)
            .dst_access_mask(
                vk::AccessFlags::ACCELERATION_STRUCTURE_READ_KHR | vk::AccessFlags::SHADER_READ,
            );
        let mut dst = vk::PipelineStageFlags::ACCELERATION_STRUCTURE_BUILD_KHR
            | vk::PipelineStageFlags::COMPUTE_SHADER;
        if dev.has_feature("rayTracingPipeline") {
            dst |= vk::PipelineStageFlags::RAY_TRACING_SHADER_KHR;
        }
        // SAFETY: recording.
        unsafe {
            dev.device.cmd_pipeline_barrier(
                self.cb,
                vk::PipelineStageFlags::ACCELERATION_STRUCTURE_BUILD_KHR,
                dst,
                vk::DependencyFlags::empty(),
                &[b],
                &[],
                &[],
            )
        };
    }
    /// The empty render pass (no attachments, one graphics subpass) and a 1x1 framebuffer for it.
    fn render_pass(&mut self, dev: &VkDevice) -> Result<(vk::RenderPass, vk::Framebuffer), String> {
        if let Some(rp) = self.render_pass {
            return Ok(rp);
        }
        let d = &dev.device;
        let subpass =
            [vk::SubpassDescription::default()
                .pipeline_bind_point(vk::PipelineBindPoint::GRAPHICS)];
        // SAFETY: valid create infos; destroyed with the commands.
        unsafe {
            let rp = d
                .create_render_pass(
                    &vk::RenderPassCreateInfo::default().subpasses(&subpass),
                    None,
                )
                .map_err(fail("vkCreateRenderPass"))?;
            let fb = d
                .create_framebuffer(
                    &vk::FramebufferCreateInfo::default()
                        .render_pass(rp)
                        .width(1)
                        .height(1)
                        .layers(1),
                    None,
                )
                .map_err(|r| {
                    d.destroy_render_pass(rp, None);
                    format!("vkCreateFramebuffer failed: {r:?}")
                })?;
            self.render_pass = Some((rp, fb));
            Ok((rp, fb))
        }
    }
    fn destroy(self, dev: &VkDevice) {
        // SAFETY: idle.
        unsafe {
            if let Some((rp, fb)) = self.render_pass {
                dev.device.destroy_framebuffer(fb, None);
                dev.device.destroy_render_pass(rp, None);
            }
            dev.device.destroy_fence(self.fence, None);
            dev.device.destroy_command_pool(self.pool, None);
        }
    }
}

/// The Vulkan form of the case's indirect call: infos (with their geometries kept alive), addresses,
/// strides and maxima.
fn indirect_args<'a>(
    case: &'a AccelBody,
    r: &Realised,
    geoms: &'a [Vec<vk::AccelerationStructureGeometryKHR<'static>>],
) -> (
    Vec<vk::AccelerationStructureBuildGeometryInfoKHR<'a>>,
    Vec<u64>,
    Vec<&'a [u32]>,
) {
    let infos = case
        .call
        .infos
        .iter()
        .zip(geoms)
        .map(|(i, g)| vk_info(i, g, r))
        .collect();
    let addrs = case
        .call
        .indirect_addresses
        .iter()
        .map(|a| r.address(a))
        .collect();
    let maxima = case
        .call
        .max_primitive_counts
        .iter()
        .map(|v| v.as_slice())
        .collect();
    (infos, addrs, maxima)
}

/// Why the case's command buffer state cannot be realised on this device, if it cannot: protected
/// command buffers, video coding scopes, pools of a queue family without compute, and recording between
/// suspended render pass instances. Every other state (primary or secondary, initial, recording,
/// executable or invalid, inside a render pass or not) is realised by [`record_indirect`].
fn unrealisable_state(inst: &VkInstance, case: &AccelBody) -> Option<String> {
    let cbs = &case.world.command_buffer;
    // SAFETY: plain query.
    let families = unsafe {
        inst.instance
            .get_physical_device_queue_family_properties(inst.physical)
    };
    let any = |f: vk::QueueFlags| families.iter().any(|p| p.queue_flags.intersects(f));
    let protected_memory = inst
        .device_features()
        .iter()
        .any(|(k, on)| *on && k.ends_with("::protectedMemory"));
    if cbs.protected {
        return Some(format!(
            "a protected command buffer comes from a pool created with VK_COMMAND_POOL_CREATE_PROTECTED_BIT, \
             which needs the protectedMemory feature (VUID-VkCommandPoolCreateInfo-flags-02860) and a queue \
             created with VK_DEVICE_QUEUE_CREATE_PROTECTED_BIT; {}",
            if protected_memory {
                "the harness's device creates no protected queue"
            } else {
                "the device lacks protectedMemory"
            }
        ));
    }
    if cbs.in_video_coding {
        let video = vk::QueueFlags::VIDEO_DECODE_KHR | vk::QueueFlags::VIDEO_ENCODE_KHR;
        return Some(if any(video) {
            "a video coding scope needs a video session (VK_KHR_video_queue) on a video queue; the harness \
             creates neither"
                .into()
        } else {
            "a video coding scope (vkCmdBeginVideoCodingKHR) needs a queue family with video decode or encode; \
             the device has none"
                .into()
        });
    }
    if !cbs
        .pool_queue
        .contains(model::flags::QueueFlags::COMPUTE_BIT)
    {
        let without_compute = families
            .iter()
            .any(|p| !p.queue_flags.contains(vk::QueueFlags::COMPUTE));
        return Some(if without_compute {
            "a pool of a queue family without compute needs the device created with a queue of that family \
             (VUID-vkCreateCommandPool-queueFamilyIndex-01937); the harness's device has its compute family only"
                .into()
        } else {
            format!(
                "a pool of a queue family without VK_QUEUE_COMPUTE_BIT needs such a family; every one of the \
                 device's {} queue famil{} has compute",
                families.len(),
                if families.len() == 1 { "y" } else { "ies" }
            )
        });
    }
    if case.world.command_buffer.between_suspended_render_passes {
        return Some(
            "recording between suspended render pass instances (dynamic rendering) is not realised for builds"
                .into(),
        );
    }
    None
}

/// Puts the case's command buffer into its state: primary or secondary (a secondary inside a render pass
/// continues the empty render pass through its inheritance), begun unless initial, inside the empty
/// render pass when asked (a primary begins it inline), ended when executable, and submitted once with
/// ONE_TIME_SUBMIT when invalid. Returns the command buffer the call is recorded into.
fn enter_state(
    dev: &VkDevice,
    cmds: &mut Commands,
    case: &AccelBody,
) -> Result<vk::CommandBuffer, String> {
    use model::world::{CommandBufferLevel, CommandBufferLifecycle};
    let cbs = &case.world.command_buffer;
    let d = &dev.device;
    let secondary = cbs.level == CommandBufferLevel::Secondary;
    let cb = if secondary { cmds.secondary } else { cmds.cb };
    let rp = if cbs.in_render_pass {
        Some(cmds.render_pass(dev)?)
    } else {
        None
    };
    // SAFETY: the command buffers are idle; everything named is alive.
    unsafe {
        d.reset_command_buffer(cb, vk::CommandBufferResetFlags::empty())
            .map_err(fail("vkResetCommandBuffer"))?;
        if cbs.lifecycle == CommandBufferLifecycle::Initial {
            return Ok(cb);
        }
        let mut inherit = vk::CommandBufferInheritanceInfo::default();
        let mut flags = vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT;
        if let (true, Some((pass, fb))) = (secondary, rp) {
            inherit = inherit.render_pass(pass).subpass(0).framebuffer(fb);
            flags |= vk::CommandBufferUsageFlags::RENDER_PASS_CONTINUE;
        }
        let mut begin = vk::CommandBufferBeginInfo::default().flags(flags);
        if secondary {
            begin = begin.inheritance_info(&inherit);
        }
        d.begin_command_buffer(cb, &begin)
            .map_err(fail("vkBeginCommandBuffer"))?;
        let primary_pass = rp.filter(|_| !secondary);
        if let Some((pass, fb)) = primary_pass {
            let info = vk::RenderPassBeginInfo::default()
                .render_pass(pass)
                .framebuffer(fb)
                .render_area(vk::Rect2D {
                    offset: vk::Offset2D::default(),
                    extent: vk::Extent2D {
                        width: 1,
                        height: 1,
                    },
                });
            d.cmd_begin_render_pass(cb, &info, vk::SubpassContents::INLINE);
        }
        match cbs.lifecycle {
            CommandBufferLifecycle::Executable | CommandBufferLifecycle::Invalid => {
                if primary_pass.is_some() {
                    d.cmd_end_render_pass(cb);
                }
                d.end_command_buffer(cb)
                    .map_err(fail("vkEndCommandBuffer"))?;
            }
            _ => {}
        }
        if cbs.lifecycle == CommandBufferLifecycle::Invalid {
            // A ONE_TIME_SUBMIT buffer moves to the invalid state once its submission completes; a
            // secondary one is executed once from the primary.
            let submit_cb = if secondary {
                d.reset_command_buffer(cmds.cb, vk::CommandBufferResetFlags::empty())
                    .map_err(fail("vkResetCommandBuffer"))?;
                d.begin_command_buffer(
                    cmds.cb,
                    &vk::CommandBufferBeginInfo::default()
                        .flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT),
                )
                .map_err(fail("vkBeginCommandBuffer"))?;
                if let Some((pass, fb)) = rp {
                    let info = vk::RenderPassBeginInfo::default()
                        .render_pass(pass)
                        .framebuffer(fb)
                        .render_area(vk::Rect2D {
                            offset: vk::Offset2D::default(),
                            extent: vk::Extent2D {
                                width: 1,
                                height: 1,
                            },
                        });
                    d.cmd_begin_render_pass(
                        cmds.cb,
                        &info,
                        vk::SubpassContents::SECONDARY_COMMAND_BUFFERS,
                    );
                    d.cmd_execute_commands(cmds.cb, &[cb]);
                    d.cmd_end_render_pass(cmds.cb);
                } else {
                    d.cmd_execute_commands(cmds.cb, &[cb]);
                }
                d.end_command_buffer(cmds.cb)
                    .map_err(fail("vkEndCommandBuffer"))?;
                cmds.cb
            } else {
                cb
            };
            let cbs_ = [submit_cb];
            d.queue_submit(
                dev.queue,
                &[vk::SubmitInfo::default().command_buffers(&cbs_)],
                cmds.fence,
            )
            .map_err(fail("vkQueueSubmit"))?;
            d.wait_for_fences(&[cmds.fence], true, 60_000_000_000)
                .map_err(fail("vkWaitForFences"))?;
            d.reset_fences(&[cmds.fence])
                .map_err(fail("vkResetFences"))?;
        }
    }
    Ok(cb)
}

/// Records the indirect call under the layer (dropped by the messenger, never submitted) into a command
/// buffer in the case's state and returns the layer's messages.
fn record_indirect(
    inst: &VkInstance,
    dev: &VkDevice,
    cmds: &mut Commands,
    case: &AccelBody,
    r: &Realised,
) -> Result<Vec<LayerMessage>, String> {
    use model::world::{CommandBufferLevel, CommandBufferLifecycle};
    let accel = dev
        .accel
        .as_ref()
        .ok_or("unsupported: no VK_KHR_acceleration_structure")?;
    let geoms: Vec<Vec<vk::AccelerationStructureGeometryKHR>> = case
        .call
        .infos
        .iter()
        .map(|i| vk_geometries(i, r))
        .collect::<Option<_>>()
        .ok_or("unsupported: geometry type not realised")?;
    let (infos, addrs, maxima) = indirect_args(case, r, &geoms);
    let cb = enter_state(dev, cmds, case)?;
    inst.collector.clear();
    inst.collector.set_abort(true);
    // SAFETY: with the messenger returning VK_TRUE the layer drops an invalid call (one recorded into a
    // command buffer that is not recording included).
    unsafe {
        accel.cmd_build_acceleration_structures_indirect(
            cb,
            &infos,
            &addrs,
            &case.call.indirect_strides,
            &maxima,
        )
    };
    inst.collector.set_abort(false);
    let msgs = inst.collector.take();
    let cbs = &case.world.command_buffer;
    // SAFETY: ending what was begun (never submitted); the buffers are reset before their next use.
    unsafe {
        if cbs.lifecycle == CommandBufferLifecycle::Recording {
            if cbs.in_render_pass && cbs.level == CommandBufferLevel::Primary {
                dev.device.cmd_end_render_pass(cb);
            }
            let _ = dev.device.end_command_buffer(cb);
        }
        for b in [cmds.cb, cmds.secondary] {
            let _ = dev
                .device
                .reset_command_buffer(b, vk::CommandBufferResetFlags::empty());
        }
    }
    Ok(msgs)
}

/// Runs one build case: the indirect call recorded under the layer, the sizes the device reports, and
/// for a case run as valid (`run_valid`), the direct build traced with the model's rays (and, where the
/// device has accelerationStructureIndirectBuild, the indirect build for real, traced the same).
pub fn execute(
    inst: &Arc<VkInstance>,
    case: &Case,
    run_valid: bool,
    check: TraceCheck,
) -> Observation {
    let Some(body) = case.as_accel() else {
        return Observation::crash(format!("{} is not a build case", case.name));
    };
    let mut obs = Observation::with_status(crate::observe::Status::Ran);
    if let Some(why) = unrealisable_state(inst, body) {
        return Observation::unsupported(why);
    }
    let dev = match device_for(inst, body, check) {
        Ok(d) => d,
        Err(e) => return failure(e),
    };
    let result = (|| -> Result<(), String> {
        let mut cmds = Commands::new(&dev)?;
        let r = match realise(&dev, body, cmds.fence) {
            Ok(r) => r,
            Err(e) => {
                cmds.destroy(&dev);
                return Err(e);
            }
        };
        let out = (|| -> Result<(), String> {
            if let Some(s) = device_sizes(&dev, body, &r) {
                obs.device_sizes = s;
            }
            let messages = record_indirect(inst, &dev, &mut cmds, body, &r)?;
            obs.set_messages(messages);
            if run_valid && fits_device_sizes(body, &obs.device_sizes) {
                let traced = direct_and_trace(inst, &dev, &cmds, body, &r, check)?;
                obs.output = Some(Output::Rays(traced));
            }
            Ok(())
        })();
        cmds.destroy(&dev);
        r.destroy(&dev);
        out
    })();
    match result {
        Ok(()) => obs,
        Err(e) => failure(e),
    }
}

/// An error of the build path as an observation: `unsupported: …` names what the device or harness
/// lacks; anything else is a failure of the driver or the harness.
fn failure(e: String) -> Observation {
    match e.strip_prefix("unsupported: ") {
        Some(reason) => Observation::unsupported(reason),
        None => Observation::crash(format!("failed: {e}")),
    }
}

/// Whether the case's first destination and scratch are as large as the device says the build needs:
/// the direct build writes them, and a smaller range would be written out of bounds.
fn fits_device_sizes(case: &AccelBody, sizes: &[BuildSizes]) -> bool {
    let (Some(info), Some(need)) = (case.call.infos.first(), sizes.first()) else {
        return true;
    };
    let dst = info.dst.as_deref().and_then(|n| case.world.structure(n));
    let scratch = info
        .scratch
        .buffer()
        .and_then(|(b, off)| Some(case.world.buffer(b)?.size.saturating_sub(off)));
    let scratch_need = match info.mode {
        BuildMode::Update => need.update_scratch,
        _ => need.build_scratch,
    };
    dst.is_none_or(|s| s.size >= need.structure) && scratch.is_none_or(|s| s >= scratch_need)
}

const TRACE_COMP: &str = r#"#version 460
#extension GL_EXT_ray_query : require
layout(local_size_x = 1) in;
layout(set = 0, binding = 0) uniform accelerationStructureEXT scene;
layout(set = 0, binding = 1, std430) readonly buffer Rays { vec4 origins[]; };
layout(set = 0, binding = 2, std430) buffer Hits { uvec4 hits[]; };
layout(set = 0, binding = 3, std430) readonly buffer Boxes { uint base[8]; vec4 box[]; };
void main() {
    uint i = gl_GlobalInvocationID.x;
    vec3 o = origins[i].xyz;
    rayQueryEXT q;
    rayQueryInitializeEXT(q, scene, gl_RayFlagsNoneEXT, 0xFF, o, 0.0, vec3(0.0, 0.0, 1.0), 100.0);
    while (rayQueryProceedEXT(q)) {
        if (rayQueryGetIntersectionTypeEXT(q, false) == gl_RayQueryCandidateIntersectionAABBEXT) {
            uint g = rayQueryGetIntersectionGeometryIndexEXT(q, false);
            uint p = rayQueryGetIntersectionPrimitiveIndexEXT(q, false);
            vec4 lo = box[2u * (base[g] + p)];
            vec4 hi = box[2u * (base[g] + p) + 1u];
            if (o.x >= lo.x && o.x <= hi.x && o.y >= lo.y && o.y <= hi.y) {
                rayQueryGenerateIntersectionEXT(q, max(lo.z - o.z, 0.0));
            }
        } else {
            rayQueryConfirmIntersectionEXT(q);
        }
    }
    if (rayQueryGetIntersectionTypeEXT(q, true) == gl_RayQueryCommittedIntersectionNoneEXT) {
        hits[i] = uvec4(0u, 0u, 0u, 0u);
    } else {
        hits[i] = uvec4(1u, uint(rayQueryGetIntersectionInstanceIdEXT(q, true)),
                        uint(rayQueryGetIntersectionGeometryIndexEXT(q, true)),
                        uint(rayQueryGetIntersectionPrimitiveIndexEXT(q, true)));
    }
}
"#;

fn compile_trace_shader() -> Result<Vec<u32>, String> {
    static SPIRV: std::sync::OnceLock<Result<Vec<u32>, String>> = std::sync::OnceLock::new();
    SPIRV
        .get_or_init(|| compile_glsl("trace.comp", TRACE_COMP))
        .clone()
}

/// Compiles one GLSL shader with glslangValidator (the stage from the file name's extension).
fn compile_glsl(file: &str, text: &str) -> Result<Vec<u32>, String> {
    let dir = std::env::temp_dir().join(format!("rtconf-build-{}", std::process::id()));
    std::fs::create_dir_all(&dir).map_err(|e| e.to_string())?;
    let src = dir.join(file);
    let spv = dir.join(format!("{file}.spv"));
    std::fs::write(&src, text).map_err(|e| e.to_string())?;
    let out = std::process::Command::new("glslangValidator")
        .args(["--target-env", "vulkan1.2", "-V"])
        .arg(&src)
        .arg("-o")
        .arg(&spv)
        .output()
        .map_err(|e| format!("unsupported: glslangValidator is not available ({e})"))?;
    if !out.status.success() {
        return Err(format!(
            "glslangValidator {file}: {}",
            String::from_utf8_lossy(&out.stdout)
        ));
    }
    let bytes = std::fs::read(&spv).map_err(|e| e.to_string())?;
    Ok(bytes
        .chunks_exact(4)
        .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect())
}

/// Builds one structure directly: returns (structure, its address, storage and scratch allocations).
fn build_direct(
    dev: &VkDevice,
    cmds: &Commands,
    ty: vk::AccelerationStructureTypeKHR,
    geoms: &[vk::AccelerationStructureGeometryKHR],
    ranges: &[vk::AccelerationStructureBuildRangeInfoKHR],
) -> Result<(vk::AccelerationStructureKHR, u64, Allocation, Allocation), String> {
    let accel = dev
        .accel
        .as_ref()
        .ok_or("no acceleration structure extension")?;
    let counts: Vec<u32> = ranges.iter().map(|r| r.primitive_count).collect();
    let info = vk::AccelerationStructureBuildGeometryInfoKHR::default()
        .ty(ty)
        .mode(vk::BuildAccelerationStructureModeKHR::BUILD)
        .geometries(geoms);
    let mut sizes = vk::AccelerationStructureBuildSizesInfoKHR::default();
    // SAFETY: counts match.
    unsafe {
        accel.get_acceleration_structure_build_sizes(
            vk::AccelerationStructureBuildTypeKHR::DEVICE,
            &info,
            &counts,
            &mut sizes,
        )
    };
    let storage = Allocation::new(
        dev,
        sizes.acceleration_structure_size.max(256),
        vk::BufferUsageFlags::ACCELERATION_STRUCTURE_STORAGE_KHR
            | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS,
        vk::BufferCreateFlags::empty(),
        256,
    )
    .map_err(realise_err)?;
    let scratch = Allocation::new(
        dev,
        sizes.build_scratch_size.max(1),
        vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS,
        vk::BufferCreateFlags::empty(),
        256,
    )
    .map_err(realise_err)?;
    // SAFETY: storage is large enough.
    let s = unsafe {
        accel.create_acceleration_structure(
            &vk::AccelerationStructureCreateInfoKHR::default()
                .buffer(storage.buffer)
                .size(sizes.acceleration_structure_size)
                .ty(ty),
            None,
        )
    }
    .map_err(fail("vkCreateAccelerationStructureKHR"))?;
    // SAFETY: valid structure.
    let addr = unsafe {
        accel.get_acceleration_structure_device_address(
            &vk::AccelerationStructureDeviceAddressInfoKHR::default().acceleration_structure(s),
        )
    };
    cmds.begin(dev)?;
    let info = info
        .dst_acceleration_structure(s)
        .scratch_data(vk::DeviceOrHostAddressKHR {
            device_address: scratch.address,
        });
    // SAFETY: recording.
    unsafe { accel.cmd_build_acceleration_structures(cmds.cb, &[info], &[ranges]) };
    cmds.barrier(dev);
    cmds.submit(dev)?;
    Ok((s, addr, storage, scratch))
}

/// How the structure under test is built.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum BuildPath {
    /// `vkCmdBuildAccelerationStructuresKHR` with the ranges the model reads from memory.
    Direct,
    /// The case's own `vkCmdBuildAccelerationStructuresIndirectKHR`, submitted.
    Indirect,
}

/// The check a device gets: ray query unless the pipeline is asked for or ray query is absent.
fn resolve_check(dev: &VkDevice, check: TraceCheck) -> Result<TraceCheck, String> {
    let query = dev.has_feature("rayQuery");
    let pipeline = dev.has_feature("rayTracingPipeline") && dev.rt.is_some();
    match check {
        TraceCheck::RayQuery if query => Ok(TraceCheck::RayQuery),
        TraceCheck::Pipeline if pipeline => Ok(TraceCheck::Pipeline),
        TraceCheck::Auto if query => Ok(TraceCheck::RayQuery),
        TraceCheck::Auto if pipeline => Ok(TraceCheck::Pipeline),
        _ => Err(format!(
            "unsupported: the traced check ({check:?}) needs rayQuery or rayTracingPipeline"
        )),
    }
}

/// The valid case as a direct build with the ranges the model reads, then one ray per primitive; where
/// the device has accelerationStructureIndirectBuild, the case's indirect build is submitted too and
/// traced with the same rays, and must report what the direct build did.
#[allow(clippy::too_many_arguments)]
fn direct_and_trace(
    inst: &VkInstance,
    dev: &VkDevice,
    cmds: &Commands,
    case: &AccelBody,
    r: &Realised,
    check: TraceCheck,
) -> Result<TracedBuild, String> {
    let check = resolve_check(dev, check)?;
    if case.call.infos.len() != 1 {
        return Err("unsupported: the traced check handles one build info".into());
    }
    let accel = dev
        .accel
        .as_ref()
        .ok_or("no acceleration structure extension")?;
    let info = &case.call.infos[0];
    let top = info.ty == AsType::TopLevel;
    let mem = case.world.memory();
    let ranges = model::accel::indirect_ranges(&mem, &case.call, 0).map_err(|e| e.to_string())?;
    let prims = model::accel::build_primitives(&mem, info, &ranges).map_err(|e| e.to_string())?;
    drop(mem);
    let mut extra: Vec<Allocation> = Vec::new();
    let result =
        (|| -> Result<TracedBuild, String> {
            // Top-level cases reference the BLAS: build it first (one triangle at the origin).
            if top {
                let tri: Vec<u8> = [-0.5f32, -0.5, 0.0, 0.5, -0.5, 0.0, 0.0, 0.5, 0.0]
                    .iter()
                    .flat_map(|f| f.to_le_bytes())
                    .collect();
                let (blas, _) = r
                    .structures
                    .get(generator_blas())
                    .copied()
                    .ok_or("the top-level case has no `blas` structure")?;
                let vb = Allocation::new(
                    dev,
                    64,
                    vk::BufferUsageFlags::ACCELERATION_STRUCTURE_BUILD_INPUT_READ_ONLY_KHR
                        | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS,
                    vk::BufferCreateFlags::empty(),
                    256,
                )
                .map_err(realise_err)?;
                vb.write(0, &tri);
                let g = [vk::AccelerationStructureGeometryKHR::default()
                    .geometry_type(vk::GeometryTypeKHR::TRIANGLES)
                    .geometry(vk::AccelerationStructureGeometryDataKHR {
                        triangles: vk::AccelerationStructureGeometryTrianglesDataKHR::default()
                            .vertex_format(vk::Format::R32G32B32_SFLOAT)
                            .vertex_data(vk::DeviceOrHostAddressConstKHR {
                                device_address: vb.address,
                            })
                            .vertex_stride(12)
                            .max_vertex(2)
                            .index_type(vk::IndexType::NONE_KHR),
                    })];
                let scratch = Allocation::new(
                    dev,
                    1 << 16,
                    vk::BufferUsageFlags::STORAGE_BUFFER
                        | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS,
                    vk::BufferCreateFlags::empty(),
                    256,
                )
                .map_err(realise_err)?;
                let bi = vk::AccelerationStructureBuildGeometryInfoKHR::default()
                    .ty(vk::AccelerationStructureTypeKHR::BOTTOM_LEVEL)
                    .mode(vk::BuildAccelerationStructureModeKHR::BUILD)
                    .geometries(&g)
                    .dst_acceleration_structure(blas)
                    .scratch_data(vk::DeviceOrHostAddressKHR {
                        device_address: scratch.address,
                    });
                cmds.begin(dev)?;
                // SAFETY: recording.
                unsafe {
                    accel.cmd_build_acceleration_structures(
                        cmds.cb,
                        &[bi],
                        &[&[vk::AccelerationStructureBuildRangeInfoKHR::default()
                            .primitive_count(1)]],
                    )
                };
                cmds.barrier(dev);
                cmds.submit(dev)?;
                extra.push(vb);
                extra.push(scratch);
            }
            let rays = expected_rays(&prims, top);
            let boxes = box_table(info, &prims);
            let (hits, direct) = build_and_trace(
                inst,
                dev,
                cmds,
                case,
                r,
                &ranges,
                BuildPath::Direct,
                check,
                &rays,
                &boxes,
            )?;
            let indirect = if dev.has_feature("accelerationStructureIndirectBuild") {
                let (hits, layer_vuids) = build_and_trace(
                    inst,
                    dev,
                    cmds,
                    case,
                    r,
                    &ranges,
                    BuildPath::Indirect,
                    check,
                    &rays,
                    &boxes,
                )?;
                Some(IndirectBuild { hits, layer_vuids })
            } else {
                None
            };
            Ok(TracedBuild {
                check,
                hits,
                direct_layer_vuids: direct,
                indirect,
            })
        })();
    for a in extra {
        a.destroy(dev);
    }
    result
}

/// Builds the case's destination one way, under the layer, and traces the rays at it (a bottom-level
/// result through a one-instance TLAS). Returns what each ray hit and the layer's VUIDs for the build.
#[allow(clippy::too_many_arguments)]
fn build_and_trace(
    inst: &VkInstance,
    dev: &VkDevice,
    cmds: &Commands,
    case: &AccelBody,
    r: &Realised,
    ranges: &[model::accel::RangeInfo],
    path: BuildPath,
    check: TraceCheck,
    rays: &[ExpectedRay],
    boxes: &[u8],
) -> Result<(Hits, Vec<String>), String> {
    let accel = dev
        .accel
        .as_ref()
        .ok_or("no acceleration structure extension")?;
    let info = &case.call.infos[0];
    let top = info.ty == AsType::TopLevel;
    let mut extra: Vec<Allocation> = Vec::new();
    let mut extra_as: Vec<vk::AccelerationStructureKHR> = Vec::new();
    let result = (|| -> Result<(Hits, Vec<String>), String> {
        let geoms = vk_geometries(info, r).ok_or("unsupported: geometry type not realised")?;
        inst.collector.clear();
        cmds.begin(dev)?;
        match path {
            BuildPath::Direct => {
                let vi = vk_info(info, &geoms, r);
                let vranges: Vec<vk::AccelerationStructureBuildRangeInfoKHR> = ranges
                    .iter()
                    .map(|x| vk::AccelerationStructureBuildRangeInfoKHR {
                        primitive_count: x.primitive_count,
                        primitive_offset: x.primitive_offset,
                        first_vertex: x.first_vertex,
                        transform_offset: x.transform_offset,
                    })
                    .collect();
                // SAFETY: recording a valid direct build.
                unsafe { accel.cmd_build_acceleration_structures(cmds.cb, &[vi], &[&vranges]) };
            }
            BuildPath::Indirect => {
                let all = [geoms.clone()];
                let (infos, addrs, maxima) = indirect_args(case, r, &all);
                // The range records are read by the build as indirect data.
                let b = vk::MemoryBarrier::default()
                    .src_access_mask(vk::AccessFlags::HOST_WRITE)
                    .dst_access_mask(vk::AccessFlags::INDIRECT_COMMAND_READ);
                // SAFETY: recording a valid indirect build on a device with accelerationStructureIndirectBuild.
                unsafe {
                    dev.device.cmd_pipeline_barrier(
                        cmds.cb,
                        vk::PipelineStageFlags::HOST,
                        vk::PipelineStageFlags::DRAW_INDIRECT,
                        vk::DependencyFlags::empty(),
                        &[b],
                        &[],
                        &[],
                    );
                    accel.cmd_build_acceleration_structures_indirect(
                        cmds.cb,
                        &infos,
                        &addrs,
                        &case.call.indirect_strides,
                        &maxima,
                    );
                }
            }
        }
        cmds.barrier(dev);
        cmds.submit(dev)?;
        let layer = error_ids(&inst.collector.take());
        let (dst, dst_addr) = r
            .structures
            .get(info.dst.as_deref().unwrap_or(""))
            .copied()
            .ok_or("no dst")?;
        let scene = if top {
            dst
        } else {
            let rec = vk::AccelerationStructureInstanceKHR {
                transform: vk::TransformMatrixKHR {
                    matrix: [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0],
                },
                instance_custom_index_and_mask: vk::Packed24_8::new(0, 0xff),
                instance_shader_binding_table_record_offset_and_flags: vk::Packed24_8::new(0, 0),
                acceleration_structure_reference: vk::AccelerationStructureReferenceKHR {
                    device_handle: dst_addr,
                },
            };
            let ib = Allocation::new(
                dev,
                64,
                vk::BufferUsageFlags::ACCELERATION_STRUCTURE_BUILD_INPUT_READ_ONLY_KHR
                    | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS,
                vk::BufferCreateFlags::empty(),
                256,
            )
            .map_err(realise_err)?;
            ib.write(0, crate::structs::as_bytes(&rec));
            let g = [vk::AccelerationStructureGeometryKHR::default()
                .geometry_type(vk::GeometryTypeKHR::INSTANCES)
                .geometry(vk::AccelerationStructureGeometryDataKHR {
                    instances: vk::AccelerationStructureGeometryInstancesDataKHR::default().data(
                        vk::DeviceOrHostAddressConstKHR {
                            device_address: ib.address,
                        },
                    ),
                })];
            let (tlas, _, st, sc) = build_direct(
                dev,
                cmds,
                vk::AccelerationStructureTypeKHR::TOP_LEVEL,
                &g,
                &[vk::AccelerationStructureBuildRangeInfoKHR::default().primitive_count(1)],
            )?;
            extra.extend([ib, st, sc]);
            extra_as.push(tlas);
            tlas
        };
        let procedural = info
            .geometries
            .iter()
            .any(|g| matches!(g.data, GeometryData::Aabbs { .. }));
        let words = match check {
            TraceCheck::Pipeline => {
                trace_pipeline(dev, cmds, scene, rays, boxes, procedural, &mut extra)?
            }
            _ => trace(dev, cmds, scene, rays, boxes, &mut extra)?,
        };
        let hits = words
            .iter()
            .map(|h| (h[0] == 1).then_some((h[1], h[2], h[3])))
            .collect();
        Ok((hits, layer))
    })();
    for s in extra_as {
        // SAFETY: idle.
        unsafe { accel.destroy_acceleration_structure(s, None) };
    }
    for a in extra {
        a.destroy(dev);
    }
    result
}

fn generator_blas() -> &'static str {
    "blas"
}

/// Per-geometry base indices (8 slots) and the boxes of every AABB primitive, as floats.
fn box_table(info: &BuildGeometryInfo, prims: &[BuiltPrimitive]) -> Vec<u8> {
    let mut base = [0u32; 8];
    let mut boxes: Vec<f32> = Vec::new();
    let mut n = 0u32;
    for g in 0..info.geometries.len().min(8) {
        base[g] = n;
        for p in prims.iter().filter(|p| p.geometry == g as u32) {
            if let Shape::Aabb { min, max } = &p.shape {
                boxes.extend([min[0], min[1], min[2], 0.0, max[0], max[1], max[2], 0.0]);
                n += 1;
            }
        }
    }
    let mut bytes: Vec<u8> = base.iter().flat_map(|b| b.to_le_bytes()).collect();
    bytes.extend(boxes.iter().flat_map(|f| f.to_le_bytes()));
    bytes.resize(bytes.len().max(64), 0);
    bytes
}

/// Traces the rays with the ray query shader; one `[hit, instance, geometry, primitive]` per ray.
fn trace(
    dev: &VkDevice,
    cmds: &Commands,
    scene: vk::AccelerationStructureKHR,
    rays: &[ExpectedRay],
    boxes: &[u8],
    keep: &mut Vec<Allocation>,
) -> Result<Vec<[u32; 4]>, String> {
    if rays.is_empty() {
        return Ok(vec![]);
    }
    let code = compile_trace_shader()?;
    let d = &dev.device;
    let sb = vk::BufferUsageFlags::STORAGE_BUFFER;
    let origins: Vec<u8> = rays
        .iter()
        .flat_map(|r| [r.origin[0], r.origin[1], r.origin[2], 0.0])
        .flat_map(|f: f32| f.to_le_bytes())
        .collect();
    let rb = Allocation::new(
        dev,
        origins.len() as u64,
        sb,
        vk::BufferCreateFlags::empty(),
        1,
    )
    .map_err(realise_err)?;
    rb.write(0, &origins);
    let hb = Allocation::new(
        dev,
        16 * rays.len() as u64,
        sb,
        vk::BufferCreateFlags::empty(),
        1,
    )
    .map_err(realise_err)?;
    let bb = Allocation::new(
        dev,
        boxes.len() as u64,
        sb,
        vk::BufferCreateFlags::empty(),
        1,
    )
    .map_err(realise_err)?;
    bb.write(0, boxes);
    let stage = vk::ShaderStageFlags::COMPUTE;
    let bind = |b: u32, t: vk::DescriptorType| {
        vk::DescriptorSetLayoutBinding::default()
            .binding(b)
            .descriptor_type(t)
            .descriptor_count(1)
            .stage_flags(stage)
    };
    let bindings = [
        bind(0, vk::DescriptorType::ACCELERATION_STRUCTURE_KHR),
        bind(1, vk::DescriptorType::STORAGE_BUFFER),
        bind(2, vk::DescriptorType::STORAGE_BUFFER),
        bind(3, vk::DescriptorType::STORAGE_BUFFER),
    ];
    // SAFETY: valid create infos; everything is destroyed below after the wait.
    let out = unsafe {
        let dsl = d
            .create_descriptor_set_layout(
                &vk::DescriptorSetLayoutCreateInfo::default().bindings(&bindings),
                None,
            )
            .map_err(fail("vkCreateDescriptorSetLayout"))?;
        let sets = [dsl];
        let pl = d
            .create_pipeline_layout(
                &vk::PipelineLayoutCreateInfo::default().set_layouts(&sets),
                None,
            )
            .map_err(fail("vkCreatePipelineLayout"))?;
        let module = d
            .create_shader_module(&vk::ShaderModuleCreateInfo::default().code(&code), None)
            .map_err(fail("vkCreateShaderModule"))?;
        let st = vk::PipelineShaderStageCreateInfo::default()
            .stage(stage)
            .module(module)
            .name(c"main");
        let pipe = d
            .create_compute_pipelines(
                vk::PipelineCache::null(),
                &[vk::ComputePipelineCreateInfo::default()
                    .stage(st)
                    .layout(pl)],
                None,
            )
            .map_err(|(_, r)| format!("vkCreateComputePipelines failed: {r:?}"))?[0];
        let sizes = [
            vk::DescriptorPoolSize {
                ty: vk::DescriptorType::ACCELERATION_STRUCTURE_KHR,
                descriptor_count: 1,
            },
            vk::DescriptorPoolSize {
                ty: vk::DescriptorType::STORAGE_BUFFER,
                descriptor_count: 3,
            },
        ];
        let pool = d
            .create_descriptor_pool(
                &vk::DescriptorPoolCreateInfo::default()
                    .max_sets(1)
                    .pool_sizes(&sizes),
                None,
            )
            .map_err(fail("vkCreateDescriptorPool"))?;
        let set = d
            .allocate_descriptor_sets(
                &vk::DescriptorSetAllocateInfo::default()
                    .descriptor_pool(pool)
                    .set_layouts(&sets),
            )
            .map_err(fail("vkAllocateDescriptorSets"))?[0];
        write_check_set(d, set, scene, [rb.buffer, hb.buffer, bb.buffer]);
        let run = (|| -> Result<(), String> {
            cmds.begin(dev)?;
            d.cmd_bind_pipeline(cmds.cb, vk::PipelineBindPoint::COMPUTE, pipe);
            d.cmd_bind_descriptor_sets(cmds.cb, vk::PipelineBindPoint::COMPUTE, pl, 0, &[set], &[]);
            d.cmd_dispatch(cmds.cb, rays.len() as u32, 1, 1);
            cmds.submit(dev)
        })();
        d.destroy_descriptor_pool(pool, None);
        d.destroy_pipeline(pipe, None);
        d.destroy_shader_module(module, None);
        d.destroy_pipeline_layout(pl, None);
        d.destroy_descriptor_set_layout(dsl, None);
        run.map(|()| {
            hb.read_u32s(4 * rays.len())
                .chunks_exact(4)
                .map(|c| [c[0], c[1], c[2], c[3]])
                .collect::<Vec<_>>()
        })
    };
    keep.extend([rb, hb, bb]);
    out
}

/// The pipeline check's shaders: raygen traces ray `i` from `origins[i]` along +z; closest-hit writes
/// `(1, gl_InstanceID, gl_GeometryIndexEXT, gl_PrimitiveID)`, miss writes zeros; the intersection
/// shader reports an AABB hit exactly where the ray query check generates one.
const PIPE_RGEN: &str = r#"#version 460
#extension GL_EXT_ray_tracing : require
layout(set = 0, binding = 0) uniform accelerationStructureEXT scene;
layout(set = 0, binding = 1, std430) readonly buffer Rays { vec4 origins[]; };
layout(set = 0, binding = 2, std430) buffer Hits { uvec4 hits[]; };
layout(location = 0) rayPayloadEXT uvec4 payload;
void main() {
    uint i = gl_LaunchIDEXT.x;
    payload = uvec4(0u);
    traceRayEXT(scene, gl_RayFlagsNoneEXT, 0xFF, 0, 0, 0, origins[i].xyz, 0.0, vec3(0.0, 0.0, 1.0), 100.0, 0);
    hits[i] = payload;
}
"#;

const PIPE_RCHIT: &str = r#"#version 460
#extension GL_EXT_ray_tracing : require
layout(location = 0) rayPayloadInEXT uvec4 payload;
void main() {
    payload = uvec4(1u, uint(gl_InstanceID), uint(gl_GeometryIndexEXT), uint(gl_PrimitiveID));
}
"#;

const PIPE_RMISS: &str = r#"#version 460
#extension GL_EXT_ray_tracing : require
layout(location = 0) rayPayloadInEXT uvec4 payload;
void main() {
    payload = uvec4(0u);
}
"#;

const PIPE_RINT: &str = r#"#version 460
#extension GL_EXT_ray_tracing : require
layout(set = 0, binding = 3, std430) readonly buffer Boxes { uint base[8]; vec4 box[]; };
void main() {
    uint g = gl_GeometryIndexEXT;
    uint p = gl_PrimitiveID;
    vec3 o = gl_ObjectRayOriginEXT;
    vec4 lo = box[2u * (base[g] + p)];
    vec4 hi = box[2u * (base[g] + p) + 1u];
    if (o.x >= lo.x && o.x <= hi.x && o.y >= lo.y && o.y <= hi.y) {
        reportIntersectionEXT(max(lo.z - o.z, 0.0), 0u);
    }
}
"#;

/// SPIR-V of the pipeline check's four shaders (raygen, miss, closest-hit, intersection), compiled once.
fn pipeline_shaders() -> Result<[Vec<u32>; 4], String> {
    static SPIRV: std::sync::OnceLock<Result<[Vec<u32>; 4], String>> = std::sync::OnceLock::new();
    SPIRV
        .get_or_init(|| {
            Ok([
                compile_glsl("check.rgen", PIPE_RGEN)?,
                compile_glsl("check.rmiss", PIPE_RMISS)?,
                compile_glsl("check.rchit", PIPE_RCHIT)?,
                compile_glsl("check.rint", PIPE_RINT)?,
            ])
        })
        .clone()
}

fn align_up(v: u64, a: u64) -> u64 {
    v.div_ceil(a.max(1)) * a.max(1)
}

/// Traces the rays with a ray tracing pipeline (for devices without ray query); one
/// `[hit, instance, geometry, primitive]` per ray, as [`trace`] reports them. Every geometry uses hit
/// record 0 (sbtRecordStride 0): the triangles hit group, or the procedural one for AABB builds.
fn trace_pipeline(
    dev: &VkDevice,
    cmds: &Commands,
    scene: vk::AccelerationStructureKHR,
    rays: &[ExpectedRay],
    boxes: &[u8],
    procedural: bool,
    keep: &mut Vec<Allocation>,
) -> Result<Vec<[u32; 4]>, String> {
    if rays.is_empty() {
        return Ok(vec![]);
    }
    let rt = dev
        .rt
        .as_ref()
        .ok_or("unsupported: the pipeline check needs VK_KHR_ray_tracing_pipeline")?;
    let code = pipeline_shaders()?;
    let d = &dev.device;
    let sb = vk::BufferUsageFlags::STORAGE_BUFFER;
    let origins: Vec<u8> = rays
        .iter()
        .flat_map(|r| [r.origin[0], r.origin[1], r.origin[2], 0.0])
        .flat_map(|f: f32| f.to_le_bytes())
        .collect();
    let rb = Allocation::new(
        dev,
        origins.len() as u64,
        sb,
        vk::BufferCreateFlags::empty(),
        1,
    )
    .map_err(realise_err)?;
    rb.write(0, &origins);
    keep.push(rb);
    let hb = Allocation::new(
        dev,
        16 * rays.len() as u64,
        sb,
        vk::BufferCreateFlags::empty(),
        1,
    )
    .map_err(realise_err)?;
    keep.push(hb);
    let bb = Allocation::new(
        dev,
        boxes.len() as u64,
        sb,
        vk::BufferCreateFlags::empty(),
        1,
    )
    .map_err(realise_err)?;
    bb.write(0, boxes);
    keep.push(bb);
    let (rb, hb, bb) = (
        &keep[keep.len() - 3],
        &keep[keep.len() - 2],
        &keep[keep.len() - 1],
    );
    let (rb_buf, hb_buf, bb_buf) = (rb.buffer, hb.buffer, bb.buffer);
    let stages = vk::ShaderStageFlags::RAYGEN_KHR | vk::ShaderStageFlags::INTERSECTION_KHR;
    let bind = |b: u32, t: vk::DescriptorType| {
        vk::DescriptorSetLayoutBinding::default()
            .binding(b)
            .descriptor_type(t)
            .descriptor_count(1)
            .stage_flags(stages)
    };
    let bindings = [
        bind(0, vk::DescriptorType::ACCELERATION_STRUCTURE_KHR),
        bind(1, vk::DescriptorType::STORAGE_BUFFER),
        bind(2, vk::DescriptorType::STORAGE_BUFFER),
        bind(3, vk::DescriptorType::STORAGE_BUFFER),
    ];
    let l = dev.limits;
    let handle = l.handle_size as u64;
    let record = align_up(handle, l.handle_alignment as u64);
    let region = align_up(record, l.base_alignment as u64);
    // SAFETY: valid create infos; everything made here is destroyed below after the wait.
    unsafe {
        let dsl = d
            .create_descriptor_set_layout(
                &vk::DescriptorSetLayoutCreateInfo::default().bindings(&bindings),
                None,
            )
            .map_err(fail("vkCreateDescriptorSetLayout"))?;
        let sets = [dsl];
        let pl = d.create_pipeline_layout(
            &vk::PipelineLayoutCreateInfo::default().set_layouts(&sets),
            None,
        );
        let mut modules = Vec::new();
        let made = (|| -> Result<Vec<[u32; 4]>, String> {
            let pl = pl.map_err(fail("vkCreatePipelineLayout"))?;
            let kinds = [
                vk::ShaderStageFlags::RAYGEN_KHR,
                vk::ShaderStageFlags::MISS_KHR,
                vk::ShaderStageFlags::CLOSEST_HIT_KHR,
                vk::ShaderStageFlags::INTERSECTION_KHR,
            ];
            for c in &code {
                modules.push(
                    d.create_shader_module(&vk::ShaderModuleCreateInfo::default().code(c), None)
                        .map_err(fail("vkCreateShaderModule"))?,
                );
            }
            let st: Vec<vk::PipelineShaderStageCreateInfo> = modules
                .iter()
                .zip(kinds)
                .map(|(m, k)| {
                    vk::PipelineShaderStageCreateInfo::default()
                        .stage(k)
                        .module(*m)
                        .name(c"main")
                })
                .collect();
            let unused = vk::SHADER_UNUSED_KHR;
            let general = |s: u32| {
                vk::RayTracingShaderGroupCreateInfoKHR::default()
                    .ty(vk::RayTracingShaderGroupTypeKHR::GENERAL)
                    .general_shader(s)
                    .closest_hit_shader(unused)
                    .any_hit_shader(unused)
                    .intersection_shader(unused)
            };
            let groups = [
                general(0),
                general(1),
                vk::RayTracingShaderGroupCreateInfoKHR::default()
                    .ty(vk::RayTracingShaderGroupTypeKHR::TRIANGLES_HIT_GROUP)
                    .general_shader(unused)
                    .closest_hit_shader(2)
                    .any_hit_shader(unused)
                    .intersection_shader(unused),
                vk::RayTracingShaderGroupCreateInfoKHR::default()
                    .ty(vk::RayTracingShaderGroupTypeKHR::PROCEDURAL_HIT_GROUP)
                    .general_shader(unused)
                    .closest_hit_shader(2)
                    .any_hit_shader(unused)
                    .intersection_shader(3),
            ];
            let ci = vk::RayTracingPipelineCreateInfoKHR::default()
                .stages(&st)
                .groups(&groups)
                .max_pipeline_ray_recursion_depth(1)
                .layout(pl);
            let pipe = rt
                .create_ray_tracing_pipelines(
                    vk::DeferredOperationKHR::null(),
                    vk::PipelineCache::null(),
                    &[ci],
                    None,
                )
                .map_err(|(_, r)| format!("vkCreateRayTracingPipelinesKHR failed: {r:?}"))?[0];
            let inner = (|| -> Result<Vec<[u32; 4]>, String> {
                let handles = rt
                    .get_ray_tracing_shader_group_handles(pipe, 0, 4, 4 * handle as usize)
                    .map_err(fail("vkGetRayTracingShaderGroupHandlesKHR"))?;
                let h = |g: usize| &handles[g * handle as usize..(g + 1) * handle as usize];
                let sbt = Allocation::new(
                    dev,
                    3 * region,
                    vk::BufferUsageFlags::SHADER_BINDING_TABLE_KHR
                        | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS,
                    vk::BufferCreateFlags::empty(),
                    l.base_alignment.max(1) as u64,
                )
                .map_err(realise_err)?;
                sbt.write(0, h(0));
                sbt.write(region, h(1));
                sbt.write(2 * region, h(if procedural { 3 } else { 2 }));
                let at = |k: u64| vk::StridedDeviceAddressRegionKHR {
                    device_address: sbt.address + k * region,
                    stride: record,
                    size: record,
                };
                let rgen = vk::StridedDeviceAddressRegionKHR {
                    stride: record,
                    ..at(0)
                };
                let (miss, hit) = (at(1), at(2));
                let call = vk::StridedDeviceAddressRegionKHR::default();
                let sizes = [
                    vk::DescriptorPoolSize {
                        ty: vk::DescriptorType::ACCELERATION_STRUCTURE_KHR,
                        descriptor_count: 1,
                    },
                    vk::DescriptorPoolSize {
                        ty: vk::DescriptorType::STORAGE_BUFFER,
                        descriptor_count: 3,
                    },
                ];
                let pool = d
                    .create_descriptor_pool(
                        &vk::DescriptorPoolCreateInfo::default()
                            .max_sets(1)
                            .pool_sizes(&sizes),
                        None,
                    )
                    .map_err(fail("vkCreateDescriptorPool"))?;
                let run = (|| -> Result<(), String> {
                    let set = d
                        .allocate_descriptor_sets(
                            &vk::DescriptorSetAllocateInfo::default()
                                .descriptor_pool(pool)
                                .set_layouts(&sets),
                        )
                        .map_err(fail("vkAllocateDescriptorSets"))?[0];
                    write_check_set(d, set, scene, [rb_buf, hb_buf, bb_buf]);
                    cmds.begin(dev)?;
                    d.cmd_bind_pipeline(cmds.cb, vk::PipelineBindPoint::RAY_TRACING_KHR, pipe);
                    d.cmd_bind_descriptor_sets(
                        cmds.cb,
                        vk::PipelineBindPoint::RAY_TRACING_KHR,
                        pl,
                        0,
                        &[set],
                        &[],
                    );
                    rt.cmd_trace_rays(cmds.cb, &rgen, &miss, &hit, &call, rays.len() as u32, 1, 1);
                    cmds.submit(dev)
                })();
                d.destroy_descriptor_pool(pool, None);
                sbt.destroy(dev);
                run.map(|()| {
                    hb.read_u32s(4 * rays.len())
                        .chunks_exact(4)
                        .map(|c| [c[0], c[1], c[2], c[3]])
                        .collect()
                })
            })();
            d.destroy_pipeline(pipe, None);
            inner
        })();
        for m in modules {
            d.destroy_shader_module(m, None);
        }
        if let Ok(pl) = pl {
            d.destroy_pipeline_layout(pl, None);
        }
        d.destroy_descriptor_set_layout(dsl, None);
        made
    }
}

/// What the device built for a case, seen through arbitrary rays: the case's first info built directly
/// with the ranges the model reads from memory, then one ray (+z, t in [0, 100]) from each origin. For
/// writing down what a driver built where no named deviation explains it.
pub fn probe_rays(
    inst: &Arc<VkInstance>,
    case: &Case,
    origins: &[[f32; 3]],
    check: TraceCheck,
) -> Result<Hits, String> {
    let case = case.as_accel().ok_or("probing needs a build case")?;
    let dev = device_for(inst, case, check)?;
    let check = resolve_check(&dev, check)?;
    let cmds = Commands::new(&dev)?;
    let r = match realise(&dev, case, cmds.fence) {
        Ok(r) => r,
        Err(e) => {
            cmds.destroy(&dev);
            return Err(e);
        }
    };
    let out = (|| -> Result<Hits, String> {
        let info = case.call.infos.first().ok_or("no build info")?;
        if info.ty != AsType::BottomLevel {
            return Err("unsupported: probing handles bottom-level builds".into());
        }
        let mem = case.world.memory();
        let ranges =
            model::accel::indirect_ranges(&mem, &case.call, 0).map_err(|e| e.to_string())?;
        let prims =
            model::accel::build_primitives(&mem, info, &ranges).map_err(|e| e.to_string())?;
        drop(mem);
        let rays: Vec<ExpectedRay> = origins
            .iter()
            .map(|o| ExpectedRay {
                origin: *o,
                hit: None,
            })
            .collect();
        let boxes = box_table(info, &prims);
        let (hits, _) = build_and_trace(
            inst,
            &dev,
            &cmds,
            case,
            &r,
            &ranges,
            BuildPath::Direct,
            check,
            &rays,
            &boxes,
        )?;
        Ok(hits)
    })();
    cmds.destroy(&dev);
    r.destroy(&dev);
    out
}

/// Writes the traced check's descriptor set: the structure under test at binding 0 and the rays, hits
/// and built-primitive buffers at bindings 1 to 3 (the same layout for the ray-query and the pipeline path).
///
/// # Safety
/// `set` is a set of the check's layout that no pending command uses; the handles are live.
unsafe fn write_check_set(
    d: &ash::Device,
    set: vk::DescriptorSet,
    scene: vk::AccelerationStructureKHR,
    buffers: [vk::Buffer; 3],
) {
    let scenes = [scene];
    let mut asw =
        vk::WriteDescriptorSetAccelerationStructureKHR::default().acceleration_structures(&scenes);
    let infos = buffers.map(|buffer| {
        [vk::DescriptorBufferInfo {
            buffer,
            offset: 0,
            range: vk::WHOLE_SIZE,
        }]
    });
    let mut w0 = vk::WriteDescriptorSet::default()
        .dst_set(set)
        .dst_binding(0)
        .descriptor_type(vk::DescriptorType::ACCELERATION_STRUCTURE_KHR)
        .push_next(&mut asw);
    w0.descriptor_count = 1;
    fn buffer_write(
        set: vk::DescriptorSet,
        binding: u32,
        info: &[vk::DescriptorBufferInfo; 1],
    ) -> vk::WriteDescriptorSet<'_> {
        vk::WriteDescriptorSet::default()
            .dst_set(set)
            .dst_binding(binding)
            .descriptor_type(vk::DescriptorType::STORAGE_BUFFER)
            .buffer_info(info)
    }
    let writes = [
        w0,
        buffer_write(set, 1, &infos[0]),
        buffer_write(set, 2, &infos[1]),
        buffer_write(set, 3, &infos[2]),
    ];
    // SAFETY: guaranteed by the caller.
    unsafe { d.update_descriptor_sets(&writes, &[]) };
}
