//! The traced check of a build run as valid: the case's first info built directly with the ranges the
//! model reads from memory (a top-level case's BLAS built first), the check's rays (through every built
//! primitive, plus random rays: `model::accel::check`) traced at it, each writing its 28-word
//! `RayRecord` — with ray query in a compute shader ([`ray_query`]), or with a ray tracing pipeline
//! ([`pipeline`]) where the device lacks ray query or when asked — and, where the device has
//! `accelerationStructureIndirectBuild`, the case's own indirect build submitted and traced the same.

mod pipeline;
mod ray_query;
mod set;

use crate::error::HarnessError;
use crate::observe::{error_ids, Hits, IndirectBuild, TraceCheck, TracedBuild};
use crate::plan::build::BuildPlan;
use crate::plan::check::{CheckPlan, BLAS_TRIANGLE, TOP_LEVEL_BLAS};
use crate::realise::accel::{device_for, indirect_args, realise, vk_geometries, vk_info, Realised};
use crate::realise::scene::{instance_buffer, sized_structure};
use crate::vk::commands::{memory_barrier, Commands};
use crate::vk::memory::Allocation;
use crate::vk::{VkDevice, VkInstance};
use ash::vk;
use model::accel::check::hits_of;
use model::accel::AsType;
use model::{AccelBody, Case};
use std::sync::Arc;

