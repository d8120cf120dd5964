//! What a run leaves besides `results.jsonl`: the per-VUID agreement table and totals of
//! `summary.json` (raw outcomes and statuses against the baseline), and the JUnit report, both read back
//! from `results.jsonl` a line at a time.

use crate::baseline::Status;
use crate::compare::{CaseReport, Outcome};
use crate::error::SessionError;
use crate::results::{read_lines, ResultLine};
use crate::triage::Triage;
use model::CommandId;
use std::collections::{BTreeMap, BTreeSet};
use std::io::Write;
use std::path::Path;

/// Per-VUID agreement counts of `summary.json`.
#[derive(Debug, Default, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct VuidTally {
    /// Cases that ran in which the model or the layer named the VUID.
    pub cases: usize,
    /// Of those, the cases in which the model named it.
    pub model: usize,
    /// Of those, the cases in which the layer reported it.
    pub layer: usize,
    /// Of those, the cases in which both named it or neither did.
    pub agree: usize,
}

/// How the run's triage entries were used.
#[derive(Debug, Default, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default)]
pub struct TriageUse {
    /// The triage files read.
    pub files: Vec<String>,
    pub entries: usize,
    /// Per entry id, the disagreements it explained.
    pub used: BTreeMap<String, usize>,
    /// Entries about a command whose cases ran that explained nothing, although cases with their VUIDs
    /// ran.
    pub stale: Vec<String>,
    /// Entries about a command whose cases ran that explained nothing because no case that ran
    /// involved their VUIDs (the profile cannot express them, or their cases were not realised).
    #[serde(default)]
    pub unexercised: Vec<String>,
    /// Whether the stale list is a verdict: only a run of every spec of its commands can say an entry
    /// is not needed (a `--vuid` or `--valid-only` run leaves most entries unexercised).
    pub stale_judged: bool,
}

/// `summary.json`.
#[derive(Debug, Default, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default)]
pub struct Summary {
    pub driver: String,
    pub profile: String,
    pub registry: Option<String>,
    /// The validation layer's version, as it reports itself.
    pub layer: Option<String>,
    /// `I/N` for one shard of a sharded run.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub shard: Option<String>,
    /// Cases with a result; the raw outcomes follow.
    pub cases: usize,
    pub passed: usize,
    pub failed: usize,
    pub triaged: usize,
    /// The device lacks what the case needs (its profile says so).
    pub unsupported: usize,
    /// The harness cannot realise the case on this device (the device has what it needs).
    pub not_realised: usize,
    pub crashes: usize,
    pub timeouts: usize,
    /// Cases at fault themselves (`case-error`): not run, or disagreeing with the model about their intent.
    pub case_errors: usize,
    /// Disagreements triage entries explained, per `<kind> <direction>` (`layer-gap layer-silent`).
    pub triaged_by: BTreeMap<String, usize>,
    pub triage: TriageUse,
    /// Cases per status against the baseline (every status, zeros included).
    pub statuses: BTreeMap<Status, usize>,
    /// Cases of the plan the skips list kept from running.
    pub skipped: usize,
    /// Cases of the plan (`caselist.txt`) without a result.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub missing: Vec<String>,
    /// Times a failing case was run again to tell a flake.
    pub retries: usize,
    /// The baseline, skips and flakes files the statuses were judged with.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub expectations: Vec<String>,
    /// Peak resident memory of the runner process itself (workers excluded), in KiB (Linux).
    pub runner_peak_rss_kib: Option<u64>,
    /// CPU time of the runner process itself (all its threads: generation, judging, writing; the
    /// workers excluded), in seconds, over the same span as `seconds`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub runner_cpu_seconds: Option<f64>,
    /// Wall time of the run, in seconds.
    pub seconds: f64,
    /// Where the cases' time went, in seconds summed over the cases (so over the workers, which run
    /// side by side): each execution phase of `harness::timing`, `worker-other` (the rest of the
    /// workers' per-case time: the plan, destroying the case's objects), and the runner's own
    /// [`GATE_PHASE`] (before a case runs) and [`JUDGE_PHASE`] (after).
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub time: BTreeMap<String, f64>,
    pub vuids: BTreeMap<String, VuidTally>,
    /// Per trace command: the rendered output judged per ray (counts, VARY share, error quantiles).
    #[serde(skip_serializing_if = "BTreeMap::is_empty")]
    pub rendered: BTreeMap<String, crate::rendered::RenderedTotals>,
    /// A run with `--inject`: the injection and its cases applied, not applicable and detected.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub inject: Option<crate::inject::InjectTotals>,
}

