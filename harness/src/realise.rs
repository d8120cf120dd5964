//! Realises a case's world on a device: buffers placed at 4096-aligned addresses with their contents (shader
//! group handles, indirect commands), the ray tracing pipeline with one specialised stage per group, and the
//! scene (one BLAS per instance, a TLAS). Pipelines and scenes are cached per device across cases.

use crate::error::HarnessError;
use crate::shaders::{self, ShaderKind};
use crate::vulkan::VkDevice;
use ash::vk;
use model::call::BUFFER_PLACEMENT_ALIGNMENT;
use model::world::{
    Contents, GeneralStage, GeometryKind, HandleRef, Instance, Pipeline, PipelineApi, ShaderGroup,
    World,
};
use std::collections::HashMap;

/// Why a case could not be realised.
#[derive(Debug)]
pub enum RealiseError {
    Unsupported(String),
    Failed(String),
}

impl From<HarnessError> for RealiseError {
    fn from(e: HarnessError) -> Self {
        RealiseError::Failed(e.to_string())
    }
}

fn vkfail(what: &'static str) -> impl Fn(vk::Result) -> RealiseError {
    move |r| RealiseError::Failed(format!("{what} failed: {r:?}"))
}

/// One memory object behind (part of) a buffer: where it sits in the buffer and its host mapping.
struct Piece {
    memory: vk::DeviceMemory,
    /// Byte offset in the buffer where this memory's range starts.
    at: u64,
    /// Bytes of the buffer backed by this memory.
    len: u64,
    /// Host pointer to the buffer byte `at`.
    ptr: *mut u8,
}

/// A buffer with host-visible memory, mapped, and its device address (0 without bufferDeviceAddress). Most
/// buffers have one memory object; a sparse buffer of a `Scattered` case has two, and an `Unbound` sparse
/// buffer none. Memory that is not HOST_COHERENT is flushed after host writes and invalidated before reads.
pub struct Allocation {
    pub buffer: vk::Buffer,
    pub address: u64,
    pub size: u64,
    pieces: Vec<Piece>,
    /// The device, kept only when the memory is not HOST_COHERENT (to flush and invalidate).
    non_coherent: Option<ash::Device>,
}

/// How a buffer's pages are bound, for [`Allocation::sparse`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SparsePlan {
    /// No memory bound at all.
    Unbound,
    /// The whole buffer bound to one memory object.
    One,
    /// The first half of the sparse blocks bound to one memory object, the rest to a second.
    Two,
}

/// A host-visible memory type for `bits`: coherent if there is one, else any host-visible type (flushed).
fn host_memory_type(dev: &VkDevice, bits: u32) -> Option<(u32, bool)> {
    let visible = vk::MemoryPropertyFlags::HOST_VISIBLE;
    dev.memory_type(bits, visible | vk::MemoryPropertyFlags::HOST_COHERENT)
        .map(|t| (t, true))
        .or_else(|| dev.memory_type(bits, visible).map(|t| (t, false)))
}

fn allocate(dev: &VkDevice, size: u64, memory_type: u32) -> Result<vk::DeviceMemory, RealiseError> {
    let mut flags_info =
        vk::MemoryAllocateFlagsInfo::default().flags(vk::MemoryAllocateFlags::DEVICE_ADDRESS);
    let mut ai = vk::MemoryAllocateInfo::default()
        .allocation_size(size)
        .memory_type_index(memory_type);
    if dev.has_feature("bufferDeviceAddress") {
        ai = ai.push_next(&mut flags_info);
    }
    // SAFETY: valid allocate info.
    unsafe { dev.device.allocate_memory(&ai, None) }
        .map_err(|r| RealiseError::Failed(format!("vkAllocateMemory({size}) failed: {r:?}")))
}

fn address_of(dev: &VkDevice, b: vk::Buffer) -> u64 {
    if dev.has_feature("bufferDeviceAddress") {
        // SAFETY: b is bound completely to memory allocated with DEVICE_ADDRESS, or sparse
        // (VUID-VkBufferDeviceAddressInfo-buffer-02600 exempts sparse buffers).
        unsafe {
            dev.device
                .get_buffer_device_address(&vk::BufferDeviceAddressInfo::default().buffer(b))
        }
    } else {
        0
    }
}

impl Allocation {
    /// Creates a buffer of `size` bytes, binds it to its own host-visible memory at an address that is a
    /// multiple of `align` (when `align` > 1), and maps it.
    pub fn new(
        dev: &VkDevice,
        size: u64,
        usage: vk::BufferUsageFlags,
        flags: vk::BufferCreateFlags,
        align: u64,
    ) -> Result<Allocation, RealiseError> {
        let d = &dev.device;
        let info = vk::BufferCreateInfo::default()
            .size(size.max(1))
            .usage(usage)
            .flags(flags);
        // SAFETY: valid create info.
        let mut buffer =
            unsafe { d.create_buffer(&info, None) }.map_err(vkfail("vkCreateBuffer"))?;
        // SAFETY: buffer is valid.
        let req = unsafe { d.get_buffer_memory_requirements(buffer) };
        let Some((mt, coherent)) = host_memory_type(dev, req.memory_type_bits) else {
            // SAFETY: destroying what we created.
            unsafe { d.destroy_buffer(buffer, None) };
            return Err(RealiseError::Unsupported(
                "no host-visible memory type for a buffer".into(),
            ));
        };
        let bda = dev.has_feature("bufferDeviceAddress");
        let alloc_size = req.size + if align > 1 { align } else { 0 };
        let memory = match allocate(dev, alloc_size, mt) {
            Ok(m) => m,
            Err(e) => {
                // SAFETY: destroying what we created.
                unsafe { d.destroy_buffer(buffer, None) };
                return Err(e);
            }
        };
        let cleanup = |buffer: vk::Buffer| {
            // SAFETY: destroying what we created.
            unsafe {
                d.destroy_buffer(buffer, None);
                d.free_memory(memory, None);
            }
        };
        // SAFETY: fresh buffer, fresh memory large enough.
        if let Err(r) = unsafe { d.bind_buffer_memory(buffer, memory, 0) } {
            cleanup(buffer);
            return Err(RealiseError::Failed(format!(
                "vkBindBufferMemory failed: {r:?}"
            )));
        }
        let mut address = address_of(dev, buffer);
        let mut offset = 0;
        if bda && align > 1 && address % align != 0 {
            let delta = align - address % align;
            if delta % req.alignment.max(1) != 0 {
                cleanup(buffer);
                return Err(RealiseError::Unsupported(format!(
                    "cannot place a buffer at a {align}-aligned device address (memory at {address:#x}, alignment {})",
                    req.alignment
                )));
            }
            // SAFETY: replacing the buffer by an identical one bound at the aligning offset.
            unsafe { d.destroy_buffer(buffer, None) };
            // SAFETY: valid create info.
            buffer = match unsafe { d.create_buffer(&info, None) } {
                Ok(b) => b,
                Err(r) => {
                    // SAFETY: freeing what we allocated.
                    unsafe { d.free_memory(memory, None) };
                    return Err(RealiseError::Failed(format!(
                        "vkCreateBuffer failed: {r:?}"
                    )));
                }
            };
            // SAFETY: offset + size fits the allocation.
            if let Err(r) = unsafe { d.bind_buffer_memory(buffer, memory, delta) } {
                cleanup(buffer);
                return Err(RealiseError::Failed(format!(
                    "vkBindBufferMemory failed: {r:?}"
                )));
            }
            offset = delta;
            address = address_of(dev, buffer);
            if address % align != 0 {
                cleanup(buffer);
                return Err(RealiseError::Unsupported(format!(
                    "the driver placed a buffer at {address:#x}, not a multiple of {align}"
                )));
            }
        }
        // SAFETY: host-visible memory, whole range.
        let ptr =
            match unsafe { d.map_memory(memory, 0, vk::WHOLE_SIZE, vk::MemoryMapFlags::empty()) } {
                Ok(p) => p as *mut u8,
                Err(r) => {
                    cleanup(buffer);
                    return Err(RealiseError::Failed(format!("vkMapMemory failed: {r:?}")));
                }
            };
        // SAFETY: mapped range covers offset..offset+size.
        let ptr = unsafe { ptr.add(offset as usize) };
        let a = Allocation {
            buffer,
            address,
            size,
            pieces: vec![Piece {
                memory,
                at: 0,
                len: size,
                ptr,
            }],
            non_coherent: (!coherent).then(|| d.clone()),
        };
        a.write(0, &vec![0u8; size as usize]);
        Ok(a)
    }

    /// Creates a sparse buffer (`flags` has SPARSE_BINDING) and binds its pages with `vkQueueBindSparse` as
    /// `plan` says, waiting on `fence` (unsignalled, left unsignalled) for the binding to finish.
    pub fn sparse(
        dev: &VkDevice,
        fence: vk::Fence,
        size: u64,
        usage: vk::BufferUsageFlags,
        flags: vk::BufferCreateFlags,
        plan: SparsePlan,
    ) -> Result<Allocation, RealiseError> {
        let d = &dev.device;
        let info = vk::BufferCreateInfo::default()
            .size(size.max(1))
            .usage(usage)
            .flags(flags);
        // SAFETY: valid create info (the caller checked sparseBinding is enabled).
        let buffer = unsafe { d.create_buffer(&info, None) }.map_err(vkfail("vkCreateBuffer"))?;
        let mut a = Allocation {
            buffer,
            address: 0,
            size,
            pieces: Vec::new(),
            non_coherent: None,
        };
        match a.bind_sparse(dev, fence, plan) {
            Ok(()) => Ok(a),
            Err(e) => {
                a.destroy(dev);
                Err(e)
            }
        }
    }

