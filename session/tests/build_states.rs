//! Command buffer states and memory bindings of build cases on real lavapipe: executable, initial and
//! invalid lifecycles, the secondary level (inside a render pass too) and a destination on unbound memory
//! are realised and recorded, and the layer — its validation continuing past the missing
//! accelerationStructureIndirectBuild (03650), which would otherwise end it in the parameter checks —
//! reports each state's VUID as the model does; what the device rules out is `unsupported` with its
//! reason, what the harness does not realise is `not-realised`.

mod common;

use common::{committed, layer_vuids, model_vuids, not_realised, status, unsupported, Lavapipe};
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
    let executable = committed("build/state-recording.yaml");
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
        committed("build/state-renderpass.yaml"),
        vec![FEATURE, RENDERPASS],
    ));
    variants.push((
        committed("build/state-03707.yaml"),
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
            &layer_vuids(&ran),
            want,
            "{cb:?}: validated past 03650, the layer's core checks report the state as the model does"
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
    let mut scattered = committed("build/state-03707.yaml");
    scattered.as_accel_mut().unwrap().world.buffers[0].memory =
        model::world::MemoryBinding::Unbound;
    let why = not_realised(&lvp.run(&scattered, TraceCheck::Auto));
    assert!(why.contains("02600"), "{why}");
}
