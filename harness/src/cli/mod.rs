//! Command-line parsing (clap) and dispatch to the subcommands; every error becomes one clear message
//! and a non-zero exit, never a panic.

mod check;
mod coverage;
mod gen;
mod probe;
mod registry;
mod replay;
mod run;

use clap::{Parser, Subcommand};
use std::path::PathBuf;

#[derive(Parser)]
#[command(
    name = "rtconf",
    version,
    about = "Conformance suite for Vulkan ray tracing: model, generator, harness"
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
    /// A conformance run: generated cases on a driver under the validation layer, compared with the model.
    Run(run::RunArgs),
    /// One case on a driver with the full comparison.
    Replay(replay::ReplayArgs),
    /// (internal) Run cases read from stdin; used by `run`'s worker processes.
    #[command(hide = true)]
    Worker,
}

/// Sources of VUIDs named on the command line, or the installed registry.
pub fn sources_or_default(from: &[PathBuf]) -> Vec<PathBuf> {
    if from.is_empty() {
        vec![PathBuf::from(vk_registry::source::DEFAULT_REGISTRY_DIR)]
    } else {
        from.to_vec()
    }
}

/// Loads the union of the sources, with a message that says how to install the registry if missing.
pub fn load_sources(from: &[PathBuf]) -> Result<vk_registry::vuid::VuidSet, String> {
    let paths = sources_or_default(from);
    vk_registry::source::load_union(&paths).map_err(|e| {
        let hint = if from.is_empty() {
            "\n(the registry comes with libvulkan-dev: run `bash scripts/setup.sh`)"
        } else {
            ""
        };
        format!("{e}{hint}")
    })
}

pub fn main() -> i32 {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Registry(c) => registry::run(c),
        Command::Coverage(a) => coverage::run(a),
        Command::Check(a) => check::run(a),
        Command::Gen(a) => gen::run(a),
        Command::Probe(a) => probe::run(a),
        Command::Run(a) => run::run(a),
        Command::Replay(a) => replay::run(a),
        Command::Worker => Ok(harness::worker::worker_main()),
    };
    match result {
        Ok(code) => code,
        Err(msg) => {
            eprintln!("rtconf: {msg}");
            2
        }
    }
}

/// The repository root (profiles/, triage/, cases/); `RTCONF_HOME` overrides it for an installed binary.
pub fn repo_dir() -> PathBuf {
    match std::env::var("RTCONF_HOME") {
        Ok(d) => PathBuf::from(d),
        Err(_) => PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(".."),
    }
}

/// The directory holding the committed device profiles (`profiles/` at the repository root).
pub fn profiles_dir() -> PathBuf {
    repo_dir().join("profiles")
}

/// A profile by short name (`lavapipe`, `nvidia-h100`) from `profiles/`, or by path.
pub fn profile_for(name: &str) -> Result<model::DeviceProfile, String> {
    let path = if name.ends_with(".json") || name.contains('/') {
        PathBuf::from(name)
    } else {
        profiles_dir().join(format!("{name}.json"))
    };
    let text = std::fs::read_to_string(&path).map_err(|e| {
        format!(
            "profile `{name}`: cannot read {}: {e} (capture one with `rtconf probe`)",
            path.display()
        )
    })?;
    model::DeviceProfile::from_profiles_json(name, &text).map_err(|e| e.to_string())
}
