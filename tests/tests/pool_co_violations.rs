//! A command buffer of a pool whose queue family lacks compute (the H200's transfer families): the
//! generator states nothing bound there — no ray tracing pipeline can be bound in such a pool — and
//! declares exactly what the model reports, under both registries: commandBuffer-cmdpool and the pipeline
//! rule, 08606 (02700 in 1.3.239), for each trace command.

use generator::{generate, CaseSpec};
use model::flags::QueueFlags;
use model::{CommandId, RuleSet};

fn check(rules: &RuleSet, registry: &str, pipeline_tag: &str) -> usize {
    let profile = rtconf_tests::profile("nvidia-h200");
    let mut judged = 0;
    for command in CommandId::TRACE {
        let vuid = format!("VUID-{}-commandBuffer-cmdpool", command.vk_name());
        let spec = CaseSpec::for_vuid(&vuid, command);
        let cases = generate(&profile, "nvidia-h200", rules, &spec, 24, 7).expect("generated");
        for case in cases {
            let trace = case.as_trace().expect("a trace case");
            let cbs = &trace.world.command_buffer;
            assert!(
                !cbs.pool_queue.contains(QueueFlags::COMPUTE_BIT),
                "{registry} {}",
                case.name
            );
            assert!(
                !cbs.pipeline_bound && !cbs.stack_size_set,
                "{registry} {}",
                case.name
            );
            let (expected, got) = rtconf_tests::declared_and_judged(rules, &profile, &case);
            assert_eq!(got, expected, "{registry} {}", case.name);
            let pipeline_rule = format!("VUID-{}-None-{pipeline_tag}", command.vk_name());
            assert_eq!(
                got,
                [vuid.clone(), pipeline_rule].into_iter().collect(),
                "{registry} {}",
                case.name
            );
            judged += 1;
        }
    }
    judged
}

#[test]
fn pool_without_compute_cases_declare_exactly_what_the_model_reports() {
    let installed = check(&rtconf_tests::installed_rules(), "1.3.239", "02700");
    let newer = check(&rtconf_tests::rules_1_4_309(), "1.4.309", "08606");
    assert_eq!((installed, newer), (72, 72), "cases judged");
}
