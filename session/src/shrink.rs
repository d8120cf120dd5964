//! Shrinking a run's failures: each failing trace case is rebuilt from its seed and shrunk (proptest's
//! value tree) to a minimal case that still fails the same way on the driver, written to
//! `cases/regressions/` ready to replay.

use crate::compare::{CaseReport, Outcome};
use crate::run::{Judging, RunConfig};
use crate::sources;
use generator::CaseSpec;
use harness::{Driver, Executor, TraceCheck};
use model::{Case, Intent};
use std::path::Path;

/// Shrinks up to `config.shrink` failing cases of the run; returns one line per case, as a person reads
/// it (where the minimal case went, or why it was not shrunk).
pub(crate) fn shrink_failures(
    config: &RunConfig,
    judging: &Judging,
    profile_name: &str,
    results: &Path,
) -> Vec<String> {
    let failing: Vec<String> = match crate::report::reports(results) {
        Ok(r) => r
            .filter(|r: &CaseReport| r.outcome == Outcome::Fail)
            .map(|r| r.case)
            .take(config.shrink)
            .collect(),
        Err(_) => return vec![],
    };
    if failing.is_empty() {
        return vec![];
    }
    let executor = match Executor::new(Driver::parse(&config.driver)) {
        Ok(e) => std::cell::RefCell::new(e),
        Err(e) => return vec![format!("cannot shrink: {e}")],
    };
    let dir = sources::repo_dir().join("cases").join("regressions");
    let mut lines = Vec::new();
    for name in failing {
        let path = config.out.join("failures").join(format!("{name}.yaml"));
        let Some(case) = crate::replay::case_text(&path)
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
        let command = case.command();
        if !command.is_trace() {
            lines.push(format!(
                "{name}: build cases are not shrunk; kept as {}",
                path.display()
            ));
            continue;
        }
        let mut spec = match &case.intent {
            Intent::Valid if name.contains("-rendered-") => CaseSpec::rendered(command),
            Intent::Valid => CaseSpec::valid(command),
            Intent::Violates { vuid, .. } => CaseSpec::violate(command, vuid),
        };
        if name.contains("-limits-") {
            spec = spec.at_limits();
        }
        // A candidate fails when it runs and compares as a failure; one that is not runnable is never
        // handed to the driver (and does not count as failing).
        let fails = |c: &Case| {
            let ran = judging.run_here(&mut executor.borrow_mut(), c, TraceCheck::Auto);
            ran.observation.is_some() && ran.report.outcome == Outcome::Fail
        };
        match generator::shrink_failure(
            judging.profile,
            profile_name,
            judging.rules,
            &spec,
            seed,
            index,
            &dir,
            fails,
        ) {
            Ok(Some(s)) => lines.push(format!(
                "shrunk {name} in {} steps: {}",
                s.steps,
                s.path.display()
            )),
            Ok(None) => lines.push(format!(
                "{name} no longer fails when regenerated from its seed; kept as {}",
                path.display()
            )),
            Err(e) => lines.push(format!("shrinking {name}: {e}")),
        }
    }
    lines
}
