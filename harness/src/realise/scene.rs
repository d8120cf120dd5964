//! The scene the rays see, realised from its plan ([`ScenePlan`]): one bottom-level structure per
//! instance holding its geometries (one triangle or box each, at the positions the rays aim at), a
//! top-level structure over them, as KHR or as NV acceleration structures, built once and cached per
//! device.

use super::DeviceCache;
use crate::error::{vkfail, HarnessError};
use crate::plan::scene::{
    instance_record, ScenePlan, AABB_STRIDE, TRIANGLE_VERTICES, VERTEX_STRIDE,
};
use crate::vk::commands::{begin_one_time, memory_barrier};
use crate::vk::memory::Allocation;
use crate::vk::VkDevice;
use ash::vk;
use model::world::{GeometryKind, PipelineApi};

/// The top-level structure of a built scene, of the extension the case's pipeline uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Tlas {
    Khr(vk::AccelerationStructureKHR),
    Nv(vk::AccelerationStructureNV),
}

/// A built scene: BLASes, TLAS and their buffers (and, for NV structures, their memory).
pub(crate) struct Scene {
    pub(crate) tlas: Tlas,
    structures: Vec<vk::AccelerationStructureKHR>,
    nv_structures: Vec<vk::AccelerationStructureNV>,
    nv_memory: Vec<vk::DeviceMemory>,
    buffers: Vec<Allocation>,
}

