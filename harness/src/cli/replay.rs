//! `rtconf replay CASE.yaml`: one case on a driver, in this process, with the full comparison printed.
//! The case file is a trace case or a build case (`vkCmdBuildAccelerationStructuresIndirectKHR`); the
//! kind is detected from the file.

use clap::Args;
use harness::accel::{BuildOptions, TraceCheck};
use harness::compare::{compare, compare_build, Triage};
use std::path::PathBuf;

#[derive(Args)]
pub struct ReplayArgs {
    case: PathBuf,
    #[arg(long, default_value = "lavapipe")]
    driver: String,
    #[arg(long = "from")]
    from: Vec<PathBuf>,
    /// The device profile the model judges with (default: the case's own).
    #[arg(long)]
    profile: Option<String>,
    /// Build cases: how the built structure is traced (auto: ray query where the device has it, else a
    /// ray tracing pipeline).
    #[arg(long, value_enum, default_value = "auto")]
    check: CheckArg,
}

#[derive(Clone, Copy, clap::ValueEnum)]
enum CheckArg {
    Auto,
    RayQuery,
    Pipeline,
}

/// The triage files `rtconf run` uses for this layer version and driver, so a replay judges a case
/// exactly as the run did.
fn default_triage(layer_version: Option<&str>, driver: &str) -> Result<Triage, String> {
    let name = harness::vulkan::Driver::parse(driver).name();
    Triage::load(&super::repo_dir().join("triage"), &[], layer_version, &name)
}

pub fn run(a: ReplayArgs) -> Result<i32, String> {
    let shown = a.case.display().to_string();
    let text =
        std::fs::read_to_string(&a.case).map_err(|e| format!("{shown}: cannot read: {e}"))?;
    let case = match model::Case::from_yaml(&shown, &text) {
        Ok(c) => c,
        Err(trace_err) => match model::accel::BuildCase::from_yaml(&shown, &text) {
            Ok(b) => return run_build(&a, b),
            Err(build_err) if looks_like_build(&text) => return Err(build_err.to_string()),
            Err(_) => return Err(trace_err.to_string()),
        },
    };
    let set = super::load_sources(&a.from)?;
    let rules = model::RuleSet::from_vuids(&set);
    let profile = super::profile_for(a.profile.as_deref().unwrap_or(&case.profile))?;
    let verdict = model::validate(&rules, &profile, &case.world, &case.call);
    let driver = harness::vulkan::Driver::parse(&a.driver);
    let mut ex = harness::execute::Executor::new(driver).map_err(|e| e.to_string())?;
    let started = std::time::Instant::now();
    let obs = harness::execute::execute(&case, &mut ex);
    let triage = default_triage(set.version.as_deref(), &a.driver)?;
    let report = compare(
        &case,
        &verdict,
        &obs,
        &triage,
        started.elapsed().as_secs_f64() * 1000.0,
    );
    println!("case:    {}", case.name);
    println!("intent:  {:?}", case.intent);
    println!("status:  {:?}", obs.status);
    println!(
        "model:   {}",
        if report.model.is_empty() {
            "valid".into()
        } else {
            report.model.join(", ")
        }
    );
    for v in &verdict.violations {
        println!("         {} at {}: {}", v.vuid, v.context, v.problem);
    }
    println!(
        "layer:   {}",
        if obs.layer_vuids.is_empty() {
            "nothing".into()
        } else {
            obs.layer_vuids.join(", ")
        }
    );
    for m in &obs.layer_messages {
        println!(
            "         [{}] {}",
            m.severity,
            m.text.chars().take(300).collect::<String>()
        );
    }
    Ok(print_outcome(&report))
}

/// Whether a file that parses as neither kind was meant as a build case (its call has `infos`).
fn looks_like_build(text: &str) -> bool {
    serde_yaml::from_str::<serde_yaml::Value>(text)
        .ok()
        .and_then(|v| v.get("call").and_then(|c| c.get("infos")).map(|_| ()))
        .is_some()
}

