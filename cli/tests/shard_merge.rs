//! Sharding for CI farms on lavapipe: `rtconf run --shard 1/3`, `2/3` and `3/3` of a generated run,
//! then `rtconf merge`, equal the unsharded run case for case (outcome, status, VUIDs, output, detail),
//! with the same totals, a case list that is the union of the shards', and the merged JUnit and report;
//! a shard left out shows as missing cases, and a torn results line is named where it is.

#[path = "common/folders.rs"]
mod common;

use common::{fresh_dir, results, rtconf, summary, text};
use serde_json::Value;
use std::path::Path;

/// The run arguments every run of this test shares: three VUIDs of both KHR trace commands.
const SCOPE: &[&str] = &[
    "--count",
    "3",
    "--seed",
    "7",
    "--vuid",
    "VUID-vkCmdTraceRaysIndirectKHR-stride-03686",
    "--vuid",
    "VUID-vkCmdTraceRaysKHR-None-02700",
    "--vuid",
    "VUID-VkStridedDeviceAddressRegionKHR-size-04631",
];

fn run(out: &Path, shard: Option<&str>) {
    // Every case file kept, so the merge of the shards' case folders is compared too.
    let mut args = vec!["run", "--keep-all", "--out", out.to_str().unwrap()];
    args.extend_from_slice(SCOPE);
    if let Some(s) = shard {
        args.extend_from_slice(&["--shard", s]);
    }
    let o = rtconf(&args, &[]);
    assert!(o.status.success(), "{}", text(&o));
}

/// A result line without its timing, for comparing runs.
fn untimed(v: &Value) -> Value {
    let mut v = v.clone();
    let line = v.as_object_mut().unwrap();
    line.remove("millis");
    line.remove("phases");
    v
}

fn caselist(run: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_to_string(run.join("caselist.txt"))
        .unwrap()
        .lines()
        .map(String::from)
        .collect();
    v.sort();
    v
}

#[test]
fn three_shards_merged_equal_the_unsharded_run_case_for_case() {
    let dir = fresh_dir("shard-merge");
    let whole = dir.join("whole");
    run(&whole, None);
    let shards: Vec<_> = (1..=3).map(|i| dir.join(format!("shard-{i}"))).collect();
    for (i, s) in shards.iter().enumerate() {
        run(s, Some(&format!("{}/3", i + 1)));
        assert_eq!(summary(s)["shard"], format!("{}/3", i + 1));
    }
    let expected = results(&whole);
    assert!(expected.len() >= 12, "{} cases", expected.len());
    // Every shard holds some cases, and no case is in two.
    let per_shard: Vec<_> = shards.iter().map(|s| results(s)).collect();
    assert!(per_shard.iter().all(|r| !r.is_empty()), "an empty shard");
    assert_eq!(
        per_shard.iter().map(|r| r.len()).sum::<usize>(),
        expected.len()
    );

    let merged = dir.join("merged");
    let mut args = vec!["merge", "--out", merged.to_str().unwrap()];
    args.extend(shards.iter().map(|s| s.to_str().unwrap()));
    let o = rtconf(&args, &[]);
    assert!(o.status.success(), "{}", text(&o));
    let got = results(&merged);
    assert_eq!(
        got.keys().collect::<Vec<_>>(),
        expected.keys().collect::<Vec<_>>()
    );
    for (name, line) in &expected {
        assert_eq!(untimed(&got[name]), untimed(line), "case {name}");
    }
    let (a, b) = (summary(&whole), summary(&merged));
    for key in [
        "cases",
        "passed",
        "failed",
        "triaged",
        "unsupported",
        "crashes",
        "timeouts",
        "statuses",
        "vuids",
        "registry",
        "driver",
        "profile",
    ] {
        assert_eq!(a[key], b[key], "summary {key}");
    }
    assert!(b.get("shard").is_none(), "{b}");
    assert_eq!(caselist(&merged), caselist(&whole));
    let junit = std::fs::read_to_string(merged.join("junit.xml")).unwrap();
    assert_eq!(junit.matches("<testcase ").count(), expected.len());
    assert!(merged.join("report/index.html").is_file());
    let n = |d: &Path| std::fs::read_dir(d.join("triaged")).map_or(0, |r| r.count());
    assert!(
        n(&whole) > 0,
        "the scope has triaged cases, kept with --keep-all"
    );
    assert_eq!(n(&merged), n(&whole), "triaged/");
    // The same details lines, whatever the order the shards ran them in.
    let details = |d: &Path| {
        let mut lines: Vec<String> = std::fs::read_to_string(d.join("details.jsonl"))
            .unwrap_or_default()
            .lines()
            .map(String::from)
            .collect();
        lines.sort();
        lines
    };
    assert!(!details(&whole).is_empty(), "the run keeps details");
    assert_eq!(details(&merged), details(&whole), "details.jsonl");

    // Without the third shard the merge says so and fails.
    let partial = dir.join("partial");
    let o = rtconf(
        &[
            "merge",
            "--out",
            partial.to_str().unwrap(),
            shards[0].to_str().unwrap(),
            shards[1].to_str().unwrap(),
        ],
        &[],
    );
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    assert!(
        String::from_utf8_lossy(&o.stderr).contains("shard(s) 3/3 of 3 are not among the inputs"),
        "{}",
        text(&o)
    );
    // Missing cases are counted against the case lists of the shards merged: none here, since each
    // shard's list holds only its own cases; a shard that stopped early leaves some.
    let cut = dir.join("shard-3-cut");
    std::fs::create_dir_all(&cut).unwrap();
    for f in ["summary.json", "caselist.txt"] {
        std::fs::copy(shards[2].join(f), cut.join(f)).unwrap();
    }
    let lines = std::fs::read_to_string(shards[2].join("results.jsonl")).unwrap();
    let kept: Vec<&str> = lines.lines().skip(1).collect();
    std::fs::write(cut.join("results.jsonl"), kept.join("\n") + "\n").unwrap();
    let dropped: Value = serde_json::from_str(lines.lines().next().unwrap()).unwrap();
    let o = merge_third(&partial, &shards, &cut);
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    let s = summary(&partial);
    assert_eq!(s["missing"], serde_json::json!([dropped["case"]]));
    assert_eq!(s["statuses"]["missing"], 1);
    let junit = std::fs::read_to_string(partial.join("junit.xml")).unwrap();
    assert!(junit.contains("<error type=\"missing\""), "{junit}");

    // A torn last line (a shard's results cut inside a line) and no case list to count the case
    // missing: the merge names the line and fails all the same, and `rtconf report` on the torn
    // folder writes the report of the other lines and exits 2, naming the same line.
    let torn = dir.join("shard-3-torn");
    std::fs::create_dir_all(&torn).unwrap();
    std::fs::copy(shards[2].join("summary.json"), torn.join("summary.json")).unwrap();
    let first = lines.lines().next().unwrap();
    std::fs::write(
        torn.join("results.jsonl"),
        format!("{}\n{}", kept.join("\n"), &first[..first.len() / 2]),
    )
    .unwrap();
    let place = format!(
        "{}:{}:",
        torn.join("results.jsonl").display(),
        kept.len() + 1
    );
    let merged = merged_and_reported_naming(&partial, &shards, &torn, &place);
    assert!(merged.contains("not a result line"), "{merged}");
    assert_eq!(summary(&partial)["cases"], expected.len() - 1);
    assert!(torn.join("report/index.html").is_file());

    // A byte that is not UTF-8 in the first line (a disk's bit flip, an editor's encoding): the merge
    // and `rtconf report` name that line and leave it out, and the merge still reads the lines after
    // it (`session::results`' own test shows the report's reader does).
    let flipped = dir.join("shard-3-flipped");
    std::fs::create_dir_all(&flipped).unwrap();
    std::fs::copy(shards[2].join("summary.json"), flipped.join("summary.json")).unwrap();
    let mut bytes = format!("{first}\n{}\n", kept.join("\n")).into_bytes();
    bytes[3] = 0xff;
    std::fs::write(flipped.join("results.jsonl"), bytes).unwrap();
    let place = format!(
        "{}:1: not a result line (not UTF-8 at column 4)",
        flipped.join("results.jsonl").display()
    );
    merged_and_reported_naming(&partial, &shards, &flipped, &place);
    assert_eq!(summary(&partial)["cases"], expected.len() - 1);

    // The report of a whole folder names nothing and exits 0.
    let o = rtconf(&["report", whole.to_str().unwrap()], &[]);
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    assert!(o.stderr.is_empty(), "{}", text(&o));
}

