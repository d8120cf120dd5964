//! `rtconf export`: a case's plan written as a standalone C program for a bug report — the model's
//! verdict and, for a valid trace case or a build run as valid (its traced check), what it allows
//! each ray's record, on the case's profile written in, the plan the harness would run
//! ([`harness::plan::CallPlan`]) as its calls.

use crate::error::SessionError;
use crate::sources;
use harness::plan::CallPlan;
use harness::Execution;
use model::{Case, RuleSet};
use std::path::{Path, PathBuf};

/// What an export wrote.
#[derive(Debug)]
pub struct Exported {
    /// `DIR/repro.c`.
    pub source: PathBuf,
    /// The command that builds it, run in its folder.
    pub build_command: &'static str,
    /// Whether the program runs the call for real (a trace submitted, read back and compared).
    pub run_valid: bool,
    /// Whether the program repeats the harness's traced check of a valid build (one info: info 0
    /// built directly and the check's rays judged); false for a build of several infos.
    pub checks_build: bool,
}

/// Writes `out/repro.c` for `case`, judged with the rules of `from` (empty: the installed registry)
/// on the profile it names.
pub fn export(case: &Case, from: &[PathBuf], out: &Path) -> Result<Exported, SessionError> {
    let set = sources::load_sources(from)?;
    let rules = RuleSet::from_vuids(&set);
    let profile = sources::profile_for(&case.profile)?;
    let verdict = model::validate(&rules, &profile, case);
    let exec = Execution::for_case(case, &profile);
    let plan = CallPlan::of(case, &exec)?;
    // A valid trace case's records are judged per launch ID against what the model allows each ray;
    // a build's output check is the plan's own.
    let launch = match case.as_trace() {
        Some(t) if exec.run_valid => {
            if let Err(why) = case.runnable(&profile) {
                return Err(SessionError::Usage(format!(
                    "{} is kept from drivers (its scene or reads are undefined), so it is not exported: {why}",
                    case.name
                )));
            }
            model::semantics::expected_launch(&t.world, &t.call)
        }
        _ => None,
    };
    let mut about = vec![
        format!(
            "intent: {}",
            match &case.intent {
                model::Intent::Valid => "valid".to_string(),
                model::Intent::Violates { vuid, also } if also.is_empty() =>
                    format!("violates {vuid}"),
                model::Intent::Violates { vuid, also } =>
                    format!("violates {vuid} (and {})", also.join(", ")),
            }
        ),
        format!(
            "profile: {}, registry {}",
            case.profile,
            set.version.as_deref().unwrap_or("?")
        ),
    ];
    if let Some(s) = &case.seed {
        about.push(format!("seed: {s}"));
    }
    if plan.command.is_trace() && !exec.run_valid {
        about.push("invalid: recorded under the layer, which drops it; never submitted".into());
    }
    // A build run as valid: the program repeats the harness's traced check of it (a direct build
    // with the ranges the model reads, the check's rays traced with ray query or the check
    // pipeline) and judges each ray.
    let build_check = match case.as_accel() {
        // The harness checks a build of one info only (`harness::accel_check`), and so does the program.
        Some(body) if exec.run_valid && body.call.infos.len() != 1 => {
            about.push(
                "valid build of several infos: the harness's traced check handles one info, so neither it nor this program traces rays at the result"
                    .into(),
            );
            None
        }
        Some(body) if exec.run_valid => {
            let plan = harness::plan::check::CheckPlan::of(body)?;
            let check = model::accel::check::BuildCheck::of(body).map_err(|e| {
                SessionError::Usage(format!(
                    "{}: the model cannot check its build: {e}",
                    case.name
                ))
            })?;
            if check.rays != plan.rays {
                return Err(SessionError::Usage(format!(
                    "{}: the harness's check rays are not the model's",
                    case.name
                )));
            }
            about.push(
                "valid build: also built directly with the ranges the model reads, and the check's rays traced at it (ray query, else the check pipeline) and judged"
                    .into(),
            );
            Some(export::BuildCheckExpectation {
                plan,
                allowed: check.allowed,
            })
        }
        _ => None,
    };
    let checks_build = build_check.is_some();
    let expectation = export::Expectation {
        model_vuids: verdict.vuids().into_iter().map(String::from).collect(),
        violations: verdict
            .violations
            .iter()
            .map(|v| format!("{} at {}: {}", v.vuid, v.context, v.problem))
            .collect(),
        launch,
        build_check,
        about,
    };
    let program =
        export::export(&plan, &expectation).map_err(|e| SessionError::Usage(e.to_string()))?;
    std::fs::create_dir_all(out).map_err(|e| SessionError::io(out.display().to_string(), e))?;
    let source = out.join("repro.c");
    std::fs::write(&source, &program.source)
        .map_err(|e| SessionError::io(source.display().to_string(), e))?;
    Ok(Exported {
        source,
        build_command: program.build_command,
        run_valid: exec.run_valid,
        checks_build,
    })
}
