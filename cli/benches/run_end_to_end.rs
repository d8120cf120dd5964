//! Throughput of `rtconf run` end to end on lavapipe (the binary, its worker processes, the layer, the
//! judging and the files it writes), against the ceiling of the same cases executed back to back in
//! this process on one warm executor. Two selections: invalid cases of every trace VUID of the indirect
//! command, and valid cases (each with its scene traced and its records judged) of vkCmdTraceRaysKHR.
//!
//! Lines printed (all measured in this one run):
//! - `run invalid cases/s`, `run rendered cases/s`: cases over the run's wall time (`summary.json`);
//! - `in-process invalid cases/s`, `in-process rendered cases/s`: the ceiling, the same cases;
//! - `run share of ceiling`: the invalid selection's end-to-end rate over its in-process rate;
//! - `run overhead`: on the rendered selection, rtconf's own time against the driver's trace time:
//!   the harness's phases (`harness::timing`: resources, shaders, record, readback and the rest of each
//!   case in its worker) and the runner's judging, over the `gpu` phase (submission to fence: the
//!   driver running the launch, with whatever it compiles lazily at the first dispatch). Pipeline
//!   creation, structure builds and device creation are the driver's work and counted in neither;
//! - `run time <phase>`: where the rendered run's case time went (`summary.json` `time`), seconds
//!   summed over the cases.

use harness::{Driver, Execution, Executor};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

const JOBS: usize = 2;

/// One selection of cases: the arguments of `rtconf run` that make it.
struct Selection {
    name: &'static str,
    args: Vec<String>,
    scope: session::Scope,
    count: usize,
}

fn selections() -> Vec<Selection> {
    let invalid = "VUID-vkCmdTraceRaysIndirectKHR-*";
    vec![
        Selection {
            name: "invalid",
            args: ["--vuid", invalid, "--count", "8"]
                .map(String::from)
                .to_vec(),
            scope: session::Scope {
                commands: vec![],
                vuids: vec![invalid.into()],
                valid_only: false,
                seed: 1,
                rendered: session::plan::DEFAULT_RENDERED,
            },
            count: 8,
        },
        Selection {
            name: "rendered",
            args: [
                "--valid-only",
                "--command",
                "vkCmdTraceRaysKHR",
                "--count",
                "120",
            ]
            .map(String::from)
            .to_vec(),
            scope: session::Scope {
                commands: vec![model::CommandId::TraceRays],
                vuids: vec![],
                valid_only: true,
                seed: 1,
                rendered: session::plan::DEFAULT_RENDERED,
            },
            count: 120,
        },
    ]
}

fn config(s: &Selection, out: &Path) -> session::RunConfig {
    session::RunConfig {
        driver: "lavapipe".into(),
        profile: None,
        scope: s.scope.clone(),
        count: s.count,
        jobs: JOBS,
        timeout: 60,
        out: out.to_path_buf(),
        shrink: 0,
        resume: false,
        from: vec![],
        triage: vec![],
        layer: None,
        strict: false,
        selection: session::Selection::default(),
        inject: None,
    }
}

/// The run's cases executed back to back on one warm executor in this process: cases per second
/// (the first pass warms devices and pipelines and is not timed).
fn in_process_rate(s: &Selection, out: &Path) -> f64 {
    let cfg = config(s, out);
    let cases = session::list(&cfg).expect("the selection lists its cases");
    let profile = session::sources::profile_for("lavapipe").expect("the lavapipe profile");
    let mut executor = Executor::new(Driver::Lavapipe).expect("a lavapipe executor");
    let execs: Vec<Execution> = cases
        .iter()
        .map(|c| Execution::for_case(c, &profile))
        .collect();
    for (c, e) in cases.iter().zip(&execs) {
        executor.execute(c, e);
    }
    let started = Instant::now();
    for (c, e) in cases.iter().zip(&execs) {
        executor.execute(c, e);
    }
    cases.len() as f64 / started.elapsed().as_secs_f64()
}

/// One `rtconf run` of the selection: its wall seconds, cases and where the case time went
/// (`summary.json` `time`, seconds per phase).
fn end_to_end(s: &Selection, out: &Path) -> (f64, usize, BTreeMap<String, f64>) {
    let status = Command::new(env!("CARGO_BIN_EXE_rtconf"))
        .args(["run", "--driver", "lavapipe", "--jobs", &JOBS.to_string()])
        .args(&s.args)
        .arg("--out")
        .arg(out)
        .env("VK_DRIVER_FILES", "/usr/share/vulkan/icd.d/lvp_icd.json")
        .current_dir(repo())
        .output()
        .expect("rtconf runs");
    let summary: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(out.join("summary.json")).unwrap_or_else(|e| {
            panic!(
                "{}: no summary ({e}); stderr: {}",
                s.name,
                String::from_utf8_lossy(&status.stderr)
            )
        }),
    )
    .expect("summary.json parses");
    let cases = summary["cases"].as_u64().unwrap_or(0) as usize;
    let seconds = summary["seconds"].as_f64().unwrap_or(f64::NAN);
    let time: BTreeMap<String, f64> = summary["time"]
        .as_object()
        .map(|o| {
            o.iter()
                .filter_map(|(k, v)| Some((k.clone(), v.as_f64()?)))
                .collect()
        })
        .unwrap_or_default();
    assert!(cases > 0, "{}: the run made no case", s.name);
    (seconds, cases, time)
}

/// rtconf's own time over the driver's trace time (see the module's `run overhead`).
fn overhead(time: &BTreeMap<String, f64>) -> f64 {
    let own: f64 = [
        "resources",
        "shaders",
        "record",
        "readback",
        "worker-other",
        "judge",
    ]
    .iter()
    .filter_map(|k| time.get(*k))
    .sum();
    own / time.get("gpu").copied().unwrap_or(f64::NAN)
}

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn main() {
    let tmp = tempfile::tempdir().expect("a temporary folder");
    let mut lines = Vec::new();
    let mut invalid_share = f64::NAN;
    let mut overhead = f64::NAN;
    for s in selections() {
        let out = tmp.path().join(s.name);
        let (seconds, cases, time) = end_to_end(&s, &out);
        let run_rate = cases as f64 / seconds;
        let ceiling = in_process_rate(&s, &tmp.path().join(format!("{}-list", s.name)));
        lines.push(format!("run {} cases/s: {run_rate:.0}", s.name));
        lines.push(format!("in-process {} cases/s: {ceiling:.0}", s.name));
        lines.push(format!("{} cases: {cases} in {seconds:.2} s", s.name));
        if s.name == "invalid" {
            invalid_share = run_rate / ceiling;
        } else {
            overhead = self::overhead(&time);
            let mut by_time: Vec<(&String, &f64)> = time.iter().collect();
            by_time.sort_by(|a, b| b.1.total_cmp(a.1));
            for (phase, secs) in by_time {
                lines.push(format!("run time {phase}: {secs:.2} s"));
            }
        }
    }
    for l in &lines {
        println!("{l}");
    }
    println!("run overhead: {:.0}%", overhead * 100.0);
    println!("run share of ceiling: {:.0}%", invalid_share * 100.0);
}
