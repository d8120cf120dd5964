//! A conformance run: the plan's cases generated on a producer thread while worker processes run the
//! earlier ones, each gated (a valid case never hands undefined behaviour to a driver) and dispatched
//! to a worker (`dispatch`), judged once by the model
//! with what the device reported, compared with what the device did, and streamed to `results.jsonl`
//! as it completes (failing cases run again to tell a flake, each with its status against the
//! baseline); then `summary.json`, `junit.xml`, the HTML report, and shrunk regressions when asked.

use crate::baseline::{Expectations, Status};
use crate::compare::{as_run, compare, CaseReport, Outcome};
use crate::details::{keep, CaseDetails};
use crate::error::SessionError;
use crate::plan::{plan, Scope};
use crate::report::{judge_triage, reports, write_junit, RunIdentity, Summary};
use crate::results::{applied_triage, ResultLine};
use crate::select::Selection;
use crate::sources;
use crate::triage::Triage;
use harness::{Driver, Execution, Request, Response};
use model::{Case, DeviceProfile, RuleSet, Verdict};
use std::collections::BTreeSet;
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
    /// A validation layer build to use instead of the one the loader finds (a manifest directory or
    /// an unpacked package root, see [`harness::select_layer`]).
    pub layer: Option<PathBuf>,
    /// Stale triage entries fail the run (they are always reported).
    pub strict: bool,
    /// Which cases run (a case folder, a shard, the baseline, skips and flakes, retries).
    pub selection: Selection,
    /// Hand the driver a perturbed copy of each valid trace case while the model judges the case
    /// itself (`crate::inject`), drawn from the run's seed.
    pub inject: Option<crate::inject::Injection>,
    /// Also keep the case files of the cases whose outcome is already explained (triaged,
    /// unsupported, not realised; see [`crate::details::keeps_file`]).
    pub keep_all: bool,
}

/// How far a run has come, for a progress display.
pub trait Progress: Sync {
    /// The number of cases the run plans (some specs may give fewer).
    fn planned(&self, cases: u64);
    /// `n` more cases are done (run, skipped, or not generated).
    fn advance(&self, n: u64);
    /// A case got its status (after any retries).
    fn status(&self, _status: Status) {}
    /// What each `--vuid` pattern expanded to, before anything is generated.
    fn selected(&self, _expanded: &[crate::names::Expanded]) {}
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
    /// Stale triage entries fail the run.
    pub strict: bool,
    /// Things the reader must know about how the run was judged (a registry of another version than
    /// the layer's, no triage file for the layer's version).
    pub warnings: Vec<String>,
    /// Specs the generator cannot make on this profile (a feature or queue the device lacks).
    pub not_expressible: Vec<String>,
    /// Cases made and left to the other shards (`--shard`).
    pub other_shards: usize,
    /// Specs the generator failed on: a failure of the run.
    pub gen_errors: Vec<String>,
    /// One line per shrunk (or no longer failing) case.
    pub shrunk: Vec<String>,
    /// Where the HTML report went, or why it could not be written.
    pub report: Result<PathBuf, String>,
}

impl RunOutcome {
    /// The exit status of the run: non-zero for any status that is a failure (fail, crash, timeout,
    /// case error, unexpected pass, missing), a generator error, and a run that made no case.
    pub fn exit_code(&self) -> i32 {
        // A run that made no case checked nothing: never a pass; under --strict a stale triage entry
        // fails it too.
        let stale = self.strict && !self.summary.triage.stale.is_empty();
        if self.summary.unexpected() > 0
            || !self.gen_errors.is_empty()
            || self.summary.cases == 0
            || stale
        {
            1
        } else {
            0
        }
    }
}

/// Cases generated and gated ahead of the workers: enough to keep them busy through a burst of slow
/// generation, few enough that a case's expected launch, traced at its gate, is still kept
/// (`model::expected`) when its result is judged.
const AHEAD: usize = 32;

/// Cases the generator draws of a spec at one call.
const CHUNK: usize = 512;

mod dispatch;
use dispatch::Dispatch;