impl Summary {
    /// Cases of a status.
    pub fn count(&self, s: Status) -> usize {
        self.statuses.get(&s).copied().unwrap_or(0)
    }

    /// Cases whose status makes the run fail.
    pub fn unexpected(&self) -> usize {
        Status::ALL
            .iter()
            .filter(|s| s.is_failure())
            .map(|s| self.count(*s))
            .sum()
    }

    /// Reads a run's `summary.json`.
    pub fn read(path: &Path) -> Result<Summary, SessionError> {
        let text = crate::outdir::read_run_text(path)
            .map_err(|e| SessionError::io(path.display().to_string(), e))?;
        serde_json::from_str(&text).map_err(|e| {
            SessionError::Usage(format!(
                "{}:{}:{}: not a summary.json: {e}",
                path.display(),
                e.line(),
                e.column()
            ))
        })
    }

    /// Writes `summary.json` whole (a temporary file, then a rename): a run stopped while writing it
    /// leaves none rather than a torn one.
    pub fn write(&self, path: &Path) -> Result<(), SessionError> {
        let text = serde_json::to_string_pretty(self).unwrap_or_default() + "\n";
        crate::outdir::write_atomically(path, text.as_bytes())
            .map_err(|e| SessionError::io(path.display().to_string(), e))
    }

    /// The `summary.json` of a finished run in `dir`. A folder whose run wrote its `run.json` but no
    /// summary stopped before it finished (interrupted, killed, or still running): refused with how to
    /// finish it, as a merge or comparison of part of a run would pass for the whole.
    pub fn read_finished(dir: &Path) -> Result<Summary, SessionError> {
        let path = dir.join("summary.json");
        if !path.exists() && dir.join("run.json").is_file() {
            return Err(SessionError::Usage(unfinished_run(dir)));
        }
        Summary::read(&path)
    }

    /// The summary of the run in `dir` and whether the run finished: its `summary.json`, or for a run
    /// that stopped before writing one ([`Summary::read_finished`]) the summary of the results it has,
    /// its driver, profile, registry and shard from `run.json` (which cases it had not run yet is not
    /// known: the case list is written at the end).
    pub fn of_folder(dir: &Path) -> Result<(Summary, bool), SessionError> {
        let path = dir.join("summary.json");
        if path.exists() || !dir.join("run.json").is_file() {
            return Ok((Summary::read(&path)?, true));
        }
        let run_json = dir.join("run.json");
        let text = crate::outdir::read_run_text(&run_json)
            .map_err(|e| SessionError::io(run_json.display().to_string(), e))?;
        let params: crate::outdir::RunParameters = serde_json::from_str(&text).map_err(|e| {
            SessionError::Usage(format!(
                "{}:{}:{}: not a run.json: {e}",
                run_json.display(),
                e.line(),
                e.column()
            ))
        })?;
        let results = dir.join("results.jsonl");
        if !results.exists() {
            return Err(SessionError::Usage(format!(
                "{}; it has no result yet, so there is nothing to report",
                unfinished_run(dir)
            )));
        }
        let who = RunIdentity {
            driver: params.driver,
            profile: params.profile,
            registry: params.registry,
            shard: params.shard,
        };
        Ok((summarise(&results, None, &who)?, false))
    }
}

