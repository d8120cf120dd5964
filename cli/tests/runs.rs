//! `rtconf run` end to end on lavapipe: names that match nothing and bad flag values are refused (a
//! CI job must never read "0 cases" as a pass), a new run into an `--out` starts clean, and a run stopped
//! by `kill -9` or a full disk and then resumed has exactly the results of an uninterrupted run (and
//! before the resume, `report` shows what the stopped run has).

mod common;
use common::*;
use std::collections::BTreeMap;
use std::path::Path;
use std::time::{Duration, Instant};

/// A run's results, case by case, without the timings.
fn results(out: &Path) -> BTreeMap<String, serde_json::Value> {
    let text = std::fs::read_to_string(out.join("results.jsonl")).unwrap();
    let mut by_case = BTreeMap::new();
    for line in text.lines() {
        let mut v: serde_json::Value =
            serde_json::from_str(line).unwrap_or_else(|e| panic!("a torn line `{line}`: {e}"));
        let line_of = v.as_object_mut().unwrap();
        line_of.remove("millis");
        line_of.remove("phases");
        let name = v["case"].as_str().unwrap().to_string();
        assert!(by_case.insert(name.clone(), v).is_none(), "{name} twice");
    }
    by_case
}

fn out_arg(dir: &Path) -> String {
    dir.display().to_string()
}

/// The run the resume tests stop and continue: 260 cases on lavapipe, one worker.
const SELECTION: [&str; 6] = [
    "--vuid",
    "VUID-vkCmdTraceRaysIndirectKHR-*",
    "--count",
    "4",
    "--jobs",
    "1",
];

fn run_into(out: &Path, extra: &[&str]) -> Ran {
    let o = out_arg(out);
    let mut args = vec!["run", "--out", &o];
    args.extend(SELECTION);
    args.extend(extra);
    rtconf(&args)
}

#[test]
fn a_vuid_that_matches_nothing_is_an_error_naming_the_nearest() {
    let out = tempfile::tempdir().unwrap();
    let o = out_arg(out.path());
    for typo in [
        "VUID-vkCmdTraceRaysIndirectKHR-stride-03868",
        "VUID-vkCmdTraceRaysIndirectKHR-strde-*",
        "99999",
    ] {
        let r = rtconf(&["run", "--vuid", typo, "--out", &o]);
        assert_eq!(r.code, 2, "{typo}: {}", r.all());
        assert!(
            r.stderr
                .contains(&format!("--vuid `{typo}` matches no VUID")),
            "{}",
            r.all()
        );
        assert!(r.stderr.contains("nearest: VUID-"), "{}", r.all());
    }
}

#[test]
fn globs_and_short_ids_expand_to_the_matching_vuids_and_say_how_many() {
    let out = tempfile::tempdir().unwrap();
    let o = out_arg(out.path());
    let r = rtconf(&["run", "--vuid", "03686", "--count", "2", "--out", &o]);
    assert_eq!(r.code, 0, "{}", r.all());
    assert!(r.stderr.contains("--vuid 03686: 2 VUID(s)"), "{}", r.all());
    let got = results(out.path());
    assert_eq!(got.len(), 4, "2 VUIDs × 2 cases: {got:?}");
    assert!(got.values().all(|v| v["target"]
        .as_str()
        .is_some_and(|t| t.ends_with("-stride-03686"))));
    let r = rtconf(&[
        "run",
        "--vuid",
        "VUID-vkCmdTraceRaysKHR-stride-*",
        "--count",
        "1",
        "--out",
        &o,
    ]);
    assert_eq!(r.code, 0, "{}", r.all());
    assert!(
        r.stderr
            .contains("--vuid VUID-vkCmdTraceRaysKHR-stride-*: "),
        "{}",
        r.all()
    );
    assert!(results(out.path()).len() >= 3);
}

#[test]
fn unknown_command_names_are_errors_in_run_coverage_and_registry() {
    let out = tempfile::tempdir().unwrap();
    let o = out_arg(out.path());
    for args in [
        vec!["run", "--command", "vkCmdBogus", "--out", &o],
        vec!["coverage", "--command", "vkCmdBogus"],
        vec!["registry", "vuids", "--command", "vkCmdBogus"],
    ] {
        let r = rtconf(&args);
        assert_eq!(r.code, 2, "{args:?}: {}", r.all());
        assert!(r.stderr.contains("`vkCmdBogus`"), "{args:?}: {}", r.all());
        assert!(r.stdout.trim().is_empty(), "{args:?}: {}", r.all());
    }
    let r = rtconf(&["registry", "vuids", "--command", "vkCmdTraceRaysNV"]);
    assert_eq!(r.code, 0, "{}", r.all());
    assert!(r.stdout.lines().count() > 50, "{}", r.all());
}

