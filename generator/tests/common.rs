//! Shared set-up for the generator's meta-tests: the rule table, the committed profiles, case counts.

#![allow(dead_code)]

use model::rules::RuleSet;
use model::{Case, DeviceProfile};
use std::sync::OnceLock;

pub fn rules() -> &'static RuleSet {
    static RULES: OnceLock<RuleSet> = OnceLock::new();
    RULES
        .get_or_init(|| generator::registry::default_rules().expect("the installed registry loads"))
}

/// Every committed profile (at least lavapipe).
pub fn profiles() -> Vec<(String, DeviceProfile)> {
    let names = generator::profiles::available();
    assert!(
        names.iter().any(|n| n == "lavapipe"),
        "profiles/lavapipe.json is committed: {names:?}"
    );
    names
        .into_iter()
        .map(|n| {
            (
                n.clone(),
                generator::profiles::load(&n).expect("committed profiles load"),
            )
        })
        .collect()
}

/// Cases per spec: ~200 in CI, thousands with RTCONF_SLOW=1.
pub fn per_spec() -> usize {
    if std::env::var("RTCONF_SLOW").is_ok_and(|v| v == "1") {
        3000
    } else {
        200
    }
}

/// The model's verdict on a generated case, which must first be a case: no name resolving to nothing,
/// no group the pipeline lacks (`model::integrity`), since `rtconf run` refuses such a case unjudged.
pub fn judge(profile: &DeviceProfile, case: &Case) -> model::Verdict {
    let flaws = model::integrity::flaws(case);
    assert!(
        flaws.is_empty(),
        "{} has errors of its own: {flaws:?}\n{}",
        case.name,
        case.to_yaml()
    );
    model::validate(rules(), profile, case)
}

/// The cases of `command` violating `vuid` on a profile; None, with a line in `report`, when the profile
/// cannot express them.
pub fn violating(
    (name, profile): (&str, &DeviceProfile),
    command: model::CommandId,
    vuid: &str,
    count: usize,
    seed: u64,
    report: &mut Vec<String>,
) -> Option<Vec<Case>> {
    let spec = generator::CaseSpec::violate(command, vuid);
    match generator::generate(profile, name, rules(), &spec, count, seed) {
        Ok(c) => Some(c),
        Err(generator::GenError::Unsupported(why)) => {
            report.push(format!("{name} {vuid}: unsupported ({why})"));
            None
        }
        Err(e) => panic!("{name} {vuid}: {e}"),
    }
}

/// How a spec's cases judge against their target.
pub struct Judged {
    /// Cases whose verdict holds the target and nothing undeclared.
    pub good: usize,
    /// Cases whose verdict is exactly what they declare.
    pub exact: usize,
    /// The first case that is not good, with its verdict, ready to read.
    pub example: Option<String>,
}

pub fn judge_all(profile: &DeviceProfile, cases: &[Case], vuid: &str) -> Judged {
    use std::collections::BTreeSet;
    let mut j = Judged {
        good: 0,
        exact: 0,
        example: None,
    };
    for case in cases {
        let v = judge(profile, case);
        let expected: BTreeSet<String> = case.expected_vuids().into_iter().collect();
        let got: BTreeSet<String> = v.vuids().into_iter().map(String::from).collect();
        if got.contains(vuid) && got.is_subset(&expected) {
            j.good += 1;
            j.exact += (got == expected) as usize;
        } else if j.example.is_none() {
            j.example = Some(format!(
                "{}\nverdict: {:?}\nexpected: {expected:?}\n{}",
                case.name,
                v.violations,
                case.to_yaml()
            ));
        }
    }
    j
}

/// The model's VUIDs for a case, sorted and unique.
pub fn verdict_vuids(profile: &DeviceProfile, case: &Case) -> Vec<String> {
    judge(profile, case)
        .vuids()
        .into_iter()
        .map(String::from)
        .collect()
}
