//! The build path: the command buffer put in the case's state (primary or secondary, initial, recording,
//! executable or invalid, inside a render pass or not), the indirect build recorded under the layer
//! (never submitted), the sizes the device reports, and — for a case run as valid — the traced check of
//! what the device builds ([`crate::accel_check`]).

use crate::accel_check::direct_and_trace;
use crate::error::{vkfail, HarnessError};
use crate::observe::{Observation, Output};
use crate::plan::build::BuildPlan;
use crate::plan::Step;
use crate::realise::accel::{
    device_for, device_sizes, indirect_args, last_build_geometries, realise, vk_as_type,
    vk_geometries, Realised,
};
use crate::vk::commands::{begin_render_pass, Commands};
use crate::vk::{LayerMessage, VkDevice, VkInstance};
use ash::vk;
use model::accel::call::BuildMode;
use model::accel::world::AddressResolver;
use model::accel::BuildSizes;
use model::{AccelBody, Case};
use std::sync::Arc;

/// Why the case's command buffer state cannot be realised for a build, if it cannot: what
/// [`super::unrealisable_command_buffer`] says for every command, and recording between suspended render
/// pass instances. Every other state (primary or secondary, initial, recording, executable or invalid,
/// inside a render pass or not) is realised by [`record_indirect`].
fn unrealisable_state(inst: &VkInstance, case: &AccelBody) -> Option<HarnessError> {
    let cbs = &case.world.command_buffer;
    if let Some(e) = super::unrealisable_command_buffer(inst, cbs) {
        return Some(e);
    }
    if cbs.between_suspended_render_passes {
        return Some(HarnessError::NotRealised(
            "recording between suspended render pass instances (dynamic rendering) is not realised for builds"
                .into(),
        ));
    }
    None
}

/// Repeats, for the layer's state, the last build the model's world says each structure had: a direct
/// build of it with that build's type, flags and geometries, recorded (not aborted, never submitted)
/// before the case's call, so update rules that compare with the source's last build (03667,
/// 03758-03770) see on the device what the model sees. The layer tracks builds as they are recorded;
/// what it says of these builds is not the case's and is dropped.
fn replay_last_builds(
    inst: &VkInstance,
    dev: &VkDevice,
    cmds: &Commands,
    case: &AccelBody,
    r: &Realised,
) -> Result<(), HarnessError> {
    let Some(accel) = dev.accel.as_ref() else {
        return Ok(());
    };
    let Some(data) = r.buffers.values().map(|a| a.address).next() else {
        return Ok(());
    };
    let scratch = case
        .call
        .infos
        .first()
        .map_or(data, |i| r.address(&i.scratch));
    let d = &dev.device;
    for s in &case.world.structures {
        let (Some(lb), Some(&(handle, _))) = (&s.last_build, r.structures.get(&s.name)) else {
            continue;
        };
        let Some((geoms, ranges)) = last_build_geometries(lb, data) else {
            continue;
        };
        let info = vk::AccelerationStructureBuildGeometryInfoKHR::default()
            .ty(vk_as_type(lb.ty))
            .flags(vk::BuildAccelerationStructureFlagsKHR::from_raw(lb.flags.0))
            .mode(vk::BuildAccelerationStructureModeKHR::BUILD)
            .dst_acceleration_structure(handle)
            .geometries(&geoms)
            .scratch_data(vk::DeviceOrHostAddressKHR {
                device_address: scratch,
            });
        inst.collector.set_abort(false);
        // SAFETY: recorded into an idle command buffer that is reset right after, never submitted.
        unsafe {
            d.reset_command_buffer(cmds.cb, vk::CommandBufferResetFlags::empty())
                .map_err(vkfail("vkResetCommandBuffer"))?;
            d.begin_command_buffer(cmds.cb, &vk::CommandBufferBeginInfo::default())
                .map_err(vkfail("vkBeginCommandBuffer"))?;
            accel.cmd_build_acceleration_structures(cmds.cb, &[info], &[&ranges]);
            let _ = d.end_command_buffer(cmds.cb);
            d.reset_command_buffer(cmds.cb, vk::CommandBufferResetFlags::empty())
                .map_err(vkfail("vkResetCommandBuffer"))?;
        }
    }
    inst.collector.clear();
    Ok(())
}

