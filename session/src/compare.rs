//! The one place where the model's verdict and expected output meet the driver's observation: per case,
//! the model's VUIDs, the layer's VUIDs, the output check (the launch's words for a trace call, the
//! rays traced at what was built for a build), and the outcome against the triage files.

use crate::triage::{CaseFacts, Triage, TriageMatch};
use harness::observe::{DeviceLack, Observation, Status, TracedBuild};
use model::accel::check::{deviation, judge_build};
use model::rules::modelled_scope;
use model::{Body, Case, CommandId, DeviceProfile, Verdict};
use std::collections::BTreeSet;

/// How one case ended against the model and the triage.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Outcome {
    /// Model and driver agree.
    Pass,
    /// They disagree and no triage entry explains it.
    Fail,
    /// They disagree exactly as a triage entry says.
    Triaged,
    /// The device lacks what the case needs, as its profile says.
    Unsupported,
    /// The harness cannot realise the case on this device, though the device has what it needs.
    NotRealised,
    Crash,
    Timeout,
    /// The case is at fault, not the driver: it is not a case (a name resolving to nothing, a group
    /// the pipeline lacks), it is not runnable, the model disagrees with its intent, or it asks for
    /// more memory than the driver gives within the profile's limits. Never run where that is known
    /// first; the detail says where in the case (a YAML path) and what.
    CaseError,
}

impl Outcome {
    /// Whether the outcome makes a run fail (the exit status) and its case worth keeping.
    pub fn is_unexpected(self) -> bool {
        matches!(
            self,
            Outcome::Fail | Outcome::Crash | Outcome::Timeout | Outcome::CaseError
        )
    }
}

/// One line of `results.jsonl`.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct CaseReport {
    pub case: String,
    pub command: CommandId,
    /// The VUID an invalid case targets; None for cases run as valid.
    pub target: Option<String>,
    pub outcome: Outcome,
    /// VUIDs the model says the call violates.
    pub model: Vec<String>,
    /// VUIDs of the modelled scopes the layer reported.
    pub layer: Vec<String>,
    /// Other VUIDs the layer reported (outside the modelled scopes), kept for the record.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub layer_other: Vec<String>,
    /// For cases run as valid: whether what the device produced is what the model expects.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub output_matches: Option<bool>,
    /// For valid trace cases: the rendered output judged per ray (counts, worst errors, histograms).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rendered: Option<model::rendered::RenderedResult>,
    /// What went wrong or what triage entry applied.
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub detail: String,
    /// The disagreements triage entries explained, each with its entry (empty unless triaged).
    /// (Written `matched`: a results line's `triage` is the applied entries, see `results::ResultLine`.)
    #[serde(default, rename = "matched", skip_serializing_if = "Vec::is_empty")]
    pub triage: Vec<TriageMatch>,
    pub millis: f64,
    /// Where the case's time went, in milliseconds: the worker's execution phases
    /// (`harness::timing`) and the runner's gate (`gate`, before the case runs) and judging
    /// (`judge`).
    #[serde(default, skip_serializing_if = "std::collections::BTreeMap::is_empty")]
    pub phases: std::collections::BTreeMap<String, f64>,
    /// In a run with `--inject`: the injection, and whether the driver ran the perturbed copy.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub injection: Option<crate::inject::CaseInjection>,
}

impl CaseReport {
    fn new(case: &Case, millis: f64) -> CaseReport {
        CaseReport {
            case: case.name.clone(),
            command: case.command(),
            target: None,
            outcome: Outcome::Pass,
            model: vec![],
            layer: vec![],
            layer_other: vec![],
            output_matches: None,
            rendered: None,
            detail: String::new(),
            triage: vec![],
            millis,
            phases: Default::default(),
            injection: None,
        }
    }
}

/// The report of a case that is not run because it is not runnable (undefined reads the driver may
/// crash on, a build the model gives no meaning): an error of the case (a generator or case-file bug).
pub(crate) fn not_runnable(case: &Case, why: &model::NotRunnable) -> CaseReport {
    case_error(case, &why.at, &format!("not run: {why}"))
}

/// The report of a case the profile says the device cannot realise: `at` is the YAML path of what.
pub(crate) fn not_realisable(case: &Case, at: &str, why: &str) -> CaseReport {
    CaseReport {
        outcome: Outcome::Unsupported,
        detail: format!("{at}: {why}"),
        ..CaseReport::new(case, 0.0)
    }
}

