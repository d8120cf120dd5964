//! The rendered-output half of a comparison (`model::rendered`): a valid trace case's records judged
//! per ray, each failure a problem of the case, the numbers kept in its report.

use crate::triage::{CaseFacts, Triage, TriageMatch};
use model::rendered::{judge_records, RenderedResult};
use model::TraceBody;

/// The output part of [`crate::compare::compare`] for a valid trace case: the records judged, each
/// failure a problem — unless every failure is one named deviation ([`model::rendered::deviation`])
/// that a triage `output` entry explains (key `<command>:<deviation>`): then it is triaged, and the
/// entry comes back. The warnings come back (in the result) to be shown beside the outcome.
pub(crate) fn compare_records(
    case: &CaseFacts,
    triage: &Triage,
    body: &TraceBody,
    words: Option<&[u32]>,
    problems: &mut Vec<String>,
    triaged: &mut Vec<String>,
) -> (Option<RenderedResult>, Option<TriageMatch>) {
    let Some(words) = words else {
        problems.push("no output was read back".into());
        return (None, None);
    };
    match judge_records(body, words) {
        Ok(j) => {
            let mut matched = None;
            let r = &j.result;
            if r.failures > 0 {
                let what = format!(
                    "{} of {} launch IDs break what the spec requires; first: {}",
                    r.failures,
                    r.rays,
                    r.first_failures.join(" | ")
                );
                let explained = model::rendered::deviation(&j).and_then(|d| {
                    let key = format!("{}:{d}", case.command.vk_name());
                    triage.explain_output(case, &key).map(|m| (key, m))
                });
                match explained {
                    Some((key, (m, reason))) => {
                        triaged.push(format!(
                            "output {key} ({what}; triaged {}: {reason})",
                            m.kind.name()
                        ));
                        matched = Some(m);
                    }
                    None => problems.push(what),
                }
            }
            (Some(j.result), matched)
        }
        Err(e) => {
            problems.push(e);
            (None, None)
        }
    }
}

/// Median, 99th percentile and maximum of one error histogram.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Quantiles {
    pub count: u64,
    pub median: Option<f64>,
    pub p99: Option<f64>,
    pub max: Option<f64>,
}

impl Quantiles {
    fn of(h: &model::tracer::summary::Histogram) -> Quantiles {
        Quantiles {
            count: h.count,
            median: h.median(),
            p99: h.p99(),
            max: (h.count > 0).then_some(h.max),
        }
    }
}

/// The rendered output of one command's cases in a run (`summary.json`'s `rendered`).
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct RenderedTotals {
    pub cases: u64,
    pub rays: u64,
    pub req: u64,
    pub vary: u64,
    /// Share of launch IDs whose allowed set had a VARY part.
    pub vary_share: f64,
    /// What the driver chose where the spec let it.
    pub vary_hit: u64,
    pub vary_miss: u64,
    /// Launch IDs that had to run an intersection shader.
    #[serde(default)]
    pub shader_required: u64,
    pub warnings: u64,
    pub failures: u64,
    /// Share of ray/primitive tests that needed exact arithmetic.
    pub exact_share: f64,
    pub t_error_ulps: Quantiles,
    pub t_error_rel: Quantiles,
    pub bary_error_abs: Quantiles,
    pub bary_error_ulps: Quantiles,
    #[serde(skip)]
    summary: model::tracer::summary::Summary,
    #[serde(skip)]
    pairs: (u64, u64),
}

impl RenderedTotals {
    /// Adds one case's result.
    pub fn add(&mut self, r: &RenderedResult) {
        self.cases += 1;
        self.rays += r.rays;
        self.req += r.req;
        self.vary += r.vary;
        self.vary_hit += r.vary_hit;
        self.vary_miss += r.vary_miss;
        self.shader_required += r.shader_required;
        self.warnings += r.warnings;
        self.failures += r.failures;
        self.pairs.0 += r.pair_tests;
        self.pairs.1 += r.exact_evaluations;
        self.summary.merge(&r.summary);
        self.vary_share = self.vary as f64 / self.rays.max(1) as f64;
        self.exact_share = self.pairs.1 as f64 / self.pairs.0.max(1) as f64;
        self.t_error_ulps = Quantiles::of(&self.summary.t_error_ulps);
        self.t_error_rel = Quantiles::of(&self.summary.t_error_rel);
        self.bary_error_abs = Quantiles::of(&self.summary.bary_error_abs);
        self.bary_error_ulps = Quantiles::of(&self.summary.bary_error_ulps);
    }
}
