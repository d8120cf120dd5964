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
    if a.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&rows).unwrap_or_default()
        );
    } else {
        print_table(&rows);
    }
    if !missing.is_empty() {
        eprintln!(
            "rtconf: {} VUIDs of the sources have no row in the rule table:",
            missing.len()
        );
        for m in &missing {
            eprintln!("  {m}");
        }
        return Ok(1);
    }
    Ok(0)
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
