//! `rtconf run`: generate cases for the requested commands and VUIDs, run them on a driver in worker
//! processes, compare with the model, and stream `results.jsonl`; then `summary.json` and a table.
//! `--command vkCmdBuildAccelerationStructuresIndirectKHR` runs build cases the same way: valid cases and
//! one spec per executable build VUID with a mutation, generated a chunk at a time, judged again with
//! the sizes the device reported, compared by `compare_build`.

use clap::Args;
use generator::CaseSpec;
use harness::compare::{compare, compare_build, CaseReport, Outcome, Triage};
use harness::worker::{run_builds_in_workers, run_in_workers, BuildRequest};
use model::{Case, DeviceProfile, RuleSet};
use std::collections::{BTreeMap, BTreeSet};
use std::io::{BufRead, Write};
use std::path::{Path, PathBuf};
use std::time::Duration;

#[derive(Args)]
pub struct RunArgs {
    /// lavapipe, nvidia, or the path of an ICD manifest.
    #[arg(long, default_value = "lavapipe")]
    driver: String,
    /// The device profile cases are generated from (default: the driver's name; nvidia → nvidia-h100).
    #[arg(long)]
    profile: Option<String>,
    /// Commands to run (repeatable; default: every trace command the profile supports). The build
    /// command vkCmdBuildAccelerationStructuresIndirectKHR runs only when named.
    #[arg(long)]
    command: Vec<String>,
    /// Only these VUIDs' invalid cases (repeatable; default: every executable VUID with a mutation).
    #[arg(long)]
    vuid: Vec<String>,
    /// Only valid cases (with read-back); no invalid ones.
    #[arg(long, conflicts_with = "vuid")]
    valid_only: bool,
    /// Cases per VUID and valid cases per command.
    #[arg(long, default_value_t = 4)]
    count: usize,
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Worker processes.
    #[arg(long, default_value_t = 2)]
    jobs: usize,
    /// Seconds a case may take.
    #[arg(long, default_value_t = 60)]
    timeout: u64,
    #[arg(long, default_value = "out/run")]
    out: PathBuf,
    /// Shrink up to this many failing cases to minimal ones in cases/regressions/ (in this process).
    #[arg(long, default_value_t = 0)]
    shrink: usize,
    /// Continue a killed run: cases already in results.jsonl are not run again.
    #[arg(long)]
    resume: bool,
    /// Registry sources for the rules (default: the installed registry, the layer's own version).
    #[arg(long = "from")]
    from: Vec<PathBuf>,
    /// Triage files (default: triage/layer-<registry version>.yaml and triage/<driver>.yaml, where present).
    #[arg(long)]
    triage: Vec<PathBuf>,
}

/// Cases generated ahead of the workers: bounds memory, and amortises worker start-up.
const CHUNK: usize = 512;

/// Per-VUID agreement counts of `summary.json`.
#[derive(Default, serde::Serialize)]
struct VuidTally {
    cases: usize,
    model: usize,
    layer: usize,
    agree: usize,
}

#[derive(Default, serde::Serialize)]
struct Summary {
    driver: String,
    profile: String,
    registry: Option<String>,
    cases: usize,
    passed: usize,
    failed: usize,
    triaged: usize,
    unsupported: usize,
    crashes: usize,
    timeouts: usize,
    /// Peak resident memory of the runner process itself (workers excluded), in KiB (Linux).
    runner_peak_rss_kib: Option<u64>,
    /// Wall time of the run, in seconds.
    seconds: f64,
    vuids: BTreeMap<String, VuidTally>,
}

/// `VmHWM` of this process from /proc (None elsewhere).
fn peak_rss_kib() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    line.split_whitespace().nth(1)?.parse().ok()
}

pub fn default_profile_name(driver: &str) -> String {
    match driver {
        "nvidia" => "nvidia-h100".into(),
        "lavapipe" | "lvp" => "lavapipe".into(),
        other => Path::new(other)
            .file_stem()
            .map_or("icd".into(), |s| s.to_string_lossy().into_owned()),
    }
}