    fn bind_sparse(
        &mut self,
        dev: &VkDevice,
        fence: vk::Fence,
        plan: SparsePlan,
    ) -> Result<(), RealiseError> {
        let d = &dev.device;
        // SAFETY: valid buffer.
        let req = unsafe { d.get_buffer_memory_requirements(self.buffer) };
        let block = req.alignment.max(1);
        let blocks = req.size.div_ceil(block);
        let ranges: Vec<(u64, u64)> = match plan {
            SparsePlan::Unbound => vec![],
            SparsePlan::One => vec![(0, blocks * block)],
            SparsePlan::Two if blocks < 2 => {
                return Err(RealiseError::Unsupported(format!(
                    "a sparse buffer of {} bytes is one sparse block ({block} bytes) here, so its pages cannot be \
                     scattered over two memory objects",
                    self.size
                )))
            }
            SparsePlan::Two => vec![(0, blocks / 2 * block), (blocks / 2 * block, (blocks - blocks / 2) * block)],
        };
        if !ranges.is_empty() {
            let Some((mt, coherent)) = host_memory_type(dev, req.memory_type_bits) else {
                return Err(RealiseError::Unsupported(
                    "no host-visible memory type for a sparse buffer (the harness writes its contents from the host)".into(),
                ));
            };
            if !coherent {
                self.non_coherent = Some(d.clone());
            }
            for &(at, len) in &ranges {
                let memory = allocate(dev, len, mt)?;
                // SAFETY: host-visible memory, whole range.
                let ptr = match unsafe {
                    d.map_memory(memory, 0, vk::WHOLE_SIZE, vk::MemoryMapFlags::empty())
                } {
                    Ok(p) => p as *mut u8,
                    Err(r) => {
                        // SAFETY: freeing what we allocated.
                        unsafe { d.free_memory(memory, None) };
                        return Err(RealiseError::Failed(format!("vkMapMemory failed: {r:?}")));
                    }
                };
                self.pieces.push(Piece {
                    memory,
                    at,
                    len,
                    ptr,
                });
            }
            let binds: Vec<vk::SparseMemoryBind> = self
                .pieces
                .iter()
                .map(|p| vk::SparseMemoryBind {
                    resource_offset: p.at,
                    size: p.len,
                    memory: p.memory,
                    memory_offset: 0,
                    flags: Default::default(),
                })
                .collect();
            let buffer_binds = [vk::SparseBufferMemoryBindInfo::default()
                .buffer(self.buffer)
                .binds(&binds)];
            let bind = [vk::BindSparseInfo::default().buffer_binds(&buffer_binds)];
            // SAFETY: the queue's family has SPARSE_BINDING (checked by the caller); the fence is unsignalled.
            unsafe {
                d.queue_bind_sparse(dev.queue, &bind, fence)
                    .map_err(vkfail("vkQueueBindSparse"))?;
                d.wait_for_fences(&[fence], true, 10_000_000_000)
                    .map_err(vkfail("vkWaitForFences (sparse binding)"))?;
                d.reset_fences(&[fence]).map_err(vkfail("vkResetFences"))?;
            }
            self.write(0, &vec![0u8; self.size as usize]);
        }
        self.address = address_of(dev, self.buffer);
        if dev.has_feature("bufferDeviceAddress") && self.address % BUFFER_PLACEMENT_ALIGNMENT != 0
        {
            return Err(RealiseError::Unsupported(format!(
                "the driver placed a sparse buffer at {:#x}, not a multiple of {BUFFER_PLACEMENT_ALIGNMENT}",
                self.address
            )));
        }
        Ok(())
    }

    /// The memory objects behind the buffer (one, two for a scattered sparse buffer, none when unbound).
    pub fn memory_count(&self) -> usize {
        self.pieces.len()
    }

    /// Copies `bytes` to `offset`, cutting what would fall past the end of the buffer or onto unbound pages.
    pub fn write(&self, offset: u64, bytes: &[u8]) {
        let end = (offset + bytes.len() as u64).min(self.size);
        for p in &self.pieces {
            let (lo, hi) = (offset.max(p.at), end.min(p.at + p.len));
            if lo >= hi {
                continue;
            }
            // SAFETY: lo..hi lies inside this piece's mapped range.
            unsafe {
                std::ptr::copy_nonoverlapping(
                    bytes.as_ptr().add((lo - offset) as usize),
                    p.ptr.add((lo - p.at) as usize),
                    (hi - lo) as usize,
                )
            };
        }
        self.sync(true);
    }

    pub fn read_u32s(&self, count: usize) -> Vec<u32> {
        self.sync(false);
        let n = count.min((self.size / 4) as usize);
        let mut bytes = vec![0u8; n * 4];
        for p in &self.pieces {
            let (lo, hi) = (
                p.at.min(bytes.len() as u64),
                (p.at + p.len).min(bytes.len() as u64),
            );
            if lo < hi {
                // SAFETY: lo..hi lies inside this piece's mapped range.
                unsafe {
                    std::ptr::copy_nonoverlapping(
                        p.ptr,
                        bytes.as_mut_ptr().add(lo as usize),
                        (hi - lo) as usize,
                    )
                };
            }
        }
        bytes
            .chunks_exact(4)
            .map(|c| u32::from_ne_bytes([c[0], c[1], c[2], c[3]]))
            .collect()
    }

    /// Flushes host writes (`to_device`) or invalidates host caches before reading, on non-coherent memory.
    fn sync(&self, to_device: bool) {
        let Some(d) = &self.non_coherent else { return };
        let ranges: Vec<vk::MappedMemoryRange> = self
            .pieces
            .iter()
            .map(|p| {
                vk::MappedMemoryRange::default()
                    .memory(p.memory)
                    .offset(0)
                    .size(vk::WHOLE_SIZE)
            })
            .collect();
        // SAFETY: every memory object is mapped whole; WHOLE_SIZE from offset 0 needs no atom alignment.
        unsafe {
            let _ = if to_device {
                d.flush_mapped_memory_ranges(&ranges)
            } else {
                d.invalidate_mapped_memory_ranges(&ranges)
            };
        }
    }

    pub fn destroy(self, dev: &VkDevice) {
        // SAFETY: the GPU no longer uses the buffer (callers wait first, or the device is lost).
        unsafe {
            dev.device.destroy_buffer(self.buffer, None);
            for p in &self.pieces {
                dev.device.unmap_memory(p.memory);
                dev.device.free_memory(p.memory, None);
            }
        }
    }
}

/// The descriptor set layout and pipeline layout of one raygen variant.
#[derive(Clone, Copy)]
pub struct Layouts {
    pub set: vk::DescriptorSetLayout,
    pub pipeline: vk::PipelineLayout,
}

/// A created ray tracing pipeline and its group handles.
pub struct RealPipeline {
    pub pipeline: vk::Pipeline,
    pub handles: Vec<u8>,
    pub group_count: usize,
    /// The stack size the spec's default formula gives for the pipeline's recursion depth (section "Ray
    /// Tracing Pipeline Stack"), used for `vkCmdSetRayTracingPipelineStackSizeKHR`; 0 for NV pipelines.
    pub default_stack_size: u32,
}

/// The top-level structure of a built scene, of the extension the case's pipeline uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Tlas {
    Khr(vk::AccelerationStructureKHR),
    Nv(vk::AccelerationStructureNV),
}

/// A built scene: BLASes, TLAS and their buffers (and, for NV structures, their memory).
pub struct Scene {
    pub tlas: Tlas,
    structures: Vec<vk::AccelerationStructureKHR>,
    nv_structures: Vec<vk::AccelerationStructureNV>,
    nv_memory: Vec<vk::DeviceMemory>,
    buffers: Vec<Allocation>,
}

/// The stack size of the spec's default pipeline stack computation ("Ray Tracing Pipeline Stack"):
/// `raygen + min(1, depth) × max(closestHit, miss, intersection + anyHit) + max(0, depth - 1) ×
/// max(closestHit, miss) + 2 × callable`, each term the largest stack size of that shader kind. A pipeline
/// with dynamic stack size must be given at least this (an arbitrary constant is too small on real GPUs
/// once closest-hit shaders trace again).
fn default_stack_size(
    rt: &ash::khr::ray_tracing_pipeline::Device,
    pipeline: vk::Pipeline,
    groups: &[(vk::RayTracingShaderGroupTypeKHR, [u32; 4])],
    depth: u32,
) -> u32 {
    let unused = vk::SHADER_UNUSED_KHR;
    let (mut raygen, mut miss, mut callable, mut closest, mut any, mut isect) =
        (0u64, 0u64, 0u64, 0u64, 0u64, 0u64);
    for (g, (ty, [gen, ch, ah, is])) in groups.iter().enumerate() {
        // SAFETY: valid pipeline and group; only shaders the group has are queried.
        let size = |which| unsafe {
            rt.get_ray_tracing_shader_group_stack_size(pipeline, g as u32, which)
        };
        if *ty == vk::RayTracingShaderGroupTypeKHR::GENERAL && *gen != unused {
            // Which general stage this is does not matter for the maximum of its own kind; count it in all
            // three general kinds conservatively.
            let s = size(vk::ShaderGroupShaderKHR::GENERAL);
            raygen = raygen.max(s);
            miss = miss.max(s);
            callable = callable.max(s);
        }
        if *ch != unused {
            closest = closest.max(size(vk::ShaderGroupShaderKHR::CLOSEST_HIT));
        }
        if *ah != unused {
            any = any.max(size(vk::ShaderGroupShaderKHR::ANY_HIT));
        }
        if *is != unused {
            isect = isect.max(size(vk::ShaderGroupShaderKHR::INTERSECTION));
        }
    }
    let d = depth as u64;
    let total = raygen
        + d.min(1) * closest.max(miss).max(isect + any)
        + d.saturating_sub(1) * closest.max(miss)
        + 2 * callable;
    total.min(u32::MAX as u64) as u32
}

