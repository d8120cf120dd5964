//! A driver crash is triaged only by a `crash` entry naming the shape the model gives the case
//! (`model::semantics::shapes`): the NVIDIA H200's DEVICE_LOST cases under triage/nvidia.yaml become
//! `triaged`, lost device or hang alike, while their controls, which lack the shape, stay crashes, and
//! so does every case without the entry.

use harness::observe::{Observation, Status};
use model::{Case, RuleSet};
use session::{compare, Outcome, Triage};

fn device_lost_case(name: &str) -> Case {
    let path = session::sources::repo_dir()
        .join("cases/nvidia-h200/device-lost")
        .join(format!("{name}.yaml"));
    session::replay::read_case(&path).unwrap_or_else(|e| panic!("{name}: {e}"))
}

fn nvidia_triage() -> Triage {
    let path = session::sources::repo_dir().join("triage/nvidia.yaml");
    let text = std::fs::read_to_string(&path).expect("triage/nvidia.yaml");
    Triage::from_yaml(&path.display().to_string(), &text).expect("the file parses")
}

/// The rules of the installed registry, read once per test.
fn rules() -> RuleSet {
    RuleSet::from_vuids(&session::sources::load_sources(&[]).expect("the installed registry"))
}

/// The comparison of `case` crashed (or hung) under `triage`.
fn judged(rules: &RuleSet, case: &Case, status: Status, triage: &Triage) -> session::CaseReport {
    let profile = session::sources::profile_for(&case.profile).expect("the case's profile");
    let verdict = rules.judge(&profile, &case.body);
    assert!(verdict.is_valid(), "{}: a valid case", case.name);
    let mut obs = Observation::crash("vkWaitForFences failed: ERROR_DEVICE_LOST");
    obs.status = status;
    compare(case, &profile, &verdict, &obs, triage, 1.0)
}

fn lost() -> Status {
    Status::Crash {
        message: "vkWaitForFences failed: ERROR_DEVICE_LOST".into(),
    }
}

#[test]
fn a_crash_of_the_culled_aabb_shape_is_triaged_and_its_controls_are_not() {
    let triage = nvidia_triage();
    let rules = rules();
    for name in [
        "device-lost-a-one-aabb-cull-opaque-null-hit",
        "device-lost-d-cull-no-opaque",
        "trace-nv-rendered-5465-24",
        "trace-indirect-rendered-8891-80",
    ] {
        let case = device_lost_case(name);
        for status in [lost(), Status::Timeout { seconds: 20.0 }] {
            let r = judged(&rules, &case, status, &triage);
            assert_eq!(r.outcome, Outcome::Triaged, "{name}: {}", r.detail);
            assert_eq!(r.triage.len(), 1, "{name}: {:?}", r.triage);
            let m = &r.triage[0];
            assert_eq!(
                (m.observed.as_str(), m.kind.name()),
                ("crash", "driver-bug"),
                "{name}"
            );
            assert_eq!(
                m.vuid,
                format!("{}:culled-aabb-null-hit-table", case.command().vk_name()),
                "{name}"
            );
        }
        // Without the entry it is a crash again.
        let r = judged(&rules, &case, lost(), &Triage::default());
        assert_eq!(r.outcome, Outcome::Crash, "{name}: {}", r.detail);
    }
    for name in [
        "device-lost-b-control-hit-region-set",
        "device-lost-g-one-triangle-cull-opaque",
    ] {
        let r = judged(&rules, &device_lost_case(name), lost(), &triage);
        assert_eq!(r.outcome, Outcome::Crash, "{name}: {}", r.detail);
        assert!(r.triage.is_empty(), "{name}: {:?}", r.triage);
    }
}
