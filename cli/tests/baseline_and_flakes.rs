//! `rtconf run --cases DIR` on lavapipe judged against a baseline, skips and flakes, deqp-runner style:
//! a case made to crash and pass by turns is reported as a flake after a retry, an expected crash is an
//! expected failure, a passing case the baseline expects to fail is an unexpected pass; the statuses
//! reach results.jsonl, summary.json, junit.xml and the console, and only failures go to `failures/`.

#[path = "common/folders.rs"]
mod common;

use common::{case_as, fresh_dir, results, rtconf, summary, text};

#[test]
fn statuses_against_the_baseline_reach_every_output() {
    let dir = fresh_dir("baseline-and-flakes");
    let cases = dir.join("cases");
    std::fs::create_dir_all(&cases).unwrap();
    let valid = "hand/trace-indirect-records-32.yaml";
    case_as(valid, "hand-made-valid", &cases);
    case_as(valid, "fault-flaky-valid", &cases);
    case_as(valid, "fault-abort-valid", &cases);
    case_as(
        "hand/trace-indirect-basic.yaml",
        "basic-expected-to-fail",
        &cases,
    );
    case_as(
        "hand/trace-indirect-miss-stride-unaligned.yaml",
        "skipped-stride",
        &cases,
    );
    // A case the layer cannot check (triaged as a layer gap).
    let gen = rtconf(
        &[
            "gen",
            "--vuid",
            "VUID-vkCmdTraceRaysIndirectKHR-None-02702",
            "--count",
            "1",
            "--out",
            cases.to_str().unwrap(),
        ],
        &[],
    );
    assert!(gen.status.success(), "{}", text(&gen));
    let baseline = dir.join("baseline.txt");
    std::fs::write(
        &baseline,
        "# lavapipe's expected failures\nbasic-expected-to-fail,fail\nfault-abort-*,crash\n",
    )
    .unwrap();
    let skips = dir.join("skips.txt");
    std::fs::write(&skips, "^skipped-\n").unwrap();
    let run = dir.join("run");
    let out = rtconf(
        &[
            "run",
            "--cases",
            cases.to_str().unwrap(),
            "--baseline",
            baseline.to_str().unwrap(),
            "--skips",
            skips.to_str().unwrap(),
            "--retries",
            "2",
            "--timeout",
            "30",
            "--out",
            run.to_str().unwrap(),
        ],
        &[(harness::worker::FAULTS_ENV, "1")],
    );
    // The unexpected pass fails the run.
    assert_eq!(out.status.code(), Some(1), "{}", text(&out));
    let r = results(&run);
    let status = |c: &str| r[c]["status"].as_str().unwrap_or("?").to_string();
    let outcome = |c: &str| r[c]["outcome"].as_str().unwrap_or("?").to_string();
    let triaged = "vkCmdTraceRaysIndirectKHR-None-02702-1-0";
    assert_eq!(status("hand-made-valid"), "pass");
    assert_eq!(status("fault-flaky-valid"), "flake");
    assert_eq!(
        outcome("fault-flaky-valid"),
        "crash",
        "the raw outcome is the first attempt's"
    );
    assert_eq!(
        r["fault-flaky-valid"]["attempts"],
        serde_json::json!(["crash", "pass"])
    );
    assert_eq!(status("fault-abort-valid"), "expected-fail");
    assert_eq!(
        r["fault-abort-valid"]["attempts"],
        serde_json::json!(["crash", "crash", "crash"])
    );
    assert_eq!(status("basic-expected-to-fail"), "unexpected-pass");
    assert_eq!(outcome("basic-expected-to-fail"), "pass");
    assert_eq!(status(triaged), "triaged");
    assert_eq!(r[triaged]["triage"][0]["kind"], "layer-gap");
    assert!(
        !r.contains_key("skipped-stride"),
        "skipped cases do not run"
    );
    assert_eq!(r.len(), 5);

    let s = summary(&run);
    let st = &s["statuses"];
    for (name, n) in [
        ("pass", 1),
        ("flake", 1),
        ("expected-fail", 1),
        ("unexpected-pass", 1),
        ("triaged", 1),
        ("fail", 0),
        ("missing", 0),
    ] {
        assert_eq!(st[name], n, "{name} in {st}");
    }
    assert_eq!(s["skipped"], 1);
    assert_eq!(s["crashes"], 2, "raw outcomes are kept apart: {s}");
    assert_eq!(s["retries"], 3);

    // The JUnit report: the triaged case carries its triage, the flake its attempts, the unexpected pass
    // is a failure; the expected failure and the flake pass.
    let junit = std::fs::read_to_string(run.join("junit.xml")).unwrap();
    let case_xml = |name: &str| -> String {
        let start = junit
            .find(&format!("<testcase name=\"{name}\""))
            .unwrap_or_else(|| panic!("{name} in {junit}"));
        let rest = &junit[start..];
        let end = rest
            .find("</testcase>")
            .map_or(rest.find("/>").unwrap() + 2, |e| e + 11);
        rest[..end].to_string()
    };
    let t = case_xml(triaged);
    assert!(
        t.contains("<property name=\"triage.kind\" value=\"layer-gap\"/>"),
        "{t}"
    );
    assert!(t.contains("<property name=\"triage.reason\" value=\"the view-type check of an unnormalized-coordinate sampler"), "{t}");
    assert!(
        t.contains(
            "<system-out>triaged layer-gap: VUID-vkCmdTraceRaysIndirectKHR-None-02702 (model only)"
        ),
        "{t}"
    );
    assert!(!t.contains("<failure"), "{t}");
    let f = case_xml("fault-flaky-valid");
    assert!(f.contains("<system-out>flake: attempts crash, pass"), "{f}");
    assert!(!f.contains("<failure") && !f.contains("<error"), "{f}");
    let u = case_xml("basic-expected-to-fail");
    assert!(u.contains("<failure type=\"unexpected-pass\""), "{u}");
    let e = case_xml("fault-abort-valid");
    assert!(e.contains("<system-out>expected failure (crash)"), "{e}");
    assert!(
        junit.contains("tests=\"5\" failures=\"1\" errors=\"0\""),
        "{junit}"
    );

    // failures/ holds failures only; triaged cases have their own folder.
    let names = |folder: &str| -> Vec<String> {
        let mut v: Vec<String> = std::fs::read_dir(run.join(folder))
            .map(|d| {
                d.flatten()
                    .map(|e| e.file_name().to_string_lossy().into_owned())
                    .collect()
            })
            .unwrap_or_default();
        v.sort();
        v
    };
    assert_eq!(
        names("failures"),
        vec!["fault-abort-valid.yaml", "fault-flaky-valid.yaml"]
    );
    // A triaged case's outcome is explained: its details are kept, its case file only with
    // --keep-all.
    assert!(names("triaged").is_empty(), "{:?}", names("triaged"));
    let details = std::fs::read_to_string(run.join("details.jsonl")).unwrap();
    assert!(
        details.contains(&format!("\"case\":\"{triaged}\"")),
        "{details}"
    );
    assert_eq!(
        names("unexpected-passes"),
        vec!["basic-expected-to-fail.yaml"]
    );

    // The console lists what fails the run and ends with the summary.
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        stdout.contains("unexpected-pass basic-expected-to-fail"),
        "{stdout}"
    );
    let last: Vec<&str> = stdout.lines().rev().take(6).collect();
    assert!(
        last[0].starts_with("verdict: 1 unexpected result"),
        "{stdout}"
    );
    assert!(
        stdout.contains(
            "status:  1 pass, 1 triaged, 0 fail, 1 expected-fail, 1 unexpected-pass, 1 flake"
        ),
        "{stdout}"
    );
    assert!(
        !stdout.contains("VUID                "),
        "the per-VUID table only with --verbose: {stdout}"
    );
}

