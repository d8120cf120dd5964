//! `rtconf gen`: write N generated cases (valid, or violating one VUID) as YAML; the same seed writes the
//! same cases.

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
    #[arg(long, default_value = "vkCmdTraceRaysIndirectKHR")]
    command: String,
    #[arg(long, default_value_t = 10)]
    count: usize,
    #[arg(long, default_value_t = 1)]
    seed: u64,
    #[arg(long)]
    out: PathBuf,
    #[arg(long = "from")]
    from: Vec<PathBuf>,
}

pub fn run(a: GenArgs) -> Result<i32, String> {
    let command = generator::Command::from_vk_name(&a.command)
        .ok_or_else(|| format!("unknown command `{}`", a.command))?;
    let spec = match (a.valid, a.vuid) {
        (_, Some(v)) => CaseSpec::violate(command, &v),
        (true, None) => CaseSpec::valid(command),
        (false, None) => return Err("say --valid or --vuid VUID".into()),
    };
    let set = super::load_sources(&a.from)?;
    let rules = model::RuleSet::from_vuids(&set);
    let profile = super::profile_for(&a.profile)?;
    let cases = generator::generate(&profile, &a.profile, &rules, &spec, a.count, a.seed)
        .map_err(|e| e.to_string())?;
    std::fs::create_dir_all(&a.out).map_err(|e| format!("{}: {e}", a.out.display()))?;
    for c in &cases {
        let p = a.out.join(format!("{}.yaml", c.name));
        std::fs::write(&p, c.to_yaml()).map_err(|e| format!("{}: {e}", p.display()))?;
    }
    eprintln!("wrote {} cases to {}", cases.len(), a.out.display());
    Ok(0)
}
