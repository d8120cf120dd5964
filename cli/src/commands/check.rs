//! `rtconf check`: the model's verdict on case files (any command), each judged on the profile it names.

use clap::Args;
use model::RuleSet;
use std::path::PathBuf;

#[derive(Args)]
pub struct CheckArgs {
    /// Case files (YAML).
    cases: Vec<PathBuf>,
    /// Registry sources for the rules (default: the installed registry).
    #[arg(long = "from")]
    from: Vec<PathBuf>,
    /// Print the verdicts as JSON.
    #[arg(long)]
    json: bool,
}

#[derive(serde::Serialize)]
struct CheckResult {
    case: String,
    vuids: Vec<String>,
    expected: Vec<String>,
    agrees: bool,
    violations: Vec<model::Violation>,
}

pub fn run(a: CheckArgs) -> super::Exit {
    if a.cases.is_empty() {
        return Err(session::SessionError::Usage("no case files given".into()));
    }
    let set = session::sources::load_sources(&a.from)?;
    let rules = RuleSet::from_vuids(&set);
    let mut results = Vec::new();
    let mut errors = 0;
    for path in &a.cases {
        let shown = path.display().to_string();
        let case = match session::replay::read_case(path) {
            Ok(c) => c,
            Err(e) => {
                // Report and carry on: verdicts already computed for other files are kept.
                eprintln!("rtconf: {}", super::printable(&e.to_string()));
                errors += 1;
                continue;
            }
        };
        let profile = match session::sources::profile_for(&case.profile) {
            Ok(p) => p,
            Err(e) => {
                eprintln!("rtconf: {}", super::printable(&format!("{shown}: {e}")));
                errors += 1;
                continue;
            }
        };
        // A case the model cannot hand to a driver is the case's error, located in its file.
        if let Err(why) = case.runnable(&profile) {
            eprintln!(
                "rtconf: {}",
                super::printable(&session::replay::located(
                    path,
                    &format!("{}: {why}", why.at)
                ))
            );
            errors += 1;
            continue;
        }
        let verdict = model::validate(&rules, &profile, &case);
        let vuids: Vec<String> = verdict.vuids().into_iter().map(String::from).collect();
        let expected = case.expected_vuids();
        results.push(CheckResult {
            case: shown,
            agrees: vuids == expected,
            vuids,
            expected,
            violations: verdict.violations,
        });
    }
    if a.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&results).unwrap_or_default()
        );
    } else {
        for r in &results {
            let mark = if r.agrees { "ok  " } else { "DIFF" };
            println!(
                "{mark} {}: {}",
                r.case,
                if r.vuids.is_empty() {
                    "valid".to_string()
                } else {
                    r.vuids.join(", ")
                }
            );
            for v in &r.violations {
                println!(
                    "       {}",
                    super::printable(&format!("{} at {}: {}", v.vuid, v.context, v.problem))
                );
            }
            if !r.agrees {
                println!(
                    "       the case expects: {}",
                    if r.expected.is_empty() {
                        "valid".into()
                    } else {
                        r.expected.join(", ")
                    }
                );
            }
        }
    }
    let disagreements = results.iter().filter(|r| !r.agrees).count();
    Ok(if errors > 0 {
        2
    } else if disagreements > 0 {
        1
    } else {
        0
    })
}