/// An acceleration structure of `ty` sized for `geometries` with `counts` primitives: its storage buffer,
/// its scratch buffer (aligned to `scratch_align`) and the created, not yet built, structure. The storage
/// buffer holds at least `storage_min` bytes.
#[allow(clippy::type_complexity)]
pub(crate) fn sized_structure(
    dev: &VkDevice,
    accel: &ash::khr::acceleration_structure::Device,
    ty: vk::AccelerationStructureTypeKHR,
    geometries: &[vk::AccelerationStructureGeometryKHR],
    counts: &[u32],
    scratch_align: u64,
    storage_min: u64,
) -> Result<(vk::AccelerationStructureKHR, Allocation, Allocation), HarnessError> {
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
        sizes.acceleration_structure_size.max(storage_min),
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

impl DeviceCache {
    /// The scene of a plan (cached).
    pub(crate) fn scene(&mut self, plan: &ScenePlan) -> Result<Tlas, HarnessError> {
        let key = serde_json::to_string(plan).unwrap_or_default();
        if !self.scenes.contains_key(&key) {
            let built = self.build_scene(plan);
            self.scenes.insert(key.clone(), built);
        }
        match &self.scenes[&key] {
            Ok(s) => Ok(s.tlas),
            Err(e) => Err(e.clone()),
        }
    }

    fn build_scene(&mut self, plan: &ScenePlan) -> Result<Scene, HarnessError> {
        let mut scene = Scene {
            tlas: Tlas::Khr(vk::AccelerationStructureKHR::null()),
            structures: Vec::new(),
            nv_structures: Vec::new(),
            nv_memory: Vec::new(),
            buffers: Vec::new(),
        };
        if plan.api == PipelineApi::Nv {
            let Some(nv) = self.dev.nv.clone() else {
                return Err(HarnessError::NotRealised(
                    "the case traces rays but does not enable VK_NV_ray_tracing".into(),
                ));
            };
            return match self.build_nv_scene_into(&nv, plan, &mut scene) {
                Ok(()) => Ok(scene),
                Err(e) => {
                    self.destroy_scene(scene);
                    Err(e)
                }
            };
        }
        let Some(accel) = self.dev.accel.clone() else {
            return Err(HarnessError::NotRealised(
                "the case traces rays but does not enable VK_KHR_acceleration_structure".into(),
            ));
        };
        if !self.dev.has_feature("accelerationStructure")
            || !self.dev.has_feature("bufferDeviceAddress")
        {
            return Err(HarnessError::NotRealised(
                "the case traces rays but does not enable accelerationStructure and bufferDeviceAddress".into(),
            ));
        }
        let result = self.build_scene_into(&accel, plan, &mut scene);
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
        plan: &ScenePlan,
        scene: &mut Scene,
    ) -> Result<(), HarnessError> {
        let dev = &self.dev;
        let input_usage = vk::BufferUsageFlags::ACCELERATION_STRUCTURE_BUILD_INPUT_READ_ONLY_KHR
            | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS;
        let scratch_align = (dev.limits.scratch_alignment as u64).max(256);
        let none = vk::BufferCreateFlags::empty();
        // Geometry input: one triangle or box per geometry, all in one buffer.
        let input = &plan.input;
        let inputs = Allocation::new(dev, input.len().max(16) as u64, input_usage, none, 256)?;
        inputs.write(0, input);
        let input_address = inputs.address;
        scene.buffers.push(inputs);

        let mut blas_addresses = Vec::new();
        let mut builds: Vec<(
            Vec<vk::AccelerationStructureGeometryKHR>,
            Vec<vk::AccelerationStructureBuildRangeInfoKHR>,
            vk::AccelerationStructureKHR,
            u64,
        )> = Vec::new();
        for bottom in &plan.bottoms {
            let mut geoms = Vec::new();
            let mut ranges = Vec::new();
            for g in bottom {
                let at = input_address + g.offset;
                let data = match g.kind {
                    GeometryKind::Triangles => vk::AccelerationStructureGeometryDataKHR {
                        triangles: vk::AccelerationStructureGeometryTrianglesDataKHR::default()
                            .vertex_format(vk::Format::R32G32B32_SFLOAT)
                            .vertex_data(vk::DeviceOrHostAddressConstKHR { device_address: at })
                            .vertex_stride(VERTEX_STRIDE)
                            .max_vertex(TRIANGLE_VERTICES - 1)
                            .index_type(vk::IndexType::NONE_KHR),
                    },
                    GeometryKind::Aabbs => vk::AccelerationStructureGeometryDataKHR {
                        aabbs: vk::AccelerationStructureGeometryAabbsDataKHR::default()
                            .data(vk::DeviceOrHostAddressConstKHR { device_address: at })
                            .stride(AABB_STRIDE),
                    },
                };
                let ty = match g.kind {
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
                0,
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
        // Instances: an inactive one (no geometry, semantics.md §4) references 0.
        let records = plan_records(plan, &blas_addresses);
        let inst_buf = instance_buffer(dev, &records, input_usage)?;
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
        let tlas_count = [plan.instances.len() as u32];
        let (tlas, storage, scratch) = sized_structure(
            dev,
            accel,
            vk::AccelerationStructureTypeKHR::TOP_LEVEL,
            &tlas_geom,
            &tlas_count,
            scratch_align,
            0,
        )?;
        scene.structures.push(tlas);
        scene.tlas = Tlas::Khr(tlas);
        let tlas_scratch = scratch.address;
        scene.buffers.push(storage);
        scene.buffers.push(scratch);

        // Record: every BLAS, a barrier, the TLAS; submit and wait.
        let d = &dev.device;
        let cb = self.cmds.cb;
        // SAFETY: the command buffer is idle (every case waits or resets before returning).
        unsafe {
            begin_one_time(d, cb)?;
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
            memory_barrier(
                d,
                cb,
                (
                    vk::PipelineStageFlags::ACCELERATION_STRUCTURE_BUILD_KHR,
                    vk::AccessFlags::ACCELERATION_STRUCTURE_WRITE_KHR,
                ),
                (
                    vk::PipelineStageFlags::ACCELERATION_STRUCTURE_BUILD_KHR
                        | vk::PipelineStageFlags::RAY_TRACING_SHADER_KHR,
                    vk::AccessFlags::ACCELERATION_STRUCTURE_READ_KHR,
                ),
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
                .primitive_count(plan.instances.len() as u32)];
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
        plan: &ScenePlan,
        scene: &mut Scene,
    ) -> Result<(), HarnessError> {
        let dev = &self.dev;
        let usage = vk::BufferUsageFlags::RAY_TRACING_NV;
        let none = vk::BufferCreateFlags::empty();
        // Geometry input, as for KHR (offsets 16-aligned; AABBs need 8).
        let input = &plan.input;
        let inputs = Allocation::new(dev, input.len().max(16) as u64, usage, none, 256)?;
        inputs.write(0, input);
        let input_buffer = inputs.buffer;
        scene.buffers.push(inputs);

        // Creates a structure for `info`, binds it to fresh memory and makes a scratch buffer for its build.
        let make = |info: vk::AccelerationStructureInfoNV,
                    scene: &mut Scene|
         -> Result<(vk::AccelerationStructureNV, vk::Buffer), HarnessError> {
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
                    HarnessError::NotRealised(
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
        for bottom in &plan.bottoms {
            let geoms: Vec<vk::GeometryNV> = bottom
                .iter()
                .map(|g| {
                    let at = g.offset;
                    let mut data = vk::GeometryDataNV::default();
                    let ty = match g.kind {
                        GeometryKind::Triangles => {
                            data.triangles = vk::GeometryTrianglesNV::default()
                                .vertex_data(input_buffer)
                                .vertex_offset(at)
                                .vertex_count(TRIANGLE_VERTICES)
                                .vertex_stride(VERTEX_STRIDE)
                                .vertex_format(vk::Format::R32G32B32_SFLOAT)
                                .index_type(vk::IndexType::NONE_NV);
                            vk::GeometryTypeNV::TRIANGLES
                        }
                        GeometryKind::Aabbs => {
                            data.aabbs = vk::GeometryAABBNV::default()
                                .aabb_data(input_buffer)
                                .num_aab_bs(1)
                                .stride(AABB_STRIDE as u32)
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
        let records = plan_records(plan, &handles);
        let inst_buf = instance_buffer(dev, &records, usage)?;
        let inst_buffer = inst_buf.buffer;
        scene.buffers.push(inst_buf);
        let tlas_info = vk::AccelerationStructureInfoNV::default()
            .ty(vk::AccelerationStructureTypeNV::TOP_LEVEL)
            .instance_count(plan.instances.len() as u32);
        let (tlas, tlas_scratch) = make(tlas_info, scene)?;
        scene.tlas = Tlas::Nv(tlas);

        let d = &self.dev.device;
        let cb = self.cmds.cb;
        // SAFETY: the command buffer is idle; every structure is bound to memory.
        unsafe {
            begin_one_time(d, cb)?;
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
            memory_barrier(
                d,
                cb,
                (
                    vk::PipelineStageFlags::ACCELERATION_STRUCTURE_BUILD_NV,
                    vk::AccessFlags::ACCELERATION_STRUCTURE_WRITE_NV,
                ),
                (
                    vk::PipelineStageFlags::ACCELERATION_STRUCTURE_BUILD_NV
                        | vk::PipelineStageFlags::RAY_TRACING_SHADER_NV,
                    vk::AccessFlags::ACCELERATION_STRUCTURE_READ_NV,
                ),
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

    pub(super) fn destroy_scene(&self, scene: Scene) {
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
}

/// The instance records of a scene's top-level structure: instance `i` with its mask and shader
/// binding table offset, referencing the bottom-level structure it names (`references[k]`, a KHR device
/// address or an NV handle) or 0 when it has none.
fn plan_records(plan: &ScenePlan, references: &[u64]) -> Vec<u8> {
    plan.instances
        .iter()
        .flat_map(|i| {
            let reference = i
                .bottom
                .and_then(|k| references.get(k))
                .copied()
                .unwrap_or(0);
            instance_record(i.mask, i.sbt_record_offset, reference)
        })
        .collect()
}

/// Instance records (64 bytes each) in a buffer of `usage`.
pub(crate) fn instance_buffer(
    dev: &VkDevice,
    records: &[u8],
    usage: vk::BufferUsageFlags,
) -> Result<Allocation, HarnessError> {
    Allocation::filled(dev, records, 64, usage, 256)
}
