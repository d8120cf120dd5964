//! `rtconf report DIR`: (re)writes the HTML report of a run folder from its results, details and case
//! files, and prints where it went.

use clap::Args;
use std::path::PathBuf;

#[derive(Args)]
pub struct ReportArgs {
    /// A run folder (what `rtconf run --out` or `rtconf merge --out` wrote).
    dir: PathBuf,
}

/// The lines of `results.jsonl` left out of the report that are named one by one.
const NAMED: usize = 20;

/// Writes the report, then names the lines of `results.jsonl` it had to leave out and says whether the
/// run stopped before it finished; either makes the exit status 2 (the input was not whole), the
/// report of what there is written all the same.
pub fn run(a: ReportArgs) -> super::Exit {
    let (page, finished) = session::html::write_report_of_folder(&a.dir)?;
    println!("{}", page.display());
    // A run that stopped before its summary: the report of its results so far, and the input named
    // as not whole.
    let unfinished = !finished;
    if unfinished {
        eprintln!(
            "rtconf: {}; the report shows the results it has",
            session::report::unfinished_run(&a.dir)
        );
    }
    let (named, count) = session::results::unreadable_lines(&a.dir.join("results.jsonl"), NAMED)?;
    for problem in &named {
        eprintln!("rtconf: {problem}; left out of the report");
    }
    if count > named.len() {
        eprintln!(
            "rtconf: … and {} more lines left out of the report",
            count - named.len()
        );
    }
    Ok(if count == 0 && !unfinished { 0 } else { 2 })
}
