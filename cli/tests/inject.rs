//! Seeded faults on the real lavapipe: `rtconf detect` on a small fixed set of rendered cases catches
//! every kind at a size well above its threshold and never catches size 0 (the case itself); `rtconf
//! run --inject` hands the driver the perturbed copy, judges the case and records the injection in
//! results.jsonl and summary.json; bad `--inject` and `--sizes` values are refused with exit 2.

mod common;

use common::rtconf;
use serde_json::Value;

/// Well above each kind's threshold (`session::inject::Kind::threshold`).
const WELL_ABOVE: [(&str, &str); 7] = [
    ("vertex-ulps", "1048576"),
    ("instance-transform", "0.05"),
    ("sbt-stride", "1"),
    ("sbt-offset", "1"),
    ("cull-mask", "1"),
    ("drop-primitive", "1"),
    ("t-bias", "0.05"),
];

#[test]
fn every_kind_well_above_threshold_is_caught_and_size_zero_never_is() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("detect");
    let kinds: Vec<&str> = WELL_ABOVE.iter().map(|(k, _)| *k).collect();
    let kinds = kinds.join(",");
    let mut args = vec!["detect", "--count", "8", "--seed", "1", "--kinds", &kinds];
    let sizes: Vec<String> = WELL_ABOVE.iter().map(|(k, s)| format!("{k}={s}")).collect();
    for s in &sizes {
        args.extend(["--sizes", s]);
    }
    let out_arg = out.display().to_string();
    args.extend(["--out", &out_arg]);
    let ran = rtconf(&args);
    assert_eq!(ran.code, 0, "{}", ran.all());
    assert!(
        ran.stdout.contains("mutation score: 100.0% of"),
        "{}",
        ran.all()
    );
    let d: Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("detection.json")).unwrap())
            .unwrap();
    let cells = d["cells"].as_array().unwrap();
    for (kind, size) in WELL_ABOVE {
        let size: f64 = size.parse().unwrap();
        let cell = |s: f64| {
            cells
                .iter()
                .find(|c| c["kind"] == kind && c["size"].as_f64() == Some(s))
                .unwrap_or_else(|| panic!("no {kind}:{s} row"))
        };
        let zero = cell(0.0);
        assert!(zero["applicable"].as_u64().unwrap() >= 1, "{kind}: {zero}");
        assert_eq!(zero["detected"], 0, "{kind} size 0 was caught: {zero}");
        let big = cell(size);
        let applicable = big["applicable"].as_u64().unwrap();
        assert!(applicable >= 1, "{kind}:{size} applied to no case: {big}");
        assert_eq!(
            big["detected"].as_u64(),
            Some(applicable),
            "{kind}:{size}: {big}"
        );
        assert_eq!(big["above_threshold"], true);
        assert_eq!(big["median_cases_to_first"].as_f64(), Some(1.0));
    }
    let md = std::fs::read_to_string(out.join("detection.md")).unwrap();
    assert!(
        md.contains("| kind | size | unit | cases applicable | detected | detection rate | median cases to first detection | median seconds to first detection |"),
        "{md}"
    );
    for png in ["detection.png", "detection-time.png"] {
        let bytes = std::fs::read(out.join(png)).unwrap();
        assert_eq!(&bytes[1..4], b"PNG", "{png}");
    }
    assert_eq!(
        std::fs::read_dir(out.join("cases")).unwrap().count(),
        8,
        "the cases it ran are kept"
    );
}

