//! Resource cases place their accesses where a ray tracing pipeline can run them: every
//! generated resource case declares its accesses in a stage the launch executes (by the model's
//! semantics), the stages vary across cases, and no access needs implicit derivatives (implicit-LOD
//! sampling or a LOD bias), which ray tracing stages do not have.

mod common;

use generator::resources::{launch_stages, mutation_for};
use generator::{executable_vuids, generate, CaseSpec, GenError};
use model::resources::Stage;
use model::CommandId;
use std::collections::BTreeSet;

#[test]
fn resource_accesses_sit_in_executed_stages_and_need_no_derivatives() {
    let (name, profile) = common::profiles()
        .into_iter()
        .find(|(n, _)| n == "lavapipe")
        .expect("the lavapipe profile");
    let mut seen: BTreeSet<Stage> = BTreeSet::new();
    let mut cases = 0;
    for command in CommandId::TRACE {
        for vuid in executable_vuids(common::rules(), command) {
            if mutation_for(&vuid).is_none() {
                continue;
            }
            let generated = match generate(
                &profile,
                &name,
                common::rules(),
                &CaseSpec::violate(command, &vuid),
                12,
                5,
            ) {
                Ok(c) => c,
                Err(GenError::Unsupported(_)) => continue,
                Err(e) => panic!("{vuid}: {e}"),
            };
            for case in generated {
                let executed = launch_stages(
                    &case.as_trace().unwrap().world,
                    &case.as_trace().unwrap().call,
                );
                for s in &case.as_trace().unwrap().world.resources.stages {
                    if s.accesses.is_empty() && s.push_constants.is_none() {
                        continue;
                    }
                    assert!(
                        executed.contains(&s.stage),
                        "{}: accesses in {:?}, the launch executes {executed:?}",
                        case.name,
                        s.stage
                    );
                    seen.insert(s.stage);
                    for a in &s.accesses {
                        assert!(
                            !a.implicit_lod && !a.lod_bias,
                            "{}: an implicit-LOD access in a ray tracing stage",
                            case.name
                        );
                    }
                }
                cases += 1;
            }
        }
    }
    assert!(cases > 100, "only {cases} resource cases");
    for stage in [Stage::Raygen, Stage::Miss, Stage::Callable] {
        assert!(seen.contains(&stage), "no case uses {stage:?}: {seen:?}");
    }
}

#[test]
fn the_unnormalized_instruction_rules_keep_explicit_lod_variants() {
    let (name, profile) = common::profiles()
        .into_iter()
        .find(|(n, _)| n == "lavapipe")
        .expect("the lavapipe profile");
    for (tag, want) in [("02703", "proj"), ("02704", "offset")] {
        let vuid = format!("VUID-vkCmdTraceRaysKHR-None-{tag}");
        let cases = generate(
            &profile,
            &name,
            common::rules(),
            &CaseSpec::violate(CommandId::TraceRays, &vuid),
            8,
            9,
        )
        .unwrap_or_else(|e| panic!("{vuid}: {e}"));
        assert!(!cases.is_empty());
        for c in cases {
            let a = c
                .as_trace()
                .unwrap()
                .world
                .resources
                .stages
                .iter()
                .flat_map(|s| &s.accesses)
                .find(|a| a.binding == 6)
                .expect("the unnormalized sample");
            let ok = match want {
                "proj" => a.proj,
                _ => a.offset,
            };
            assert!(ok, "{}: {a:?}", c.name);
            let v = common::judge(&profile, &c);
            assert!(v.vuids().iter().any(|x| *x == vuid), "{}: {v:?}", c.name);
        }
    }
}
