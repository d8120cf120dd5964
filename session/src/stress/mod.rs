//! `rtconf stress`: the numerical stress families of [`model::stress`] on a real driver. Each
//! family's cases are generated from a seed, their claims proven in exact arithmetic, turned into
//! ordinary valid trace cases ([`cases::trace_cases`]), gated and run in worker processes as a run
//! runs them (a driver that dies costs a `crash`, never the report), judged once by the session
//! ([`crate::run::Judging`]), and their 28-word records judged ray by ray into the family's
//! [`FamilyReport`]: double hits and holes, t and barycentric errors in ULPs, the VARY share and
//! what the driver chose on it. The run writes `stress.json` and `stress.png` ([`picture`]).

pub mod cases;
pub mod picture;

use crate::compare::{CaseReport, Outcome};
use crate::error::SessionError;
use crate::run::Judging;
use crate::sources;
use harness::{Driver, Execution, Request, Response};
use model::stress::{families, ErrorStats, Family, FamilyReport, VaryChoices};
use model::tracer::record::RayRecord;
use model::{DeviceProfile, RuleSet};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::PathBuf;
use std::time::{Duration, Instant};

pub use cases::{trace_cases, StressLaunch, MAX_RAYS_PER_CASE, STRESS_COMMAND};

/// How large a stress run's cases are.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Size {
    /// Each family's test size (`cargo test`): a few seconds in all.
    Small,
    /// Each family's full size.
    Full,
}

impl Size {
    pub fn parse(s: &str) -> Result<Size, SessionError> {
        match s {
            "small" => Ok(Size::Small),
            "full" => Ok(Size::Full),
            other => Err(SessionError::Usage(format!(
                "--size {other}: expected small or full"
            ))),
        }
    }

    /// Rays per case of `family` at this size.
    pub fn rays(self, family: &Family) -> usize {
        match self {
            Size::Small => family.test_size,
            Size::Full => family.full_size,
        }
    }

    /// Seeds per family when the run does not say: one (the model's judgement of a full-size
    /// case takes minutes on the ill-conditioned and large-mesh families).
    pub fn default_seeds(self) -> usize {
        1
    }
}

/// Everything a stress run is asked to do.
#[derive(Debug, Clone)]
pub struct StressConfig {
    /// `lavapipe`, `nvidia`, or the path of an ICD manifest.
    pub driver: String,
    /// A committed profile or a profile file; None: the live device's, probed.
    pub profile: Option<String>,
    /// Family names (empty: every family).
    pub families: Vec<String>,
    /// Family cases have seeds `seed .. seed + seeds`.
    pub seed: u64,
    /// None: [`Size::default_seeds`].
    pub seeds: Option<usize>,
    pub size: Size,
    pub jobs: usize,
    /// Seconds one case may take.
    pub timeout: u64,
    pub out: PathBuf,
    /// Registry sources for the rules (empty: the installed registry, the layer's version).
    pub from: Vec<PathBuf>,
}

/// The outcome counts of a family's cases, by [`Outcome`] name.
pub type Outcomes = BTreeMap<String, u64>;

/// One family's row of `stress.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FamilyResult {
    pub family: String,
    pub about: String,
    pub seeds: Vec<u64>,
    /// Claims of the family's cases, every one proven before a ray was traced.
    pub claims: u64,
    /// Trace cases run (a family case whose rays exceed one launch is several).
    pub cases: u64,
    /// How those cases ended in the session's comparison.
    pub outcomes: Outcomes,
    /// Rays judged (those of cases whose records came back).
    pub rays: u64,
    /// Rays on which the driver broke what the spec requires (double hits included).
    pub req_violations: u64,
    pub double_hits: u64,
    /// Rays through a watertight group that hit nothing there (quality warnings).
    pub holes: u64,
    pub watertight_rays: u64,
    pub vary_rays: u64,
    pub vary_share: f64,
    /// What the driver chose on the rays the model classed VARY.
    pub on_vary: VaryChoices,
    pub t_error_ulps: ErrorStats,
    pub t_error_bound: ErrorStats,
    pub bary_error_eps: ErrorStats,
    pub bary_error_ulps: ErrorStats,
    /// Records that could not be read (counted as REQ violations).
    pub unreadable_records: u64,
    /// The error statistics whose value is infinite (JSON has no infinity: those read `null`
    /// above), as `t_error_ulps.max`.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub infinite: Vec<String>,
    /// Seconds the family took: generation and proofs, the workers, the judgement.
    pub seconds: f64,
    /// How the family's cases were cut to fit launches, when they were.
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub note: String,
    /// The first failures and warnings (`case#ray: message`), and cases that did not run.
    pub findings: Vec<String>,
    /// The full report, histograms included.
    pub report: FamilyReport,
}