/// Records the plan's steps: the command buffer put into the case's state (primary or secondary — a
/// secondary inside a render pass continues the empty render pass through its inheritance — begun
/// unless initial, inside the empty render pass when asked, ended when executable, and submitted once
/// with ONE_TIME_SUBMIT when invalid), then the indirect call under the layer (dropped by the
/// messenger, never submitted). Returns the layer's messages for the call.
fn record_indirect(
    inst: &VkInstance,
    dev: &VkDevice,
    cmds: &mut Commands,
    plan: &BuildPlan,
    r: &Realised,
    continue_past: &[String],
) -> Result<Vec<LayerMessage>, HarnessError> {
    use model::world::CommandBufferLevel;
    let accel = dev
        .accel
        .as_ref()
        .ok_or_else(|| HarnessError::NotRealised("no VK_KHR_acceleration_structure".into()))?;
    let geoms: Vec<Vec<vk::AccelerationStructureGeometryKHR>> = plan
        .infos
        .iter()
        .map(|i| vk_geometries(i, r))
        .collect::<Option<_>>()
        .ok_or_else(|| HarnessError::NotRealised("geometry type not realised".into()))?;
    let (infos, addrs, maxima) = indirect_args(plan, r, &geoms);
    let secondary = plan.level == CommandBufferLevel::Secondary;
    let cb = if secondary { cmds.secondary } else { cmds.cb };
    let rp = if plan.in_render_pass {
        Some(cmds.render_pass(dev)?)
    } else {
        None
    };
    let d = &dev.device;
    let mut msgs = Vec::new();
    let mut called = false;
    for step in &plan.steps {
        // SAFETY: the command buffers are idle; everything named is alive. With the messenger returning
        // VK_TRUE the layer drops an invalid call (one recorded into a command buffer that is not
        // recording included).
        unsafe {
            match step {
                Step::Reset { .. } => d
                    .reset_command_buffer(cb, vk::CommandBufferResetFlags::empty())
                    .map_err(vkfail("vkResetCommandBuffer"))?,
                Step::Begin {
                    continue_render_pass,
                    ..
                } => {
                    let mut inherit = vk::CommandBufferInheritanceInfo::default();
                    let mut flags = vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT;
                    if let (true, Some((pass, fb))) = (*continue_render_pass, rp) {
                        inherit = inherit.render_pass(pass).subpass(0).framebuffer(fb);
                        flags |= vk::CommandBufferUsageFlags::RENDER_PASS_CONTINUE;
                    }
                    let mut begin = vk::CommandBufferBeginInfo::default().flags(flags);
                    if secondary {
                        begin = begin.inheritance_info(&inherit);
                    }
                    d.begin_command_buffer(cb, &begin)
                        .map_err(vkfail("vkBeginCommandBuffer"))?;
                }
                Step::BeginRenderPass => {
                    if let Some(pass) = rp {
                        begin_render_pass(d, cb, pass, vk::SubpassContents::INLINE);
                    }
                }
                Step::EndRenderPass => d.cmd_end_render_pass(cb),
                // After the call a recording buffer is ended only to be reset.
                Step::End if called => {
                    let _ = d.end_command_buffer(cb);
                }
                Step::End => d
                    .end_command_buffer(cb)
                    .map_err(vkfail("vkEndCommandBuffer"))?,
                Step::SubmitToInvalidate => cmds.submit_to_invalidate(dev, cb, secondary, rp)?,
                Step::Call { .. } => {
                    inst.collector.clear();
                    inst.collector.set_abort(true);
                    // Past the `continue_past` VUIDs the layer goes on validating; a call it finds
                    // nothing else wrong with is recorded by the driver (never submitted: the command
                    // buffers are reset before their next use).
                    inst.collector.set_continue_past(continue_past);
                    accel.cmd_build_acceleration_structures_indirect(
                        cb,
                        &infos,
                        &addrs,
                        &plan.indirect_strides,
                        &maxima,
                    );
                    inst.collector.set_abort(false);
                    inst.collector.set_continue_past(&[]);
                    msgs = inst.collector.take();
                    called = true;
                }
                _ => {}
            }
        }
    }
    // SAFETY: never submitted (or waited for); the buffers are reset before their next use.
    unsafe {
        for b in [cmds.cb, cmds.secondary] {
            let _ = d.reset_command_buffer(b, vk::CommandBufferResetFlags::empty());
        }
    }
    Ok(msgs)
}