/// What every case of a run is judged with.
pub struct Judging<'a> {
    pub rules: &'a RuleSet,
    pub profile: &'a DeviceProfile,
    pub triage: &'a Triage,
    /// The profile's limits on buffers and push constants the gate holds every case to.
    pub(crate) capacity_limits: crate::gate::CapacityLimits,
    /// The rule table prepared per command and enabled extensions ([`RuleSet::prepare`]): the
    /// profile is the run's, so each preparation serves every later case with the same key.
    prepared: std::sync::Mutex<PreparedRules<'a>>,
}

/// Prepared rule tables by (command, the device's enabled extensions).
type PreparedRules<'a> = std::collections::HashMap<
    (model::CommandId, BTreeSet<String>),
    std::sync::Arc<model::rules::Judge<'a>>,
>;

impl<'a> Judging<'a> {
    /// The judging of a run with these rules, the run's profile and its triage.
    pub fn new(rules: &'a RuleSet, profile: &'a DeviceProfile, triage: &'a Triage) -> Judging<'a> {
        Judging {
            rules,
            profile,
            triage,
            capacity_limits: crate::gate::CapacityLimits::of(profile),
            prepared: Default::default(),
        }
    }

    /// The model's verdict on a call: [`RuleSet::judge`] with the run's profile, the preparation
    /// kept for the next call of the same command on a device with the same extensions.
    pub fn verdict(&self, body: &model::case::Body) -> Verdict {
        let key = (body.command(), body.device().extensions.clone());
        let found = self
            .prepared
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .get(&key)
            .cloned();
        let judge = found.unwrap_or_else(|| {
            let judge = std::sync::Arc::new(self.rules.prepare(
                self.profile,
                body.device(),
                body.command(),
            ));
            self.prepared
                .lock()
                .unwrap_or_else(|e| e.into_inner())
                .insert(key, judge.clone());
            judge
        });
        judge.judge(body)
    }
}

impl Judging<'_> {
    /// The VUIDs the device makes unavoidable for builds, which the layer's validation continues past.
    fn profile_unavoidable(&self) -> Vec<String> {
        model::accel::unavoidable(self.profile)
    }

    /// The one judgement of a case: the model's verdict on the case as it ran (a build with the sizes
    /// the device reported), compared with the observation.
    pub fn judge(&self, case: &Case, resp: &Response) -> CaseReport {
        self.judge_with_verdict(case, resp).0
    }

    /// [`Judging::judge`], with the verdict it compared.
    pub fn judge_with_verdict(&self, case: &Case, resp: &Response) -> (CaseReport, Verdict) {
        let ran = as_run(case, &resp.observation);
        let verdict = self.verdict(&ran.body);
        let report = compare(
            &ran,
            self.profile,
            &verdict,
            &resp.observation,
            self.triage,
            resp.millis,
        );
        (report, verdict)
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
    /// Runs one case on `executor` and judges it: the gate (the case's own errors, [`Case::runnable`]), the execution (for
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
                verdict: self.verdict(&case.body),
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
        let verdict = self.verdict(&ran.body);
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
                verdict: self.verdict(&case.body),
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
            phases: Default::default(),
        });
        let ran = as_run(case, &resp.observation).into_owned();
        let verdict = self.verdict(&ran.body);
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

/// Where a run writes: `results.jsonl` and `details.jsonl` (appended and flushed per case), the case
/// files of the cases that did not pass.
struct Sink<'a> {
    /// Set when a write fails.
    stop: &'a std::sync::atomic::AtomicBool,
    out: PathBuf,
    results_path: PathBuf,
    results: std::fs::File,
    /// `details.jsonl`, opened (for appending) at the first case kept.
    details: Option<std::fs::File>,
    /// The first write that failed: the file and the error.
    error: Option<(PathBuf, std::io::Error)>,
    /// The case folders made so far.
    folders: crate::details::MadeFolders,
    /// Case files of explained outcomes are kept too ([`RunConfig::keep_all`]).
    keep_all: bool,
    expectations: &'a Expectations,
    /// The run's triage entries by id, for the entries a case's line names.
    triage_ids: crate::results::TriageIds<'a>,
    progress: &'a dyn Progress,
}