/// Builds one structure directly: returns (structure, its address, storage and scratch allocations).
fn build_direct(
    dev: &VkDevice,
    cmds: &Commands,
    ty: vk::AccelerationStructureTypeKHR,
    geoms: &[vk::AccelerationStructureGeometryKHR],
    ranges: &[vk::AccelerationStructureBuildRangeInfoKHR],
) -> Result<(vk::AccelerationStructureKHR, u64, Allocation, Allocation), HarnessError> {
    let accel = accel_of(dev)?;
    let counts: Vec<u32> = ranges.iter().map(|r| r.primitive_count).collect();
    let (s, storage, scratch) = sized_structure(dev, accel, ty, geoms, &counts, 256, 256)?;
    let info = vk::AccelerationStructureBuildGeometryInfoKHR::default()
        .ty(ty)
        .mode(vk::BuildAccelerationStructureModeKHR::BUILD)
        .geometries(geoms);
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
fn resolve_check(dev: &VkDevice, check: TraceCheck) -> Result<TraceCheck, HarnessError> {
    let query = dev.has_feature("rayQuery");
    let pipeline = dev.has_feature("rayTracingPipeline") && dev.rt.is_some();
    match check {
        TraceCheck::RayQuery if query => Ok(TraceCheck::RayQuery),
        TraceCheck::Pipeline if pipeline => Ok(TraceCheck::Pipeline),
        TraceCheck::Auto if query => Ok(TraceCheck::RayQuery),
        TraceCheck::Auto if pipeline => Ok(TraceCheck::Pipeline),
        _ => HarnessError::not_realised(format!(
            "the traced check ({check:?}) needs rayQuery or rayTracingPipeline"
        )),
    }
}

/// The valid case as a direct build with the ranges the model reads, then the check's rays; where
/// the device has accelerationStructureIndirectBuild, the case's indirect build is submitted too and
/// traced with the same rays, and must report what the direct build did.
#[allow(clippy::too_many_arguments)]
pub(crate) fn direct_and_trace(
    inst: &VkInstance,
    dev: &VkDevice,
    cmds: &Commands,
    case: &AccelBody,
    plan: &BuildPlan,
    r: &Realised,
    check: TraceCheck,
) -> Result<TracedBuild, HarnessError> {
    let check = resolve_check(dev, check)?;
    if case.call.infos.len() != 1 {
        return HarnessError::not_realised("the traced check handles one build info");
    }
    let accel = accel_of(dev)?;
    let info = &case.call.infos[0];
    let top = info.ty == AsType::TopLevel;
    let check_plan = CheckPlan::of(case)?;
    let ranges = check_plan.ranges.clone();
    let mut extra: Vec<Allocation> = Vec::new();
    let result =
        (|| -> Result<TracedBuild, HarnessError> {
            // Top-level cases reference the BLAS: build it first (one triangle at the origin).
            if top {
                let tri: Vec<u8> = BLAS_TRIANGLE.iter().flat_map(|f| f.to_le_bytes()).collect();
                let (blas, _) = r.structures.get(TOP_LEVEL_BLAS).copied().ok_or_else(|| {
                    HarnessError::Failed("the top-level case has no `blas` structure".into())
                })?;
                let vb = Allocation::filled(dev, &tri, 64, build_input(), 256)?;
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
                )?;
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
            let (records, direct) = build_and_trace(
                inst,
                dev,
                cmds,
                case,
                plan,
                r,
                &ranges,
                BuildPath::Direct,
                check,
                &check_plan,
            )?;
            let indirect = if dev.has_feature("accelerationStructureIndirectBuild") {
                let (records, layer_vuids) = build_and_trace(
                    inst,
                    dev,
                    cmds,
                    case,
                    plan,
                    r,
                    &ranges,
                    BuildPath::Indirect,
                    check,
                    &check_plan,
                )?;
                Some(IndirectBuild {
                    hits: hits_of(&records),
                    records,
                    layer_vuids,
                })
            } else {
                None
            };
            Ok(TracedBuild {
                check,
                hits: hits_of(&records),
                records,
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
/// result through a one-instance TLAS). Returns the rays' records and the layer's VUIDs for the build.
#[allow(clippy::too_many_arguments)]
fn build_and_trace(
    inst: &VkInstance,
    dev: &VkDevice,
    cmds: &Commands,
    case: &AccelBody,
    plan: &BuildPlan,
    r: &Realised,
    ranges: &[model::accel::RangeInfo],
    path: BuildPath,
    check: TraceCheck,
    check_plan: &CheckPlan,
) -> Result<(Vec<u32>, Vec<String>), HarnessError> {
    let accel = accel_of(dev)?;
    let info = &case.call.infos[0];
    let top = info.ty == AsType::TopLevel;
    let mut extra: Vec<Allocation> = Vec::new();
    let mut extra_as: Vec<vk::AccelerationStructureKHR> = Vec::new();
    let result = (|| -> Result<(Vec<u32>, Vec<String>), HarnessError> {
        let geoms = vk_geometries(&plan.infos[0], r)
            .ok_or_else(|| HarnessError::NotRealised("geometry type not realised".into()))?;
        inst.collector.clear();
        cmds.begin(dev)?;
        match path {
            BuildPath::Direct => {
                let vi = vk_info(&plan.infos[0], &geoms, r);
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
                let (infos, addrs, maxima) = indirect_args(plan, r, &all);
                // The range records are read by the build as indirect data.
                // SAFETY: recording a valid indirect build on a device with accelerationStructureIndirectBuild.
                unsafe {
                    memory_barrier(
                        &dev.device,
                        cmds.cb,
                        (vk::PipelineStageFlags::HOST, vk::AccessFlags::HOST_WRITE),
                        (
                            vk::PipelineStageFlags::DRAW_INDIRECT,
                            vk::AccessFlags::INDIRECT_COMMAND_READ,
                        ),
                    );
                    accel.cmd_build_acceleration_structures_indirect(
                        cmds.cb,
                        &infos,
                        &addrs,
                        &plan.indirect_strides,
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
            .ok_or_else(|| HarnessError::Failed("no dst".into()))?;
        let scene = if top {
            dst
        } else {
            // One instance (full mask, record offset 0, identity transform) of the built structure.
            let one = model::scene::SceneInstance::of(0);
            let ib = instance_buffer(dev, &[one], &[dst_addr], build_input())?;
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
        let words = match check {
            TraceCheck::Pipeline => pipeline::trace_pipeline(dev, cmds, scene, check_plan)?,
            _ => ray_query::trace(dev, cmds, scene, check_plan)?,
        };
        Ok((words, layer))
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

/// What the device built for a case, seen through arbitrary rays: the case's first info built directly
/// with the ranges the model reads from memory, then one ray (+z, t in [0, 100]) from each origin. For
/// writing down what a driver built where no named deviation explains it.
pub(crate) fn probe_rays(
    inst: &Arc<VkInstance>,
    case: &Case,
    origins: &[[f32; 3]],
    check: TraceCheck,
) -> Result<Hits, HarnessError> {
    let case = case
        .as_accel()
        .ok_or_else(|| HarnessError::Failed("probing needs a build case".into()))?;
    let dev = device_for(inst, case, check)?;
    let check = resolve_check(&dev, check)?;
    let plan = BuildPlan::of(case)?;
    let cmds = Commands::new(&dev)?;
    let r = match realise(&dev, &plan, cmds.fence) {
        Ok(r) => r,
        Err(e) => {
            cmds.destroy(&dev);
            return Err(e);
        }
    };
    let out = (|| -> Result<Hits, HarnessError> {
        let info = case
            .call
            .infos
            .first()
            .ok_or_else(|| HarnessError::Failed("no build info".into()))?;
        if info.ty != AsType::BottomLevel {
            return HarnessError::not_realised("probing handles bottom-level builds");
        }
        let probe = CheckPlan::probe(case, origins)?;
        let (records, _) = build_and_trace(
            inst,
            &dev,
            &cmds,
            case,
            &plan,
            &r,
            &probe.ranges,
            BuildPath::Direct,
            check,
            &probe,
        )?;
        Ok(hits_of(&records))
    })();
    cmds.destroy(&dev);
    r.destroy(&dev);
    out
}

/// The usage of the check's build inputs (the BLAS's triangle, the TLAS's instance).
fn build_input() -> vk::BufferUsageFlags {
    vk::BufferUsageFlags::ACCELERATION_STRUCTURE_BUILD_INPUT_READ_ONLY_KHR
        | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS
}

/// The acceleration structure functions of the check's device (its device always enables them).
fn accel_of(dev: &VkDevice) -> Result<&ash::khr::acceleration_structure::Device, HarnessError> {
    dev.accel
        .as_ref()
        .ok_or_else(|| HarnessError::Failed("no acceleration structure extension".into()))
}

/// The SPIR-V of the ray query check's compute shader.
pub(crate) fn ray_query_spirv() -> Result<Vec<u32>, HarnessError> {
    ray_query::compile_trace_shader()
}

/// The SPIR-V of the pipeline check's raygen, miss, closest-hit and intersection shaders.
pub(crate) fn pipeline_spirv() -> Result<[Vec<u32>; 4], HarnessError> {
    pipeline::pipeline_shaders()
}

/// The SPIR-V of one of the check's shaders: compiled by build.rs from `shaders/` (`name` in its
/// table), or at first use from `text` where the build had no glslangValidator.
fn check_spirv(name: &str, file: &str, text: &str) -> Result<Vec<u32>, HarnessError> {
    match crate::shaders::PRECOMPILED
        .iter()
        .find(|(n, _)| *n == name)
        .and_then(|(_, b)| *b)
    {
        Some(b) if b.len() % 4 == 0 && b.len() >= 20 => Ok(b
            .chunks_exact(4)
            .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect()),
        Some(b) => Err(HarnessError::Shader(format!(
            "{name}: not SPIR-V ({} bytes)",
            b.len()
        ))),
        None => {
            let ext = file.rsplit('.').next().unwrap_or(file);
            crate::shaders::compile_glsl(file, ext, text, &[])
        }
    }
}