/// Per-device objects the harness reuses across cases.
pub struct DeviceCache {
    modules: HashMap<(ShaderKind, bool), vk::ShaderModule>,
    layouts: HashMap<(bool, bool), Layouts>,
    pipelines: HashMap<String, Result<RealPipeline, String>>,
    scenes: HashMap<String, Result<Scene, String>>,
    pub command_pool: vk::CommandPool,
    pub primary: vk::CommandBuffer,
    pub secondary: vk::CommandBuffer,
    pub fence: vk::Fence,
    pub descriptor_pool: vk::DescriptorPool,
    /// Output words and rays, reused and grown as needed.
    pub output: Option<Allocation>,
    pub rays: Option<Allocation>,
    /// The callable record indices the raygen executes: a 16-byte header (count) and one u32 each.
    pub callables: Option<Allocation>,
    /// Set when a submission ended in DEVICE_LOST or a timeout: nothing may be recorded on this device
    /// again, and dropping it neither waits for it nor resets what is pending on it.
    pub lost: bool,
    pub render_pass: Option<(vk::RenderPass, vk::Framebuffer)>,
    /// issue 4 hook: the pipeline of a case with a resource state (its own raygen module and pipeline
    /// layout, made by `crate::resources`), returned by [`DeviceCache::pipeline`] for the case's own
    /// (non-foreign) pipeline while that case runs. Owned and destroyed by `crate::resources::Realised`.
    pub resource_pipeline: Option<RealPipeline>,
    pub dev: VkDevice,
}

/// The ray data the raygen shader reads: std430 `Ray` (64 bytes) after a 16-byte header.
pub const RAY_RECORD_SIZE: usize = 64;

impl DeviceCache {
    pub fn new(dev: VkDevice) -> Result<DeviceCache, RealiseError> {
        let d = &dev.device;
        // SAFETY: valid create infos on a live device.
        unsafe {
            let command_pool = d
                .create_command_pool(
                    &vk::CommandPoolCreateInfo::default()
                        .queue_family_index(dev.queue_family)
                        .flags(vk::CommandPoolCreateFlags::RESET_COMMAND_BUFFER),
                    None,
                )
                .map_err(vkfail("vkCreateCommandPool"))?;
            let alloc = |level| {
                d.allocate_command_buffers(
                    &vk::CommandBufferAllocateInfo::default()
                        .command_pool(command_pool)
                        .level(level)
                        .command_buffer_count(1),
                )
                .map(|v| v[0])
            };
            let primary = alloc(vk::CommandBufferLevel::PRIMARY)
                .map_err(vkfail("vkAllocateCommandBuffers"))?;
            let secondary = alloc(vk::CommandBufferLevel::SECONDARY)
                .map_err(vkfail("vkAllocateCommandBuffers"))?;
            let fence = d
                .create_fence(&vk::FenceCreateInfo::default(), None)
                .map_err(vkfail("vkCreateFence"))?;
            let mut sizes = vec![vk::DescriptorPoolSize {
                ty: vk::DescriptorType::STORAGE_BUFFER,
                descriptor_count: 6,
            }];
            if dev.accel.is_some() {
                sizes.push(vk::DescriptorPoolSize {
                    ty: vk::DescriptorType::ACCELERATION_STRUCTURE_KHR,
                    descriptor_count: 2,
                });
            }
            if dev.nv.is_some() {
                sizes.push(vk::DescriptorPoolSize {
                    ty: vk::DescriptorType::ACCELERATION_STRUCTURE_NV,
                    descriptor_count: 2,
                });
            }
            let descriptor_pool = d
                .create_descriptor_pool(
                    &vk::DescriptorPoolCreateInfo::default()
                        .max_sets(2)
                        .pool_sizes(&sizes),
                    None,
                )
                .map_err(vkfail("vkCreateDescriptorPool"))?;
            Ok(DeviceCache {
                modules: HashMap::new(),
                layouts: HashMap::new(),
                pipelines: HashMap::new(),
                scenes: HashMap::new(),
                command_pool,
                primary,
                secondary,
                fence,
                descriptor_pool,
                output: None,
                rays: None,
                callables: None,
                lost: false,
                render_pass: None,
                resource_pipeline: None,
                dev,
            })
        }
    }

    fn module(
        &mut self,
        kind: ShaderKind,
        api: PipelineApi,
    ) -> Result<vk::ShaderModule, RealiseError> {
        if let Some(m) = self.modules.get(&(kind, api == PipelineApi::Nv)) {
            return Ok(*m);
        }
        let code = shaders::spirv(kind, api)?;
        // SAFETY: valid SPIR-V words.
        let m = unsafe {
            self.dev
                .device
                .create_shader_module(&vk::ShaderModuleCreateInfo::default().code(&code), None)
        }
        .map_err(vkfail("vkCreateShaderModule"))?;
        self.modules.insert((kind, api == PipelineApi::Nv), m);
        Ok(m)
    }

    /// Layouts for the raygen variant: with the scene at binding 0 (`trace`, a KHR or NV acceleration
    /// structure by `api`) or without. Binding 1 is the output, 2 the rays, 3 the callable indices; the
    /// closest-hit reads the scene and the rays to trace its ray again.
    pub fn layouts(&mut self, trace: bool, api: PipelineApi) -> Result<Layouts, RealiseError> {
        if let Some(l) = self.layouts.get(&(trace, api == PipelineApi::Nv)) {
            return Ok(*l);
        }
        let raygen = vk::ShaderStageFlags::RAYGEN_KHR;
        let traced = if trace {
            raygen | vk::ShaderStageFlags::CLOSEST_HIT_KHR
        } else {
            raygen
        };
        let storage = |binding: u32, stages| {
            vk::DescriptorSetLayoutBinding::default()
                .binding(binding)
                .descriptor_type(vk::DescriptorType::STORAGE_BUFFER)
                .descriptor_count(1)
                .stage_flags(stages)
        };
        let mut bindings = vec![storage(1, raygen), storage(2, traced), storage(3, raygen)];
        if trace {
            let ty = match api {
                PipelineApi::Khr => vk::DescriptorType::ACCELERATION_STRUCTURE_KHR,
                PipelineApi::Nv => vk::DescriptorType::ACCELERATION_STRUCTURE_NV,
            };
            bindings.push(
                vk::DescriptorSetLayoutBinding::default()
                    .binding(0)
                    .descriptor_type(ty)
                    .descriptor_count(1)
                    .stage_flags(traced),
            );
        }
        let d = &self.dev.device;
        // SAFETY: valid create infos.
        let set = unsafe {
            d.create_descriptor_set_layout(
                &vk::DescriptorSetLayoutCreateInfo::default().bindings(&bindings),
                None,
            )
        }
        .map_err(vkfail("vkCreateDescriptorSetLayout"))?;
        let sets = [set];
        // SAFETY: as above.
        let pipeline = unsafe {
            d.create_pipeline_layout(
                &vk::PipelineLayoutCreateInfo::default().set_layouts(&sets),
                None,
            )
        }
        .map_err(vkfail("vkCreatePipelineLayout"))?;
        let l = Layouts { set, pipeline };
        self.layouts.insert((trace, api == PipelineApi::Nv), l);
        Ok(l)
    }

    /// The pipeline for a description (cached); `foreign` makes a second, distinct pipeline of it.
    pub fn pipeline(
        &mut self,
        p: &Pipeline,
        trace: bool,
        foreign: bool,
    ) -> Result<&RealPipeline, RealiseError> {
        // issue 4 hook: a case with a resource state runs its own pipeline (see `resource_pipeline`).
        if !foreign && self.resource_pipeline.is_some() {
            return Ok(self.resource_pipeline.as_ref().expect("checked"));
        }
        let key = format!(
            "{}|{trace}|{foreign}",
            serde_json::to_string(p).unwrap_or_default()
        );
        if !self.pipelines.contains_key(&key) {
            let made = self.create_pipeline(p, trace).map_err(|e| match e {
                RealiseError::Unsupported(s) => format!("unsupported: {s}"),
                RealiseError::Failed(s) => s,
            });
            self.pipelines.insert(key.clone(), made);
        }
        match &self.pipelines[&key] {
            Ok(p) => Ok(p),
            Err(s) => match s.strip_prefix("unsupported: ") {
                Some(r) => Err(RealiseError::Unsupported(r.to_string())),
                None => Err(RealiseError::Failed(s.clone())),
            },
        }
    }

    fn create_pipeline(&mut self, p: &Pipeline, trace: bool) -> Result<RealPipeline, RealiseError> {
        let layout = self.layouts(trace, p.api)?.pipeline;
        self.create_pipeline_with(p, trace, layout, &[])
    }

