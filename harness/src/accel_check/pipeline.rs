//! The pipeline check, for devices without ray query: a ray tracing pipeline (raygen, miss,
//! closest-hit, and an intersection shader for AABBs: `shaders/check.*`) that writes per ray the
//! `RayRecord` the ray query check writes.

use super::set::CheckSet;
use crate::error::{vkfail, HarnessError};
use crate::plan::check::CheckPlan;
use crate::shaders;
use crate::vk::commands::Commands;
use crate::vk::memory::Allocation;
use crate::vk::VkDevice;
use ash::vk;

/// SPIR-V of the pipeline check's four shaders (raygen, miss, closest-hit, intersection:
/// `shaders/check.*`).
pub(super) fn pipeline_shaders() -> Result<[Vec<u32>; 4], HarnessError> {
    use super::check_spirv as c;
    Ok([
        c(
            "check_raygen",
            "check.rgen",
            include_str!("../../shaders/check.rgen"),
        )?,
        c(
            "check_miss",
            "check.rmiss",
            include_str!("../../shaders/check.rmiss"),
        )?,
        c(
            "check_closest_hit",
            "check.rchit",
            include_str!("../../shaders/check.rchit"),
        )?,
        c(
            "check_intersection",
            "check.rint",
            include_str!("../../shaders/check.rint"),
        )?,
    ])
}

fn align_up(v: u64, a: u64) -> u64 {
    v.div_ceil(a.max(1)) * a.max(1)
}

/// Traces the plan's rays with a ray tracing pipeline (for devices without ray query); one `RayRecord`
/// per ray, as the ray query check writes them. Every geometry
/// uses hit record 0 (sbtRecordStride 0): the triangles hit group, or the procedural one for AABB
/// builds.
pub(super) fn trace_pipeline(
    dev: &VkDevice,
    cmds: &Commands,
    scene: vk::AccelerationStructureKHR,
    plan: &CheckPlan,
) -> Result<Vec<u32>, HarnessError> {
    let procedural = plan.procedural;
    if plan.rays.is_empty() {
        return Ok(vec![]);
    }
    let rt = dev.rt.as_ref().ok_or_else(|| {
        HarnessError::NotRealised("the pipeline check needs VK_KHR_ray_tracing_pipeline".into())
    })?;
    let code = pipeline_shaders()?;
    let d = &dev.device;
    let stages = vk::ShaderStageFlags::RAYGEN_KHR | vk::ShaderStageFlags::INTERSECTION_KHR;
    let check = CheckSet::new(dev, scene, plan, stages)?;
    let l = dev.limits;
    let handle = l.handle_size as u64;
    let record = align_up(handle, l.handle_alignment as u64);
    let region = align_up(record, l.base_alignment as u64);
    let mut pl = vk::PipelineLayout::null();
    let mut modules = Vec::new();
    let mut pipe = vk::Pipeline::null();
    let mut sbt: Option<Allocation> = None;
    // SAFETY: valid create infos; everything made here is destroyed below after the wait.
    let out = unsafe {
        (|| -> Result<Vec<u32>, HarnessError> {
            pl = check.pipeline_layout(dev)?;
            let kinds = [
                vk::ShaderStageFlags::RAYGEN_KHR,
                vk::ShaderStageFlags::MISS_KHR,
                vk::ShaderStageFlags::CLOSEST_HIT_KHR,
                vk::ShaderStageFlags::INTERSECTION_KHR,
            ];
            for c in &code {
                modules.push(shaders::module(dev, c)?);
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
            let group = |ty, general, closest, intersection| {
                vk::RayTracingShaderGroupCreateInfoKHR::default()
                    .ty(ty)
                    .general_shader(general)
                    .closest_hit_shader(closest)
                    .any_hit_shader(unused)
                    .intersection_shader(intersection)
            };
            use vk::RayTracingShaderGroupTypeKHR as G;
            let groups = [
                group(G::GENERAL, 0, unused, unused),
                group(G::GENERAL, 1, unused, unused),
                group(G::TRIANGLES_HIT_GROUP, unused, 2, unused),
                group(G::PROCEDURAL_HIT_GROUP, unused, 2, 3),
            ];
            let ci = vk::RayTracingPipelineCreateInfoKHR::default()
                .stages(&st)
                .groups(&groups)
                .max_pipeline_ray_recursion_depth(1)
                .layout(pl);
            pipe = rt
                .create_ray_tracing_pipelines(
                    vk::DeferredOperationKHR::null(),
                    vk::PipelineCache::null(),
                    &[ci],
                    None,
                )
                .map_err(|(_, r)| vkfail("vkCreateRayTracingPipelinesKHR")(r))?[0];
            let handles = rt
                .get_ray_tracing_shader_group_handles(pipe, 0, 4, 4 * handle as usize)
                .map_err(vkfail("vkGetRayTracingShaderGroupHandlesKHR"))?;
            let h = |g: usize| &handles[g * handle as usize..(g + 1) * handle as usize];
            let table = sbt.insert(Allocation::new(
                dev,
                3 * region,
                vk::BufferUsageFlags::SHADER_BINDING_TABLE_KHR
                    | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS,
                vk::BufferCreateFlags::empty(),
                l.base_alignment.max(1) as u64,
            )?);
            table.write(0, h(0));
            table.write(region, h(1));
            table.write(2 * region, h(if procedural { 3 } else { 2 }));
            let at = |k: u64| vk::StridedDeviceAddressRegionKHR {
                device_address: table.address + k * region,
                stride: record,
                size: record,
            };
            let (rgen, miss, hit) = (at(0), at(1), at(2));
            let call = vk::StridedDeviceAddressRegionKHR::default();
            cmds.begin(dev)?;
            d.cmd_bind_pipeline(cmds.cb, vk::PipelineBindPoint::RAY_TRACING_KHR, pipe);
            d.cmd_bind_descriptor_sets(
                cmds.cb,
                vk::PipelineBindPoint::RAY_TRACING_KHR,
                pl,
                0,
                &[check.set],
                &[],
            );
            rt.cmd_trace_rays(
                cmds.cb,
                &rgen,
                &miss,
                &hit,
                &call,
                plan.rays.len() as u32,
                1,
                1,
            );
            cmds.submit(dev)?;
            Ok(check.records())
        })()
    };
    // SAFETY: the submission was waited for (or never made); null handles are ignored.
    unsafe {
        d.destroy_pipeline(pipe, None);
        for m in modules {
            d.destroy_shader_module(m, None);
        }
        d.destroy_pipeline_layout(pl, None);
    }
    if let Some(t) = sbt {
        t.destroy(dev);
    }
    check.destroy(dev);
    out
}