#[test]
fn jobs_timeout_and_count_of_zero_are_refused() {
    let out = tempfile::tempdir().unwrap();
    let o = out_arg(out.path());
    for (flag, value) in [("--jobs", "0"), ("--timeout", "0"), ("--count", "0")] {
        let r = rtconf(&["run", flag, value, "--out", &o]);
        assert_eq!(r.code, 2, "{flag}: {}", r.all());
        assert!(
            r.stderr.contains(flag) && r.stderr.contains("0 is not in 1.."),
            "{}",
            r.all()
        );
    }
    let r = rtconf(&["replay", HAND, "--timeout", "0"]);
    assert_eq!(r.code, 2, "{}", r.all());
    // `gen` writes no empty folder with exit 0 either.
    let r = rtconf(&["gen", "--valid", "--count", "0", "--out", &o]);
    assert_eq!(r.code, 2, "{}", r.all());
    assert!(r.stderr.contains("0 is not in 1.."), "{}", r.all());
}

#[test]
fn worker_and_case_counts_past_their_bounds_are_refused_before_anything_starts() {
    // Every worker is started at once, and stress and detect lay out every case before the first
    // runs: past these bounds they spawned without end or panicked allocating.
    let out = tempfile::tempdir().unwrap();
    let o = out_arg(out.path());
    for (command, flag, value, bound) in [
        ("run", "--jobs", "257", "257 is not in 1..=256"),
        ("stress", "--jobs", "100000", "100000 is not in 1..=256"),
        ("detect", "--jobs", "257", "257 is not in 1..=256"),
        (
            "stress",
            "--seeds",
            "18446744073709551615",
            "18446744073709551615 is not in 1..=10000",
        ),
        ("detect", "--count", "10001", "10001 is not in 1..=10000"),
    ] {
        let r = rtconf(&[command, flag, value, "--out", &o]);
        assert_eq!(r.code, 2, "{command} {flag}: {}", r.all());
        assert!(r.stderr.contains(bound), "{}", r.all());
    }
    let r = rtconf(&[
        "stress",
        "--seed",
        "18446744073709551615",
        "--seeds",
        "2",
        "--size",
        "small",
        "--out",
        &o,
    ]);
    assert_eq!(r.code, 2, "{}", r.all());
    assert!(
        r.stderr.contains("the last seed would be past"),
        "{}",
        r.all()
    );
}

#[test]
fn a_run_that_makes_no_case_exits_non_zero() {
    // Lavapipe has no VK_NV_ray_tracing: every spec of the NV command is inexpressible.
    let out = tempfile::tempdir().unwrap();
    let r = rtconf(&[
        "run",
        "--command",
        "vkCmdTraceRaysNV",
        "--count",
        "1",
        "--out",
        &out_arg(out.path()),
    ]);
    assert_eq!(r.code, 1, "{}", r.all());
    assert!(r.stdout.contains("0 cases on lavapipe"), "{}", r.all());
    assert!(r.stderr.contains("the run made no case"), "{}", r.all());
    // Why: the profile lacks the extension, said with the spec it stopped.
    assert!(
        r.stderr
            .contains("needs VK_NV_ray_tracing, which `lavapipe` lacks"),
        "{}",
        r.all()
    );
    assert!(r.stdout.contains("verdict: nothing checked"), "{}", r.all());
    // A shard that holds none of the cases made: said as such, not blamed on the profile.
    let r = rtconf(&[
        "run",
        "--shard",
        "1/4294967295",
        "--count",
        "1",
        "--rendered",
        "0",
        "--out",
        &out_arg(&out.path().join("shard")),
    ]);
    assert_eq!(r.code, 1, "{}", r.all());
    assert!(
        r.stderr.contains("cases made, ") && r.stderr.contains(" belong to other shards"),
        "{}",
        r.all()
    );
    assert!(!r.stderr.contains("not expressible"), "{}", r.all());
}

