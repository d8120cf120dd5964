//! The `rtconf` command: registry summaries, coverage, case checking and generation, device probing,
//! conformance runs on a real driver, and replay of one case. Argument parsing and printing only: the
//! work is done by `session`, `model`, `generator` and `harness`.

mod commands;
mod interrupt;

fn main() {
    std::process::exit(commands::main());
}
