//! Command buffer states and memory bindings of build cases on real lavapipe: executable, initial and
//! invalid lifecycles, the secondary level (inside a render pass too) and a destination on unbound memory
//! are realised and recorded (the 1.3.239 layer reports only the missing feature for them: layer gaps in
//! triage/), and what Vulkan or the device rules out is `unsupported` with its reason.

use harness::accel::run_case;
use harness::vulkan::VkInstance;
use harness::Driver;
use model::accel::{BuildCase, BuildRuleSet};
use model::world::{CommandBufferLevel, CommandBufferLifecycle};
use std::sync::Arc;

fn case(name: &str) -> BuildCase {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join(format!("../cases/build/{name}.yaml"));
    BuildCase::from_yaml(name, &std::fs::read_to_string(path).unwrap()).unwrap()
}

const FEATURE: &str =
    "VUID-vkCmdBuildAccelerationStructuresIndirectKHR-accelerationStructureIndirectBuild-03650";
const RECORDING: &str = "VUID-vkCmdBuildAccelerationStructuresIndirectKHR-commandBuffer-recording";
const RENDERPASS: &str = "VUID-vkCmdBuildAccelerationStructuresIndirectKHR-renderpass";

#[test]
fn command_buffer_states_and_unbound_memory_are_realised() {
    let inst = Arc::new(
        VkInstance::new(Driver::Lavapipe, true)
            .expect("lavapipe and the layer are installed by scripts/setup.sh"),
    );
    let profile = generator::profiles::load("lavapipe").unwrap();
    let set = vk_registry::source::load_vuids(std::path::Path::new("/usr/share/vulkan/registry"))
        .unwrap();
    let rules = BuildRuleSet::from_vuids(&set);
    let unavoidable = generator::accel::unavoidable(&profile);
    let run = |c: &BuildCase| run_case(&inst, &profile, &rules, c, &unavoidable);

    let executable = case("layer-1.3.239-recording");
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
        c.world.command_buffer.lifecycle = lifecycle;
        c.world.command_buffer.level = level;
        c.world.command_buffer.in_render_pass = in_pass;
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
    variants.push((case("layer-1.3.239-renderpass"), vec![FEATURE, RENDERPASS]));
    variants.push((
        case("layer-1.3.239-03707"),
        vec![
            FEATURE,
            "VUID-vkCmdBuildAccelerationStructuresIndirectKHR-pInfos-03707",
        ],
    ));
    for (c, want) in &variants {
        let obs = run(c);
        assert_eq!(obs.status, "ran", "{:?}", c.world.command_buffer);
        assert_eq!(&obs.model_vuids, want, "{:?}", c.world.command_buffer);
        assert_eq!(
            obs.layer_vuids,
            vec![FEATURE],
            "the 1.3.239 layer reports only the missing feature (triaged layer gaps)"
        );
    }

    let mut protected = executable.clone();
    protected.world.command_buffer.lifecycle = CommandBufferLifecycle::Recording;
    protected.world.command_buffer.protected = true;
    let obs = run(&protected);
    assert!(
        obs.status
            .starts_with("unsupported: a protected command buffer")
            && obs.status.contains("lacks protectedMemory"),
        "{}",
        obs.status
    );
    let mut scattered = case("layer-1.3.239-03707");
    scattered.world.buffers[0].memory = model::world::MemoryBinding::Unbound;
    let obs = run(&scattered);
    assert!(obs.status.contains("02600"), "{}", obs.status);
}
