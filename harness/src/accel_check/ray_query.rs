//! The ray query check: a compute shader that traces each ray with `rayQueryEXT` and writes
//! `[hit, instance, geometry, primitive]`, generating AABB hits where the box table says.

use super::set::CheckSet;
use crate::error::{vkfail, HarnessError};
use crate::shaders;
use crate::vk::commands::Commands;
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

pub(super) fn compile_trace_shader() -> Result<Vec<u32>, HarnessError> {
    shaders::compile_glsl("the ray query check", "comp", TRACE_COMP, &[])
}

/// Traces the rays with the ray query shader; one `[hit, instance, geometry, primitive]` per ray.
pub(super) fn trace(
    dev: &VkDevice,
    cmds: &Commands,
    scene: vk::AccelerationStructureKHR,
    rays: &[ExpectedRay],
    boxes: &[u8],
) -> Result<Vec<[u32; 4]>, HarnessError> {
    if rays.is_empty() {
        return Ok(vec![]);
    }
    let code = compile_trace_shader()?;
    let d = &dev.device;
    let stage = vk::ShaderStageFlags::COMPUTE;
    let check = CheckSet::new(dev, scene, rays, boxes, stage)?;
    let mut module = vk::ShaderModule::null();
    let mut pl = vk::PipelineLayout::null();
    let mut pipe = vk::Pipeline::null();
    // SAFETY: valid create infos; everything is destroyed below after the wait.
    let out = unsafe {
        (|| -> Result<Vec<[u32; 4]>, HarnessError> {
            pl = check.pipeline_layout(dev)?;
            module = shaders::module(dev, &code)?;
            let st = vk::PipelineShaderStageCreateInfo::default()
                .stage(stage)
                .module(module)
                .name(c"main");
            pipe = d
                .create_compute_pipelines(
                    vk::PipelineCache::null(),
                    &[vk::ComputePipelineCreateInfo::default()
                        .stage(st)
                        .layout(pl)],
                    None,
                )
                .map_err(|(_, r)| vkfail("vkCreateComputePipelines")(r))?[0];
            cmds.begin(dev)?;
            d.cmd_bind_pipeline(cmds.cb, vk::PipelineBindPoint::COMPUTE, pipe);
            d.cmd_bind_descriptor_sets(
                cmds.cb,
                vk::PipelineBindPoint::COMPUTE,
                pl,
                0,
                &[check.set],
                &[],
            );
            d.cmd_dispatch(cmds.cb, rays.len() as u32, 1, 1);
            cmds.submit(dev)?;
            Ok(check.hits())
        })()
    };
    // SAFETY: the submission was waited for (or never made); null handles are ignored.
    unsafe {
        d.destroy_pipeline(pipe, None);
        d.destroy_shader_module(module, None);
        d.destroy_pipeline_layout(pl, None);
    }
    check.destroy(dev);
    out
}
