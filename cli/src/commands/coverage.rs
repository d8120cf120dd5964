//! `rtconf coverage`: the rule table joined with the registry's VUIDs, per command, with totals.

use clap::Args;
use model::rules::{modelled_scope, CoverageRow, RuleSet, Status};
use std::collections::BTreeMap;
use std::path::PathBuf;

#[derive(Args)]
pub struct CoverageArgs {
    /// Registry directories, validusage.json files or man pages (repeatable; their union).
    #[arg(long = "from")]
    from: Vec<PathBuf>,
    /// Only this command (and, for the KHR trace commands, the structures they take).
    #[arg(long)]
    command: Option<String>,
    /// Print the rows as JSON.
    #[arg(long)]
    json: bool,
    /// Device profiles to check the executable rows against (repeatable; default: every committed
    /// profile): a row comparing against a limit a profile lacks is listed (not judged there).
    #[arg(long)]
    profile: Vec<String>,
}

/// Coverage rows and the VUIDs of the sources that have no row (which must be none).
fn compute(
    set: &vk_registry::vuid::VuidSet,
    command: Option<model::CommandId>,
) -> (Vec<CoverageRow>, Vec<String>) {
    let rules = RuleSet::from_vuids(set);
    let rows = rules.coverage(command);
    let missing = set
        .records
        .iter()
        .filter(|r| {
            modelled_scope(&r.scope)
                && command.is_none_or(|c| model::rules::applies_to(&r.scope, c))
        })
        .filter(|r| rules.row(&r.id).is_none())
        .map(|r| r.id.clone())
        .collect();
    (rows, missing)
}

pub fn run(a: CoverageArgs) -> super::Exit {
    let set = session::sources::load_sources(&a.from)?;
    let command = a.command.as_deref().map(super::command_id).transpose()?;
    let (rows, missing) = compute(&set, command);
    let rules = RuleSet::from_vuids(&set);
    let untested = session::plan::untested(&rules, command);
    let profiles: Vec<String> = if a.profile.is_empty() {
        committed_profiles()
    } else {
        a.profile.clone()
    };
    let mut unjudged = Vec::new();
    for name in &profiles {
        let p = session::sources::profile_for(name)?;
        for (vuid, limits) in rules.unjudged_on(&p) {
            if rules
                .row(&vuid)
                .is_some_and(|r| command.is_none_or(|c| model::rules::applies_to(&r.scope, c)))
            {
                unjudged.push(format!(
                    "{vuid} on {name}: the profile lacks {}",
                    limits.join(", ")
                ));
            }
        }
    }
    if a.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&rows).unwrap_or_default()
        );
    } else {
        print_table(&rows);
    }
    for u in &unjudged {
        eprintln!("rtconf: not judged: {u}");
    }
    let mut status = 0;
    let (said, unsaid): (Vec<_>, Vec<_>) = untested.iter().partition(|(_, _, why)| why.is_some());
    for (c, v, why) in &said {
        eprintln!("rtconf: untested: {v} ({c}): {}", why.unwrap_or_default());
    }
    if !unsaid.is_empty() {
        eprintln!(
            "rtconf: {} executable rows have no mutation and no reason why, so no run tests them:",
            unsaid.len()
        );
        for (c, v, _) in &unsaid {
            eprintln!("  {v} ({c})");
        }
        status = 1;
    }
    if !missing.is_empty() {
        eprintln!(
            "rtconf: {} VUIDs of the sources have no row in the rule table:",
            missing.len()
        );
        for m in &missing {
            eprintln!("  {m}");
        }
        status = 1;
    }
    Ok(status)
}

/// The short names of the committed profiles (`profiles/*.json`).
fn committed_profiles() -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(session::sources::profiles_dir())
        .map(|d| {
            d.filter_map(|e| e.ok())
                .filter_map(|e| {
                    let p = e.path();
                    if p.extension()? != "json" {
                        return None;
                    }
                    Some(p.file_stem()?.to_string_lossy().into_owned())
                })
                .collect()
        })
        .unwrap_or_default();
    names.sort();
    names
}

fn print_table(rows: &[CoverageRow]) {
    let mut totals: BTreeMap<&str, [usize; 5]> = BTreeMap::new();
    for r in rows {
        let t = totals.entry(r.scope.as_str()).or_default();
        match (r.status, r.source) {
            (Status::Executable, Some(model::rules::Source::Template)) => t[0] += 1,
            (Status::Executable, _) => t[1] += 1,
            (Status::NotExecutable, _) => t[2] += 1,
            (Status::Pending, _) => t[3] += 1,
        }
        t[4] += 1;
    }
    for r in rows {
        let status = match r.status {
            Status::Executable => "executable",
            Status::NotExecutable => "not-executable",
            Status::Pending => "pending",
        };
        let source = match r.source {
            Some(model::rules::Source::Template) => "template",
            Some(model::rules::Source::Hand) => "hand",
            None => "-",
        };
        println!(
            "{:<78} {:<15} {:<8} {}",
            r.vuid,
            status,
            source,
            r.reason.as_deref().unwrap_or("")
        );
    }
    println!();
    println!(
        "{:<46} {:>9} {:>6} {:>9} {:>8} {:>6}",
        "scope", "template", "hand", "not-exec", "pending", "total"
    );
    let mut all = [0usize; 5];
    for (scope, t) in &totals {
        println!(
            "{:<46} {:>9} {:>6} {:>9} {:>8} {:>6}",
            scope, t[0], t[1], t[2], t[3], t[4]
        );
        for i in 0..5 {
            all[i] += t[i];
        }
    }
    println!(
        "{:<46} {:>9} {:>6} {:>9} {:>8} {:>6}",
        "all", all[0], all[1], all[2], all[3], all[4]
    );
}
