//! Meta-test: for every executable VUID with a mutation, at least 95% of its generated cases carry the
//! VUID and nothing undeclared; and the list of executable VUIDs without a mutation is a committed
//! expectation, so coverage changes show up in review.

mod common;

use generator::{executable_vuids, generate, mutations_for, CaseSpec, GenError};
use model::CommandId;
use std::collections::BTreeSet;

/// VUIDs excluded because of a model bug (see the generator report); empty when none.
const MODEL_BUG_EXCLUDED: &[&str] = &[];

#[test]
fn one_vuid_invalid_cases_carry_their_vuid_and_nothing_undeclared() {
    let n = common::per_spec();
    let mut report = vec![];
    let mut failures = vec![];
    let mut generated_any = 0;
    for (name, profile) in common::profiles() {
        for command in CommandId::TRACE {
            for vuid in executable_vuids(common::rules(), command) {
                if mutations_for(&vuid).is_none() || MODEL_BUG_EXCLUDED.contains(&vuid.as_str()) {
                    continue;
                }
                let Some(cases) =
                    common::violating((&name, &profile), command, &vuid, n, 11, &mut report)
                else {
                    continue;
                };
                generated_any += 1;
                let common::Judged {
                    good,
                    exact,
                    example,
                } = common::judge_all(&profile, &cases, &vuid);
                let rate = good as f64 / cases.len() as f64;
                report.push(format!(
                    "{name} {vuid}: {good}/{} ({:.1}%), exact {exact}",
                    cases.len(),
                    rate * 100.0
                ));
                if rate < 0.95 {
                    failures.push(format!(
                        "{name} {vuid}: {:.1}%\n{}",
                        rate * 100.0,
                        example.unwrap_or_default()
                    ));
                }
            }
        }
    }
    println!("{}", report.join("\n"));
    assert!(generated_any > 50, "only {generated_any} VUIDs generated");
    assert!(failures.is_empty(), "{}", failures.join("\n\n"));
}

/// Executable VUIDs of the three commands that have no mutation yet. Update when adding mutations
/// or when the model makes new rows executable.
const NO_MUTATION_YET: &[&str] = &[];

#[test]
fn executable_vuids_without_a_mutation_match_the_committed_list() {
    let mut missing: BTreeSet<String> = BTreeSet::new();
    for command in CommandId::TRACE {
        for vuid in executable_vuids(common::rules(), command) {
            if mutations_for(&vuid).is_none() {
                missing.insert(vuid);
            }
        }
    }
    let expected: BTreeSet<String> = NO_MUTATION_YET.iter().map(|s| s.to_string()).collect();
    assert_eq!(
        missing, expected,
        "executable VUIDs without a mutation changed"
    );
}

#[test]
fn invalid_case_names_use_the_short_vuid_and_seed() {
    let (name, profile) = common::profiles()
        .into_iter()
        .find(|(n, _)| n == "lavapipe")
        .unwrap();
    let vuid = "VUID-vkCmdTraceRaysIndirectKHR-indirectDeviceAddress-03634";
    let cases = generate(
        &profile,
        &name,
        common::rules(),
        &CaseSpec::violate(CommandId::TraceRaysIndirect, vuid),
        2,
        5,
    )
    .unwrap();
    assert_eq!(
        cases[1].name,
        "vkCmdTraceRaysIndirectKHR-indirectDeviceAddress-03634-5-1"
    );
    assert_eq!(
        cases[0].intent,
        model::Intent::Violates {
            vuid: vuid.into(),
            also: vec![]
        }
    );
}

#[test]
fn boundary_values_come_first() {
    // Knob 0 is the boundary: the misaligned indirect address is exactly one byte past alignment.
    let (name, profile) = common::profiles()
        .into_iter()
        .find(|(n, _)| n == "lavapipe")
        .unwrap();
    let vuid = "VUID-vkCmdTraceRaysIndirectKHR-indirectDeviceAddress-03634";
    let cases = generate(
        &profile,
        &name,
        common::rules(),
        &CaseSpec::violate(CommandId::TraceRaysIndirect, vuid),
        100,
        9,
    )
    .unwrap();
    let one_off = cases
        .iter()
        .filter(|c| matches!(&c.as_trace().unwrap().call, model::Call::TraceRaysIndirect(x) if x.indirect_address.alignment_value() % 4 == 1))
        .count();
    assert!(one_off >= 50, "only {one_off} of 100 at alignment + 1");
}

#[test]
fn vuids_of_other_commands_are_refused() {
    let (name, profile) = common::profiles()
        .into_iter()
        .find(|(n, _)| n == "lavapipe")
        .unwrap();
    let err = generate(
        &profile,
        &name,
        common::rules(),
        &CaseSpec::violate(
            CommandId::TraceRays,
            "VUID-vkCmdTraceRaysIndirectKHR-indirectDeviceAddress-03634",
        ),
        1,
        1,
    )
    .unwrap_err();
    assert!(matches!(err, GenError::NotForCommand { .. }), "{err}");
}

/// The distinct pipeline descriptions among cases (as JSON).
fn distinct_pipelines(cases: &[model::Case]) -> BTreeSet<String> {
    cases
        .iter()
        .map(|c| {
            let p = &c.as_trace().expect("trace cases").world.pipeline;
            serde_json::to_string(p).expect("a pipeline serialises")
        })
        .collect()
}

#[test]
fn invalid_cases_share_canonical_pipelines_unless_their_mutation_edits_the_pipeline() {
    let (name, profile) = common::profiles()
        .into_iter()
        .find(|(n, _)| n == "lavapipe")
        .unwrap();
    let n = 64;
    let gen = |spec: &CaseSpec| generate(&profile, &name, common::rules(), spec, n, 5).unwrap();
    // A rule about the indirect buffer: its cases' pipelines come from the canonical set, and the
    // seed still picks more than one of them.
    let address = gen(&CaseSpec::violate(
        CommandId::TraceRaysIndirect,
        "VUID-vkCmdTraceRaysIndirectKHR-indirectDeviceAddress-03634",
    ));
    let shared = distinct_pipelines(&address);
    assert!(
        shared.len() > 1 && shared.len() <= generator::valid::CANONICAL_PIPELINES as usize,
        "{} distinct pipelines among {n} cases of 03634",
        shared.len()
    );
    // A rule about the pipeline's flags: its base is the drawn pipeline, so its pipelines vary more.
    let flags = gen(&CaseSpec::violate(
        CommandId::TraceRaysIndirect,
        "VUID-vkCmdTraceRaysIndirectKHR-flags-03513",
    ));
    assert!(
        distinct_pipelines(&flags).len() > generator::valid::CANONICAL_PIPELINES as usize,
        "the pipelines of 03513 are as varied as their draws"
    );
    // Valid cases keep their drawn pipelines.
    let valid = gen(&CaseSpec::valid(CommandId::TraceRaysIndirect));
    assert!(
        distinct_pipelines(&valid).len() > generator::valid::CANONICAL_PIPELINES as usize,
        "valid cases' pipelines are drawn"
    );
}