/// Asserts that the merge of the first two shards with `third` (into `out`) fails naming `place`, and
/// that `rtconf report` of `third` writes its report and exits 2 naming it too; the merge's stderr.
fn merged_and_reported_naming(
    out: &Path,
    shards: &[std::path::PathBuf],
    third: &Path,
    place: &str,
) -> String {
    let o = merge_third(out, shards, third);
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    let merged = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(merged.contains(place), "{}", text(&o));
    let o = rtconf(&["report", third.to_str().unwrap()], &[]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(
        String::from_utf8_lossy(&o.stderr).contains(place),
        "{}",
        text(&o)
    );
    merged
}

/// `rtconf merge` of the first two shards with `third` in place of the third, into `out`.
fn merge_third(out: &Path, shards: &[std::path::PathBuf], third: &Path) -> std::process::Output {
    rtconf(
        &[
            "merge",
            "--out",
            out.to_str().unwrap(),
            shards[0].to_str().unwrap(),
            shards[1].to_str().unwrap(),
            third.to_str().unwrap(),
        ],
        &[],
    )
}

#[test]
fn list_prints_the_cases_of_a_shard() {
    let mut args = vec!["run", "--list"];
    args.extend_from_slice(SCOPE);
    let all = rtconf(&args, &[]);
    assert!(all.status.success(), "{}", text(&all));
    let all: Vec<String> = String::from_utf8_lossy(&all.stdout)
        .lines()
        .map(String::from)
        .collect();
    assert!(all.len() >= 12, "{all:?}");
    let mut union = Vec::new();
    for i in 1..=3 {
        let mut a = args.clone();
        let shard = format!("{i}/3");
        a.extend_from_slice(&["--shard", &shard]);
        let o = rtconf(&a, &[]);
        assert!(o.status.success(), "{}", text(&o));
        union.extend(String::from_utf8_lossy(&o.stdout).lines().map(String::from));
    }
    union.sort();
    let mut sorted = all.clone();
    sorted.sort();
    assert_eq!(union, sorted);
}
