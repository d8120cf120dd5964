//! The one place where the model's verdict and expected output meet the driver's observation: per case,
//! the model's VUIDs, the layer's VUIDs, the output check, and the outcome against the triage file.

use crate::observe::{Observation, Status};
use model::rules::modelled_scope;
use model::{Case, Intent, Verdict};
use std::collections::BTreeSet;

/// A known, written-down disagreement: a layer gap, a driver bug, or a model limitation.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TriageEntry {
    pub vuid: String,
    /// `layer-gap` (the layer does not check it), `layer-extra`, `driver`, or `model`.
    pub kind: String,
    pub reason: String,
    /// A case file that reproduces it.
    #[serde(default)]
    pub case: Option<String>,
}

/// The triage file of one driver and layer version.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Triage {
    #[serde(default)]
    pub layer_version: Option<String>,
    #[serde(default)]
    pub entries: Vec<TriageEntry>,
}

impl Triage {
    pub fn from_yaml(path: &str, text: &str) -> Result<Triage, String> {
        serde_yaml::from_str(text).map_err(|e| {
            let loc = e
                .location()
                .map(|l| format!(":{}:{}", l.line(), l.column()))
                .unwrap_or_default();
            format!("{path}{loc}: {e}")
        })
    }

    /// The entries of the named files; with none named, of `dir/<driver>.yaml` and
    /// `dir/layer-<layer version>.yaml` where they exist.
    pub fn load(
        dir: &std::path::Path,
        named: &[std::path::PathBuf],
        layer_version: Option<&str>,
        driver: &str,
    ) -> Result<Triage, String> {
        let (paths, must_exist) = if named.is_empty() {
            let mut v = vec![dir.join(format!("{driver}.yaml"))];
            if let Some(ver) = layer_version {
                v.push(dir.join(format!("layer-{ver}.yaml")));
            }
            (v, false)
        } else {
            (named.to_vec(), true)
        };
        let mut all = Triage::default();
        for p in paths {
            match std::fs::read_to_string(&p) {
                Ok(t) => all
                    .entries
                    .extend(Triage::from_yaml(&p.display().to_string(), &t)?.entries),
                Err(_) if !must_exist => {}
                Err(e) => return Err(format!("triage file {}: {e}", p.display())),
            }
        }
        Ok(all)
    }

    /// The entry for a VUID; an entry's `vuid` may hold `*` wildcards (`VUID-vkCmdTraceRays*KHR-None-03429`
    /// covers the direct and the indirect command).
    pub fn covers(&self, vuid: &str) -> Option<&TriageEntry> {
        self.entries.iter().find(|e| wildcard_match(&e.vuid, vuid))
    }
}

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
    Unsupported,
    Crash,
    Timeout,
}

/// One line of `results.jsonl`.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct CaseReport {
    pub case: String,
    pub command: String,
    /// The VUID an invalid case targets; None for valid cases.
    pub target: Option<String>,
    pub outcome: Outcome,
    /// VUIDs the model says the call violates.
    pub model: Vec<String>,
    /// VUIDs of the modelled commands the layer reported.
    pub layer: Vec<String>,
    /// Other VUIDs the layer reported (outside the modelled scopes), kept for the record.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub layer_other: Vec<String>,
    /// For valid cases: whether the output words equal the model's expectation.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub output_matches: Option<bool>,
    /// What went wrong or what triage entry applied.
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub detail: String,
    pub millis: f64,
}

/// The report of a valid case that is not run because its launch reads outside its tables (undefined
/// behaviour the driver may crash on): a generator or case-file bug, reported as a failure.
pub fn undefined_case(case: &Case, reads: &[String]) -> CaseReport {
    CaseReport {
        case: case.name.clone(),
        command: case.call.command().to_string(),
        target: None,
        outcome: Outcome::Fail,
        model: vec![],
        layer: vec![],
        layer_other: vec![],
        output_matches: None,
        detail: format!(
            "not run: the valid case's launch has undefined reads: {}",
            reads.join("; ")
        ),
        millis: 0.0,
    }
}

