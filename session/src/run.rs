//! A conformance run: the plan's cases generated a chunk at a time, each gated (a valid case never
//! hands undefined behaviour to a driver), dispatched to worker processes, judged once by the model
//! with what the device reported, compared with what the device did, and streamed to `results.jsonl`
//! as it completes; then `summary.json`, `junit.xml`, and shrunk regressions when asked.

use crate::compare::{as_run, compare, not_runnable, CaseReport, Outcome};
use crate::error::SessionError;
use crate::plan::{plan, Scope};
use crate::report::{reports, summarise, write_junit, Summary};
use crate::sources;
use crate::triage::Triage;
use harness::{Driver, Execution, Request, Response};
use model::{Case, DeviceProfile, RuleSet};
use std::collections::BTreeSet;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Duration;

/// Everything a run is asked to do.
#[derive(Debug, Clone)]
pub struct RunConfig {
    /// `lavapipe`, `nvidia`, or the path of an ICD manifest.
    pub driver: String,
    /// The device profile cases are generated from (None: the driver's, see
    /// [`sources::default_profile_name`]).
    pub profile: Option<String>,
    pub scope: Scope,
    /// Cases per spec.
    pub count: usize,
    /// Worker processes.
    pub jobs: usize,
    /// Seconds a case may take.
    pub timeout: u64,
    pub out: PathBuf,
    /// Shrink up to this many failing cases to minimal ones in `cases/regressions/`.
    pub shrink: usize,
    /// Continue a killed run: cases already in `results.jsonl` are not run again.
    pub resume: bool,
    /// Registry sources for the rules (empty: the installed registry).
    pub from: Vec<PathBuf>,
    /// Triage files (empty: the driver's and the layer version's, where present).
    pub triage: Vec<PathBuf>,
}

/// How far a run has come, for a progress display.
pub trait Progress {
    /// The number of cases the run plans (some specs may give fewer).
    fn planned(&self, cases: u64);
    /// `n` more cases are done (run, skipped, or not generated).
    fn advance(&self, n: u64);
}

/// A progress display that shows nothing.
pub struct Quiet;

impl Progress for Quiet {
    fn planned(&self, _: u64) {}
    fn advance(&self, _: u64) {}
}

/// What a run did, besides the files it wrote.
#[derive(Debug)]
pub struct RunOutcome {
    pub summary: Summary,
    /// Specs the generator cannot make on this profile (a feature or queue the device lacks).
    pub not_expressible: Vec<String>,
    /// Specs the generator failed on: a failure of the run.
    pub gen_errors: Vec<String>,
    /// One line per shrunk (or no longer failing) case.
    pub shrunk: Vec<String>,
}

impl RunOutcome {
    /// The exit status of the run: non-zero for any fail, crash, timeout or generator error.
    pub fn exit_code(&self) -> i32 {
        let s = &self.summary;
        let unexpected = s.failed + s.crashes + s.timeouts;
        if unexpected > 0 || !self.gen_errors.is_empty() {
            1
        } else {
            0
        }
    }
}

/// Cases generated ahead of the workers: bounds memory, and amortises worker start-up.
const CHUNK: usize = 512;

/// What every case of a run is judged with.
pub struct Judging<'a> {
    pub rules: &'a RuleSet,
    pub profile: &'a DeviceProfile,
    pub triage: &'a Triage,
}

impl Judging<'_> {
    /// The one judgement of a case: the model's verdict on the case as it ran (a build with the sizes
    /// the device reported), compared with the observation.
    pub fn judge(&self, case: &Case, resp: &Response) -> CaseReport {
        let ran = as_run(case, &resp.observation);
        let verdict = self.rules.judge(self.profile, &ran.body);
        compare(
            &ran,
            self.profile,
            &verdict,
            &resp.observation,
            self.triage,
            resp.millis,
        )
    }
}

/// One case run in this process and judged, as a run judges it.
#[derive(Debug, Clone)]
pub struct Ran {
    /// The case as it ran (a build with the sizes the device reported).
    pub case: Case,
    /// None when the gate kept the case from the driver.
    pub observation: Option<harness::Observation>,
    pub verdict: model::Verdict,
    pub report: CaseReport,
}

