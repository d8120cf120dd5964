//! A command buffer that is not recording: the generator declares exactly the co-violations the model
//! reports, under both registries. In a never-begun command buffer nothing is bound, so the pipeline
//! rule fires beside commandBuffer-recording: 08606 without shaderObject (02700 in 1.3.239), never
//! 08607, which holds only with shaderObject enabled.

use generator::{generate, CaseSpec};
use model::world::CommandBufferLifecycle;
use model::{CommandId, RuleSet};

fn check(rules: &RuleSet, registry: &str) -> usize {
    let mut initial = 0;
    for name in rtconf_tests::profile_names() {
        let profile = rtconf_tests::profile(&name);
        for command in [CommandId::TraceRays, CommandId::TraceRaysIndirect] {
            let vuid = format!("VUID-{}-commandBuffer-recording", command.vk_name());
            let spec = CaseSpec::for_vuid(&vuid, command);
            let cases = generate(&profile, &name, rules, &spec, 24, 7).expect("generated");
            for case in cases {
                let Some(trace) = case.as_trace() else {
                    continue;
                };
                let (expected, got) = rtconf_tests::declared_and_judged(rules, &profile, &case);
                assert_eq!(got, expected, "{registry} {name} {}", case.name);
                if trace.world.command_buffer.lifecycle == CommandBufferLifecycle::Initial {
                    initial += 1;
                    assert!(
                        got.iter()
                            .any(|v| v.ends_with("-02700") || v.ends_with("-08606")),
                        "{registry} {name} {}: {got:?}",
                        case.name
                    );
                }
            }
        }
    }
    initial
}

#[test]
fn recording_cases_declare_exactly_what_the_model_reports() {
    let installed = check(&rtconf_tests::installed_rules(), "1.3.239");
    let newer = check(&rtconf_tests::rules_1_4_309(), "1.4.309");
    assert!(
        installed > 0 && newer > 0,
        "{installed} / {newer} never-begun cases"
    );
}
