//! Where a session finds what it reads: the repository root (`profiles/`, `triage/`, `cases/`), the
//! registry sources of the rules, and device profiles by short name or path.

use crate::error::SessionError;
use crate::triage::Triage;
use model::profile::PROFILE_FILE_LIMIT;
use model::DeviceProfile;
use std::path::{Path, PathBuf};

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

/// Sources of VUIDs named on the command line, or the installed registry.
pub fn sources_or_default(from: &[PathBuf]) -> Vec<PathBuf> {
    if from.is_empty() {
        vec![PathBuf::from(vk_registry::source::DEFAULT_REGISTRY_DIR)]
    } else {
        from.to_vec()
    }
}

/// Loads the union of the sources, with a message that says how to install the registry if missing.
pub fn load_sources(from: &[PathBuf]) -> Result<vk_registry::vuid::VuidSet, SessionError> {
    load_sources_where(from, &|_| true)
}

/// [`load_sources`] with the VUIDs whose scope `keep` accepts (`vk_registry::source::load_union_where`).
pub fn load_sources_where(
    from: &[PathBuf],
    keep: &dyn Fn(&str) -> bool,
) -> Result<vk_registry::vuid::VuidSet, SessionError> {
    let paths = sources_or_default(from);
    vk_registry::source::load_union_where(&paths, keep).map_err(|e| SessionError::Registry {
        problem: e.to_string(),
        hint: if from.is_empty() {
            format!(
                "\n(the registry comes with libvulkan-dev: run `{}`)",
                harness::error::SETUP_COMMAND
            )
        } else {
            String::new()
        },
    })
}

/// The file of a profile named by short name (`lavapipe`, `nvidia-h100`, from `profiles/`) or by path.
pub fn profile_path(name: &str) -> PathBuf {
    if name.ends_with(".json") || name.contains('/') {
        PathBuf::from(name)
    } else {
        profiles_dir().join(format!("{name}.json"))
    }
}

/// A profile by short name or path (see [`profile_path`]).
pub fn profile_for(name: &str) -> Result<DeviceProfile, SessionError> {
    let path = profile_path(name);
    let text = vk_registry::input::read_text_at_most(&path, PROFILE_FILE_LIMIT, "a profile")
        .map_err(|e| SessionError::Profile {
            name: name.into(),
            problem: format!(
                "cannot read {}: {e} (capture one with `rtconf probe`)",
                path.display()
            ),
        })?;
    DeviceProfile::from_profiles_json(name, &text).map_err(|e| SessionError::Profile {
        name: name.into(),
        problem: e.to_string(),
    })
}

/// The profile a driver's cases are generated from by default: its short name (nvidia → nvidia-h100).
pub fn default_profile_name(driver: &str) -> String {
    match driver {
        "nvidia" => "nvidia-h100".into(),
        "lavapipe" | "lvp" => "lavapipe".into(),
        other => Path::new(other)
            .file_stem()
            .map_or("icd".into(), |s| s.to_string_lossy().into_owned()),
    }
}

/// The registry a run judges with when no source is named: the installed one if it is of the layer's
/// version, else `target/registry/<layer version>/usr/share/vulkan/registry` (what
/// `scripts/fetch-registry.sh` unpacks), so the model's VUIDs are the layer's. An explicit `--from`
/// is used as given. Only the VUIDs of the scopes the rule table models
/// ([`model::rules::modelled_scope`]) are read: a rule table and the version are what its callers
/// take from it, and the other scopes' thousands of records are most of a registry's reading time.
pub fn registry_for_layer(
    from: &[PathBuf],
    layer: Option<&harness::LayerInfo>,
) -> Result<vk_registry::vuid::VuidSet, SessionError> {
    let modelled = &model::rules::modelled_scope;
    let installed = load_sources_where(from, modelled)?;
    let Some(layer) = layer else {
        return Ok(installed);
    };
    if !from.is_empty() || installed.version.as_deref() == Some(layer.version.as_str()) {
        return Ok(installed);
    }
    let fetched = repo_dir()
        .join("target/registry")
        .join(&layer.version)
        .join("usr/share/vulkan/registry");
    if fetched.join("validusage.json").is_file() {
        return load_sources_where(&[fetched], modelled);
    }
    Err(SessionError::Registry {
        problem: format!(
            "the validation layer is {} but the installed registry is {}; the model must judge with the \
             registry of the layer's version",
            layer.version,
            installed.version.as_deref().unwrap_or("of unknown version")
        ),
        hint: format!(
            "\n(unpack it with `bash scripts/fetch-registry.sh` into {}, or name it with --from)",
            fetched.display()
        ),
    })
}

/// The triage files of a run: the named ones, or `triage/<driver>.yaml` and
/// `triage/layer-<layer version>.yaml` where present (the same for a run and a replay); the layer's
/// version is its own (`vkEnumerateInstanceLayerProperties`), not the registry's.
pub fn triage_for(
    named: &[PathBuf],
    layer_version: Option<&str>,
    driver: &harness::Driver,
) -> Result<Triage, SessionError> {
    Triage::load(
        &repo_dir().join("triage"),
        named,
        layer_version,
        &driver.name(),
    )
}
