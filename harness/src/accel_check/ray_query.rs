//! The ray query check: a compute shader (`shaders/check_query.comp`) that traces each ray with
//! `rayQueryEXT` and writes its 28-word `RayRecord`, generating AABB hits where the sphere of the box
//! says.

use super::set::CheckSet;
use crate::error::{vkfail, HarnessError};
use crate::plan::check::CheckPlan;
use crate::shaders;
use crate::vk::commands::Commands;
use crate::vk::VkDevice;
use ash::vk;

pub(super) fn compile_trace_shader() -> Result<Vec<u32>, HarnessError> {
    super::check_spirv(
        "check_query",
        "check_query.comp",
        include_str!("../../shaders/check_query.comp"),
    )
}

/// Traces the plan's rays with the ray query shader; one `RayRecord` per ray.
pub(super) fn trace(
    dev: &VkDevice,
    cmds: &Commands,
    scene: vk::AccelerationStructureKHR,
    plan: &CheckPlan,
) -> Result<Vec<u32>, HarnessError> {
    if plan.rays.is_empty() {
        return Ok(vec![]);
    }
    let code = compile_trace_shader()?;
    let d = &dev.device;
    let stage = vk::ShaderStageFlags::COMPUTE;
    let check = CheckSet::new(dev, scene, plan, stage)?;
    let mut module = vk::ShaderModule::null();
    let mut pl = vk::PipelineLayout::null();
    let mut pipe = vk::Pipeline::null();
    // SAFETY: valid create infos; everything is destroyed below after the wait.
    let out = unsafe {
        (|| -> Result<Vec<u32>, HarnessError> {
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
            d.cmd_dispatch(cmds.cb, plan.rays.len() as u32, 1, 1);
            cmds.submit(dev)?;
            Ok(check.records())
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
