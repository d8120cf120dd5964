//! Throughput of `rtconf run` end to end on lavapipe (the binary, its worker processes, the layer, the
//! judging and the files it writes), against the ceiling of the same cases executed back to back in
//! this process on one warm executor. Three selections: invalid cases of every trace VUID of the
//! indirect command; valid cases of vkCmdTraceRaysKHR as a run draws them (aimed launches and
//! rendered scenes of every size from 1x1 to 256x256); and rendered cases at 64x64 — the run's
//! rendered vkCmdTraceRaysKHR cases with their launch (and camera) set to 64x64 and without the
//! explicit rays such a launch never traces, written to a folder and run with `--cases`.
//!
//! Lines printed (all measured in this one run):
//! - `run invalid cases/s`, `run valid cases/s`, `run rendered cases/s`: cases over the run's wall
//!   time (`summary.json`), the last for the 64x64 rendered cases; of each selection the median of
//!   three runs by that rate (its phases are the ones printed);
//! - `in-process … cases/s`: the ceiling, the same cases executed (not judged) in this process, the
//!   median of three timed passes;
//! - `run share of ceiling`: the invalid selection's end-to-end rate over its in-process rate;
//! - `run overhead`: on the 64x64 rendered cases, the harness's own time against the driver's
//!   trace time: the worker's phases that are the harness's (`harness::timing`: resources, shaders,
//!   record, readback and the rest of each case in its worker) over the `gpu` phase (submission to
//!   fence: the driver running the launch, with whatever it compiles lazily at the first dispatch).
//!   Pipeline creation, structure builds and device creation are the driver's work and counted in
//!   neither; the model's work is the runner's and printed on its own lines: `run gate over gpu`
//!   (the gate, before a case runs: for a valid case mostly the reference tracer's expected
//!   outcomes of its launch), `run judge over gpu` (the comparison after it ran), and `run oracle
//!   over gpu`, their sum (the oracle's speed against lavapipe is `--bench render_rays`);
//! - `run time <phase>`: where each run's case time went (`summary.json` `time`), seconds summed
//!   over the cases, and `runner-cpu`: the CPU seconds of the runner process itself (generating,
//!   judging and writing, beside the workers);
//! - `in-process time <phase>`: the same phases in the ceiling's median pass, for the gap between
//!   the two (a warm executor makes no device and, for a case it ran before, no pipeline).
//!
//! The run's lavapipe shader cache (Mesa's, on disk) is warm after the first run on a machine: the
//! harness makes each valid pipeline as the same code every time (see `harness::Executor`), so the
//! figures are those of a second run. A first run on a fresh machine compiles each pipeline once.
//! `RTCONF_BENCH_DIR=DIR` keeps every run folder and the 64x64 case folder under DIR.

use harness::{Driver, Execution, Executor};
use model::case::Case;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

const JOBS: usize = 2;

/// Runs of each selection end to end, and timed passes of its in-process ceiling: each figure is the
/// median (the machine's load drifts between runs of a second or two).
const REPEATS: usize = 3;

/// The launch side of the rendered selection.
const SIDE: u32 = 64;

/// One selection of cases: the arguments of `rtconf run` that make it.
struct Selection {
    name: &'static str,
    args: Vec<String>,
    scope: session::Scope,
    count: usize,
    /// The cases of a selection run from a folder (`--cases`), written there first.
    folder: Option<Vec<Case>>,
}