    /// issue 4 hook: the pipeline for a description with `layout` and, for each shader kind `modules`
    /// names, that module in every stage of that kind (used by `crate::resources` for cases with a
    /// resource state: its templated raygen, closest-hit, miss, ... modules). Not cached.
    pub fn create_pipeline_with(
        &mut self,
        p: &Pipeline,
        trace: bool,
        layout: vk::PipelineLayout,
        modules: &[(ShaderKind, vk::ShaderModule)],
    ) -> Result<RealPipeline, RealiseError> {
        let api = p.api;
        match api {
            PipelineApi::Khr if self.dev.rt.is_none() => {
                return Err(RealiseError::Unsupported(
                    "the case does not enable VK_KHR_ray_tracing_pipeline, so no ray tracing pipeline can be made".into(),
                ))
            }
            PipelineApi::Nv if self.dev.nv.is_none() => {
                return Err(RealiseError::Unsupported(
                    "the case does not enable VK_NV_ray_tracing, so no NV ray tracing pipeline can be made".into(),
                ))
            }
            _ => {}
        }
        let raygen = if trace {
            ShaderKind::RaygenTrace
        } else {
            ShaderKind::RaygenPlain
        };
        let closest = if trace {
            ShaderKind::ClosestHitTrace
        } else {
            ShaderKind::ClosestHitPlain
        };
        // (group index, stage flag, module) per stage, and per group (type, [general, closest, any, intersection]).
        let mut stage_list: Vec<(u32, vk::ShaderStageFlags, vk::ShaderModule)> = Vec::new();
        let mut groups: Vec<(vk::RayTracingShaderGroupTypeKHR, [u32; 4])> = Vec::new();
        let unused = vk::SHADER_UNUSED_KHR;
        for (g, group) in p.groups.iter().enumerate() {
            let g = g as u32;
            let mut add = |this: &mut Self,
                           kind: ShaderKind,
                           stage: vk::ShaderStageFlags|
             -> Result<u32, RealiseError> {
                // issue 4 hook: a templated module of this kind replaces the harness's.
                let m = match modules.iter().find(|(k, _)| *k == kind) {
                    Some(&(_, m)) => m,
                    None => this.module(kind, api)?,
                };
                stage_list.push((g, stage, m));
                Ok(stage_list.len() as u32 - 1)
            };
            let info = match group {
                ShaderGroup::General { stage } => {
                    let (kind, flag) = match stage {
                        GeneralStage::Raygen => (raygen, vk::ShaderStageFlags::RAYGEN_KHR),
                        GeneralStage::Miss => (ShaderKind::Miss, vk::ShaderStageFlags::MISS_KHR),
                        GeneralStage::Callable => {
                            (ShaderKind::Callable, vk::ShaderStageFlags::CALLABLE_KHR)
                        }
                    };
                    let s = add(self, kind, flag)?;
                    (
                        vk::RayTracingShaderGroupTypeKHR::GENERAL,
                        [s, unused, unused, unused],
                    )
                }
                ShaderGroup::TrianglesHit {
                    closest_hit,
                    any_hit,
                }
                | ShaderGroup::ProceduralHit {
                    closest_hit,
                    any_hit,
                    ..
                } => {
                    let procedural = matches!(group, ShaderGroup::ProceduralHit { .. });
                    let ch = if *closest_hit {
                        add(self, closest, vk::ShaderStageFlags::CLOSEST_HIT_KHR)?
                    } else {
                        unused
                    };
                    let ah = if *any_hit {
                        add(self, ShaderKind::AnyHit, vk::ShaderStageFlags::ANY_HIT_KHR)?
                    } else {
                        unused
                    };
                    let is = match group {
                        ShaderGroup::ProceduralHit { intersection: true, .. } => {
                            add(self, ShaderKind::Intersection, vk::ShaderStageFlags::INTERSECTION_KHR)?
                        }
                        ShaderGroup::ProceduralHit { intersection: false, .. } => {
                            return Err(RealiseError::Unsupported(format!(
                                "group {g} is procedural without an intersection shader, which no valid pipeline has"
                            )))
                        }
                        _ => unused,
                    };
                    let ty = if procedural {
                        vk::RayTracingShaderGroupTypeKHR::PROCEDURAL_HIT_GROUP
                    } else {
                        vk::RayTracingShaderGroupTypeKHR::TRIANGLES_HIT_GROUP
                    };
                    (ty, [unused, ch, ah, is])
                }
            };
            groups.push(info);
        }
        let group_values: Vec<u32> = stage_list.iter().map(|(g, _, _)| *g).collect();
        let entry = [vk::SpecializationMapEntry {
            constant_id: 0,
            offset: 0,
            size: 4,
        }];
        let specs: Vec<vk::SpecializationInfo> = group_values
            .iter()
            .map(|v| {
                let bytes: &[u8] = crate::structs::as_bytes(v);
                vk::SpecializationInfo::default()
                    .map_entries(&entry)
                    .data(bytes)
            })
            .collect();
        let main = c"main";
        let stages: Vec<vk::PipelineShaderStageCreateInfo> = stage_list
            .iter()
            .zip(&specs)
            .map(|((_, flag, m), spec)| {
                vk::PipelineShaderStageCreateInfo::default()
                    .stage(*flag)
                    .module(*m)
                    .name(main)
                    .specialization_info(spec)
            })
            .collect();
        let flags = vk::PipelineCreateFlags::from_raw(p.flags.0 as u32);
        let hs = self.dev.limits.handle_size as usize;
        let n = p.groups.len();
        if api == PipelineApi::Nv {
            let hs = self.dev.limits.nv_handle_size as usize;
            let nv_groups: Vec<vk::RayTracingShaderGroupCreateInfoNV> = groups
                .iter()
                .map(|(ty, [gen, ch, ah, is])| {
                    vk::RayTracingShaderGroupCreateInfoNV::default()
                        .ty(*ty)
                        .general_shader(*gen)
                        .closest_hit_shader(*ch)
                        .any_hit_shader(*ah)
                        .intersection_shader(*is)
                })
                .collect();
            // The KHR-only flags (NO_NULL_*, SKIP_*, LIBRARY) are not NV pipeline flags.
            let info = vk::RayTracingPipelineCreateInfoNV::default()
                .flags(
                    flags
                        & (vk::PipelineCreateFlags::DISABLE_OPTIMIZATION
                            | vk::PipelineCreateFlags::DEFER_COMPILE_NV),
                )
                .stages(&stages)
                .groups(&nv_groups)
                .max_recursion_depth(p.max_recursion_depth)
                .layout(layout);
            let nv = self.dev.nv.as_ref().expect("checked above");
            // SAFETY: every pointer in `info` outlives the call.
            let pipeline = unsafe {
                nv.create_ray_tracing_pipelines(vk::PipelineCache::null(), &[info], None)
            }
            .map_err(|(_, r)| {
                RealiseError::Failed(format!("vkCreateRayTracingPipelinesNV failed: {r:?}"))
            })?[0];
            let mut handles = vec![0u8; hs * n];
            if n > 0 {
                // SAFETY: valid pipeline, group range inside it, data sized for the groups.
                if let Err(r) = unsafe {
                    nv.get_ray_tracing_shader_group_handles(pipeline, 0, n as u32, &mut handles)
                } {
                    // SAFETY: destroying what we created.
                    unsafe { self.dev.device.destroy_pipeline(pipeline, None) };
                    return Err(RealiseError::Failed(format!(
                        "vkGetRayTracingShaderGroupHandlesNV failed: {r:?}"
                    )));
                }
            }
            return Ok(RealPipeline {
                pipeline,
                handles,
                group_count: n,
                default_stack_size: 0,
            });
        }
        let khr_groups: Vec<vk::RayTracingShaderGroupCreateInfoKHR> = groups
            .iter()
            .map(|(ty, [gen, ch, ah, is])| {
                vk::RayTracingShaderGroupCreateInfoKHR::default()
                    .ty(*ty)
                    .general_shader(*gen)
                    .closest_hit_shader(*ch)
                    .any_hit_shader(*ah)
                    .intersection_shader(*is)
            })
            .collect();
        let dynamic = [vk::DynamicState::RAY_TRACING_PIPELINE_STACK_SIZE_KHR];
        let dyn_info = vk::PipelineDynamicStateCreateInfo::default().dynamic_states(&dynamic);
        // The payload is `Payload { uint word, depth, ray; }` (12 bytes); the shaders declare no hit attributes.
        let iface = vk::RayTracingPipelineInterfaceCreateInfoKHR::default()
            .max_pipeline_ray_payload_size(12)
            .max_pipeline_ray_hit_attribute_size(8);
        let mut info = vk::RayTracingPipelineCreateInfoKHR::default()
            .flags(flags)
            .stages(&stages)
            .groups(&khr_groups)
            .max_pipeline_ray_recursion_depth(p.max_recursion_depth)
            .layout(layout);
        if p.dynamic_stack_size {
            info = info.dynamic_state(&dyn_info);
        }
        if flags.contains(vk::PipelineCreateFlags::LIBRARY_KHR) {
            info = info.library_interface(&iface);
        }
        let rt = self.dev.rt.as_ref().expect("checked above");
        // SAFETY: every pointer in `info` outlives the call.
        let pipeline = unsafe {
            rt.create_ray_tracing_pipelines(
                vk::DeferredOperationKHR::null(),
                vk::PipelineCache::null(),
                &[info],
                None,
            )
        }
        .map_err(|(_, r)| {
            RealiseError::Failed(format!("vkCreateRayTracingPipelinesKHR failed: {r:?}"))
        })?[0];
        let library = flags.contains(vk::PipelineCreateFlags::LIBRARY_KHR);
        let handles = if library || n == 0 {
            vec![0u8; hs * n]
        } else {
            // SAFETY: valid pipeline, group range inside it.
            unsafe { rt.get_ray_tracing_shader_group_handles(pipeline, 0, n as u32, hs * n) }
                .map_err(vkfail("vkGetRayTracingShaderGroupHandlesKHR"))?
        };
        let default_stack_size = if library {
            0
        } else {
            default_stack_size(rt, pipeline, &groups, p.max_recursion_depth)
        };
        Ok(RealPipeline {
            pipeline,
            handles,
            group_count: n,
            default_stack_size,
        })
    }