#[test]
fn a_second_run_into_the_same_out_starts_clean() {
    let out = tempfile::tempdir().unwrap();
    let o = out_arg(out.path());
    let first = rtconf(&[
        "run",
        "--vuid",
        "VUID-vkCmdTraceRaysKHR-stride-*",
        "--count",
        "1",
        "--out",
        &o,
    ]);
    assert_eq!(first.code, 0, "{}", first.all());
    // What the first run left, and a failure file of a case the second run does not make.
    std::fs::write(
        out.path().join("failures/first-run-only.yaml"),
        "name: first-run-only\n",
    )
    .unwrap();
    let second = rtconf(&["run", "--vuid", "03686", "--count", "1", "--out", &o]);
    assert_eq!(second.code, 0, "{}", second.all());
    assert!(!out.path().join("failures/first-run-only.yaml").exists());
    let got = results(out.path());
    assert_eq!(got.len(), 2, "only the second run's cases: {got:?}");
    let failures: Vec<String> = std::fs::read_dir(out.path().join("failures"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert!(
        failures
            .iter()
            .all(|f| got.contains_key(f.trim_end_matches(".yaml"))),
        "{failures:?}"
    );
}

#[test]
fn a_resume_with_another_seed_or_count_is_refused_naming_the_parameter() {
    let out = tempfile::tempdir().unwrap();
    let o = out_arg(out.path());
    let r = rtconf(&["run", "--vuid", "03686", "--count", "1", "--out", &o]);
    assert_eq!(r.code, 0, "{}", r.all());
    for (flag, value, was) in [("--seed", "7", "1"), ("--count", "3", "1")] {
        let mut args = vec![
            "run", "--vuid", "03686", "--out", &o, "--resume", flag, value,
        ];
        if flag != "--count" {
            args.extend(["--count", "1"]);
        }
        let r = rtconf(&args);
        assert_eq!(r.code, 2, "{flag}: {}", r.all());
        assert!(
            r.stderr.contains(&format!("--resume with {flag} {value}"))
                && r.stderr.contains(&format!("started with {flag} {was}")),
            "{}",
            r.all()
        );
    }
    assert_eq!(
        results(out.path()).len(),
        2,
        "the refused resumes added nothing"
    );
    let r = rtconf(&[
        "run", "--vuid", "03686", "--count", "1", "--out", &o, "--resume",
    ]);
    assert_eq!(r.code, 0, "{}", r.all());
    assert_eq!(results(out.path()).len(), 2);
}

#[test]
fn kill_9_then_resume_gives_the_uninterrupted_run_case_for_case() {
    let whole = tempfile::tempdir().unwrap();
    let r = run_into(whole.path(), &[]);
    assert_eq!(r.code, 0, "{}", r.all());
    let expected = results(whole.path());
    assert!(expected.len() > 200, "{}", expected.len());

    let cut = tempfile::tempdir().unwrap();
    let o = out_arg(cut.path());
    let mut args = vec!["run", "--out", &o];
    args.extend(SELECTION);
    let (mut child, lines) = started_run(&args, cut.path(), 60);
    // SAFETY: kill(2) on the pid of the child this test started.
    unsafe { libc_kill(child.id() as i32) };
    let status = child.wait().unwrap();
    assert!(!status.success(), "killed mid-way: {status:?}");
    let partial = lines();
    assert!(partial >= 60 && partial < expected.len(), "{partial}");

    // The stopped run's folder: `report` writes the page of the results it has and says, with exit 2,
    // that the run did not finish and how to finish it; `merge` refuses it as a shard.
    let r = rtconf(&["report", &o]);
    assert_eq!(r.code, 2, "{}", r.all());
    let unfinished = format!("{o}: the run there did not finish");
    assert!(
        r.stderr.contains(&unfinished) && r.stderr.contains("--resume"),
        "{}",
        r.all()
    );
    let page = std::fs::read_to_string(cut.path().join("report/index.html")).unwrap();
    assert!(page.contains("id=\"run-verdict\">unfinished</span>"));
    assert!(page.contains(&format!("the {partial} cases with a result")));
    let merged = tempfile::tempdir().unwrap();
    let r = rtconf(&["merge", "--out", &out_arg(merged.path()), &o, &o]);
    assert_eq!(r.code, 2, "{}", r.all());
    assert!(r.stderr.contains(&unfinished), "{}", r.all());

    let r = run_into(cut.path(), &["--resume"]);
    assert_eq!(r.code, 0, "{}", r.all());
    assert_eq!(results(cut.path()), expected);
}

/// Ctrl-C (SIGINT to the runner): the run ends with the shell's status for it, 130, and says where the
/// results of the finished cases are and how to go on; the results it had are there, whole.
#[test]
fn an_interrupted_run_says_where_its_results_are_and_how_to_go_on() {
    let cut = tempfile::tempdir().unwrap();
    let o = out_arg(cut.path());
    // Ten times the resume tests' run (some seven seconds), so the signal comes well before its end.
    let args = [
        "run",
        "--out",
        &o,
        "--vuid",
        "VUID-vkCmdTraceRaysIndirectKHR-*",
        "--count",
        "40",
        "--jobs",
        "1",
    ];
    let (child, lines) = started_run(&args, cut.path(), 30);
    // SAFETY: kill(2) on the pid of the child this test started.
    assert_eq!(unsafe { kill(child.id() as i32, 2) }, 0);
    let done = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&done.stderr);
    assert_eq!(done.status.code(), Some(130), "{stderr}");
    assert!(
        stderr.contains(&format!(
            "rtconf: interrupted; the results of the cases that finished are in {o}/results.jsonl"
        )) && stderr.contains(&format!(
            "`rtconf run --resume --out {o}` with the same arguments"
        )),
        "{stderr}"
    );
    assert!(lines() >= 30);
    assert!(!cut.path().join("summary.json").exists());
}

/// `rtconf ARGS` started (its standard error piped), once its `results.jsonl` in `out` has `lines`
/// lines or two minutes have passed; and a count of those lines.
fn started_run<'a>(
    args: &[&str],
    out: &'a Path,
    lines: usize,
) -> (std::process::Child, impl Fn() -> usize + 'a) {
    let child = std::process::Command::new(env!("CARGO_BIN_EXE_rtconf"))
        .args(args)
        .current_dir(root())
        .env("VK_DRIVER_FILES", "/usr/share/vulkan/icd.d/lvp_icd.json")
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let count = move || {
        std::fs::read_to_string(out.join("results.jsonl"))
            .map(|t| t.lines().count())
            .unwrap_or(0)
    };
    let started = Instant::now();
    while count() < lines && started.elapsed() < Duration::from_secs(120) {
        std::thread::sleep(Duration::from_millis(20));
    }
    (child, count)
}

