//! `rtconf report DIR`: (re)writes the HTML report of a run folder from its results, details and case
//! files, and prints where it went.

use clap::Args;
use std::path::PathBuf;

#[derive(Args)]
pub struct ReportArgs {
    /// A run folder (what `rtconf run --out` or `rtconf merge --out` wrote).
    dir: PathBuf,
}

/// Writes the report, then names every line of `results.jsonl` it had to leave out; such lines make the
/// exit status 2 (the input was not whole), the report of the rest written all the same.
pub fn run(a: ReportArgs) -> super::Exit {
    let page = session::html::write_report(&a.dir)?;
    println!("{}", page.display());
    let left_out = session::results::unreadable_lines(&a.dir.join("results.jsonl"))?;
    for problem in &left_out {
        eprintln!("rtconf: {problem}; left out of the report");
    }
    Ok(if left_out.is_empty() { 0 } else { 2 })
}
