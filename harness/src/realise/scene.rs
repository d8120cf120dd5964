//! The scene the rays see: one bottom-level structure per instance holding its geometries (one triangle
//! or box each, at the positions the rays aim at), a top-level structure over them, as KHR or as NV
//! acceleration structures, built once and cached per device.

use super::DeviceCache;
use crate::error::{vkfail, HarnessError};
use crate::vk::commands::{begin_one_time, memory_barrier};
use crate::vk::memory::Allocation;
use crate::vk::VkDevice;
use ash::vk;
use model::world::{GeometryKind, Instance, PipelineApi};

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

impl DeviceCache {
    /// The scene for a list of instances (cached).
    pub(crate) fn scene(
        &mut self,
        instances: &[Instance],
        api: PipelineApi,
    ) -> Result<Tlas, HarnessError> {
        let key = format!(
            "{api:?}|{}",
            serde_json::to_string(instances).unwrap_or_default()
        );
        if !self.scenes.contains_key(&key) {
            let built = self.build_scene(instances, api);
            self.scenes.insert(key.clone(), built);
        }
        match &self.scenes[&key] {
            Ok(s) => Ok(s.tlas),
            Err(e) => Err(e.clone()),
        }
    }

    fn build_scene(
        &mut self,
        instances: &[Instance],
        api: PipelineApi,
    ) -> Result<Scene, HarnessError> {
        // A bottom-level structure holds geometries of one type; a case that mixes them cannot be built
        // validly, so it is not realised rather than handed to the driver.
        if let Some(i) = instances
            .iter()
            .position(|inst| inst.geometries.windows(2).any(|w| w[0] != w[1]))
        {
            return Err(HarnessError::NotRealised(format!(
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
                return Err(HarnessError::NotRealised(
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
    ) -> Result<(), HarnessError> {
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
        // Instances.
        let inst_buf = instance_buffer(dev, instances, &blas_addresses, input_usage)?;
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
    ) -> Result<(), HarnessError> {
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
        let inst_buf = instance_buffer(dev, instances, &handles, usage)?;
        let inst_buffer = inst_buf.buffer;
        scene.buffers.push(inst_buf);
        let tlas_info = vk::AccelerationStructureInfoNV::default()
            .ty(vk::AccelerationStructureTypeNV::TOP_LEVEL)
            .instance_count(instances.len() as u32);
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

/// The instance records of a scene's top-level structure in a buffer of `usage`: instance `i` with its
/// mask and shader binding table offset, referencing `references[i]` (a KHR device address or an NV
/// handle; 0 for an inactive instance), with the identity transform. KHR and NV records have one layout.
pub(crate) fn instance_buffer(
    dev: &VkDevice,
    instances: &[Instance],
    references: &[u64],
    usage: vk::BufferUsageFlags,
) -> Result<Allocation, HarnessError> {
    let bytes: Vec<u8> = instances
        .iter()
        .zip(references)
        .flat_map(|(inst, reference)| {
            let record = vk::AccelerationStructureInstanceKHR {
                transform: vk::TransformMatrixKHR {
                    matrix: [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0],
                },
                instance_custom_index_and_mask: vk::Packed24_8::new(0, inst.mask),
                instance_shader_binding_table_record_offset_and_flags: vk::Packed24_8::new(
                    inst.sbt_record_offset & 0xFF_FFFF,
                    0,
                ),
                acceleration_structure_reference: vk::AccelerationStructureReferenceKHR {
                    device_handle: *reference,
                },
            };
            crate::vk::structs::as_bytes(&record).to_vec()
        })
        .collect();
    Allocation::filled(dev, &bytes, 64, usage, 256)
}