/// The report of a case that is at fault: `at` is the YAML path of what is wrong.
pub(crate) fn case_error(case: &Case, at: &str, problem: &str) -> CaseReport {
    CaseReport {
        outcome: Outcome::CaseError,
        detail: format!("{at}: {problem}"),
        ..CaseReport::new(case, 0.0)
    }
}

/// The case as the model judges it after the run: a build's sizes are the ones the device reported.
pub(crate) fn as_run<'a>(case: &'a Case, obs: &Observation) -> std::borrow::Cow<'a, Case> {
    match &case.body {
        Body::Accel(_) if !obs.device_sizes.is_empty() => {
            let mut c = case.clone();
            if let Some(a) = c.as_accel_mut() {
                a.world.sizes = obs.device_sizes.clone();
            }
            std::borrow::Cow::Owned(c)
        }
        _ => std::borrow::Cow::Borrowed(case),
    }
}

/// Compares one case's observation with the model's verdict (judged on `as_run`'s case). A case run as
/// valid ([`Case::runs_as_valid`]) must draw no more than what the device makes unavoidable, from the
/// model and from the layer, and its output must be the model's.
pub fn compare(
    case: &Case,
    profile: &DeviceProfile,
    verdict: &Verdict,
    obs: &Observation,
    triage: &Triage,
    millis: f64,
) -> CaseReport {
    let mut report = CaseReport::new(case, millis);
    let model: Vec<String> = verdict.vuids().into_iter().map(String::from).collect();
    let (layer, layer_other): (Vec<String>, Vec<String>) = obs
        .layer_vuids
        .iter()
        .cloned()
        .partition(|v| vuid_scope(v).is_some_and(modelled_scope));
    let valid = case.runs_as_valid(profile);
    report.target = match case.intent.target() {
        Some(t) if !valid => Some(t.to_string()),
        _ => None,
    };
    report.model = model.clone();
    report.layer = layer.clone();
    report.layer_other = layer_other;
    match &obs.status {
        Status::OutOfMemory { message } => {
            // The profile's limits allow the case's buffers (the gate checked): the case asks for
            // more memory at once than the driver gives, which is the case's to change.
            report.outcome = Outcome::CaseError;
            report.detail = format!(
                "world.buffers: not realised: the driver ran out of memory ({message}) for buffers within the profile's limits"
            );
            return report;
        }
        Status::Unsupported { reason, lacks } => {
            if profile_lacks(profile, lacks) {
                report.outcome = Outcome::Unsupported;
                report.detail = reason.clone();
            } else {
                report.outcome = Outcome::NotRealised;
                report.detail = format!(
                    "the harness says the device lacks {lacks}, but profile {} has it: {reason}",
                    profile.name
                );
            }
            return report;
        }
        Status::NotRealised { reason } => {
            report.outcome = Outcome::NotRealised;
            report.detail = reason.clone();
            return report;
        }
        Status::Crash { message } => {
            report.outcome = Outcome::Crash;
            report.detail = message.clone();
            triage_crash(&mut report, case, valid, triage);
            return report;
        }
        Status::Timeout { seconds } => {
            report.outcome = Outcome::Timeout;
            report.detail = format!("after {seconds:.1} s");
            triage_crash(&mut report, case, valid, triage);
            return report;
        }
        Status::Ran => {}
    }
    let mut problems = Vec::new();
    let mut triaged = Vec::new();
    // Where the model disagrees with the case's own intent, the case (or its generator) is wrong.
    let mut of_the_case = Vec::new();
    let target = report.target.clone();
    let model_problems: Vec<(String, String)> = verdict
        .violations
        .iter()
        .map(|v| (v.vuid.clone(), v.problem.clone()))
        .collect();
    let facts = CaseFacts {
        name: &case.name,
        command: case.command(),
        target: target.as_deref(),
        model: &model,
        layer: &layer,
        layer_other: &report.layer_other,
        problems: &model_problems,
    };
    let explained = triage.explain(&facts);
    for u in &explained.unexplained {
        problems.push(match &u.note {
            Some(n) => format!("{}: {} ({n})", u.vuid, u.side),
            None => format!("{}: {}", u.vuid, u.side),
        });
    }
    for (m, reason) in explained.matched {
        triaged.push(format!(
            "{}{} ({}; triaged {}: {reason})",
            m.vuid,
            m.layer_vuid
                .as_deref()
                .map_or(String::new(), |w| format!(" as {w}")),
            m.observed,
            m.kind.name()
        ));
        report.triage.push(m);
    }
    let m: BTreeSet<&String> = model.iter().collect();
    if valid {
        let unavoidable = match case.body {
            Body::Trace(_) => vec![],
            Body::Accel(_) => model::accel::unavoidable(profile),
        };
        let extra: Vec<&String> = model.iter().filter(|v| !unavoidable.contains(v)).collect();
        if !extra.is_empty() {
            of_the_case.push(format!(
                "intent: the model judges this valid-by-construction case invalid: {}",
                extra
                    .iter()
                    .map(|s| s.as_str())
                    .collect::<Vec<_>>()
                    .join(", ")
            ));
        }
        if !report.layer_other.is_empty() {
            problems.push(format!(
                "the layer reported {} on a valid case",
                report.layer_other.join(", ")
            ));
        }
        match &case.body {
            Body::Trace(t) if extra.is_empty() => {
                let (rendered, matched) = crate::rendered::compare_records(
                    &facts,
                    triage,
                    t,
                    obs.words(),
                    &mut problems,
                    &mut triaged,
                );
                report.output_matches = rendered.as_ref().map(|r| r.failures == 0);
                report.rendered = rendered;
                report.triage.extend(matched);
            }
            Body::Trace(_) => {}
            Body::Accel(a) if extra.is_empty() => {
                let ok = compare_rays(&facts, a, obs.traced(), triage, &mut problems, &mut triaged);
                report.output_matches = Some(ok.0);
                report.triage.extend(ok.1);
                report.rendered = ok.2;
            }
            Body::Accel(_) => {}
        }
    } else if let Some(t) = &report.target {
        if !m.contains(t) {
            of_the_case.push(format!("intent: the model does not report the target {t}"));
        }
    }
    if !of_the_case.is_empty() {
        report.outcome = Outcome::CaseError;
        report.detail = of_the_case
            .into_iter()
            .chain(problems)
            .chain(triaged)
            .collect::<Vec<_>>()
            .join("; ");
        return report;
    }
    let warnings = report
        .rendered
        .as_ref()
        .map(|r| (r.warnings, r.first_warnings.clone()));
    let mut report = conclude(report, problems, triaged);
    // Warnings (the spec's "should") are shown beside the outcome, never failed.
    if let Some((n, first)) = warnings.filter(|(n, _)| *n > 0) {
        let w = format!("{n} warnings; first: {}", first.join(" | "));
        report.detail = if report.detail.is_empty() {
            w
        } else {
            format!("{}; {w}", report.detail)
        };
    }
    report
}