/// The specs of a run: one valid spec per command, and one per (command, VUID) that has a mutation.
fn plan_specs(a: &RunArgs, rules: &RuleSet, profile: &DeviceProfile) -> Vec<CaseSpec> {
    let commands: Vec<String> = if a.command.is_empty() {
        model::rules::TRACE_COMMANDS
            .iter()
            .filter(|c| **c != "vkCmdTraceRaysNV" || profile.has_extension("VK_NV_ray_tracing"))
            .map(|c| c.to_string())
            .collect()
    } else {
        a.command.clone()
    };
    let mut specs = Vec::new();
    for c in &commands {
        let Some(command) = generator::Command::from_vk_name(c) else {
            continue;
        };
        if a.vuid.is_empty() {
            specs.push(CaseSpec::valid(command));
        }
        if a.valid_only {
            continue;
        }
        for row in rules
            .rows
            .iter()
            .filter(|r| r.status == model::rules::Status::Executable)
        {
            if !model::rules::applies_to(&row.scope, c) {
                continue;
            }
            if !a.vuid.is_empty() && !a.vuid.contains(&row.vuid) {
                continue;
            }
            if generator::mutation::mutations_for(&row.vuid).is_some() {
                specs.push(CaseSpec::violate(command, &row.vuid));
            }
        }
    }
    specs
}

fn done_cases(results: &Path) -> BTreeSet<String> {
    let Ok(f) = std::fs::File::open(results) else {
        return BTreeSet::new();
    };
    std::io::BufReader::new(f)
        .lines()
        .map_while(Result::ok)
        .filter_map(|l| serde_json::from_str::<CaseReport>(&l).ok())
        .map(|r| r.case)
        .collect()
}