/// Runs one build case: the indirect call recorded under the layer, the sizes the device reports, and
/// for a case run as valid (`run_valid`), the direct build traced with the model's rays (and, where the
/// device has accelerationStructureIndirectBuild, the indirect build for real, traced the same).
pub(crate) fn execute(inst: &Arc<VkInstance>, case: &Case, exec: &super::Execution) -> Observation {
    let (run_valid, check) = (exec.run_valid, exec.check);
    let Some(body) = case.as_accel() else {
        return Observation::crash(format!("{} is not a build case", case.name));
    };
    let mut obs = Observation::with_status(crate::observe::Status::Ran);
    if let Some(e) = unrealisable_state(inst, body) {
        return failure(e);
    }
    let plan = match BuildPlan::of(body) {
        Ok(p) => p,
        Err(e) => return failure(e),
    };
    let dev = {
        let _phase = crate::timing::span(crate::timing::Phase::Device);
        match device_for(inst, body, check) {
            Ok(d) => d,
            Err(e) => return failure(e),
        }
    };
    let _phase = crate::timing::span(crate::timing::Phase::Structures);
    let result = (|| -> Result<(), HarnessError> {
        let mut cmds = Commands::new(&dev)?;
        let r = match realise(&dev, &plan, cmds.fence) {
            Ok(r) => r,
            Err(e) => {
                cmds.destroy(&dev);
                return Err(e);
            }
        };
        let out = (|| -> Result<(), HarnessError> {
            if let Some(s) = device_sizes(&dev, &plan, &r) {
                obs.device_sizes = s;
            }
            replay_last_builds(inst, &dev, &cmds, body, &r)?;
            let messages = record_indirect(inst, &dev, &mut cmds, &plan, &r, &exec.continue_past)?;
            obs.set_messages(messages);
            if run_valid && fits_device_sizes(body, &obs.device_sizes) {
                let traced = direct_and_trace(inst, &dev, &cmds, body, &plan, &r, check)?;
                obs.output = Some(Output::Rays(traced));
            }
            Ok(())
        })();
        cmds.destroy(&dev);
        r.destroy(&dev);
        out
    })();
    match result {
        Ok(()) => obs,
        Err(e) => failure(e),
    }
}

/// An error of the build path as an observation: `unsupported: …` names what the device or harness
/// lacks; anything else is a failure of the driver or the harness.
fn failure(e: HarnessError) -> Observation {
    match e {
        HarnessError::NotRealised(reason) => Observation::not_realised(reason),
        HarnessError::DeviceLacks { lack, reason } => Observation::unsupported(lack, reason),
        HarnessError::OutOfMemory(s) => Observation::out_of_memory(s),
        e => Observation::crash(format!("failed: {e}")),
    }
}

/// Whether the case's first destination and scratch are as large as the device says the build needs:
/// the direct build writes them, and a smaller range would be written out of bounds.
fn fits_device_sizes(case: &AccelBody, sizes: &[BuildSizes]) -> bool {
    let (Some(info), Some(need)) = (case.call.infos.first(), sizes.first()) else {
        return true;
    };
    let dst = info.dst.as_deref().and_then(|n| case.world.structure(n));
    let scratch = info
        .scratch
        .buffer()
        .and_then(|(b, off)| Some(case.world.buffer(b)?.size.saturating_sub(off)));
    let scratch_need = match info.mode {
        BuildMode::Update => need.update_scratch,
        _ => need.build_scratch,
    };
    dst.is_none_or(|s| s.size >= need.structure) && scratch.is_none_or(|s| s >= scratch_need)
}