fn selections(tmp: &Path) -> Vec<Selection> {
    let invalid = "VUID-vkCmdTraceRaysIndirectKHR-*";
    let valid_scope = session::Scope {
        commands: vec![model::CommandId::TraceRays],
        vuids: vec![],
        valid_only: true,
        seed: 1,
        rendered: session::plan::DEFAULT_RENDERED,
    };
    let valid = Selection {
        name: "valid",
        args: [
            "--valid-only",
            "--command",
            "vkCmdTraceRaysKHR",
            "--count",
            "60",
        ]
        .map(String::from)
        .to_vec(),
        scope: valid_scope.clone(),
        count: 60,
        folder: None,
    };
    // The run's rendered cases of vkCmdTraceRaysKHR, each at 64x64.
    let drawn = session::list(&config(&valid, &tmp.join("rendered-list")))
        .expect("the selection lists its cases");
    let rendered: Vec<Case> = drawn
        .into_iter()
        .filter(|c| c.name.contains("rendered"))
        .filter_map(at_side)
        .collect();
    assert!(
        rendered.len() >= 50,
        "the valid selection draws rendered cases ({} at {SIDE}x{SIDE})",
        rendered.len()
    );
    let folder = tmp.join("rendered-cases");
    std::fs::create_dir_all(&folder).expect("a case folder");
    for c in &rendered {
        std::fs::write(folder.join(format!("{}.yaml", c.name)), c.to_yaml())
            .expect("the case folder is writable");
    }
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
            folder: None,
        },
        valid,
        Selection {
            name: "rendered",
            args: vec!["--cases".into(), folder.display().to_string()],
            scope: valid_scope,
            count: 1,
            folder: Some(rendered),
        },
    ]
}

/// A rendered vkCmdTraceRaysKHR case with its launch (and its camera, where it has one) set to
/// SIDE x SIDE launch IDs, if it still is a case the gate lets run.
fn at_side(mut case: Case) -> Option<Case> {
    let profile = session::sources::profile_for("lavapipe").expect("the lavapipe profile");
    let body = case.as_trace_mut()?;
    let model::call::Call::TraceRays(call) = &mut body.call else {
        return None;
    };
    (call.width, call.height, call.depth) = (SIDE, SIDE, 1);
    if let Some(camera) = body.world.launch.camera.as_mut() {
        (camera.width, camera.height) = (SIDE, SIDE);
    }
    // Launch ID i traces ray i of the ray list (explicit rays first) while there are more rays than
    // IDs: the explicit rays past SIDE x SIDE (a 256x256 draw keeps tens of thousands) are never
    // traced at this size, and go. The traced rays are the same.
    body.world.launch.rays.truncate((SIDE * SIDE) as usize);
    case.name = format!("{}-{SIDE}x{SIDE}", case.name);
    case.runnable(&profile).ok().map(|_| case)
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
        keep_all: false,
    }
}

/// The run's cases executed back to back on one warm executor in this process: cases per second and
/// the seconds per phase (`harness::timing`) of the median of [`REPEATS`] timed passes (a first pass
/// warms devices and pipelines and is not timed).
fn in_process_rate(s: &Selection, out: &Path) -> (f64, BTreeMap<String, f64>) {
    let cases = match &s.folder {
        Some(cases) => cases.clone(),
        None => session::list(&config(s, out)).expect("the selection lists its cases"),
    };
    let profile = session::sources::profile_for("lavapipe").expect("the lavapipe profile");
    let mut executor = Executor::new(Driver::Lavapipe).expect("a lavapipe executor");
    let execs: Vec<Execution> = cases
        .iter()
        .map(|c| Execution::for_case(c, &profile))
        .collect();
    for (c, e) in cases.iter().zip(&execs) {
        executor.execute(c, e);
    }
    let mut passes: Vec<(f64, BTreeMap<String, f64>)> = (0..REPEATS)
        .map(|_| {
            let _ = harness::timing::take();
            let started = Instant::now();
            for (c, e) in cases.iter().zip(&execs) {
                executor.execute(c, e);
            }
            let rate = cases.len() as f64 / started.elapsed().as_secs_f64();
            let phases = harness::timing::take()
                .into_iter()
                .map(|(phase, ms)| (phase, ms / 1000.0))
                .collect();
            (rate, phases)
        })
        .collect();
    passes.sort_by(|a, b| a.0.total_cmp(&b.0));
    passes.swap_remove(REPEATS / 2)
}

