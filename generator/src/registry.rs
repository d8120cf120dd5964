//! Loading the rule table the generator aims at: the registry's VUIDs through `vk-registry`.

use crate::GenError;
use model::rules::RuleSet;
use std::path::Path;

/// Where Debian installs the registry.
pub const REGISTRY_DIR: &str = vk_registry::source::DEFAULT_REGISTRY_DIR;

/// Loads the rule table from a registry directory, a validusage.json or a man page.
pub fn load_rules(path: &Path) -> Result<RuleSet, GenError> {
    let set =
        vk_registry::source::load_vuids(path).map_err(|e| GenError::Registry(e.to_string()))?;
    Ok(RuleSet::from_vuids(&set))
}

/// The rule table of the installed registry.
pub fn default_rules() -> Result<RuleSet, GenError> {
    load_rules(Path::new(REGISTRY_DIR))
}