impl Sink<'_> {
    /// Writes a case's line: its report, its status against the baseline from every attempt's outcome
    /// (`attempts` empty when it ran once), and the triage entries that applied. The case's files are
    /// written whole or not at all, and before its line; the first error is kept and ends the run.
    fn write(
        &mut self,
        case: &Case,
        report: &CaseReport,
        details: &CaseDetails,
        attempts: Vec<Outcome>,
        observation: Option<&harness::Observation>,
    ) {
        // After a failed write nothing more is written: a later line must not follow a torn one.
        if self.error.is_some() {
            return;
        }
        let once = [report.outcome];
        let status = self.expectations.status(
            report,
            if attempts.is_empty() {
                &once
            } else {
                &attempts
            },
        );
        let kept = keep(
            &self.out,
            &mut self.folders,
            case,
            report,
            status,
            self.keep_all,
        )
        .and_then(|kept| {
            if kept {
                self.append_details(case, details)
            } else {
                Ok(())
            }
        });
        if let Err(e) = kept {
            self.error.get_or_insert(e);
            self.stop.store(true, std::sync::atomic::Ordering::Relaxed);
            return;
        }
        if let Some(obs) = observation {
            crate::pictures::for_kept(&self.out, case, obs, report, status);
        }
        self.progress.status(status);
        let line = ResultLine {
            report: report.clone(),
            status,
            attempts,
            triage: applied_triage(report, &self.triage_ids),
        };
        let text = serde_json::to_string(&line).unwrap_or_default();
        if let Err(e) = writeln!(self.results, "{text}").and_then(|_| self.results.flush()) {
            self.error.get_or_insert((self.results_path.clone(), e));
            self.stop.store(true, std::sync::atomic::Ordering::Relaxed);
        }
    }

    /// Appends a kept case's details line (one write, flushed; a reader leaves out a torn last line).
    fn append_details(
        &mut self,
        case: &Case,
        details: &CaseDetails,
    ) -> Result<(), (PathBuf, std::io::Error)> {
        let path = self.out.join(crate::details::DETAILS_FILE);
        if self.details.is_none() {
            let f = std::fs::OpenOptions::new()
                .create(true)
                .append(true)
                .open(&path)
                .map_err(|e| (path.clone(), e))?;
            self.details = Some(f);
        }
        let line = crate::details::details_line(&case.name, details);
        let f = self.details.as_mut().expect("opened above");
        f.write_all(line.as_bytes())
            .and_then(|_| f.flush())
            .map_err(|e| (path, e))
    }
}

/// The cases of a run, one at a time, as `each` receives them: read from the case folder or generated
/// spec by spec, then kept to the shard and off the skips list. Returns what could not be generated.
struct Planned {
    /// The names of every case handed to `each`, in order (`caselist.txt`).
    caselist: Vec<String>,
    /// Cases of the shard the skips list kept back.
    skipped: usize,
    /// Cases made and left to the other shards.
    other_shards: usize,
    not_expressible: Vec<String>,
    gen_errors: Vec<String>,
}

fn each_case(
    config: &RunConfig,
    rules: &RuleSet,
    profile: &DeviceProfile,
    profile_name: &str,
    expectations: &Expectations,
    progress: &dyn Progress,
    each: &mut dyn FnMut(Case),
) -> Result<Planned, SessionError> {
    let mut planned = Planned {
        caselist: Vec::new(),
        skipped: 0,
        other_shards: 0,
        not_expressible: Vec::new(),
        gen_errors: Vec::new(),
    };
    let shard = config.selection.shard;
    let mut offer = |c: Case, planned: &mut Planned| {
        if shard.is_some_and(|s| !s.holds(&c.name)) {
            planned.other_shards += 1;
            progress.advance(1);
            return;
        }
        if expectations.skips(&c.name, c.intent.target()) {
            planned.skipped += 1;
            progress.advance(1);
            return;
        }
        planned.caselist.push(c.name.clone());
        each(c);
    };
    if let Some(dir) = &config.selection.cases {
        let mut cases = crate::select::read_case_folder(dir)?;
        // Chunks hold one command family: the trace cases first, then the builds, each in file order.
        cases.sort_by_key(|c| !c.command().is_trace());
        progress.planned(cases.len() as u64);
        for c in cases {
            offer(c, &mut planned);
        }
        return Ok(planned);
    }
    let mut scope = config.scope.clone();
    if !scope.vuids.is_empty() {
        let mut known: Vec<String> = rules.rows.iter().map(|r| r.vuid.clone()).collect();
        known.sort();
        known.dedup();
        let expanded = crate::names::expand_vuids(&scope.vuids, &known)?;
        progress.selected(&expanded);
        scope.vuids = expanded.into_iter().flat_map(|e| e.vuids).collect();
        scope.vuids.sort();
        scope.vuids.dedup();
    }
    let specs = plan(&scope, rules, profile);
    // A spec's own count (the rendered scenes') is a floor under the run's.
    let count_of =
        |p: &crate::plan::PlannedSpec| p.count.map_or(config.count, |n| n.max(config.count));
    progress.planned(specs.iter().map(count_of).sum::<usize>() as u64);
    for p in &specs {
        let count = count_of(p);
        for range in slices(count) {
            let len = range.len();
            let cases = match generator::generate_range(
                profile,
                profile_name,
                rules,
                &p.spec,
                range,
                p.seed,
            ) {
                Ok(c) => c,
                Err(e @ generator::GenError::Unsupported(_)) => {
                    planned.not_expressible.push(format!("{}: {e}", p.label()));
                    progress.advance(count as u64);
                    break;
                }
                Err(e) => {
                    planned.gen_errors.push(format!("{}: {e}", p.label()));
                    progress.advance(count as u64);
                    break;
                }
            };
            // Indices no build plan fits give no case: counted done.
            progress.advance((len - cases.len()) as u64);
            for c in cases {
                offer(c, &mut planned);
            }
        }
    }
    Ok(planned)
}

