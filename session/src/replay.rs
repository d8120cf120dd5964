//! Replaying one case in this process, as a run would judge it: the gate, the execution on the driver,
//! the model's verdict on the case as it ran, and the comparison against the same triage files.

use crate::error::SessionError;
use crate::run::{Judging, Ran};
use crate::sources;
use harness::{Driver, Executor, TraceCheck};
use model::{Case, RuleSet};
use std::path::PathBuf;

/// What a replay is asked to do.
#[derive(Debug, Clone, Default)]
pub struct ReplayConfig {
    pub driver: String,
    /// Registry sources for the rules (empty: the installed registry).
    pub from: Vec<PathBuf>,
    /// The device profile the model judges with (None: the case's own).
    pub profile: Option<String>,
    /// How a build's traced check traces its rays.
    pub check: TraceCheck,
}

/// Everything a replay found, for printing.
#[derive(Debug)]
pub struct Replayed {
    /// The case as it ran, its observation, verdict and report.
    pub ran: Ran,
    /// For a build whose rays disagree: the named deviation that explains them, if one does.
    pub deviation: Option<String>,
    /// The device, driver and layer it ran on.
    pub running_on: harness::RunningOn,
    /// What the harness made and recorded for it (None when the gate kept it from the driver or the
    /// harness cannot realise it).
    pub plan: Option<harness::plan::CallPlan>,
}

/// Reads a case file (any command) with a located error.
pub fn read_case(path: &std::path::Path) -> Result<Case, SessionError> {
    let shown = path.display().to_string();
    let text = std::fs::read_to_string(path).map_err(|e| SessionError::io(&shown, e))?;
    Ok(Case::from_yaml(&shown, &text)?)
}

/// Replays `case`: see the module documentation.
pub fn replay(case: &Case, config: &ReplayConfig) -> Result<Replayed, SessionError> {
    let set = sources::load_sources(&config.from)?;
    let rules = RuleSet::from_vuids(&set);
    let profile = sources::profile_for(config.profile.as_deref().unwrap_or(&case.profile))?;
    let driver = Driver::parse(&config.driver);
    let triage = sources::triage_for(&[], set.version.as_deref(), &driver)?;
    let judging = Judging {
        rules: &rules,
        profile: &profile,
        triage: &triage,
    };
    let mut executor = Executor::new(driver)?;
    let ran = judging.run_here(&mut executor, case, config.check);
    let plan = ran.observation.as_ref().and_then(|_| {
        let exec = harness::Execution {
            check: config.check,
            ..harness::Execution::for_case(case, &profile)
        };
        harness::plan::CallPlan::of(case, &exec).ok()
    });
    let deviation = match (
        ran.case.as_accel(),
        ran.observation.as_ref().and_then(|o| o.traced()),
    ) {
        (Some(a), Some(t)) => model::accel::check::deviation(a, &t.hits),
        _ => None,
    };
    Ok(Replayed {
        ran,
        deviation,
        running_on: executor.running_on(),
        plan,
    })
}