/// Triages the crash or hang of a valid trace case when a `crash` entry names one of the case's
/// shapes (`model::semantics::shapes`, keyed `<command>:<shape>`): the outcome becomes `triaged`, and
/// the detail keeps what happened and says which entry explains it. Any other crash stays one.
fn triage_crash(report: &mut CaseReport, case: &Case, valid: bool, triage: &Triage) {
    let Some(t) = case.as_trace().filter(|_| valid) else {
        return;
    };
    let (model, layer, layer_other) = (
        report.model.clone(),
        report.layer.clone(),
        report.layer_other.clone(),
    );
    let facts = CaseFacts {
        name: &case.name,
        command: case.command(),
        target: None,
        model: &model,
        layer: &layer,
        layer_other: &layer_other,
        problems: &[],
    };
    for shape in model::semantics::shapes(&t.world, &t.call) {
        let key = format!("{}:{shape}", case.command().vk_name());
        if let Some((m, reason)) = triage.explain_crash(&facts, &key) {
            report.detail = format!(
                "{} ({} {key}; triaged {}: {reason})",
                report.detail,
                m.observed,
                m.kind.name()
            );
            report.outcome = Outcome::Triaged;
            report.triage.push(m);
            return;
        }
    }
}

/// Whether the device's profile confirms that it lacks `lack`.
pub fn profile_lacks(profile: &DeviceProfile, lack: &DeviceLack) -> bool {
    match lack {
        DeviceLack::Feature(f) => !profile.has_feature(f),
        DeviceLack::Extension(e) => !profile.has_extension(e),
        DeviceLack::QueueFamilyWithAny(flags) => !profile
            .queue_families
            .iter()
            .any(|fam| flags.iter().any(|f| fam.contains(f))),
        DeviceLack::QueueFamilyWithout(flag) => {
            profile.queue_families.iter().all(|fam| fam.contains(flag))
        }
    }
}

