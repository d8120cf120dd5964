//! Loading VUIDs from any supported source path (a registry directory, a validusage.json, or
//! a man page) and unions of several sources.

use crate::error::{read_to_string, RegistryError};
use crate::vuid::VuidSet;
use crate::{manpage, validusage};
use std::path::{Path, PathBuf};

/// Where Debian installs the registry.
pub const DEFAULT_REGISTRY_DIR: &str = "/usr/share/vulkan/registry";

/// Load the VUIDs of `path`: a directory holding validusage.json, a validusage.json file
/// (anything whose content starts with `{`), or a man page in any of the supported formats.
pub fn load_vuids(path: &Path) -> Result<VuidSet, RegistryError> {
    load_vuids_where(path, &|_| true)
}

/// [`load_vuids`], keeping the VUIDs whose scope `keep` accepts (`validusage::parse_where`).
pub fn load_vuids_where(
    path: &Path,
    keep: &dyn Fn(&str) -> bool,
) -> Result<VuidSet, RegistryError> {
    let meta = std::fs::metadata(path).map_err(|e| RegistryError::io(path, e))?;
    if meta.is_dir() {
        let file = path.join("validusage.json");
        if !file.exists() {
            return Err(RegistryError::NotFound {
                path: file.display().to_string(),
            });
        }
        return validusage::load_where(&file, keep);
    }
    let text = read_to_string(path)?;
    let origin = path.display().to_string();
    let is_json =
        path.extension().is_some_and(|e| e == "json") || text.trim_start().starts_with('{');
    if is_json {
        validusage::parse_where(&text, &origin, keep)
    } else {
        manpage::parse(&text, &origin).map(|(_, mut set)| {
            set.records.retain(|r| keep(&r.scope));
            set
        })
    }
}

/// The union by id of the VUIDs of several sources; where an id appears in more than one,
/// the record of the first source wins. The version is the first source's.
pub fn load_union(paths: &[PathBuf]) -> Result<VuidSet, RegistryError> {
    load_union_where(paths, &|_| true)
}

/// [`load_union`] of the VUIDs whose scope `keep` accepts.
pub fn load_union_where(
    paths: &[PathBuf],
    keep: &dyn Fn(&str) -> bool,
) -> Result<VuidSet, RegistryError> {
    let mut sets = Vec::with_capacity(paths.len());
    for p in paths {
        sets.push(load_vuids_where(p, keep)?);
    }
    Ok(union(sets))
}

/// The union of already loaded sets (first wins).
pub fn union(sets: Vec<VuidSet>) -> VuidSet {
    let origin = sets
        .iter()
        .map(|s| s.origin.as_str())
        .collect::<Vec<_>>()
        .join(" + ");
    let version = sets.iter().find_map(|s| s.version.clone());
    let records = sets.into_iter().flat_map(|s| s.records).collect();
    VuidSet::new(origin, version, records)
}
