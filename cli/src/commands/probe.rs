//! `rtconf probe`: capture a real device's profile through the harness and write it as Vulkan Profiles JSON.

use clap::Args;
use std::path::PathBuf;

#[derive(Args)]
pub struct ProbeArgs {
    /// lavapipe, nvidia, or the path of an ICD manifest.
    #[arg(long, default_value = "lavapipe")]
    driver: String,
    /// Output file (default: standard output).
    #[arg(long)]
    out: Option<PathBuf>,
    /// The profile's short name (default: the driver's).
    #[arg(long)]
    name: Option<String>,
}

pub fn run(a: ProbeArgs) -> super::Exit {
    let driver = harness::Driver::parse(&a.driver);
    let mut profile = harness::probe::probe(driver)?;
    if let Some(n) = a.name {
        profile.name = n;
    }
    let text = profile.to_profiles_json();
    match a.out {
        Some(p) => std::fs::write(&p, &text)
            .map_err(|e| session::SessionError::io(p.display().to_string(), e))?,
        None => print!("{text}"),
    }
    for f in model::required_limits::findings(&profile) {
        eprintln!("rtconf: warning: {f}");
    }
    // What the device reported is written either way, as evidence; a profile no case can be laid
    // out with is said so and fails the command.
    if let Err(e) = model::DeviceProfile::from_profiles_json(&profile.name, &text) {
        eprintln!("rtconf: the profile cannot be used to make cases: {e}");
        return Ok(1);
    }
    Ok(0)
}