/// The check's rays traced at what the device built, each record judged by the reference tracer
/// against the model's primitives (`model::accel::check::judge_build`): a failing ray is a problem
/// unless the triage names the deviation that explains them; the direct and the real indirect build
/// must draw no layer message and must trace alike. Returns whether everything matched, the triage
/// entry that explained a deviation, and the judged numbers (reported like a rendered case's).
fn compare_rays(
    case: &CaseFacts,
    body: &model::AccelBody,
    traced: Option<&TracedBuild>,
    triage: &Triage,
    problems: &mut Vec<String>,
    triaged: &mut Vec<String>,
) -> (
    bool,
    Option<TriageMatch>,
    Option<model::rendered::RenderedResult>,
) {
    let Some(traced) = traced else {
        problems.push("no traced check of the build came back".into());
        return (false, None, None);
    };
    let mut matched = None;
    if !traced.direct_layer_vuids.is_empty() {
        problems.push(format!(
            "the layer reported {} for the equivalent direct build",
            traced.direct_layer_vuids.join(", ")
        ));
    }
    let judged = match judge_build(body, &traced.records) {
        Ok(j) => j.result,
        Err(e) => {
            problems.push(format!("the model cannot judge the build's rays: {e}"));
            return (false, None, None);
        }
    };
    let rays = model::accel::check::check_rays(body).unwrap_or_default();
    let mut indirect_vs_direct = Vec::new();
    if let Some(ind) = &traced.indirect {
        if !ind.layer_vuids.is_empty() {
            problems.push(format!(
                "the layer reported {} for the real indirect build",
                ind.layer_vuids.join(", ")
            ));
        }
        for (k, (d, i)) in traced.hits.iter().zip(&ind.hits).enumerate() {
            if d != i {
                let origin = rays.get(k).map(|r| r.origin).unwrap_or_default();
                indirect_vs_direct.push(format!(
                    "ray {k} from {origin:?}: direct build {d:?}, indirect build {i:?}"
                ));
            }
        }
    }
    if judged.failures > 0 {
        let first = judged.first_failures.join(" | ");
        let key = format!(
            "{}:{}",
            case.command,
            deviation(body, &traced.records).unwrap_or_else(|| "rays".into())
        );
        let n = judged.rays;
        match triage.explain_output(case, &key) {
            Some((m, reason)) => {
                triaged.push(format!(
                    "output {key} ({} of {n} rays, first {first}; triaged {}: {reason})",
                    judged.failures,
                    m.kind.name(),
                ));
                matched = Some(m);
            }
            None => problems.push(format!(
                "output {key}: {} of {n} rays break what the model allows for its primitives, first {first}",
                judged.failures
            )),
        }
    }
    if let Some(first) = indirect_vs_direct.first() {
        problems.push(format!(
            "the real indirect build traces differently from the direct build: {first}"
        ));
    }
    (
        judged.failures == 0 && indirect_vs_direct.is_empty(),
        matched,
        Some(judged),
    )
}

/// The check rays whose record the reference tracer fails, as a person reads them (all of them when
/// the model cannot judge the build).
pub fn ray_mismatches(body: &model::AccelBody, records: &[u32]) -> Vec<String> {
    let Ok(check) = model::accel::check::BuildCheck::of(body) else {
        return vec!["the model cannot judge the build's rays".into()];
    };
    let Ok(j) =
        model::accel::check::judge_against(&check.rays, &check.allowed, &check.stats, records)
    else {
        return vec!["the records do not fit the check's rays".into()];
    };
    j.verdicts
        .iter()
        .enumerate()
        .filter_map(|(k, v)| match v {
            model::tracer::judge::RayVerdict::Fail(f) => {
                let r = &check.rays[k];
                Some(format!(
                    "ray {k} from {:?} along {:?}: {f}",
                    r.origin, r.direction
                ))
            }
            _ => None,
        })
        .collect()
}

/// The outcome of a comparison that ran: a failure if any problem is left, triaged if only triaged
/// disagreements are, a pass otherwise; the detail lists the problems, then the triaged ones.
fn conclude(mut report: CaseReport, problems: Vec<String>, triaged: Vec<String>) -> CaseReport {
    report.outcome = if !problems.is_empty() {
        Outcome::Fail
    } else if !triaged.is_empty() {
        Outcome::Triaged
    } else {
        Outcome::Pass
    };
    report.detail = problems
        .into_iter()
        .chain(triaged)
        .collect::<Vec<_>>()
        .join("; ");
    report
}

/// The scope part of a VUID (`vkCmdTraceRaysIndirectKHR` of `VUID-vkCmdTraceRaysIndirectKHR-stride-03686`).
pub(crate) fn vuid_scope(vuid: &str) -> Option<&str> {
    vuid.strip_prefix("VUID-")?.split('-').next()
}