/// Compares one case's observation with the model.
pub fn compare(
    case: &Case,
    verdict: &Verdict,
    obs: &Observation,
    triage: &Triage,
    millis: f64,
) -> CaseReport {
    let model: Vec<String> = verdict.vuids().into_iter().map(String::from).collect();
    let (layer, layer_other): (Vec<String>, Vec<String>) = obs
        .layer_vuids
        .iter()
        .cloned()
        .partition(|v| vuid_scope(v).is_some_and(modelled_scope));
    let target = match &case.intent {
        Intent::Valid => None,
        Intent::Violates { vuid, .. } => Some(vuid.clone()),
    };
    let mut report = CaseReport {
        case: case.name.clone(),
        command: case.call.command().to_string(),
        target,
        outcome: Outcome::Pass,
        model: model.clone(),
        layer: layer.clone(),
        layer_other,
        output_matches: None,
        detail: String::new(),
        millis,
    };
    match &obs.status {
        Status::Unsupported { reason } => {
            report.outcome = Outcome::Unsupported;
            report.detail = reason.clone();
            return report;
        }
        Status::Crash { message } => {
            report.outcome = Outcome::Crash;
            report.detail = message.clone();
            return report;
        }
        Status::Timeout { seconds } => {
            report.outcome = Outcome::Timeout;
            report.detail = format!("after {seconds:.1} s");
            return report;
        }
        Status::Ran => {}
    }
    let mut problems = Vec::new();
    let mut triaged = Vec::new();
    let m: BTreeSet<&String> = model.iter().collect();
    let l: BTreeSet<&String> = layer.iter().collect();
    for v in m.symmetric_difference(&l) {
        let side = if m.contains(v) {
            "model only"
        } else {
            "layer only"
        };
        match triage.covers(v) {
            Some(t) => triaged.push(format!("{v} ({side}; triaged {}: {})", t.kind, t.reason)),
            None => problems.push(format!("{v}: {side}")),
        }
    }
    if case.intent == Intent::Valid {
        if !model.is_empty() {
            problems.push(format!(
                "the model judges this valid-by-construction case invalid: {}",
                model.join(", ")
            ));
        }
        if obs.layer_vuids.iter().any(|v| !l.contains(v)) {
            problems.push(format!(
                "the layer reported {} on a valid case",
                report.layer_other.join(", ")
            ));
        }
        if let Some(expected) = model::semantics::expected_launch(&case.world, &case.call) {
            match &obs.output {
                Some(words) => {
                    let ok = *words == expected.words;
                    report.output_matches = Some(ok);
                    if !ok {
                        let first = words.iter().zip(&expected.words).position(|(a, b)| a != b);
                        problems.push(match first {
                            Some(i) => format!(
                                "output word {i}: driver 0x{:08x}, model 0x{:08x}",
                                words[i], expected.words[i]
                            ),
                            None => format!(
                                "output has {} words, model expects {}",
                                words.len(),
                                expected.words.len()
                            ),
                        });
                    }
                }
                None => problems.push("no output was read back".into()),
            }
        }
    } else if let Some(t) = &report.target {
        if !m.contains(t) {
            problems.push(format!("the model does not report the target {t}"));
        }
    }
    conclude(report, problems, triaged)
}

