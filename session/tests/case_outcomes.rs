//! `case-error`: where the case, not the driver, is at fault, the comparison says so — a valid case
//! the model judges invalid, an invalid case whose target the model does not report, buffers the
//! driver had no memory for within the profile's limits — and never `fail` or `crash`.

use harness::observe::{Observation, Status};
use model::{Case, DeviceProfile, RuleSet};
use session::{compare, Outcome, Triage};

mod common;

fn root() -> std::path::PathBuf {
    std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn setup() -> (RuleSet, DeviceProfile, Triage) {
    let set = session::sources::load_sources(&[]).unwrap();
    let profile = session::sources::profile_for("lavapipe").unwrap();
    let triage = Triage::default();
    (RuleSet::from_vuids(&set), profile, triage)
}

fn hand_text() -> String {
    std::fs::read_to_string(root().join("cases/hand/trace-indirect-records-32.yaml")).unwrap()
}

fn hand_case() -> Case {
    Case::from_yaml("hand", &hand_text()).unwrap()
}

/// What lavapipe wrote for the hand case run as valid (its records pass the comparison: the first
/// test checks that). Cases changed from the hand case keep its launch, so its records stand in for
/// theirs where the comparison stops before the output.
fn ran_on_lavapipe(case: &Case) -> Observation {
    let _one = common::DEVICE.lock().unwrap_or_else(|e| e.into_inner());
    let mut lvp = common::Lavapipe::new();
    let ran = lvp.run(case, harness::TraceCheck::Auto);
    let mut obs = ran.observation.expect("the hand case is runnable");
    assert!(obs.words().is_some(), "records were read back");
    obs.layer_messages.clear();
    obs.layer_vuids.clear();
    obs
}

#[test]
fn the_hand_case_passes_on_the_records_lavapipe_writes() {
    let (rules, profile, triage) = setup();
    let case = hand_case();
    let verdict = rules.judge(&profile, &case.body);
    let r = compare(
        &case,
        &profile,
        &verdict,
        &ran_on_lavapipe(&case),
        &triage,
        1.0,
    );
    assert_eq!(r.outcome, Outcome::Pass, "{r:?}");
}

#[test]
fn a_valid_case_the_model_judges_invalid_is_an_error_of_the_case_not_a_failure() {
    let (rules, profile, triage) = setup();
    // The miss stride is no longer a multiple of the handle alignment.
    let from = "miss: { address: { buffer: sbt, offset: 64 }, stride: 32, size: 64 }";
    assert!(hand_text().contains(from));
    let yaml = hand_text().replacen(from, &from.replace("stride: 32", "stride: 33"), 1);
    let case = Case::from_yaml("mutated", &yaml).unwrap();
    let verdict = rules.judge(&profile, &case.body);
    assert!(!verdict.is_valid());
    let r = compare(
        &case,
        &profile,
        &verdict,
        &ran_on_lavapipe(&hand_case()),
        &triage,
        1.0,
    );
    assert_eq!(r.outcome, Outcome::CaseError, "{r:?}");
    assert!(r.detail.starts_with("intent: "), "{}", r.detail);
    assert!(r.outcome.is_unexpected());
}

#[test]
fn an_invalid_case_whose_target_the_model_does_not_report_is_an_error_of_the_case() {
    let (rules, profile, triage) = setup();
    let mut case = hand_case();
    case.intent = model::Intent::Violates {
        vuid: "VUID-vkCmdTraceRaysIndirectKHR-stride-03686".into(),
        also: vec![],
    };
    let verdict = rules.judge(&profile, &case.body);
    let r = compare(
        &case,
        &profile,
        &verdict,
        &Observation::with_status(Status::Ran),
        &triage,
        1.0,
    );
    assert_eq!(r.outcome, Outcome::CaseError, "{r:?}");
    assert!(
        r.detail.contains("does not report the target"),
        "{}",
        r.detail
    );
}

#[test]
fn a_driver_out_of_memory_within_the_profile_s_limits_is_an_error_of_the_case_not_a_crash() {
    let (rules, profile, triage) = setup();
    let case = hand_case();
    let verdict = rules.judge(&profile, &case.body);
    let obs = Observation::with_status(Status::OutOfMemory {
        message: "vkAllocateMemory(2147483648): ERROR_OUT_OF_DEVICE_MEMORY".into(),
    });
    let r = compare(&case, &profile, &verdict, &obs, &triage, 1.0);
    assert_eq!(r.outcome, Outcome::CaseError, "{r:?}");
    assert!(
        r.detail.contains("ERROR_OUT_OF_DEVICE_MEMORY"),
        "{}",
        r.detail
    );
}

#[test]
fn case_error_is_written_and_read_as_case_error() {
    assert_eq!(
        serde_json::to_string(&Outcome::CaseError).unwrap(),
        "\"case-error\""
    );
}