pub fn run(a: RunArgs) -> Result<i32, String> {
    let started = std::time::Instant::now();
    let set = super::load_sources(&a.from)?;
    let rules = RuleSet::from_vuids(&set);
    let profile_name = a
        .profile
        .clone()
        .unwrap_or_else(|| default_profile_name(&a.driver));
    let profile = super::profile_for(&profile_name)?;
    let driver = harness::vulkan::Driver::parse(&a.driver);
    if !driver.icd_path().exists() {
        return Err(format!(
            "driver `{}`: no ICD manifest at {} (for lavapipe run `bash scripts/setup.sh`)",
            a.driver,
            driver.icd_path().display()
        ));
    }
    let triage = Triage::load(
        &super::repo_dir().join("triage"),
        &a.triage,
        set.version.as_deref(),
        &driver.name(),
    )?;
    std::fs::create_dir_all(a.out.join("failures"))
        .map_err(|e| format!("{}: {e}", a.out.display()))?;
    let results_path = a.out.join("results.jsonl");
    let done = if a.resume {
        done_cases(&results_path)
    } else {
        let _ = std::fs::remove_file(&results_path);
        BTreeSet::new()
    };
    let mut results = std::fs::OpenOptions::new()
        .create(true)
        .append(true)
        .open(&results_path)
        .map_err(|e| format!("{}: {e}", results_path.display()))?;
    std::env::set_var(harness::worker::DRIVER_ENV, &a.driver);

    let specs = plan_specs(&a, &rules, &profile);
    let build_rules = model::accel::BuildRuleSet::from_vuids(&set);
    let build_specs = if a.command.iter().any(|c| c == BUILD_COMMAND) {
        build_specs(&a, &build_rules)
    } else {
        vec![]
    };
    let total = (specs.len() + build_specs.len()) * a.count;
    let bar = if std::io::IsTerminal::is_terminal(&std::io::stderr()) {
        let b = indicatif::ProgressBar::new(total as u64);
        b.set_style(
            indicatif::ProgressStyle::with_template(
                "{bar:40} {pos}/{len} cases {elapsed_precise} {msg}",
            )
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
        );
        b
    } else {
        indicatif::ProgressBar::hidden()
    };
    // Specs a generator cannot make on this profile (a feature or queue the device lacks) are listed,
    // not failed; any other generator error is a failure of the run.
    let mut gen_errors = Vec::new();
    let mut not_expressible = Vec::new();
    let handle_size = profile.limit("shaderGroupHandleSize").unwrap_or(32);
    // Cases are generated spec by spec into a bounded chunk; a full chunk runs on one set of workers
    // (which keep their devices and pipelines warm) and its results are written before the next
    // chunk is generated, so memory stays flat however long the run.
    let mut chunk: Vec<Case> = Vec::with_capacity(CHUNK);
    let run_chunk = |chunk: &mut Vec<Case>, results: &mut std::fs::File| -> Result<(), String> {
        let cases = std::mem::take(chunk);
        let mut write_error = None;
        run_in_workers(&cases, a.jobs, Duration::from_secs(a.timeout), |res| {
            let case = &cases[res.index.min(cases.len() - 1)];
            let verdict = model::validate(&rules, &profile, &case.world, &case.call);
            let report = compare(case, &verdict, &res.observation, &triage, res.millis);
            if report.outcome != Outcome::Pass && report.outcome != Outcome::Unsupported {
                let _ = std::fs::write(
                    a.out.join("failures").join(format!("{}.yaml", case.name)),
                    case.to_yaml(),
                );
            }
            let line = serde_json::to_string(&report).unwrap_or_default();
            if let Err(e) = writeln!(results, "{line}").and_then(|_| results.flush()) {
                write_error = Some(e.to_string());
            }
            bar.inc(1);
        });
        match write_error {
            Some(e) => Err(format!("{}: {e}", results_path.display())),
            None => Ok(()),
        }
    };
    let slices = |count: usize| {
        (0..count)
            .step_by(CHUNK)
            .map(move |start| start..(start + CHUNK).min(count))
    };
    for (i, spec) in specs.iter().enumerate() {
        let seed = a.seed.wrapping_add(i as u64);
        for range in slices(a.count) {
            let len = range.len();
            let cases =
                match generator::generate_range(&profile, &profile_name, &rules, spec, range, seed)
                {
                    Ok(c) => c,
                    Err(e @ generator::GenError::Unsupported(_)) => {
                        not_expressible.push(format!("{}: {e}", spec_label(spec)));
                        bar.inc(a.count as u64);
                        break;
                    }
                    Err(e) => {
                        gen_errors.push(format!("{}: {e}", spec_label(spec)));
                        bar.inc(a.count as u64);
                        break;
                    }
                };
            debug_assert!(cases.len() == len);
            for c in cases {
                if done.contains(&c.name) {
                    bar.inc(1);
                    continue;
                }
                // A valid case whose launch reads outside its tables is undefined behaviour: never hand it
                // to the driver; report it as the generator bug it is.
                let reads = model::semantics::undefined_reads(handle_size, &c.world, &c.call);
                if c.intent == model::Intent::Valid && !reads.is_empty() {
                    let report = harness::compare::undefined_case(&c, &reads);
                    let _ = std::fs::write(
                        a.out.join("failures").join(format!("{}.yaml", c.name)),
                        c.to_yaml(),
                    );
                    let _ = writeln!(
                        results,
                        "{}",
                        serde_json::to_string(&report).unwrap_or_default()
                    );
                    bar.inc(1);
                    continue;
                }
                chunk.push(c);
                if chunk.len() == CHUNK {
                    run_chunk(&mut chunk, &mut results)?;
                }
            }
        }
    }
    if !chunk.is_empty() {
        run_chunk(&mut chunk, &mut results)?;
    }
    if a.command.iter().any(|c| c == BUILD_COMMAND) {
        run_builds(
            &a,
            &set,
            &profile,
            &profile_name,
            &triage,
            &done,
            &bar,
            &mut results,
        )
        .map_err(|e| format!("{}: {e}", results_path.display()))?;
    }
    bar.finish_and_clear();
    let mut summary = summarise(&results_path, &a.driver, &profile_name, set.version.clone())?;
    summary.runner_peak_rss_kib = peak_rss_kib();
    summary.seconds = started.elapsed().as_secs_f64();
    std::fs::write(
        a.out.join("summary.json"),
        serde_json::to_string_pretty(&summary).unwrap_or_default() + "\n",
    )
    .map_err(|e| e.to_string())?;
    write_junit(&results_path, &a.out.join("junit.xml"), &summary)?;
    if a.shrink > 0 {
        shrink_failures(&a, &rules, &profile, &profile_name, &triage, &results_path);
    }
    print_summary(&summary, &a.out);
    if !not_expressible.is_empty() {
        println!(
            "{} specs are not expressible on profile {profile_name}:",
            not_expressible.len()
        );
        for e in &not_expressible {
            println!("  {e}");
        }
    }
    for e in &gen_errors {
        eprintln!("rtconf: could not generate {e}");
    }
    let unexpected = summary.failed + summary.crashes + summary.timeouts;
    Ok(if unexpected > 0 || !gen_errors.is_empty() {
        1
    } else {
        0
    })
}

