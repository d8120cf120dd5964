//! A conformance run: the plan's cases generated a chunk at a time, each gated (a valid case never
//! hands undefined behaviour to a driver), dispatched to worker processes, judged once by the model
//! with what the device reported, compared with what the device did, and streamed to `results.jsonl`
//! as it completes; then `summary.json`, `junit.xml`, and shrunk regressions when asked.

use crate::compare::{as_run, compare, CaseReport, Outcome};
use crate::error::SessionError;
use crate::plan::{plan, Scope};
use crate::report::{summarise, write_junit, Summary};
use crate::sources;
use crate::triage::Triage;
use harness::{Driver, Execution, Request, Response};
use model::{Case, DeviceProfile, RuleSet};
use std::io::Write;
use std::path::PathBuf;
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
    /// What each `--vuid` pattern expanded to, before anything is generated.
    fn selected(&self, _expanded: &[crate::select::Expanded]) {}
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
    /// The exit status of the run: non-zero for any fail, crash, timeout, case error or generator error,
    /// and for a run that made no case.
    pub fn exit_code(&self) -> i32 {
        let s = &self.summary;
        let unexpected = s.failed + s.crashes + s.timeouts + s.case_errors;
        // A run that made no case checked nothing: never a pass.
        if unexpected > 0 || !self.gen_errors.is_empty() || s.cases == 0 {
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
        if let Some(report) = crate::gate::gate(case, self) {
            return Ran {
                case: case.clone(),
                verdict: model::validate(self.rules, self.profile, case),
                observation: None,
                report,
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

impl Judging<'_> {
    /// Runs one case in a worker process (`rtconf worker`, the driver named by
    /// [`harness::worker::DRIVER_ENV`]) as a run does, and judges it: the gate, the execution, the
    /// verdict on the case as it ran, the comparison. A driver that kills or hangs the worker gives the
    /// case's `crash` or `timeout`, as in a run.
    pub fn run_in_worker(&self, case: &Case, check: harness::TraceCheck, timeout: Duration) -> Ran {
        if let Some(report) = crate::gate::gate(case, self) {
            return Ran {
                case: case.clone(),
                verdict: model::validate(self.rules, self.profile, case),
                observation: None,
                report,
            };
        }
        let request = Request {
            index: 0,
            execution: Execution {
                check,
                ..Execution::for_case(case, self.profile)
            },
            case: case.clone(),
        };
        let mut response = None;
        harness::run_in_workers(std::slice::from_ref(&request), 1, timeout, |r| {
            response = Some(r)
        });
        let resp = response.unwrap_or_else(|| Response {
            index: 0,
            name: case.name.clone(),
            observation: harness::Observation::crash("the worker gave no result"),
            millis: 0.0,
        });
        let ran = as_run(case, &resp.observation).into_owned();
        let verdict = self.rules.judge(self.profile, &ran.body);
        let report = compare(
            &ran,
            self.profile,
            &verdict,
            &resp.observation,
            self.triage,
            resp.millis,
        );
        Ran {
            case: ran,
            observation: Some(resp.observation),
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
    /// The first write that failed: the file and the error.
    error: Option<(PathBuf, std::io::Error)>,
}

impl Sink {
    /// Writes a case's failure file (whole or not at all) and then its line; the first error is kept
    /// and ends the run.
    fn write(&mut self, case: &Case, report: &CaseReport) {
        // After a failed write nothing more is written: a later line must not follow a torn one.
        if self.error.is_some() {
            return;
        }
        if report.outcome != Outcome::Pass && report.outcome != Outcome::Unsupported {
            let path = self
                .out
                .join("failures")
                .join(format!("{}.yaml", case.name));
            if let Err(e) = crate::outdir::write_atomically(&path, case.to_yaml().as_bytes()) {
                self.error.get_or_insert((path, e));
            }
        }
        let line = serde_json::to_string(report).unwrap_or_default();
        if let Err(e) = writeln!(self.results, "{line}").and_then(|_| self.results.flush()) {
            self.error.get_or_insert((self.results_path.clone(), e));
        }
    }
}

/// Runs the configured conformance run; see the module documentation.
pub fn run(config: &RunConfig, progress: &dyn Progress) -> Result<RunOutcome, SessionError> {
    let started = std::time::Instant::now();
    let set = sources::load_sources(&config.from)?;
    let rules = RuleSet::from_vuids(&set);
    // The driver first: a path that is not a driver is never taken for a profile's name.
    let driver = Driver::parse(&config.driver);
    harness::check_driver(&driver)?;
    let profile_name = config
        .profile
        .clone()
        .unwrap_or_else(|| sources::default_profile_name(&config.driver));
    let profile = sources::profile_for(&profile_name)?;
    let triage = sources::triage_for(&config.triage, set.version.as_deref(), &driver)?;
    let params = crate::outdir::RunParameters {
        driver: config.driver.clone(),
        profile: profile_name.clone(),
        command: config
            .scope
            .commands
            .iter()
            .map(|c| c.vk_name().to_string())
            .collect(),
        vuid: config.scope.vuids.clone(),
        valid_only: config.scope.valid_only,
        seed: config.scope.seed,
        count: config.count,
        rendered: config.scope.rendered,
        from: config
            .from
            .iter()
            .map(|p| p.display().to_string())
            .collect(),
        registry: set.version.clone(),
        triage: config
            .triage
            .iter()
            .map(|p| p.display().to_string())
            .collect(),
    };
    let done = crate::outdir::prepare(&config.out, &params, config.resume)?;
    let results_path = config.out.join("results.jsonl");
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

    let mut scope = config.scope.clone();
    if !scope.vuids.is_empty() {
        let mut known: Vec<String> = rules.rows.iter().map(|r| r.vuid.clone()).collect();
        known.sort();
        known.dedup();
        let expanded = crate::select::expand_vuids(&scope.vuids, &known)?;
        progress.selected(&expanded);
        scope.vuids = expanded.into_iter().flat_map(|e| e.vuids).collect();
        scope.vuids.sort();
        scope.vuids.dedup();
    }
    let specs = plan(&scope, &rules, &profile);
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
    'specs: for planned in &specs {
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
                // A write that failed (a full disk) ends the run: nothing more could be kept.
                if sink.error.is_some() {
                    break 'specs;
                }
                if done.contains(&c.name) {
                    progress.advance(1);
                    continue;
                }
                if let Some(report) = crate::gate::gate(&c, &judging) {
                    sink.write(&c, &report);
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
    if let Some((path, e)) = sink.error.take() {
        return Err(SessionError::io(
            format!(
                "{} (resume with --resume once there is room)",
                path.display()
            ),
            e,
        ));
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

/// `VmHWM` of this process from /proc (None elsewhere).
fn peak_rss_kib() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    line.split_whitespace().nth(1)?.parse().ok()
}
