//! The pipeline check, for devices without ray query: a ray tracing pipeline (raygen, miss,
//! closest-hit, and an intersection shader for AABBs) that reports per ray what the ray query check
//! reports.

use super::set::CheckSet;
use crate::error::{vkfail, HarnessError};
use crate::shaders;
use crate::vk::commands::Commands;
use crate::vk::memory::Allocation;
use crate::vk::VkDevice;
use ash::vk;
use model::accel::check::ExpectedRay;

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
fn pipeline_shaders() -> Result<[Vec<u32>; 4], HarnessError> {
    let c = |ext, text| shaders::compile_glsl("the pipeline check", ext, text, &[]);
    Ok([
        c("rgen", PIPE_RGEN)?,
        c("rmiss", PIPE_RMISS)?,
        c("rchit", PIPE_RCHIT)?,
        c("rint", PIPE_RINT)?,
    ])
}

fn align_up(v: u64, a: u64) -> u64 {
    v.div_ceil(a.max(1)) * a.max(1)
}

/// Traces the rays with a ray tracing pipeline (for devices without ray query); one
/// `[hit, instance, geometry, primitive]` per ray, as the ray query check reports them. Every geometry
/// uses hit record 0 (sbtRecordStride 0): the triangles hit group, or the procedural one for AABB
/// builds.
pub(super) fn trace_pipeline(
    dev: &VkDevice,
    cmds: &Commands,
    scene: vk::AccelerationStructureKHR,
    rays: &[ExpectedRay],
    boxes: &[u8],
    procedural: bool,
) -> Result<Vec<[u32; 4]>, HarnessError> {
    if rays.is_empty() {
        return Ok(vec![]);
    }
    let rt = dev.rt.as_ref().ok_or_else(|| {
        HarnessError::NotRealised("the pipeline check needs VK_KHR_ray_tracing_pipeline".into())
    })?;
    let code = pipeline_shaders()?;
    let d = &dev.device;
    let stages = vk::ShaderStageFlags::RAYGEN_KHR | vk::ShaderStageFlags::INTERSECTION_KHR;
    let check = CheckSet::new(dev, scene, rays, boxes, stages)?;
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
        (|| -> Result<Vec<[u32; 4]>, HarnessError> {
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
            rt.cmd_trace_rays(cmds.cb, &rgen, &miss, &hit, &call, rays.len() as u32, 1, 1);
            cmds.submit(dev)?;
            Ok(check.hits())
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
