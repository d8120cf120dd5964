//! Realises a case's world on a device: buffers placed at 4096-aligned addresses with their contents (shader
//! group handles, indirect commands), the ray tracing pipeline with one specialised stage per group, and the
//! scene (one BLAS per instance, a TLAS). Pipelines and scenes are cached per device across cases.

use crate::error::HarnessError;
use crate::shaders::{self, ShaderKind};
use crate::vulkan::VkDevice;
use ash::vk;
use model::call::BUFFER_PLACEMENT_ALIGNMENT;
use model::world::{Contents, GeneralStage, GeometryKind, HandleRef, Instance, Pipeline, PipelineApi, ShaderGroup, World};
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

/// A buffer with host-visible memory, mapped, and its device address (0 without bufferDeviceAddress).
pub struct Allocation {
    pub buffer: vk::Buffer,
    pub memory: vk::DeviceMemory,
    pub address: u64,
    pub size: u64,
    pub ptr: *mut u8,
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
        let info = vk::BufferCreateInfo::default().size(size.max(1)).usage(usage).flags(flags);
        // SAFETY: valid create info.
        let mut buffer = unsafe { d.create_buffer(&info, None) }.map_err(vkfail("vkCreateBuffer"))?;
        // SAFETY: buffer is valid.
        let req = unsafe { d.get_buffer_memory_requirements(buffer) };
        let host = vk::MemoryPropertyFlags::HOST_VISIBLE | vk::MemoryPropertyFlags::HOST_COHERENT;
        let Some(mt) = dev.memory_type(req.memory_type_bits, host) else {
            // SAFETY: destroying what we created.
            unsafe { d.destroy_buffer(buffer, None) };
            return Err(RealiseError::Unsupported("no host-visible, coherent memory type for a buffer".into()));
        };
        let bda = dev.has_feature("bufferDeviceAddress");
        let alloc_size = req.size + if align > 1 { align } else { 0 };
        let mut flags_info = vk::MemoryAllocateFlagsInfo::default().flags(vk::MemoryAllocateFlags::DEVICE_ADDRESS);
        let mut ai = vk::MemoryAllocateInfo::default().allocation_size(alloc_size).memory_type_index(mt);
        if bda {
            ai = ai.push_next(&mut flags_info);
        }
        // SAFETY: valid allocate info.
        let memory = match unsafe { d.allocate_memory(&ai, None) } {
            Ok(m) => m,
            Err(r) => {
                // SAFETY: destroying what we created.
                unsafe { d.destroy_buffer(buffer, None) };
                return Err(RealiseError::Failed(format!("vkAllocateMemory({alloc_size}) failed: {r:?}")));
            }
        };
        let cleanup = |buffer: vk::Buffer| {
            // SAFETY: destroying what we created.
            unsafe {
                d.destroy_buffer(buffer, None);
                d.free_memory(memory, None);
            }
        };
        let address_of = |b: vk::Buffer| -> u64 {
            if bda {
                // SAFETY: b is bound to memory allocated with DEVICE_ADDRESS.
                unsafe { d.get_buffer_device_address(&vk::BufferDeviceAddressInfo::default().buffer(b)) }
            } else {
                0
            }
        };
        // SAFETY: fresh buffer, fresh memory large enough.
        if let Err(r) = unsafe { d.bind_buffer_memory(buffer, memory, 0) } {
            cleanup(buffer);
            return Err(RealiseError::Failed(format!("vkBindBufferMemory failed: {r:?}")));
        }
        let mut address = address_of(buffer);
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
            buffer = unsafe { d.create_buffer(&info, None) }.map_err(vkfail("vkCreateBuffer"))?;
            // SAFETY: offset + size fits the allocation.
            if let Err(r) = unsafe { d.bind_buffer_memory(buffer, memory, delta) } {
                cleanup(buffer);
                return Err(RealiseError::Failed(format!("vkBindBufferMemory failed: {r:?}")));
            }
            offset = delta;
            address = address_of(buffer);
            if address % align != 0 {
                cleanup(buffer);
                return Err(RealiseError::Unsupported(format!(
                    "the driver placed a buffer at {address:#x}, not a multiple of {align}"
                )));
            }
        }
        // SAFETY: host-visible memory, whole range.
        let ptr = match unsafe { d.map_memory(memory, 0, vk::WHOLE_SIZE, vk::MemoryMapFlags::empty()) } {
            Ok(p) => p as *mut u8,
            Err(r) => {
                cleanup(buffer);
                return Err(RealiseError::Failed(format!("vkMapMemory failed: {r:?}")));
            }
        };
        // SAFETY: mapped range covers offset..offset+size.
        let ptr = unsafe { ptr.add(offset as usize) };
        // SAFETY: zero the buffer's bytes.
        unsafe { std::ptr::write_bytes(ptr, 0, size as usize) };
        Ok(Allocation { buffer, memory, address, size, ptr })
    }

    /// Copies `bytes` to `offset`, cutting what would fall past the end of the buffer.
    pub fn write(&self, offset: u64, bytes: &[u8]) {
        if offset >= self.size {
            return;
        }
        let n = bytes.len().min((self.size - offset) as usize);
        // SAFETY: the range lies inside the mapped buffer.
        unsafe { std::ptr::copy_nonoverlapping(bytes.as_ptr(), self.ptr.add(offset as usize), n) };
    }

    pub fn read_u32s(&self, count: usize) -> Vec<u32> {
        let n = count.min((self.size / 4) as usize);
        // SAFETY: the range lies inside the mapped buffer; u32 reads of a 4-aligned mapping.
        unsafe { std::slice::from_raw_parts(self.ptr as *const u32, n) }.to_vec()
    }

    pub fn destroy(self, dev: &VkDevice) {
        // SAFETY: the GPU no longer uses the buffer (callers wait first).
        unsafe {
            dev.device.destroy_buffer(self.buffer, None);
            dev.device.unmap_memory(self.memory);
            dev.device.free_memory(self.memory, None);
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
}

/// A built scene: BLASes, TLAS and their buffers.
pub struct Scene {
    pub tlas: vk::AccelerationStructureKHR,
    structures: Vec<vk::AccelerationStructureKHR>,
    buffers: Vec<Allocation>,
}

/// Per-device objects the harness reuses across cases.
pub struct DeviceCache {
    modules: HashMap<ShaderKind, vk::ShaderModule>,
    layouts: HashMap<bool, Layouts>,
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
    pub render_pass: Option<(vk::RenderPass, vk::Framebuffer)>,
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
            let primary = alloc(vk::CommandBufferLevel::PRIMARY).map_err(vkfail("vkAllocateCommandBuffers"))?;
            let secondary = alloc(vk::CommandBufferLevel::SECONDARY).map_err(vkfail("vkAllocateCommandBuffers"))?;
            let fence = d.create_fence(&vk::FenceCreateInfo::default(), None).map_err(vkfail("vkCreateFence"))?;
            let mut sizes = vec![vk::DescriptorPoolSize { ty: vk::DescriptorType::STORAGE_BUFFER, descriptor_count: 4 }];
            if dev.accel.is_some() {
                sizes.push(vk::DescriptorPoolSize {
                    ty: vk::DescriptorType::ACCELERATION_STRUCTURE_KHR,
                    descriptor_count: 2,
                });
            }
            let descriptor_pool = d
                .create_descriptor_pool(&vk::DescriptorPoolCreateInfo::default().max_sets(2).pool_sizes(&sizes), None)
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
                render_pass: None,
                dev,
            })
        }
    }

    fn module(&mut self, kind: ShaderKind) -> Result<vk::ShaderModule, RealiseError> {
        if let Some(m) = self.modules.get(&kind) {
            return Ok(*m);
        }
        let code = shaders::spirv(kind)?;
        // SAFETY: valid SPIR-V words.
        let m = unsafe { self.dev.device.create_shader_module(&vk::ShaderModuleCreateInfo::default().code(&code), None) }
            .map_err(vkfail("vkCreateShaderModule"))?;
        self.modules.insert(kind, m);
        Ok(m)
    }

    /// Layouts for the raygen variant: with the scene at binding 0 (`trace`) or without.
    pub fn layouts(&mut self, trace: bool) -> Result<Layouts, RealiseError> {
        if let Some(l) = self.layouts.get(&trace) {
            return Ok(*l);
        }
        let stages = vk::ShaderStageFlags::RAYGEN_KHR;
        let mut bindings = vec![
            vk::DescriptorSetLayoutBinding::default()
                .binding(1)
                .descriptor_type(vk::DescriptorType::STORAGE_BUFFER)
                .descriptor_count(1)
                .stage_flags(stages),
            vk::DescriptorSetLayoutBinding::default()
                .binding(2)
                .descriptor_type(vk::DescriptorType::STORAGE_BUFFER)
                .descriptor_count(1)
                .stage_flags(stages),
        ];
        if trace {
            bindings.push(
                vk::DescriptorSetLayoutBinding::default()
                    .binding(0)
                    .descriptor_type(vk::DescriptorType::ACCELERATION_STRUCTURE_KHR)
                    .descriptor_count(1)
                    .stage_flags(stages),
            );
        }
        let d = &self.dev.device;
        // SAFETY: valid create infos.
        let set = unsafe {
            d.create_descriptor_set_layout(&vk::DescriptorSetLayoutCreateInfo::default().bindings(&bindings), None)
        }
        .map_err(vkfail("vkCreateDescriptorSetLayout"))?;
        let sets = [set];
        // SAFETY: as above.
        let pipeline =
            unsafe { d.create_pipeline_layout(&vk::PipelineLayoutCreateInfo::default().set_layouts(&sets), None) }
                .map_err(vkfail("vkCreatePipelineLayout"))?;
        let l = Layouts { set, pipeline };
        self.layouts.insert(trace, l);
        Ok(l)
    }

    /// The pipeline for a description (cached); `foreign` makes a second, distinct pipeline of it.
    pub fn pipeline(&mut self, p: &Pipeline, trace: bool, foreign: bool) -> Result<&RealPipeline, RealiseError> {
        let key = format!("{}|{trace}|{foreign}", serde_json::to_string(p).unwrap_or_default());
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
        if p.api == PipelineApi::Nv {
            return Err(RealiseError::Unsupported("VK_NV_ray_tracing pipelines are not realised by the harness yet".into()));
        }
        if self.dev.rt.is_none() {
            return Err(RealiseError::Unsupported(
                "the case does not enable VK_KHR_ray_tracing_pipeline, so no ray tracing pipeline can be made".into(),
            ));
        }
        let layouts = self.layouts(trace)?;
        let raygen = if trace { ShaderKind::RaygenTrace } else { ShaderKind::RaygenPlain };
        // (group index, stage flag, module) per stage, and the group create infos.
        let mut stage_list: Vec<(u32, vk::ShaderStageFlags, vk::ShaderModule)> = Vec::new();
        let mut groups = Vec::new();
        let unused = vk::SHADER_UNUSED_KHR;
        for (g, group) in p.groups.iter().enumerate() {
            let g = g as u32;
            let mut add = |this: &mut Self, kind: ShaderKind, stage: vk::ShaderStageFlags| -> Result<u32, RealiseError> {
                let m = this.module(kind)?;
                stage_list.push((g, stage, m));
                Ok(stage_list.len() as u32 - 1)
            };
            let info = match group {
                ShaderGroup::General { stage } => {
                    let (kind, flag) = match stage {
                        GeneralStage::Raygen => (raygen, vk::ShaderStageFlags::RAYGEN_KHR),
                        GeneralStage::Miss => (ShaderKind::Miss, vk::ShaderStageFlags::MISS_KHR),
                        GeneralStage::Callable => (ShaderKind::Callable, vk::ShaderStageFlags::CALLABLE_KHR),
                    };
                    let s = add(self, kind, flag)?;
                    vk::RayTracingShaderGroupCreateInfoKHR::default()
                        .ty(vk::RayTracingShaderGroupTypeKHR::GENERAL)
                        .general_shader(s)
                        .closest_hit_shader(unused)
                        .any_hit_shader(unused)
                        .intersection_shader(unused)
                }
                ShaderGroup::TrianglesHit { closest_hit, any_hit } | ShaderGroup::ProceduralHit { closest_hit, any_hit, .. } => {
                    let procedural = matches!(group, ShaderGroup::ProceduralHit { .. });
                    let ch = if *closest_hit { add(self, ShaderKind::ClosestHit, vk::ShaderStageFlags::CLOSEST_HIT_KHR)? } else { unused };
                    let ah = if *any_hit { add(self, ShaderKind::AnyHit, vk::ShaderStageFlags::ANY_HIT_KHR)? } else { unused };
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
                    vk::RayTracingShaderGroupCreateInfoKHR::default()
                        .ty(if procedural {
                            vk::RayTracingShaderGroupTypeKHR::PROCEDURAL_HIT_GROUP
                        } else {
                            vk::RayTracingShaderGroupTypeKHR::TRIANGLES_HIT_GROUP
                        })
                        .general_shader(unused)
                        .closest_hit_shader(ch)
                        .any_hit_shader(ah)
                        .intersection_shader(is)
                }
            };
            groups.push(info);
        }
        let group_values: Vec<u32> = stage_list.iter().map(|(g, _, _)| *g).collect();
        let entry = [vk::SpecializationMapEntry { constant_id: 0, offset: 0, size: 4 }];
        let specs: Vec<vk::SpecializationInfo> = group_values
            .iter()
            .map(|v| {
                let bytes: &[u8] = crate::structs::as_bytes(v);
                vk::SpecializationInfo::default().map_entries(&entry).data(bytes)
            })
            .collect();
        let main = c"main";
        let stages: Vec<vk::PipelineShaderStageCreateInfo> = stage_list
            .iter()
            .zip(&specs)
            .map(|((_, flag, m), spec)| {
                vk::PipelineShaderStageCreateInfo::default().stage(*flag).module(*m).name(main).specialization_info(spec)
            })
            .collect();
        let dynamic = [vk::DynamicState::RAY_TRACING_PIPELINE_STACK_SIZE_KHR];
        let dyn_info = vk::PipelineDynamicStateCreateInfo::default().dynamic_states(&dynamic);
        let iface = vk::RayTracingPipelineInterfaceCreateInfoKHR::default()
            .max_pipeline_ray_payload_size(4)
            .max_pipeline_ray_hit_attribute_size(8);
        let flags = vk::PipelineCreateFlags::from_raw(p.flags.0 as u32);
        let mut info = vk::RayTracingPipelineCreateInfoKHR::default()
            .flags(flags)
            .stages(&stages)
            .groups(&groups)
            .max_pipeline_ray_recursion_depth(p.max_recursion_depth)
            .layout(layouts.pipeline);
        if p.dynamic_stack_size {
            info = info.dynamic_state(&dyn_info);
        }
        if flags.contains(vk::PipelineCreateFlags::LIBRARY_KHR) {
            info = info.library_interface(&iface);
        }
        let rt = self.dev.rt.as_ref().expect("checked above");
        // SAFETY: every pointer in `info` outlives the call.
        let pipeline = unsafe {
            rt.create_ray_tracing_pipelines(vk::DeferredOperationKHR::null(), vk::PipelineCache::null(), &[info], None)
        }
        .map_err(|(_, r)| RealiseError::Failed(format!("vkCreateRayTracingPipelinesKHR failed: {r:?}")))?[0];
        let hs = self.dev.limits.handle_size as usize;
        let n = p.groups.len();
        let handles = if flags.contains(vk::PipelineCreateFlags::LIBRARY_KHR) || n == 0 {
            vec![0u8; hs * n]
        } else {
            // SAFETY: valid pipeline, group range inside it.
            unsafe { rt.get_ray_tracing_shader_group_handles(pipeline, 0, n as u32, hs * n) }
                .map_err(vkfail("vkGetRayTracingShaderGroupHandlesKHR"))?
        };
        Ok(RealPipeline { pipeline, handles, group_count: n })
    }

    /// The scene for a list of instances (cached).
    pub fn scene(&mut self, instances: &[Instance]) -> Result<vk::AccelerationStructureKHR, RealiseError> {
        let key = serde_json::to_string(instances).unwrap_or_default();
        if !self.scenes.contains_key(&key) {
            let built = self.build_scene(instances).map_err(|e| match e {
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

    fn build_scene(&mut self, instances: &[Instance]) -> Result<Scene, RealiseError> {
        let Some(accel) = self.dev.accel.clone() else {
            return Err(RealiseError::Unsupported(
                "the case traces rays but does not enable VK_KHR_acceleration_structure".into(),
            ));
        };
        if !self.dev.has_feature("accelerationStructure") || !self.dev.has_feature("bufferDeviceAddress") {
            return Err(RealiseError::Unsupported(
                "the case traces rays but does not enable accelerationStructure and bufferDeviceAddress".into(),
            ));
        }
        let mut scene = Scene { tlas: vk::AccelerationStructureKHR::null(), structures: Vec::new(), buffers: Vec::new() };
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
        // A bottom-level structure holds geometries of one type; a case that mixes them cannot be built
        // validly, so it is not realised rather than handed to the driver.
        if let Some(i) = instances.iter().position(|inst| inst.geometries.windows(2).any(|w| w[0] != w[1])) {
            return Err(RealiseError::Unsupported(format!(
                "instance {i} mixes triangle and AABB geometries; one acceleration structure holds one type"
            )));
        }
        let dev = &self.dev;
        let input_usage = vk::BufferUsageFlags::ACCELERATION_STRUCTURE_BUILD_INPUT_READ_ONLY_KHR
            | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS;
        let storage_usage =
            vk::BufferUsageFlags::ACCELERATION_STRUCTURE_STORAGE_KHR | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS;
        let scratch_usage = vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS;
        let scratch_align = (dev.limits.scratch_alignment as u64).max(256);
        let none = vk::BufferCreateFlags::empty();
        // Geometry input: triangles (3 vertices) and boxes per geometry, all in one buffer.
        let mut input: Vec<u8> = Vec::new();
        let mut offsets: Vec<Vec<u64>> = Vec::new();
        for (i, inst) in instances.iter().enumerate() {
            let mut per = Vec::new();
            for (g, kind) in inst.geometries.iter().enumerate() {
                let (cx, cy) = (2.0 * g as f32, 4.0 * i as f32);
                while input.len() % 16 != 0 {
                    input.push(0);
                }
                per.push(input.len() as u64);
                let floats: Vec<f32> = match kind {
                    GeometryKind::Triangles => {
                        vec![cx - 0.5, cy - 0.5, 0.0, cx + 0.5, cy - 0.5, 0.0, cx, cy + 0.5, 0.0]
                    }
                    GeometryKind::Aabbs => vec![cx - 0.5, cy - 0.5, -0.5, cx + 0.5, cy + 0.5, 0.5],
                };
                floats.iter().for_each(|f| input.extend_from_slice(&f.to_ne_bytes()));
            }
            offsets.push(per);
        }
        let inputs = Allocation::new(dev, input.len().max(16) as u64, input_usage, none, 256)?;
        inputs.write(0, &input);
        let input_address = inputs.address;
        scene.buffers.push(inputs);

        let mut blas_addresses = Vec::new();
        let mut builds: Vec<(Vec<vk::AccelerationStructureGeometryKHR>, Vec<vk::AccelerationStructureBuildRangeInfoKHR>, vk::AccelerationStructureKHR, u64)> =
            Vec::new();
        for (i, inst) in instances.iter().enumerate() {
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
                geoms.push(vk::AccelerationStructureGeometryKHR::default().geometry_type(ty).geometry(data));
                ranges.push(vk::AccelerationStructureBuildRangeInfoKHR::default().primitive_count(1));
            }
            let counts: Vec<u32> = ranges.iter().map(|r| r.primitive_count).collect();
            let info = vk::AccelerationStructureBuildGeometryInfoKHR::default()
                .ty(vk::AccelerationStructureTypeKHR::BOTTOM_LEVEL)
                .mode(vk::BuildAccelerationStructureModeKHR::BUILD)
                .geometries(&geoms);
            let mut sizes = vk::AccelerationStructureBuildSizesInfoKHR::default();
            // SAFETY: geometry descriptions are valid; counts match.
            unsafe {
                accel.get_acceleration_structure_build_sizes(
                    vk::AccelerationStructureBuildTypeKHR::DEVICE,
                    &info,
                    &counts,
                    &mut sizes,
                )
            };
            let storage = Allocation::new(dev, sizes.acceleration_structure_size, storage_usage, none, 256)?;
            let scratch = Allocation::new(dev, sizes.build_scratch_size.max(1), scratch_usage, none, scratch_align)?;
            // SAFETY: storage buffer is large enough.
            let blas = unsafe {
                accel.create_acceleration_structure(
                    &vk::AccelerationStructureCreateInfoKHR::default()
                        .buffer(storage.buffer)
                        .size(sizes.acceleration_structure_size)
                        .ty(vk::AccelerationStructureTypeKHR::BOTTOM_LEVEL),
                    None,
                )
            }
            .map_err(vkfail("vkCreateAccelerationStructureKHR"))?;
            scene.structures.push(blas);
            // SAFETY: valid structure.
            let addr = unsafe {
                accel.get_acceleration_structure_device_address(
                    &vk::AccelerationStructureDeviceAddressInfoKHR::default().acceleration_structure(blas),
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
                transform: vk::TransformMatrixKHR { matrix: [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0] },
                instance_custom_index_and_mask: vk::Packed24_8::new(0, inst.mask),
                instance_shader_binding_table_record_offset_and_flags: vk::Packed24_8::new(
                    inst.sbt_record_offset & 0xFF_FFFF,
                    0,
                ),
                acceleration_structure_reference: vk::AccelerationStructureReferenceKHR { device_handle: *addr },
            })
            .collect();
        let record_bytes: Vec<u8> = records.iter().flat_map(|r| crate::structs::as_bytes(r).to_vec()).collect();
        let inst_buf = Allocation::new(dev, record_bytes.len().max(64) as u64, input_usage, none, 256)?;
        inst_buf.write(0, &record_bytes);
        let tlas_geom = [vk::AccelerationStructureGeometryKHR::default()
            .geometry_type(vk::GeometryTypeKHR::INSTANCES)
            .geometry(vk::AccelerationStructureGeometryDataKHR {
                instances: vk::AccelerationStructureGeometryInstancesDataKHR::default()
                    .data(vk::DeviceOrHostAddressConstKHR { device_address: inst_buf.address }),
            })];
        scene.buffers.push(inst_buf);
        let tlas_count = [instances.len() as u32];
        let tlas_info = vk::AccelerationStructureBuildGeometryInfoKHR::default()
            .ty(vk::AccelerationStructureTypeKHR::TOP_LEVEL)
            .mode(vk::BuildAccelerationStructureModeKHR::BUILD)
            .geometries(&tlas_geom);
        let mut sizes = vk::AccelerationStructureBuildSizesInfoKHR::default();
        // SAFETY: valid description.
        unsafe {
            accel.get_acceleration_structure_build_sizes(
                vk::AccelerationStructureBuildTypeKHR::DEVICE,
                &tlas_info,
                &tlas_count,
                &mut sizes,
            )
        };
        let storage = Allocation::new(dev, sizes.acceleration_structure_size, storage_usage, none, 256)?;
        let scratch = Allocation::new(dev, sizes.build_scratch_size.max(1), scratch_usage, none, scratch_align)?;
        // SAFETY: storage is large enough.
        let tlas = unsafe {
            accel.create_acceleration_structure(
                &vk::AccelerationStructureCreateInfoKHR::default()
                    .buffer(storage.buffer)
                    .size(sizes.acceleration_structure_size)
                    .ty(vk::AccelerationStructureTypeKHR::TOP_LEVEL),
                None,
            )
        }
        .map_err(vkfail("vkCreateAccelerationStructureKHR"))?;
        scene.structures.push(tlas);
        scene.tlas = tlas;
        let tlas_scratch = scratch.address;
        scene.buffers.push(storage);
        scene.buffers.push(scratch);

        // Record: every BLAS, a barrier, the TLAS; submit and wait.
        let d = &dev.device;
        let cb = self.primary;
        // SAFETY: the command buffer is idle (every case waits or resets before returning).
        unsafe {
            d.reset_command_buffer(cb, vk::CommandBufferResetFlags::empty()).map_err(vkfail("vkResetCommandBuffer"))?;
            d.begin_command_buffer(cb, &vk::CommandBufferBeginInfo::default().flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT))
                .map_err(vkfail("vkBeginCommandBuffer"))?;
            for (geoms, ranges, blas, scratch) in &builds {
                let info = vk::AccelerationStructureBuildGeometryInfoKHR::default()
                    .ty(vk::AccelerationStructureTypeKHR::BOTTOM_LEVEL)
                    .mode(vk::BuildAccelerationStructureModeKHR::BUILD)
                    .geometries(geoms)
                    .dst_acceleration_structure(*blas)
                    .scratch_data(vk::DeviceOrHostAddressKHR { device_address: *scratch });
                accel.cmd_build_acceleration_structures(cb, &[info], &[ranges.as_slice()]);
            }
            let barrier = vk::MemoryBarrier::default()
                .src_access_mask(vk::AccessFlags::ACCELERATION_STRUCTURE_WRITE_KHR)
                .dst_access_mask(vk::AccessFlags::ACCELERATION_STRUCTURE_READ_KHR);
            d.cmd_pipeline_barrier(
                cb,
                vk::PipelineStageFlags::ACCELERATION_STRUCTURE_BUILD_KHR,
                vk::PipelineStageFlags::ACCELERATION_STRUCTURE_BUILD_KHR | vk::PipelineStageFlags::RAY_TRACING_SHADER_KHR,
                vk::DependencyFlags::empty(),
                &[barrier],
                &[],
                &[],
            );
            let info = tlas_info
                .dst_acceleration_structure(tlas)
                .scratch_data(vk::DeviceOrHostAddressKHR { device_address: tlas_scratch });
            let range = [vk::AccelerationStructureBuildRangeInfoKHR::default().primitive_count(instances.len() as u32)];
            accel.cmd_build_acceleration_structures(cb, &[info], &[&range]);
            d.end_command_buffer(cb).map_err(vkfail("vkEndCommandBuffer"))?;
        }
        self.submit_and_wait(std::time::Duration::from_secs(60))
    }

    /// Submits the primary command buffer and waits for it.
    pub fn submit_and_wait(&self, timeout: std::time::Duration) -> Result<(), RealiseError> {
        let d = &self.dev.device;
        let cbs = [self.primary];
        let submit = [vk::SubmitInfo::default().command_buffers(&cbs)];
        // SAFETY: the command buffer is executable; the fence is unsignalled.
        unsafe {
            d.queue_submit(self.dev.queue, &submit, self.fence).map_err(vkfail("vkQueueSubmit"))?;
            let waited = d.wait_for_fences(&[self.fence], true, timeout.as_nanos().min(u64::MAX as u128) as u64);
            match waited {
                Ok(()) => {}
                Err(vk::Result::TIMEOUT) => {
                    return Err(RealiseError::Failed(format!("TIMEOUT: the GPU did not finish within {timeout:?}")))
                }
                Err(r) => return Err(RealiseError::Failed(format!("vkWaitForFences failed: {r:?}"))),
            }
            d.reset_fences(&[self.fence]).map_err(vkfail("vkResetFences"))?;
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
        for b in scene.buffers {
            b.destroy(&self.dev);
        }
    }

    /// Buffers at least `words` output words and `rays` ray records large (grown when needed).
    pub fn io_buffers(&mut self, words: usize, rays: usize) -> Result<(), RealiseError> {
        let usage = vk::BufferUsageFlags::STORAGE_BUFFER;
        let want_out = (words.max(1) * 4) as u64;
        if self.output.as_ref().is_none_or(|a| a.size < want_out) {
            if let Some(a) = self.output.take() {
                a.destroy(&self.dev);
            }
            self.output = Some(Allocation::new(&self.dev, want_out.max(4096), usage, vk::BufferCreateFlags::empty(), 1)?);
        }
        let want_rays = (16 + rays.max(1) * RAY_RECORD_SIZE) as u64;
        if self.rays.as_ref().is_none_or(|a| a.size < want_rays) {
            if let Some(a) = self.rays.take() {
                a.destroy(&self.dev);
            }
            self.rays = Some(Allocation::new(&self.dev, want_rays.max(4096), usage, vk::BufferCreateFlags::empty(), 1)?);
        }
        Ok(())
    }

    /// A render pass with no attachments and a 1x1 framebuffer, for cases recorded inside a render pass.
    pub fn empty_render_pass(&mut self) -> Result<(vk::RenderPass, vk::Framebuffer), RealiseError> {
        if let Some(rp) = self.render_pass {
            return Ok(rp);
        }
        let d = &self.dev.device;
        let subpass = [vk::SubpassDescription::default().pipeline_bind_point(vk::PipelineBindPoint::GRAPHICS)];
        // SAFETY: valid create infos.
        unsafe {
            let rp = d
                .create_render_pass(&vk::RenderPassCreateInfo::default().subpasses(&subpass), None)
                .map_err(vkfail("vkCreateRenderPass"))?;
            let fb = d
                .create_framebuffer(
                    &vk::FramebufferCreateInfo::default().render_pass(rp).width(1).height(1).layers(1),
                    None,
                )
                .map_err(vkfail("vkCreateFramebuffer"))?;
            self.render_pass = Some((rp, fb));
            Ok((rp, fb))
        }
    }

    /// Creates the case's buffers with their contents; returns them by name.
    pub fn case_buffers(&mut self, world: &World, pipeline: Option<(&Pipeline, bool)>) -> Result<Vec<(String, Allocation)>, RealiseError> {
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
        let hs = self.dev.limits.handle_size as usize;
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
                return Err(RealiseError::Unsupported("foreign handles need a pipeline description to copy".into()))
            }
            _ => Vec::new(),
        };
        if !self.dev.has_feature("bufferDeviceAddress") && !world.buffers.is_empty() {
            return Err(RealiseError::Unsupported(
                "the case does not enable bufferDeviceAddress, so the harness cannot give its buffers addresses".into(),
            ));
        }
        for b in &world.buffers {
            if b.is_sparse() {
                let why = if self.dev.sparse_binding {
                    "sparse buffers are not realised by the harness yet"
                } else {
                    "the case has a sparse buffer but the device lacks sparseBinding"
                };
                return Err(RealiseError::Unsupported(format!("buffer `{}`: {why}", b.name)));
            }
            if b.memory != MemoryBinding::Whole {
                return Err(RealiseError::Unsupported(format!(
                    "buffer `{}`: memory binding {:?} is not realised by the harness yet",
                    b.name, b.memory
                )));
            }
            let usage = vk::BufferUsageFlags::from_raw(b.usage.0 as u32);
            let flags = vk::BufferCreateFlags::from_raw(b.flags.0 as u32);
            if b.size == 0 {
                return Err(RealiseError::Unsupported(format!("buffer `{}` has size 0, which cannot be created", b.name)));
            }
            let a = Allocation::new(&self.dev, b.size, usage, flags, BUFFER_PLACEMENT_ALIGNMENT)?;
            for c in &b.contents {
                match c {
                    Contents::ShaderRecords { offset, stride, handles } => {
                        for (i, h) in handles.iter().enumerate() {
                            let bytes: Vec<u8> = match h {
                                HandleRef::Zero => vec![0; hs],
                                HandleRef::Group(n) => own.get(*n as usize * hs..(*n as usize + 1) * hs).map_or(vec![0; hs], |s| s.to_vec()),
                                HandleRef::Foreign(n) => {
                                    foreign.get(*n as usize * hs..(*n as usize + 1) * hs).map_or(vec![0; hs], |s| s.to_vec())
                                }
                            };
                            a.write(offset + i as u64 * stride, &bytes);
                        }
                    }
                    Contents::TraceRaysIndirectCommand { offset, width, height, depth } => {
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

impl Drop for DeviceCache {
    fn drop(&mut self) {
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
    }
}
