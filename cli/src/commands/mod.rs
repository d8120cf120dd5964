//! Command-line parsing (clap) and dispatch to the subcommands; every error becomes one clear message
//! and a non-zero exit, never a panic.

mod check;
mod coverage;
mod detect;
mod export;
mod gen;
mod merge;
mod probe;
mod registry;
mod replay;
mod report;
mod run;
mod stress;

use clap::{Parser, Subcommand};

/// The most workers `--jobs` may ask for: each is a process (or a thread) with the driver loaded, all
/// started at once.
pub const MAX_JOBS: u64 = 256;

/// `text` as it may go to a terminal: control characters other than newline and tab (which a case
/// file's names and strings may hold, `\x1b[...` among them) written as Rust escapes (`\u{1b}`), so
/// an error quoting what a file holds neither drives the terminal nor hides a character.
pub fn printable(text: &str) -> std::borrow::Cow<'_, str> {
    if !text
        .chars()
        .any(|c| c.is_control() && c != '\n' && c != '\t')
    {
        return text.into();
    }
    text.chars()
        .map(|c| {
            if c.is_control() && c != '\n' && c != '\t' {
                c.escape_default().to_string()
            } else {
                c.to_string()
            }
        })
        .collect::<String>()
        .into()
}
use session::SessionError;

#[derive(Parser)]
#[command(
    name = "rtconf",
    version,
    about = "Conformance suite for Vulkan ray tracing: model, generator, harness",
    after_help = EXIT_CODES
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Read the registry: VUID lists, diffs between versions, and registry entries.
    #[command(subcommand)]
    Registry(registry::RegistryCommand),
    /// One row per VUID of the modelled commands: executable, not executable (with reason), or pending.
    Coverage(coverage::CoverageArgs),
    /// The model's verdict on case files.
    Check(check::CheckArgs),
    /// Write generated cases (valid, or violating one VUID) as YAML files.
    Gen(gen::GenArgs),
    /// Capture a real device's profile (Vulkan Profiles JSON).
    Probe(probe::ProbeArgs),
    /// A conformance run: generated cases (or a folder of case files) on a driver under the validation
    /// layer, compared with the model, judged against a baseline.
    #[command(after_help = EXIT_CODES)]
    Run(Box<run::RunArgs>),
    /// Merge the run folders of a sharded run into one (results, summary, JUnit, report).
    #[command(after_help = EXIT_CODES)]
    Merge(merge::MergeArgs),
    /// The numerical stress families on a driver: per family REQ violations, double hits, holes,
    /// t and barycentric errors in ULPs and the driver's choices on VARY rays (stress.json, stress.png).
    #[command(after_help = EXIT_CODES)]
    Stress(stress::StressArgs),
    /// Write the HTML report of a run folder (DIR/report/index.html).
    Report(report::ReportArgs),
    /// The suite's detection table: seeded faults (`run --inject`) by kind and size, the detection rate
    /// and the median cases and seconds to the first catch, the mutation score.
    #[command(after_help = EXIT_CODES)]
    Detect(detect::DetectArgs),
    /// One case on a driver with the full comparison.
    #[command(after_help = EXIT_CODES)]
    Replay(replay::ReplayArgs),
    /// Write a case as a standalone C program (repro.c) for a bug report.
    Export(export::ExportArgs),
    /// (internal) Run cases read from stdin; used by `run`'s worker processes.
    #[command(hide = true)]
    Worker,
}

/// The exit statuses every subcommand follows, for `--help`.
const EXIT_CODES: &str = "Exit status:\n  \
    0  done, and nothing unexpected (run, merge: no case has status fail, crash, timeout, unexpected-pass\n     \
    or missing; replay: the case passed or is triaged; check: every verdict is the case's intent;\n     \
    stress: no REQ violation or double hit)\n  \
    1  unexpected results (those statuses, a generator error, a disagreeing verdict, a failing replay,\n     \
    a stress family's REQ violation, double hit, failure, crash or timeout)\n  \
    2  the command could not do its work: bad arguments or input files, a missing driver, layer or registry,\n     \
    a stress case at fault or a stress family that judged no ray";

/// What a subcommand gives back: its exit status, or the error that stopped it.
type Exit = Result<i32, SessionError>;

/// A command name of the command line, as a typed id.
fn command_id(name: &str) -> Result<model::CommandId, SessionError> {
    Ok(session::plan::commands(&[name.to_string()])?[0])
}

pub fn main() -> i32 {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Registry(c) => registry::run(c),
        Command::Coverage(a) => coverage::run(a),
        Command::Check(a) => check::run(a),
        Command::Gen(a) => gen::run(a),
        Command::Probe(a) => probe::run(a),
        Command::Run(a) => run::run(*a),
        Command::Merge(a) => merge::run(a),
        Command::Stress(a) => stress::run(a),
        Command::Report(a) => report::run(a),
        Command::Detect(a) => detect::run(a),
        Command::Replay(a) => replay::run(a),
        Command::Export(a) => export::run(a),
        Command::Worker => Ok(harness::worker::worker_main()),
    };
    match result {
        Ok(code) => code,
        Err(e) => {
            eprintln!("rtconf: {}", printable(&e.to_string()));
            2
        }
    }
}
