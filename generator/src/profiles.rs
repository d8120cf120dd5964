//! Device profile loading: short names (`lavapipe`, `nvidia-h100`) resolve to the captured profiles
//! under `<repo>/profiles/`, anything else is read as a path to a Vulkan Profiles JSON file.

use crate::GenError;
use model::profile::PROFILE_FILE_LIMIT;
use model::DeviceProfile;
use std::path::{Path, PathBuf};

/// The repository root (the workspace that holds `profiles/` and `cases/`).
pub fn repo_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("generator/ sits in the workspace")
        .to_path_buf()
}

/// The file a profile name or path stands for.
pub fn resolve(name_or_path: &str) -> PathBuf {
    let looks_like_path = name_or_path.contains('/') || name_or_path.ends_with(".json");
    if looks_like_path {
        PathBuf::from(name_or_path)
    } else {
        repo_root()
            .join("profiles")
            .join(format!("{name_or_path}.json"))
    }
}

/// The short name a profile is recorded under in cases: the name itself, or a path's file stem.
pub fn short_name(name_or_path: &str) -> String {
    let p = Path::new(name_or_path);
    if name_or_path.contains('/') || name_or_path.ends_with(".json") {
        p.file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_else(|| name_or_path.to_string())
    } else {
        name_or_path.to_string()
    }
}

/// Loads a captured device profile by short name or path.
pub fn load(name_or_path: &str) -> Result<DeviceProfile, GenError> {
    let path = resolve(name_or_path);
    let text = vk_registry::input::read_text_at_most(&path, PROFILE_FILE_LIMIT, "a profile")
        .map_err(|e| GenError::Profile(format!("{}: {e}", path.display())))?;
    DeviceProfile::from_profiles_json(&short_name(name_or_path), &text)
        .map_err(|e| GenError::Profile(e.to_string()))
}

/// Every profile committed under `<repo>/profiles/`, by short name, sorted.
pub fn available() -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(repo_root().join("profiles"))
        .into_iter()
        .flatten()
        .flatten()
        .filter_map(|e| {
            let p = e.path();
            if p.extension().is_some_and(|x| x == "json") {
                Some(p.file_stem()?.to_string_lossy().into_owned())
            } else {
                None
            }
        })
        .collect();
    names.sort();
    names
}
