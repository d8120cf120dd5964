//! `rtconf gen`: write N generated cases (valid, or violating one VUID) of any command as YAML; the same
//! seed writes the same cases. A VUID that names its command decides the command.

use clap::Args;
use generator::CaseSpec;
use std::path::PathBuf;

#[derive(Args)]
pub struct GenArgs {
    /// A profile name under profiles/ or a path.
    #[arg(long, default_value = "lavapipe")]
    profile: String,
    /// Valid cases.
    #[arg(long, conflicts_with = "vuid")]
    valid: bool,
    /// Cases violating this VUID.
    #[arg(long)]
    vuid: Option<String>,
    /// The command (a VUID that names one decides it; default vkCmdTraceRaysIndirectKHR).
    #[arg(long)]
    command: Option<String>,
    /// How many cases to write (at least 1).
    #[arg(long, default_value_t = 10, value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..))]
    count: usize,
    /// The seed; the same seed writes the same cases.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// The folder the case files go to.
    #[arg(long)]
    out: PathBuf,
    /// Registry sources for the rules (default: the installed registry).
    #[arg(long = "from")]
    from: Vec<PathBuf>,
}

pub fn run(a: GenArgs) -> super::Exit {
    let command = match &a.command {
        Some(c) => super::command_id(c)?,
        None => model::CommandId::TraceRaysIndirect,
    };
    let spec = match (a.valid, a.vuid) {
        (_, Some(v)) => CaseSpec::for_vuid(&v, command),
        (true, None) => CaseSpec::valid(command),
        (false, None) => {
            return Err(session::SessionError::Usage(
                "say --valid or --vuid VUID".into(),
            ))
        }
    };
    let set = session::sources::load_sources(&a.from)?;
    let rules = model::RuleSet::from_vuids(&set);
    let profile = session::sources::profile_for(&a.profile)?;
    for f in model::required_limits::findings(&profile) {
        eprintln!("rtconf: warning: {}", f.warning(&a.profile));
    }
    std::fs::create_dir_all(&a.out)
        .map_err(|e| session::SessionError::io(a.out.display().to_string(), e))?;
    // A slice at a time (the same cases however the count is sliced), so memory stays that of one
    // slice whatever the count.
    let mut written = 0;
    for start in (0..a.count).step_by(SLICE) {
        let range = start..(start + SLICE).min(a.count);
        let cases = generator::generate_range(&profile, &a.profile, &rules, &spec, range, a.seed)?;
        for c in &cases {
            let p = a.out.join(format!("{}.yaml", c.name));
            std::fs::write(&p, c.to_yaml())
                .map_err(|e| session::SessionError::io(p.display().to_string(), e))?;
        }
        written += cases.len();
    }
    eprintln!("wrote {written} cases to {}", a.out.display());
    Ok(0)
}

/// Cases generated and written together.
const SLICE: usize = 256;
