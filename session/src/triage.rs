//! Triage: the written-down disagreements with the validation layer and the driver (`triage/*.yaml`),
//! which turn a disagreement the files explain into `triaged` instead of `fail`.

use crate::error::SessionError;

/// A known, written-down disagreement: a layer gap, a driver bug, or a model limitation.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TriageEntry {
    pub vuid: String,
    /// `layer-gap` (the layer does not check it), `layer-extra`, `driver`, or `model`.
    pub kind: String,
    pub reason: String,
    /// A case file that reproduces it.
    #[serde(default)]
    pub case: Option<String>,
}

/// The triage file of one driver and layer version.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Triage {
    #[serde(default)]
    pub layer_version: Option<String>,
    #[serde(default)]
    pub entries: Vec<TriageEntry>,
}

impl Triage {
    pub fn from_yaml(path: &str, text: &str) -> Result<Triage, SessionError> {
        model::case::parse_yaml(path, text).map_err(SessionError::Case)
    }

    /// The entries of the named files; with none named, of `dir/<driver>.yaml` and
    /// `dir/layer-<layer version>.yaml` where they exist.
    pub fn load(
        dir: &std::path::Path,
        named: &[std::path::PathBuf],
        layer_version: Option<&str>,
        driver: &str,
    ) -> Result<Triage, SessionError> {
        let (paths, must_exist) = if named.is_empty() {
            let mut v = vec![dir.join(format!("{driver}.yaml"))];
            if let Some(ver) = layer_version {
                v.push(dir.join(format!("layer-{ver}.yaml")));
            }
            (v, false)
        } else {
            (named.to_vec(), true)
        };
        let mut all = Triage::default();
        for p in paths {
            match std::fs::read_to_string(&p) {
                Ok(t) => all
                    .entries
                    .extend(Triage::from_yaml(&p.display().to_string(), &t)?.entries),
                Err(_) if !must_exist => {}
                Err(e) => return Err(SessionError::io(format!("triage file {}", p.display()), e)),
            }
        }
        Ok(all)
    }

    /// The entry for a VUID; an entry's `vuid` may hold `*` wildcards (`VUID-vkCmdTraceRays*KHR-None-03429`
    /// covers the direct and the indirect command).
    pub fn covers(&self, vuid: &str) -> Option<&TriageEntry> {
        self.entries.iter().find(|e| wildcard_match(&e.vuid, vuid))
    }
}

/// Whether `text` matches `pattern`, where `*` stands for any run of characters.
fn wildcard_match(pattern: &str, text: &str) -> bool {
    let mut parts = pattern.split('*');
    let first = parts.next().unwrap_or("");
    let Some(mut rest) = text.strip_prefix(first) else {
        return false;
    };
    let parts: Vec<&str> = parts.collect();
    for (i, part) in parts.iter().enumerate() {
        if i == parts.len() - 1 {
            return rest.ends_with(part);
        }
        match rest.find(part) {
            Some(at) => rest = &rest[at + part.len()..],
            None => return false,
        }
    }
    rest.is_empty()
}

#[cfg(test)]
mod tests {
    use super::wildcard_match;

    #[test]
    fn triage_patterns_match_both_trace_commands_and_nothing_else() {
        let p = "VUID-vkCmdTraceRays*KHR-None-03429";
        assert!(wildcard_match(p, "VUID-vkCmdTraceRaysKHR-None-03429"));
        assert!(wildcard_match(
            p,
            "VUID-vkCmdTraceRaysIndirectKHR-None-03429"
        ));
        assert!(!wildcard_match(p, "VUID-vkCmdTraceRaysNV-None-03429"));
        assert!(!wildcard_match(p, "VUID-vkCmdTraceRaysKHR-None-034290"));
        assert!(wildcard_match("VUID-x", "VUID-x"));
        assert!(!wildcard_match("VUID-x", "VUID-xy"));
    }
}