/// A spec as a person reads it: the command and the VUID it violates, or `valid`.
fn spec_label(spec: &CaseSpec) -> String {
    match &spec.intent {
        generator::SpecIntent::Valid => format!("{} valid", spec.command.vk_name()),
        generator::SpecIntent::Violate(v) => v.clone(),
    }
}

/// The build command's name on the command line.
const BUILD_COMMAND: &str = model::accel::call::COMMAND;

/// The build specs of a run: `None` for valid cases, then every executable build VUID with a mutation.
fn build_specs(a: &RunArgs, rules: &model::accel::BuildRuleSet) -> Vec<Option<String>> {
    let mut specs = Vec::new();
    if a.vuid.is_empty() {
        specs.push(None);
    }
    if a.valid_only {
        return specs;
    }
    let mut seen = BTreeSet::new();
    for row in &rules.rows {
        if !a.vuid.is_empty() && !a.vuid.contains(&row.vuid) {
            continue;
        }
        if generator::accel::mutation_for(&row.vuid).is_some() && seen.insert(row.vuid.clone()) {
            specs.push(Some(row.vuid.clone()));
        }
    }
    specs
}

/// The profile file a worker loads (as `super::profile_for` resolves a name).
fn profile_path(name: &str) -> PathBuf {
    if name.ends_with(".json") || name.contains('/') {
        PathBuf::from(name)
    } else {
        super::profiles_dir().join(format!("{name}.json"))
    }
}

/// Runs the build specs: cases generated a chunk at a time into worker requests, each result judged
/// again by the model with the device's sizes and written to `results.jsonl` as it arrives.
#[allow(clippy::too_many_arguments)]
fn run_builds(
    a: &RunArgs,
    set: &vk_registry::vuid::VuidSet,
    profile: &DeviceProfile,
    profile_name: &str,
    triage: &Triage,
    done: &BTreeSet<String>,
    bar: &indicatif::ProgressBar,
    results: &mut std::fs::File,
) -> Result<(), String> {
    let rules = model::accel::BuildRuleSet::from_vuids(set);
    generator::accel::use_rules(rules.clone());
    let unavoidable = generator::accel::unavoidable(profile);
    let sources = super::sources_or_default(&a.from);
    let sources: Vec<PathBuf> = sources
        .iter()
        .map(|p| std::fs::canonicalize(p).unwrap_or_else(|_| p.clone()))
        .collect();
    let ppath = profile_path(profile_name);
    let ppath = std::fs::canonicalize(&ppath).unwrap_or(ppath);
    let mut write_error = None;
    let mut run_chunk = |chunk: &mut Vec<BuildRequest>, results: &mut std::fs::File| {
        let reqs = std::mem::take(chunk);
        run_builds_in_workers(&reqs, a.jobs, Duration::from_secs(a.timeout), |res| {
            let req = &reqs[res.index.min(reqs.len() - 1)];
            let case = &req.build;
            let mut world = case.world.clone();
            if !res.observation.device_sizes.is_empty() {
                world.sizes = res.observation.device_sizes.clone();
            }
            let verdict = rules.validate(profile, &world, &case.call);
            let model: BTreeSet<String> = verdict.violations.into_iter().map(|v| v.vuid).collect();
            let model: Vec<String> = model.into_iter().collect();
            let report = compare_build(
                case,
                &model,
                &res.observation,
                &unavoidable,
                triage,
                res.millis,
            );
            if report.outcome != Outcome::Pass && report.outcome != Outcome::Unsupported {
                let _ = std::fs::write(
                    a.out.join("failures").join(format!("{}.yaml", case.name)),
                    case.to_yaml(),
                );
            }
            let line = serde_json::to_string(&report).unwrap_or_default();
            if let Err(e) = writeln!(results, "{line}").and_then(|_| results.flush()) {
                write_error = Some(e.to_string());
            }
            bar.inc(1);
        });
    };
    let mut chunk: Vec<BuildRequest> = Vec::with_capacity(CHUNK);
    for (i, target) in build_specs(a, &rules).iter().enumerate() {
        let seed = a.seed.wrapping_add(i as u64);
        for start in (0..a.count).step_by(CHUNK) {
            let range = start..(start + CHUNK).min(a.count);
            let len = range.len();
            let cases = generator::accel::generate_range(profile, target.as_deref(), seed, range);
            // Indices no plan fits give no case: counted done on the bar.
            bar.inc((len - cases.len()) as u64);
            for c in cases {
                if done.contains(&c.name) {
                    bar.inc(1);
                    continue;
                }
                chunk.push(BuildRequest {
                    index: 0,
                    build: c,
                    profile_name: profile_name.to_string(),
                    profile_path: ppath.clone(),
                    sources: sources.clone(),
                    options: Default::default(),
                });
                if chunk.len() == CHUNK {
                    run_chunk(&mut chunk, results);
                }
            }
        }
    }
    if !chunk.is_empty() {
        run_chunk(&mut chunk, results);
    }
    match write_error {
        Some(e) => Err(e),
        None => Ok(()),
    }
}