/// What is said of a run folder with a `run.json` and no `summary.json`.
pub fn unfinished_run(dir: &Path) -> String {
    format!(
        "{0}: the run there did not finish (it has run.json but no summary.json: it was stopped, or is \
         still running); `rtconf run --resume --out {0}` with the run's arguments runs the cases it has \
         not run and writes the summary",
        dir.display()
    )
}

/// The reports of `results.jsonl`, read one line at a time.
pub(crate) fn reports(path: &Path) -> Result<impl Iterator<Item = CaseReport>, SessionError> {
    Ok(read_lines(path)?.map(|l| l.report))
}

/// What a summary is about (the run's driver, profile and registry).
#[derive(Debug, Clone, Default)]
pub struct RunIdentity {
    pub driver: String,
    pub profile: String,
    pub registry: Option<String>,
    pub shard: Option<String>,
}

/// The runner's phase of a case before it runs: the gate (the case's own errors, the rules' view of
/// what it may run, and a valid launch's expected outcomes from the reference tracer).
pub const GATE_PHASE: &str = "gate";
/// The runner's phase of a case after it ran: the comparison of what the layer and the driver gave
/// with the model.
pub const JUDGE_PHASE: &str = "judge";

/// Reads `results.jsonl` back, streaming, into the summary; `planned` (the case list, when known) gives
/// the missing cases. A resumed run never runs a case twice, so each line is one case. Memory is per
/// VUID, and a name per case for the missing ones.
pub fn summarise(
    path: &Path,
    planned: Option<&[String]>,
    who: &RunIdentity,
) -> Result<Summary, SessionError> {
    Ok(summarise_exercised(path, planned, who)?.0)
}

/// What the cases of a run exercised, for judging its triage entries ([`judge_triage`]): the commands
/// whose cases ran (were not refused or lost) and every VUID those cases targeted or either side
/// reported.
#[derive(Debug, Default)]
pub(crate) struct Exercised {
    ran: BTreeSet<CommandId>,
    vuids: BTreeSet<String>,
}

/// [`summarise`], and what the cases exercised, in the one pass over `results.jsonl`.
pub(crate) fn summarise_exercised(
    path: &Path,
    planned: Option<&[String]>,
    who: &RunIdentity,
) -> Result<(Summary, Exercised), SessionError> {
    let mut exercised = Exercised::default();
    let mut s = Summary {
        driver: who.driver.clone(),
        profile: who.profile.clone(),
        registry: who.registry.clone(),
        shard: who.shard.clone(),
        statuses: Status::ALL.iter().map(|s| (*s, 0)).collect(),
        ..Default::default()
    };
    let mut seen = BTreeSet::new();
    for line in read_lines(path)? {
        let r = &line.report;
        if planned.is_some() {
            seen.insert(r.case.clone());
        }
        s.cases += 1;
        if let Some(x) = &r.rendered {
            s.rendered
                .entry(r.command.vk_name().to_string())
                .or_default()
                .add(x);
        }
        *s.statuses.entry(line.status).or_default() += 1;
        let mut in_phases = 0.0;
        for (phase, ms) in &r.phases {
            *s.time.entry(phase.clone()).or_default() += ms / 1000.0;
            // The worker's own phases: what else it spent on the case is `worker-other`.
            if phase != GATE_PHASE && phase != JUDGE_PHASE {
                in_phases += ms;
            }
        }
        if !r.phases.is_empty() {
            *s.time.entry("worker-other".into()).or_default() +=
                (r.millis - in_phases).max(0.0) / 1000.0;
        }
        s.retries += line.attempts.len().saturating_sub(1);
        match r.outcome {
            Outcome::Pass => s.passed += 1,
            Outcome::Fail => s.failed += 1,
            Outcome::Triaged => s.triaged += 1,
            Outcome::Unsupported => s.unsupported += 1,
            Outcome::NotRealised => s.not_realised += 1,
            Outcome::Crash => s.crashes += 1,
            Outcome::Timeout => s.timeouts += 1,
            Outcome::CaseError => s.case_errors += 1,
        }
        for m in &r.triage {
            *s.triage.used.entry(m.entry.clone()).or_default() += 1;
            *s.triaged_by
                .entry(format!("{} {}", m.kind.name(), m.observed))
                .or_default() += 1;
        }
        if matches!(
            r.outcome,
            Outcome::Unsupported
                | Outcome::NotRealised
                | Outcome::Crash
                | Outcome::Timeout
                | Outcome::CaseError
        ) {
            continue;
        }
        exercised.ran.insert(r.command);
        for v in r.target.iter().chain(&r.model).chain(&r.layer) {
            if !exercised.vuids.contains(v) {
                exercised.vuids.insert(v.clone());
            }
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
    if let Some(planned) = planned {
        s.missing = planned
            .iter()
            .filter(|n| !seen.contains(*n))
            .cloned()
            .collect();
        *s.statuses.entry(Status::Missing).or_default() = s.missing.len();
    }
    Ok((s, exercised))
}

/// Judges the run's triage entries on what its cases exercised ([`summarise_exercised`]): the files
/// and entries read, and the entries about a command whose cases ran that explained nothing (stale;
/// a verdict only for a `full` run, one of every spec of its commands). The per-entry use is counted
/// by [`summarise`].
pub(crate) fn judge_triage(s: &mut Summary, exercised: &Exercised, triage: &Triage, full: bool) {
    s.triage.files = triage.files.clone();
    s.triage.entries = triage.entries.len();
    let used: BTreeSet<String> = s.triage.used.keys().cloned().collect();
    (s.triage.stale, s.triage.unexercised) =
        crate::triage::unused(triage, &used, &exercised.ran, &exercised.vuids);
    s.triage.stale_judged = full;
}

pub(crate) fn xml_escape(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&apos;"),
            // Characters XML 1.0 cannot hold (control characters other than tab and line ends).
            c if (c as u32) < 0x20 && !matches!(c, '\t' | '\n' | '\r') => out.push('?'),
            c => out.push(c),
        }
    }
    out
}

