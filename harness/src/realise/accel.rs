//! A build case's world on the device, from its plan ([`BuildPlan`]): its buffers at 4096-aligned
//! addresses with the model's memory image written through the device's addresses (sparse buffers
//! bound with `vkQueueBindSparse`), its acceleration structures at their buffer ranges, the Vulkan form
//! of its build infos, and the sizes the device reports for them.

use crate::error::{vkfail, HarnessError};
use crate::observe::TraceCheck;
use crate::plan::build::{
    vk_format, vk_index, vk_type, BuildInfoPlan, BuildPlan, GeometryDataPlan,
};
use crate::vk::memory::Allocation;
use crate::vk::{VkDevice, VkInstance};
use ash::vk;
use model::accel::call::{IndexType, VertexFormat};
use model::accel::world::AddressResolver;
use model::accel::{AsType, BuildSizes};
use model::call::BUFFER_PLACEMENT_ALIGNMENT;
use model::AccelBody;
use std::collections::BTreeMap;
use std::sync::Arc;

/// Device objects of one case.
pub(crate) struct Realised {
    pub(crate) buffers: BTreeMap<String, Allocation>,
    /// Non-sparse buffers with no memory bound (a case's `unbound` buffer that no address names).
    pub(crate) bare: BTreeMap<String, vk::Buffer>,
    pub(crate) structures: BTreeMap<String, (vk::AccelerationStructureKHR, u64)>,
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
    pub(crate) fn destroy(self, dev: &VkDevice) {
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

/// What the last build of a structure was, as the Vulkan structures of a direct build that repeats it
/// for the layer's state (type, flags, and per geometry its type, flags, vertex format, maximum vertex,
/// index type, transform and primitive count): geometry data at `data`, an address of one of the
/// case's buffers (the build is recorded, never submitted). None for geometry types not realised.
pub(crate) fn last_build_geometries(
    lb: &model::accel::world::LastBuild,
    data: u64,
) -> Option<(
    Vec<vk::AccelerationStructureGeometryKHR<'static>>,
    Vec<vk::AccelerationStructureBuildRangeInfoKHR>,
)> {
    use model::accel::call::GeometryType;
    let a = vk::DeviceOrHostAddressConstKHR {
        device_address: data,
    };
    let mut geoms = Vec::new();
    let mut ranges = Vec::new();
    for g in &lb.geometries {
        let (ty, d) = match g.geometry_type {
            GeometryType::Triangles => (
                vk::GeometryTypeKHR::TRIANGLES,
                vk::AccelerationStructureGeometryDataKHR {
                    triangles: vk::AccelerationStructureGeometryTrianglesDataKHR::default()
                        .vertex_format(vk_format(
                            g.vertex_format.unwrap_or(VertexFormat::R32g32b32Sfloat),
                        ))
                        .vertex_data(a)
                        .vertex_stride(12)
                        .max_vertex(g.max_vertex)
                        .index_type(vk_index(g.index_type.unwrap_or(IndexType::None)))
                        .index_data(a)
                        .transform_data(vk::DeviceOrHostAddressConstKHR {
                            device_address: if g.has_transform { data } else { 0 },
                        }),
                },
            ),
            GeometryType::Aabbs => (
                vk::GeometryTypeKHR::AABBS,
                vk::AccelerationStructureGeometryDataKHR {
                    aabbs: vk::AccelerationStructureGeometryAabbsDataKHR::default()
                        .data(a)
                        .stride(24),
                },
            ),
            GeometryType::Instances => (
                vk::GeometryTypeKHR::INSTANCES,
                vk::AccelerationStructureGeometryDataKHR {
                    instances: vk::AccelerationStructureGeometryInstancesDataKHR::default().data(a),
                },
            ),
            _ => return None,
        };
        geoms.push(
            vk::AccelerationStructureGeometryKHR::default()
                .geometry_type(ty)
                .geometry(d)
                .flags(vk::GeometryFlagsKHR::from_raw(g.flags.0)),
        );
        ranges.push(vk::AccelerationStructureBuildRangeInfoKHR {
            primitive_count: g.range.primitive_count,
            primitive_offset: g.range.primitive_offset,
            first_vertex: g.range.first_vertex,
            transform_offset: g.range.transform_offset,
        });
    }
    Some((geoms, ranges))
}

/// The Vulkan type of a structure type.
pub(crate) fn vk_as_type(t: AsType) -> vk::AccelerationStructureTypeKHR {
    vk_type(t)
}

/// The Vulkan geometries of an info's plan (None for geometry types the harness does not realise).
pub(crate) fn vk_geometries(
    info: &BuildInfoPlan,
    r: &Realised,
) -> Option<Vec<vk::AccelerationStructureGeometryKHR<'static>>> {
    let a = |x: &model::call::Address| vk::DeviceOrHostAddressConstKHR {
        device_address: r.address(x),
    };
    Some(
        info.geometries
            .as_ref()?
            .iter()
            .map(|g| {
                let data = match &g.data {
                    GeometryDataPlan::Triangles {
                        vertex_format,
                        vertex_data,
                        vertex_stride,
                        max_vertex,
                        index_type,
                        index_data,
                        transform_data,
                    } => vk::AccelerationStructureGeometryDataKHR {
                        triangles: vk::AccelerationStructureGeometryTrianglesDataKHR::default()
                            .vertex_format(vk::Format::from_raw(*vertex_format))
                            .vertex_data(a(vertex_data))
                            .vertex_stride(*vertex_stride)
                            .max_vertex(*max_vertex)
                            .index_type(vk::IndexType::from_raw(*index_type))
                            .index_data(a(index_data))
                            .transform_data(a(transform_data)),
                    },
                    GeometryDataPlan::Aabbs { data, stride } => {
                        vk::AccelerationStructureGeometryDataKHR {
                            aabbs: vk::AccelerationStructureGeometryAabbsDataKHR::default()
                                .data(a(data))
                                .stride(*stride),
                        }
                    }
                    GeometryDataPlan::Instances {
                        array_of_pointers,
                        data,
                    } => vk::AccelerationStructureGeometryDataKHR {
                        instances: vk::AccelerationStructureGeometryInstancesDataKHR::default()
                            .array_of_pointers(*array_of_pointers)
                            .data(a(data)),
                    },
                };
                vk::AccelerationStructureGeometryKHR::default()
                    .geometry_type(vk::GeometryTypeKHR::from_raw(g.ty))
                    .geometry(data)
                    .flags(vk::GeometryFlagsKHR::from_raw(g.flags))
            })
            .collect(),
    )
}

pub(crate) fn vk_info<'a>(
    info: &BuildInfoPlan,
    geoms: &'a [vk::AccelerationStructureGeometryKHR<'static>],
    r: &Realised,
) -> vk::AccelerationStructureBuildGeometryInfoKHR<'a> {
    let handle = |n: &Option<String>| {
        n.as_ref()
            .and_then(|n| r.structures.get(n))
            .map_or(vk::AccelerationStructureKHR::null(), |s| s.0)
    };
    vk::AccelerationStructureBuildGeometryInfoKHR::default()
        .ty(vk::AccelerationStructureTypeKHR::from_raw(info.ty))
        .flags(vk::BuildAccelerationStructureFlagsKHR::from_raw(info.flags))
        .mode(vk::BuildAccelerationStructureModeKHR::from_raw(info.mode))
        .src_acceleration_structure(handle(&info.src))
        .dst_acceleration_structure(handle(&info.dst))
        .geometries(geoms)
        .scratch_data(vk::DeviceOrHostAddressKHR {
            device_address: r.address(&info.scratch),
        })
}

