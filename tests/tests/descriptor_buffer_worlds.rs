//! Worlds that use descriptor buffers or a DESCRIPTOR_BUFFER_BIT_EXT pipeline enable
//! VK_EXT_descriptor_buffer and its feature themselves, under both registries: the 1.4.309 registry
//! lists 08115-08119 as core, so the VUIDs' dependencies enable nothing, and a world without the
//! extension cannot be realised (its pipeline flag or descriptor-buffer binds would be invalid of
//! their own). Every such case declares exactly what the model reports.

use generator::{generate, CaseSpec};
use model::{CommandId, RuleSet};

fn check(rules: &RuleSet, registry: &str) -> usize {
    let mut cases_seen = 0;
    for name in rtconf_tests::profile_names() {
        let profile = rtconf_tests::profile(&name);
        if !profile.has_extension("VK_EXT_descriptor_buffer") {
            continue;
        }
        for command in CommandId::ALL.into_iter().filter(|c| c.is_trace()) {
            for tag in ["08115", "08116", "08117"] {
                let vuid = format!("VUID-{}-None-{tag}", command.vk_name());
                if rules.row(&vuid).is_none() {
                    continue;
                }
                let spec = CaseSpec::for_vuid(&vuid, command);
                // A command the device lacks (NV on lavapipe) has no cases to look at.
                if command.is_nv() && !profile.has_extension("VK_NV_ray_tracing") {
                    continue;
                }
                let cases = generate(&profile, &name, rules, &spec, 6, 3)
                    .unwrap_or_else(|e| panic!("{registry} {name} {vuid}: {e}"));
                for case in cases {
                    let Some(trace) = case.as_trace() else {
                        continue;
                    };
                    let dev = &trace.world.device;
                    assert!(
                        dev.extensions.contains("VK_EXT_descriptor_buffer")
                            && dev.features.contains("descriptorBuffer"),
                        "{registry} {name} {}: {:?}",
                        case.name,
                        dev
                    );
                    let (declared, judged) =
                        rtconf_tests::declared_and_judged(rules, &profile, &case);
                    assert_eq!(judged, declared, "{registry} {name} {}", case.name);
                    cases_seen += 1;
                }
            }
        }
    }
    cases_seen
}

#[test]
fn descriptor_buffer_worlds_enable_the_extension_under_both_registries() {
    let installed = check(&rtconf_tests::installed_rules(), "1.3.239");
    let newer = check(&rtconf_tests::rules_1_4_309(), "1.4.309");
    assert!(installed > 0 && newer > 0, "{installed} / {newer} cases");
}
