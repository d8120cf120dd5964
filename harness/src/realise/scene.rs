//! The scene the rays see, built from the case's scene plan (`crate::plan::scene::ScenePlan`, the
//! bytes the C export embeds too): one bottom-level structure per built bottom level (triangles from
//! f32 positions with optional u16/u32 indices and 3x4 geometry transform, or AABBs; the plan's
//! geometry flags), a top-level structure over the plan's instance records (an inactive instance
//! references 0), as KHR or NV acceleration structures, and the spheres buffer the intersection
//! shader reads. Built once per content (a hash of the scene) and kept for the next cases on the
//! device; for a case that is only recorded, only its top level is made, and not built.

use super::DeviceCache;
use crate::error::{vkfail, HarnessError};
use crate::plan::scene::{GeometryDataPlan, InstancePlan, ScenePlan, AABB_STRIDE, VERTEX_STRIDE};
use crate::vk::commands::{begin_one_time, memory_barrier};
use crate::vk::memory::Allocation;
use crate::vk::VkDevice;
use ash::vk;
use model::scene::SceneInstance;
use model::world::PipelineApi;

/// The top-level structure of a built scene, of the extension the case's pipeline uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Tlas {
    Khr(vk::AccelerationStructureKHR),
    Nv(vk::AccelerationStructureNV),
}

/// A built scene: BLASes, TLAS and their buffers (and, for NV structures, their memory), and the
/// spheres buffer of its boxes.
pub(crate) struct Scene {
    pub(crate) tlas: Tlas,
    pub(crate) spheres: vk::Buffer,
    structures: Vec<vk::AccelerationStructureKHR>,
    nv_structures: Vec<vk::AccelerationStructureNV>,
    nv_memory: Vec<vk::DeviceMemory>,
    buffers: Vec<Allocation>,
}

/// How many built scenes a device keeps (the oldest goes first).
const KEPT_SCENES: usize = 8;

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
    let scratch_usage =
        vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS;
    let (structure, storage) = structure_on_storage(dev, accel, ty, &sizes, storage_min)?;
    let scratch = Allocation::new(
        dev,
        sizes.build_scratch_size.max(1),
        scratch_usage,
        vk::BufferCreateFlags::empty(),
        scratch_align,
    )?;
    Ok((structure, storage, scratch))
}

