//! `rtconf run --strict` on lavapipe: the whole default run uses every entry of the committed triage
//! files (none stale, exit 0), an entry that explains nothing is listed as stale and fails the strict
//! run, and a partial run refuses --strict (it cannot call an entry stale).

mod common;
use common::*;

fn summary(out: &std::path::Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap()
}

#[test]
fn the_whole_default_run_has_no_stale_entry_and_a_stale_one_fails_it() {
    let out = tempfile::tempdir().unwrap();
    let o = out.path().display().to_string();
    let r = rtconf(&["run", "--strict", "--out", &o]);
    assert_eq!(r.code, 0, "{}", r.all());
    let s = summary(out.path());
    assert_eq!(s["triage"]["stale_judged"], true, "{s}");
    assert_eq!(s["triage"]["stale"], serde_json::json!([]), "{}", r.all());
    assert!(
        s["failed"] == 0 && s["triaged"].as_u64().unwrap() > 100,
        "{s}"
    );
    assert!(r.stdout.contains("none stale"), "{}", r.all());

    // The same run with an extra file whose one entry names a VUID no case disagrees on.
    let dir = tempfile::tempdir().unwrap();
    let extra = dir.path().join("extra.yaml");
    std::fs::write(
        &extra,
        "entries:\n  - layer-silent: VUID-vkCmdTraceRaysKHR-stride-04041\n    kind: layer-gap\n    reason: never seen\n    evidence: a made-up entry of this test\n",
    )
    .unwrap();
    let e = extra.display().to_string();
    let out2 = tempfile::tempdir().unwrap();
    let o2 = out2.path().display().to_string();
    let layer = root()
        .join("triage/layer-1.3.239.yaml")
        .display()
        .to_string();
    let driver = root().join("triage/lavapipe.yaml").display().to_string();
    let r = rtconf(&[
        "run", "--strict", "--out", &o2, "--triage", &layer, "--triage", &driver, "--triage", &e,
    ]);
    assert_eq!(r.code, 1, "{}", r.all());
    let s = summary(out2.path());
    assert_eq!(
        s["triage"]["stale"],
        serde_json::json!(["extra.yaml: layer-silent VUID-vkCmdTraceRaysKHR-stride-04041"]),
        "{s}"
    );
    assert!(
        r.stdout.contains("STALE (an error under --strict)"),
        "{}",
        r.all()
    );
}

#[test]
fn a_partial_run_refuses_strict() {
    let out = tempfile::tempdir().unwrap();
    let o = out.path().display().to_string();
    let r = rtconf(&["run", "--strict", "--vuid", "03686", "--out", &o]);
    assert_eq!(r.code, 2, "{}", r.all());
    assert!(r.stderr.contains("--strict"), "{}", r.all());
}