impl FamilyResult {
    /// The row of `family` before any case ran.
    pub fn new(family: &Family, seeds: Vec<u64>) -> FamilyResult {
        FamilyResult {
            family: family.name.into(),
            about: family.about.into(),
            seeds,
            claims: 0,
            cases: 0,
            outcomes: Outcomes::new(),
            rays: 0,
            req_violations: 0,
            double_hits: 0,
            holes: 0,
            watertight_rays: 0,
            vary_rays: 0,
            vary_share: 0.0,
            on_vary: VaryChoices::default(),
            t_error_ulps: ErrorStats::default(),
            t_error_bound: ErrorStats::default(),
            bary_error_eps: ErrorStats::default(),
            bary_error_ulps: ErrorStats::default(),
            unreadable_records: 0,
            infinite: Vec::new(),
            seconds: 0.0,
            note: String::new(),
            findings: Vec::new(),
            report: FamilyReport::new(family.name),
        }
    }

    /// Fills the row's numbers from its report (and its unreadable records).
    pub fn refresh(&mut self) {
        let r = &self.report;
        self.rays = r.rays();
        self.req_violations = r.summary.fail + self.unreadable_records;
        self.double_hits = r.double_hits;
        self.holes = r.holes;
        self.watertight_rays = r.watertight_rays;
        self.vary_rays = r.summary.vary;
        self.vary_share = r.vary_share();
        self.on_vary = r.on_vary;
        self.t_error_ulps = r.t_error_ulps();
        self.t_error_bound = r.t_error_bound();
        self.bary_error_eps = r.bary_error_eps();
        self.bary_error_ulps = r.bary_error_ulps();
        self.infinite.clear();
        for (name, e) in [
            ("t_error_ulps", &self.t_error_ulps),
            ("t_error_bound", &self.t_error_bound),
            ("bary_error_eps", &self.bary_error_eps),
            ("bary_error_ulps", &self.bary_error_ulps),
        ] {
            for (q, v) in [("median", e.median), ("p99", e.p99), ("max", e.max)] {
                if v.is_some_and(|x| !x.is_finite()) {
                    self.infinite.push(format!("{name}.{q}"));
                }
            }
        }
    }

    /// Whether the driver did something the spec forbids on this family.
    pub fn driver_finding(&self) -> bool {
        self.req_violations > 0
            || self.double_hits > 0
            || ["fail", "crash", "timeout"]
                .iter()
                .any(|o| self.outcomes.get(*o).copied().unwrap_or(0) > 0)
    }

    /// The console table's header.
    pub fn header() -> String {
        format!(
            "{:<20} {:>5} {:>6} {:>5} {:>6} {:>6} {:>7} {:>7} {:>22} {:>22} {:>24} {:>7}  outcomes",
            "family",
            "cases",
            "rays",
            "REQ",
            "double",
            "holes",
            "w-tight",
            "VARY %",
            "VARY req/pos/miss/oth",
            "t ulps med/p99/max",
            "bary eps med/p99/max",
            "seconds"
        )
    }

