//! `rtconf registry vuids|diff|show`: thin wrappers over `vk_registry::report`.

use clap::Subcommand;
use std::io::Write;
use std::path::{Path, PathBuf};

#[derive(Subcommand)]
pub enum RegistryCommand {
    /// The VUIDs a source defines, one per line, sorted (or records as JSON).
    Vuids {
        /// A registry directory, a validusage.json, or a man page (repeatable; default: the installed registry).
        #[arg(long = "from")]
        from: Vec<PathBuf>,
        /// Only this command's VUIDs.
        #[arg(long)]
        command: Option<String>,
        /// Print the records (text, condition, origin) as JSON.
        #[arg(long)]
        json: bool,
    },
    /// VUIDs added, removed and changed between two sources.
    Diff {
        /// The older source: a registry directory, a validusage.json or a man page.
        a: PathBuf,
        /// The newer source.
        b: PathBuf,
        /// Only this command's VUIDs.
        #[arg(long)]
        command: Option<String>,
        /// Leave out VUIDs whose text is unchanged and only their condition (the extensions and
        /// versions they depend on) differs.
        #[arg(long)]
        ignore_conditions: bool,
    },
    /// A command, structure or enum of vk.xml with its attributes.
    Show {
        name: String,
        /// A registry directory or a vk.xml (default: the installed registry).
        #[arg(long = "from")]
        from: Option<PathBuf>,
    },
}

fn print(s: &str) -> super::Exit {
    let mut out = std::io::stdout().lock();
    // A closed pipe (`| head`) is not an error worth a message.
    let _ = out.write_all(s.as_bytes());
    if !s.is_empty() && !s.ends_with('\n') {
        let _ = out.write_all(b"\n");
    }
    Ok(0)
}

/// A registry error as the session reports it.
fn registry_error(e: impl std::fmt::Display) -> session::SessionError {
    session::SessionError::Registry {
        problem: e.to_string(),
        hint: String::new(),
    }
}

pub fn run(c: RegistryCommand) -> super::Exit {
    match c {
        RegistryCommand::Vuids {
            from,
            command,
            json,
        } => {
            let set = session::sources::load_sources(&from)?;
            if let Some(c) = command.as_deref() {
                session::names::known_scope(c, set.records.iter().map(|r| r.scope.as_str()))?;
            }
            let text = if json {
                vk_registry::report::vuids_json(&set, command.as_deref())
            } else {
                vk_registry::report::vuids_plain(&set, command.as_deref())
            };
            print(&text)
        }
        RegistryCommand::Diff {
            a,
            b,
            command,
            ignore_conditions,
        } => {
            let sa = vk_registry::source::load_vuids(&a).map_err(registry_error)?;
            let sb = vk_registry::source::load_vuids(&b).map_err(registry_error)?;
            if let Some(c) = command.as_deref() {
                let scopes = sa
                    .records
                    .iter()
                    .chain(&sb.records)
                    .map(|r| r.scope.as_str());
                session::names::known_scope(c, scopes)?;
            }
            let options = vk_registry::report::DiffOptions {
                command: command.as_deref(),
                ignore_conditions,
            };
            print(&vk_registry::report::diff_with(&sa, &sb, &options))
        }
        RegistryCommand::Show { name, from } => {
            let dir =
                from.unwrap_or_else(|| PathBuf::from(vk_registry::source::DEFAULT_REGISTRY_DIR));
            let xml = if dir.is_dir() {
                dir.join("vk.xml")
            } else {
                dir
            };
            let reg = vk_registry::xml::Registry::load(Path::new(&xml)).map_err(registry_error)?;
            let text = vk_registry::report::show(&reg, &name).map_err(registry_error)?;
            print(&text)
        }
    }
}