extern "C" {
    fn kill(pid: i32, sig: i32) -> i32;
}

/// SIGKILL, as `kill -9` sends it.
unsafe fn libc_kill(pid: i32) {
    assert_eq!(kill(pid, 9), 0);
}

#[test]
fn a_full_disk_stops_the_run_and_a_resume_repairs_its_torn_line() {
    let whole = tempfile::tempdir().unwrap();
    let r = run_into(whole.path(), &[]);
    assert_eq!(r.code, 0, "{}", r.all());
    let expected = results(whole.path());

    // A tmpfs of 48 KiB: room for run.json and part of the results and failure files.
    let disk = tempfile::tempdir().unwrap();
    let mounted = std::process::Command::new("mount")
        .args(["-t", "tmpfs", "-o", "size=48k", "tmpfs"])
        .arg(disk.path())
        .status()
        .unwrap();
    assert!(mounted.success(), "mount a tmpfs (the tests run as root)");
    struct Unmount<'a>(&'a Path);
    impl Drop for Unmount<'_> {
        fn drop(&mut self) {
            let _ = std::process::Command::new("umount").arg(self.0).status();
        }
    }
    let _unmount = Unmount(disk.path());
    let full = run_into(disk.path(), &[]);
    assert_ne!(full.code, 0, "{}", full.all());
    assert!(
        full.stderr.contains("No space left on device"),
        "{}",
        full.all()
    );
    let failures = disk.path().join("failures");
    for e in std::fs::read_dir(&failures).unwrap() {
        let p = e.unwrap().path();
        let len = std::fs::metadata(&p).unwrap().len();
        let name = p.file_name().unwrap().to_string_lossy().into_owned();
        assert!(
            len > 0 && !name.ends_with(".tmp"),
            "{name}: {len} bytes left"
        );
    }
    // Move the stopped run to a disk with room, and resume it there.
    let moved = tempfile::tempdir().unwrap();
    let copied = std::process::Command::new("cp")
        .arg("-a")
        .arg(format!("{}/.", disk.path().display()))
        .arg(moved.path())
        .status()
        .unwrap();
    assert!(copied.success());
    // The disk filled in the middle of a line (where it filled in a failure file instead, tear the
    // last line as a full disk would have).
    let path = moved.path().join("results.jsonl");
    let text = std::fs::read_to_string(&path).unwrap();
    if text.ends_with('\n') {
        let last = text.lines().last().unwrap();
        std::fs::write(&path, &text[..text.len() - last.len() / 2 - 1]).unwrap();
    }
    assert!(!std::fs::read_to_string(&path).unwrap().ends_with('\n'));
    let r = run_into(moved.path(), &["--resume"]);
    assert_eq!(r.code, 0, "{}", r.all());
    assert_eq!(results(moved.path()), expected);
}

