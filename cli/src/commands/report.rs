//! `rtconf report DIR`: (re)writes the HTML report of a run folder from its results, details and case
//! files, and prints where it went.

use clap::Args;
use std::path::PathBuf;

#[derive(Args)]
pub struct ReportArgs {
    /// A run folder (what `rtconf run --out` or `rtconf merge --out` wrote).
    dir: PathBuf,
}

pub fn run(a: ReportArgs) -> super::Exit {
    let page = session::html::write_report(&a.dir)?;
    println!("{}", page.display());
    Ok(0)
}