    /// One row of the console table.
    pub fn row(&self) -> String {
        let v = &self.on_vary;
        let outcomes: Vec<String> = self
            .outcomes
            .iter()
            .map(|(k, n)| format!("{k} {n}"))
            .collect();
        format!(
            "{:<20} {:>5} {:>6} {:>5} {:>6} {:>6} {:>7} {:>7.2} {:>22} {:>22} {:>24} {:>7.1}  {}",
            self.family,
            self.cases,
            self.rays,
            self.req_violations,
            self.double_hits,
            self.holes,
            self.watertight_rays,
            100.0 * self.vary_share,
            format!(
                "{}/{}/{}/{}",
                v.hit_required,
                v.hit_possible,
                v.miss,
                v.hit_other + v.no_shader + v.not_run
            ),
            stats_text(&self.t_error_ulps),
            stats_text(&self.bary_error_eps),
            self.seconds,
            outcomes.join(", ")
        )
    }
}

/// `median/p99/max`, each with four significant digits (three decimals below 1000, else in
/// exponent form), `-` where there is no value.
pub fn stats_text(s: &ErrorStats) -> String {
    let f = |x: Option<f64>| match x {
        None => "-".to_string(),
        Some(v) if v.abs() < 1000.0 => format!("{v:.3}"),
        Some(v) => format!("{v:.3e}"),
    };
    format!("{}/{}/{}", f(s.median), f(s.p99), f(s.max))
}

/// `stress.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StressSummary {
    pub driver: String,
    /// The profile the cases were laid out and judged with (`probed:` the live device's).
    pub profile: String,
    pub device: String,
    pub layer: String,
    pub registry: Option<String>,
    pub size: Size,
    pub seed: u64,
    pub seeds: usize,
    pub families: Vec<FamilyResult>,
    pub seconds: f64,
    /// The exit status of the run: 1 a driver finding, 2 a case error or a family that judged no
    /// ray, 0 otherwise.
    pub exit: i32,
    /// Why the exit status is what it is.
    pub verdict: String,
}

impl StressSummary {
    /// The exit status and why: a case the session could not run as made (a case error) is the
    /// suite's fault (2); a REQ violation, double hit, failure, crash or timeout is the driver's (1);
    /// a family that judged no ray checked nothing (2).
    pub fn judge(&self) -> (i32, String) {
        let errors: u64 = self
            .families
            .iter()
            .map(|f| f.outcomes.get("case-error").copied().unwrap_or(0))
            .sum();
        if errors > 0 {
            return (
                2,
                format!(
                    "{errors} stress cases are at fault (case-error): nothing was judged of them"
                ),
            );
        }
        let findings: Vec<&str> = self
            .families
            .iter()
            .filter(|f| f.driver_finding())
            .map(|f| f.family.as_str())
            .collect();
        if !findings.is_empty() {
            return (
                1,
                format!(
                    "the driver broke what the spec requires in {}",
                    findings.join(", ")
                ),
            );
        }
        let empty: Vec<&str> = self
            .families
            .iter()
            .filter(|f| f.rays == 0)
            .map(|f| f.family.as_str())
            .collect();
        if self.families.is_empty() || !empty.is_empty() {
            return (
                2,
                format!(
                    "no ray was judged for {}: nothing was checked there",
                    if empty.is_empty() {
                        "any family".to_string()
                    } else {
                        empty.join(", ")
                    }
                ),
            );
        }
        (0, "no REQ violation, no double hit".into())
    }

    pub fn write(&self, path: &std::path::Path) -> Result<(), SessionError> {
        let text = serde_json::to_string_pretty(self).unwrap_or_default();
        crate::outdir::write_atomically(path, text.as_bytes())
            .map_err(|e| SessionError::io(path.display().to_string(), e))
    }
}

/// The families a run names (all when none is named); an unknown name is a usage error listing
/// the known ones.
pub fn select_families(names: &[String]) -> Result<Vec<Family>, SessionError> {
    let all = families();
    if names.is_empty() {
        return Ok(all);
    }
    names
        .iter()
        .map(|n| {
            all.iter().find(|f| f.name == n).copied().ok_or_else(|| {
                SessionError::Usage(format!(
                    "--family {n}: no such stress family (known: {})",
                    all.iter().map(|f| f.name).collect::<Vec<_>>().join(", ")
                ))
            })
        })
        .collect()
}