impl Judging<'_> {
    /// Runs one case on `executor` and judges it: the gate ([`Case::runnable`]), the execution (for
    /// real when the case runs as valid; a build's rays traced as `check` says), the verdict on the
    /// case as it ran, and the comparison.
    pub fn run_here(
        &self,
        executor: &mut harness::Executor,
        case: &Case,
        check: harness::TraceCheck,
    ) -> Ran {
        if let Err(why) = case.runnable(self.profile) {
            return Ran {
                case: case.clone(),
                verdict: model::validate(self.rules, self.profile, case),
                observation: None,
                report: not_runnable(case, &why),
            };
        }
        let exec = Execution {
            check,
            ..Execution::for_case(case, self.profile)
        };
        let started = std::time::Instant::now();
        let observation = executor.execute(case, &exec);
        let millis = started.elapsed().as_secs_f64() * 1000.0;
        let ran = as_run(case, &observation).into_owned();
        let verdict = self.rules.judge(self.profile, &ran.body);
        let report = compare(
            &ran,
            self.profile,
            &verdict,
            &observation,
            self.triage,
            millis,
        );
        Ran {
            case: ran,
            observation: Some(observation),
            verdict,
            report,
        }
    }
}

/// Where a run writes: `results.jsonl` (appended and flushed per case) and `failures/`.
struct Sink {
    out: PathBuf,
    results_path: PathBuf,
    results: std::fs::File,
    error: Option<std::io::Error>,
}

impl Sink {
    fn write(&mut self, case: &Case, report: &CaseReport) {
        if report.outcome != Outcome::Pass && report.outcome != Outcome::Unsupported {
            let _ = std::fs::write(
                self.out
                    .join("failures")
                    .join(format!("{}.yaml", case.name)),
                case.to_yaml(),
            );
        }
        let line = serde_json::to_string(report).unwrap_or_default();
        if let Err(e) = writeln!(self.results, "{line}").and_then(|_| self.results.flush()) {
            self.error.get_or_insert(e);
        }
    }
}

