//! Meta-tests of the resource-access mutations: generated invalid cases carry their VUID
//! and nothing undeclared; vendor mutations, which no captured driver can run, do the same when
//! judged by the model alone; valid cases stay valid with an empty or a generated resource state.

mod common;

use generator::resources::{mutate, mutation_for, state_strategy, vendor, TAGS};
use generator::{executable_vuids, generate, CaseSpec, GenError};
use model::rules::{RuleSet, Status};
use model::CommandId;
use proptest::strategy::{Strategy, ValueTree};
use std::collections::BTreeSet;

fn resource_vuids(rules: &RuleSet, command: CommandId) -> Vec<String> {
    executable_vuids(rules, command)
        .into_iter()
        .filter(|v| mutation_for(v).is_some())
        .collect()
}

#[test]
fn every_executable_resource_rule_has_a_mutation() {
    for command in CommandId::TRACE {
        for row in common::rules()
            .rows
            .iter()
            .filter(|r| r.status == Status::Executable && r.scope == command.vk_name())
        {
            if matches!(
                row.predicate,
                Some(model::rules::predicate::Predicate::Resource(_))
            ) {
                assert!(
                    mutation_for(&row.vuid).is_some(),
                    "{} has no mutation",
                    row.vuid
                );
            }
        }
    }
}

#[test]
fn resource_invalid_cases_carry_their_vuid_and_nothing_undeclared() {
    let n = 60;
    let mut generated = 0;
    let mut report = vec![];
    let mut failures = vec![];
    for (name, profile) in common::profiles() {
        for command in CommandId::TRACE {
            for vuid in resource_vuids(common::rules(), command) {
                let Some(cases) =
                    common::violating((&name, &profile), command, &vuid, n, 23, &mut report)
                else {
                    continue;
                };
                generated += 1;
                let common::Judged { good, example, .. } =
                    common::judge_all(&profile, &cases, &vuid);
                report.push(format!("{name} {vuid}: {good}/{}", cases.len()));
                if good * 100 < cases.len() * 95 {
                    failures.push(format!(
                        "{name} {vuid}: {good}/{}\n{}",
                        cases.len(),
                        example.unwrap_or_default()
                    ));
                }
            }
        }
    }
    println!("{}", report.join("\n"));
    assert!(generated >= 60, "only {generated} resource VUIDs generated");
    assert!(failures.is_empty(), "{}", failures.join("\n\n"));
}

/// Vendor rules: the mutation applied to a generated valid case with the rule's extension enabled in
/// the world; the model alone judges (no captured driver has the extension).
#[test]
fn vendor_mutations_fire_their_rule_in_the_model() {
    let rules = generator::registry::load_rules(std::path::Path::new(
        &std::env::var("RTCONF_RESOURCES_REGISTRY").unwrap_or_else(|_| {
            let p = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
                .join("../target/registry/1.4.309/usr/share/vulkan/registry");
            if p.exists() {
                p.display().to_string()
            } else {
                generator::registry::REGISTRY_DIR.to_string()
            }
        }),
    ))
    .unwrap();
    let (name, profile) = common::profiles()
        .into_iter()
        .find(|(n, _)| n == "lavapipe")
        .unwrap();
    let base = generate(
        &profile,
        &name,
        &rules,
        &CaseSpec::valid(CommandId::TraceRays),
        8,
        5,
    )
    .unwrap();
    let mut checked = 0;
    for vuid in executable_vuids(&rules, CommandId::TraceRays) {
        let Some(m) = mutation_for(&vuid) else {
            continue;
        };
        if vendor(m).is_none() {
            continue;
        }
        for (k, case) in base.iter().enumerate() {
            let mut case = case.clone();
            if let model::Call::TraceRays(x) = &mut case.as_trace_mut().unwrap().call {
                x.width = x.width.max(1);
                x.height = x.height.max(1);
                x.depth = x.depth.max(1);
            }
            let mut st = generator::resources::valid_state(&profile, k as u32, 0x1ff);
            let world = &mut case.as_trace_mut().unwrap().world;
            let tags = mutate(
                m,
                &mut st,
                &mut world.device,
                &mut world.command_buffer,
                &profile,
                k as u32,
            )
            .unwrap();
            case.as_trace_mut().unwrap().world.resources = st;
            let row = rules.row(&vuid).unwrap();
            // Enable what the row's condition names, as a device with the extension would: all of them,
            // or, where the condition excludes one (`…+(A,B)+!(B)`), one of them at a time.
            let base = case.as_trace().unwrap().world.device.extensions.clone();
            let names: Vec<String> = row
                .condition
                .names()
                .into_iter()
                .filter(|n| !n.starts_with("VK_VERSION_"))
                .map(String::from)
                .collect();
            let mut candidates = vec![names.clone()];
            candidates.extend(names.iter().map(|n| vec![n.clone()]));
            for extra in candidates {
                let mut exts = base.clone();
                exts.extend(extra);
                if row
                    .condition
                    .eval(&|n: &str| exts.contains(n) || n.starts_with("VK_VERSION_1_"))
                {
                    case.as_trace_mut().unwrap().world.device.extensions = exts;
                    break;
                }
            }
            let v = model::validate(&rules, &profile, &case);
            let got: BTreeSet<String> = v.vuids().into_iter().map(String::from).collect();
            let allowed: BTreeSet<String> = std::iter::once(vuid.clone())
                .chain(tags.iter().filter_map(|t| {
                    rules
                        .rows
                        .iter()
                        .find(|r| {
                            r.scope == "vkCmdTraceRaysKHR" && r.vuid.ends_with(&format!("-{t}"))
                        })
                        .map(|r| r.vuid.clone())
                }))
                .collect();
            assert!(
                got.contains(&vuid),
                "{vuid}: not fired: {:?}\n{}",
                v.violations,
                case.to_yaml()
            );
            assert!(
                got.is_subset(&allowed),
                "{vuid}: undeclared {:?}",
                got.difference(&allowed).collect::<Vec<_>>()
            );
            checked += 1;
        }
    }
    assert!(checked >= 8, "{checked} vendor cases checked");
}