    /// The scene for a list of instances (cached).
    pub fn scene(
        &mut self,
        instances: &[Instance],
        api: PipelineApi,
    ) -> Result<Tlas, RealiseError> {
        let key = format!(
            "{api:?}|{}",
            serde_json::to_string(instances).unwrap_or_default()
        );
        if !self.scenes.contains_key(&key) {
            let built = self.build_scene(instances, api).map_err(|e| match e {
                RealiseError::Unsupported(s) => format!("unsupported: {s}"),
                RealiseError::Failed(s) => s,
            });
            self.scenes.insert(key.clone(), built);
        }
        match &self.scenes[&key] {
            Ok(s) => Ok(s.tlas),
            Err(s) => match s.strip_prefix("unsupported: ") {
                Some(r) => Err(RealiseError::Unsupported(r.to_string())),
                None => Err(RealiseError::Failed(s.clone())),
            },
        }
    }

    fn build_scene(
        &mut self,
        instances: &[Instance],
        api: PipelineApi,
    ) -> Result<Scene, RealiseError> {
        // A bottom-level structure holds geometries of one type; a case that mixes them cannot be built
        // validly, so it is not realised rather than handed to the driver.
        if let Some(i) = instances
            .iter()
            .position(|inst| inst.geometries.windows(2).any(|w| w[0] != w[1]))
        {
            return Err(RealiseError::Unsupported(format!(
                "instance {i} mixes triangle and AABB geometries; one acceleration structure holds one type"
            )));
        }
        let mut scene = Scene {
            tlas: Tlas::Khr(vk::AccelerationStructureKHR::null()),
            structures: Vec::new(),
            nv_structures: Vec::new(),
            nv_memory: Vec::new(),
            buffers: Vec::new(),
        };
        if api == PipelineApi::Nv {
            let Some(nv) = self.dev.nv.clone() else {
                return Err(RealiseError::Unsupported(
                    "the case traces rays but does not enable VK_NV_ray_tracing".into(),
                ));
            };
            return match self.build_nv_scene_into(&nv, instances, &mut scene) {
                Ok(()) => Ok(scene),
                Err(e) => {
                    self.destroy_scene(scene);
                    Err(e)
                }
            };
        }
        let Some(accel) = self.dev.accel.clone() else {
            return Err(RealiseError::Unsupported(
                "the case traces rays but does not enable VK_KHR_acceleration_structure".into(),
            ));
        };
        if !self.dev.has_feature("accelerationStructure")
            || !self.dev.has_feature("bufferDeviceAddress")
        {
            return Err(RealiseError::Unsupported(
                "the case traces rays but does not enable accelerationStructure and bufferDeviceAddress".into(),
            ));
        }
        let result = self.build_scene_into(&accel, instances, &mut scene);
        match result {
            Ok(()) => Ok(scene),
            Err(e) => {
                self.destroy_scene(scene);
                Err(e)
            }
        }
    }