/// The reports of `results.jsonl`, read one line at a time.
fn reports(path: &Path) -> Result<impl Iterator<Item = CaseReport>, String> {
    let f = std::fs::File::open(path).map_err(|e| format!("{}: {e}", path.display()))?;
    Ok(std::io::BufReader::new(f)
        .lines()
        .map_while(Result::ok)
        .filter_map(|l| serde_json::from_str::<CaseReport>(&l).ok()))
}

/// Reads `results.jsonl` back, streaming, into the summary; a resumed run never runs a case twice, so
/// each line is one case. Memory is per VUID, not per case.
fn summarise(
    path: &Path,
    driver: &str,
    profile: &str,
    registry: Option<String>,
) -> Result<Summary, String> {
    let mut s = Summary {
        driver: driver.into(),
        profile: profile.into(),
        registry,
        ..Default::default()
    };
    for r in reports(path)? {
        s.cases += 1;
        match r.outcome {
            Outcome::Pass => s.passed += 1,
            Outcome::Fail => s.failed += 1,
            Outcome::Triaged => s.triaged += 1,
            Outcome::Unsupported => s.unsupported += 1,
            Outcome::Crash => s.crashes += 1,
            Outcome::Timeout => s.timeouts += 1,
        }
        if matches!(
            r.outcome,
            Outcome::Unsupported | Outcome::Crash | Outcome::Timeout
        ) {
            continue;
        }
        let m: BTreeSet<&String> = r.model.iter().collect();
        let l: BTreeSet<&String> = r.layer.iter().collect();
        for v in m.union(&l) {
            let t = s.vuids.entry((*v).clone()).or_default();
            t.cases += 1;
            t.model += m.contains(v) as usize;
            t.layer += l.contains(v) as usize;
            t.agree += (m.contains(v) == l.contains(v)) as usize;
        }
    }
    Ok(s)
}

fn xml_escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// Writes the JUnit report (one suite for the run; triaged cases pass, unsupported ones are skipped),
/// streaming from `results.jsonl` so memory does not grow with the run.
fn write_junit(results: &Path, out: &Path, s: &Summary) -> Result<(), String> {
    let mut w = std::io::BufWriter::new(
        std::fs::File::create(out).map_err(|e| format!("{}: {e}", out.display()))?,
    );
    let name = xml_escape(&format!("rtconf on {}", s.driver));
    let errors = s.crashes + s.timeouts;
    let head = format!(
        "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<testsuites name=\"{name}\" tests=\"{}\" failures=\"{}\" errors=\"{errors}\">\n  <testsuite name=\"{name}\" tests=\"{}\" failures=\"{}\" errors=\"{errors}\" skipped=\"{}\">\n",
        s.cases, s.failed, s.cases, s.failed, s.unsupported
    );
    let io = |e: std::io::Error| format!("{}: {e}", out.display());
    w.write_all(head.as_bytes()).map_err(io)?;
    for r in reports(results)? {
        let open = format!(
            "    <testcase name=\"{}\" classname=\"{}.{}\" time=\"{:.3}\"",
            xml_escape(&r.case),
            xml_escape(&s.driver),
            xml_escape(&r.command),
            r.millis.max(0.0) / 1000.0
        );
        let msg = xml_escape(&r.detail);
        let body = match r.outcome {
            Outcome::Pass | Outcome::Triaged => "/>\n".to_string(),
            Outcome::Unsupported => format!("><skipped message=\"{msg}\"/></testcase>\n"),
            Outcome::Fail => format!("><failure message=\"{msg}\"/></testcase>\n"),
            Outcome::Crash | Outcome::Timeout => {
                format!("><error message=\"{:?}: {msg}\"/></testcase>\n", r.outcome)
            }
        };
        w.write_all(open.as_bytes())
            .and_then(|_| w.write_all(body.as_bytes()))
            .map_err(io)?;
    }
    w.write_all(b"  </testsuite>\n</testsuites>\n")
        .and_then(|_| w.flush())
        .map_err(io)
}