/// The body of one JUnit testcase: how its status reads to a CI system. Triaged cases, expected
/// failures and flakes pass but say why in properties and `system-out`, as deqp-runner writes them.
fn junit_body(line: &ResultLine) -> String {
    let r = &line.report;
    let msg = xml_escape(&r.detail);
    let mut props: Vec<(String, String)> = vec![
        ("status".into(), line.status.name().to_string()),
        ("outcome".into(), outcome_name(r.outcome).to_string()),
    ];
    if let Some(t) = &r.target {
        props.push(("target".into(), t.clone()));
    }
    for (i, t) in line.triage.iter().enumerate() {
        let n = if line.triage.len() > 1 {
            format!("[{i}]")
        } else {
            String::new()
        };
        props.push((format!("triage{n}.key"), t.key.clone()));
        props.push((format!("triage{n}.kind"), t.kind.clone()));
        props.push((format!("triage{n}.reason"), t.reason.clone()));
    }
    if line.attempts.len() > 1 {
        props.push((
            "attempts".into(),
            line.attempts
                .iter()
                .map(|o| outcome_name(*o))
                .collect::<Vec<_>>()
                .join(", "),
        ));
    }
    let mut body = String::from("\n      <properties>\n");
    for (k, v) in &props {
        body.push_str(&format!(
            "        <property name=\"{}\" value=\"{}\"/>\n",
            xml_escape(k),
            xml_escape(v)
        ));
    }
    body.push_str("      </properties>\n");
    let out = |text: String| format!("      <system-out>{}</system-out>\n", xml_escape(&text));
    let status = line.status.name();
    match line.status {
        Status::Pass => return "/>\n".into(),
        Status::Triaged => {
            let why: Vec<String> = line
                .triage
                .iter()
                .map(|t| format!("triaged {}: {} ({}): {}", t.kind, t.key, t.side, t.reason))
                .collect();
            body.push_str(&out(if why.is_empty() {
                r.detail.clone()
            } else {
                why.join("\n")
            }));
        }
        Status::ExpectedFail => body.push_str(&out(format!(
            "expected failure ({}): {}",
            outcome_name(r.outcome),
            r.detail
        ))),
        Status::Flake => body.push_str(&out(format!(
            "flake: {}; {}",
            if line.attempts.len() > 1 {
                format!(
                    "attempts {}",
                    line.attempts
                        .iter()
                        .map(|o| outcome_name(*o))
                        .collect::<Vec<_>>()
                        .join(", ")
                )
            } else {
                "on the flakes list".into()
            },
            r.detail
        ))),
        Status::Skip => body.push_str(&format!("      <skipped message=\"{msg}\"/>\n")),
        Status::Fail | Status::UnexpectedPass => body.push_str(&format!(
            "      <failure type=\"{status}\" message=\"{msg}\"/>\n"
        )),
        Status::Crash | Status::Timeout | Status::Missing | Status::CaseError => body.push_str(
            &format!("      <error type=\"{status}\" message=\"{msg}\"/>\n"),
        ),
    }
    format!(">{body}    </testcase>\n")
}