#[test]
fn a_failing_case_on_the_flakes_list_is_a_flake_and_bad_files_name_their_line() {
    let dir = fresh_dir("flakes-list");
    let cases = dir.join("cases");
    std::fs::create_dir_all(&cases).unwrap();
    case_as(
        "hand/trace-indirect-records-32.yaml",
        "fault-abort-listed",
        &cases,
    );
    let flakes = dir.join("flakes.txt");
    std::fs::write(&flakes, "# known flaky\n^fault-abort-\n").unwrap();
    let run = dir.join("run");
    let args = |flakes: &str| -> Vec<String> {
        [
            "run",
            "--cases",
            cases.to_str().unwrap(),
            "--flakes",
            flakes,
            "--out",
            run.to_str().unwrap(),
        ]
        .map(String::from)
        .to_vec()
    };
    let a = args(flakes.to_str().unwrap());
    let out = rtconf(
        &a.iter().map(String::as_str).collect::<Vec<_>>(),
        &[(harness::worker::FAULTS_ENV, "1")],
    );
    assert_eq!(out.status.code(), Some(0), "{}", text(&out));
    assert_eq!(results(&run)["fault-abort-listed"]["status"], "flake");

    let bad = dir.join("bad-baseline.txt");
    std::fs::write(&bad, "ok-case,fail\nno status here\n").unwrap();
    let out = rtconf(
        &[
            "run",
            "--cases",
            cases.to_str().unwrap(),
            "--baseline",
            bad.to_str().unwrap(),
            "--out",
            run.to_str().unwrap(),
        ],
        &[],
    );
    assert_eq!(out.status.code(), Some(2), "{}", text(&out));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains(&format!(
            "{}:2: expected `CASE-OR-VUID,STATUS`",
            bad.display()
        )),
        "{err}"
    );
}