/// A build case: the indirect call under the layer (its messages in full), the model's verdict with the
/// device's sizes, and for a valid case the traced check of the equivalent direct build.
fn run_build(a: &ReplayArgs, case: model::accel::BuildCase) -> Result<i32, String> {
    let set = super::load_sources(&a.from)?;
    let rules = model::accel::BuildRuleSet::from_vuids(&set);
    let profile = super::profile_for(a.profile.as_deref().unwrap_or(&case.profile))?;
    let unavoidable = generator::accel::unavoidable(&profile);
    let driver = harness::vulkan::Driver::parse(&a.driver);
    let inst = std::sync::Arc::new(
        harness::vulkan::VkInstance::new(driver, true).map_err(|e| e.to_string())?,
    );
    let check = match a.check {
        CheckArg::Auto => TraceCheck::Auto,
        CheckArg::RayQuery => TraceCheck::RayQuery,
        CheckArg::Pipeline => TraceCheck::Pipeline,
    };
    let started = std::time::Instant::now();
    let obs = harness::accel::run_case_with(
        &inst,
        &profile,
        &rules,
        &case,
        &unavoidable,
        BuildOptions { check },
    );
    let millis = started.elapsed().as_secs_f64() * 1000.0;
    let mut world = case.world.clone();
    if !obs.device_sizes.is_empty() {
        world.sizes = obs.device_sizes.clone();
    }
    let verdict = rules.validate(&profile, &world, &case.call);
    let mut model: Vec<String> = verdict.violations.iter().map(|v| v.vuid.clone()).collect();
    model.dedup();
    let triage = default_triage(set.version.as_deref(), &a.driver)?;
    let report = compare_build(&case, &model, &obs, &unavoidable, &triage, millis);
    println!("case:    {} (build)", case.name);
    println!("intent:  {:?}", case.intent);
    println!("status:  {}", obs.status);
    println!("sizes:   {:?}", obs.device_sizes);
    println!(
        "model:   {}",
        if model.is_empty() {
            "valid".into()
        } else {
            model.join(", ")
        }
    );
    for v in &verdict.violations {
        println!("         {} at {}: {}", v.vuid, v.context, v.problem);
    }
    println!(
        "layer:   {}",
        if obs.layer_vuids.is_empty() {
            "nothing".into()
        } else {
            obs.layer_vuids.join(", ")
        }
    );
    for m in &obs.layer_messages {
        println!("         [{}] {}: {}", m.severity, m.id, m.text);
    }
    if !obs.check.is_empty() {
        println!("check:   {} ray(s) traced with {}", obs.rays, obs.check);
        for (k, h) in obs.ray_hits.iter().enumerate() {
            println!(
                "         ray {k}: {}",
                h.map_or("miss".into(), |(i, g, p)| format!(
                    "instance {i} geometry {g} primitive {p}"
                ))
            );
        }
        for m in &obs.ray_mismatches {
            println!("         MISMATCH {m}");
        }
        if let Some(d) = harness::accel::deviation(&case, &obs) {
            println!("         the device's hits are exactly those of the build under `{d}`");
        }
        if !obs.direct_layer_vuids.is_empty() {
            println!(
                "         direct build: layer reported {}",
                obs.direct_layer_vuids.join(", ")
            );
        }
        if obs.indirect_ran {
            println!(
                "indirect: ran for real; {} ray(s) differ from the direct build",
                obs.indirect_vs_direct.len()
            );
        }
    }
    Ok(print_outcome(&report))
}

/// Prints the end of a replay's report (output check and outcome) and returns the exit status:
/// 0 when the case passed or disagreed only as the triage files say.
fn print_outcome(report: &harness::compare::CaseReport) -> i32 {
    if let Some(ok) = report.output_matches {
        println!(
            "output:  {}",
            if ok {
                "matches the model"
            } else {
                "DIFFERS from the model"
            }
        );
    }
    println!("outcome: {:?} {}", report.outcome, report.detail);
    match report.outcome {
        harness::compare::Outcome::Pass | harness::compare::Outcome::Triaged => 0,
        _ => 1,
    }
}