/// Shrinks up to `a.shrink` failing cases of the run, each to a minimal case that still fails the same
/// way on the driver, written to `cases/regressions/` with its seed (replay it with `rtconf replay`).
fn shrink_failures(
    a: &RunArgs,
    rules: &RuleSet,
    profile: &DeviceProfile,
    profile_name: &str,
    triage: &Triage,
    results: &Path,
) {
    let Ok(f) = std::fs::File::open(results) else {
        return;
    };
    let failing: Vec<String> = std::io::BufReader::new(f)
        .lines()
        .map_while(Result::ok)
        .filter_map(|l| serde_json::from_str::<CaseReport>(&l).ok())
        .filter(|r| r.outcome == Outcome::Fail)
        .map(|r| r.case)
        .take(a.shrink)
        .collect();
    if failing.is_empty() {
        return;
    }
    let executor = match harness::Executor::new(harness::vulkan::Driver::parse(&a.driver)) {
        Ok(e) => std::cell::RefCell::new(e),
        Err(e) => {
            eprintln!("rtconf: cannot shrink: {e}");
            return;
        }
    };
    let dir = super::repo_dir().join("cases").join("regressions");
    for name in failing {
        let path = a.out.join("failures").join(format!("{name}.yaml"));
        let Some(case) = std::fs::read_to_string(&path)
            .ok()
            .and_then(|t| Case::from_yaml(&name, &t).ok())
        else {
            continue;
        };
        let Some((seed, index)) = case.seed.as_deref().and_then(|s| s.split_once('/')) else {
            continue;
        };
        let (Ok(seed), Ok(index)) = (seed.parse::<u64>(), index.parse::<usize>()) else {
            continue;
        };
        let Some(command) = generator::Command::from_vk_name(case.call.command()) else {
            continue;
        };
        let mut spec = match &case.intent {
            model::Intent::Valid => CaseSpec::valid(command),
            model::Intent::Violates { vuid, .. } => CaseSpec::violate(command, vuid),
        };
        if name.contains("-limits-") {
            spec = spec.at_limits();
        }
        let fails = |c: &Case| {
            let verdict = model::validate(rules, profile, &c.world, &c.call);
            let obs = harness::execute(c, &mut executor.borrow_mut());
            compare(c, &verdict, &obs, triage, 0.0).outcome == Outcome::Fail
        };
        match generator::shrink_failure(
            profile,
            profile_name,
            rules,
            &spec,
            seed,
            index,
            &dir,
            fails,
        ) {
            Ok(Some(s)) => println!("shrunk {name} in {} steps: {}", s.steps, s.path.display()),
            Ok(None) => println!(
                "{name} no longer fails when regenerated from its seed; kept as {}",
                path.display()
            ),
            Err(e) => eprintln!("rtconf: shrinking {name}: {e}"),
        }
    }
}

fn print_summary(s: &Summary, out: &Path) {
    println!(
        "{:<78} {:>6} {:>6} {:>6} {:>6}",
        "VUID", "cases", "model", "layer", "agree"
    );
    for (v, t) in &s.vuids {
        println!(
            "{:<78} {:>6} {:>6} {:>6} {:>6}",
            v, t.cases, t.model, t.layer, t.agree
        );
    }
    println!();
    println!(
        "{} cases on {} (profile {}): {} passed, {} failed, {} triaged, {} unsupported, {} crashes, {} timeouts",
        s.cases, s.driver, s.profile, s.passed, s.failed, s.triaged, s.unsupported, s.crashes, s.timeouts
    );
    println!(
        "{:.1} s, {:.0} cases/s, runner peak RSS {} KiB",
        s.seconds,
        s.cases as f64 / s.seconds.max(1e-9),
        s.runner_peak_rss_kib.map_or("?".into(), |k| k.to_string())
    );
    println!(
        "results: {0}/results.jsonl, summary: {0}/summary.json, junit: {0}/junit.xml, failing cases: {0}/failures/",
        out.display()
    );
}