    fn build_scene_into(
        &mut self,
        accel: &ash::khr::acceleration_structure::Device,
        instances: &[Instance],
        scene: &mut Scene,
    ) -> Result<(), RealiseError> {
        let dev = &self.dev;
        let input_usage = vk::BufferUsageFlags::ACCELERATION_STRUCTURE_BUILD_INPUT_READ_ONLY_KHR
            | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS;
        let scratch_align = (dev.limits.scratch_alignment as u64).max(256);
        let none = vk::BufferCreateFlags::empty();
        // Geometry input: one triangle or box per geometry, all in one buffer.
        let (input, offsets) = geometry_input(instances);
        let inputs = Allocation::new(dev, input.len().max(16) as u64, input_usage, none, 256)?;
        inputs.write(0, &input);
        let input_address = inputs.address;
        scene.buffers.push(inputs);

        let mut blas_addresses = Vec::new();
        let mut builds: Vec<(
            Vec<vk::AccelerationStructureGeometryKHR>,
            Vec<vk::AccelerationStructureBuildRangeInfoKHR>,
            vk::AccelerationStructureKHR,
            u64,
        )> = Vec::new();
        for (i, inst) in instances.iter().enumerate() {
            if inst.geometries.is_empty() {
                // An instance without geometry is made inactive (reference 0, semantics.md §4): it keeps its
                // place in the instance numbering, and no bottom-level structure of zero geometries (whose
                // size query some drivers answer with 0) is built.
                blas_addresses.push(0);
                continue;
            }
            let mut geoms = Vec::new();
            let mut ranges = Vec::new();
            for (g, kind) in inst.geometries.iter().enumerate() {
                let at = input_address + offsets[i][g];
                let data = match kind {
                    GeometryKind::Triangles => vk::AccelerationStructureGeometryDataKHR {
                        triangles: vk::AccelerationStructureGeometryTrianglesDataKHR::default()
                            .vertex_format(vk::Format::R32G32B32_SFLOAT)
                            .vertex_data(vk::DeviceOrHostAddressConstKHR { device_address: at })
                            .vertex_stride(12)
                            .max_vertex(2)
                            .index_type(vk::IndexType::NONE_KHR),
                    },
                    GeometryKind::Aabbs => vk::AccelerationStructureGeometryDataKHR {
                        aabbs: vk::AccelerationStructureGeometryAabbsDataKHR::default()
                            .data(vk::DeviceOrHostAddressConstKHR { device_address: at })
                            .stride(24),
                    },
                };
                let ty = match kind {
                    GeometryKind::Triangles => vk::GeometryTypeKHR::TRIANGLES,
                    GeometryKind::Aabbs => vk::GeometryTypeKHR::AABBS,
                };
                geoms.push(
                    vk::AccelerationStructureGeometryKHR::default()
                        .geometry_type(ty)
                        .geometry(data),
                );
                ranges
                    .push(vk::AccelerationStructureBuildRangeInfoKHR::default().primitive_count(1));
            }
            let counts: Vec<u32> = ranges.iter().map(|r| r.primitive_count).collect();
            let (blas, storage, scratch) = sized_structure(
                dev,
                accel,
                vk::AccelerationStructureTypeKHR::BOTTOM_LEVEL,
                &geoms,
                &counts,
                scratch_align,
            )?;
            scene.structures.push(blas);
            // SAFETY: valid structure.
            let addr = unsafe {
                accel.get_acceleration_structure_device_address(
                    &vk::AccelerationStructureDeviceAddressInfoKHR::default()
                        .acceleration_structure(blas),
                )
            };
            blas_addresses.push(addr);
            builds.push((geoms, ranges, blas, scratch.address));
            scene.buffers.push(storage);
            scene.buffers.push(scratch);
        }
        // Instances.
        let records: Vec<vk::AccelerationStructureInstanceKHR> = instances
            .iter()
            .zip(&blas_addresses)
            .map(|(inst, addr)| vk::AccelerationStructureInstanceKHR {
                transform: vk::TransformMatrixKHR {
                    matrix: [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0],
                },
                instance_custom_index_and_mask: vk::Packed24_8::new(0, inst.mask),
                instance_shader_binding_table_record_offset_and_flags: vk::Packed24_8::new(
                    inst.sbt_record_offset & 0xFF_FFFF,
                    0,
                ),
                acceleration_structure_reference: vk::AccelerationStructureReferenceKHR {
                    device_handle: *addr,
                },
            })
            .collect();
        let record_bytes: Vec<u8> = records
            .iter()
            .flat_map(|r| crate::structs::as_bytes(r).to_vec())
            .collect();
        let inst_buf = Allocation::new(
            dev,
            record_bytes.len().max(64) as u64,
            input_usage,
            none,
            256,
        )?;
        inst_buf.write(0, &record_bytes);
        let tlas_geom = [vk::AccelerationStructureGeometryKHR::default()
            .geometry_type(vk::GeometryTypeKHR::INSTANCES)
            .geometry(vk::AccelerationStructureGeometryDataKHR {
                instances: vk::AccelerationStructureGeometryInstancesDataKHR::default().data(
                    vk::DeviceOrHostAddressConstKHR {
                        device_address: inst_buf.address,
                    },
                ),
            })];
        scene.buffers.push(inst_buf);
        let tlas_count = [instances.len() as u32];
        let (tlas, storage, scratch) = sized_structure(
            dev,
            accel,
            vk::AccelerationStructureTypeKHR::TOP_LEVEL,
            &tlas_geom,
            &tlas_count,
            scratch_align,
        )?;
        scene.structures.push(tlas);
        scene.tlas = Tlas::Khr(tlas);
        let tlas_scratch = scratch.address;
        scene.buffers.push(storage);
        scene.buffers.push(scratch);

        // Record: every BLAS, a barrier, the TLAS; submit and wait.
        let d = &dev.device;
        let cb = self.primary;
        // SAFETY: the command buffer is idle (every case waits or resets before returning).
        unsafe {
            d.reset_command_buffer(cb, vk::CommandBufferResetFlags::empty())
                .map_err(vkfail("vkResetCommandBuffer"))?;
            d.begin_command_buffer(
                cb,
                &vk::CommandBufferBeginInfo::default()
                    .flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT),
            )
            .map_err(vkfail("vkBeginCommandBuffer"))?;
            for (geoms, ranges, blas, scratch) in &builds {
                let info = vk::AccelerationStructureBuildGeometryInfoKHR::default()
                    .ty(vk::AccelerationStructureTypeKHR::BOTTOM_LEVEL)
                    .mode(vk::BuildAccelerationStructureModeKHR::BUILD)
                    .geometries(geoms)
                    .dst_acceleration_structure(*blas)
                    .scratch_data(vk::DeviceOrHostAddressKHR {
                        device_address: *scratch,
                    });
                accel.cmd_build_acceleration_structures(cb, &[info], &[ranges.as_slice()]);
            }
            let barrier = vk::MemoryBarrier::default()
                .src_access_mask(vk::AccessFlags::ACCELERATION_STRUCTURE_WRITE_KHR)
                .dst_access_mask(vk::AccessFlags::ACCELERATION_STRUCTURE_READ_KHR);
            d.cmd_pipeline_barrier(
                cb,
                vk::PipelineStageFlags::ACCELERATION_STRUCTURE_BUILD_KHR,
                vk::PipelineStageFlags::ACCELERATION_STRUCTURE_BUILD_KHR
                    | vk::PipelineStageFlags::RAY_TRACING_SHADER_KHR,
                vk::DependencyFlags::empty(),
                &[barrier],
                &[],
                &[],
            );
            let info = vk::AccelerationStructureBuildGeometryInfoKHR::default()
                .ty(vk::AccelerationStructureTypeKHR::TOP_LEVEL)
                .mode(vk::BuildAccelerationStructureModeKHR::BUILD)
                .geometries(&tlas_geom)
                .dst_acceleration_structure(tlas)
                .scratch_data(vk::DeviceOrHostAddressKHR {
                    device_address: tlas_scratch,
                });
            let range = [vk::AccelerationStructureBuildRangeInfoKHR::default()
                .primitive_count(instances.len() as u32)];
            accel.cmd_build_acceleration_structures(cb, &[info], &[&range]);
            d.end_command_buffer(cb)
                .map_err(vkfail("vkEndCommandBuffer"))?;
        }
        self.submit_and_wait(std::time::Duration::from_secs(60))
    }

    /// The scene as VK_NV_ray_tracing structures: one bottom-level `VkAccelerationStructureNV` per instance
    /// (its geometries as `VkGeometryNV`, buffer + offset based), a top-level one over
    /// `VkAccelerationStructureInstanceNV` records, each bound to its own memory, built with
    /// `vkCmdBuildAccelerationStructureNV` (barrier between the levels), submitted and waited for.
    fn build_nv_scene_into(
        &mut self,
        nv: &ash::nv::ray_tracing::Device,
        instances: &[Instance],
        scene: &mut Scene,
    ) -> Result<(), RealiseError> {
        let dev = &self.dev;
        let usage = vk::BufferUsageFlags::RAY_TRACING_NV;
        let none = vk::BufferCreateFlags::empty();
        // Geometry input, as for KHR (offsets 16-aligned; AABBs need 8).
        let (input, offsets) = geometry_input(instances);
        let inputs = Allocation::new(dev, input.len().max(16) as u64, usage, none, 256)?;
        inputs.write(0, &input);
        let input_buffer = inputs.buffer;
        scene.buffers.push(inputs);

        // Creates a structure for `info`, binds it to fresh memory and makes a scratch buffer for its build.
        let make = |info: vk::AccelerationStructureInfoNV,
                    scene: &mut Scene|
         -> Result<(vk::AccelerationStructureNV, vk::Buffer), RealiseError> {
            // SAFETY: valid description whose geometry pointers outlive the call.
            let s = unsafe {
                nv.create_acceleration_structure(
                    &vk::AccelerationStructureCreateInfoNV::default().info(info),
                    None,
                )
            }
            .map_err(vkfail("vkCreateAccelerationStructureNV"))?;
            scene.nv_structures.push(s);
            let req = |ty| {
                // SAFETY: valid structure.
                unsafe {
                    nv.get_acceleration_structure_memory_requirements(
                        &vk::AccelerationStructureMemoryRequirementsInfoNV::default()
                            .ty(ty)
                            .acceleration_structure(s),
                    )
                }
                .memory_requirements
            };
            let object = req(vk::AccelerationStructureMemoryRequirementsTypeNV::OBJECT);
            let scratch = req(vk::AccelerationStructureMemoryRequirementsTypeNV::BUILD_SCRATCH);
            let mt = dev
                .memory_type(
                    object.memory_type_bits,
                    vk::MemoryPropertyFlags::DEVICE_LOCAL,
                )
                .or_else(|| {
                    dev.memory_type(object.memory_type_bits, vk::MemoryPropertyFlags::empty())
                })
                .ok_or_else(|| {
                    RealiseError::Unsupported(
                        "no memory type for an NV acceleration structure".into(),
                    )
                })?;
            let ai = vk::MemoryAllocateInfo::default()
                .allocation_size(object.size.max(1))
                .memory_type_index(mt);
            // SAFETY: valid allocate info.
            let memory = unsafe { dev.device.allocate_memory(&ai, None) }
                .map_err(vkfail("vkAllocateMemory"))?;
            scene.nv_memory.push(memory);
            let bind = [vk::BindAccelerationStructureMemoryInfoNV::default()
                .acceleration_structure(s)
                .memory(memory)];
            // SAFETY: fresh memory of the required type and size.
            unsafe { nv.bind_acceleration_structure_memory(&bind) }
                .map_err(vkfail("vkBindAccelerationStructureMemoryNV"))?;
            let scratch_buf = Allocation::new(
                dev,
                scratch.size.max(1),
                usage,
                none,
                scratch.alignment.max(256),
            )?;
            let b = scratch_buf.buffer;
            scene.buffers.push(scratch_buf);
            Ok((s, b))
        };

        let mut handles = Vec::new();
        let mut blas_builds: Vec<(Vec<vk::GeometryNV>, vk::AccelerationStructureNV, vk::Buffer)> =
            Vec::new();
        for (i, inst) in instances.iter().enumerate() {
            if inst.geometries.is_empty() {
                handles.push(0u64);
                continue;
            }
            let geoms: Vec<vk::GeometryNV> = inst
                .geometries
                .iter()
                .enumerate()
                .map(|(g, kind)| {
                    let at = offsets[i][g];
                    let mut data = vk::GeometryDataNV::default();
                    let ty = match kind {
                        GeometryKind::Triangles => {
                            data.triangles = vk::GeometryTrianglesNV::default()
                                .vertex_data(input_buffer)
                                .vertex_offset(at)
                                .vertex_count(3)
                                .vertex_stride(12)
                                .vertex_format(vk::Format::R32G32B32_SFLOAT)
                                .index_type(vk::IndexType::NONE_NV);
                            vk::GeometryTypeNV::TRIANGLES
                        }
                        GeometryKind::Aabbs => {
                            data.aabbs = vk::GeometryAABBNV::default()
                                .aabb_data(input_buffer)
                                .num_aab_bs(1)
                                .stride(24)
                                .offset(at);
                            vk::GeometryTypeNV::AABBS
                        }
                    };
                    vk::GeometryNV::default().geometry_type(ty).geometry(data)
                })
                .collect();
            let info = vk::AccelerationStructureInfoNV::default()
                .ty(vk::AccelerationStructureTypeNV::BOTTOM_LEVEL)
                .geometries(&geoms);
            let (blas, scratch) = make(info, scene)?;
            // SAFETY: the structure is bound to memory.
            let handle = unsafe { nv.get_acceleration_structure_handle(blas) }
                .map_err(vkfail("vkGetAccelerationStructureHandleNV"))?;
            handles.push(handle);
            blas_builds.push((geoms, blas, scratch));
        }
        let records: Vec<vk::AccelerationStructureInstanceNV> = instances
            .iter()
            .zip(&handles)
            .map(|(inst, handle)| vk::AccelerationStructureInstanceNV {
                transform: vk::TransformMatrixKHR {
                    matrix: [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0],
                },
                instance_custom_index_and_mask: vk::Packed24_8::new(0, inst.mask),
                instance_shader_binding_table_record_offset_and_flags: vk::Packed24_8::new(
                    inst.sbt_record_offset & 0xFF_FFFF,
                    0,
                ),
                acceleration_structure_reference: vk::AccelerationStructureReferenceKHR {
                    device_handle: *handle,
                },
            })
            .collect();
        let record_bytes: Vec<u8> = records
            .iter()
            .flat_map(|r| crate::structs::as_bytes(r).to_vec())
            .collect();
        let inst_buf = Allocation::new(dev, record_bytes.len().max(64) as u64, usage, none, 256)?;
        inst_buf.write(0, &record_bytes);
        let inst_buffer = inst_buf.buffer;
        scene.buffers.push(inst_buf);
        let tlas_info = vk::AccelerationStructureInfoNV::default()
            .ty(vk::AccelerationStructureTypeNV::TOP_LEVEL)
            .instance_count(instances.len() as u32);
        let (tlas, tlas_scratch) = make(tlas_info, scene)?;
        scene.tlas = Tlas::Nv(tlas);

        let d = &self.dev.device;
        let cb = self.primary;
        // SAFETY: the command buffer is idle; every structure is bound to memory.
        unsafe {
            d.reset_command_buffer(cb, vk::CommandBufferResetFlags::empty())
                .map_err(vkfail("vkResetCommandBuffer"))?;
            d.begin_command_buffer(
                cb,
                &vk::CommandBufferBeginInfo::default()
                    .flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT),
            )
            .map_err(vkfail("vkBeginCommandBuffer"))?;
            for (geoms, blas, scratch) in &blas_builds {
                let info = vk::AccelerationStructureInfoNV::default()
                    .ty(vk::AccelerationStructureTypeNV::BOTTOM_LEVEL)
                    .geometries(geoms);
                nv.cmd_build_acceleration_structure(
                    cb,
                    &info,
                    vk::Buffer::null(),
                    0,
                    false,
                    *blas,
                    vk::AccelerationStructureNV::null(),
                    *scratch,
                    0,
                );
            }
            let barrier = vk::MemoryBarrier::default()
                .src_access_mask(vk::AccessFlags::ACCELERATION_STRUCTURE_WRITE_NV)
                .dst_access_mask(vk::AccessFlags::ACCELERATION_STRUCTURE_READ_NV);
            d.cmd_pipeline_barrier(
                cb,
                vk::PipelineStageFlags::ACCELERATION_STRUCTURE_BUILD_NV,
                vk::PipelineStageFlags::ACCELERATION_STRUCTURE_BUILD_NV
                    | vk::PipelineStageFlags::RAY_TRACING_SHADER_NV,
                vk::DependencyFlags::empty(),
                &[barrier],
                &[],
                &[],
            );
            nv.cmd_build_acceleration_structure(
                cb,
                &tlas_info,
                inst_buffer,
                0,
                false,
                tlas,
                vk::AccelerationStructureNV::null(),
                tlas_scratch,
                0,
            );
            d.end_command_buffer(cb)
                .map_err(vkfail("vkEndCommandBuffer"))?;
        }
        self.submit_and_wait(std::time::Duration::from_secs(60))
    }

    /// Submits the primary command buffer and waits for it. A lost device or a submission that does not
    /// finish marks the cache [`lost`](Self::lost): nothing is recorded or submitted on it again.
    pub fn submit_and_wait(&mut self, timeout: std::time::Duration) -> Result<(), RealiseError> {
        if self.lost {
            return Err(RealiseError::Failed(
                "the device was lost by an earlier case (ERROR_DEVICE_LOST)".into(),
            ));
        }
        let d = &self.dev.device;
        let cbs = [self.primary];
        let submit = [vk::SubmitInfo::default().command_buffers(&cbs)];
        // SAFETY: the command buffer is executable; the fence is unsignalled.
        unsafe {
            if let Err(r) = d.queue_submit(self.dev.queue, &submit, self.fence) {
                self.lost |= r == vk::Result::ERROR_DEVICE_LOST;
                return Err(RealiseError::Failed(format!("vkQueueSubmit failed: {r:?}")));
            }
            let waited = d.wait_for_fences(
                &[self.fence],
                true,
                timeout.as_nanos().min(u64::MAX as u128) as u64,
            );
            match waited {
                Ok(()) => {}
                Err(vk::Result::TIMEOUT) => {
                    self.lost = true;
                    return Err(RealiseError::Failed(format!(
                        "TIMEOUT: the GPU did not finish within {timeout:?}"
                    )));
                }
                Err(r) => {
                    self.lost |= r == vk::Result::ERROR_DEVICE_LOST;
                    return Err(RealiseError::Failed(format!(
                        "vkWaitForFences failed: {r:?}"
                    )));
                }
            }
            d.reset_fences(&[self.fence])
                .map_err(vkfail("vkResetFences"))?;
        }
        Ok(())
    }

    fn destroy_scene(&self, scene: Scene) {
        if let Some(accel) = &self.dev.accel {
            for s in scene.structures {
                // SAFETY: no pending work uses the structure.
                unsafe { accel.destroy_acceleration_structure(s, None) };
            }
        }
        if let Some(nv) = &self.dev.nv {
            for s in scene.nv_structures {
                // SAFETY: no pending work uses the structure.
                unsafe { nv.destroy_acceleration_structure(s, None) };
            }
        }
        for m in scene.nv_memory {
            // SAFETY: the structures bound to it are destroyed above.
            unsafe { self.dev.device.free_memory(m, None) };
        }
        for b in scene.buffers {
            b.destroy(&self.dev);
        }
    }

    /// Buffers at least `words` output words, `rays` ray records and `callables` callable indices large
    /// (grown when needed).
    pub fn io_buffers(
        &mut self,
        words: usize,
        rays: usize,
        callables: usize,
    ) -> Result<(), RealiseError> {
        let usage = vk::BufferUsageFlags::STORAGE_BUFFER;
        let want_out = (words.max(1) * 4) as u64;
        if self.output.as_ref().is_none_or(|a| a.size < want_out) {
            if let Some(a) = self.output.take() {
                a.destroy(&self.dev);
            }
            self.output = Some(Allocation::new(
                &self.dev,
                want_out.max(4096),
                usage,
                vk::BufferCreateFlags::empty(),
                1,
            )?);
        }
        let want_rays = (16 + rays.max(1) * RAY_RECORD_SIZE) as u64;
        if self.rays.as_ref().is_none_or(|a| a.size < want_rays) {
            if let Some(a) = self.rays.take() {
                a.destroy(&self.dev);
            }
            self.rays = Some(Allocation::new(
                &self.dev,
                want_rays.max(4096),
                usage,
                vk::BufferCreateFlags::empty(),
                1,
            )?);
        }
        let want_calls = (16 + callables.max(1) * 4) as u64;
        if self.callables.as_ref().is_none_or(|a| a.size < want_calls) {
            if let Some(a) = self.callables.take() {
                a.destroy(&self.dev);
            }
            self.callables = Some(Allocation::new(
                &self.dev,
                want_calls.max(256),
                usage,
                vk::BufferCreateFlags::empty(),
                1,
            )?);
        }
        Ok(())
    }

    /// A render pass with no attachments and a 1x1 framebuffer, for cases recorded inside a render pass.
    pub fn empty_render_pass(&mut self) -> Result<(vk::RenderPass, vk::Framebuffer), RealiseError> {
        if let Some(rp) = self.render_pass {
            return Ok(rp);
        }
        let d = &self.dev.device;
        let subpass =
            [vk::SubpassDescription::default()
                .pipeline_bind_point(vk::PipelineBindPoint::GRAPHICS)];
        // SAFETY: valid create infos.
        unsafe {
            let rp = d
                .create_render_pass(
                    &vk::RenderPassCreateInfo::default().subpasses(&subpass),
                    None,
                )
                .map_err(vkfail("vkCreateRenderPass"))?;
            let fb = d
                .create_framebuffer(
                    &vk::FramebufferCreateInfo::default()
                        .render_pass(rp)
                        .width(1)
                        .height(1)
                        .layers(1),
                    None,
                )
                .map_err(vkfail("vkCreateFramebuffer"))?;
            self.render_pass = Some((rp, fb));
            Ok((rp, fb))
        }
    }

    /// Creates the case's buffers with their contents; returns them by name.
    pub fn case_buffers(
        &mut self,
        world: &World,
        pipeline: Option<(&Pipeline, bool)>,
    ) -> Result<Vec<(String, Allocation)>, RealiseError> {
        let mut out: Vec<(String, Allocation)> = Vec::new();
        let r = self.case_buffers_into(world, pipeline, &mut out);
        if let Err(e) = r {
            for (_, a) in out {
                a.destroy(&self.dev);
            }
            return Err(e);
        }
        Ok(out)
    }

    fn case_buffers_into(
        &mut self,
        world: &World,
        pipeline: Option<(&Pipeline, bool)>,
        out: &mut Vec<(String, Allocation)>,
    ) -> Result<(), RealiseError> {
        use model::world::MemoryBinding;
        let hs = match pipeline {
            Some((p, _)) if p.api == PipelineApi::Nv => self.dev.limits.nv_handle_size,
            _ => self.dev.limits.handle_size,
        } as usize;
        let needs_foreign = world.buffers.iter().any(|b| {
            b.contents.iter().any(|c| matches!(c, Contents::ShaderRecords { handles, .. } if handles.iter().any(|h| matches!(h, HandleRef::Foreign(_)))))
        });
        let own: Vec<u8> = match pipeline {
            Some((p, trace)) => self.pipeline(p, trace, false)?.handles.clone(),
            None => Vec::new(),
        };
        let foreign: Vec<u8> = match (pipeline, needs_foreign) {
            (Some((p, trace)), true) => self.pipeline(p, trace, true)?.handles.clone(),
            (None, true) => {
                return Err(RealiseError::Unsupported(
                    "foreign handles need a pipeline description to copy".into(),
                ))
            }
            _ => Vec::new(),
        };
        // KHR calls name buffers by device address; vkCmdTraceRaysNV names them by handle and needs none.
        let wants_address = pipeline.is_none_or(|(p, _)| p.api == PipelineApi::Khr);
        if !self.dev.has_feature("bufferDeviceAddress")
            && wants_address
            && !world.buffers.is_empty()
        {
            return Err(RealiseError::Unsupported(
                "the case does not enable bufferDeviceAddress, so the harness cannot give its buffers addresses".into(),
            ));
        }
        for b in &world.buffers {
            let usage = vk::BufferUsageFlags::from_raw(b.usage.0 as u32);
            let flags = vk::BufferCreateFlags::from_raw(b.flags.0 as u32);
            if b.size == 0 {
                return Err(RealiseError::Unsupported(format!(
                    "buffer `{}` has size 0, which cannot be created",
                    b.name
                )));
            }
            let a = if b.is_sparse() {
                let plan = match b.memory {
                    MemoryBinding::Whole => SparsePlan::One,
                    MemoryBinding::Unbound => SparsePlan::Unbound,
                    MemoryBinding::Scattered => SparsePlan::Two,
                };
                self.check_sparse(b)?;
                Allocation::sparse(&self.dev, self.fence, b.size, usage, flags, plan)?
            } else {
                match b.memory {
                    MemoryBinding::Whole => {}
                    MemoryBinding::Unbound => {
                        return Err(RealiseError::Unsupported(format!(
                            "buffer `{}` is not sparse and has no memory bound: vkGetBufferDeviceAddress on it is \
                             itself invalid (VUID-VkBufferDeviceAddressInfo-buffer-02600: a non-sparse buffer must be \
                             bound completely and contiguously to a single VkDeviceMemory object), so the harness \
                             cannot give it the address the call uses",
                            b.name
                        )))
                    }
                    MemoryBinding::Scattered => {
                        return Err(RealiseError::Unsupported(format!(
                            "buffer `{}` is not sparse, so it cannot be bound to several memory objects \
                             (vkBindBufferMemory binds one; VUID-VkBufferDeviceAddressInfo-buffer-02600)",
                            b.name
                        )))
                    }
                }
                Allocation::new(&self.dev, b.size, usage, flags, BUFFER_PLACEMENT_ALIGNMENT)?
            };
            for c in &b.contents {
                match c {
                    Contents::ShaderRecords {
                        offset,
                        stride,
                        handles,
                    } => {
                        for (i, h) in handles.iter().enumerate() {
                            let bytes: Vec<u8> = match h {
                                HandleRef::Zero => vec![0; hs],
                                HandleRef::Group(n) => own
                                    .get(*n as usize * hs..(*n as usize + 1) * hs)
                                    .map_or(vec![0; hs], |s| s.to_vec()),
                                HandleRef::Foreign(n) => foreign
                                    .get(*n as usize * hs..(*n as usize + 1) * hs)
                                    .map_or(vec![0; hs], |s| s.to_vec()),
                            };
                            a.write(offset + i as u64 * stride, &bytes);
                        }
                    }
                    Contents::TraceRaysIndirectCommand {
                        offset,
                        width,
                        height,
                        depth,
                    } => {
                        let mut bytes = Vec::with_capacity(12);
                        for v in [width, height, depth] {
                            bytes.extend_from_slice(&v.to_ne_bytes());
                        }
                        a.write(*offset, &bytes);
                    }
                }
            }
            out.push((b.name.clone(), a));
        }
        Ok(())
    }
}