/// The cases a run would make (after the shard and the skips list), without a driver.
pub fn list(config: &RunConfig) -> Result<Vec<Case>, SessionError> {
    let mut cases = Vec::new();
    list_each(config, &mut |c| cases.push(c))?;
    Ok(cases)
}

/// [`list`]'s cases handed to `each` as they are made, a slice of the run at a time: no more than a
/// slice of cases is held (the planned names are, as a run keeps them for its case list).
pub fn list_each(config: &RunConfig, each: &mut dyn FnMut(Case)) -> Result<(), SessionError> {
    let set = sources::load_sources(&config.from)?;
    let rules = RuleSet::from_vuids(&set);
    let profile_name = config
        .profile
        .clone()
        .unwrap_or_else(|| sources::default_profile_name(&config.driver));
    let profile = sources::profile_for(&profile_name)?;
    let expectations = config.selection.expectations()?;
    let planned = each_case(
        config,
        &rules,
        &profile,
        &profile_name,
        &expectations,
        &Quiet,
        each,
    )?;
    if let Some(e) = planned.gen_errors.first() {
        return Err(SessionError::Usage(format!("could not generate {e}")));
    }
    Ok(())
}

/// Runs the configured conformance run; see the module documentation.
pub fn run(config: &RunConfig, progress: &dyn Progress) -> Result<RunOutcome, SessionError> {
    let started = std::time::Instant::now();
    if config.strict && (!config.scope.vuids.is_empty() || config.scope.valid_only) {
        return Err(SessionError::Usage(
            "--strict judges stale triage entries, which needs a full run of the commands (no --vuid, no --valid-only)"
                .into(),
        ));
    }
    if config.inject.is_some() && config.shrink > 0 {
        return Err(SessionError::Usage(
            "--shrink with --inject: a case fails only under its injection, which the shrinker does not apply"
                .into(),
        ));
    }
    if let Some(dir) = &config.layer {
        harness::select_layer(dir)?;
    }
    let layer = harness::validation_layer()?;
    // The driver's check: its manifest here (nothing loaded), then the instance the run's first worker
    // makes with the layer — the workers start now and load the driver while the registry is read;
    // a registry that does not read is still the error reported first. Without the executable to
    // start workers from, the instance is made here, as `replay` checks.
    let driver = Driver::parse(&config.driver);
    let manifest = harness::check_manifest(&driver);
    std::env::set_var(harness::worker::DRIVER_ENV, &config.driver);
    let workers = match (&manifest, harness::WorkerCommand::current_exe()) {
        (Ok(_), Ok(cmd)) => Some(harness::StartedWorkers::start(&cmd, config.jobs)),
        _ => None,
    };
    let set = sources::registry_for_layer(&config.from, Some(&layer))?;
    let mut warnings = Vec::new();
    if set.version.as_deref() != Some(layer.version.as_str()) {
        warnings.push(format!(
            "the model judges with registry {} but the validation layer is {}: VUIDs either side lacks show as disagreements",
            set.version.as_deref().unwrap_or("of unknown version"),
            layer.version
        ));
    }
    let rules = RuleSet::from_vuids(&set);
    // The driver first: a path that is not a driver is never taken for a profile's name.
    manifest?;
    match &workers {
        Some(s) => s
            .ready(Duration::from_secs(config.timeout))
            .map(drop)
            .map_err(harness::HarnessError::Failed)?,
        None => drop(harness::check_driver(&driver)?),
    }
    let profile_name = config
        .profile
        .clone()
        .unwrap_or_else(|| sources::default_profile_name(&config.driver));
    let profile = sources::profile_for(&profile_name)?;
    warnings.extend(
        model::required_limits::findings(&profile)
            .iter()
            .map(|f| f.warning(&profile_name)),
    );
    let triage = sources::triage_for(&config.triage, Some(&layer.version), &driver)?;
    if config.triage.is_empty()
        && !triage
            .files
            .iter()
            .any(|f| f.ends_with(&format!("layer-{}.yaml", layer.version)))
    {
        warnings.push(format!(
            "no triage/layer-{}.yaml: every disagreement with this layer is a failure",
            layer.version
        ));
    }
    let expectations = config.selection.expectations()?;
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
        cases: config
            .selection
            .cases
            .as_ref()
            .map(|p| p.display().to_string()),
        shard: config.selection.shard.map(|s| s.to_string()),
        baseline: config
            .selection
            .baseline
            .as_ref()
            .map(|p| p.display().to_string()),
        skips: config
            .selection
            .skips
            .as_ref()
            .map(|p| p.display().to_string()),
        flakes: config
            .selection
            .flakes
            .as_ref()
            .map(|p| p.display().to_string()),
        inject: config.inject.map(|i| i.to_string()),
    };
    // Held until the run returns: another run into this folder is refused meanwhile.
    let _lock = crate::outdir::lock(&config.out)?;
    let done = crate::outdir::prepare(&config.out, &params, config.resume)?;
    let results_path = config.out.join("results.jsonl");
    let results = std::fs::OpenOptions::new()
        .create(true)
        .append(true)
        .open(&results_path)
        .map_err(|e| SessionError::io(results_path.display().to_string(), e))?;
    // Set by the first write that fails: the producer stops drawing cases.
    let stop = std::sync::atomic::AtomicBool::new(false);
    let mut sink = Sink {
        stop: &stop,
        out: config.out.clone(),
        results_path: results_path.clone(),
        results,
        details: None,
        error: None,
        folders: Default::default(),
        keep_all: config.keep_all,
        expectations: &expectations,
        triage_ids: crate::results::TriageIds::new(&triage),
        progress,
    };
    let judging = Judging::new(&rules, &profile, &triage);
    let dispatch = Dispatch {
        jobs: config.jobs,
        timeout: Duration::from_secs(config.timeout),
        retries: config.selection.retries,
        judging: &judging,
        progress,
        inject: config.inject.map(|i| (i, config.scope.seed)),
    };
    // The workers of each stream, told to exit once every answer is in and reaped when the run
    // returns: their exit (the kernel freeing what the driver made) overlaps the summary and report.
    let mut exiting: Vec<harness::ExitingWorkers> = Vec::new();
    // The cases are generated on a thread of their own, a bounded stretch ahead of the workers; the
    // thread that draws a case for a worker gates it; results are judged and written here as they
    // come.
    let planned = std::thread::scope(|scope| {
        let (tx, rx) = std::sync::mpsc::sync_channel::<dispatch::Drawn>(AHEAD);
        let producer = scope.spawn(|| {
            let tx = tx;
            let mut index = 0usize;
            each_case(
                config,
                &rules,
                &profile,
                &profile_name,
                &expectations,
                progress,
                &mut |c: Case| {
                    // A write that failed (a full disk) ends the run: nothing more could be kept.
                    if stop.load(std::sync::atomic::Ordering::Relaxed) {
                        return;
                    }
                    if done.contains(&c.name) {
                        progress.advance(1);
                        return;
                    }
                    index += 1;
                    let drawn = dispatch::Drawn::Ungated(c, index);
                    if tx.send(drawn).is_err() {
                        stop.store(true, std::sync::atomic::Ordering::Relaxed);
                    }
                },
            )
        });
        exiting.push(dispatch.run_stream(rx.into_iter(), &mut sink, workers));
        producer
            .join()
            .unwrap_or_else(|panic| std::panic::resume_unwind(panic))
    })?;
    let full = config.scope.vuids.is_empty()
        && !config.scope.valid_only
        && config.selection.is_whole_plan();
    if full {
        // Entries the generated cases left unused get their own evidence run: the reproducing cases
        // they name (of this profile and a command whose cases ran), so an entry is stale only when its
        // own case no longer disagrees as it says.
        let lines: Vec<CaseReport> = reports(&results_path)
            .map(|r| r.collect())
            .unwrap_or_default();
        let ran: BTreeSet<model::CommandId> = lines.iter().map(|r| r.command).collect();
        let used: BTreeSet<String> = lines
            .iter()
            .flat_map(|r| r.triage.iter().map(|m| m.entry.clone()))
            .collect();
        let written: BTreeSet<&str> = lines.iter().map(|r| r.case.as_str()).collect();
        let mut evidence = crate::triage::evidence_cases(&triage, &used, &ran, &profile_name);
        evidence.retain(|c| !written.contains(c.name.as_str()));
        let drawn: Vec<dispatch::Drawn> = evidence
            .into_iter()
            .enumerate()
            .map(|(index, c)| dispatch.drawn(c, index, &judging))
            .collect();
        // A few evidence cases start no more workers than they can use.
        let evidence_dispatch = Dispatch {
            jobs: dispatch.jobs.min(drawn.len()).max(1),
            ..dispatch
        };
        exiting.push(evidence_dispatch.run_stream(drawn.into_iter(), &mut sink, None));
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
    let caselist_path = config.out.join("caselist.txt");
    std::fs::write(
        &caselist_path,
        planned
            .caselist
            .iter()
            .map(|n| format!("{n}\n"))
            .collect::<String>(),
    )
    .map_err(|e| SessionError::io(caselist_path.display().to_string(), e))?;
    let who = RunIdentity {
        driver: config.driver.clone(),
        profile: profile_name.clone(),
        registry: set.version.clone(),
        shard: config.selection.shard.map(|s| s.to_string()),
    };
    let (mut summary, exercised) =
        crate::report::summarise_exercised(&results_path, Some(&planned.caselist), &who)?;
    summary.skipped = planned.skipped;
    summary.expectations = expectations.files.clone();
    summary.layer = Some(layer.version.clone());
    judge_triage(&mut summary, &exercised, &triage, full);
    if let Some(i) = &config.inject {
        summary.inject = Some(crate::inject::totals(i, &results_path)?);
    }
    summary.runner_peak_rss_kib = peak_rss_kib();
    summary.runner_cpu_seconds = runner_cpu_seconds();
    summary.seconds = started.elapsed().as_secs_f64();
    summary.write(&config.out.join("summary.json"))?;
    write_junit(&results_path, &config.out.join("junit.xml"), &summary)?;
    let report = crate::html::write_report(&config.out).map_err(|e| e.to_string());
    let shrunk = if config.shrink > 0 {
        crate::shrink::shrink_failures(config, &judging, &profile_name, &results_path)
    } else {
        vec![]
    };
    Ok(RunOutcome {
        summary,
        strict: config.strict,
        warnings,
        not_expressible: planned.not_expressible,
        other_shards: planned.other_shards,
        gen_errors: planned.gen_errors,
        shrunk,
        report,
    })
}

fn slices(count: usize) -> impl Iterator<Item = std::ops::Range<usize>> {
    (0..count)
        .step_by(CHUNK)
        .map(move |start| start..(start + CHUNK).min(count))
}

/// CPU seconds (user and system) of this process's threads so far; workers are other processes.
fn runner_cpu_seconds() -> Option<f64> {
    // SAFETY: an all-zero rusage is a valid value of the plain C struct.
    let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
    // SAFETY: getrusage writes one rusage through a valid pointer.
    if unsafe { libc::getrusage(libc::RUSAGE_SELF, &mut usage) } != 0 {
        return None;
    }
    let seconds = |t: libc::timeval| t.tv_sec as f64 + t.tv_usec as f64 * 1e-6;
    Some(seconds(usage.ru_utime) + seconds(usage.ru_stime))
}

/// `VmHWM` of this process from /proc, in KiB (None elsewhere).
fn peak_rss_kib() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    line.split_whitespace().nth(1)?.parse().ok()
}