/// One trace case of a family, with what its records are judged into.
struct Planned {
    family: usize,
    launch: StressLaunch,
}

/// A family's running totals.
struct Totals {
    result: FamilyResult,
    /// The family's cases' time in the workers.
    worker_millis: f64,
    judge_seconds: f64,
    generate_seconds: f64,
}

/// Judges one launch's records into `report`, one ray per launch ID: Err when the model cannot
/// state the launch's expected records or the words do not fit it. Returns the unreadable records.
pub fn judge_launch(
    report: &mut FamilyReport,
    case: &model::Case,
    words: &[u32],
) -> Result<u64, String> {
    let body = case
        .as_trace()
        .ok_or_else(|| format!("{}: not a trace case", case.name))?;
    let judged = model::rendered::judge_records(body, words)?;
    report.cases += 1;
    let mut unreadable = 0;
    for (id, j) in judged.ids.iter().enumerate() {
        let name = format!("{}#{id}", case.name);
        match (j.ray, &j.record) {
            (Some(k), Some(record)) => report.add_ray(&name, &judged.expected.allowed[k], record),
            (Some(_), None) => {
                unreadable += 1;
                if report.findings.len() < 32 {
                    report
                        .findings
                        .push(format!("{name}: fail: unreadable record"));
                }
            }
            (None, _) => {}
        }
    }
    Ok(unreadable)
}

/// Fills a family's row from its report and its times.
fn finish(t: &mut Totals) {
    let f = &mut t.result;
    f.refresh();
    let room = 32usize.saturating_sub(f.findings.len());
    let kept: Vec<String> = f.report.findings.iter().take(room).cloned().collect();
    f.findings.extend(kept);
    f.seconds = t.generate_seconds + t.worker_millis / 1000.0 + t.judge_seconds;
}

/// The profile of a run: the named one, or the live device's (probed, named `probed:<name>`).
fn profile_of(
    config: &StressConfig,
    driver: &Driver,
) -> Result<(DeviceProfile, String), SessionError> {
    match &config.profile {
        Some(name) => Ok((sources::profile_for(name)?, name.clone())),
        None => {
            let mut p = harness::probe::probe(driver.clone())?;
            p.name = format!("probed:{}", p.name);
            let name = p.name.clone();
            Ok((p, name))
        }
    }
}

