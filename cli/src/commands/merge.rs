//! `rtconf merge DIR... --out DIR`: the run folders of a sharded run merged into one, with the summary
//! printed as a run prints it.

use clap::Args;
use std::path::PathBuf;

#[derive(Args)]
pub struct MergeArgs {
    /// The run folders of the shards (`rtconf run --shard I/N --out DIR` each).
    #[arg(required = true)]
    dirs: Vec<PathBuf>,
    /// The merged run folder.
    #[arg(long)]
    out: PathBuf,
    /// Also print the per-VUID agreement table.
    #[arg(long, short)]
    verbose: bool,
}

pub fn run(a: MergeArgs) -> super::Exit {
    let merged = session::merge::merge(&a.dirs, &a.out)?;
    for n in &merged.notes {
        eprintln!("rtconf: {n}");
    }
    if let Err(e) = &merged.report {
        eprintln!("rtconf: the HTML report could not be written: {e}");
    }
    if a.verbose {
        super::run::print_vuid_table(&merged.summary);
    }
    super::run::print_summary(&merged.summary, &a.out, 0, a.verbose);
    Ok(if merged.summary.unexpected() > 0 || !merged.complete {
        1
    } else {
        0
    })
}
