//! Replaying one case as a run would: the gate, the execution on the driver in a worker process (so a
//! driver that kills or hangs it gives `crash` or `timeout`, with its message, as in a run), the model's
//! verdict on the case as it ran, and the comparison against the same triage files.

use crate::error::SessionError;
use crate::run::{Judging, Ran};
use crate::sources;
use harness::{Driver, Executor, TraceCheck};
use model::case::YAML_FILE_LIMIT;
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
    /// Seconds the case may take in its worker (0: a run's default, 60).
    pub timeout: u64,
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

/// A case file's text, at most [`YAML_FILE_LIMIT`] bytes (the one way a case file is read).
pub fn case_text(path: &std::path::Path) -> std::io::Result<String> {
    vk_registry::input::read_text_at_most(path, YAML_FILE_LIMIT, "a case file")
}

/// Reads a case file (any command) with a located error: one that does not parse, or that is not a
/// case ([`Case::read`]: a name resolving to nothing, a group the pipeline lacks).
pub fn read_case(path: &std::path::Path) -> Result<Case, SessionError> {
    let shown = path.display().to_string();
    let text = case_text(path).map_err(|e| SessionError::io(&shown, e))?;
    Ok(Case::read(&shown, &text)?)
}

/// A case report's detail (`path: problem`, as an error of the case gives it) as a located error of the
/// case file: `file:line:col: path: problem` (the line and column from [`model::locate`]).
pub fn located(file: &std::path::Path, detail: &str) -> String {
    let shown = file.display().to_string();
    let text = case_text(file).unwrap_or_default();
    let at = detail.split_once(": ").map_or("", |(at, _)| at);
    match model::locate::locate(&text, at) {
        Some((l, c)) => format!("{shown}:{l}:{c}: {detail}"),
        None => format!("{shown}: {detail}"),
    }
}

/// Replays `case`: see the module documentation.
pub fn replay(case: &Case, config: &ReplayConfig) -> Result<Replayed, SessionError> {
    let layer = harness::validation_layer()?;
    let set = sources::registry_for_layer(&config.from, Some(&layer))?;
    let rules = RuleSet::from_vuids(&set);
    let driver = Driver::parse(&config.driver);
    harness::check_driver(&driver)?;
    let profile = sources::profile_for(config.profile.as_deref().unwrap_or(&case.profile))?;
    let triage = sources::triage_for(&[], Some(&layer.version), &driver)?;
    let judging = Judging::new(&rules, &profile, &triage);
    // What it runs on comes from an instance of this process (as the driver check makes one); the
    // case itself runs in a worker process, so a driver that dies or hangs gives a crash or timeout.
    let running_on = Executor::new(driver)?.running_on();
    std::env::set_var(harness::worker::DRIVER_ENV, &config.driver);
    let timeout = std::time::Duration::from_secs(if config.timeout == 0 {
        60
    } else {
        config.timeout
    });
    let ran = judging.run_in_worker(case, config.check, timeout);
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
        (Some(a), Some(t)) => model::accel::check::deviation(a, &t.records),
        _ => None,
    };
    Ok(Replayed {
        ran,
        deviation,
        running_on,
        plan,
    })
}