/// A structure of `ty` created on a storage buffer of its size (at least `storage_min` bytes).
fn structure_on_storage(
    dev: &VkDevice,
    accel: &ash::khr::acceleration_structure::Device,
    ty: vk::AccelerationStructureTypeKHR,
    sizes: &vk::AccelerationStructureBuildSizesInfoKHR,
    storage_min: u64,
) -> Result<(vk::AccelerationStructureKHR, Allocation), HarnessError> {
    let storage_usage = vk::BufferUsageFlags::ACCELERATION_STRUCTURE_STORAGE_KHR
        | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS;
    let storage = Allocation::new(
        dev,
        sizes.acceleration_structure_size.max(storage_min),
        storage_usage,
        vk::BufferCreateFlags::empty(),
        256,
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
    .map_err(vkfail("vkCreateAccelerationStructureKHR"));
    match structure {
        Ok(s) => Ok((s, storage)),
        Err(e) => {
            storage.destroy(dev);
            Err(e)
        }
    }
}

impl DeviceCache {
    /// The scene of a case's scene plan (cached by the content of `scene`, the model's scene the
    /// plan was made from): its top level and spheres buffer. With `build` false — a case that is
    /// only recorded, never submitted — only the top level (sized for the instances, on its own
    /// memory) and the spheres buffer are made, and nothing is built: no ray will read the
    /// structure, and what the layer checks of a bound structure at record time is its handle and
    /// memory, not its content. A built scene of the same content serves such a case too; an unbuilt
    /// one never serves a case that builds.
    pub(crate) fn scene(
        &mut self,
        scene: &model::scene::Scene,
        plan: &ScenePlan,
        build: bool,
    ) -> Result<(Tlas, vk::Buffer), HarnessError> {
        let built_key = format!("{:?}|{:016x}", plan.api, model::semantics::scene_key(scene));
        let key = if build || self.scenes.contains_key(&built_key) {
            built_key
        } else {
            format!("{built_key}|unbuilt")
        };
        if !self.scenes.contains_key(&key) {
            // Every earlier case waited for its submission: no kept scene is in use.
            while self.scene_order.len() >= KEPT_SCENES {
                let old = self.scene_order.remove(0);
                if let Some(Ok(s)) = self.scenes.remove(&old) {
                    self.destroy_scene(s);
                }
            }
            let built = self.build_scene(plan, build);
            self.scenes.insert(key.clone(), built);
            self.scene_order.push(key.clone());
        }
        match &self.scenes[&key] {
            Ok(s) => Ok((s.tlas, s.spheres)),
            Err(e) => Err(e.clone()),
        }
    }

    fn build_scene(&mut self, scene: &ScenePlan, build: bool) -> Result<Scene, HarnessError> {
        let mut built = Scene {
            tlas: Tlas::Khr(vk::AccelerationStructureKHR::null()),
            spheres: vk::Buffer::null(),
            structures: Vec::new(),
            nv_structures: Vec::new(),
            nv_memory: Vec::new(),
            buffers: Vec::new(),
        };
        let result = self.build_scene_into(scene, &mut built, build);
        match result {
            Ok(()) => Ok(built),
            Err(e) => {
                self.destroy_scene(built);
                Err(e)
            }
        }
    }

    fn build_scene_into(
        &mut self,
        scene: &ScenePlan,
        built: &mut Scene,
        build: bool,
    ) -> Result<(), HarnessError> {
        let bytes = scene.sphere_bytes();
        // Every allocation on a device with bufferDeviceAddress is asked for its address, which needs
        // SHADER_DEVICE_ADDRESS usage (VUID-VkBufferDeviceAddressInfo-buffer-02601).
        let spheres = Allocation::filled(
            &self.dev,
            &bytes,
            16,
            vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS,
            256,
        )?;
        built.spheres = spheres.buffer;
        built.buffers.push(spheres);
        if scene.api == PipelineApi::Nv {
            let Some(nv) = self.dev.nv.clone() else {
                return Err(HarnessError::NotRealised(
                    "the case traces rays but does not enable VK_NV_ray_tracing".into(),
                ));
            };
            return self.build_nv_scene_into(&nv, scene, built, build);
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
        self.build_khr_scene_into(&accel, scene, built, build)
    }

    fn build_khr_scene_into(
        &mut self,
        accel: &ash::khr::acceleration_structure::Device,
        scene: &ScenePlan,
        built: &mut Scene,
        build: bool,
    ) -> Result<(), HarnessError> {
        let dev = &self.dev;
        let input_usage = vk::BufferUsageFlags::ACCELERATION_STRUCTURE_BUILD_INPUT_READ_ONLY_KHR
            | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS;
        let scratch_align = (dev.limits.scratch_alignment as u64).max(256);
        if !build {
            // What the trace command sees of the scene is its top level (the descriptor): only that
            // is made, sized for the instances; no bottom level, input or scratch for builds that
            // will not be recorded.
            let geometry = [vk::AccelerationStructureGeometryKHR::default()
                .geometry_type(vk::GeometryTypeKHR::INSTANCES)
                .geometry(vk::AccelerationStructureGeometryDataKHR {
                    instances: vk::AccelerationStructureGeometryInstancesDataKHR::default(),
                })];
            let info = vk::AccelerationStructureBuildGeometryInfoKHR::default()
                .ty(vk::AccelerationStructureTypeKHR::TOP_LEVEL)
                .mode(vk::BuildAccelerationStructureModeKHR::BUILD)
                .geometries(&geometry);
            let mut sizes = vk::AccelerationStructureBuildSizesInfoKHR::default();
            // SAFETY: a valid instances geometry (its address is ignored here) and one count.
            unsafe {
                accel.get_acceleration_structure_build_sizes(
                    vk::AccelerationStructureBuildTypeKHR::DEVICE,
                    &info,
                    &[scene.instances.len() as u32],
                    &mut sizes,
                )
            };
            let (tlas, storage) = structure_on_storage(
                dev,
                accel,
                vk::AccelerationStructureTypeKHR::TOP_LEVEL,
                &sizes,
                0,
            )?;
            built.structures.push(tlas);
            built.tlas = Tlas::Khr(tlas);
            built.buffers.push(storage);
            return Ok(());
        }
        let none = vk::BufferCreateFlags::empty();
        let input = &scene.input;
        let inputs = Allocation::new(dev, input.len() as u64, input_usage, none, 256)?;
        inputs.write(0, input);
        let base = inputs.address;
        built.buffers.push(inputs);
        let address = |offset: u64| vk::DeviceOrHostAddressConstKHR {
            device_address: base + offset,
        };

        let mut blas_addresses = Vec::new();
        let mut builds: Vec<(
            Vec<vk::AccelerationStructureGeometryKHR>,
            Vec<vk::AccelerationStructureBuildRangeInfoKHR>,
            vk::AccelerationStructureKHR,
            u64,
        )> = Vec::new();
        for bl in &scene.bottoms {
            if !bl.built() {
                blas_addresses.push(0);
                continue;
            }
            let mut geoms = Vec::new();
            let mut ranges = Vec::new();
            for geometry in &bl.geometries {
                let none_address = vk::DeviceOrHostAddressConstKHR { device_address: 0 };
                let (ty, data) = match geometry.data {
                    GeometryDataPlan::Triangles {
                        vertices,
                        vertex_count,
                        indices,
                        transform,
                    } => {
                        let (index_type, index_data) = match indices {
                            Some((o, _, 16)) => (vk::IndexType::UINT16, address(o)),
                            Some((o, _, _)) => (vk::IndexType::UINT32, address(o)),
                            None => (vk::IndexType::NONE_KHR, none_address),
                        };
                        (
                            vk::GeometryTypeKHR::TRIANGLES,
                            vk::AccelerationStructureGeometryDataKHR {
                                triangles:
                                    vk::AccelerationStructureGeometryTrianglesDataKHR::default()
                                        .vertex_format(vk::Format::R32G32B32_SFLOAT)
                                        .vertex_data(address(vertices))
                                        .vertex_stride(VERTEX_STRIDE)
                                        .max_vertex(vertex_count.saturating_sub(1))
                                        .index_type(index_type)
                                        .index_data(index_data)
                                        .transform_data(transform.map_or(none_address, address)),
                            },
                        )
                    }
                    GeometryDataPlan::Aabbs { boxes, .. } => (
                        vk::GeometryTypeKHR::AABBS,
                        vk::AccelerationStructureGeometryDataKHR {
                            aabbs: vk::AccelerationStructureGeometryAabbsDataKHR::default()
                                .data(address(boxes))
                                .stride(AABB_STRIDE),
                        },
                    ),
                };
                let count = geometry.primitive_count;
                geoms.push(
                    vk::AccelerationStructureGeometryKHR::default()
                        .geometry_type(ty)
                        .geometry(data)
                        .flags(vk::GeometryFlagsKHR::from_raw(geometry.flags)),
                );
                ranges.push(
                    vk::AccelerationStructureBuildRangeInfoKHR::default().primitive_count(count),
                );
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
            built.structures.push(blas);
            // SAFETY: valid structure.
            let addr = unsafe {
                accel.get_acceleration_structure_device_address(
                    &vk::AccelerationStructureDeviceAddressInfoKHR::default()
                        .acceleration_structure(blas),
                )
            };
            blas_addresses.push(addr);
            builds.push((geoms, ranges, blas, scratch.address));
            built.buffers.push(storage);
            built.buffers.push(scratch);
        }
        let records = scene.instance_bytes(&|b| blas_addresses.get(b).copied().unwrap_or(0));
        let inst_buf = Allocation::filled(dev, &records, 64, input_usage, 256)?;
        let tlas_geom = [vk::AccelerationStructureGeometryKHR::default()
            .geometry_type(vk::GeometryTypeKHR::INSTANCES)
            .geometry(vk::AccelerationStructureGeometryDataKHR {
                instances: vk::AccelerationStructureGeometryInstancesDataKHR::default().data(
                    vk::DeviceOrHostAddressConstKHR {
                        device_address: inst_buf.address,
                    },
                ),
            })];
        built.buffers.push(inst_buf);
        let tlas_count = [scene.instances.len() as u32];
        let (tlas, storage, scratch) = sized_structure(
            dev,
            accel,
            vk::AccelerationStructureTypeKHR::TOP_LEVEL,
            &tlas_geom,
            &tlas_count,
            scratch_align,
            0,
        )?;
        built.structures.push(tlas);
        built.tlas = Tlas::Khr(tlas);
        let tlas_scratch = scratch.address;
        built.buffers.push(storage);
        built.buffers.push(scratch);

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
                .primitive_count(scene.instances.len() as u32)];
            accel.cmd_build_acceleration_structures(cb, &[info], &[&range]);
            d.end_command_buffer(cb)
                .map_err(vkfail("vkEndCommandBuffer"))?;
        }
        self.submit_and_wait(std::time::Duration::from_secs(60))
    }

    /// The scene as VK_NV_ray_tracing structures: one bottom-level `VkAccelerationStructureNV` per
    /// bottom level (its geometries as `VkGeometryNV`, buffer + offset based, with index and transform
    /// data where the scene has them), a top-level one over `VkAccelerationStructureInstanceNV` records
    /// (the KHR layout), each bound to its own memory, built with `vkCmdBuildAccelerationStructureNV`
    /// (barrier between the levels), submitted and waited for.
    fn build_nv_scene_into(
        &mut self,
        nv: &ash::nv::ray_tracing::Device,
        scene: &ScenePlan,
        built: &mut Scene,
        build: bool,
    ) -> Result<(), HarnessError> {
        let dev = &self.dev;
        let usage = vk::BufferUsageFlags::RAY_TRACING_NV;
        let none = vk::BufferCreateFlags::empty();

        // Creates a structure for `info`, binds it to fresh memory and, where it will be built, makes
        // a scratch buffer for its build.
        let make = |info: vk::AccelerationStructureInfoNV,
                    built: &mut Scene|
         -> Result<(vk::AccelerationStructureNV, vk::Buffer), HarnessError> {
            // SAFETY: valid description whose geometry pointers outlive the call.
            let s = unsafe {
                nv.create_acceleration_structure(
                    &vk::AccelerationStructureCreateInfoNV::default().info(info),
                    None,
                )
            }
            .map_err(vkfail("vkCreateAccelerationStructureNV"))?;
            built.nv_structures.push(s);
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
            built.nv_memory.push(memory);
            let bind = [vk::BindAccelerationStructureMemoryInfoNV::default()
                .acceleration_structure(s)
                .memory(memory)];
            // SAFETY: fresh memory of the required type and size.
            unsafe { nv.bind_acceleration_structure_memory(&bind) }
                .map_err(vkfail("vkBindAccelerationStructureMemoryNV"))?;
            if !build {
                return Ok((s, vk::Buffer::null()));
            }
            let scratch_buf = Allocation::new(
                dev,
                scratch.size.max(1),
                usage,
                none,
                scratch.alignment.max(256),
            )?;
            let b = scratch_buf.buffer;
            built.buffers.push(scratch_buf);
            Ok((s, b))
        };
        if !build {
            // What the trace command sees of the scene is its top level (the descriptor): only that
            // is made, sized for the instances; no bottom level, input or scratch for builds that
            // will not be recorded.
            let info = vk::AccelerationStructureInfoNV::default()
                .ty(vk::AccelerationStructureTypeNV::TOP_LEVEL)
                .instance_count(scene.instances.len() as u32);
            built.tlas = Tlas::Nv(make(info, built)?.0);
            return Ok(());
        }
        let input = &scene.input;
        let inputs = Allocation::new(dev, input.len() as u64, usage, none, 256)?;
        inputs.write(0, input);
        let input_buffer = inputs.buffer;
        built.buffers.push(inputs);

        let mut handles = Vec::new();
        let mut blas_builds: Vec<(Vec<vk::GeometryNV>, vk::AccelerationStructureNV, vk::Buffer)> =
            Vec::new();
        for bl in &scene.bottoms {
            if !bl.built() {
                handles.push(0u64);
                continue;
            }
            let geoms: Vec<vk::GeometryNV> = bl
                .geometries
                .iter()
                .map(|geometry| {
                    let mut data = vk::GeometryDataNV::default();
                    let ty = match geometry.data {
                        GeometryDataPlan::Triangles {
                            vertices,
                            vertex_count,
                            indices,
                            transform,
                        } => {
                            let mut tri = vk::GeometryTrianglesNV::default()
                                .vertex_data(input_buffer)
                                .vertex_offset(vertices)
                                .vertex_count(vertex_count)
                                .vertex_stride(VERTEX_STRIDE)
                                .vertex_format(vk::Format::R32G32B32_SFLOAT)
                                .index_type(vk::IndexType::NONE_NV);
                            if let Some((o, count, bits)) = indices {
                                tri = tri
                                    .index_data(input_buffer)
                                    .index_offset(o)
                                    .index_count(count)
                                    .index_type(if bits == 16 {
                                        vk::IndexType::UINT16
                                    } else {
                                        vk::IndexType::UINT32
                                    });
                            }
                            if let Some(o) = transform {
                                tri = tri.transform_data(input_buffer).transform_offset(o);
                            }
                            data.triangles = tri;
                            vk::GeometryTypeNV::TRIANGLES
                        }
                        GeometryDataPlan::Aabbs { boxes, count } => {
                            data.aabbs = vk::GeometryAABBNV::default()
                                .aabb_data(input_buffer)
                                .num_aab_bs(count)
                                .stride(AABB_STRIDE as u32)
                                .offset(boxes);
                            vk::GeometryTypeNV::AABBS
                        }
                    };
                    vk::GeometryNV::default()
                        .geometry_type(ty)
                        .geometry(data)
                        .flags(vk::GeometryFlagsKHR::from_raw(geometry.flags))
                })
                .collect();
            let info = vk::AccelerationStructureInfoNV::default()
                .ty(vk::AccelerationStructureTypeNV::BOTTOM_LEVEL)
                .geometries(&geoms);
            let (blas, scratch) = make(info, built)?;
            // SAFETY: the structure is bound to memory.
            let handle = unsafe { nv.get_acceleration_structure_handle(blas) }
                .map_err(vkfail("vkGetAccelerationStructureHandleNV"))?;
            handles.push(handle);
            blas_builds.push((geoms, blas, scratch));
        }
        let records = scene.instance_bytes(&|b| handles.get(b).copied().unwrap_or(0));
        let inst_buf = Allocation::filled(dev, &records, 64, usage, 256)?;
        let inst_buffer = inst_buf.buffer;
        built.buffers.push(inst_buf);
        let tlas_info = vk::AccelerationStructureInfoNV::default()
            .ty(vk::AccelerationStructureTypeNV::TOP_LEVEL)
            .instance_count(scene.instances.len() as u32);
        let (tlas, tlas_scratch) = make(tlas_info, built)?;
        built.tlas = Tlas::Nv(tlas);

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

/// The instance records of `instances` in a buffer of `usage`, referencing `references[i]` (a KHR
/// device address or an NV handle; 0 for an inactive instance), written as the scene plan writes them.
pub(crate) fn instance_buffer(
    dev: &VkDevice,
    instances: &[SceneInstance],
    references: &[u64],
    usage: vk::BufferUsageFlags,
) -> Result<Allocation, HarnessError> {
    let bytes: Vec<u8> = instances
        .iter()
        .zip(references)
        .flat_map(|(inst, reference)| {
            crate::plan::scene::instance_record(&InstancePlan::of(inst, None), *reference)
        })
        .collect();
    Allocation::filled(dev, &bytes, 64, usage, 256)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::vk::lavapipe_device;
    use model::scene::{build, Scene};

    /// A scene made for a case that is only recorded is never handed to a case that builds: the
    /// latter gets a structure of its own, which then serves the recorded cases too (lavapipe).
    #[test]
    fn an_unbuilt_scene_serves_only_recorded_cases() {
        // Vulkan called directly, as the executor does, in the process's turn.
        let _turn = crate::vk::turn::take();
        let dev = lavapipe_device(
            &[
                "VK_KHR_acceleration_structure",
                "VK_KHR_buffer_device_address",
                "VK_KHR_deferred_host_operations",
            ],
            &["accelerationStructure", "bufferDeviceAddress"],
        );
        let mut cache = DeviceCache::new(dev).expect("a device cache");
        let scene = Scene {
            bottom_levels: vec![build::icosphere(0, 1.0)],
            instances: vec![SceneInstance::of(0)],
        };
        let plan = ScenePlan::of(&scene, PipelineApi::Khr);
        let (recorded, _) = cache.scene(&scene, &plan, false).expect("made");
        assert_eq!(
            cache.scene(&scene, &plan, false).expect("kept").0,
            recorded,
            "kept for the next recorded case"
        );
        let (submitted, _) = cache.scene(&scene, &plan, true).expect("built");
        assert_ne!(submitted, recorded, "a case that builds gets its own");
        assert_eq!(cache.scene(&scene, &plan, true).expect("kept").0, submitted);
        assert_eq!(
            cache.scene(&scene, &plan, false).expect("kept").0,
            submitted,
            "the built one serves recorded cases once it exists"
        );
    }
}