impl DeviceCache {
    /// Why a sparse buffer cannot be made validly here, if it cannot: the features its flags need must be
    /// enabled (VUID-VkBufferCreateInfo-flags-00915/00916/00917) and the harness's queue must bind sparse.
    fn check_sparse(&self, b: &model::world::Buffer) -> Result<(), RealiseError> {
        use model::flags::BufferCreate;
        let needs = [
            (
                BufferCreate::SPARSE_BINDING_BIT,
                "sparseBinding",
                "VUID-VkBufferCreateInfo-flags-00915",
            ),
            (
                BufferCreate::SPARSE_RESIDENCY_BIT,
                "sparseResidencyBuffer",
                "VUID-VkBufferCreateInfo-flags-00916",
            ),
            (
                BufferCreate::SPARSE_ALIASED_BIT,
                "sparseResidencyAliased",
                "VUID-VkBufferCreateInfo-flags-00917",
            ),
        ];
        for (flag, feature, vuid) in needs {
            if b.flags.contains(flag) && !self.dev.has_feature(feature) {
                return Err(RealiseError::Unsupported(format!(
                    "buffer `{}` is sparse but the case does not enable {feature}, so creating it is invalid ({vuid})",
                    b.name
                )));
            }
        }
        if !b.flags.contains(BufferCreate::SPARSE_BINDING_BIT) {
            return Err(RealiseError::Unsupported(format!(
                "buffer `{}` has sparse residency/aliasing flags without SPARSE_BINDING (VUID-VkBufferCreateInfo-flags-00918)",
                b.name
            )));
        }
        if !self.dev.sparse_binding {
            return Err(RealiseError::Unsupported(format!(
                "buffer `{}` is sparse but the device lacks sparseBinding or its compute queue family has no \
                 VK_QUEUE_SPARSE_BINDING_BIT, so vkQueueBindSparse cannot bind it",
                b.name
            )));
        }
        Ok(())
    }
}