#[test]
fn valid_cases_stay_valid_with_empty_or_generated_resource_states() {
    let mut judged = 0;
    for (name, profile) in common::profiles() {
        let strategy = state_strategy(&profile);
        for command in CommandId::TRACE {
            let cases = match generate(
                &profile,
                &name,
                common::rules(),
                &CaseSpec::valid(command),
                100,
                31,
            ) {
                Ok(c) => c,
                Err(GenError::Unsupported(_)) => continue,
                Err(e) => panic!("{e}"),
            };
            for (i, case) in cases.into_iter().enumerate() {
                let mut runner = generator::case_runner(77, i as u64);
                let mut case = case;
                case.as_trace_mut().unwrap().world.resources =
                    strategy.new_tree(&mut runner).unwrap().current();
                let v = common::judge(&profile, &case);
                assert!(
                    v.is_valid(),
                    "{name}: {:?}\n{}",
                    v.violations,
                    case.to_yaml()
                );
                judged += 1;
            }
        }
    }
    assert!(judged >= 400, "{judged}");
}

#[test]
fn the_tag_table_and_the_model_agree() {
    for (tag, _) in TAGS {
        let vuid = format!("VUID-vkCmdTraceRaysKHR-None-{tag}");
        assert!(mutation_for(&vuid).is_some(), "{tag}");
    }
    assert!(
        mutation_for("VUID-vkCmdTraceRaysKHR-None-08612").is_none(),
        "shader-object rules are not executable"
    );
}

/// A corner-sampled image needs VK_NV_corner_sampled_image on the device whatever the VUID's listed
/// dependencies (1.4.309 lists 02696 as core): the world enables it where the profile has it, and a
/// profile without it cannot express the case (unsupported by profile, not a case the harness is left
/// to refuse).
#[test]
fn a_corner_sampled_image_enables_its_extension_or_is_unsupported() {
    const EXTENSION: &str = "VK_NV_corner_sampled_image";
    let m = mutation_for("VUID-vkCmdTraceRaysKHR-flags-02696").expect("a resource rule");
    for (name, profile) in common::profiles() {
        let mut st = generator::resources::valid_state(&profile, 0, 0x1ff);
        let mut dev = model::world::DeviceState::default();
        let mut cb = model::world::CommandBufferState::default();
        let made = mutate(m, &mut st, &mut dev, &mut cb, &profile, 0);
        if profile.has_extension(EXTENSION) {
            assert!(made.is_ok(), "{name}: {made:?}");
            assert!(dev.extensions.contains(EXTENSION), "{name}: {dev:?}");
            assert!(st.images.iter().any(|i| i.corner_sampled), "{name}");
        } else {
            let why = made.expect_err(&name);
            assert!(why.contains(EXTENSION), "{name}: {why}");
        }
    }
    assert!(
        common::profiles()
            .iter()
            .any(|(_, p)| !p.has_extension(EXTENSION))
            && common::profiles()
                .iter()
                .any(|(_, p)| p.has_extension(EXTENSION)),
        "the committed profiles include one with the extension and one without"
    );
}