#[test]
fn run_with_inject_judges_the_case_and_records_the_injection() {
    let dir = tempfile::tempdir().unwrap();
    let cases = dir.path().join("cases");
    let made = rtconf(&[
        "detect",
        "--count",
        "4",
        "--kinds",
        "drop-primitive",
        "--out",
        &dir.path().join("d").display().to_string(),
    ]);
    assert!(made.code == 0 || made.code == 1, "{}", made.all());
    std::fs::rename(dir.path().join("d/cases"), &cases).unwrap();
    let out = dir.path().join("run");
    let ran = rtconf(&[
        "run",
        "--cases",
        &cases.display().to_string(),
        "--inject",
        "drop-primitive:1",
        "--out",
        &out.display().to_string(),
    ]);
    let summary: Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    let inject = &summary["inject"];
    assert_eq!(inject["injection"], "drop-primitive:1", "{summary}");
    let applied = inject["applied"].as_u64().unwrap();
    let detected = inject["detected"].as_u64().unwrap();
    assert!(applied >= 1, "{}", ran.all());
    assert_eq!(detected, applied, "{}", ran.all());
    assert_eq!(
        applied + inject["not_applicable"].as_u64().unwrap(),
        4,
        "{summary}"
    );
    // A caught fault fails the run, as any failing case does.
    assert_eq!(ran.code, 1, "{}", ran.all());
    assert!(
        ran.stdout.contains(&format!(
            "inject drop-primitive:1: {applied} cases ran the perturbed copy, {detected} detected"
        )),
        "{}",
        ran.all()
    );
    let run_json = std::fs::read_to_string(out.join("run.json")).unwrap();
    assert!(
        run_json.contains("\"inject\": \"drop-primitive:1\""),
        "{run_json}"
    );
    let lines = std::fs::read_to_string(out.join("results.jsonl")).unwrap();
    let mut kept = 0;
    for l in lines.lines() {
        let v: Value = serde_json::from_str(l).unwrap();
        let i = &v["injection"];
        assert_eq!(i["injection"], "drop-primitive:1", "{l}");
        if i["applied"] == true {
            assert_eq!(v["outcome"], "fail", "{l}");
            assert!(
                i["detail"].as_str().unwrap().contains("degenerate")
                    || i["detail"].as_str().unwrap().contains("inactive"),
                "{l}"
            );
            // The failing case kept is the case as judged, not the copy the driver ran.
            let name = v["case"].as_str().unwrap();
            let kept_case =
                std::fs::read_to_string(out.join(format!("failures/{name}.yaml"))).unwrap();
            let original = std::fs::read_to_string(cases.join(format!("{name}.yaml"))).unwrap();
            assert_eq!(kept_case, original, "{name}");
            kept += 1;
        } else {
            assert!(
                i["detail"]
                    .as_str()
                    .unwrap()
                    .starts_with("not applicable: "),
                "{l}"
            );
        }
    }
    assert_eq!(kept, applied);
    // Resuming without --inject is refused: it would mix two runs.
    let again = rtconf(&[
        "run",
        "--cases",
        &cases.display().to_string(),
        "--resume",
        "--out",
        &out.display().to_string(),
    ]);
    assert_eq!(again.code, 2, "{}", again.all());
    assert!(again.stderr.contains("--inject"), "{}", again.all());
}

#[test]
fn bad_inject_and_sizes_values_are_refused_with_exit_2() {
    for (value, says) in [
        ("vertex-ulps", "is not KIND:SIZE"),
        ("vertex-moves:4", "unknown injection kind `vertex-moves`"),
        ("vertex-ulps:1.5", "is not a whole number of ULPs"),
        ("vertex-ulps:-3", "is not a whole number of ULPs"),
        ("cull-mask:9", "larger than 8 bits"),
        ("t-bias:2", "not a relative size between 0 and 1"),
        (
            "instance-transform:nan",
            "not a relative size between 0 and 1",
        ),
        ("t-bias:", "not a relative size between 0 and 1"),
    ] {
        let ran = rtconf(&["run", "--inject", value, "--out", "/nonexistent/never"]);
        assert_eq!(ran.code, 2, "--inject {value}: {}", ran.all());
        assert!(ran.stderr.contains(says), "--inject {value}: {}", ran.all());
        assert!(!ran.stderr.contains("panicked"), "{}", ran.all());
    }
    let ran = rtconf(&[
        "run",
        "--inject",
        "cull-mask:1",
        "--shrink",
        "1",
        "--out",
        "/nonexistent/never",
    ]);
    assert_eq!(ran.code, 2, "{}", ran.all());
    assert!(
        ran.stderr.contains("--shrink with --inject"),
        "{}",
        ran.all()
    );
    for (args, says) in [
        (vec!["--kinds", "t-bais"], "unknown injection kind `t-bais`"),
        (
            vec!["--kinds", "cull-mask", "--sizes", "t-bias=0.1"],
            "t-bias is not among --kinds",
        ),
        (
            vec!["--kinds", "cull-mask", "--sizes", "x"],
            "is not a whole number of bits",
        ),
    ] {
        let mut all = vec!["detect", "--out", "/nonexistent/never"];
        all.extend(args.iter().copied());
        let ran = rtconf(&all);
        assert_eq!(ran.code, 2, "{args:?}: {}", ran.all());
        assert!(ran.stderr.contains(says), "{args:?}: {}", ran.all());
    }
}
