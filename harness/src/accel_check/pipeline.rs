//! The pipeline check, for devices without ray query: a ray tracing pipeline (raygen, miss,
//! closest-hit, and an intersection shader for AABBs) that reports per ray what the ray query check
//! reports.

use super::write_check_set;
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
/// `[hit, instance, geometry, primitive]` per ray, as [`trace`] reports them. Every geometry uses hit
/// record 0 (sbtRecordStride 0): the triangles hit group, or the procedural one for AABB builds.
pub(super) fn trace_pipeline(
    dev: &VkDevice,
    cmds: &Commands,
    scene: vk::AccelerationStructureKHR,
    rays: &[ExpectedRay],
    boxes: &[u8],
    procedural: bool,
    keep: &mut Vec<Allocation>,
) -> Result<Vec<[u32; 4]>, HarnessError> {
    if rays.is_empty() {
        return Ok(vec![]);
    }
    let rt = dev.rt.as_ref().ok_or_else(|| {
        HarnessError::Unsupported("the pipeline check needs VK_KHR_ray_tracing_pipeline".into())
    })?;
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
    )?;
    rb.write(0, &origins);
    keep.push(rb);
    let hb = Allocation::new(
        dev,
        16 * rays.len() as u64,
        sb,
        vk::BufferCreateFlags::empty(),
        1,
    )?;
    keep.push(hb);
    let bb = Allocation::new(
        dev,
        boxes.len() as u64,
        sb,
        vk::BufferCreateFlags::empty(),
        1,
    )?;
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
            .map_err(vkfail("vkCreateDescriptorSetLayout"))?;
        let sets = [dsl];
        let pl = d.create_pipeline_layout(
            &vk::PipelineLayoutCreateInfo::default().set_layouts(&sets),
            None,
        );
        let mut modules = Vec::new();
        let made = (|| -> Result<Vec<[u32; 4]>, HarnessError> {
            let pl = pl.map_err(vkfail("vkCreatePipelineLayout"))?;
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
                .map_err(|(_, r)| vkfail("vkCreateRayTracingPipelinesKHR")(r))?[0];
            let inner = (|| -> Result<Vec<[u32; 4]>, HarnessError> {
                let handles = rt
                    .get_ray_tracing_shader_group_handles(pipe, 0, 4, 4 * handle as usize)
                    .map_err(vkfail("vkGetRayTracingShaderGroupHandlesKHR"))?;
                let h = |g: usize| &handles[g * handle as usize..(g + 1) * handle as usize];
                let sbt = Allocation::new(
                    dev,
                    3 * region,
                    vk::BufferUsageFlags::SHADER_BINDING_TABLE_KHR
                        | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS,
                    vk::BufferCreateFlags::empty(),
                    l.base_alignment.max(1) as u64,
                )?;
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
                    .map_err(vkfail("vkCreateDescriptorPool"))?;
                let run = (|| -> Result<(), HarnessError> {
                    let set = d
                        .allocate_descriptor_sets(
                            &vk::DescriptorSetAllocateInfo::default()
                                .descriptor_pool(pool)
                                .set_layouts(&sets),
                        )
                        .map_err(vkfail("vkAllocateDescriptorSets"))?[0];
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