/// A device for build cases: the case's extensions and features plus what the traced check needs
/// (ray query, or a ray tracing pipeline where ray query is absent or the pipeline check is asked for).
pub(crate) fn device_for(
    inst: &Arc<VkInstance>,
    case: &AccelBody,
    check: TraceCheck,
) -> Result<VkDevice, HarnessError> {
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
    VkDevice::new(inst.clone(), &ext, &feat, None)
}

/// Creates the case's buffers and structures and writes the memory image. Memory follows each buffer's
/// binding: wholly bound buffers get one allocation; sparse buffers are bound with `vkQueueBindSparse`
/// (whole: one memory object, scattered: two, unbound: none) waiting on `fence`; a non-sparse unbound
/// buffer is created with no memory where no address of the call lies in it (a structure may be placed
/// on it: VkAccelerationStructureCreateInfoKHR asks nothing of its binding). What Vulkan forbids is
/// `unsupported` with the rule: a non-sparse buffer bound to several memory objects, and the device
/// address of a non-sparse unbound buffer (VUID-VkBufferDeviceAddressInfo-buffer-02600).
pub(crate) fn realise(
    dev: &VkDevice,
    plan: &BuildPlan,
    fence: vk::Fence,
) -> Result<Realised, HarnessError> {
    use model::world::MemoryBinding;
    let accel = dev.accel.as_ref().ok_or_else(|| {
        HarnessError::NotRealised("the case does not enable VK_KHR_acceleration_structure".into())
    })?;
    let mut r = Realised {
        buffers: BTreeMap::new(),
        bare: BTreeMap::new(),
        structures: BTreeMap::new(),
    };
    let made = (|| -> Result<(), HarnessError> {
        for b in &plan.buffers {
            let usage = vk::BufferUsageFlags::from_raw(b.usage);
            let flags = vk::BufferCreateFlags::from_raw(b.flags);
            if b.sparse {
                if !dev.has_feature("sparseBinding") || !dev.sparse_binding {
                    return Err(HarnessError::NotRealised(format!(
                        "buffer `{}` is sparse: creating it needs the sparseBinding feature and \
                         binding it a queue with VK_QUEUE_SPARSE_BINDING_BIT (the case's device has {})",
                        b.name,
                        if dev.has_feature("sparseBinding") {
                            "no such queue"
                        } else {
                            "no sparseBinding"
                        }
                    )));
                }
                let plan = match b.memory {
                    MemoryBinding::Whole => crate::vk::memory::SparsePlan::One,
                    MemoryBinding::Scattered => crate::vk::memory::SparsePlan::Two,
                    MemoryBinding::Unbound => crate::vk::memory::SparsePlan::Unbound,
                };
                let a = Allocation::sparse(dev, fence, b.size, usage, flags, plan)?;
                r.buffers.insert(b.name.clone(), a);
                continue;
            }
            match b.memory {
                MemoryBinding::Whole => {
                    let a = Allocation::new(dev, b.size, usage, flags, BUFFER_PLACEMENT_ALIGNMENT)
                        ?;
                    r.buffers.insert(b.name.clone(), a);
                }
                MemoryBinding::Scattered => {
                    return Err(HarnessError::NotRealised(format!(
                        "buffer `{}` is not sparse, so it cannot be bound to several memory objects \
                         (vkBindBufferMemory binds a non-sparse buffer to one, completely and contiguously); the \
                         one realisable non-contiguous non-sparse buffer is an unbound one, whose device address \
                         is itself invalid to ask for (VUID-VkBufferDeviceAddressInfo-buffer-02600)",
                        b.name
                    )))
                }
                MemoryBinding::Unbound if b.addressed || b.written => {
                    return Err(HarnessError::NotRealised(format!(
                        "buffer `{}` is not sparse and has no memory bound, yet the call reads \
                         it by device address: vkGetBufferDeviceAddress on it is itself invalid \
                         (VUID-VkBufferDeviceAddressInfo-buffer-02600: a non-sparse buffer must be bound \
                         completely and contiguously to a single VkDeviceMemory object)",
                        b.name
                    )))
                }
                MemoryBinding::Unbound => {
                    let info = vk::BufferCreateInfo::default()
                        .size(b.size.max(1))
                        .usage(usage)
                        .flags(flags);
                    // SAFETY: valid create info; destroyed with the case.
                    let buf = unsafe { dev.device.create_buffer(&info, None) }
                        .map_err(vkfail("vkCreateBuffer"))?;
                    r.bare.insert(b.name.clone(), buf);
                }
            }
        }
        for s in &plan.structures {
            let (buffer, bound) = match (r.buffers.get(&s.buffer), r.bare.get(&s.buffer)) {
                (Some(a), _) => (a.buffer, a.memory_count() > 0),
                (None, Some(b)) => (*b, false),
                _ => {
                    return Err(HarnessError::Failed(format!(
                        "structure `{}`: no buffer `{}`",
                        s.name, s.buffer
                    )))
                }
            };
            let info = vk::AccelerationStructureCreateInfoKHR::default()
                .buffer(buffer)
                .offset(s.offset)
                .size(s.size)
                .ty(vk::AccelerationStructureTypeKHR::from_raw(s.ty));
            // SAFETY: the buffer lives as long as the structure.
            let h = unsafe { accel.create_acceleration_structure(&info, None) }
                .map_err(vkfail("vkCreateAccelerationStructureKHR"))?;
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
        for b in &plan.buffers {
            let Some(a) = r.buffers.get(&b.name) else {
                continue;
            };
            if a.memory_count() == 0 {
                if b.written {
                    return Err(HarnessError::NotRealised(format!(
                        "buffer `{}` has no memory bound, so its contents cannot be written",
                        b.name
                    )));
                }
                continue;
            }
            // The buffer is zeroed: only what the contents write is copied.
            for (at, bytes) in b.image_at(&r).runs() {
                a.write(at, bytes);
            }
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
pub(crate) fn device_sizes(
    dev: &VkDevice,
    plan: &BuildPlan,
    r: &Realised,
) -> Option<Vec<BuildSizes>> {
    let accel = dev.accel.as_ref()?;
    plan.infos
        .iter()
        .zip(&plan.max_primitive_counts)
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

/// The Vulkan form of the case's indirect call: infos (with their geometries kept alive), addresses,
/// strides and maxima.
pub(crate) fn indirect_args<'a>(
    plan: &'a BuildPlan,
    r: &Realised,
    geoms: &'a [Vec<vk::AccelerationStructureGeometryKHR<'static>>],
) -> (
    Vec<vk::AccelerationStructureBuildGeometryInfoKHR<'a>>,
    Vec<u64>,
    Vec<&'a [u32]>,
) {
    let infos = plan
        .infos
        .iter()
        .zip(geoms)
        .map(|(i, g)| vk_info(i, g, r))
        .collect();
    let addrs = plan
        .indirect_addresses
        .iter()
        .map(|a| r.address(a))
        .collect();
    let maxima = plan
        .max_primitive_counts
        .iter()
        .map(|v| v.as_slice())
        .collect();
    (infos, addrs, maxima)
}