/// Runs the configured stress run: writes `stress.json` and `stress.png` into `config.out` and
/// returns what it wrote.
pub fn stress(config: &StressConfig) -> Result<StressSummary, SessionError> {
    let started = Instant::now();
    let chosen = select_families(&config.families)?;
    let seeds = config.seeds.unwrap_or(config.size.default_seeds());
    if seeds == 0 {
        return Err(SessionError::Usage(
            "--seeds 0: a stress run needs at least one seed per family".into(),
        ));
    }
    if config.seed.checked_add(seeds as u64 - 1).is_none() {
        return Err(SessionError::Usage(format!(
            "--seed {} --seeds {seeds}: the last seed would be past {}",
            config.seed,
            u64::MAX
        )));
    }
    let layer = harness::validation_layer()?;
    let set = sources::registry_for_layer(&config.from, Some(&layer))?;
    let rules = RuleSet::from_vuids(&set);
    let driver = Driver::parse(&config.driver);
    harness::check_driver(&driver)?;
    let (profile, profile_name) = profile_of(config, &driver)?;
    let triage = sources::triage_for(&[], Some(&layer.version), &driver)?;
    std::fs::create_dir_all(&config.out)
        .map_err(|e| SessionError::io(config.out.display().to_string(), e))?;
    std::env::set_var(harness::worker::DRIVER_ENV, &config.driver);
    let judging = Judging::new(&rules, &profile, &triage);

    // Generate, prove and lay out every family's cases; gate each.
    let mut totals: Vec<Totals> = Vec::new();
    let mut planned: Vec<Planned> = Vec::new();
    for (fi, family) in chosen.iter().enumerate() {
        let t0 = Instant::now();
        let rays = config.size.rays(family);
        let seed_list: Vec<u64> = (0..seeds as u64).map(|k| config.seed + k).collect();
        let mut result = FamilyResult::new(family, seed_list.clone());
        let mut split = 0;
        for &seed in &seed_list {
            let stress_case = family.case(seed, rays);
            let failures = stress_case.check_claims();
            if let Some((i, why)) = failures.first() {
                return Err(SessionError::Usage(format!(
                    "{}: claim {i} of {} does not hold: {why} (a bug of the family, not the driver's)",
                    stress_case.name,
                    stress_case.claims.len()
                )));
            }
            result.claims += stress_case.claims.len() as u64;
            let launches = trace_cases(&stress_case, &profile, &profile_name, seed)
                .map_err(SessionError::Usage)?;
            if launches.len() > 1 {
                split += 1;
            }
            for launch in launches {
                result.cases += 1;
                planned.push(Planned { family: fi, launch });
            }
        }
        if split > 0 {
            result.note = format!(
                "{split} of its cases had more rays than one launch holds and were split into launches of at most {} rays, each with the whole scene",
                cases::rays_per_launch(
                    &generator::plan::Limits::for_command(&profile, STRESS_COMMAND)
                        .map_err(SessionError::Generate)?
                )
            );
        }
        totals.push(Totals {
            result,
            worker_millis: 0.0,
            judge_seconds: 0.0,
            generate_seconds: t0.elapsed().as_secs_f64(),
        });
    }

    // The gate (which traces every ray to know what the launch reads) on `jobs` threads; the
    // cases it keeps from the driver are counted in their families.
    let gated = gate_all(&planned, &judging, config.jobs.max(1));
    let mut kept = Vec::with_capacity(planned.len());
    for (p, g) in planned.into_iter().zip(gated) {
        match g {
            Some(report) => count(&mut totals[p.family].result, &report),
            None => kept.push(p),
        }
    }
    let planned = kept;

    // Run them in workers, judging each as it comes back.
    let requests: Vec<Request> = planned
        .iter()
        .enumerate()
        .map(|(index, p)| Request {
            index,
            execution: Execution::for_case(&p.launch.case, &profile),
            case: p.launch.case.clone(),
        })
        .collect();
    // Judged on `jobs` threads as the responses arrive (the model's judgement is the run's CPU
    // cost), then summed per family in case order, so the report does not depend on timing.
    let (tx, rx) = std::sync::mpsc::channel::<Response>();
    let rx = std::sync::Mutex::new(rx);
    let judged = std::sync::Mutex::new(Vec::<Judged>::new());
    std::thread::scope(|scope| {
        for _ in 0..config.jobs.max(1) {
            scope.spawn(|| loop {
                let next = rx.lock().map(|r| r.recv());
                let Ok(Ok(resp)) = next else {
                    break;
                };
                let Some(p) = planned.get(resp.index) else {
                    continue;
                };
                let j = judge_one(&judging, &p.launch.case, resp);
                if let Ok(mut v) = judged.lock() {
                    v.push(j);
                }
            });
        }
        harness::run_in_workers(
            &requests,
            config.jobs.max(1),
            Duration::from_secs(config.timeout.max(1)),
            |resp: Response| {
                let _ = tx.send(resp);
            },
        );
        drop(tx);
    });
    let mut judged = judged.into_inner().unwrap_or_default();
    judged.sort_by_key(|j| j.index);
    let mut answered = vec![false; planned.len()];
    for j in judged {
        answered[j.index] = true;
        let t = &mut totals[planned[j.index].family];
        t.worker_millis += j.worker_millis;
        t.judge_seconds += j.seconds;
        count(&mut t.result, &j.report);
        t.result.report.merge(&j.family);
        t.result.unreadable_records += j.unreadable;
        if let Some(problem) = j.problem {
            t.result.findings.push(problem);
        }
    }
    for (p, done) in planned.iter().zip(&answered) {
        if !done {
            let t = &mut totals[p.family];
            *t.result.outcomes.entry("crash".into()).or_default() += 1;
            t.result
                .findings
                .push(format!("{}: the worker gave no result", p.launch.case.name));
        }
    }
    let mut results = Vec::with_capacity(totals.len());
    for mut t in totals {
        finish(&mut t);
        results.push(t.result);
    }
    let mut summary = StressSummary {
        driver: config.driver.clone(),
        profile: profile_name,
        device: profile.description.clone(),
        layer: layer.version.clone(),
        registry: set.version.clone(),
        size: config.size,
        seed: config.seed,
        seeds,
        families: results,
        seconds: started.elapsed().as_secs_f64(),
        exit: 0,
        verdict: String::new(),
    };
    let (exit, verdict) = summary.judge();
    summary.exit = exit;
    summary.verdict = verdict;
    summary.write(&config.out.join("stress.json"))?;
    let png = config.out.join("stress.png");
    picture::render(&summary)
        .write_png(&png)
        .map_err(|e| SessionError::io(png.display().to_string(), e))?;
    Ok(summary)
}