/// Compares one build case's observation with the model. `model` is the model's verdict for the world
/// with the device's build sizes; `unavoidable` the VUIDs every case violates on the device (the missing
/// accelerationStructureIndirectBuild), so a case expecting no more than those is a valid one: its
/// indirect call must draw exactly them, and the traced check of its direct build (and, on a device
/// with the feature, of its real indirect build) must agree with the model's primitives.
pub fn compare_build(
    case: &model::accel::BuildCase,
    model: &[String],
    obs: &crate::accel::BuildObservation,
    unavoidable: &[String],
    triage: &Triage,
    millis: f64,
) -> CaseReport {
    let command = model::accel::call::COMMAND;
    let expected = case.expected_vuids();
    let valid = expected.iter().all(|v| unavoidable.contains(v));
    let (layer, layer_other): (Vec<String>, Vec<String>) = obs
        .layer_vuids
        .iter()
        .cloned()
        .partition(|v| vuid_scope(v) == Some(command));
    let target = match &case.intent {
        Intent::Violates { vuid, .. } if !valid => Some(vuid.clone()),
        _ => None,
    };
    let mut report = CaseReport {
        case: case.name.clone(),
        command: command.to_string(),
        target,
        outcome: Outcome::Pass,
        model: model.to_vec(),
        layer: layer.clone(),
        layer_other,
        output_matches: None,
        detail: String::new(),
        millis,
    };
    let status = obs.status.as_str();
    if status != "ran" {
        let (outcome, detail) = if let Some(r) = status.strip_prefix("unsupported: ") {
            (Outcome::Unsupported, r)
        } else if let Some(r) = status.strip_prefix("timeout: ") {
            (Outcome::Timeout, r)
        } else {
            (
                Outcome::Crash,
                status.strip_prefix("crash: ").unwrap_or(status),
            )
        };
        report.outcome = outcome;
        report.detail = detail.to_string();
        return report;
    }
    let mut problems = Vec::new();
    let mut triaged = Vec::new();
    let m: BTreeSet<&String> = model.iter().collect();
    let l: BTreeSet<&String> = layer.iter().collect();
    for v in m.symmetric_difference(&l) {
        let side = if m.contains(v) {
            "model only"
        } else {
            "layer only"
        };
        match triage.covers(v) {
            Some(t) => triaged.push(format!("{v} ({side}; triaged {}: {})", t.kind, t.reason)),
            None => problems.push(format!("{v}: {side}")),
        }
    }
    if valid {
        let extra: Vec<&String> = model.iter().filter(|v| !unavoidable.contains(v)).collect();
        if !extra.is_empty() {
            problems.push(format!("the model judges this valid-by-construction case invalid with the device's sizes: {extra:?}"));
        }
        if !report.layer_other.is_empty() {
            problems.push(format!(
                "the layer reported {} on a valid case",
                report.layer_other.join(", ")
            ));
        }
        if !obs.direct_layer_vuids.is_empty() {
            problems.push(format!(
                "the layer reported {} for the equivalent direct build",
                obs.direct_layer_vuids.join(", ")
            ));
        }
        if !obs.indirect_layer_vuids.is_empty() {
            problems.push(format!(
                "the layer reported {} for the real indirect build",
                obs.indirect_layer_vuids.join(", ")
            ));
        }
        if extra.is_empty() {
            let ok = obs.ray_mismatches.is_empty() && obs.indirect_vs_direct.is_empty();
            report.output_matches = Some(ok);
            if !obs.ray_mismatches.is_empty() {
                let key = format!(
                    "output:{command}:{}",
                    crate::accel::deviation(case, obs).unwrap_or_else(|| "rays".into())
                );
                let first = obs.ray_mismatches[0].clone();
                match triage.covers(&key) {
                    Some(t) => triaged.push(format!(
                        "{key} ({} of {} rays, first {first}; triaged {}: {})",
                        obs.ray_mismatches.len(),
                        obs.rays,
                        t.kind,
                        t.reason
                    )),
                    None => problems.push(format!(
                        "{key}: {} of {} rays disagree with the model's primitives, first {first}",
                        obs.ray_mismatches.len(),
                        obs.rays
                    )),
                }
            }
            if let Some(first) = obs.indirect_vs_direct.first() {
                problems.push(format!(
                    "the real indirect build traces differently from the direct build: {first}"
                ));
            }
        }
    } else if let Some(t) = &report.target {
        if !m.contains(t) {
            problems.push(format!("the model does not report the target {t}"));
        }
    }
    conclude(report, problems, triaged)
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
pub fn vuid_scope(vuid: &str) -> Option<&str> {
    vuid.strip_prefix("VUID-")?.split('-').next()
}

/// Whether `text` matches `pattern`, where `*` stands for any run of characters.
fn wildcard_match(pattern: &str, text: &str) -> bool {
    let mut parts = pattern.split('*');
    let first = parts.next().unwrap_or("");
    let Some(mut rest) = text.strip_prefix(first) else {
        return false;
    };
    let parts: Vec<&str> = parts.collect();
    for (i, part) in parts.iter().enumerate() {
        if i == parts.len() - 1 {
            return rest.ends_with(part);
        }
        match rest.find(part) {
            Some(at) => rest = &rest[at + part.len()..],
            None => return false,
        }
    }
    rest.is_empty()
}

#[cfg(test)]
mod tests {
    use super::wildcard_match;

    #[test]
    fn triage_patterns_match_both_trace_commands_and_nothing_else() {
        let p = "VUID-vkCmdTraceRays*KHR-None-03429";
        assert!(wildcard_match(p, "VUID-vkCmdTraceRaysKHR-None-03429"));
        assert!(wildcard_match(
            p,
            "VUID-vkCmdTraceRaysIndirectKHR-None-03429"
        ));
        assert!(!wildcard_match(p, "VUID-vkCmdTraceRaysNV-None-03429"));
        assert!(!wildcard_match(p, "VUID-vkCmdTraceRaysKHR-None-034290"));
        assert!(wildcard_match("VUID-x", "VUID-x"));
        assert!(!wildcard_match("VUID-x", "VUID-xy"));
    }
}