impl Drop for DeviceCache {
    fn drop(&mut self) {
        if self.lost {
            // A lost device: destroying its objects is allowed but waiting on it may not return on every
            // driver, and a timed-out submission may still be running. Leak every object (handles have no
            // destructor of their own) and the VkDevice with the instance it holds, rather than free memory
            // the GPU may still use or block the process; the worker then starts a fresh instance.
            self.dev.leak = true;
            return;
        }
        // SAFETY: the device is idle after this wait; everything below was made from it.
        unsafe {
            let _ = self.dev.device.device_wait_idle();
        }
        for (_, s) in std::mem::take(&mut self.scenes) {
            if let Ok(s) = s {
                self.destroy_scene(s);
            }
        }
        let d = &self.dev.device;
        // SAFETY: as above.
        unsafe {
            for (_, p) in self.pipelines.drain() {
                if let Ok(p) = p {
                    d.destroy_pipeline(p.pipeline, None);
                }
            }
            for (_, l) in self.layouts.drain() {
                d.destroy_pipeline_layout(l.pipeline, None);
                d.destroy_descriptor_set_layout(l.set, None);
            }
            for (_, m) in self.modules.drain() {
                d.destroy_shader_module(m, None);
            }
            if let Some((rp, fb)) = self.render_pass.take() {
                d.destroy_framebuffer(fb, None);
                d.destroy_render_pass(rp, None);
            }
            d.destroy_descriptor_pool(self.descriptor_pool, None);
            d.destroy_fence(self.fence, None);
            d.destroy_command_pool(self.command_pool, None);
        }
        if let Some(a) = self.output.take() {
            a.destroy(&self.dev);
        }
        if let Some(a) = self.rays.take() {
            a.destroy(&self.dev);
        }
        if let Some(a) = self.callables.take() {
            a.destroy(&self.dev);
        }
    }
}

/// An acceleration structure of `ty` sized for `geometries` with `counts` primitives: its storage buffer,
/// its scratch buffer (aligned to `scratch_align`) and the created, not yet built, structure.
fn sized_structure(
    dev: &VkDevice,
    accel: &ash::khr::acceleration_structure::Device,
    ty: vk::AccelerationStructureTypeKHR,
    geometries: &[vk::AccelerationStructureGeometryKHR],
    counts: &[u32],
    scratch_align: u64,
) -> Result<(vk::AccelerationStructureKHR, Allocation, Allocation), RealiseError> {
    let info = vk::AccelerationStructureBuildGeometryInfoKHR::default()
        .ty(ty)
        .mode(vk::BuildAccelerationStructureModeKHR::BUILD)
        .geometries(geometries);
    let mut sizes = vk::AccelerationStructureBuildSizesInfoKHR::default();
    // SAFETY: the geometry descriptions are valid and `counts` has one entry per geometry.
    unsafe {
        accel.get_acceleration_structure_build_sizes(
            vk::AccelerationStructureBuildTypeKHR::DEVICE,
            &info,
            counts,
            &mut sizes,
        )
    };
    let storage_usage = vk::BufferUsageFlags::ACCELERATION_STRUCTURE_STORAGE_KHR
        | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS;
    let scratch_usage =
        vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS;
    let none = vk::BufferCreateFlags::empty();
    let storage = Allocation::new(
        dev,
        sizes.acceleration_structure_size,
        storage_usage,
        none,
        256,
    )?;
    let scratch = Allocation::new(
        dev,
        sizes.build_scratch_size.max(1),
        scratch_usage,
        none,
        scratch_align,
    )?;
    // SAFETY: the storage buffer holds `acceleration_structure_size` bytes.
    let structure = unsafe {
        accel.create_acceleration_structure(
            &vk::AccelerationStructureCreateInfoKHR::default()
                .buffer(storage.buffer)
                .size(sizes.acceleration_structure_size)
                .ty(ty),
            None,
        )
    }
    .map_err(vkfail("vkCreateAccelerationStructureKHR"))?;
    Ok((structure, storage, scratch))
}

/// The bytes every scene's bottom-level structures are built from, and each geometry's offset in them:
/// geometry `g` of instance `i` is a triangle (3 vertices) or a box (min, max) around (2g, 4i, 0), at a
/// 16-aligned offset. The rays and the intersection shader rely on this placement (see `Instance`).
fn geometry_input(instances: &[Instance]) -> (Vec<u8>, Vec<Vec<u64>>) {
    let mut input: Vec<u8> = Vec::new();
    let mut offsets = Vec::with_capacity(instances.len());
    for (i, inst) in instances.iter().enumerate() {
        let mut per = Vec::with_capacity(inst.geometries.len());
        for (g, kind) in inst.geometries.iter().enumerate() {
            let (cx, cy) = (2.0 * g as f32, 4.0 * i as f32);
            input.resize(input.len().next_multiple_of(16), 0);
            per.push(input.len() as u64);
            let floats: &[f32] = match kind {
                GeometryKind::Triangles => &[
                    cx - 0.5,
                    cy - 0.5,
                    0.0,
                    cx + 0.5,
                    cy - 0.5,
                    0.0,
                    cx,
                    cy + 0.5,
                    0.0,
                ],
                GeometryKind::Aabbs => &[cx - 0.5, cy - 0.5, -0.5, cx + 0.5, cy + 0.5, 0.5],
            };
            floats
                .iter()
                .for_each(|f| input.extend_from_slice(&f.to_ne_bytes()));
        }
        offsets.push(per);
    }
    (input, offsets)
}