/// The median of [`REPEATS`] runs of the selection by rate (cases over seconds), each in its own
/// folder under `out`: its wall seconds, cases and phases (see [`end_to_end`]).
fn median_run(s: &Selection, out: &Path) -> (f64, usize, BTreeMap<String, f64>) {
    let mut runs: Vec<(f64, usize, BTreeMap<String, f64>)> = (0..REPEATS)
        .map(|k| end_to_end(s, &out.join(k.to_string())))
        .collect();
    runs.sort_by(|a, b| (a.1 as f64 / a.0).total_cmp(&(b.1 as f64 / b.0)));
    runs.swap_remove(REPEATS / 2)
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
    let mut time: BTreeMap<String, f64> = summary["time"]
        .as_object()
        .map(|o| {
            o.iter()
                .filter_map(|(k, v)| Some((k.clone(), v.as_f64()?)))
                .collect()
        })
        .unwrap_or_default();
    // The runner's own CPU (generation, judging, writing), beside the workers' phases.
    if let Some(cpu) = summary["runner_cpu_seconds"].as_f64() {
        time.insert("runner-cpu".into(), cpu);
    }
    assert!(cases > 0, "{}: the run made no case", s.name);
    (seconds, cases, time)
}

/// The harness's own time over the driver's trace time (see the module's `run overhead`).
fn overhead(time: &BTreeMap<String, f64>) -> f64 {
    let own: f64 = ["resources", "shaders", "record", "readback", "worker-other"]
        .iter()
        .filter_map(|k| time.get(*k))
        .sum();
    own / gpu(time)
}

fn gpu(time: &BTreeMap<String, f64>) -> f64 {
    time.get("gpu").copied().unwrap_or(f64::NAN)
}

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn main() {
    // RTCONF_BENCH_DIR keeps the runs' folders (and the 64x64 case folder) there for inspection.
    let kept = std::env::var_os("RTCONF_BENCH_DIR").map(PathBuf::from);
    let tmp = tempfile::tempdir().expect("a temporary folder");
    let tmp = match &kept {
        Some(dir) => {
            std::fs::create_dir_all(dir).expect("RTCONF_BENCH_DIR is writable");
            dir.clone()
        }
        None => tmp.path().to_path_buf(),
    };
    let tmp = &tmp;
    let mut lines = Vec::new();
    let mut invalid_share = f64::NAN;
    let mut overhead = f64::NAN;
    let mut judge_over_gpu = f64::NAN;
    let mut gate_over_gpu = f64::NAN;
    for s in selections(tmp) {
        let out = tmp.join(s.name);
        let (seconds, cases, time) = median_run(&s, &out);
        let run_rate = cases as f64 / seconds;
        let (ceiling, ceiling_time) = in_process_rate(&s, &tmp.join(format!("{}-list", s.name)));
        lines.push(format!("run {} cases/s: {run_rate:.0}", s.name));
        lines.push(format!("in-process {} cases/s: {ceiling:.0}", s.name));
        lines.push(format!("{} cases: {cases} in {seconds:.2} s", s.name));
        match s.name {
            "invalid" => invalid_share = run_rate / ceiling,
            "rendered" => {
                overhead = self::overhead(&time);
                judge_over_gpu = time.get("judge").copied().unwrap_or(f64::NAN) / gpu(&time);
                gate_over_gpu = time.get("gate").copied().unwrap_or(f64::NAN) / gpu(&time);
            }
            _ => {}
        }
        let mut by_time: Vec<(&String, &f64)> = time.iter().collect();
        by_time.sort_by(|a, b| b.1.total_cmp(a.1));
        for (phase, secs) in by_time {
            lines.push(format!("run time {} {phase}: {secs:.2} s", s.name));
        }
        for (phase, secs) in &ceiling_time {
            lines.push(format!("in-process time {} {phase}: {secs:.2} s", s.name));
        }
    }
    for l in &lines {
        println!("{l}");
    }
    println!("run gate over gpu: {:.0}%", gate_over_gpu * 100.0);
    println!("run judge over gpu: {:.0}%", judge_over_gpu * 100.0);
    println!(
        "run oracle over gpu: {:.0}%",
        (gate_over_gpu + judge_over_gpu) * 100.0
    );
    println!("run overhead: {:.0}%", overhead * 100.0);
    println!("run share of ceiling: {:.0}%", invalid_share * 100.0);
}
