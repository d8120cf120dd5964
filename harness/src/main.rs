//! The `rtconf` command: registry summaries, coverage, case checking and generation, device probing,
//! conformance runs on a real driver, and replay of one case.

mod cli;

fn main() {
    std::process::exit(cli::main());
}