#[test]
fn the_runner_times_its_gate_and_judge_beside_the_workers_phases() {
    // Valid cases: the gate traces each launch with the reference tracer before the case runs.
    let out = tempfile::tempdir().unwrap();
    let o = out_arg(out.path());
    let ran = rtconf(&[
        "run",
        "--command",
        "vkCmdTraceRaysKHR",
        "--valid-only",
        "--count",
        "3",
        "--out",
        &o,
    ]);
    assert_eq!(ran.code, 0, "{}", ran.all());
    let text = std::fs::read_to_string(out.path().join("results.jsonl")).unwrap();
    let (mut gate, mut judge, mut other) = (0.0, 0.0, 0.0);
    let mut lines = 0;
    for line in text.lines() {
        let v: serde_json::Value = serde_json::from_str(line).unwrap();
        let phases = v["phases"].as_object().expect("a run case's phases");
        let ms = |k: &str| phases.get(k).and_then(|x| x.as_f64());
        gate += ms("gate").unwrap_or_else(|| panic!("no gate phase: {line}"));
        judge += ms("judge").unwrap_or_else(|| panic!("no judge phase: {line}"));
        // The worker's phases are the rest; what else the worker spent is `worker-other`.
        let worker: f64 = phases
            .iter()
            .filter(|(k, _)| *k != "gate" && *k != "judge")
            .filter_map(|(_, x)| x.as_f64())
            .sum();
        other += (v["millis"].as_f64().unwrap() - worker).max(0.0);
        lines += 1;
    }
    assert!(lines >= 3, "{lines} cases");
    assert!(
        gate > 0.0 && judge > 0.0,
        "gate {gate} ms, judge {judge} ms"
    );
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.path().join("summary.json")).unwrap())
            .unwrap();
    let time = |k: &str| summary["time"][k].as_f64().unwrap_or(f64::NAN);
    let close = |a: f64, b: f64| (a - b).abs() <= 1e-6 + 1e-9 * b.abs();
    assert!(close(time("gate"), gate / 1000.0), "{:?}", summary["time"]);
    assert!(
        close(time("judge"), judge / 1000.0),
        "{:?}",
        summary["time"]
    );
    assert!(
        close(time("worker-other"), other / 1000.0),
        "{:?}",
        summary["time"]
    );
}

#[test]
fn a_run_into_a_folder_another_run_is_writing_is_refused() {
    // flock(1) holds the folder's lock as a running `rtconf run` does, while the second one starts.
    let out = tempfile::tempdir().unwrap();
    let o = out_arg(out.path());
    let lock = out.path().join(".rtconf-run.lock").display().to_string();
    let args = [
        "run",
        "--count",
        "1",
        "--rendered",
        "0",
        "--vuid",
        "03686",
        "--out",
        &o,
    ];
    let r = rtconf_under(&["flock", &lock], &args);
    assert_eq!(r.code, 2, "{}", r.all());
    assert!(
        r.stderr
            .contains("another rtconf run is writing this folder"),
        "{}",
        r.all()
    );
    assert!(!out.path().join("run.json").exists(), "nothing written");
    // Once the lock is free, the same run goes ahead.
    let r = rtconf(&args);
    assert_eq!(r.code, 0, "{}", r.all());
}
