//! The ray query check: a compute shader that traces each ray with `rayQueryEXT` and writes
//! `[hit, instance, geometry, primitive]`, generating AABB hits where the box table says.

use super::write_check_set;
use crate::error::{vkfail, HarnessError};
use crate::shaders;
use crate::vk::commands::Commands;
use crate::vk::memory::Allocation;
use crate::vk::VkDevice;
use ash::vk;
use model::accel::check::ExpectedRay;

const TRACE_COMP: &str = r#"#version 460
#extension GL_EXT_ray_query : require
layout(local_size_x = 1) in;
layout(set = 0, binding = 0) uniform accelerationStructureEXT scene;
layout(set = 0, binding = 1, std430) readonly buffer Rays { vec4 origins[]; };
layout(set = 0, binding = 2, std430) buffer Hits { uvec4 hits[]; };
layout(set = 0, binding = 3, std430) readonly buffer Boxes { uint base[8]; vec4 box[]; };
void main() {
    uint i = gl_GlobalInvocationID.x;
    vec3 o = origins[i].xyz;
    rayQueryEXT q;
    rayQueryInitializeEXT(q, scene, gl_RayFlagsNoneEXT, 0xFF, o, 0.0, vec3(0.0, 0.0, 1.0), 100.0);
    while (rayQueryProceedEXT(q)) {
        if (rayQueryGetIntersectionTypeEXT(q, false) == gl_RayQueryCandidateIntersectionAABBEXT) {
            uint g = rayQueryGetIntersectionGeometryIndexEXT(q, false);
            uint p = rayQueryGetIntersectionPrimitiveIndexEXT(q, false);
            vec4 lo = box[2u * (base[g] + p)];
            vec4 hi = box[2u * (base[g] + p) + 1u];
            if (o.x >= lo.x && o.x <= hi.x && o.y >= lo.y && o.y <= hi.y) {
                rayQueryGenerateIntersectionEXT(q, max(lo.z - o.z, 0.0));
            }
        } else {
            rayQueryConfirmIntersectionEXT(q);
        }
    }
    if (rayQueryGetIntersectionTypeEXT(q, true) == gl_RayQueryCommittedIntersectionNoneEXT) {
        hits[i] = uvec4(0u, 0u, 0u, 0u);
    } else {
        hits[i] = uvec4(1u, uint(rayQueryGetIntersectionInstanceIdEXT(q, true)),
                        uint(rayQueryGetIntersectionGeometryIndexEXT(q, true)),
                        uint(rayQueryGetIntersectionPrimitiveIndexEXT(q, true)));
    }
}
"#;

fn compile_trace_shader() -> Result<Vec<u32>, HarnessError> {
    shaders::compile_glsl("the ray query check", "comp", TRACE_COMP, &[])
}

/// Traces the rays with the ray query shader; one `[hit, instance, geometry, primitive]` per ray.
pub(super) fn trace(
    dev: &VkDevice,
    cmds: &Commands,
    scene: vk::AccelerationStructureKHR,
    rays: &[ExpectedRay],
    boxes: &[u8],
    keep: &mut Vec<Allocation>,
) -> Result<Vec<[u32; 4]>, HarnessError> {
    if rays.is_empty() {
        return Ok(vec![]);
    }
    let code = compile_trace_shader()?;
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
    let hb = Allocation::new(
        dev,
        16 * rays.len() as u64,
        sb,
        vk::BufferCreateFlags::empty(),
        1,
    )?;
    let bb = Allocation::new(
        dev,
        boxes.len() as u64,
        sb,
        vk::BufferCreateFlags::empty(),
        1,
    )?;
    bb.write(0, boxes);
    let stage = vk::ShaderStageFlags::COMPUTE;
    let bind = |b: u32, t: vk::DescriptorType| {
        vk::DescriptorSetLayoutBinding::default()
            .binding(b)
            .descriptor_type(t)
            .descriptor_count(1)
            .stage_flags(stage)
    };
    let bindings = [
        bind(0, vk::DescriptorType::ACCELERATION_STRUCTURE_KHR),
        bind(1, vk::DescriptorType::STORAGE_BUFFER),
        bind(2, vk::DescriptorType::STORAGE_BUFFER),
        bind(3, vk::DescriptorType::STORAGE_BUFFER),
    ];
    // SAFETY: valid create infos; everything is destroyed below after the wait.
    let out = unsafe {
        let dsl = d
            .create_descriptor_set_layout(
                &vk::DescriptorSetLayoutCreateInfo::default().bindings(&bindings),
                None,
            )
            .map_err(vkfail("vkCreateDescriptorSetLayout"))?;
        let sets = [dsl];
        let pl = d
            .create_pipeline_layout(
                &vk::PipelineLayoutCreateInfo::default().set_layouts(&sets),
                None,
            )
            .map_err(vkfail("vkCreatePipelineLayout"))?;
        let module = shaders::module(dev, &code)?;
        let st = vk::PipelineShaderStageCreateInfo::default()
            .stage(stage)
            .module(module)
            .name(c"main");
        let pipe = d
            .create_compute_pipelines(
                vk::PipelineCache::null(),
                &[vk::ComputePipelineCreateInfo::default()
                    .stage(st)
                    .layout(pl)],
                None,
            )
            .map_err(|(_, r)| vkfail("vkCreateComputePipelines")(r))?[0];
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
        let set = d
            .allocate_descriptor_sets(
                &vk::DescriptorSetAllocateInfo::default()
                    .descriptor_pool(pool)
                    .set_layouts(&sets),
            )
            .map_err(vkfail("vkAllocateDescriptorSets"))?[0];
        write_check_set(d, set, scene, [rb.buffer, hb.buffer, bb.buffer]);
        let run = (|| -> Result<(), HarnessError> {
            cmds.begin(dev)?;
            d.cmd_bind_pipeline(cmds.cb, vk::PipelineBindPoint::COMPUTE, pipe);
            d.cmd_bind_descriptor_sets(cmds.cb, vk::PipelineBindPoint::COMPUTE, pl, 0, &[set], &[]);
            d.cmd_dispatch(cmds.cb, rays.len() as u32, 1, 1);
            cmds.submit(dev)
        })();
        d.destroy_descriptor_pool(pool, None);
        d.destroy_pipeline(pipe, None);
        d.destroy_shader_module(module, None);
        d.destroy_pipeline_layout(pl, None);
        d.destroy_descriptor_set_layout(dsl, None);
        run.map(|()| {
            hb.read_u32s(4 * rays.len())
                .chunks_exact(4)
                .map(|c| [c[0], c[1], c[2], c[3]])
                .collect::<Vec<_>>()
        })
    };
    keep.extend([rb, hb, bb]);
    out
}
