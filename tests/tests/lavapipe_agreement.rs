//! vkCmdTraceRaysIndirectKHR on the real lavapipe under the real validation layer: for every executable
//! VUID with a mutation, generated invalid cases are recorded (never submitted) and the layer's verdict
//! must agree with the model's or match the triage file; valid cases are submitted and their read-back
//! output must equal the model's expected launch.

use generator::CaseSpec;
use model::CommandId;
use rtconf_tests::Lavapipe;
use session::{CaseReport, Outcome};
use std::collections::BTreeMap;

const COMMAND: CommandId = CommandId::TraceRaysIndirect;

#[test]
fn the_layer_agrees_with_the_model_on_every_executable_vuid_or_the_triage_says_why() {
    let mut lvp = Lavapipe::new();
    let rows: Vec<String> = lvp
        .rules
        .rows
        .iter()
        .filter(|r| {
            r.status == model::rules::Status::Executable
                && model::rules::applies_to(&r.scope, COMMAND)
        })
        .map(|r| r.vuid.clone())
        .collect();
    let mut outcomes: BTreeMap<String, Vec<Outcome>> = BTreeMap::new();
    let mut failures = Vec::new();
    for vuid in &rows {
        let spec = CaseSpec::violate(COMMAND, vuid);
        let cases = match lvp.generate(&spec, 3, 11) {
            Ok(c) => c,
            Err(generator::GenError::Unsupported(why)) => {
                outcomes
                    .entry(vuid.clone())
                    .or_default()
                    .push(Outcome::Unsupported);
                eprintln!("{vuid}: not expressible on lavapipe: {why}");
                continue;
            }
            Err(e) => panic!("{vuid}: {e}"),
        };
        for r in cases.iter().map(|c| lvp.run(c)) {
            if matches!(r.outcome, Outcome::Fail | Outcome::Crash | Outcome::Timeout) {
                failures.push(format!("{}: {:?} {}", r.case, r.outcome, r.detail));
            }
            outcomes.entry(vuid.clone()).or_default().push(r.outcome);
        }
    }
    assert!(
        failures.is_empty(),
        "disagreements not in the triage file:\n{}",
        failures.join("\n")
    );
    let agreed = outcomes
        .values()
        .filter(|o| o.contains(&Outcome::Pass))
        .count();
    let exercised = outcomes
        .values()
        .filter(|o| o.iter().any(|x| *x != Outcome::Unsupported))
        .count();
    // Most rules the layer checks agree outright; the rest are written down in triage/.
    assert!(
        exercised >= 35,
        "only {exercised} VUIDs exercised: {outcomes:?}"
    );
    assert!(
        agreed >= 15,
        "only {agreed} VUIDs agreed outright: {outcomes:?}"
    );
}

#[test]
fn valid_launches_write_what_the_model_expects_and_the_layer_stays_silent() {
    let mut lvp = Lavapipe::new();
    let cases = lvp
        .generate(&CaseSpec::valid(COMMAND), 40, 3)
        .expect("valid cases");
    let reports: Vec<CaseReport> = cases.iter().map(|c| lvp.run(c)).collect();
    let bad: Vec<String> = reports
        .iter()
        .filter(|r| !matches!(r.outcome, Outcome::Pass | Outcome::Triaged))
        .map(|r| format!("{}: {:?} {}", r.case, r.outcome, r.detail))
        .collect();
    assert!(bad.is_empty(), "{}", bad.join("\n"));
    let read_back = reports
        .iter()
        .filter(|r| r.output_matches == Some(true))
        .count();
    assert!(
        read_back >= 30,
        "only {read_back} of 40 valid cases compared their output"
    );
}
