//! `rtconf replay CASE.yaml`: one case on a driver, in this process, with the full comparison printed.

use clap::Args;
use harness::compare::{compare, Triage};
use std::path::PathBuf;

#[derive(Args)]
pub struct ReplayArgs {
    case: PathBuf,
    #[arg(long, default_value = "lavapipe")]
    driver: String,
    #[arg(long = "from")]
    from: Vec<PathBuf>,
}

pub fn run(a: ReplayArgs) -> Result<i32, String> {
    let shown = a.case.display().to_string();
    let text = std::fs::read_to_string(&a.case).map_err(|e| format!("{shown}: cannot read: {e}"))?;
    let case = model::Case::from_yaml(&shown, &text).map_err(|e| e.to_string())?;
    let set = super::load_sources(&a.from)?;
    let rules = model::RuleSet::from_vuids(&set);
    let profile = super::profile_for(&case.profile)?;
    let verdict = model::validate(&rules, &profile, &case.world, &case.call);
    let driver = harness::vulkan::Driver::parse(&a.driver);
    let mut ex = harness::execute::Executor::new(driver).map_err(|e| e.to_string())?;
    let started = std::time::Instant::now();
    let obs = harness::execute::execute(&case, &mut ex);
    let report = compare(&case, &verdict, &obs, &Triage::default(), started.elapsed().as_secs_f64() * 1000.0);
    println!("case:    {}", case.name);
    println!("intent:  {:?}", case.intent);
    println!("status:  {:?}", obs.status);
    println!("model:   {}", if report.model.is_empty() { "valid".into() } else { report.model.join(", ") });
    for v in &verdict.violations {
        println!("         {} at {}: {}", v.vuid, v.context, v.problem);
    }
    println!("layer:   {}", if obs.layer_vuids.is_empty() { "nothing".into() } else { obs.layer_vuids.join(", ") });
    for m in &obs.layer_messages {
        println!("         [{}] {}", m.severity, m.text.chars().take(300).collect::<String>());
    }
    if let Some(ok) = report.output_matches {
        println!("output:  {}", if ok { "matches the model" } else { "DIFFERS from the model" });
    }
    println!("outcome: {:?} {}", report.outcome, report.detail);
    Ok(if report.outcome == harness::compare::Outcome::Pass { 0 } else { 1 })
}