/// Counts a case's outcome in its family and keeps what went wrong.
fn count(result: &mut FamilyResult, report: &CaseReport) {
    let name = serde_json::to_value(report.outcome)
        .ok()
        .and_then(|v| v.as_str().map(str::to_string))
        .unwrap_or_else(|| format!("{:?}", report.outcome));
    *result.outcomes.entry(name).or_default() += 1;
    if !matches!(report.outcome, Outcome::Pass) && result.findings.len() < 32 {
        let detail: String = report.detail.chars().take(400).collect();
        result.findings.push(format!(
            "{}: {}: {detail}",
            report.case,
            serde_json::to_value(report.outcome)
                .ok()
                .and_then(|v| v.as_str().map(str::to_string))
                .unwrap_or_default()
        ));
    }
}

/// The gate's report of each planned case (None: it may run), on `threads` threads.
fn gate_all(planned: &[Planned], judging: &Judging, threads: usize) -> Vec<Option<CaseReport>> {
    let next = std::sync::atomic::AtomicUsize::new(0);
    let out = std::sync::Mutex::new(vec![None; planned.len()]);
    std::thread::scope(|scope| {
        for _ in 0..threads {
            scope.spawn(|| loop {
                let i = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                let Some(p) = planned.get(i) else {
                    break;
                };
                let g = crate::gate::gate(&p.launch.case, judging);
                if let Ok(mut v) = out.lock() {
                    v[i] = g;
                }
            });
        }
    });
    out.into_inner().unwrap_or_default()
}

/// One case judged: the session's report, and its records judged into a report of their own.
struct Judged {
    index: usize,
    report: CaseReport,
    family: FamilyReport,
    unreadable: u64,
    /// Why the records could not be judged, when they could not.
    problem: Option<String>,
    worker_millis: f64,
    seconds: f64,
}

/// One worker response: the session's judgement of the case, then its records ray by ray.
fn judge_one(judging: &Judging, case: &model::Case, resp: Response) -> Judged {
    let started = Instant::now();
    let report = judging.judge(case, &resp);
    let mut family = FamilyReport::new(&case.name);
    let mut unreadable = 0;
    let mut problem = None;
    if let Some(words) = resp.observation.words() {
        match judge_launch(&mut family, case, words) {
            Ok(n) => unreadable = n,
            Err(e) => problem = Some(format!("{}: {e}", case.name)),
        }
    }
    Judged {
        index: resp.index,
        report,
        family,
        unreadable,
        problem,
        worker_millis: resp.millis,
        seconds: started.elapsed().as_secs_f64(),
    }
}

/// The records of a launch as the words a worker reads back (for tests that doctor them).
pub fn words_of(records: &[RayRecord]) -> Vec<u32> {
    records.iter().flat_map(|r| r.to_words()).collect()
}