/// Runs the configured conformance run; see the module documentation.
pub fn run(config: &RunConfig, progress: &dyn Progress) -> Result<RunOutcome, SessionError> {
    let started = std::time::Instant::now();
    let set = sources::load_sources(&config.from)?;
    let rules = RuleSet::from_vuids(&set);
    let profile_name = config
        .profile
        .clone()
        .unwrap_or_else(|| sources::default_profile_name(&config.driver));
    let profile = sources::profile_for(&profile_name)?;
    let driver = Driver::parse(&config.driver);
    if !driver.icd_path().exists() {
        return Err(SessionError::NoDriver {
            driver: config.driver.clone(),
            path: driver.icd_path().display().to_string(),
        });
    }
    let triage = sources::triage_for(&config.triage, set.version.as_deref(), &driver)?;
    let failures = config.out.join("failures");
    std::fs::create_dir_all(&failures)
        .map_err(|e| SessionError::io(failures.display().to_string(), e))?;
    let results_path = config.out.join("results.jsonl");
    let done = if config.resume {
        done_cases(&results_path)
    } else {
        let _ = std::fs::remove_file(&results_path);
        BTreeSet::new()
    };
    let results = std::fs::OpenOptions::new()
        .create(true)
        .append(true)
        .open(&results_path)
        .map_err(|e| SessionError::io(results_path.display().to_string(), e))?;
    let mut sink = Sink {
        out: config.out.clone(),
        results_path: results_path.clone(),
        results,
        error: None,
    };
    std::env::set_var(harness::worker::DRIVER_ENV, &config.driver);
    let judging = Judging {
        rules: &rules,
        profile: &profile,
        triage: &triage,
    };

    let specs = plan(&config.scope, &rules, &profile);
    let count_of =
        |p: &crate::plan::PlannedSpec| p.count.map_or(config.count, |n| n.max(config.count));
    progress.planned(specs.iter().map(count_of).sum::<usize>() as u64);
    let mut not_expressible = Vec::new();
    let mut gen_errors = Vec::new();
    let mut chunk: Vec<Case> = Vec::with_capacity(CHUNK);
    let dispatch = Dispatch {
        jobs: config.jobs,
        timeout: Duration::from_secs(config.timeout),
        judging: &judging,
        progress,
    };
    let mut family = None;
    for planned in &specs {
        // A chunk holds cases of one command family, in the plan's order.
        let this = planned.spec.command.is_trace();
        if family.is_some_and(|f| f != this) && !chunk.is_empty() {
            dispatch.run(&mut chunk, &mut sink);
        }
        family = Some(this);
        let count = count_of(planned);
        for range in slices(count) {
            let len = range.len();
            let cases = match generator::generate_range(
                &profile,
                &profile_name,
                &rules,
                &planned.spec,
                range,
                planned.seed,
            ) {
                Ok(c) => c,
                Err(e @ generator::GenError::Unsupported(_)) => {
                    not_expressible.push(format!("{}: {e}", planned.label()));
                    progress.advance(count as u64);
                    break;
                }
                Err(e) => {
                    gen_errors.push(format!("{}: {e}", planned.label()));
                    progress.advance(count as u64);
                    break;
                }
            };
            // Indices no build plan fits give no case: counted done.
            progress.advance((len - cases.len()) as u64);
            for c in cases {
                if done.contains(&c.name) {
                    progress.advance(1);
                    continue;
                }
                if let Err(why) = c.runnable(&profile) {
                    sink.write(&c, &not_runnable(&c, &why));
                    progress.advance(1);
                    continue;
                }
                chunk.push(c);
                if chunk.len() == CHUNK {
                    dispatch.run(&mut chunk, &mut sink);
                }
            }
        }
    }
    if !chunk.is_empty() {
        dispatch.run(&mut chunk, &mut sink);
    }
    if let Some(e) = sink.error.take() {
        return Err(SessionError::io(sink.results_path.display().to_string(), e));
    }
    let mut summary = summarise(
        &results_path,
        &config.driver,
        &profile_name,
        set.version.clone(),
    )?;
    summary.runner_peak_rss_kib = peak_rss_kib();
    summary.seconds = started.elapsed().as_secs_f64();
    let summary_path = config.out.join("summary.json");
    std::fs::write(
        &summary_path,
        serde_json::to_string_pretty(&summary).unwrap_or_default() + "\n",
    )
    .map_err(|e| SessionError::io(summary_path.display().to_string(), e))?;
    write_junit(&results_path, &config.out.join("junit.xml"), &summary)?;
    let shrunk = if config.shrink > 0 {
        crate::shrink::shrink_failures(config, &judging, &profile_name, &results_path)
    } else {
        vec![]
    };
    Ok(RunOutcome {
        summary,
        not_expressible,
        gen_errors,
        shrunk,
    })
}

/// How a run's chunks go to the workers and their results to the judge.
struct Dispatch<'a> {
    jobs: usize,
    timeout: Duration,
    judging: &'a Judging<'a>,
    progress: &'a dyn Progress,
}

impl Dispatch<'_> {
    /// Runs one chunk on a fresh set of workers (which keep their devices and pipelines warm for the
    /// chunk), judging and writing each result as it arrives.
    fn run(&self, chunk: &mut Vec<Case>, sink: &mut Sink) {
        let requests: Vec<Request> = std::mem::take(chunk)
            .into_iter()
            .enumerate()
            .map(|(index, case)| Request {
                index,
                execution: Execution::for_case(&case, self.judging.profile),
                case,
            })
            .collect();
        harness::run_in_workers(&requests, self.jobs, self.timeout, |resp| {
            let case = &requests[resp.index.min(requests.len() - 1)].case;
            let report = self.judging.judge(case, &resp);
            sink.write(case, &report);
            crate::pictures::for_failure(
                &sink.out.join("failures"),
                case,
                &resp.observation,
                &report,
            );
            self.progress.advance(1);
        });
    }
}

/// `0..count` in slices of [`CHUNK`].
fn slices(count: usize) -> impl Iterator<Item = std::ops::Range<usize>> {
    (0..count)
        .step_by(CHUNK)
        .map(move |start| start..(start + CHUNK).min(count))
}

/// The cases a killed run already wrote.
fn done_cases(results: &Path) -> BTreeSet<String> {
    match reports(results) {
        Ok(r) => r.map(|r| r.case).collect(),
        Err(_) => BTreeSet::new(),
    }
}

/// `VmHWM` of this process from /proc (None elsewhere).
fn peak_rss_kib() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    line.split_whitespace().nth(1)?.parse().ok()
}