/// The name of a raw outcome, as `results.jsonl` writes it.
pub fn outcome_name(o: Outcome) -> &'static str {
    match o {
        Outcome::Pass => "pass",
        Outcome::Fail => "fail",
        Outcome::Triaged => "triaged",
        Outcome::Unsupported => "unsupported",
        Outcome::NotRealised => "not-realised",
        Outcome::Crash => "crash",
        Outcome::Timeout => "timeout",
        Outcome::CaseError => "case-error",
    }
}

/// Writes the JUnit report (one suite for the run), streaming from `results.jsonl` so memory does not
/// grow with the run; missing cases are errors.
pub fn write_junit(results: &Path, out: &Path, s: &Summary) -> Result<(), SessionError> {
    let io = |e: std::io::Error| SessionError::io(out.display().to_string(), e);
    let mut w = std::io::BufWriter::new(std::fs::File::create(out).map_err(io)?);
    let name = xml_escape(&match &s.shard {
        Some(sh) => format!("rtconf on {} (shard {sh})", s.driver),
        None => format!("rtconf on {}", s.driver),
    });
    let tests = s.cases + s.missing.len();
    let failures = s.count(Status::Fail) + s.count(Status::UnexpectedPass);
    let errors = s.count(Status::Crash)
        + s.count(Status::Timeout)
        + s.count(Status::Missing)
        + s.count(Status::CaseError);
    let skipped = s.count(Status::Skip);
    let head = format!(
        "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<testsuites name=\"{name}\" tests=\"{tests}\" failures=\"{failures}\" errors=\"{errors}\">\n  <testsuite name=\"{name}\" tests=\"{tests}\" failures=\"{failures}\" errors=\"{errors}\" skipped=\"{skipped}\" time=\"{:.3}\">\n",
        s.seconds
    );
    w.write_all(head.as_bytes()).map_err(io)?;
    for line in read_lines(results)? {
        let r = &line.report;
        let open = format!(
            "    <testcase name=\"{}\" classname=\"{}.{}\" time=\"{:.3}\"",
            xml_escape(&r.case),
            xml_escape(&s.driver),
            xml_escape(r.command.vk_name()),
            r.millis.max(0.0) / 1000.0
        );
        w.write_all(open.as_bytes())
            .and_then(|_| w.write_all(junit_body(&line).as_bytes()))
            .map_err(io)?;
    }
    for m in &s.missing {
        let case = format!(
            "    <testcase name=\"{}\" classname=\"{}.missing\" time=\"0\">\n      <error type=\"missing\" message=\"planned for the run (caselist.txt) but without a result\"/>\n    </testcase>\n",
            xml_escape(m),
            xml_escape(&s.driver)
        );
        w.write_all(case.as_bytes()).map_err(io)?;
    }
    w.write_all(b"  </testsuite>\n</testsuites>\n")
        .and_then(|_| w.flush())
        .map_err(io)
}
