//! Loading the rule table the generator aims at: the registry's VUIDs through `vk-registry`, with a
//! fallback that reads only the modelled scopes when the full file does not load.

use crate::GenError;
use model::rules::{modelled_scope, RuleSet};
use std::path::Path;

/// Where Debian installs the registry.
pub const REGISTRY_DIR: &str = "/usr/share/vulkan/registry";

/// Loads the rule table from a registry directory or validusage.json.
///
/// FIXME(vk-registry): the full validusage.json of 1.3.239 currently fails to load
/// (`VUID-vkAllocateCommandBuffers-pAllocateInfo::commandBufferCount-arraylength` is rejected as
/// not a VUID). Until the reader accepts it, the fallback keeps only the scopes the model judges
/// and loads those through the same reader, so the rows are exactly what `from_vuids` would build.
pub fn load_rules(path: &Path) -> Result<RuleSet, GenError> {
    match vk_registry::source::load_vuids(path) {
        Ok(set) => Ok(RuleSet::from_vuids(&set)),
        Err(first) => {
            let file = if path.is_dir() { path.join("validusage.json") } else { path.to_path_buf() };
            let text = std::fs::read_to_string(&file).map_err(|e| GenError::Registry(format!("{}: {e}", file.display())))?;
            let mut doc: serde_json::Value =
                serde_json::from_str(&text).map_err(|e| GenError::Registry(format!("{}: {e}", file.display())))?;
            let Some(validation) = doc.get_mut("validation").and_then(|v| v.as_object_mut()) else {
                return Err(GenError::Registry(first.to_string()));
            };
            validation.retain(|scope, _| modelled_scope(scope));
            let tmp = std::env::temp_dir().join(format!("rtconf-generator-vu-{}.json", std::process::id()));
            std::fs::write(&tmp, doc.to_string()).map_err(|e| GenError::Registry(e.to_string()))?;
            let set = vk_registry::source::load_vuids(&tmp);
            let _ = std::fs::remove_file(&tmp);
            let set = set.map_err(|e| GenError::Registry(format!("{first}; fallback: {e}")))?;
            Ok(RuleSet::from_vuids(&set))
        }
    }
}

/// The rule table of the installed registry.
pub fn default_rules() -> Result<RuleSet, GenError> {
    load_rules(Path::new(REGISTRY_DIR))
}
