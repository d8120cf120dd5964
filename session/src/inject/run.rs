//! What a run does with an injection: the copy handed to a worker in place of each case (gated like
//! any case), the `injection` note of its report, and the totals of `summary.json`.

use super::{inject, Injected, Injection, NotApplicable};
use model::Case;

/// What a run with `--inject` did with one case (its report's `injection`).
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct CaseInjection {
    /// `KIND:SIZE`.
    pub injection: String,
    /// Whether the driver ran the perturbed copy (false: not applicable, the case ran as it is).
    pub applied: bool,
    /// What the copy changed, or why the injection was not applicable.
    pub detail: String,
}

/// `summary.json`'s `inject`: the cases of a run with `--inject`.
#[derive(Debug, Default, Clone, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct InjectTotals {
    pub injection: String,
    /// Cases whose perturbed copy ran.
    pub applied: usize,
    /// Cases the injection had nothing to act on (run as they are; neither detected nor missed).
    pub not_applicable: usize,
    /// Applied cases whose outcome catches the fault ([`detects`]).
    pub detected: usize,
}

/// Whether a case's outcome catches an injected fault: the run fails it (a REQ violation or an error
/// outside its bound, or the driver crashing or hanging on the copy).
pub fn detects(outcome: crate::compare::Outcome) -> bool {
    use crate::compare::Outcome;
    matches!(outcome, Outcome::Fail | Outcome::Crash | Outcome::Timeout)
}

/// The perturbed copy of `case`, if the gate lets it reach a driver: a copy the model judges invalid
/// or not runnable is not applicable (the layer stays quiet; only the output decides).
pub fn applied(
    injection: &Injection,
    seed: u64,
    case: &Case,
    judging: &crate::run::Judging,
) -> Result<Injected, NotApplicable> {
    let injected = inject(case, injection, judging.profile, seed)?;
    if let Some(report) = crate::gate::gate(&injected.case, judging) {
        return Err(NotApplicable(format!(
            "the perturbed copy may not reach a driver: {}",
            report.detail
        )));
    }
    Ok(injected)
}

/// The case a run hands the driver in place of `case`, and what its report will say: the case itself
/// without an injection or where the injection is not applicable.
pub(crate) fn executed(
    injection: Option<&(Injection, u64)>,
    case: &Case,
    judging: &crate::run::Judging,
) -> (Case, Option<CaseInjection>) {
    let Some((injection, seed)) = injection else {
        return (case.clone(), None);
    };
    let (run, applied, detail) = match applied(injection, *seed, case, judging) {
        Ok(i) => (i.case, true, i.what),
        Err(why) => (case.clone(), false, format!("not applicable: {why}")),
    };
    (
        run,
        Some(CaseInjection {
            injection: injection.to_string(),
            applied,
            detail,
        }),
    )
}

/// The injection totals of a run's results.
pub(crate) fn totals(
    injection: &Injection,
    results: &std::path::Path,
) -> Result<InjectTotals, crate::SessionError> {
    let mut t = InjectTotals {
        injection: injection.to_string(),
        ..Default::default()
    };
    for line in crate::results::read_lines(results)? {
        match &line.report.injection {
            Some(i) if i.applied => {
                t.applied += 1;
                if detects(line.report.outcome) {
                    t.detected += 1;
                }
            }
            _ => t.not_applicable += 1,
        }
    }
    Ok(t)
}
