//! The build path: the command buffer put in the case's state (primary or secondary, initial, recording,
//! executable or invalid, inside a render pass or not), the indirect build recorded under the layer
//! (never submitted), the sizes the device reports, and — for a case run as valid — the traced check of
//! what the device builds ([`crate::accel_check`]).

use crate::accel_check::direct_and_trace;
use crate::error::{vkfail, HarnessError};
use crate::observe::{Observation, Output, TraceCheck};
use crate::realise::accel::{
    device_for, device_sizes, indirect_args, realise, vk_geometries, Realised,
};
use crate::vk::commands::{begin_render_pass, Commands};
use crate::vk::{LayerMessage, VkDevice, VkInstance};
use ash::vk;
use model::accel::call::BuildMode;
use model::accel::BuildSizes;
use model::{AccelBody, Case};
use std::sync::Arc;

/// Why the case's command buffer state cannot be realised on this device, if it cannot: protected
/// command buffers, video coding scopes, pools of a queue family without compute, and recording between
/// suspended render pass instances. Every other state (primary or secondary, initial, recording,
/// executable or invalid, inside a render pass or not) is realised by [`record_indirect`].
fn unrealisable_state(inst: &VkInstance, case: &AccelBody) -> Option<String> {
    let cbs = &case.world.command_buffer;
    // SAFETY: plain query.
    let families = unsafe {
        inst.instance
            .get_physical_device_queue_family_properties(inst.physical)
    };
    let any = |f: vk::QueueFlags| families.iter().any(|p| p.queue_flags.intersects(f));
    let protected_memory = inst
        .device_features()
        .iter()
        .any(|(k, on)| *on && k.ends_with("::protectedMemory"));
    if cbs.protected {
        return Some(format!(
            "a protected command buffer comes from a pool created with VK_COMMAND_POOL_CREATE_PROTECTED_BIT, \
             which needs the protectedMemory feature (VUID-VkCommandPoolCreateInfo-flags-02860) and a queue \
             created with VK_DEVICE_QUEUE_CREATE_PROTECTED_BIT; {}",
            if protected_memory {
                "the harness's device creates no protected queue"
            } else {
                "the device lacks protectedMemory"
            }
        ));
    }
    if cbs.in_video_coding {
        let video = vk::QueueFlags::VIDEO_DECODE_KHR | vk::QueueFlags::VIDEO_ENCODE_KHR;
        return Some(if any(video) {
            "a video coding scope needs a video session (VK_KHR_video_queue) on a video queue; the harness \
             creates neither"
                .into()
        } else {
            "a video coding scope (vkCmdBeginVideoCodingKHR) needs a queue family with video decode or encode; \
             the device has none"
                .into()
        });
    }
    if !cbs
        .pool_queue
        .contains(model::flags::QueueFlags::COMPUTE_BIT)
    {
        let without_compute = families
            .iter()
            .any(|p| !p.queue_flags.contains(vk::QueueFlags::COMPUTE));
        return Some(if without_compute {
            "a pool of a queue family without compute needs the device created with a queue of that family \
             (VUID-vkCreateCommandPool-queueFamilyIndex-01937); the harness's device has its compute family only"
                .into()
        } else {
            format!(
                "a pool of a queue family without VK_QUEUE_COMPUTE_BIT needs such a family; every one of the \
                 device's {} queue famil{} has compute",
                families.len(),
                if families.len() == 1 { "y" } else { "ies" }
            )
        });
    }
    if case.world.command_buffer.between_suspended_render_passes {
        return Some(
            "recording between suspended render pass instances (dynamic rendering) is not realised for builds"
                .into(),
        );
    }
    None
}

/// Puts the case's command buffer into its state: primary or secondary (a secondary inside a render pass
/// continues the empty render pass through its inheritance), begun unless initial, inside the empty
/// render pass when asked (a primary begins it inline), ended when executable, and submitted once with
/// ONE_TIME_SUBMIT when invalid. Returns the command buffer the call is recorded into.
fn enter_state(
    dev: &VkDevice,
    cmds: &mut Commands,
    case: &AccelBody,
) -> Result<vk::CommandBuffer, HarnessError> {
    use model::world::{CommandBufferLevel, CommandBufferLifecycle};
    let cbs = &case.world.command_buffer;
    let d = &dev.device;
    let secondary = cbs.level == CommandBufferLevel::Secondary;
    let cb = if secondary { cmds.secondary } else { cmds.cb };
    let rp = if cbs.in_render_pass {
        Some(cmds.render_pass(dev)?)
    } else {
        None
    };
    // SAFETY: the command buffers are idle; everything named is alive.
    unsafe {
        d.reset_command_buffer(cb, vk::CommandBufferResetFlags::empty())
            .map_err(vkfail("vkResetCommandBuffer"))?;
        if cbs.lifecycle == CommandBufferLifecycle::Initial {
            return Ok(cb);
        }
        let mut inherit = vk::CommandBufferInheritanceInfo::default();
        let mut flags = vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT;
        if let (true, Some((pass, fb))) = (secondary, rp) {
            inherit = inherit.render_pass(pass).subpass(0).framebuffer(fb);
            flags |= vk::CommandBufferUsageFlags::RENDER_PASS_CONTINUE;
        }
        let mut begin = vk::CommandBufferBeginInfo::default().flags(flags);
        if secondary {
            begin = begin.inheritance_info(&inherit);
        }
        d.begin_command_buffer(cb, &begin)
            .map_err(vkfail("vkBeginCommandBuffer"))?;
        let primary_pass = rp.filter(|_| !secondary);
        if let Some(pass) = primary_pass {
            begin_render_pass(d, cb, pass, vk::SubpassContents::INLINE);
        }
        match cbs.lifecycle {
            CommandBufferLifecycle::Executable | CommandBufferLifecycle::Invalid => {
                if primary_pass.is_some() {
                    d.cmd_end_render_pass(cb);
                }
                d.end_command_buffer(cb)
                    .map_err(vkfail("vkEndCommandBuffer"))?;
            }
            _ => {}
        }
        if cbs.lifecycle == CommandBufferLifecycle::Invalid {
            // A ONE_TIME_SUBMIT buffer moves to the invalid state once its submission completes; a
            // secondary one is executed once from the primary.
            let submit_cb = if secondary {
                d.reset_command_buffer(cmds.cb, vk::CommandBufferResetFlags::empty())
                    .map_err(vkfail("vkResetCommandBuffer"))?;
                d.begin_command_buffer(
                    cmds.cb,
                    &vk::CommandBufferBeginInfo::default()
                        .flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT),
                )
                .map_err(vkfail("vkBeginCommandBuffer"))?;
                if let Some(pass) = rp {
                    begin_render_pass(
                        d,
                        cmds.cb,
                        pass,
                        vk::SubpassContents::SECONDARY_COMMAND_BUFFERS,
                    );
                    d.cmd_execute_commands(cmds.cb, &[cb]);
                    d.cmd_end_render_pass(cmds.cb);
                } else {
                    d.cmd_execute_commands(cmds.cb, &[cb]);
                }
                d.end_command_buffer(cmds.cb)
                    .map_err(vkfail("vkEndCommandBuffer"))?;
                cmds.cb
            } else {
                cb
            };
            cmds.submit_and_wait(dev, submit_cb)?;
        }
    }
    Ok(cb)
}

