//! The committed resource cases under `cases/resources/` (one valid case with a full resource state,
//! one invalid case per resource rule lavapipe can express) judge as their intent declares.
//! `RTCONF_WRITE_RESOURCE_CASES=1` regenerates them from fixed seeds.

mod common;

use generator::resources::mutation_for;
use generator::{executable_vuids, generate, CaseSpec};
use model::CommandId;
use std::collections::BTreeSet;

fn dir() -> std::path::PathBuf {
    generator::profiles::repo_root()
        .join("cases")
        .join("resources")
}

fn write_cases() {
    let (name, profile) = common::profiles()
        .into_iter()
        .find(|(n, _)| n == "lavapipe")
        .unwrap();
    std::fs::create_dir_all(dir()).unwrap();
    let mut valid = generate(
        &profile,
        &name,
        common::rules(),
        &CaseSpec::valid(CommandId::TraceRaysIndirect),
        1,
        4,
    )
    .unwrap()
    .remove(0);
    valid.as_trace_mut().unwrap().world.resources =
        generator::resources::valid_state(&profile, 3, 0x1ff);
    valid.name = "trace-indirect-valid-resources".into();
    std::fs::write(dir().join(format!("{}.yaml", valid.name)), valid.to_yaml()).unwrap();
    for vuid in executable_vuids(common::rules(), CommandId::TraceRaysIndirect) {
        if mutation_for(&vuid).is_none() {
            continue;
        }
        if let Ok(mut c) = generate(
            &profile,
            &name,
            common::rules(),
            &CaseSpec::violate(CommandId::TraceRaysIndirect, &vuid),
            1,
            4,
        ) {
            let c = c.remove(0);
            std::fs::write(dir().join(format!("{}.yaml", c.name)), c.to_yaml()).unwrap();
        }
    }
}

#[test]
fn resource_cases_judge_as_declared() {
    if std::env::var("RTCONF_WRITE_RESOURCE_CASES").is_ok_and(|v| v == "1") {
        write_cases();
    }
    let profiles = common::profiles();
    let mut n = 0;
    let mut valid = 0;
    for e in std::fs::read_dir(dir()).expect("cases/resources") {
        let path = e.unwrap().path();
        let text = std::fs::read_to_string(&path).unwrap();
        let case = model::Case::from_yaml(&path.display().to_string(), &text).unwrap();
        let profile = &profiles.iter().find(|(n, _)| *n == case.profile).unwrap().1;
        let got: BTreeSet<String> = common::judge(profile, &case)
            .vuids()
            .into_iter()
            .map(String::from)
            .collect();
        let expected: BTreeSet<String> = case.expected_vuids().into_iter().collect();
        match &case.intent {
            model::Intent::Valid => {
                assert!(got.is_empty(), "{}: {got:?}", path.display());
                assert!(
                    !case.as_trace().unwrap().world.resources.is_empty(),
                    "{}: a resource case has resources",
                    path.display()
                );
                valid += 1;
            }
            model::Intent::Violates { vuid, .. } => {
                assert!(
                    got.contains(vuid) && got.is_subset(&expected),
                    "{}: {got:?} vs {expected:?}",
                    path.display()
                );
            }
        }
        n += 1;
    }
    assert!(valid >= 1 && n >= 20, "{n} cases, {valid} valid");
}
