//! The run's verdicts come from rule tables prepared once per command and enabled extensions
//! (`Judging::verdict`); each must be the verdict a fresh preparation gives
//! (`RuleSet::judge`), whatever order the cases come in.

use generator::CaseSpec;
use model::rules::{RuleSet, Status};
use model::CommandId;
use session::run::Judging;

#[test]
fn a_kept_preparation_judges_as_a_fresh_one() {
    let set = session::sources::load_sources(&[]).expect("the installed registry");
    let rules = RuleSet::from_vuids(&set);
    let profile = session::sources::profile_for("lavapipe").expect("the lavapipe profile");
    let triage = session::triage::Triage::default();
    let mut cases = Vec::new();
    for command in CommandId::ALL {
        let mut specs = vec![CaseSpec::valid(command)];
        let vuids: Vec<&str> = rules
            .rows
            .iter()
            .filter(|r| r.status == Status::Executable && r.scope == command.vk_name())
            .map(|r| r.vuid.as_str())
            .collect();
        specs.extend(
            vuids
                .iter()
                .step_by(7)
                .map(|v| CaseSpec::violate(command, v)),
        );
        for (i, spec) in specs.iter().enumerate() {
            if let Ok(mut drawn) =
                generator::generate(&profile, "lavapipe", &rules, spec, 2, i as u64)
            {
                cases.append(&mut drawn);
            }
        }
    }
    let judging = Judging::new(&rules, &profile, &triage);
    let (mut valid, mut invalid) = (0, 0);
    // Twice, the second time backwards: every case meets both a fresh and a kept preparation.
    for case in cases.iter().chain(cases.iter().rev()) {
        let want = rules.judge(&profile, &case.body);
        assert_eq!(judging.verdict(&case.body), want, "{}", case.name);
        if want.is_valid() {
            valid += 1;
        } else {
            invalid += 1;
        }
    }
    let commands: std::collections::BTreeSet<CommandId> =
        cases.iter().map(|c| c.body.command()).collect();
    assert!(commands.len() >= 3, "cases of {commands:?}");
    assert!(valid > 0 && invalid > 0, "{valid} valid, {invalid} invalid");
}