/// Records the indirect call under the layer (dropped by the messenger, never submitted) into a command
/// buffer in the case's state and returns the layer's messages.
fn record_indirect(
    inst: &VkInstance,
    dev: &VkDevice,
    cmds: &mut Commands,
    case: &AccelBody,
    r: &Realised,
) -> Result<Vec<LayerMessage>, HarnessError> {
    use model::world::{CommandBufferLevel, CommandBufferLifecycle};
    let accel = dev
        .accel
        .as_ref()
        .ok_or_else(|| HarnessError::Unsupported("no VK_KHR_acceleration_structure".into()))?;
    let geoms: Vec<Vec<vk::AccelerationStructureGeometryKHR>> = case
        .call
        .infos
        .iter()
        .map(|i| vk_geometries(i, r))
        .collect::<Option<_>>()
        .ok_or_else(|| HarnessError::Unsupported("geometry type not realised".into()))?;
    let (infos, addrs, maxima) = indirect_args(case, r, &geoms);
    let cb = enter_state(dev, cmds, case)?;
    inst.collector.clear();
    inst.collector.set_abort(true);
    // SAFETY: with the messenger returning VK_TRUE the layer drops an invalid call (one recorded into a
    // command buffer that is not recording included).
    unsafe {
        accel.cmd_build_acceleration_structures_indirect(
            cb,
            &infos,
            &addrs,
            &case.call.indirect_strides,
            &maxima,
        )
    };
    inst.collector.set_abort(false);
    let msgs = inst.collector.take();
    let cbs = &case.world.command_buffer;
    // SAFETY: ending what was begun (never submitted); the buffers are reset before their next use.
    unsafe {
        if cbs.lifecycle == CommandBufferLifecycle::Recording {
            if cbs.in_render_pass && cbs.level == CommandBufferLevel::Primary {
                dev.device.cmd_end_render_pass(cb);
            }
            let _ = dev.device.end_command_buffer(cb);
        }
        for b in [cmds.cb, cmds.secondary] {
            let _ = dev
                .device
                .reset_command_buffer(b, vk::CommandBufferResetFlags::empty());
        }
    }
    Ok(msgs)
}

/// Runs one build case: the indirect call recorded under the layer, the sizes the device reports, and
/// for a case run as valid (`run_valid`), the direct build traced with the model's rays (and, where the
/// device has accelerationStructureIndirectBuild, the indirect build for real, traced the same).
pub(crate) fn execute(
    inst: &Arc<VkInstance>,
    case: &Case,
    run_valid: bool,
    check: TraceCheck,
) -> Observation {
    let Some(body) = case.as_accel() else {
        return Observation::crash(format!("{} is not a build case", case.name));
    };
    let mut obs = Observation::with_status(crate::observe::Status::Ran);
    if let Some(why) = unrealisable_state(inst, body) {
        return Observation::unsupported(why);
    }
    let dev = match device_for(inst, body, check) {
        Ok(d) => d,
        Err(e) => return failure(e),
    };
    let result = (|| -> Result<(), HarnessError> {
        let mut cmds = Commands::new(&dev)?;
        let r = match realise(&dev, body, cmds.fence) {
            Ok(r) => r,
            Err(e) => {
                cmds.destroy(&dev);
                return Err(e);
            }
        };
        let out = (|| -> Result<(), HarnessError> {
            if let Some(s) = device_sizes(&dev, body, &r) {
                obs.device_sizes = s;
            }
            let messages = record_indirect(inst, &dev, &mut cmds, body, &r)?;
            obs.set_messages(messages);
            if run_valid && fits_device_sizes(body, &obs.device_sizes) {
                let traced = direct_and_trace(inst, &dev, &cmds, body, &r, check)?;
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
        HarnessError::Unsupported(reason) => Observation::unsupported(reason),
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
