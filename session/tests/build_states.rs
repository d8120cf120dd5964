//! Command buffer states and memory bindings of build cases on real lavapipe: executable, initial and
//! invalid lifecycles, the secondary level (inside a render pass too) and a destination on unbound memory
//! are realised and recorded (the 1.3.239 layer reports only the missing feature for them: layer gaps in
//! triage/), and what Vulkan or the device rules out is `unsupported` with its reason.

mod common;

use common::{committed, layer_vuids, model_vuids, status, unsupported, Lavapipe};
use harness::{Status, TraceCheck};
use model::world::{CommandBufferLevel, CommandBufferLifecycle, CommandBufferState};
use model::Case;

const FEATURE: &str =
    "VUID-vkCmdBuildAccelerationStructuresIndirectKHR-accelerationStructureIndirectBuild-03650";
const RECORDING: &str = "VUID-vkCmdBuildAccelerationStructuresIndirectKHR-commandBuffer-recording";
const RENDERPASS: &str = "VUID-vkCmdBuildAccelerationStructuresIndirectKHR-renderpass";

fn command_buffer(c: &mut Case) -> &mut CommandBufferState {
    &mut c.as_accel_mut().unwrap().world.command_buffer
}

#[test]
fn command_buffer_states_and_unbound_memory_are_realised() {
    let mut lvp = Lavapipe::new();
    let executable = committed("build/layer-1.3.239-recording.yaml");
    let mut variants = vec![(executable.clone(), vec![FEATURE, RECORDING])];
    for (lifecycle, level, in_pass) in [
        (
            CommandBufferLifecycle::Initial,
            CommandBufferLevel::Primary,
            false,
        ),
        (
            CommandBufferLifecycle::Invalid,
            CommandBufferLevel::Primary,
            false,
        ),
        (
            CommandBufferLifecycle::Executable,
            CommandBufferLevel::Secondary,
            false,
        ),
        (
            CommandBufferLifecycle::Invalid,
            CommandBufferLevel::Secondary,
            true,
        ),
        (
            CommandBufferLifecycle::Recording,
            CommandBufferLevel::Secondary,
            true,
        ),
    ] {
        let mut c = executable.clone();
        let cb = command_buffer(&mut c);
        cb.lifecycle = lifecycle;
        cb.level = level;
        cb.in_render_pass = in_pass;
        let mut want = vec![FEATURE];
        if lifecycle != CommandBufferLifecycle::Recording {
            want.push(RECORDING);
        }
        if in_pass {
            want.push(RENDERPASS);
        }
        want.sort();
        variants.push((c, want));
    }
    variants.push((
        committed("build/layer-1.3.239-renderpass.yaml"),
        vec![FEATURE, RENDERPASS],
    ));
    variants.push((
        committed("build/layer-1.3.239-03707.yaml"),
        vec![
            FEATURE,
            "VUID-vkCmdBuildAccelerationStructuresIndirectKHR-pInfos-03707",
        ],
    ));
    for (c, want) in &variants {
        let cb = &c.as_accel().unwrap().world.command_buffer;
        let ran = lvp.run(c, TraceCheck::Auto);
        assert_eq!(status(&ran), &Status::Ran, "{cb:?}");
        assert_eq!(&model_vuids(&ran), want, "{cb:?}");
        assert_eq!(
            layer_vuids(&ran),
            vec![FEATURE],
            "the 1.3.239 layer reports only the missing feature (triaged layer gaps)"
        );
    }

    let mut protected = executable.clone();
    command_buffer(&mut protected).lifecycle = CommandBufferLifecycle::Recording;
    command_buffer(&mut protected).protected = true;
    let why = unsupported(&lvp.run(&protected, TraceCheck::Auto));
    assert!(
        why.starts_with("a protected command buffer") && why.contains("lacks protectedMemory"),
        "{why}"
    );
    let mut scattered = committed("build/layer-1.3.239-03707.yaml");
    scattered.as_accel_mut().unwrap().world.buffers[0].memory =
        model::world::MemoryBinding::Unbound;
    let why = unsupported(&lvp.run(&scattered, TraceCheck::Auto));
    assert!(why.contains("02600"), "{why}");
}
